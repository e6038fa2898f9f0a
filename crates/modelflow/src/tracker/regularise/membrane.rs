//! The frame-to-frame membrane (our addition to the thesis): each edge vector should stay close
//! to its value in a reference shape, residual `√μ·(e − e_ref)/L̄` (L̄: mean rest edge length, so
//! μ has no units), normalised by the number of edges. The tracker's reference is its
//! constant-velocity prediction from the two previous frames, so the membrane penalises changes
//! of the deformation's *rate* (a cloth that keeps folding is not held back). It is quadratic,
//! so it gives the system stiffness where the cubic springs have none (at rest), and it carries
//! vertices that no camera sees along with their neighbours instead of leaving them behind.

use super::{EdgeSet, FrameContext, Regulariser, System};
use nalgebra::{Matrix3, Point3};
use std::sync::Arc;

/// The membrane on every edge of the mesh.
pub(crate) struct Membrane {
    edges: Arc<EdgeSet>,
    /// μ / (L̄² · number of edges).
    scale: f64,
    /// The reference shape of the frame being solved.
    reference: Vec<Point3<f64>>,
}

impl Membrane {
    pub fn new(edges: Arc<EdgeSet>, mu: f64) -> Self {
        let l = edges.mean_length;
        let scale = mu / (l * l) / edges.edges.len().max(1) as f64;
        Membrane {
            edges,
            scale,
            reference: Vec::new(),
        }
    }
}

impl Regulariser for Membrane {
    fn name(&self) -> &'static str {
        "membrane"
    }

    fn begin_frame(&mut self, frame: &FrameContext<'_>) {
        self.reference.clear();
        self.reference.extend_from_slice(frame.predicted);
    }

    fn accumulate(&self, x: &[Point3<f64>], mut system: Option<System<'_>>) -> f64 {
        let (s, prev) = (self.scale, &self.reference);
        let h = Matrix3::identity() * s;
        let mut cost = 0.0;
        for (e, edge) in self.edges.edges.iter().enumerate() {
            let [a, b] = edge.map(|v| v as usize);
            let r = (x[b] - x[a]) - (prev[b] - prev[a]);
            cost += s * r.norm_squared();
            if let Some(sys) = system.as_mut() {
                EdgeSet::add_edge(sys, e, [a, b], &h, &(r * s));
            }
        }
        cost
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::mesh::grid;
    use crate::tracker::sparse::BlockSparse;
    use nalgebra::Vector3;

    #[test]
    fn a_translation_of_the_reference_costs_nothing_and_a_stretch_does() {
        let m = grid(4, 4, |u, v| Point3::new(u, v, 0.0));
        let edges = Arc::new(EdgeSet::new(&m));
        let mut t = Membrane::new(edges, 0.5);
        t.begin_frame(&FrameContext {
            previous: &m.positions,
            predicted: &m.positions,
            information: None,
        });
        let moved: Vec<_> = m
            .positions
            .iter()
            .map(|p| p + Vector3::new(0.3, -0.1, 2.0))
            .collect();
        assert!(t.accumulate(&moved, None) < 1e-24);
        let stretched: Vec<_> = m
            .positions
            .iter()
            .map(|p| Point3::new(1.1 * p.x, p.y, p.z))
            .collect();
        assert!(t.accumulate(&stretched, None) > 1e-4);
    }

    #[test]
    fn normal_equations_are_exact_for_the_quadratic_term() {
        // For a quadratic term, cost(x + δ) = cost(x) − 2δᵀb + δᵀAδ exactly.
        let m = grid(3, 3, |u, v| Point3::new(u, v, 0.1 * u * v));
        let edges = Arc::new(EdgeSet::new(&m));
        let mut t = Membrane::new(edges.clone(), 0.7);
        t.begin_frame(&FrameContext {
            previous: &m.positions,
            predicted: &m.positions,
            information: None,
        });
        let x: Vec<_> = m
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| p + Vector3::new(0.01 * i as f64, 0.0, -0.02))
            .collect();
        let mut a = BlockSparse::new(x.len(), &edges.edges);
        let mut b = vec![Vector3::zeros(); x.len()];
        let c0 = t.accumulate(&x, Some((&mut a, &mut b[..])));
        let delta: Vec<Vector3<f64>> = (0..x.len())
            .map(|i| Vector3::new(0.003 * i as f64, -0.002, 0.001 * (i % 3) as f64))
            .collect();
        let mut ad = vec![Vector3::zeros(); x.len()];
        a.mul(&delta, &mut ad);
        let model = c0 - 2.0 * delta.iter().zip(&b).map(|(d, b)| d.dot(b)).sum::<f64>()
            + delta.iter().zip(&ad).map(|(d, ad)| d.dot(ad)).sum::<f64>();
        let moved: Vec<_> = x.iter().zip(&delta).map(|(p, d)| p + d).collect();
        let c1 = t.accumulate(&moved, None);
        assert!(
            (c1 - model).abs() <= 1e-12 * c1.max(1e-12),
            "{c1} vs {model}"
        );
    }
}

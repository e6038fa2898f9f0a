//! The frame-to-frame membrane (our addition to the thesis): each edge vector should stay close
//! to its value in a reference shape, residual `√μ·(e − R·e_ref)/L̄` (L̄: mean rest edge length,
//! so μ has no units), normalised by the number of edges. The tracker's reference is its
//! constant-velocity prediction from the two previous frames, so the membrane penalises changes
//! of the deformation's *rate* (a cloth that keeps folding is not held back). It is quadratic,
//! so it gives the system stiffness where the cubic springs have none (at rest), and it carries
//! vertices that no camera sees along with their neighbours instead of leaving them behind.
//!
//! `R` is the rotation that best turns the reference's edges into the current ones, one per
//! connected piece of the mesh (orthogonal Procrustes on the edge vectors), so a piece that
//! turns faster or slower than the prediction (a hand-held object starting to turn, a twist
//! that speeds up) is not held back either: what the membrane resists is a change of the
//! deformation's rate, not of the pieces' rotation (2026-12-01; docs/tracker.md, "The
//! membrane follows each piece's turn"). Because `R` minimises the term's own energy, the
//! gradient at fixed `R` is the energy's gradient (envelope theorem), and the normal-equation
//! matrix is the same constant one as with `R = I`. [`Membrane::fixed`] keeps `R = I` (runs
//! recorded before, `--membrane-resists-turns`).

use super::{procrustes_if_fixed, EdgeSet, FrameContext, Regulariser, System};
use nalgebra::{Matrix3, Point3};
use std::sync::Arc;

/// The membrane on every edge of the mesh.
pub(crate) struct Membrane {
    edges: Arc<EdgeSet>,
    /// μ / (L̄² · number of edges).
    scale: f64,
    /// The reference shape of the frame being solved.
    reference: Vec<Point3<f64>>,
    /// Per edge, the connected piece of the mesh it belongs to (`0..pieces`), when the
    /// reference is turned with each piece; `None`: never turned (`R = I`).
    piece: Option<Vec<u32>>,
    pieces: usize,
}

impl Membrane {
    /// The membrane whose reference turns with each connected piece of the mesh.
    pub fn new(edges: Arc<EdgeSet>, mu: f64) -> Self {
        let (piece, pieces) = edge_pieces(&edges.edges);
        Membrane {
            piece: Some(piece),
            pieces,
            ..Membrane::fixed(edges, mu)
        }
    }

    /// The membrane with a reference that does not turn (`R = I`): a change of a piece's
    /// rotation rate is resisted like any other change of rate.
    pub fn fixed(edges: Arc<EdgeSet>, mu: f64) -> Self {
        let l = edges.mean_length;
        let scale = mu / (l * l) / edges.edges.len().max(1) as f64;
        Membrane {
            edges,
            scale,
            reference: Vec::new(),
            piece: None,
            pieces: 0,
        }
    }

    /// Per piece, the rotation that best turns the reference's edges into those of `x`: the
    /// polar factor of `Σ e·e_refᵀ` over the piece's edges (summed in edge order), or the
    /// identity where that sum does not fix one (a piece whose edges all lie on a line, or none).
    fn turns(&self, x: &[Point3<f64>]) -> Vec<Matrix3<f64>> {
        let Some(piece) = &self.piece else {
            return Vec::new();
        };
        let prev = &self.reference;
        let mut m = vec![Matrix3::zeros(); self.pieces];
        for (edge, &k) in self.edges.edges.iter().zip(piece) {
            let [a, b] = edge.map(|v| v as usize);
            m[k as usize] += (x[b] - x[a]) * (prev[b] - prev[a]).transpose();
        }
        // Two independent directions fix a rotation (the third follows from them); fewer leave
        // it free, and the reference then keeps its own orientation.
        m.iter().map(procrustes_if_fixed).collect()
    }
}

/// Each edge's connected piece of the graph `edges` (pieces numbered in order of their lowest
/// vertex), and the number of pieces.
fn edge_pieces(edges: &[[u32; 2]]) -> (Vec<u32>, usize) {
    let n = edges
        .iter()
        .map(|e| e[0].max(e[1]) as usize + 1)
        .max()
        .unwrap_or(0);
    // Union–find with path halving; the root of a set is its lowest vertex.
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    for e in edges {
        let (a, b) = (
            root(&mut parent, e[0] as usize),
            root(&mut parent, e[1] as usize),
        );
        if a != b {
            let (lo, hi) = (a.min(b), a.max(b));
            parent[hi] = lo;
        }
    }
    let mut id = vec![u32::MAX; n];
    let mut pieces = 0usize;
    for v in 0..n {
        let r = root(&mut parent, v);
        if id[r] == u32::MAX {
            id[r] = pieces as u32;
            pieces += 1;
        }
        id[v] = id[r];
    }
    (edges.iter().map(|e| id[e[0] as usize]).collect(), pieces)
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
        let turns = self.turns(x);
        let mut cost = 0.0;
        for (e, edge) in self.edges.edges.iter().enumerate() {
            let [a, b] = edge.map(|v| v as usize);
            let reference = prev[b] - prev[a];
            let reference = match &self.piece {
                Some(piece) => turns[piece[e] as usize] * reference,
                None => reference,
            };
            let r = (x[b] - x[a]) - reference;
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

    /// Two separate pieces (grids side by side), each turned by its own rotation and shifted.
    fn two_pieces() -> (crate::base::mesh::Mesh, Vec<Point3<f64>>) {
        let a = grid(4, 4, |u, v| Point3::new(u, v, 0.1 * u * v));
        let n = a.positions.len() as u32;
        let mut positions = a.positions.clone();
        positions.extend(a.positions.iter().map(|p| p + Vector3::new(3.0, 0.0, 0.0)));
        let mut triangles = a.triangles.clone();
        triangles.extend(a.triangles.iter().map(|t| t.map(|v| v + n)));
        let mesh = crate::base::mesh::Mesh::new(positions, triangles);
        let (r1, r2) = (
            nalgebra::Rotation3::from_euler_angles(0.2, -0.1, 0.3),
            nalgebra::Rotation3::from_euler_angles(-0.4, 0.25, 0.05),
        );
        let turned = mesh
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                if (i as u32) < n {
                    Point3::from(r1 * p.coords + Vector3::new(0.5, 0.0, 0.0))
                } else {
                    Point3::from(r2 * p.coords - Vector3::new(0.0, 1.0, 2.0))
                }
            })
            .collect();
        (mesh, turned)
    }

    #[test]
    fn each_piece_may_turn_at_no_cost_but_a_stretch_still_costs() {
        // A hand-held object that starts to turn, or turns faster than its prediction: the
        // membrane holds the deformation's rate, not the pieces' rotation.
        let (mesh, turned) = two_pieces();
        let edges = Arc::new(EdgeSet::new(&mesh));
        let frame = FrameContext {
            previous: &mesh.positions,
            predicted: &mesh.positions,
            information: None,
        };
        let mut turning = Membrane::new(edges.clone(), 0.5);
        turning.begin_frame(&frame);
        let mut fixed = Membrane::fixed(edges, 0.5);
        fixed.begin_frame(&frame);
        assert_eq!(turning.pieces, 2);
        assert!(turning.accumulate(&turned, None) < 1e-24);
        assert!(fixed.accumulate(&turned, None) > 1e-3);
        // A stretch costs about what it does without turning (the best turn takes out only
        // the little of it that a rotation mimics on this curved grid, never more than all).
        let stretched: Vec<_> = mesh
            .positions
            .iter()
            .map(|p| Point3::new(1.1 * p.x, p.y, p.z))
            .collect();
        let (c_turn, c_fixed) = (
            turning.accumulate(&stretched, None),
            fixed.accumulate(&stretched, None),
        );
        assert!(
            c_turn > 0.9 * c_fixed && c_turn <= c_fixed * (1.0 + 1e-12),
            "{c_turn} vs {c_fixed}"
        );
        // Turned *and* stretched: it costs what the stretch alone did (the turn is free).
        let r = nalgebra::Rotation3::from_euler_angles(0.3, 0.2, -0.1);
        let both: Vec<_> = stretched
            .iter()
            .map(|p| Point3::from(r * p.coords))
            .collect();
        let c_both = turning.accumulate(&both, None);
        assert!(
            (c_both - c_turn).abs() <= 1e-9 * c_turn,
            "{c_both} vs {c_turn}"
        );
    }

    /// `t` begun at rest on `rest` (the previous frame and the prediction both there).
    fn begun_at(mut t: Membrane, rest: &[Point3<f64>]) -> Membrane {
        t.begin_frame(&FrameContext {
            previous: rest,
            predicted: rest,
            information: None,
        });
        t
    }

    /// The term's cost at `x` and its normal equations `(A, b)`.
    fn normal_equations(
        t: &Membrane,
        edges: &EdgeSet,
        x: &[Point3<f64>],
    ) -> (f64, BlockSparse, Vec<Vector3<f64>>) {
        let mut a = BlockSparse::new(x.len(), &edges.edges);
        let mut b = vec![Vector3::zeros(); x.len()];
        let c = t.accumulate(x, Some((&mut a, &mut b[..])));
        (c, a, b)
    }

    #[test]
    fn the_turning_membranes_gradient_is_its_costs() {
        // The rotations are refitted at every x but minimise the term's own energy, so the
        // gradient taken with them held (−2·b) is the cost's: checked by central differences.
        let (mesh, turned) = two_pieces();
        let edges = Arc::new(EdgeSet::new(&mesh));
        let t = begun_at(Membrane::new(edges.clone(), 0.7), &mesh.positions);
        // Turned and bent a little: not at the minimum.
        let x: Vec<_> = turned
            .iter()
            .enumerate()
            .map(|(i, p)| p + Vector3::new(0.0, 0.01 * (i % 5) as f64, -0.02 * (i % 3) as f64))
            .collect();
        let (_, _, b) = normal_equations(&t, &edges, &x);
        let h = 1e-6;
        let mut worst = 0.0f64;
        let scale = b.iter().map(|v| v.amax()).fold(0.0, f64::max);
        for v in [0usize, 5, 17, 20, 31] {
            for k in 0..3 {
                let mut xp = x.clone();
                let mut xm = x.clone();
                xp[v][k] += h;
                xm[v][k] -= h;
                let fd = (t.accumulate(&xp, None) - t.accumulate(&xm, None)) / (2.0 * h);
                worst = worst.max((fd + 2.0 * b[v][k]).abs());
            }
        }
        assert!(worst <= 1e-6 * scale, "{worst} against {scale}");
    }

    #[test]
    fn normal_equations_are_exact_for_the_quadratic_term() {
        // For a quadratic term, cost(x + δ) = cost(x) − 2δᵀb + δᵀAδ exactly.
        let m = grid(3, 3, |u, v| Point3::new(u, v, 0.1 * u * v));
        let edges = Arc::new(EdgeSet::new(&m));
        // With the reference held in its orientation (with it turning, the cost is quadratic
        // only up to the rotations' change).
        let t = begun_at(Membrane::fixed(edges.clone(), 0.7), &m.positions);
        let x: Vec<_> = m
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| p + Vector3::new(0.01 * i as f64, 0.0, -0.02))
            .collect();
        let (c0, a, b) = normal_equations(&t, &edges, &x);
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

//! Edge regularisers that keep the mesh sane where the images say little (thesis §5.1.1, §5.2.4).
//!
//! * Cubic springs (Eq. 5.16): each edge contributes the residual `F = −k·Δd³/T²`. In the thesis'
//!   worked example (Eq. 5.17–5.20) `Δd` is the change of length itself; the tracker measures it
//!   relative to the rest length (`Δd = (L − L₀)/L₀`, a strain), which makes `T` exactly the
//!   "threshold ratio" the thesis describes (T = 0.1: soft below 10 % stretch, stiff above) and
//!   makes `k` independent of scene units. [`cubic_spring`] takes the normalising length so the
//!   worked example is reproduced with `scale = 1`.
//! * Membrane (our addition): each edge vector should stay close to a reference (the tracker uses
//!   its constant-velocity prediction from the two previous frames), residual `√μ·(e − e_ref)/L̄`. It is quadratic, so it gives the system stiffness where the cubic
//!   springs have none (at rest) and carries vertices that no camera sees along with their
//!   neighbours instead of leaving them behind.

use nalgebra::{Point3, Vector3};

/// Value and gradient of the cubic spring residual `F = −k·Δd³/T²` with `Δd = (|b − a| − rest)/scale`.
/// The gradient is with respect to `b`; with respect to `a` it is its negative.
pub fn cubic_spring(
    a: &Point3<f64>,
    b: &Point3<f64>,
    rest: f64,
    scale: f64,
    k: f64,
    t: f64,
) -> (f64, Vector3<f64>) {
    let d = b - a;
    let len = d.norm();
    let dd = (len - rest) / scale;
    let f = -k * dd.powi(3) / (t * t);
    if len == 0.0 {
        return (f, Vector3::zeros());
    }
    let grad = d * (-3.0 * k * dd * dd / (t * t * scale * len));
    (f, grad)
}

/// Parameters of the edge regularisers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpringParams {
    /// Spring constant `k` of Eq. 5.16.
    pub k: f64,
    /// Threshold ratio `T` of Eq. 5.16 (0.1 = 10 % of the rest length).
    pub t: f64,
    /// Weight `μ` of the frame-to-frame membrane (0 turns it off).
    pub membrane: f64,
    /// Weight `β` of the bending term against the rest shape (see `bending`; 0 turns it off).
    pub bending: f64,
}

/// The edges of a mesh with their rest lengths (taken from the first frame).
#[derive(Clone, Debug)]
pub struct EdgeSet {
    pub edges: Vec<[u32; 2]>,
    pub rest: Vec<f64>,
    pub mean_length: f64,
}

impl EdgeSet {
    pub fn new(edges: Vec<[u32; 2]>, rest_positions: &[Point3<f64>]) -> Self {
        let rest: Vec<f64> = edges
            .iter()
            .map(|[a, b]| (rest_positions[*b as usize] - rest_positions[*a as usize]).norm())
            .collect();
        let mean_length = if rest.is_empty() {
            1.0
        } else {
            rest.iter().sum::<f64>() / rest.len() as f64
        };
        EdgeSet {
            edges,
            rest,
            mean_length,
        }
    }
}

/// One edge's contribution to the normal equations: `H` blocks for (a,a), (a,b), (b,b) are
/// `c·I`-like 3×3 matrices, gradients `g_a`, `g_b`, and its cost.
pub struct EdgeTerm {
    pub cost: f64,
    pub h: nalgebra::Matrix3<f64>,
    /// Off-diagonal block is `-h` for both terms used here.
    pub g_b: Vector3<f64>,
}

/// Contribution of edge `e` (cubic spring + membrane) at positions `x`, with previous-frame
/// positions `prev`; `weight` scales everything (the tracker normalises by the edge count).
pub fn edge_term(
    set: &EdgeSet,
    e: usize,
    x: &[Point3<f64>],
    prev: &[Point3<f64>],
    p: &SpringParams,
    weight: f64,
) -> EdgeTerm {
    let [a, b] = set.edges[e].map(|v| v as usize);
    let rest = set.rest[e];
    let mut cost = 0.0;
    let mut h = nalgebra::Matrix3::zeros();
    let mut g_b = Vector3::zeros();
    if p.k > 0.0 && rest > 0.0 {
        let (f, grad) = cubic_spring(&x[a], &x[b], rest, rest, p.k, p.t);
        cost += weight * f * f;
        h += grad * grad.transpose() * weight;
        g_b += grad * (f * weight);
    }
    if p.membrane > 0.0 {
        let s = p.membrane / (set.mean_length * set.mean_length);
        let r = (x[b] - x[a]) - (prev[b] - prev[a]);
        cost += weight * s * r.norm_squared();
        h += nalgebra::Matrix3::identity() * (weight * s);
        g_b += r * (weight * s);
    }
    EdgeTerm { cost, h, g_b }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_worked_example() {
        // Eq. 5.17–5.20: a spring from (0,0,0) to (5,5,0) stretched to (6,6,0).
        let (k, t) = (2.0, 0.1);
        let rest = 50f64.sqrt();
        let (f, grad) = cubic_spring(
            &Point3::origin(),
            &Point3::new(6.0, 6.0, 0.0),
            rest,
            1.0,
            k,
            t,
        );
        // Δd = √72 − √50 = √2; F = −k/T²·2√2 (Eq. 5.18).
        assert!((f - (-k / (t * t) * 2.0 * 2f64.sqrt())).abs() < 1e-9, "{f}");
        // ∂F/∂x at (6,6,0) = −k/T²·3√2 (Eq. 5.20); by symmetry the same for y; zero for z.
        let expect = -k / (t * t) * 3.0 * 2f64.sqrt();
        assert!((grad.x - expect).abs() < 1e-9 && (grad.y - expect).abs() < 1e-9 && grad.z == 0.0);
    }

    #[test]
    fn strain_form_is_unit_free_and_soft_below_threshold() {
        let a = Point3::origin();
        let (f1, _) = cubic_spring(&a, &Point3::new(1.05, 0.0, 0.0), 1.0, 1.0, 1.0, 0.1);
        let (f2, _) = cubic_spring(&a, &Point3::new(105.0, 0.0, 0.0), 100.0, 100.0, 1.0, 0.1);
        assert!((f1 - f2).abs() < 1e-12);
        // At half the threshold the cubic spring is 4× softer than the linear spring k·Δd.
        assert!((f1.abs() - 0.05 / 4.0).abs() < 1e-12);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let a = Point3::new(0.1, 0.2, -0.3);
        let b = Point3::new(1.2, 0.4, 0.1);
        let (_, g) = cubic_spring(&a, &b, 0.8, 0.8, 3.0, 0.2);
        for k in 0..3 {
            let mut bp = b;
            bp[k] += 1e-6;
            let mut bm = b;
            bm[k] -= 1e-6;
            let fd = (cubic_spring(&a, &bp, 0.8, 0.8, 3.0, 0.2).0
                - cubic_spring(&a, &bm, 0.8, 0.8, 3.0, 0.2).0)
                / 2e-6;
            assert!((fd - g[k]).abs() < 1e-6 * (1.0 + fd.abs()));
        }
    }
}

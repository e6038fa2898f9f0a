//! The thesis' cubic edge springs (§5.1.1, §5.2.4, Eq. 5.16): each edge contributes the
//! residual `F = −k·Δd³/T²`. In the thesis' worked example (Eq. 5.17–5.20) `Δd` is the change of
//! length itself; the tracker measures it relative to the rest length (`Δd = (L − L₀)/L₀`, a
//! strain), which makes `T` exactly the "threshold ratio" the thesis describes (T = 0.1: soft
//! below 10 % stretch, stiff above) and makes `k` independent of scene units. [`cubic_spring`]
//! takes the normalising length so the worked example is reproduced with `scale = 1`. Each
//! edge is weighted by its share of the surface's area (the weights sum to 1), so the term
//! does not depend on how finely or how irregularly the surface is triangulated.

use super::{EdgeSet, Regulariser, System};
use nalgebra::{Matrix3, Point3, Vector3};
use std::sync::Arc;

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

/// Half the Hessian of `F²` with respect to `b` (the block the normal equations take), where
/// it is positive: `(15/9)·F′²` along the edge, `F·F′/L` across it when stretched (`F`, its
/// gradient `grad` with respect to `b`, from [`cubic_spring`]).
fn curvature(a: &Point3<f64>, b: &Point3<f64>, f: f64, grad: &Vector3<f64>) -> Matrix3<f64> {
    let d = b - a;
    let len = d.norm();
    if len == 0.0 {
        return Matrix3::zeros();
    }
    let u = d / len;
    let uu = u * u.transpose();
    let mut h = uu * (grad.norm_squared() * 15.0 / 9.0);
    let ffl = f * grad.dot(&u);
    if ffl > 0.0 {
        h += (Matrix3::identity() - uu) * (ffl / len);
    }
    h
}

/// The cubic springs on every edge of the mesh, against its rest lengths, each weighted by its
/// share of the surface's area (`EdgeSet::area_weight`).
///
/// The normal equations carry the term's true curvature where it is positive, not only the
/// Gauss–Newton `JᵀJ`: with `c = w·F²` and `F` cubic in the strain, `∂²c/∂L² = 2w(F′² + F·F″)
/// = (15/9)·2wF′²` along the edge, and across it `∂c/∂L / L` when the edge is stretched
/// (a stretched spring resists turning about its end). So the model sees the springs as
/// stiffly as they are, and a step that lowers the model lowers the cost.
pub(crate) struct CubicSprings {
    edges: Arc<EdgeSet>,
    k: f64,
    t: f64,
}

impl CubicSprings {
    pub fn new(edges: Arc<EdgeSet>, k: f64, t: f64) -> Self {
        CubicSprings { edges, k, t }
    }
}

impl Regulariser for CubicSprings {
    fn name(&self) -> &'static str {
        "cubic_springs"
    }

    fn accumulate(&self, x: &[Point3<f64>], mut system: Option<System<'_>>) -> f64 {
        let mut cost = 0.0;
        let es = &*self.edges;
        for (e, ((edge, &rest), &w)) in es
            .edges
            .iter()
            .zip(&es.rest)
            .zip(&es.area_weight)
            .enumerate()
        {
            if rest <= 0.0 || w <= 0.0 {
                continue;
            }
            let [a, b] = edge.map(|v| v as usize);
            let (f, grad) = cubic_spring(&x[a], &x[b], rest, rest, self.k, self.t);
            cost += w * f * f;
            if let Some(sys) = system.as_mut() {
                let h = curvature(&x[a], &x[b], f, &grad) * w;
                EdgeSet::add_edge(sys, e, [a, b], &h, &(grad * (f * w)));
            }
        }
        cost
    }
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
    fn normal_equations_carry_the_true_curvature() {
        // A stretched edge (15 % over rest): the block added for (b, b) equals half the Hessian
        // of F² by central differences, along the edge and across it; compressed, the part
        // across (negative) is left out.
        let a = Point3::new(0.1, 0.2, -0.3);
        let rest = 1.0;
        for (stretch, across) in [(1.15, true), (0.85, false)] {
            let b = a + Vector3::new(0.6, 0.64, 0.48) * stretch;
            let c = |p: &Point3<f64>| cubic_spring(&a, p, rest, rest, 1.0, 0.1).0.powi(2);
            let (f, g) = cubic_spring(&a, &b, rest, rest, 1.0, 0.1);
            let h = curvature(&a, &b, f, &g);
            let eps = 1e-4;
            for i in 0..3 {
                for j in 0..3 {
                    let mut pp = b;
                    pp[i] += eps;
                    pp[j] += eps;
                    let mut pm = b;
                    pm[i] += eps;
                    pm[j] -= eps;
                    let mut mp = b;
                    mp[i] -= eps;
                    mp[j] += eps;
                    let mut mm = b;
                    mm[i] -= eps;
                    mm[j] -= eps;
                    let fd = (c(&pp) - c(&pm) - c(&mp) + c(&mm)) / (4.0 * eps * eps) / 2.0;
                    if across {
                        assert!(
                            (fd - h[(i, j)]).abs() < 1e-4 * (1.0 + fd.abs()),
                            "{i}{j}: {fd} vs {}",
                            h[(i, j)]
                        );
                    }
                }
            }
            // Along the edge the model is exact in both cases.
            let u = (b - a).normalize();
            let along = |p: f64| c(&(b + u * p));
            let fd = (along(eps) - 2.0 * along(0.0) + along(-eps)) / (eps * eps) / 2.0;
            let model = u.dot(&(h * u));
            assert!(
                (fd - model).abs() < 1e-4 * (1.0 + fd.abs()),
                "{fd} vs {model}"
            );
        }
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

//! The thesis' cubic edge springs (§5.1.1, §5.2.4, Eq. 5.16): each edge contributes the
//! residual `F = −k·Δd³/T²`. In the thesis' worked example (Eq. 5.17–5.20) `Δd` is the change of
//! length itself; the tracker measures it relative to the rest length (`Δd = (L − L₀)/L₀`, a
//! strain), which makes `T` exactly the "threshold ratio" the thesis describes (T = 0.1: soft
//! below 10 % stretch, stiff above) and makes `k` independent of scene units. [`cubic_spring`]
//! takes the normalising length so the worked example is reproduced with `scale = 1`. Each
//! edge is weighted by its share of the surface's area (the weights sum to 1), so the term
//! does not depend on how finely or how irregularly the surface is triangulated.

use super::{EdgeSet, FrameContext, Regulariser, System};
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

/// Where the springs yield: the strain (a fraction of the rest length) beyond which an edge's
/// spring follows the previous frame, and how far behind it then stands, as a fraction of that
/// strain (see [`spring_centre`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Yield {
    pub strain: f64,
    pub pull_back: f64,
    /// When at least this share of the edges was strained beyond twice the yield strain in
    /// the previous frame, the surface stretches (a bending elbow, a swelling lobe) and the
    /// pull-back is 0 for the frame; 0 = off (always `pull_back`). See [`pull_back_for`].
    pub stretch_share: f64,
}

/// The pull-back for a frame whose previous positions strain `beyond` of `edges` edges past
/// twice the yield strain: 0 once the surface shows that it stretches (`stretch_share` of its
/// edges or more), `y.pull_back` otherwise.
///
/// Why per shot and not per edge: where the images see an edge little, nothing local tells a
/// cloth's drift past the yield (which must be pulled back) from the fold in a bending elbow's
/// crook (which must not). What the images see well does tell the material: a cloth or a rigid
/// object never holds an edge at twice the yield (no edge of the hard sample, the real board or
/// the cloths does, at 320×240 neither), a limb bending or a lobe swelling holds hundreds.
pub(crate) fn pull_back_for(y: &Yield, beyond: usize, edges: usize) -> f64 {
    if y.stretch_share > 0.0 && beyond as f64 >= y.stretch_share * edges as f64 && beyond > 0 {
        0.0
    } else {
        y.pull_back
    }
}

/// The length an edge's spring pulls toward in a frame: its rest length, unless the edge was
/// stretched or compressed by more than the yield strain `y` in the previous frame; then the
/// previous frame's length, less `pull_back·y` toward the rest length (`None`: always the rest
/// length, as in the thesis).
///
/// Plastic flow, in the terms of materials: up to the yield strain the springs hold the surface
/// to its first frame's shape (tracking drift, which is small, is pulled back), beyond it they
/// follow a stretch that the images held in the previous frame (a swelling lobe, skin, rubber,
/// the outside of a bending elbow, and its inside, compressed), while still resisting a sudden
/// change from one frame to the next as the thesis' springs do. A stretch that the images give
/// up is not kept: the centre follows the previous frame back. With `pull_back` 1 (the default
/// while a shot shows no stretch, [`pull_back_for`]) a strain is also pulled back by the whole
/// yield every frame: a cloth's drift past the yield is undone, but what the images see little
/// (a bending elbow's crook) is held at the yield strain.
pub(crate) fn spring_centre(rest: f64, previous: f64, yielding: Option<Yield>) -> f64 {
    let Some(Yield {
        strain: y,
        pull_back,
        ..
    }) = yielding
    else {
        return rest;
    };
    let strain = (previous - rest) / rest;
    if !strain.is_finite() || strain.abs() <= y {
        return rest;
    }
    rest * (1.0 + strain.signum() * (strain.abs() - pull_back * y))
}

/// The cubic springs on every edge of the mesh, against its rest lengths (or, past the yield
/// strain, the lengths of [`spring_centre`]), each weighted by its share of the surface's area
/// (`EdgeSet::area_weight`). The strain is always measured over the rest length, so `T` keeps
/// its meaning.
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
    yielding: Option<Yield>,
    /// Each edge's length the spring pulls toward in this frame (`spring_centre`).
    centre: Vec<f64>,
}

impl CubicSprings {
    pub fn new(edges: Arc<EdgeSet>, k: f64, t: f64, yielding: Option<Yield>) -> Self {
        let centre = edges.rest.clone();
        CubicSprings {
            edges,
            k,
            t,
            yielding,
            centre,
        }
    }
}

impl Regulariser for CubicSprings {
    fn name(&self) -> &'static str {
        "cubic_springs"
    }

    fn begin_frame(&mut self, frame: &FrameContext<'_>) {
        let es = &*self.edges;
        let previous: Vec<f64> = es
            .edges
            .iter()
            .map(|&[a, b]| (frame.previous[b as usize] - frame.previous[a as usize]).norm())
            .collect();
        let yielding = self.yielding.map(|y| {
            let beyond = previous
                .iter()
                .zip(&es.rest)
                .filter(|&(&l, &rest)| rest > 0.0 && ((l - rest) / rest).abs() > 2.0 * y.strain)
                .count();
            Yield {
                pull_back: pull_back_for(&y, beyond, es.edges.len()),
                ..y
            }
        });
        for ((c, &l), &rest) in self.centre.iter_mut().zip(&previous).zip(&es.rest) {
            *c = spring_centre(rest, l, yielding);
        }
    }

    fn accumulate(&self, x: &[Point3<f64>], mut system: Option<System<'_>>) -> f64 {
        let mut cost = 0.0;
        let es = &*self.edges;
        for (e, (((edge, &rest), &w), &centre)) in es
            .edges
            .iter()
            .zip(&es.rest)
            .zip(&es.area_weight)
            .zip(&self.centre)
            .enumerate()
        {
            if rest <= 0.0 || w <= 0.0 {
                continue;
            }
            let [a, b] = edge.map(|v| v as usize);
            let (f, grad) = cubic_spring(&x[a], &x[b], centre, rest, self.k, self.t);
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
    fn past_the_yield_strain_the_spring_follows_the_previous_frame() {
        // Rest length 2, yield 5 %: within ±5 % the spring pulls to the rest length; an edge
        // held 30 % longer (2.6) pulls to that length (pull-back 0), or to 25 % longer (2.5)
        // with the whole yield pulled back; one held 20 % shorter to 1.6, or to 15 % (1.7).
        let y = |pull_back| {
            Some(Yield {
                strain: 0.05,
                pull_back,
                stretch_share: 0.0,
            })
        };
        for p in [0.0, 0.5, 1.0] {
            assert_eq!(spring_centre(2.0, 2.09, y(p)), 2.0);
            assert_eq!(spring_centre(2.0, 1.91, y(p)), 2.0);
        }
        assert_eq!(spring_centre(2.0, 2.6, y(0.0)), 2.6);
        assert_eq!(spring_centre(2.0, 1.6, y(0.0)), 1.6);
        assert!((spring_centre(2.0, 2.6, y(1.0)) - 2.5).abs() < 1e-12);
        assert!((spring_centre(2.0, 1.6, y(1.0)) - 1.7).abs() < 1e-12);
        assert!((spring_centre(2.0, 2.6, y(0.5)) - 2.55).abs() < 1e-12);
        // Off: the thesis' springs, always the rest length.
        assert_eq!(spring_centre(2.0, 2.6, None), 2.0);
        // A degenerate rest length or a non-finite previous length keeps the rest length.
        assert_eq!(spring_centre(0.0, 1.0, y(0.0)), 0.0);
        assert_eq!(spring_centre(2.0, f64::NAN, y(0.0)), 2.0);
    }

    #[test]
    fn the_pull_back_stops_once_enough_edges_are_held_past_twice_the_yield() {
        let y = Yield {
            strain: 0.05,
            pull_back: 1.0,
            stretch_share: 0.005,
        };
        // 1 000 edges: 4 beyond twice the yield is drift or a sliver; 5 is a surface that
        // stretches.
        assert_eq!(pull_back_for(&y, 0, 1000), 1.0);
        assert_eq!(pull_back_for(&y, 4, 1000), 1.0);
        assert_eq!(pull_back_for(&y, 5, 1000), 0.0);
        // Off: always the given pull-back.
        let off = Yield {
            stretch_share: 0.0,
            ..y
        };
        assert_eq!(pull_back_for(&off, 1000, 1000), 1.0);
        // And through the term: an edge held 40 % long among 99 at rest is past twice the
        // yield, so its spring is centred on its previous length and costs nothing there.
        let n = 100;
        let mut positions = Vec::new();
        let mut edges = Vec::new();
        for i in 0..n {
            positions.push(Point3::new(0.0, 2.0 * i as f64, 0.0));
            positions.push(Point3::new(1.0, 2.0 * i as f64, 0.0));
            edges.push([2 * i as u32, 2 * i as u32 + 1]);
        }
        let set = Arc::new(EdgeSet {
            edges,
            rest: vec![1.0; n],
            mean_length: 1.0,
            area_weight: vec![1.0 / n as f64; n],
        });
        let mut previous = positions.clone();
        previous[1].x = 1.4;
        let frame = FrameContext {
            previous: &previous,
            predicted: &previous,
            information: None,
        };
        for (share, expect_free) in [(0.01, true), (0.02, false)] {
            let mut s = CubicSprings::new(
                set.clone(),
                1.0,
                0.2,
                Some(Yield {
                    stretch_share: share,
                    ..y
                }),
            );
            s.begin_frame(&frame);
            let cost = s.accumulate(&previous, None);
            assert_eq!(cost == 0.0, expect_free, "share {share}: cost {cost}");
        }
    }

    #[test]
    fn an_edge_held_stretched_costs_little_the_next_frame_and_a_further_jump_still_costs() {
        // A unit edge the images held 40 % longer in the previous frame.
        let edges = Arc::new(EdgeSet {
            edges: vec![[0, 1]],
            rest: vec![1.0],
            mean_length: 1.0,
            area_weight: vec![1.0],
        });
        let previous = [Point3::origin(), Point3::new(1.4, 0.0, 0.0)];
        let frame = FrameContext {
            previous: &previous,
            predicted: &previous,
            information: None,
        };
        let cost = |yielding: Option<Yield>, length: f64| {
            let mut s = CubicSprings::new(edges.clone(), 1.0, 0.2, yielding);
            s.begin_frame(&frame);
            s.accumulate(&[Point3::origin(), Point3::new(length, 0.0, 0.0)], None)
        };
        let y = |pull_back| {
            Some(Yield {
                strain: 0.05,
                pull_back,
                stretch_share: 0.0,
            })
        };
        // Staying at 1.4 costs the thesis' springs F² = 0.4⁶/0.2⁴ = 2.56; nothing with the
        // default yield; and (0.05/0.4)⁶ of that with the whole yield pulled back (0.05 from
        // the centre at 1.35).
        assert!((cost(None, 1.4) - 2.56).abs() < 1e-12);
        assert_eq!(cost(y(0.0), 1.4), 0.0);
        assert!((cost(y(1.0), 1.4) - 2.56 / 8f64.powi(6)).abs() < 1e-15);
        // A further jump of 0.4 in one frame is resisted as the first 0.4 was from rest.
        assert!((cost(y(0.0), 1.8) - cost(None, 1.4)).abs() < 1e-12);
        assert!(cost(y(1.0), 1.8) > cost(None, 1.4));
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

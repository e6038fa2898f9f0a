//! Multi-view triangulation of one 3D point from its pixel positions in two or more calibrated
//! cameras: the linear DLT solution (Hartley & Zisserman §12.2, with rows scaled to unit norm and
//! world coordinates centred and scaled on the cameras), refined by Gauss–Newton on the
//! reprojection error. Used by the optical-flow baseline (`baseline`); each camera may be at a
//! different pose per frame, so callers pass the projection of each camera at the frame.
//!
//! Hand-written (on nalgebra) because it is a 4×4 SVD and a 3×3 solve; no crate offers the
//! N-view version with the project's `Projection`.

use crate::base::camera::Projection;
use nalgebra::{Matrix3, Matrix4, Point2, Point3, Vector3, Vector4};

/// A triangulated point and how well it explains its observations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangulated {
    pub point: Point3<f64>,
    /// Root mean square reprojection error in pixels over the observations.
    pub rms_error: f64,
    /// The largest reprojection error and the index of the observation that has it.
    pub worst: (usize, f64),
}

/// Reprojection errors (pixels) of `x` in each observation; `None` if behind a camera.
pub fn reprojection_errors(
    obs: &[(&Projection, Point2<f64>)],
    x: &Point3<f64>,
) -> Option<Vec<f64>> {
    obs.iter()
        .map(|(p, m)| p.project(x).map(|q| (q - m).norm()))
        .collect()
}

/// The linear (DLT) solution; `None` with fewer than two observations, for a degenerate
/// configuration (e.g. all rays through one centre) or a point at infinity.
pub fn dlt(obs: &[(&Projection, Point2<f64>)]) -> Option<Point3<f64>> {
    if obs.len() < 2 {
        return None;
    }
    // World normalisation X = c + s·X̃ on the camera centres, so the system is well scaled.
    let n = obs.len() as f64;
    let c = obs
        .iter()
        .fold(Vector3::zeros(), |a, (p, _)| a + p.center().coords)
        / n;
    let spread = obs
        .iter()
        .map(|(p, _)| (p.center().coords - c).norm())
        .sum::<f64>()
        / n;
    let s = if spread > 0.0 { spread } else { 1.0 };
    let mut t = Matrix4::identity() * s;
    t[(3, 3)] = 1.0;
    t.fixed_view_mut::<3, 1>(0, 3).copy_from(&c);
    // A^T A accumulated row by row (same null vector as A, and a fixed 4×4 size).
    let mut ata = Matrix4::<f64>::zeros();
    for (p, m) in obs {
        if !m.x.is_finite() || !m.y.is_finite() {
            return None;
        }
        let pt = p.matrix() * t;
        for (coord, row) in [(m.x, 0), (m.y, 1)] {
            let r: Vector4<f64> = (pt.row(2) * coord - pt.row(row)).transpose();
            let norm = r.norm();
            if norm == 0.0 {
                return None;
            }
            let r = r / norm;
            ata += r * r.transpose();
        }
    }
    let eig = ata.symmetric_eigen();
    let mut order = [0usize, 1, 2, 3];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    // Rank below 3 means the point is not pinned down (e.g. all rays coincide).
    if eig.eigenvalues[order[1]] <= 1e-14 * eig.eigenvalues[order[3]].max(f64::MIN_POSITIVE) {
        return None;
    }
    let h = t * eig.eigenvectors.column(order[0]);
    if h.w.abs() <= 1e-12 * h.xyz().norm() {
        return None;
    }
    Some(Point3::from(h.xyz() / h.w))
}

/// Gauss–Newton refinement of `x` on the sum of squared reprojection errors, at most
/// `iterations` steps, each accepted only if it lowers the cost (halving otherwise).
pub fn refine(
    obs: &[(&Projection, Point2<f64>)],
    mut x: Point3<f64>,
    iterations: usize,
) -> Point3<f64> {
    let cost = |x: &Point3<f64>| -> Option<f64> {
        obs.iter()
            .map(|(p, m)| p.project(x).map(|q| (q - m).norm_squared()))
            .sum()
    };
    let Some(mut current) = cost(&x) else {
        return x;
    };
    for _ in 0..iterations {
        let mut jtj = Matrix3::<f64>::zeros();
        let mut jtr = Vector3::<f64>::zeros();
        for (p, m) in obs {
            let pm = p.matrix();
            let h = p.project_h(&x);
            let (u, v) = (h.x / h.z, h.y / h.z);
            let r = [u - m.x, v - m.y];
            let p3: Vector3<f64> = pm.fixed_view::<1, 3>(2, 0).transpose();
            for (k, val) in [u, v].into_iter().enumerate() {
                let pk: Vector3<f64> = pm.fixed_view::<1, 3>(k, 0).transpose();
                let j = (pk - p3 * val) / h.z;
                jtj += j * j.transpose();
                jtr += j * r[k];
            }
        }
        let Some(step) = jtj.cholesky().map(|c| -c.solve(&jtr)) else {
            break;
        };
        let mut scale = 1.0;
        let mut accepted = false;
        for _ in 0..8 {
            let cand = x + step * scale;
            if let Some(c) = cost(&cand) {
                if c <= current {
                    x = cand;
                    current = c;
                    accepted = true;
                    break;
                }
            }
            scale *= 0.5;
        }
        if !accepted || step.norm() * scale <= 1e-13 * (1.0 + x.coords.norm()) {
            break;
        }
    }
    x
}

/// DLT followed by `iterations` Gauss–Newton steps. `None` with fewer than two observations, for
/// degenerate geometry, or when the point lands behind one of the cameras.
pub fn triangulate(obs: &[(&Projection, Point2<f64>)], iterations: usize) -> Option<Triangulated> {
    let x = refine(obs, dlt(obs)?, iterations);
    let errors = reprojection_errors(obs, &x)?;
    let rms_error = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let worst = errors
        .iter()
        .copied()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
    Some(Triangulated {
        point: x,
        rms_error,
        worst,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::camera::look_at;

    fn ring(n: usize, radius: f64) -> Vec<Projection> {
        let k = Matrix3::new(800.0, 0.0, 319.5, 0.0, 780.0, 239.5, 0.0, 0.0, 1.0);
        (0..n)
            .map(|i| {
                let a = i as f64 / n as f64 * 1.2 - 0.6;
                let eye = Point3::new(radius * a.sin(), -radius * a.cos(), 0.3 * i as f64);
                let (r, t) = look_at(&eye, &Point3::new(0.1, 0.0, 0.2), &Vector3::z());
                Projection::from_krt(&k, &r, &t).unwrap()
            })
            .collect()
    }

    #[test]
    fn exact_projections_give_the_point_to_1e9() {
        let cams = ring(4, 3.0);
        for x in [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.31, -0.27, 0.55),
            Point3::new(-0.4, 0.6, -0.2),
        ] {
            for n in [2, 3, 4] {
                let obs: Vec<_> = cams[..n]
                    .iter()
                    .map(|p| (p, p.project(&x).unwrap()))
                    .collect();
                let t = triangulate(&obs, 5).unwrap();
                assert!(
                    (t.point - x).norm() < 1e-9,
                    "{n} cams: {:?} vs {x:?}",
                    t.point
                );
                assert!(t.rms_error < 1e-6);
            }
        }
    }

    #[test]
    fn noisy_projections_stay_close_and_refinement_lowers_the_error() {
        let cams = ring(4, 3.0);
        let x = Point3::new(0.2, 0.1, 0.3);
        // Deterministic pseudo-noise of up to ±0.5 px.
        let mut state = 12345u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 1.0
        };
        let obs: Vec<_> = cams
            .iter()
            .map(|p| {
                let q = p.project(&x).unwrap();
                (p, Point2::new(q.x + noise(), q.y + noise()))
            })
            .collect();
        let lin = dlt(&obs).unwrap();
        let t = triangulate(&obs, 10).unwrap();
        // Half a pixel at 3 m with f = 800 is about 2 mm on the image plane.
        assert!(
            (t.point - x).norm() < 5e-3,
            "error {}",
            (t.point - x).norm()
        );
        let sq = |e: Vec<f64>| e.iter().map(|v| v * v).sum::<f64>();
        let before = sq(reprojection_errors(&obs, &lin).unwrap());
        let after = sq(reprojection_errors(&obs, &t.point).unwrap());
        assert!(after <= before + 1e-12, "{after} > {before}");
        assert!(t.rms_error < 0.5 && t.worst.1 >= t.rms_error);
    }

    #[test]
    fn degenerate_inputs_are_refused() {
        let cams = ring(2, 3.0);
        let x = Point3::new(0.1, 0.2, 0.3);
        let one = [(&cams[0], cams[0].project(&x).unwrap())];
        assert!(triangulate(&one, 5).is_none(), "one view is not enough");
        // The same camera twice: every ray passes through one centre.
        let same = [
            (&cams[0], cams[0].project(&x).unwrap()),
            (&cams[0], cams[0].project(&x).unwrap()),
        ];
        assert!(triangulate(&same, 5).is_none());
        let nan = [
            (&cams[0], Point2::new(f64::NAN, 1.0)),
            (&cams[1], cams[1].project(&x).unwrap()),
        ];
        assert!(triangulate(&nan, 5).is_none());
    }
}

//! The per-triangle homography warp of the thesis (Eq. 5.4–5.8) and its analytic derivative with
//! respect to the triangle's three 3D vertices in the next frame (Eq. 5.10–5.15).
//!
//! For a triangle seen by a camera, `S_cur = P_cur·V_cur` holds the *homogeneous* projections of
//! its vertices in the source frame (columns `P_cur·[X_i; 1]`, whose third entry is the depth).
//! Using the homogeneous columns instead of the normalised pixel positions makes
//! `λ = S_cur⁻¹·(u, v, 1)` the true (perspective-correct) barycentric coordinates of the surface
//! point seen at pixel `(u, v)`, so the warp `W = P_next·V_next·S_cur⁻¹` is exact for a planar
//! triangle under perspective. Per pixel, `h = W·(u, v, 1) = Σ_i λ_i·Y_i` with
//! `Y_i = P_next·[X_i; 1]`, and the warped pixel is `(h_x/h_z, h_y/h_z)`.
//!
//! The thesis precomputes nine 3×3 gradient matrices per triangle and camera,
//! `∂W/∂q_ik = M[:, k] ⊗ (row i of S_cur⁻¹)` where `M` is the left 3×3 block of `P_next`
//! ([`warp_gradients`]). Applied to a pixel they give `(∂W/∂q_ik)·(u, v, 1) = λ_i·M[:, k]`, so the
//! hot loop stores `λ` per pixel and uses that factorised form: the same derivative, nine times
//! fewer operations. A test checks the two against each other and against finite differences.

use crate::base::camera::Projection;
use nalgebra::{Matrix3, Point3, Vector3};

/// `S = P·V`: columns are the homogeneous projections of the triangle's vertices.
pub fn source_matrix(proj: &Projection, x: &[Point3<f64>; 3]) -> Matrix3<f64> {
    Matrix3::from_columns(&[
        proj.project_h(&x[0]),
        proj.project_h(&x[1]),
        proj.project_h(&x[2]),
    ])
}

// The thesis' matrix form, kept as the reference the solver's fused loop is tested against.
#[cfg(test)]
/// The warp `W = P_next·V_next·S_cur⁻¹` (Eq. 5.7), or `None` if `S_cur` is singular.
pub fn warp_matrix(
    s_cur: &Matrix3<f64>,
    next: &Projection,
    x_next: &[Point3<f64>; 3],
) -> Option<Matrix3<f64>> {
    Some(source_matrix(next, x_next) * s_cur.try_inverse()?)
}

// The thesis' matrix form, kept as the reference the solver's fused loop is tested against.
#[cfg(test)]
/// The nine gradient matrices `∂W/∂q` (Eq. 5.15), ordered vertex-major: index `3·i + k` is the
/// derivative with respect to coordinate `k` (x, y, z) of vertex `i`.
pub fn warp_gradients(s_cur_inv: &Matrix3<f64>, next: &Projection) -> [Matrix3<f64>; 9] {
    let m = next.matrix();
    std::array::from_fn(|ik| {
        let (i, k) = (ik / 3, ik % 3);
        m.fixed_view::<3, 1>(0, k) * s_cur_inv.row(i)
    })
}

/// Barycentric coordinates (summing to one) of the surface point seen at pixel `(u, v)`.
#[inline]
pub fn barycentric(s_cur_inv: &Matrix3<f64>, u: f64, v: f64) -> [f64; 3] {
    let l = s_cur_inv * Vector3::new(u, v, 1.0);
    let sum = l.x + l.y + l.z;
    [l.x / sum, l.y / sum, l.z / sum]
}

/// Homogeneous warped point `h = Σ λ_i·Y_i`.
#[inline]
pub fn warp_h(lambda: &[f64; 3], y: &[Vector3<f64>; 3]) -> Vector3<f64> {
    y[0] * lambda[0] + y[1] * lambda[1] + y[2] * lambda[2]
}

// The thesis' matrix form, kept as the reference the solver's fused loop is tested against.
#[cfg(test)]
/// Derivatives of the warped pixel: `∂û/∂X_i = λ_i·a` and `∂v̂/∂X_i = λ_i·b`, returned as
/// `(a, b)` for the point `h` (Eq. 5.11 with 5.13). `m` is the left 3×3 block of `P_next`.
#[inline]
pub fn pixel_derivatives(m: &Matrix3<f64>, h: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let inv = 1.0 / h.z;
    let (u, v) = (h.x * inv, h.y * inv);
    let r0 = m.row(0).transpose();
    let r1 = m.row(1).transpose();
    let r2 = m.row(2).transpose();
    ((r0 - r2 * u) * inv, (r1 - r2 * v) * inv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::camera::look_at;

    fn cams() -> (Projection, Projection) {
        let k = Matrix3::new(600.0, 0.0, 319.5, 0.0, 600.0, 239.5, 0.0, 0.0, 1.0);
        let (r0, t0) = look_at(
            &Point3::new(0.1, -2.0, 0.3),
            &Point3::origin(),
            &Vector3::z(),
        );
        let (r1, t1) = look_at(
            &Point3::new(0.4, -2.1, 0.2),
            &Point3::origin(),
            &Vector3::z(),
        );
        (
            Projection::from_krt(&k, &r0, &t0).unwrap(),
            Projection::from_krt(&k, &r1, &t1).unwrap(),
        )
    }

    fn tri(d: f64) -> [Point3<f64>; 3] {
        [
            Point3::new(-0.2, 0.0 + d, -0.1),
            Point3::new(0.25, 0.05, -0.05 + d),
            Point3::new(0.0, -0.1, 0.2),
        ]
    }

    #[test]
    fn warp_maps_surface_points_exactly_under_perspective() {
        let (cur, next) = cams();
        let xc = tri(0.0);
        let xn = tri(0.07);
        let s = source_matrix(&cur, &xc);
        let w = warp_matrix(&s, &next, &xn).unwrap();
        // A surface point with barycentrics (0.2, 0.5, 0.3) in both frames.
        let b = [0.2, 0.5, 0.3];
        let pc = Point3::from(xc[0].coords * b[0] + xc[1].coords * b[1] + xc[2].coords * b[2]);
        let pn = Point3::from(xn[0].coords * b[0] + xn[1].coords * b[1] + xn[2].coords * b[2]);
        let uc = cur.project(&pc).unwrap();
        let un = next.project(&pn).unwrap();
        let h = w * Vector3::new(uc.x, uc.y, 1.0);
        assert!(((h.x / h.z) - un.x).abs() < 1e-9 && ((h.y / h.z) - un.y).abs() < 1e-9);
        let l = barycentric(&s.try_inverse().unwrap(), uc.x, uc.y);
        for k in 0..3 {
            assert!((l[k] - b[k]).abs() < 1e-12);
        }
    }

    #[test]
    fn jacobian_matches_gradient_matrices_and_finite_differences() {
        let (cur, next) = cams();
        let xc = tri(0.0);
        let xn = tri(0.03);
        let s = source_matrix(&cur, &xc);
        let s_inv = s.try_inverse().unwrap();
        let (u, v) = (300.0, 250.0);
        let lambda = barycentric(&s_inv, u, v);
        let y = xn.map(|x| next.project_h(&x));
        let h = warp_h(&lambda, &y);
        let m: Matrix3<f64> = next.matrix().fixed_view::<3, 3>(0, 0).into_owned();
        let (a, b) = pixel_derivatives(&m, &h);
        let grads = warp_gradients(&s_inv, &next);
        let sp = Vector3::new(u, v, 1.0);
        let eps = 1e-6;
        for (ik, grad) in grads.iter().enumerate() {
            let (i, k) = (ik / 3, ik % 3);
            // Eq. 5.13 with the precomputed matrix: d(W·s)/dq = G·s; then the quotient rule (5.11).
            let hw = warp_matrix(&s, &next, &xn).unwrap() * sp;
            let dh = grad * sp;
            let du_g = (dh.x * hw.z - hw.x * dh.z) / (hw.z * hw.z);
            let dv_g = (dh.y * hw.z - hw.y * dh.z) / (hw.z * hw.z);
            // Finite differences of the full warp.
            let mut xp = xn;
            xp[i][k] += eps;
            let mut xm = xn;
            xm[i][k] -= eps;
            let f = |x: &[Point3<f64>; 3]| {
                let w = warp_matrix(&s, &next, x).unwrap();
                let h = w * sp;
                (h.x / h.z, h.y / h.z)
            };
            let (up, vp) = f(&xp);
            let (um, vm) = f(&xm);
            let (du_fd, dv_fd) = ((up - um) / (2.0 * eps), (vp - vm) / (2.0 * eps));
            let (du_a, dv_a) = (lambda[i] * a[k], lambda[i] * b[k]);
            let tol = 1e-5 * (1.0 + du_fd.abs().max(dv_fd.abs()));
            assert!(
                (du_a - du_fd).abs() < tol && (dv_a - dv_fd).abs() < tol,
                "q{ik}: {du_a} {du_fd} {dv_a} {dv_fd}"
            );
            assert!(
                (du_g - du_fd).abs() < tol && (dv_g - dv_fd).abs() < tol,
                "q{ik} (5.15): {du_g} {du_fd}"
            );
        }
    }
}

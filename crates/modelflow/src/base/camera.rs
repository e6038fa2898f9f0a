//! The camera model shared by the renderer, the tracker, the baseline and the report.
//!
//! Convention (the contract of `docs/conventions.md`): OpenCV pinhole. A world point `X` maps to
//! camera coordinates `x = R·X + t`; the camera looks down +z, image `u` grows to the right and `v`
//! grows downwards; the pixel is `(u, v) = (K·x)[0..2] / x_z`. Pixel centres sit at integer
//! coordinates: the top-left pixel's centre is `(0, 0)` and it covers `[-0.5, 0.5)²`.
//!
//! A camera may also have a [`Lens`] (distortion, see `lens`): its frames are then resampled
//! once at load into the pinhole image of the same `K`, and every stage works on that image
//! with the pinhole model above; the lens is kept for what must meet the raw frames (drawing on
//! them, rendering distorted footage).
//!
//! Internally every camera pose is a 3×4 projection matrix `P` (the thesis' P), normalised so that
//! its left 3×3 block has a positive determinant and a unit third row: then `(P·[X;1])_z` is the
//! point's depth along the optical axis, in world units.

use crate::base::lens::Lens;
use nalgebra::{Matrix3, Matrix3x4, Point2, Point3, Vector3, Vector4};

/// One camera pose at one frame: a normalised 3×4 projection matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct Projection {
    p: Matrix3x4<f64>,
    center: Point3<f64>,
}

/// Why a matrix is not a usable projection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProjectionError {
    /// Some entry is NaN or infinite.
    NonFinite,
    /// The left 3×3 block of P (K·R) is singular.
    Singular,
}

impl std::fmt::Display for ProjectionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ProjectionError::NonFinite => write!(f, "has a non-finite entry"),
            ProjectionError::Singular => {
                write!(f, "is singular (its left 3x3 block K*R has no inverse)")
            }
        }
    }
}

impl Projection {
    /// `P = K·[R | t]`. The caller validates K and R (see `scene`); this only checks that the
    /// product is finite and non-singular.
    pub fn from_krt(
        k: &Matrix3<f64>,
        r: &Matrix3<f64>,
        t: &Vector3<f64>,
    ) -> Result<Self, ProjectionError> {
        let mut rt = Matrix3x4::zeros();
        rt.fixed_view_mut::<3, 3>(0, 0).copy_from(r);
        rt.set_column(3, t);
        Self::from_matrix(&(k * rt))
    }

    /// From a 3×4 projection matrix given up to scale (and sign).
    pub fn from_matrix(p: &Matrix3x4<f64>) -> Result<Self, ProjectionError> {
        if p.iter().any(|v| !v.is_finite()) {
            return Err(ProjectionError::NonFinite);
        }
        let m: Matrix3<f64> = p.fixed_view::<3, 3>(0, 0).into_owned();
        let det = m.determinant();
        let row3 = m.row(2).norm();
        if !det.is_finite() || row3 == 0.0 || det.abs() <= 1e-12 * m.norm().powi(3) {
            return Err(ProjectionError::Singular);
        }
        let scale = det.signum() / row3;
        let p = p * scale;
        let m = m * scale;
        let minv = m.try_inverse().ok_or(ProjectionError::Singular)?;
        let center = Point3::from(-(minv * p.column(3)));
        Ok(Projection { p, center })
    }

    /// The calibration `K` (upper triangular, positive diagonal, `K[2][2] = 1`), rotation `R`
    /// and translation `t` with `P = K·[R | t]` up to a positive scale: what `from_krt` was
    /// given, for a matrix made from it. By RQ decomposition of `P`'s left 3×3 block, written
    /// here from nalgebra's QR (it has no RQ): with `J` the row reversal, `(J·M)ᵀ = Q·U` gives
    /// `M = (J·Uᵀ·J)·(J·Qᵀ)`, an upper triangular matrix times an orthogonal one.
    pub fn krt(&self) -> (Matrix3<f64>, Matrix3<f64>, Vector3<f64>) {
        let m: Matrix3<f64> = self.p.fixed_view::<3, 3>(0, 0).into_owned();
        let j = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
        let qr = (j * m).transpose().qr();
        let mut k = j * qr.r().transpose() * j;
        let mut r = j * qr.q().transpose();
        // M = (K·D)·(D·R) for D = diag(±1): make K's diagonal positive. `from_matrix` made
        // det M > 0, so R is then a rotation (det +1).
        for i in 0..3 {
            if k[(i, i)] < 0.0 {
                k.column_mut(i).neg_mut();
                r.row_mut(i).neg_mut();
            }
        }
        let s = k[(2, 2)];
        let k = k / s;
        let t = k
            .try_inverse()
            .map_or_else(Vector3::zeros, |ki| ki * self.p.column(3) / s);
        (k, r, t)
    }

    /// The normalised 3×4 matrix.
    pub fn matrix(&self) -> &Matrix3x4<f64> {
        &self.p
    }

    /// The camera centre in world coordinates.
    pub fn center(&self) -> Point3<f64> {
        self.center
    }

    /// Homogeneous image point `P·[X;1]`; its third entry is the depth.
    #[inline]
    pub fn project_h(&self, x: &Point3<f64>) -> Vector3<f64> {
        self.p * Vector4::new(x.x, x.y, x.z, 1.0)
    }

    /// Depth of a world point along the optical axis (negative behind the camera).
    #[inline]
    pub fn depth(&self, x: &Point3<f64>) -> f64 {
        self.project_h(x).z
    }

    /// Pixel coordinates of a world point, or `None` if it is not in front of the camera.
    #[inline]
    pub fn project(&self, x: &Point3<f64>) -> Option<Point2<f64>> {
        let h = self.project_h(x);
        (h.z > 0.0).then(|| Point2::new(h.x / h.z, h.y / h.z))
    }

    /// The same camera for an image downsampled by an integer `factor` (pixel `i` of the small
    /// image averages pixels `factor·i .. factor·i + factor - 1`). With centres at integer
    /// coordinates, `u_small = (u + 0.5) / factor - 0.5`.
    pub fn downscaled(&self, factor: u32) -> Projection {
        self.scaled(1.0 / factor as f64)
    }

    /// The same camera for an image enlarged by an integer `factor` (pixel `j` of the large
    /// image centred at `(j + 0.5) / factor - 0.5` of this one, the inverse of
    /// [`Projection::downscaled`]): `u_large = factor·(u + 0.5) - 0.5`.
    pub fn upscaled(&self, factor: u32) -> Projection {
        self.scaled(factor as f64)
    }

    /// The same camera for its image resampled by `s` about pixel centres at integers:
    /// `u' = s·(u + 0.5) - 0.5`.
    fn scaled(&self, s: f64) -> Projection {
        let off = 0.5 * s - 0.5;
        let a = Matrix3::new(s, 0.0, off, 0.0, s, off, 0.0, 0.0, 1.0);
        Projection {
            p: a * self.p,
            center: self.center,
        }
    }

    /// The same camera with its image shifted by `d` pixels (x right, y down): every point
    /// projects `d` further, `P' = T(d)·P`. A shift of the principal point, exact for pinhole
    /// images.
    pub fn shifted(&self, d: [f64; 2]) -> Projection {
        let a = Matrix3::new(1.0, 0.0, d[0], 0.0, 1.0, d[1], 0.0, 0.0, 1.0);
        Projection {
            p: a * self.p,
            center: self.center,
        }
    }
}

/// A calibrated camera over a sequence: its image size, its name and one pose per frame (or one
/// for all frames when it is static).
#[derive(Clone, Debug)]
pub struct Camera {
    pub name: String,
    pub width: u32,
    pub height: u32,
    first_frame: u32,
    poses: Vec<Projection>,
    /// The lens distortion of the raw frames (`None`: they are pinhole images already).
    pub lens: Option<Lens>,
    /// When, in frames, this camera records each frame relative to the frame's time (0: on
    /// time; 0.1: a tenth of a frame late). A rig that is not genlocked has a known sub-frame
    /// lag per camera; the tracker sees the surface moved along its velocity by that much.
    pub time_offset: f64,
    /// How long the shutter stays open, as a fraction of a frame (0: sharp images; 0.5: a
    /// 180° shutter). A moving surface is smeared along its motion over that time; the tracker
    /// compares each template and frame under their common smear (`tracker::smear`).
    pub shutter: f64,
    /// A rolling shutter's readout: how long, in frames, the sensor takes from its top row to
    /// its bottom row (0: a global shutter, every row at once; a webcam at 30 fps often reads
    /// for most of a frame). Row `y` of the raw frame (pixel centres at integers) is recorded
    /// at `time_offset + rolling_shutter·((y + 0.5)/height − 1/2)`: the middle row at the
    /// camera's own time ([`Camera::lag_at_row`]). The tracker sees each vertex where it was
    /// when its row was read (`tracker::solve::Lag`).
    pub rolling_shutter: f64,
}

impl Camera {
    /// A camera that does not move.
    pub fn fixed(name: impl Into<String>, width: u32, height: u32, pose: Projection) -> Self {
        Camera {
            name: name.into(),
            width,
            height,
            first_frame: 0,
            poses: vec![pose],
            lens: None,
            time_offset: 0.0,
            shutter: 0.0,
            rolling_shutter: 0.0,
        }
    }

    /// A moving camera with one pose per frame, starting at `first_frame`.
    pub fn moving(
        name: impl Into<String>,
        width: u32,
        height: u32,
        first_frame: u32,
        poses: Vec<Projection>,
    ) -> Self {
        assert!(!poses.is_empty(), "a camera needs at least one pose");
        Camera {
            name: name.into(),
            width,
            height,
            first_frame,
            poses,
            lens: None,
            time_offset: 0.0,
            shutter: 0.0,
            rolling_shutter: 0.0,
        }
    }

    /// The same camera with a lens (distortion of its raw frames).
    pub fn with_lens(mut self, lens: Option<Lens>) -> Self {
        self.lens = lens;
        self
    }

    /// Raw-frame pixel of a world point at `frame`: the pinhole projection, then the lens (if
    /// any). `None` behind the camera or beyond the lens model's range.
    pub fn project_raw(&self, frame: u32, x: &Point3<f64>) -> Option<Point2<f64>> {
        let p = self.at(frame).project(x)?;
        match &self.lens {
            Some(lens) => lens.distort_pixel(&p),
            None => Some(p),
        }
    }

    /// When, in frames after the frame's time, this camera records row `y` of its raw frame
    /// (pixel centres at integers): its `time_offset`, plus for a rolling shutter the row's
    /// place in the readout, centred on the middle row.
    pub fn lag_at_row(&self, y: f64) -> f64 {
        if self.rolling_shutter == 0.0 {
            return self.time_offset;
        }
        let h = self.height.max(1) as f64;
        let row = ((y + 0.5) / h).clamp(0.0, 1.0);
        self.time_offset + self.rolling_shutter * (row - 0.5)
    }

    /// When this camera records each of `positions` at `frame`, in frames: the row each
    /// projects to in the raw frame ([`Camera::lag_at_row`]). Empty when the camera records
    /// every point at the frame's own time (no `time_offset`, no rolling shutter); a point
    /// behind the camera or beyond its lens takes the middle row's time.
    pub fn lags(&self, frame: u32, positions: &[Point3<f64>]) -> Vec<f64> {
        if self.time_offset == 0.0 && self.rolling_shutter == 0.0 {
            return Vec::new();
        }
        if self.rolling_shutter == 0.0 {
            return vec![self.time_offset; positions.len()];
        }
        positions
            .iter()
            .map(|p| match self.project_raw(frame, p) {
                Some(q) => self.lag_at_row(q.y),
                None => self.time_offset,
            })
            .collect()
    }

    /// Whether this camera records some point other than at the frame's own time.
    pub fn records_late_or_early(&self) -> bool {
        self.time_offset != 0.0 || self.rolling_shutter != 0.0
    }

    /// Whether the camera has a pose per frame.
    pub fn is_moving(&self) -> bool {
        self.poses.len() > 1
    }

    /// The pose at `frame` (the last known pose past the end, the first before the start).
    pub fn at(&self, frame: u32) -> &Projection {
        if self.poses.len() == 1 {
            return &self.poses[0];
        }
        let i = frame.saturating_sub(self.first_frame) as usize;
        &self.poses[i.min(self.poses.len() - 1)]
    }

    /// The same camera with `pose` from `frame` on (the poses before it as they were): a camera
    /// found turned since it was calibrated (`tracker::steady`).
    pub(crate) fn with_pose_from(&self, frame: u32, pose: Projection) -> Camera {
        let first = self.first_frame.min(frame);
        let poses = (first..frame)
            .map(|f| self.at(f).clone())
            .chain(std::iter::once(pose))
            .collect();
        Camera {
            first_frame: first,
            poses,
            ..self.clone()
        }
    }

    /// The same camera with its images shifted by `d` pixels in every pose
    /// ([`Projection::shifted`]).
    pub fn shifted(&self, d: [f64; 2]) -> Camera {
        Camera {
            poses: self.poses.iter().map(|p| p.shifted(d)).collect(),
            ..self.clone()
        }
    }

    /// The same camera for pinhole images enlarged by an integer `factor` in every pose
    /// ([`Projection::upscaled`]); its size grows by as much. Without a lens: what is enlarged
    /// is the pinhole image the tracker compares, not the raw frame.
    pub fn enlarged(&self, factor: u32) -> Camera {
        Camera {
            width: self.width * factor,
            height: self.height * factor,
            poses: self.poses.iter().map(|p| p.upscaled(factor)).collect(),
            lens: None,
            ..self.clone()
        }
    }

    /// All poses (one for a fixed camera).
    pub fn poses(&self) -> &[Projection] {
        &self.poses
    }

    /// The first frame of the pose list.
    pub fn first_frame(&self) -> u32 {
        self.first_frame
    }

    /// Whether a pixel position lies inside the image (pixel centres at integers).
    #[inline]
    pub fn contains(&self, p: &Point2<f64>) -> bool {
        p.x >= -0.5
            && p.y >= -0.5
            && p.x < self.width as f64 - 0.5
            && p.y < self.height as f64 - 0.5
    }
}

/// `true` if `r` is a rotation matrix (orthonormal, determinant +1) within `tol`.
pub fn is_rotation(r: &Matrix3<f64>, tol: f64) -> bool {
    r.iter().all(|v| v.is_finite())
        && (r.transpose() * r - Matrix3::identity()).abs().max() <= tol
        && (r.determinant() - 1.0).abs() <= tol
}

/// A camera looking from `eye` at `target` with `up` roughly up in the image, as (R, t) in the
/// OpenCV convention (+z forward, +y down in the image).
pub fn look_at(
    eye: &Point3<f64>,
    target: &Point3<f64>,
    up: &Vector3<f64>,
) -> (Matrix3<f64>, Vector3<f64>) {
    let z = (target - eye).normalize();
    let x = z.cross(up).normalize();
    let y = z.cross(&x);
    let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    let t = -(r * eye.coords);
    (r, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn k_r_and_t_come_back_from_the_projection_matrix() {
        // A principal point off centre, non-square pixels, a skew-free K; any scale and sign of
        // the matrix gives the same camera back.
        let k = Matrix3::new(812.5, 0.0, 330.25, 0.0, 798.0, 241.75, 0.0, 0.0, 1.0);
        let r = nalgebra::Rotation3::from_scaled_axis(Vector3::new(0.3, -1.1, 0.45)).into_inner();
        let t = Vector3::new(0.2, -0.15, 2.7);
        let p = Projection::from_krt(&k, &r, &t).unwrap();
        for scaled in [
            p.clone(),
            Projection::from_matrix(&(p.matrix() * -3.5)).unwrap(),
        ] {
            let (k2, r2, t2) = scaled.krt();
            assert!((k2 - k).abs().max() < 1e-9, "{k2}");
            assert!((r2 - r).abs().max() < 1e-12, "{r2}");
            assert!((t2 - t).abs().max() < 1e-12, "{t2}");
        }
    }

    fn cam() -> Projection {
        let k = Matrix3::new(500.0, 0.0, 319.5, 0.0, 400.0, 239.5, 0.0, 0.0, 1.0);
        Projection::from_krt(&k, &Matrix3::identity(), &Vector3::new(0.0, 0.0, 2.0)).unwrap()
    }

    #[test]
    fn projects_with_exact_opencv_values() {
        let p = cam();
        // On the optical axis: the principal point.
        let c = p.project(&Point3::new(0.0, 0.0, 0.0)).unwrap();
        assert_eq!((c.x, c.y), (319.5, 239.5));
        // x = (0.2, -0.1, 2.0 + 0.5) -> u = 500*0.2/2.5 + 319.5 = 359.5, v = 400*(-0.1)/2.5 + 239.5 = 223.5
        let q = p.project(&Point3::new(0.2, -0.1, 0.5)).unwrap();
        assert!(
            (q.x - 359.5).abs() < 1e-12 && (q.y - 223.5).abs() < 1e-12,
            "{q:?}"
        );
        assert!((p.depth(&Point3::new(0.2, -0.1, 0.5)) - 2.5).abs() < 1e-12);
        assert!(
            p.project(&Point3::new(0.0, 0.0, -3.0)).is_none(),
            "behind the camera"
        );
        assert!((p.center() - Point3::new(0.0, 0.0, -2.0)).norm() < 1e-12);
    }

    #[test]
    fn matrix_up_to_scale_and_sign_gives_same_depth() {
        let p = cam();
        let q = Projection::from_matrix(&(p.matrix() * -3.7)).unwrap();
        let x = Point3::new(0.3, 0.2, 1.0);
        assert!((p.depth(&x) - q.depth(&x)).abs() < 1e-12);
        assert!((p.project(&x).unwrap() - q.project(&x).unwrap()).norm() < 1e-9);
    }

    #[test]
    fn singular_and_nonfinite_rejected() {
        let mut m = *cam().matrix();
        m[(0, 0)] = f64::NAN;
        assert_eq!(Projection::from_matrix(&m), Err(ProjectionError::NonFinite));
        let z = Matrix3x4::zeros();
        assert_eq!(Projection::from_matrix(&z), Err(ProjectionError::Singular));
    }

    #[test]
    fn downscaling_keeps_pixel_centres() {
        let p = cam();
        let x = Point3::new(0.13, 0.07, 0.4);
        let a = p.project(&x).unwrap();
        let b = p.downscaled(2).project(&x).unwrap();
        assert!((b.x - ((a.x + 0.5) / 2.0 - 0.5)).abs() < 1e-12);
        assert!((b.y - ((a.y + 0.5) / 2.0 - 0.5)).abs() < 1e-12);
    }

    #[test]
    fn an_enlarged_camera_sees_every_point_at_the_enlarged_images_pixel() {
        // Pixel centres at integers: pixel j of an image enlarged twice is centred at j/2 - 1/4
        // of the original, so a point at u lands at 2u + 1/2; the size doubles, the pose stays.
        let p = cam();
        let x = Point3::new(0.13, 0.07, 0.4);
        let a = p.project(&x).unwrap();
        let b = p.upscaled(2).project(&x).unwrap();
        assert!((b.x - (2.0 * a.x + 0.5)).abs() < 1e-9 && (b.y - (2.0 * a.y + 0.5)).abs() < 1e-9);
        // Exactly the inverse of `downscaled`.
        let back = p.upscaled(2).downscaled(2).project(&x).unwrap();
        assert!((back - a).norm() < 1e-9);
        let c = Camera::fixed("c", 320, 240, p.clone()).enlarged(2);
        assert_eq!((c.width, c.height), (640, 480));
        assert!((c.at(0).project(&x).unwrap() - b).norm() < 1e-12);
        assert_eq!(c.at(0).center(), p.center());
        assert!(c.lens.is_none());
    }

    #[test]
    fn a_shifted_camera_sees_every_point_that_far_over_and_keeps_its_pose() {
        // The shift the tracker gives a camera whose calibration disagrees with the others'
        // (`tracker::camera_shifts`): every point moves by exactly (dx, dy) pixels, x right and
        // y down, whatever its depth; the principal point moves by as much, R and t stay.
        let p = cam();
        let s = p.shifted([0.75, -0.25]);
        for x in [Point3::new(0.13, 0.07, 0.4), Point3::new(-0.3, 0.2, 2.5)] {
            let (a, b) = (p.project(&x).unwrap(), s.project(&x).unwrap());
            assert!((b.x - a.x - 0.75).abs() < 1e-9 && (b.y - a.y + 0.25).abs() < 1e-9);
        }
        let ((k0, r0, t0), (k1, r1, t1)) = (p.krt(), s.krt());
        assert!((k1[(0, 2)] - k0[(0, 2)] - 0.75).abs() < 1e-9);
        assert!((k1[(1, 2)] - k0[(1, 2)] + 0.25).abs() < 1e-9);
        assert!((r1 - r0).norm() < 1e-12 && (t1 - t0).norm() < 1e-9);
        assert_eq!(s.center(), p.center());
    }

    #[test]
    fn look_at_points_camera_at_target() {
        let (r, t) = look_at(
            &Point3::new(1.0, -3.0, 0.5),
            &Point3::origin(),
            &Vector3::z(),
        );
        assert!(is_rotation(&r, 1e-12));
        let xc = r * Vector3::zeros() + t;
        assert!(xc.x.abs() < 1e-12 && xc.y.abs() < 1e-12 && xc.z > 0.0);
        // World up (+z) appears upwards in the image, i.e. towards -v.
        let up = r * Vector3::new(0.0, 0.0, 1.0);
        assert!(up.y < 0.0);
    }
}

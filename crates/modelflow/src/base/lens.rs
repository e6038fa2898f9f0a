//! Lens distortion: the map between a pinhole camera's *ideal* pixel and the pixel a real lens
//! puts the same ray on, in OpenCV's two models, and the resampling that turns a distorted frame
//! into the pinhole frame every other stage works on (`docs/conventions.md`, "Lens distortion").
//!
//! - `opencv`: radial–tangential with optional rational, thin-prism and tilt terms, coefficients
//!   `(k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, τx, τy]]]])` exactly as
//!   `cv::projectPoints` takes them (4, 5, 8, 12 or 14 of them);
//! - `fisheye`: Kannala–Brandt, `(k1, k2, k3, k4)` as `cv::fisheye::projectPoints` takes them.
//!
//! Both act on normalised coordinates `(x, y) = (X/Z, Y/Z)` of the camera frame, and the camera
//! matrix `K` maps the distorted normalised point to the raw pixel, so a lens is `K` plus a model.
//! The inverse has no closed form: [`Lens::undistort_pixel`] solves it by Newton's method.
//! Written by hand: it is the camera model itself, and no maintained Rust crate implements
//! OpenCV's models.

use crate::base::image::RgbImage;
use nalgebra::{Matrix2, Matrix3, Point2, Vector2, Vector3};
use rayon::prelude::*;

/// A distortion model and its coefficients.
#[derive(Clone, Debug, PartialEq)]
pub enum Distortion {
    /// OpenCV's radial–tangential model; the given coefficients padded with zeros to 14, and how
    /// many were given (4, 5, 8, 12 or 14).
    OpenCv {
        coefficients: [f64; 14],
        given: usize,
    },
    /// OpenCV's fisheye model (Kannala–Brandt).
    Fisheye { coefficients: [f64; 4] },
}

impl Distortion {
    /// The model named as in the scene format (`"opencv"` or `"fisheye"`) with its coefficients,
    /// or the reason they do not fit it.
    pub fn new(model: &str, coefficients: &[f64]) -> Result<Distortion, String> {
        if let Some(i) = coefficients.iter().position(|c| !c.is_finite()) {
            return Err(format!(
                "coefficient {i} is {}, expected a finite number",
                coefficients[i]
            ));
        }
        match model {
            "opencv" => {
                if ![4, 5, 8, 12, 14].contains(&coefficients.len()) {
                    return Err(format!(
                        "the opencv model takes 4, 5, 8, 12 or 14 coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tau_x, tau_y]]]]), found {}",
                        coefficients.len()
                    ));
                }
                let mut c = [0.0; 14];
                c[..coefficients.len()].copy_from_slice(coefficients);
                Ok(Distortion::OpenCv {
                    coefficients: c,
                    given: coefficients.len(),
                })
            }
            "fisheye" => {
                let c: [f64; 4] = coefficients.try_into().map_err(|_| {
                    format!(
                        "the fisheye model takes 4 coefficients (k1, k2, k3, k4), found {}",
                        coefficients.len()
                    )
                })?;
                Ok(Distortion::Fisheye { coefficients: c })
            }
            other => Err(format!(
                "unknown model {other:?} (expected \"opencv\" or \"fisheye\")"
            )),
        }
    }

    /// The model's name in the scene format.
    pub fn model(&self) -> &'static str {
        match self {
            Distortion::OpenCv { .. } => "opencv",
            Distortion::Fisheye { .. } => "fisheye",
        }
    }

    /// The coefficients as given.
    pub fn coefficients(&self) -> Vec<f64> {
        match self {
            Distortion::OpenCv {
                coefficients,
                given,
            } => coefficients[..*given].to_vec(),
            Distortion::Fisheye { coefficients } => coefficients.to_vec(),
        }
    }

    /// Whether every coefficient is zero (the lens is a pinhole).
    pub fn is_identity(&self) -> bool {
        self.coefficients().iter().all(|&c| c == 0.0)
    }
}

impl std::str::FromStr for Distortion {
    type Err = String;

    /// `MODEL:c1,c2,...`, e.g. `opencv:-0.3,0.1,0,0,0` or `fisheye:0.05,-0.01,0,0`.
    fn from_str(s: &str) -> Result<Self, String> {
        let (model, list) = s.split_once(':').ok_or_else(|| {
            format!("{s:?}: expected MODEL:c1,c2,... (e.g. opencv:-0.3,0.1,0,0,0)")
        })?;
        let coefficients = list
            .split(',')
            .map(|c| {
                c.trim()
                    .parse::<f64>()
                    .map_err(|_| format!("{s:?}: {c:?} is not a number"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Distortion::new(model.trim(), &coefficients)
    }
}

/// A camera matrix with a distortion model: the map between ideal (pinhole) pixels and raw ones.
#[derive(Clone, Debug, PartialEq)]
pub struct Lens {
    k: Matrix3<f64>,
    k_inv: Matrix3<f64>,
    distortion: Distortion,
    /// OpenCV's tilt projection (identity unless τx or τy is given).
    tilt: Matrix3<f64>,
    /// The normalised radius up to which the radial part is increasing (the model is one-to-one);
    /// beyond it the polynomial folds back and the model means nothing.
    max_radius: f64,
}

/// Largest normalised radius considered (about 84° off axis): no lens of the two models is
/// calibrated beyond it.
const RADIUS_LIMIT: f64 = 10.0;

impl Lens {
    /// `k` must be invertible with a last row (0, 0, 1) (the scene reader checks it).
    pub fn new(k: Matrix3<f64>, distortion: Distortion) -> Lens {
        let k_inv = k.try_inverse().unwrap_or_else(Matrix3::identity);
        let tilt = match &distortion {
            Distortion::OpenCv { coefficients, .. } => {
                tilt_matrix(coefficients[12], coefficients[13])
            }
            Distortion::Fisheye { .. } => Matrix3::identity(),
        };
        let mut lens = Lens {
            k,
            k_inv,
            distortion,
            tilt,
            max_radius: RADIUS_LIMIT,
        };
        lens.max_radius = lens.monotonic_radius();
        lens
    }

    pub fn k(&self) -> &Matrix3<f64> {
        &self.k
    }

    pub fn distortion(&self) -> &Distortion {
        &self.distortion
    }

    /// The normalised radius `r = |(X/Z, Y/Z)|` up to which the model is one-to-one.
    pub fn max_radius(&self) -> f64 {
        self.max_radius
    }

    /// The distorted normalised point of an ideal normalised point `(X/Z, Y/Z)`, as OpenCV's
    /// `projectPoints` (or `fisheye::projectPoints`) computes it before applying `K`.
    pub fn distort_normalized(&self, p: Vector2<f64>) -> Vector2<f64> {
        let (x, y) = (p.x, p.y);
        match &self.distortion {
            Distortion::OpenCv {
                coefficients: k, ..
            } => {
                let r2 = x * x + y * y;
                let (r4, r6) = (r2 * r2, r2 * r2 * r2);
                let radial = (1.0 + k[0] * r2 + k[1] * r4 + k[4] * r6)
                    / (1.0 + k[5] * r2 + k[6] * r4 + k[7] * r6);
                let xd = x * radial
                    + 2.0 * k[2] * x * y
                    + k[3] * (r2 + 2.0 * x * x)
                    + k[8] * r2
                    + k[9] * r4;
                let yd = y * radial
                    + k[2] * (r2 + 2.0 * y * y)
                    + 2.0 * k[3] * x * y
                    + k[10] * r2
                    + k[11] * r4;
                let v = self.tilt * Vector3::new(xd, yd, 1.0);
                let s = if v.z != 0.0 { 1.0 / v.z } else { 1.0 };
                Vector2::new(v.x * s, v.y * s)
            }
            Distortion::Fisheye { coefficients: k } => {
                let r = (x * x + y * y).sqrt();
                if r < 1e-8 {
                    return p;
                }
                let t = r.atan();
                let t2 = t * t;
                let td = t * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
                p * (td / r)
            }
        }
    }

    /// The raw pixel on which the lens puts the ray of the ideal (pinhole) pixel `p`, or `None`
    /// where the ray lies beyond the model's one-to-one range.
    pub fn distort_pixel(&self, p: &Point2<f64>) -> Option<Point2<f64>> {
        let n = self.k_inv * Vector3::new(p.x, p.y, 1.0);
        let n = Vector2::new(n.x / n.z, n.y / n.z);
        if n.norm() > self.max_radius {
            return None;
        }
        let d = self.distort_normalized(n);
        let q = self.k * Vector3::new(d.x, d.y, 1.0);
        Some(Point2::new(q.x / q.z, q.y / q.z))
    }

    /// The ideal (pinhole) pixel whose ray the lens puts on raw pixel `q`, or `None` where no
    /// ray within the model's one-to-one range does (Newton's method on the normalised point,
    /// to 1e-12; `cv::undistortPoints` with enough iterations gives the same).
    pub fn undistort_pixel(&self, q: &Point2<f64>) -> Option<Point2<f64>> {
        let t = self.k_inv * Vector3::new(q.x, q.y, 1.0);
        let target = Vector2::new(t.x / t.z, t.y / t.z);
        let mut x = self.initial_guess(target);
        for _ in 0..50 {
            let f = self.distort_normalized(x) - target;
            if f.norm() < 1e-12 {
                break;
            }
            let j = self.jacobian(x);
            let step = j.try_inverse()? * f;
            // Stay inside the one-to-one range: halve steps that leave it.
            let mut next = x - step;
            let mut tries = 0;
            while next.norm() > self.max_radius && tries < 30 {
                next = x - step * 0.5f64.powi(tries + 1);
                tries += 1;
            }
            x = next;
        }
        if (self.distort_normalized(x) - target).norm() > 1e-9 || x.norm() > self.max_radius {
            return None;
        }
        let p = self.k * Vector3::new(x.x, x.y, 1.0);
        Some(Point2::new(p.x / p.z, p.y / p.z))
    }

    /// A start for Newton: the distorted point scaled back by the radial factor at its radius
    /// (one fixed-point step, as `cv::undistortPoints` begins).
    fn initial_guess(&self, target: Vector2<f64>) -> Vector2<f64> {
        let r = target.norm().min(self.max_radius);
        if r == 0.0 {
            return target;
        }
        // Solve |distort(s·u)| = r along the target's direction by bisection on s·|u|.
        let u = target / target.norm();
        let radial = |s: f64| self.distort_normalized(u * s).norm();
        let (mut lo, mut hi) = (0.0, self.max_radius);
        if radial(hi) < r {
            return u * hi;
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if radial(mid) < r {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        u * (0.5 * (lo + hi))
    }

    /// ∂distort/∂(x, y) by central differences (the model is smooth; 1e-7 gives ~1e-9 accuracy,
    /// ample for Newton's direction: convergence is checked on the residual itself).
    fn jacobian(&self, x: Vector2<f64>) -> Matrix2<f64> {
        let h = 1e-7;
        let dx = (self.distort_normalized(x + Vector2::new(h, 0.0))
            - self.distort_normalized(x - Vector2::new(h, 0.0)))
            / (2.0 * h);
        let dy = (self.distort_normalized(x + Vector2::new(0.0, h))
            - self.distort_normalized(x - Vector2::new(0.0, h)))
            / (2.0 * h);
        Matrix2::from_columns(&[dx, dy])
    }

    /// The first radius at which the radial map `r ↦ |distort(r, 0)|` stops increasing (or its
    /// rational denominator reaches zero), scanned in steps of 1e-3; [`RADIUS_LIMIT`] if never.
    fn monotonic_radius(&self) -> f64 {
        let radial = |r: f64| -> Option<f64> {
            match &self.distortion {
                Distortion::OpenCv {
                    coefficients: k, ..
                } => {
                    let r2 = r * r;
                    let den = 1.0 + k[5] * r2 + k[6] * r2 * r2 + k[7] * r2 * r2 * r2;
                    (den > 1e-6)
                        .then(|| r * (1.0 + k[0] * r2 + k[1] * r2 * r2 + k[4] * r2 * r2 * r2) / den)
                }
                Distortion::Fisheye { coefficients: k } => {
                    let t = r.atan();
                    let t2 = t * t;
                    Some(t * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])))))
                }
            }
        };
        const STEP: f64 = 1e-3;
        let mut prev = 0.0;
        let mut r = STEP;
        while r <= RADIUS_LIMIT {
            match radial(r) {
                Some(v) if v > prev => prev = v,
                _ => return r - STEP,
            }
            r += STEP;
        }
        RADIUS_LIMIT
    }
}

/// OpenCV's `computeTiltProjectionMatrix(τx, τy)`.
fn tilt_matrix(tau_x: f64, tau_y: f64) -> Matrix3<f64> {
    if tau_x == 0.0 && tau_y == 0.0 {
        return Matrix3::identity();
    }
    let (sx, cx) = tau_x.sin_cos();
    let (sy, cy) = tau_y.sin_cos();
    let rot_x = Matrix3::new(1.0, 0.0, 0.0, 0.0, cx, sx, 0.0, -sx, cx);
    let rot_y = Matrix3::new(cy, 0.0, -sy, 0.0, 1.0, 0.0, sy, 0.0, cy);
    let r = rot_y * rot_x;
    let proj_z = Matrix3::new(
        r[(2, 2)],
        0.0,
        -r[(0, 2)],
        0.0,
        r[(2, 2)],
        -r[(1, 2)],
        0.0,
        0.0,
        1.0,
    );
    proj_z * r
}

/// For every pixel of the pinhole (undistorted) image, where to read the raw frame: computed
/// once per camera, applied to every frame.
#[derive(Clone, Debug)]
pub struct UndistortMap {
    width: usize,
    height: usize,
    /// Raw-image position per output pixel, row-major; clamped into the raw image, so pixels
    /// whose ray the raw frame does not cover repeat its border.
    source: Vec<[f32; 2]>,
    /// How many output pixels have no ray in the raw frame (outside it or beyond the model's
    /// one-to-one range).
    uncovered: usize,
}

impl UndistortMap {
    /// The map of `lens` for images of `width × height` (the pinhole image has the raw image's
    /// size and camera matrix, as OpenCV's `initUndistortRectifyMap` with `newCameraMatrix = K`).
    pub fn new(lens: &Lens, width: usize, height: usize) -> UndistortMap {
        let (wm, hm) = ((width - 1) as f64, (height - 1) as f64);
        let rows: Vec<(Vec<[f32; 2]>, usize)> = (0..height)
            .into_par_iter()
            .map(|y| {
                let mut uncovered = 0;
                let row = (0..width)
                    .map(|x| {
                        let q = lens.distort_pixel(&Point2::new(x as f64, y as f64));
                        let q = match q {
                            Some(q)
                                if q.x >= -0.5
                                    && q.y >= -0.5
                                    && q.x <= wm + 0.5
                                    && q.y <= hm + 0.5 =>
                            {
                                q
                            }
                            Some(q) => {
                                uncovered += 1;
                                q
                            }
                            None => {
                                uncovered += 1;
                                // Beyond the model's range: the border along the same ray.
                                let c = Point2::new(lens.k[(0, 2)], lens.k[(1, 2)]);
                                let dir = Point2::new(x as f64, y as f64) - c;
                                c + dir * 1e6
                            }
                        };
                        [q.x.clamp(0.0, wm) as f32, q.y.clamp(0.0, hm) as f32]
                    })
                    .collect();
                (row, uncovered)
            })
            .collect();
        let uncovered = rows.iter().map(|(_, u)| u).sum();
        UndistortMap {
            width,
            height,
            source: rows.into_iter().flat_map(|(r, _)| r).collect(),
            uncovered,
        }
    }

    /// Share of the pinhole image that the raw frame does not cover (filled from its border).
    pub fn uncovered_share(&self) -> f64 {
        self.uncovered as f64 / (self.width * self.height).max(1) as f64
    }

    /// The pinhole image of a raw frame: each pixel sampled from the raw frame with Catmull–Rom
    /// bicubic interpolation (sharper than bilinear, which blurs by up to half a pixel depending
    /// on the phase). `raw` must have the map's size.
    pub fn apply(&self, raw: &RgbImage) -> RgbImage {
        assert_eq!(
            (raw.width(), raw.height()),
            (self.width, self.height),
            "undistortion map and image sizes differ"
        );
        remap(raw, &self.source, self.width, self.height)
    }
}

/// A `width × height` image whose pixel `i` is `from` sampled (Catmull–Rom) at `source[i]`,
/// rows in parallel.
fn remap(from: &RgbImage, source: &[[f32; 2]], width: usize, height: usize) -> RgbImage {
    let mut out = RgbImage::new(width, height);
    out.pixels_mut()
        .par_chunks_mut(width)
        .zip(source.par_chunks(width))
        .for_each(|(row, src)| {
            for (px, s) in row.iter_mut().zip(src) {
                *px = from.sample_cubic_value(s[0], s[1]);
            }
        });
    out
}

/// The other way round: for every pixel of a raw (distorted) frame, where to read a pinhole
/// image of the same camera. A renderer makes distorted footage with it: render the pinhole image
/// on a canvas large enough to hold every raw pixel's ray ([`DistortMap::canvas`]), then
/// [`DistortMap::apply`].
#[derive(Clone, Debug)]
pub struct DistortMap {
    width: usize,
    height: usize,
    /// Top-left pixel of the canvas in the pinhole image's coordinates, and its size.
    origin: (i64, i64),
    canvas: (usize, usize),
    /// Canvas position per raw pixel, row-major.
    source: Vec<[f32; 2]>,
}

impl DistortMap {
    /// The map of `lens` for raw frames of `width × height`. Raw pixels with no ray within the
    /// model's range read the canvas' nearest edge.
    pub fn new(lens: &Lens, width: usize, height: usize) -> DistortMap {
        let ideal: Vec<Option<Point2<f64>>> = (0..width * height)
            .into_par_iter()
            .map(|i| lens.undistort_pixel(&Point2::new((i % width) as f64, (i / width) as f64)))
            .collect();
        let (mut lo, mut hi) = (
            Point2::new(0.0f64, 0.0),
            Point2::new(width as f64 - 1.0, height as f64 - 1.0),
        );
        for p in ideal.iter().flatten() {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        // Two pixels of margin for the bicubic taps; the canvas never exceeds 4× the frame's side.
        let clamp = |v: f64, n: usize| v.clamp(-1.5 * n as f64, 2.5 * n as f64);
        let origin = (
            clamp(lo.x, width).floor() as i64 - 2,
            clamp(lo.y, height).floor() as i64 - 2,
        );
        let canvas = (
            (clamp(hi.x, width).ceil() as i64 + 3 - origin.0) as usize,
            (clamp(hi.y, height).ceil() as i64 + 3 - origin.1) as usize,
        );
        let (cw, ch) = ((canvas.0 - 1) as f64, (canvas.1 - 1) as f64);
        let source = ideal
            .iter()
            .map(|p| {
                let p = p.unwrap_or(Point2::new(-1e9, -1e9));
                [
                    (p.x - origin.0 as f64).clamp(0.0, cw) as f32,
                    (p.y - origin.1 as f64).clamp(0.0, ch) as f32,
                ]
            })
            .collect();
        DistortMap {
            width,
            height,
            origin,
            canvas,
            source,
        }
    }

    /// The pinhole canvas to render: the pixel `(0, 0)` of the canvas is pixel `origin` of the
    /// pinhole image, and it is `size` pixels large. Render it with the projection shifted by
    /// `-origin` (pixel centres at integers, so a pure translation).
    pub fn canvas(&self) -> ((i64, i64), (usize, usize)) {
        (self.origin, self.canvas)
    }

    /// The raw frame from a rendered canvas (Catmull–Rom bicubic).
    pub fn apply(&self, canvas: &RgbImage) -> RgbImage {
        assert_eq!(
            (canvas.width(), canvas.height()),
            self.canvas,
            "canvas size"
        );
        remap(canvas, &self.source, self.width, self.height)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k() -> Matrix3<f64> {
        Matrix3::new(800.0, 0.0, 319.5, 0.0, 780.0, 239.5, 0.0, 0.0, 1.0)
    }

    /// The projections of four points through each model, as OpenCV 5.0.0 (`opencv-python-headless`)
    /// computed them once: `cv2.projectPoints(X, rvec, tvec, K, d)` and
    /// `cv2.fisheye.projectPoints(X, rvec, tvec, K, d)` with `K = [[800, 0, 319.5], [0, 780, 239.5],
    /// [0, 0, 1]]`, `rvec = (0.1, -0.2, 0.05)`, `tvec = (0.05, -0.02, 2.0)` (the script is in
    /// `docs/scene-format.md`). Same numbers as the worked example there.
    #[test]
    fn projections_match_opencv() {
        use crate::base::camera::{Camera, Projection};
        use nalgebra::Point3;
        let r = Matrix3::new(
            0.9788428062071254,
            -0.0595199734937639,
            -0.1957655063893064,
            0.03960732051223486,
            0.9937772959432721,
            -0.10410545725138103,
            0.20074366963468865,
            0.0941491307606165,
            0.9751091837730888,
        );
        let t = Vector3::new(0.05, -0.02, 2.0);
        let points = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.3, -0.2, 0.1),
            Point3::new(-0.5, 0.4, -0.2),
            Point3::new(0.6, 0.5, 0.3),
        ];
        type Case<'a> = (&'a str, &'a [f64], [[f64; 2]; 4]);
        let cases: [Case; 4] = [
            (
                "opencv",
                &[-0.33, 0.12, 0.001, -0.0007, -0.02],
                [
                    [339.4937102613476, 231.70286015807446],
                    [443.6588689913291, 161.22680623330044],
                    [131.14560852996138, 403.45222292381726],
                    [493.0180493831025, 384.31307599402845],
                ],
            ),
            (
                "opencv",
                &[0.18, -0.1, 0.0005, 0.0003, 0.03, 0.05, -0.02, 0.01],
                [
                    [339.50215809087393, 231.69950895455915],
                    [445.7304411822317, 159.92458510436552],
                    [122.27764490905966, 411.2024320388358],
                    [499.93940825774087, 389.9940452243599],
                ],
            ),
            (
                "opencv",
                &[
                    -0.2, 0.05, 0.001, 0.002, 0.01, 0.02, 0.0, 0.005, 0.001, -0.002, 0.0015,
                    0.0005, 0.01, -0.02,
                ],
                [
                    [339.51215765549176, 231.70242464513765],
                    [444.6303310707608, 160.7562477501567],
                    [130.01686454103802, 404.75918905860044],
                    [496.22678014492385, 386.9023088065596],
                ],
            ),
            (
                "fisheye",
                &[0.05, -0.01, 0.002, -0.0005],
                [
                    [339.49589313782604, 231.70160167624783],
                    [443.9396257158823, 161.03483687894527],
                    [130.35726302940336, 404.10715277453687],
                    [493.7920536043516, 384.85108906141534],
                ],
            ),
        ];
        for (model, coefficients, want) in cases {
            let lens = Lens::new(k(), Distortion::new(model, coefficients).unwrap());
            let cam = Camera::fixed("c", 640, 480, Projection::from_krt(&k(), &r, &t).unwrap())
                .with_lens(Some(lens.clone()));
            for (x, w) in points.iter().zip(want) {
                let q = cam.project_raw(0, x).unwrap();
                assert!(
                    (q.x - w[0]).abs() < 1e-6 && (q.y - w[1]).abs() < 1e-6,
                    "{model} {coefficients:?}: {x} -> {q}, OpenCV {w:?}"
                );
                // And back: the ideal pixel is the pinhole projection.
                let ideal = cam.at(0).project(x).unwrap();
                let back = lens.undistort_pixel(&q).unwrap();
                assert!((back - ideal).norm() < 1e-6, "{back} vs {ideal}");
            }
        }
    }

    #[test]
    fn coefficient_counts_are_checked() {
        for n in [4, 5, 8, 12, 14] {
            assert!(Distortion::new("opencv", &vec![0.0; n]).is_ok(), "{n}");
        }
        let e = Distortion::new("opencv", &[0.1, 0.2, 0.3]).unwrap_err();
        assert!(
            e.contains("4, 5, 8, 12 or 14") && e.contains("found 3"),
            "{e}"
        );
        let e = Distortion::new("fisheye", &[0.1; 5]).unwrap_err();
        assert!(e.contains("4 coefficients") && e.contains("found 5"), "{e}");
        let e = Distortion::new("opencv", &[0.1, f64::NAN, 0.0, 0.0]).unwrap_err();
        assert!(e.contains("coefficient 1 is NaN"), "{e}");
        let e = Distortion::new("brown", &[0.0; 4]).unwrap_err();
        assert!(e.contains("unknown model \"brown\""), "{e}");
    }

    #[test]
    fn undistort_inverts_distort_for_every_model() {
        let models = [
            Distortion::new("opencv", &[-0.33, 0.12, 0.001, -0.0007, -0.02]).unwrap(),
            Distortion::new("opencv", &[0.18, -0.1, 0.0, 0.0, 0.03, 0.05, -0.02, 0.01]).unwrap(),
            Distortion::new(
                "opencv",
                &[
                    -0.2, 0.05, 0.001, 0.002, 0.0, 0.0, 0.0, 0.0, 0.001, -0.002, 0.0015, 0.0005,
                    0.01, -0.02,
                ],
            )
            .unwrap(),
            Distortion::new("fisheye", &[0.05, -0.01, 0.002, -0.0005]).unwrap(),
        ];
        for d in models {
            let lens = Lens::new(k(), d.clone());
            for &(u, v) in &[
                (0.0, 0.0),
                (319.5, 239.5),
                (639.0, 479.0),
                (100.0, 400.0),
                (600.0, 20.0),
            ] {
                let p = Point2::new(u, v);
                let q = lens.distort_pixel(&p).unwrap();
                let back = lens.undistort_pixel(&q).unwrap();
                assert!((back - p).norm() < 1e-6, "{d:?}: {p} -> {q} -> {back}");
            }
        }
    }

    #[test]
    fn barrel_distortion_folds_beyond_its_range() {
        // r(1 - 0.33 r² + ...) peaks near r = 1: beyond, two rays would share a pixel.
        let lens = Lens::new(
            k(),
            Distortion::new("opencv", &[-0.33, 0.0, 0.0, 0.0]).unwrap(),
        );
        let rmax = lens.max_radius();
        assert!(
            (rmax - (1.0f64 / (3.0 * 0.33)).sqrt()).abs() < 2e-3,
            "{rmax}"
        );
        let far = Point2::new(319.5 + 800.0 * (rmax + 0.1), 239.5);
        assert!(lens.distort_pixel(&far).is_none());
    }

    #[test]
    fn undistorting_a_distorted_image_gives_back_the_pinhole_image() {
        // A smooth pattern seen through a lens: the raw image at q shows the pinhole pattern at
        // undistort(q); the map must bring it back.
        let lens = Lens::new(
            k(),
            Distortion::new("opencv", &[-0.25, 0.08, 0.0005, -0.0005, 0.0]).unwrap(),
        );
        let pattern = |u: f64, v: f64| {
            [
                (0.5 + 0.4 * (u / 9.0).sin() * (v / 13.0).cos()) as f32,
                (0.5 + 0.4 * ((u + v) / 17.0).sin()) as f32,
                0.5,
            ]
        };
        let raw = RgbImage::from_fn(640, 480, |x, y| {
            let p = lens
                .undistort_pixel(&Point2::new(x as f64, y as f64))
                .unwrap();
            pattern(p.x, p.y)
        });
        let map = UndistortMap::new(&lens, 640, 480);
        let out = map.apply(&raw);
        let mut worst = 0.0f32;
        for y in 40..440 {
            for x in 40..600 {
                let want = pattern(x as f64, y as f64);
                let got = out.get(x, y);
                worst = worst
                    .max((want[0] - got[0]).abs())
                    .max((want[1] - got[1]).abs());
            }
        }
        assert!(worst < 0.01, "worst difference {worst}");
        // Barrel distortion with K kept: the raw frame covers all of the pinhole one.
        assert_eq!(map.uncovered_share(), 0.0);
    }
}

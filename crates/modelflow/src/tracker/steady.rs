//! Whether each camera still stands where it was calibrated. A knock on a tripod, a mount that
//! slips or a camera that sags turns it a fraction of a degree, and from then on every ray the
//! tracker casts through it is off by that turn: with two cameras the mesh slides along the
//! other camera's rays to where the two agree again, a consistent change of depth that no
//! comparison between the cameras can show. What does show it is everything that does not
//! move: the room behind the subject. Each frame, each static camera's view of its background
//! (its image outside the mesh's reach) is compared with its first frame's, and the turn about
//! its own centre that lines the two up is found (a rotation moves every background point the
//! same way whatever its depth, `H = K·ΔR·K⁻¹`). A turn that moves the image by more than
//! [`MOVED_PX`] from the one the tracker uses is taken: the camera's pose from that frame on is
//! the calibrated one turned by it (`Tracker::steady_cameras`).
//!
//! The comparison is a Gauss–Newton fit of the turn, a brightness gain and an offset (the
//! exposure may change), Huber-weighted and then Tukey-weighted at a scale taken from the
//! residuals' median (a person walking through the room, the hands holding the object and its
//! shadow are outliers), coarse level then fine (a knock past the coarse level's reach is found
//! by the background's best whole-pixel shift there, by normalised cross-correlation, and the
//! fit is taken again from it), on the pyramid levels the tracker builds
//! anyway, sampled on a grid of about [`SAMPLES`] background pixels (a quarter as many at the
//! coarser levels). It reads a turn only from a
//! background with texture: at least [`TEXTURED_SHARE`] of the samples must show a gradient,
//! spread in every direction at least [`TEXTURE_SPREAD`] as widely as the background itself,
//! the first frame's background must explain the frame's (correlation at least
//! [`MIN_CORRELATION`]: image noise has gradients everywhere, unrelated between frames), and
//! the turn must be held to a tenth of a pixel
//! (a plain studio wall gives no reading; a rod crossing a plain wall does not pass for the
//! room). Written for this project: no crate aligns
//! images by a camera's rotation with robust weights.

use crate::base::camera::{Camera, Projection};
use crate::base::image::RgbImage;
use nalgebra::{Matrix3, Rotation3, Vector3};

/// The image motion (RMS over the image, full-resolution pixels) between the turn the tracker
/// uses for a camera and the turn its background shows, above which the camera is taken to
/// have moved.
pub const MOVED_PX: f64 = 0.5;
/// The share of the background's samples that must show texture (a gradient above
/// [`TEXTURE_GRADIENT`]) for a reading, and the fewest such samples.
pub const TEXTURED_SHARE: f64 = 0.1;
const MIN_TEXTURED: usize = 100;
/// How widely the textured samples must be spread over the background: in every direction, the
/// standard deviation of their positions at least this share of all the background samples'
/// (1 for texture spread evenly over the background, 0.5 for texture over half of it, one side).
/// A room behind the subject is textured all over; a rod, a cable or a person crossing a plain
/// wall is textured along one band or in one blob, and its own motion would be read as the
/// camera's turn (the Blender hard sample tracked from its frame 16, where a rod stands beside
/// the object in one camera's first image, had that camera "turned" by 19 px and the mesh
/// lost: the rod spreads 0.08–0.14, a furnished room 0.86–1.02). Measured against the
/// background's own spread, so that a background reduced to a strip along one side by an
/// object filling the view still reads.
pub const TEXTURE_SPREAD: f64 = 0.35;
/// The least correlation between the first frame's background and this one's, where the fit
/// ends, for a reading. Heavy image noise (`synth --noise 0.08` over a plain grey wall) has
/// gradients everywhere and passes for texture, but two frames' noise is unrelated: the fit
/// turned the cameras by 1–3 px every frame, every frame was flagged suspect, and the
/// correlation there is −0.14 to 0.23. A real room, seen by real webcams, correlates at 0.9999
/// (the caliscope board's); noise as strong as a dim room's texture still leaves about 0.5.
const MIN_CORRELATION: f64 = 0.5;
/// A gradient (intensity per pixel at the level read) that counts as texture.
const TEXTURE_GRADIENT: f32 = 0.01;
/// About how many background pixels the finest level's comparison samples; the coarser levels,
/// which only have to tell whether anything moved, a quarter as many.
pub const SAMPLES: usize = 16_000;
/// The largest standard error of a reading (full-resolution pixels) that is taken, or its share
/// of the move it reads when that is larger.
const MAX_ERROR_PX: f64 = 0.1;
const MAX_ERROR_SHARE: f64 = 0.02;
/// How far (pixels of the coarse level, each way) and on how many background pixels a hard
/// knock is searched for when the coarse level finds the background moved.
const SHIFT_REACH: usize = 16;
const SHIFT_SAMPLES: usize = 1_000;
/// The finest level read is the first at most this wide.
const FINE_WIDTH: usize = 640;

/// A luminance image.
#[derive(Clone, Debug)]
struct Grey {
    width: usize,
    height: usize,
    data: Vec<f32>,
}

impl Grey {
    fn of(img: &RgbImage) -> Grey {
        Grey {
            width: img.width(),
            height: img.height(),
            data: img
                .pixels()
                .iter()
                .map(|p| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2])
                .collect(),
        }
    }

    #[inline]
    fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Bilinear value and gradient at `(x, y)` (pixel centres at integers); `None` within a
    /// pixel of the border.
    #[inline]
    fn sample(&self, x: f64, y: f64) -> Option<(f32, f32, f32)> {
        if !(x >= 1.0 && y >= 1.0 && x < (self.width - 2) as f64 && y < (self.height - 2) as f64) {
            return None;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let w = self.width;
        let d = &self.data;
        let i = y0 * w + x0;
        let (a, b, c, e) = (d[i], d[i + 1], d[i + w], d[i + w + 1]);
        let top = a + fx * (b - a);
        let bottom = c + fx * (e - c);
        let v = top + fy * (bottom - top);
        let gx = (b - a) + fy * ((e - c) - (b - a));
        let gy = bottom - top;
        Some((v, gx, gy))
    }
}

/// One camera's first-frame view, at the levels the check reads (finest first).
#[derive(Clone, Debug)]
pub(crate) struct Reference {
    /// `(pyramid level, its image)`, finest first.
    levels: Vec<(usize, Grey)>,
    /// The full-resolution intrinsics of the calibrated pose.
    k: Matrix3<f64>,
    /// Where the mesh was at the first frame (full-resolution window, widened): not background.
    first_window: Option<[f64; 4]>,
    /// The full-resolution image's width and height.
    size: (f64, f64),
    /// Whether the first frame's background shows enough texture at the finest level read to
    /// read a turn from (a plain studio wall does not: nothing is read, at no cost).
    textured: bool,
}

/// The pyramid levels read for images `width` wide out of `levels`: the first at most
/// [`FINE_WIDTH`] wide, and two coarser (or the coarsest there is).
pub(crate) fn levels_read(width: usize, levels: usize) -> Vec<usize> {
    let top = levels.max(1) - 1;
    let mut fine = 0;
    while fine < top && width >> fine > FINE_WIDTH {
        fine += 1;
    }
    let coarse = (fine + 2).min(top);
    if coarse == fine {
        vec![fine]
    } else {
        vec![fine, coarse]
    }
}

impl Reference {
    /// Camera's first frame: its pyramid levels, its calibrated pose, and the window its mesh
    /// covered (`None`: it saw none of it).
    pub(crate) fn new(
        levels: &[RgbImage],
        pose: &Projection,
        mesh_window: Option<[f64; 4]>,
    ) -> Reference {
        let width = levels.first().map_or(0, |l| l.width());
        let read = levels_read(width, levels.len());
        let first_window = mesh_window.map(widened);
        let size = levels
            .first()
            .map_or((0.0, 0.0), |l| (l.width() as f64, l.height() as f64));
        let levels: Vec<(usize, Grey)> = read
            .into_iter()
            .map(|l| (l, Grey::of(&levels[l])))
            .collect();
        let textured = levels.first().is_some_and(|(l, g)| {
            let scale = (1u32 << l) as f64;
            let skip: Vec<[f64; 4]> = first_window
                .iter()
                .map(|w| w.map(|v| (v + 0.5) / scale - 0.5))
                .collect();
            background_samples(g, &skip, SAMPLES, |_, _| ()).is_enough()
        });
        Reference {
            levels,
            textured,
            k: pose.krt().0,
            first_window,
            size,
        }
    }
}

/// `pose` turned by `turn` about the camera's centre (a rotation vector in its own axes):
/// `exp(turn)·R`, `exp(turn)·t`, the intrinsics kept.
pub(crate) fn turned(pose: &Projection, turn: &Vector3<f64>) -> Option<Projection> {
    let (k, r, t) = pose.krt();
    let q = Rotation3::new(*turn);
    Projection::from_krt(&k, &(q.matrix() * r), &(q * t)).ok()
}

/// `cameras` as a run used them: each one posed turned by the turns its frames' log lines give
/// (`FrameReport::camera_turns`, frame by frame in order; its pose at `first` is the calibrated
/// one), from the frame each turn was first used on. The images were taken with the cameras
/// turned, so whatever is drawn over them (the report's overlays) is drawn through these.
pub(crate) fn cameras_as_used(
    cameras: &[Camera],
    first: u32,
    turns: &[(u32, Vec<[f64; 3]>)],
) -> Vec<Camera> {
    let mut out = cameras.to_vec();
    let mut in_use = vec![[0.0; 3]; cameras.len()];
    for (frame, t) in turns {
        if t.len() != cameras.len() {
            continue;
        }
        for (c, turn) in t.iter().enumerate() {
            if *turn == in_use[c] || !turn.iter().all(|v| v.is_finite()) {
                continue;
            }
            if let Some(pose) = turned(cameras[c].at(first), &Vector3::from(*turn)) {
                out[c] = out[c].with_pose_from(*frame, pose);
                in_use[c] = *turn;
            }
        }
    }
    out
}

/// A mesh's window widened by a quarter of its size and 8 pixels each way: the hands that hold
/// an object and its shadow are near it.
pub(crate) fn widened(w: [f64; 4]) -> [f64; 4] {
    let (dx, dy) = (0.25 * (w[2] - w[0]) + 8.0, 0.25 * (w[3] - w[1]) + 8.0);
    [w[0] - dx, w[1] - dy, w[2] + dx, w[3] + dy]
}

/// What the background of one frame showed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Reading {
    /// The camera's turn since the first frame (rotation vector, radians, in its own frame:
    /// its new world-to-camera rotation is `exp(turn)·R`).
    pub turn: Vector3<f64>,
    /// The standard error of the image motion it gives, full-resolution pixels.
    pub error_px: f64,
}

/// The pixel map of a turn `r` at the level whose intrinsics are `k`.
fn homography(k: &Matrix3<f64>, k_inv: &Matrix3<f64>, r: &Matrix3<f64>) -> Matrix3<f64> {
    k * r * k_inv
}

/// The intrinsics at pyramid level `l` (`Projection::downscaled`'s pixel-centre convention).
fn level_k(k: &Matrix3<f64>, l: usize) -> Matrix3<f64> {
    let s = 1.0 / (1u32 << l) as f64;
    let off = 0.5 * s - 0.5;
    Matrix3::new(s, 0.0, off, 0.0, s, off, 0.0, 0.0, 1.0) * k
}

/// The RMS image motion, full-resolution pixels over a 5×5 grid of the `width × height` image,
/// between turns `a` and `b` of a camera with intrinsics `k`.
pub(crate) fn motion_px(
    k: &Matrix3<f64>,
    width: f64,
    height: f64,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
) -> f64 {
    let Some(k_inv) = k.try_inverse() else {
        return 0.0;
    };
    let ha = homography(k, &k_inv, Rotation3::new(*a).matrix());
    let hb = homography(k, &k_inv, Rotation3::new(*b).matrix());
    let mut sum = 0.0;
    for i in 0..5 {
        for j in 0..5 {
            let u = Vector3::new(
                (width - 1.0) * i as f64 / 4.0,
                (height - 1.0) * j as f64 / 4.0,
                1.0,
            );
            let (pa, pb) = (ha * u, hb * u);
            sum += (pa.xy() / pa.z - pb.xy() / pb.z).norm_squared();
        }
    }
    (sum / 25.0).sqrt()
}

/// Camera's turn since the first frame as its background shows it in `levels` (this frame's
/// pyramid), started from `start`, with `windows` (full-resolution, where the mesh may be now)
/// left out besides the first frame's (`just_moved`: the camera was found turned at the frame
/// before, so every level is read); `None` when the background shows too little texture to
/// tell (or the mesh covers it), or when it shows nothing moved.
pub(crate) fn read(
    reference: &Reference,
    levels: &[RgbImage],
    windows: &[[f64; 4]],
    start: Vector3<f64>,
    just_moved: bool,
) -> Option<Reading> {
    if !reference.textured {
        return None;
    }
    let mut skip: Vec<[f64; 4]> = windows.iter().map(|w| widened(*w)).collect();
    skip.extend(reference.first_window);
    let at = |l: usize| {
        let scale = (1u32 << l) as f64;
        let level_skip: Vec<[f64; 4]> = skip
            .iter()
            .map(|w| w.map(|v| (v + 0.5) / scale - 0.5))
            .collect();
        (level_k(&reference.k, l), level_skip)
    };
    let moved = |t: &Rotation3<f64>| {
        motion_px(
            &reference.k,
            reference.size.0,
            reference.size.1,
            &t.scaled_axis(),
            &start,
        )
    };
    let mut turn = Rotation3::new(start);
    let mut last = None;
    let mut coarse: Option<(Rotation3<f64>, Fit)> = None;
    let read_levels = reference.levels.len();
    // Coarse to fine.
    for (i, (l, refimg)) in reference.levels.iter().enumerate().rev() {
        let image = levels.get(*l)?;
        let img = Grey::of(image);
        if (img.width, img.height) != (refimg.width, refimg.height) {
            return None;
        }
        let (k, level_skip) = at(*l);
        let samples = if i == 0 { SAMPLES } else { SAMPLES / 4 };
        last = fit_level(refimg, &img, &k, &level_skip, samples, &mut turn);
        if i + 1 == read_levels && read_levels > 1 {
            // The coarse level: finding the background where the turn in use puts it (within
            // half of `MOVED_PX`) settles it, nothing moved; that is the common case. Not
            // right after the camera was found turned: a hard knock may have been read only
            // partly, and this level may hold on where that reading left it.
            if !just_moved && last.as_ref().is_some_and(usable) && moved(&turn) < 0.5 * MOVED_PX {
                return None;
            }
            // Something moved, maybe past this level's reach (a hard knock): the best shift of
            // the whole background here, searched pixel by pixel, then the same fit from there,
            // kept if it explains the background better.
            let shift = if last.as_ref().is_some_and(usable) {
                best_shift(refimg, &img, &k, &level_skip, &Rotation3::new(start))
            } else {
                None
            };
            if let Some((dx, dy)) = shift {
                // A shift of the image centre by (dx, dy) is the turn (−dy/fy, dx/fx, 0).
                let mut wide = Rotation3::new(Vector3::new(-dy / k[(1, 1)], dx / k[(0, 0)], 0.0))
                    * Rotation3::new(start);
                let from_wide = fit_level(refimg, &img, &k, &level_skip, samples, &mut wide);
                let better = match (&last, &from_wide) {
                    (_, None) => false,
                    (None, Some(_)) => true,
                    (Some(a), Some(b)) => b.residual < a.residual,
                };
                if better {
                    turn = wide;
                    last = from_wide;
                }
            }
            // What the finer level starts from, and what is read if it cannot tell (a knock
            // past its reach leaves it too far off: the next frame starts from this reading
            // and closes in).
            coarse = last
                .as_ref()
                .filter(|f| usable(f))
                .map(|f| (turn, f.clone()));
        }
    }
    let (turn, fit) = match last.filter(usable) {
        Some(fit) => (turn, fit),
        None => coarse?,
    };
    // The turn's standard error (radians: its covariance is σ² times the inverse of its
    // normal matrix), times the focal length: full-resolution pixels.
    let error_px = reference.k[(0, 0)] / fit.min_curvature.max(1e-300).sqrt();
    // Held to a tenth of a pixel, or to 2 % of a larger move (a hard knock read partly: the
    // next frame starts from it and closes in).
    let limit = MAX_ERROR_PX.max(MAX_ERROR_SHARE * moved(&turn));
    (error_px <= limit).then(|| Reading {
        turn: turn.scaled_axis(),
        error_px,
    })
}

/// How far, in whole pixels of `img` up to [`SHIFT_REACH`] each way, the background moved from
/// where `turn` puts it: the shift whose samples correlate best with the reference's (normalised
/// cross-correlation, so brightness does not matter). `None` without enough background.
fn best_shift(
    reference: &Grey,
    img: &Grey,
    k: &Matrix3<f64>,
    skip: &[[f64; 4]],
    turn: &Rotation3<f64>,
) -> Option<(f64, f64)> {
    let k_inv = k.try_inverse()?;
    let mut points: Vec<(f64, f64, f64)> = Vec::new();
    background_samples(reference, skip, SHIFT_SAMPLES, |x, y| {
        let p = k * (turn * (k_inv * Vector3::new(x as f64, y as f64, 1.0)));
        if p.z > 0.0 {
            points.push((p.x / p.z, p.y / p.z, reference.at(x, y) as f64));
        }
    });
    if points.len() < MIN_TEXTURED {
        return None;
    }
    let n = points.len() as f64;
    let mean_v = points.iter().map(|p| p.2).sum::<f64>() / n;
    let var_v = points.iter().map(|p| (p.2 - mean_v).powi(2)).sum::<f64>();
    let reach = SHIFT_REACH as i32;
    let mut best: Option<(f64, f64, f64)> = None;
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            let (mut si, mut sii, mut svi, mut m) = (0.0, 0.0, 0.0, 0.0);
            for (x, y, v) in &points {
                if let Some((i, _, _)) = img.sample(x + dx as f64, y + dy as f64) {
                    let i = i as f64;
                    si += i;
                    sii += i * i;
                    svi += (v - mean_v) * i;
                    m += 1.0;
                }
            }
            // Most of the background must still be in view.
            if m < 0.5 * n {
                continue;
            }
            let var_i = sii - si * si / m;
            let ncc = svi / (var_i * var_v).max(1e-300).sqrt();
            if best.is_none_or(|b| ncc > b.2) {
                best = Some((dx as f64, dy as f64, ncc));
            }
        }
    }
    best.map(|(dx, dy, _)| (dx, dy))
}

/// Whether a fit saw enough textured background to read a turn from, and whether what it saw
/// was the background rather than the images' noise: the first frame's background correlates
/// with this one's at least [`MIN_CORRELATION`] where the fit ended.
fn usable(fit: &Fit) -> bool {
    fit.enough_texture && fit.correlation >= MIN_CORRELATION
}

/// What a level's background samples show of texture.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Texture {
    /// Background samples.
    count: usize,
    /// Those with a gradient above [`TEXTURE_GRADIENT`].
    textured: usize,
    /// How widely the textured samples are spread over the background: the smallest, over
    /// directions, of their positions' standard deviation over all the background samples'
    /// (the square root of the smaller generalised eigenvalue of the two covariances).
    spread: f64,
}

impl Texture {
    /// Enough texture, spread widely enough over the background, to read a turn from: at
    /// least [`MIN_TEXTURED`] textured samples, [`TEXTURED_SHARE`] of the background's, spread
    /// by [`TEXTURE_SPREAD`].
    fn is_enough(&self) -> bool {
        self.textured >= MIN_TEXTURED
            && self.textured as f64 >= TEXTURED_SHARE * self.count as f64
            && self.spread >= TEXTURE_SPREAD
    }
}

/// Running first and second moments of 2-D positions (about a fixed origin).
#[derive(Clone, Copy, Default)]
struct Moments {
    n: f64,
    x: f64,
    y: f64,
    xx: f64,
    yy: f64,
    xy: f64,
}

impl Moments {
    fn add(&mut self, x: f64, y: f64) {
        self.n += 1.0;
        self.x += x;
        self.y += y;
        self.xx += x * x;
        self.yy += y * y;
        self.xy += x * y;
    }

    /// The covariance `(cxx, cyy, cxy)`.
    fn covariance(&self) -> (f64, f64, f64) {
        let n = self.n.max(1.0);
        let (mx, my) = (self.x / n, self.y / n);
        (
            self.xx / n - mx * mx,
            self.yy / n - my * my,
            self.xy / n - mx * my,
        )
    }
}

/// The square root of the smaller `λ` of `det(A − λ·B) = 0` for the 2×2 covariances `a` (the
/// textured samples') and `b` (all the background's): the least, over directions `v`, of
/// `sqrt(vᵀAv / vᵀBv)`. 0 when `b` is degenerate (the background a single line of samples).
fn relative_spread(a: (f64, f64, f64), b: (f64, f64, f64)) -> f64 {
    let det_a = a.0 * a.1 - a.2 * a.2;
    let det_b = b.0 * b.1 - b.2 * b.2;
    if det_b <= 1e-12 * (b.0 + b.1).powi(2).max(1e-300) {
        return 0.0;
    }
    let trace = a.0 * b.1 + a.1 * b.0 - 2.0 * a.2 * b.2;
    let disc = (trace * trace - 4.0 * det_a * det_b).max(0.0);
    ((trace - disc.sqrt()) / (2.0 * det_b)).max(0.0).sqrt()
}

/// What one level's fit left.
#[derive(Clone, Debug)]
struct Fit {
    /// Whether its background showed enough texture, spread widely enough
    /// ([`Texture::is_enough`]).
    enough_texture: bool,
    /// The median absolute residual where the fit ended (gain and offset applied).
    residual: f64,
    /// The smallest eigenvalue of the turn's weighted normal matrix over the residuals'
    /// robust scale squared (per radian²): the turn's standard error is one over its root.
    min_curvature: f64,
    /// How well the first frame's background explains this one's where the fit ended: the
    /// correlation of their values over the samples within the robust cutoff
    /// ([`correlation`]).
    correlation: f64,
}

/// Gauss–Newton over the turn (three parameters, applied on the left), a gain and an offset at
/// one level; `turn` updated in place. `None` when too few background samples remain.
fn fit_level(
    reference: &Grey,
    img: &Grey,
    k: &Matrix3<f64>,
    skip: &[[f64; 4]],
    samples_wanted: usize,
    turn: &mut Rotation3<f64>,
) -> Option<Fit> {
    let k_inv = k.try_inverse()?;
    // The background samples: their rays and reference values.
    let mut samples: Vec<(Vector3<f64>, f32)> = Vec::new();
    let texture = background_samples(reference, skip, samples_wanted, |x, y| {
        samples.push((
            k_inv * Vector3::new(x as f64, y as f64, 1.0),
            reference.at(x, y),
        ))
    });
    if samples.len() < MIN_TEXTURED {
        return None;
    }
    let (mut gain, mut offset) = (1.0f64, 0.0f64);
    let mut min_curvature = 0.0;
    let mut residuals: Vec<f64> = Vec::with_capacity(samples.len());
    const ITERATIONS: usize = 6;
    for it in 0..ITERATIONS {
        // The residuals' median at the current estimate, for the scale.
        let r_mat = *turn.matrix();
        let median = median_residual(&samples, img, k, &r_mat, gain, offset, &mut residuals)?;
        let sigma = (1.4826 * median).max(1e-3);
        let tukey = it >= 2;
        let c = if tukey { 4.685 * sigma } else { 1.345 * sigma };
        // Normal equations over (δ turn, gain, offset).
        let mut am = nalgebra::Matrix5::<f64>::zeros();
        let mut g = nalgebra::Vector5::<f64>::zeros();
        for (ray, v) in &samples {
            let q = r_mat * ray;
            let p = k * q;
            if p.z <= 0.0 {
                continue;
            }
            let Some((i, gx, gy)) = img.sample(p.x / p.z, p.y / p.z) else {
                continue;
            };
            let r = i as f64 - gain * *v as f64 - offset;
            let wgt = if tukey {
                if r.abs() >= c {
                    continue;
                }
                let t = 1.0 - (r / c) * (r / c);
                t * t
            } else if r.abs() <= c {
                1.0
            } else {
                c / r.abs()
            };
            // d(pixel)/d(p) then d(p)/dδ = −K·[q]×.
            let iz = 1.0 / p.z;
            let du = [iz, 0.0, -p.x * iz * iz];
            let dv = [0.0, iz, -p.y * iz * iz];
            let (gx, gy) = (gx as f64, gy as f64);
            let dp = [
                gx * du[0] + gy * dv[0],
                gx * du[1] + gy * dv[1],
                gx * du[2] + gy * dv[2],
            ];
            // Row vector dp·K, then times −[q]×: (dp·K) × q... written out: (dpK)·(−[q]×) =
            // (q × (dpK)ᵀ)ᵀ.
            let dpk = Vector3::new(
                dp[0] * k[(0, 0)] + dp[1] * k[(1, 0)] + dp[2] * k[(2, 0)],
                dp[0] * k[(0, 1)] + dp[1] * k[(1, 1)] + dp[2] * k[(2, 1)],
                dp[0] * k[(0, 2)] + dp[1] * k[(1, 2)] + dp[2] * k[(2, 2)],
            );
            let jt = q.cross(&dpk);
            let j = nalgebra::Vector5::new(jt.x, jt.y, jt.z, -(*v as f64), -1.0);
            g += j * (wgt * r);
            am.ger(wgt, &j, &j, 1.0);
        }
        let turn_block = am.fixed_view::<3, 3>(0, 0).into_owned();
        min_curvature = turn_block
            .symmetric_eigenvalues()
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
            / (sigma * sigma);
        let damped = am + nalgebra::Matrix5::from_diagonal(&(am.diagonal() * 1e-6));
        let step = damped.cholesky()?.solve(&-g);
        *turn = Rotation3::new(Vector3::new(step[0], step[1], step[2])) * *turn;
        gain += step[3];
        offset += step[4];
        // Converged once the step moves the image by under a fiftieth of a pixel.
        if Vector3::new(step[0], step[1], step[2]).norm() * k[(0, 0)] < 0.02 {
            break;
        }
    }
    let residual = median_residual(
        &samples,
        img,
        k,
        turn.matrix(),
        gain,
        offset,
        &mut residuals,
    )?;
    let cutoff = 4.685 * (1.4826 * residual).max(1e-3);
    Some(Fit {
        enough_texture: texture.is_enough(),
        residual,
        min_curvature,
        correlation: correlation(&samples, img, k, turn.matrix(), gain, offset, cutoff),
    })
}

/// The correlation (Pearson) of `samples`' reference values with `img`'s at turn `r`, over the
/// samples whose residual (`gain` and `offset` applied) is within `cutoff` (the outliers, a
/// person walking through, left out as the fit leaves them out); 0 without variance.
fn correlation(
    samples: &[(Vector3<f64>, f32)],
    img: &Grey,
    k: &Matrix3<f64>,
    r: &Matrix3<f64>,
    gain: f64,
    offset: f64,
    cutoff: f64,
) -> f64 {
    let (mut n, mut sv, mut si, mut svv, mut sii, mut svi) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (v, i) in landed(samples, img, k, r) {
        if (i - gain * v - offset).abs() > cutoff {
            continue;
        }
        n += 1.0;
        sv += v;
        si += i;
        svv += v * v;
        sii += i * i;
        svi += v * i;
    }
    if n < 2.0 {
        return 0.0;
    }
    let cov = svi - sv * si / n;
    let (var_v, var_i) = (svv - sv * sv / n, sii - si * si / n);
    if var_v <= 0.0 || var_i <= 0.0 {
        return 0.0;
    }
    cov / (var_v * var_i).sqrt()
}

/// Visits `img`'s background samples (`each(x, y)`): about `wanted` of its pixels off every
/// window in `skip`, however much of the image those cover (disjoint windows: somewhat fewer),
/// at least 2 pixels from the border; returns how many, how many show texture (a gradient
/// above [`TEXTURE_GRADIENT`]) and how widely those are spread.
fn background_samples(
    img: &Grey,
    skip: &[[f64; 4]],
    wanted: usize,
    mut each: impl FnMut(usize, usize),
) -> Texture {
    let (w, h) = (img.width, img.height);
    let clipped = |s: &[f64; 4]| {
        let (x0, x1) = (s[0].max(0.0), s[2].min(w as f64));
        let (y0, y1) = (s[1].max(0.0), s[3].min(h as f64));
        (x1 - x0).max(0.0) * (y1 - y0).max(0.0)
    };
    // The windows are mostly the same object's, one inside another: the largest is taken out.
    let area =
        ((w * h) as f64 - skip.iter().map(clipped).fold(0.0, f64::max)).max((w * h) as f64 / 16.0);
    let stride = ((area / wanted as f64).sqrt().round() as usize).max(1);
    let (mut count, mut textured) = (0, 0);
    // The positions' moments (about the image centre), all samples' and the textured ones'.
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    let (mut all, mut tex) = (Moments::default(), Moments::default());
    for y in (2..h.saturating_sub(2)).step_by(stride) {
        for x in (2..w.saturating_sub(2)).step_by(stride) {
            let (xf, yf) = (x as f64, y as f64);
            if skip
                .iter()
                .any(|s| xf >= s[0] && xf <= s[2] && yf >= s[1] && yf <= s[3])
            {
                continue;
            }
            let gx = 0.5 * (img.at(x + 1, y) - img.at(x - 1, y));
            let gy = 0.5 * (img.at(x, y + 1) - img.at(x, y - 1));
            if gx.abs().max(gy.abs()) > TEXTURE_GRADIENT {
                textured += 1;
                tex.add(xf - cx, yf - cy);
            }
            all.add(xf - cx, yf - cy);
            count += 1;
            each(x, y);
        }
    }
    let spread = if textured == 0 {
        0.0
    } else {
        relative_spread(tex.covariance(), all.covariance())
    };
    Texture {
        count,
        textured,
        spread,
    }
}

/// Each of `samples` (rays and reference values) that turn `r` puts inside `img`: its reference
/// value and `img`'s value there (bilinear).
fn landed<'a>(
    samples: &'a [(Vector3<f64>, f32)],
    img: &'a Grey,
    k: &'a Matrix3<f64>,
    r: &'a Matrix3<f64>,
) -> impl Iterator<Item = (f64, f64)> + 'a {
    samples.iter().filter_map(move |(ray, v)| {
        let p = k * (r * ray);
        if p.z <= 0.0 {
            return None;
        }
        let (i, _, _) = img.sample(p.x / p.z, p.y / p.z)?;
        Some((*v as f64, i as f64))
    })
}

/// The median absolute residual of `samples` (rays and reference values) against `img` with
/// turn `r`, `gain` and `offset`; `None` when fewer than [`MIN_TEXTURED`] land in the image.
fn median_residual(
    samples: &[(Vector3<f64>, f32)],
    img: &Grey,
    k: &Matrix3<f64>,
    r: &Matrix3<f64>,
    gain: f64,
    offset: f64,
    residuals: &mut Vec<f64>,
) -> Option<f64> {
    residuals.clear();
    residuals.extend(landed(samples, img, k, r).map(|(v, i)| (i - gain * v - offset).abs()));
    if residuals.len() < MIN_TEXTURED {
        return None;
    }
    let mid = residuals.len() / 2;
    residuals.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    Some(residuals[mid])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{Bump, SynthOptions, Synthetic};
    use crate::tracker::pyramid::Pyramid;

    /// The window the first mesh covers in camera `c` of `syn` at frame 0.
    fn window(syn: &Synthetic, c: usize) -> [f64; 4] {
        crate::tracker::sequence::mesh_window(&syn.cameras[c], 0, &syn.truth[0]).unwrap()
    }

    #[test]
    fn the_cameras_a_run_used_are_turned_from_the_frame_each_turn_was_first_used_on() {
        let syn = Synthetic::generate(&SynthOptions {
            cameras: Some(2),
            width: 64,
            height: 48,
            frames: 2,
            ..SynthOptions::default()
        })
        .unwrap();
        let turn = [0.001, -0.002, 0.0005];
        // Camera 1 turned from frame 3 on (frames 1 and 2 logged without turns).
        let lines = vec![
            (1, vec![]),
            (2, vec![]),
            (3, vec![[0.0; 3], turn]),
            (4, vec![[0.0; 3], turn]),
        ];
        let used = cameras_as_used(&syn.cameras, 0, &lines);
        let x = syn.truth[0][100];
        let expected = turned(syn.cameras[1].at(0), &Vector3::from(turn)).unwrap();
        for f in 0..6 {
            assert_eq!(used[0].at(f).project(&x), syn.cameras[0].at(0).project(&x));
            let want = if f < 3 {
                syn.cameras[1].at(0)
            } else {
                &expected
            };
            assert_eq!(used[1].at(f).project(&x), want.project(&x), "frame {f}");
        }
        // The turn moves the point by about f·|turn| pixels.
        let moved =
            (expected.project(&x).unwrap() - syn.cameras[1].at(0).project(&x).unwrap()).norm();
        assert!((0.05..0.3).contains(&moved), "{moved}");
    }

    #[test]
    fn the_levels_read_are_the_first_at_most_640_wide_and_two_coarser() {
        assert_eq!(levels_read(640, 3), [0, 2]);
        assert_eq!(levels_read(1280, 4), [1, 3]);
        assert_eq!(levels_read(3840, 6), [3, 5]);
        assert_eq!(levels_read(1920, 3), [2]);
        assert_eq!(levels_read(320, 1), [0]);
    }

    #[test]
    fn a_cameras_turn_is_read_from_its_background_and_nothing_from_a_plain_one() {
        // Camera 0 turned 0.25° from frame 1 on (about 2 px at 320×240); camera 1 not.
        let opts = SynthOptions {
            cameras: Some(2),
            width: 320,
            height: 240,
            frames: 2,
            backdrop: true,
            bump: Some(Bump {
                camera: 0,
                frame: 1,
                degrees: 0.25,
            }),
            ..SynthOptions::default()
        };
        let syn = Synthetic::generate(&opts).unwrap();
        let pyramid = |c: usize, f: u32| Pyramid::new(&syn.render(c, f), 3, 1.0);
        let reference = |c: usize| {
            Reference::new(
                &pyramid(c, 0).levels,
                syn.cameras[c].at(0),
                Some(window(&syn, c)),
            )
        };
        let truth = opts.bump.unwrap().rotation().scaled_axis();
        let got = read(
            &reference(0),
            &pyramid(0, 1).levels,
            &[window(&syn, 0)],
            Vector3::zeros(),
            false,
        )
        .expect("a textured wall gives a reading");
        assert!(
            (got.turn - truth).norm() < 0.02 * truth.norm(),
            "{:?} against {truth:?}",
            got.turn
        );
        assert!(got.error_px < MAX_ERROR_PX, "{got:?}");
        let k = reference(0).k;
        let px = motion_px(&k, 320.0, 240.0, &got.turn, &Vector3::zeros());
        assert!((1.5..3.0).contains(&px), "{px} px");
        // Started from the turn already found, the reading stays there (or, when a coarse level
        // sees enough of the wall, settles there: nothing more moved), also when every level is
        // read again.
        for just_moved in [false, true] {
            let again = read(
                &reference(0),
                &pyramid(0, 1).levels,
                &[window(&syn, 0)],
                got.turn,
                just_moved,
            );
            assert!(
                again.is_none_or(|r| motion_px(&k, 320.0, 240.0, &r.turn, &got.turn) < 0.05),
                "{again:?}"
            );
        }
        // The camera that stayed put: nothing to take.
        let still = read(
            &reference(1),
            &pyramid(1, 1).levels,
            &[window(&syn, 1)],
            Vector3::zeros(),
            false,
        );
        assert!(
            still.is_none_or(|r| motion_px(&k, 320.0, 240.0, &r.turn, &Vector3::zeros()) < 0.05),
            "{still:?}"
        );
        // A plain background shows no turn, however far the camera turned.
        let plain = Synthetic::generate(&SynthOptions {
            backdrop: false,
            ..opts.clone()
        })
        .unwrap();
        let plain_pyramid = |f: u32| Pyramid::new(&plain.render(0, f), 3, 1.0);
        let plain_reference = Reference::new(
            &plain_pyramid(0).levels,
            plain.cameras[0].at(0),
            Some(window(&plain, 0)),
        );
        assert_eq!(
            read(
                &plain_reference,
                &plain_pyramid(1).levels,
                &[window(&plain, 0)],
                Vector3::zeros(),
                false,
            ),
            None
        );
    }

    #[test]
    fn heavy_image_noise_over_a_plain_wall_is_not_read_as_the_cameras_turning() {
        // Noise of 0.08 over the plain grey wall has gradients everywhere and passes for
        // texture, but two frames' noise is unrelated: before the correlation rule three of the
        // blob's four still cameras were read as turned 1–3 px at frame 1 (and at every frame
        // after), and every frame was flagged suspect.
        let syn = Synthetic::generate(&SynthOptions {
            preset: crate::synth::Preset::Blob,
            width: 480,
            height: 360,
            frames: 2,
            noise: 0.08,
            ..SynthOptions::default()
        })
        .unwrap();
        for c in 0..syn.cameras.len() {
            let pyramid = |f: u32| Pyramid::new(&syn.render(c, f), 3, 1.0);
            let reference = Reference::new(
                &pyramid(0).levels,
                syn.cameras[c].at(0),
                Some(window(&syn, c)),
            );
            assert!(
                reference.textured,
                "camera {c}: the noise passes for texture"
            );
            let got = read(
                &reference,
                &pyramid(1).levels,
                &[window(&syn, c)],
                Vector3::zeros(),
                false,
            );
            assert!(
                got.is_none_or(|r| motion_px(
                    &reference.k,
                    480.0,
                    360.0,
                    &r.turn,
                    &Vector3::zeros()
                ) < MOVED_PX),
                "camera {c}: {got:?}"
            );
        }
    }

    #[test]
    fn a_rod_moving_across_a_plain_wall_is_not_read_as_the_camera_turning() {
        // The Blender hard sample tracked from its frame 16: a rod beside the object in one
        // camera's first image, textured, on a plain wall; it moves, and before the spread
        // rule its motion was read as a 19 px turn of that camera, and the mesh was lost.
        let syn = Synthetic::generate(&SynthOptions {
            cameras: Some(2),
            width: 320,
            height: 240,
            frames: 2,
            ..SynthOptions::default()
        })
        .unwrap();
        let pose = syn.cameras[0].at(0);
        let texture = |x: f64, y: f64| {
            let v = 0.5 + 0.2 * (0.9 * x + 0.3 * y).sin() + 0.15 * (0.4 * y - 0.7 * x).sin();
            [v as f32; 3]
        };
        // `band`: the textured part's columns (the rest a plain grey wall), moved `dx` px.
        let image = |band: (f64, f64), dx: f64| {
            let img = RgbImage::from_fn(320, 240, |x, y| {
                let xs = x as f64 - dx;
                if xs >= band.0 && xs < band.1 {
                    texture(xs, y as f64)
                } else {
                    [0.3; 3]
                }
            });
            Pyramid::new(&img, 3, 1.0).levels
        };
        // The mesh's window, away from the rod.
        let mesh = [200.0, 60.0, 290.0, 180.0];
        let reading = |band: (f64, f64)| {
            let reference = Reference::new(&image(band, 0.0), pose, Some(mesh));
            read(
                &reference,
                &image(band, 3.0),
                &[mesh],
                Vector3::zeros(),
                false,
            )
        };
        // A rod 48 px wide: 15 % of the background textured, all of it in one band.
        assert_eq!(reading((40.0, 88.0)), None);
        // The same texture over the whole image, moved the same 3 px: a camera's turn, read.
        let k = pose.krt().0;
        let wall = reading((-1e9, 1e9)).expect("a wall textured all over gives a reading");
        let px = motion_px(&k, 320.0, 240.0, &wall.turn, &Vector3::zeros());
        assert!((2.5..3.5).contains(&px), "{px} px");
    }
}

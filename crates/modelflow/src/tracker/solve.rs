//! The per-frame solver (thesis §5.2, §6.4, §6.6): given template patches, the next frame's
//! images and cameras, and a starting guess, find the vertex positions that minimise
//!
//! `E(X) = Σ_patches w·Σ_pixels ρ(|I_next(W(X)·s) − I_template(s)|²) / N  +  Σ_terms R_k(X)`
//!
//! (the `R_k` are the regularisers of `regularise`, which the solver sees only through their
//! trait) by Gauss–Newton with Levenberg–Marquardt damping: the normal equations are accumulated
//! straight into the block-sparse matrix (J is never stored), solved by preconditioned conjugate
//! gradients, and a step is accepted only if the cost falls; otherwise the positions roll back and
//! the damping grows. `ρ` is a robust loss on the RGB residual (Huber, or Tukey's biweight with a
//! per-pixel threshold set once per solve, see [`Loss`]), so that pixels that changed for
//! reasons the warp does not explain (occlusion, specular light) do not dominate.
//!
//! Invariant: this module does no I/O. It reports per iteration, like Ceres' summary: cost, its
//! change, the step, the CG work, the time, and why it stopped.

// The inner kernels index small fixed arrays (RGB channels, the three vertices, the six vertex
// pairs) by position on purpose: it reads like the equations.
#![allow(clippy::needless_range_loop)]

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::base::mesh::{centroid, rms_radius};
use crate::tracker::gpu::Uploaded;
use crate::tracker::patch::{Patch, PatchSet, PixelSample};
use crate::tracker::regularise::Regulariser;
use crate::tracker::rim::Rims;
use crate::tracker::sparse::{solve_pcg_until, BlockSparse, CgStop};
use crate::tracker::warp::{source_matrix, warp_h};
use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Solver settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolverOptions {
    /// Gauss–Newton iterations at most (per pyramid level).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub min_relative_decrease: f64,
    /// Huber threshold on the RGB residual norm (image values are 0..1).
    pub huber: f64,
    /// The robust loss on each pixel's RGB residual.
    #[serde(default)]
    pub loss: Loss,
    /// With [`Loss::Tukey`]: the rejection threshold as a multiple of the median residual norm
    /// at the start of each solve.
    #[serde(default = "default_tukey_k")]
    pub tukey_k: f64,
    /// With [`Loss::Tukey`]: the smallest threshold (image units), so that a near-perfect fit
    /// does not reject its own sub-pixel misfits.
    #[serde(default = "default_tukey_min")]
    pub tukey_min: f64,
    /// With [`Loss::Tukey`]: the misalignment in pixels (of the level solved) a pixel may have
    /// and still be kept: the threshold grows by this times the image gradient's norm there.
    #[serde(default = "default_tukey_px")]
    pub tukey_px: f64,
    /// With [`Loss::Tukey`]: the scale of the Cauchy loss on each (triangle, camera) patch's
    /// mean pixel cost, as a fraction of its pixels' mean threshold; a patch that fits worse
    /// than that as a whole (a highlight over a facet) is down-weighted. 0 turns it off; options
    /// written before it existed (a run's manifest) read as 0, which is how those builds ran.
    #[serde(default)]
    pub patch_scale: f64,
    /// Initial Levenberg–Marquardt damping (relative to the diagonal).
    pub damping: f64,
    /// Rejected steps in a row before giving up.
    pub max_rejections: usize,
    pub cg_tolerance: f64,
    pub cg_max_iterations: usize,
    /// Brightness gain compensated per (triangle, camera) (diffuse shading changes as the
    /// surface turns).
    pub gain: GainModel,
    /// The fitted gains are kept within `[1 / gain_range, gain_range]`: how far a patch's
    /// brightness may change between the template and the frame solved (a surface turning
    /// from facing its light to 75° off it darkens about 4×). Options written before it
    /// existed (a run's manifest) read as 2, which is how those builds ran.
    #[serde(default = "legacy_gain_range")]
    pub gain_range: f64,
    /// How the next frame is sampled at warped positions (the tracker uses it at the finest
    /// pyramid level and bilinear at coarser ones, which only bring the mesh near the solution).
    pub interpolation: Interpolation,
}

/// How the next frame's image is sampled between pixel centres (the derivatives used are always
/// the interpolant's own, so the Jacobian is exact for the cost evaluated).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// Bilinear, four taps (`RgbImage::sample_exact`).
    Linear,
    /// Catmull–Rom bicubic, sixteen taps (`RgbImage::sample_cubic`): a smaller sub-pixel bias,
    /// for about a fifth more time per frame (used at the finest level only).
    Cubic,
}

fn default_tukey_k() -> f64 {
    3.0
}

fn default_tukey_px() -> f64 {
    1.0
}

fn default_tukey_min() -> f64 {
    0.03
}

fn default_patch_scale() -> f64 {
    0.5
}

/// The default `gain_range`: a Lambertian surface turned from facing its light to 75° off it
/// (cos 75° ≈ 0.26). The earlier bound, 2, held the first frame's view of a turning object to a
/// brightness it no longer had (docs/tracker.md, "Brightness gains").
pub(crate) const DEFAULT_GAIN_RANGE: f64 = 4.0;

/// `gain_range` of the builds before it was an option.
fn legacy_gain_range() -> f64 {
    2.0
}

/// The robust loss `ρ(e²)` on a pixel's RGB residual norm `e` (both are `e²` for small `e`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Loss {
    /// Huber with the fixed threshold `huber`: quadratic, then linear (convex; every pixel keeps
    /// some pull).
    Huber,
    /// Tukey's biweight with a threshold set at the start of every solve from the residuals
    /// there (`tukey_k` × their median, at least `tukey_min`, widened per pixel by `tukey_px` ×
    /// the image gradient's norm where it lands): pixels beyond it are
    /// rejected (an occluder, a highlight), and the threshold is fixed within the solve so that
    /// the cost the steps are judged by does not change under them.
    #[default]
    Tukey,
}

/// How the template's brightness may change in the next frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GainModel {
    /// Plain brightness constancy, as in the thesis.
    Off,
    /// One gain per (triangle, camera).
    Constant,
    /// A gain varying linearly over the triangle (three per (triangle, camera)).
    Linear,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            max_iterations: 25,
            min_relative_decrease: 1e-3,
            huber: 0.1,
            loss: Loss::Tukey,
            tukey_k: default_tukey_k(),
            tukey_min: default_tukey_min(),
            tukey_px: default_tukey_px(),
            patch_scale: default_patch_scale(),
            damping: 1e-4,
            max_rejections: 4,
            cg_tolerance: 1e-3,
            cg_max_iterations: 100,
            gain: GainModel::Linear,
            gain_range: DEFAULT_GAIN_RANGE,
            interpolation: Interpolation::Cubic,
        }
    }
}

/// Tukey's loss `ρ(e²) = δ²/3·(1 − (1 − e²/δ²)³)` below the threshold `d2 = δ²`, `δ²/3` above,
/// and its IRLS weight `ρ' = (1 − e²/δ²)²` (0 above): the pixels' loss, and the rims' (`rim`).
#[inline(always)]
pub(crate) fn tukey(e2: f64, d2: f64) -> (f64, f64) {
    if e2 >= d2 {
        (d2 / 3.0, 0.0)
    } else {
        let t = 1.0 - e2 / d2;
        (d2 / 3.0 * (1.0 - t * t * t), t * t)
    }
}

/// What the solver needs about one frame pair at one pyramid level.
#[derive(Clone)]
pub(crate) struct Problem<'a> {
    pub triangles: &'a [[u32; 3]],
    /// Patches ordered by triangle (see `PatchSet::by_triangle`) and their pixels.
    pub patches: &'a [Patch],
    pub pixels: &'a [PixelSample],
    pub by_triangle: &'a [(u32, std::ops::Range<usize>)],
    /// Next-frame image and projection of each camera, at this level.
    pub targets: Vec<&'a RgbImage>,
    pub projections: Vec<Projection>,
    /// The mesh's edges: the vertex pairs whose 3×3 blocks the normal equations hold.
    pub pattern: &'a [[u32; 2]],
    /// The regularisers, added to the photometric cost in this order.
    pub regularisers: &'a [Box<dyn Regulariser>],
    /// Checked before every iteration: when set, the solve stops (`StopReason::Cancelled`).
    pub cancel: Option<&'a AtomicBool>,
    /// When set, the photometric sums are evaluated on the GPU (this problem's inputs already
    /// there); `None`: on the CPU.
    pub gpu: Option<&'a Uploaded>,
    /// `None` when every patch comes from a template frame, whose mesh is known and fixed.
    /// `Some(x0)` when some come from the unknowns' own frame (`align`; the tracker's
    /// `stereo` term): such a patch (its `source` camera not its `camera`) has its pixels taken
    /// from camera `source` with the mesh at `x0`, and the surface point each pixel sees moves
    /// along that camera's ray as the mesh moves. See [`SourceWarp`]. A patch whose `source`
    /// is its `camera` is a template's either way.
    pub moving_source: Option<&'a [Point3<f64>]>,
    /// With a rigid or similarity motion: whole-mesh motions whose curvature is below this
    /// fraction of the best-fixed one's are left out of every step (0: none are).
    pub gauge_floor: f64,
    /// Cameras that record the next frame late or early (`Camera::time_offset`), with the
    /// previous frame's positions: camera `c` sees the surface at `x + δ_c·(x − previous)/gap`.
    /// `None`: every camera on time.
    pub lag: Option<Lag<'a>>,
    /// The rims held to the outline the images show (`rim`); `None`: no such term.
    pub rims: Option<&'a Rims>,
}

impl<'a> Problem<'a> {
    /// The photometric problem of `set`'s patches (grouped by `by_triangle`) against `targets`
    /// seen through `projections`: no regulariser, on the CPU, no cancel flag, template patches
    /// only, every camera on time. Callers set the other fields with struct update syntax.
    pub fn photometric(
        triangles: &'a [[u32; 3]],
        set: &'a PatchSet,
        by_triangle: &'a [(u32, std::ops::Range<usize>)],
        targets: Vec<&'a RgbImage>,
        projections: Vec<Projection>,
        pattern: &'a [[u32; 2]],
    ) -> Self {
        Problem {
            triangles,
            patches: &set.patches,
            pixels: &set.pixels,
            by_triangle,
            targets,
            projections,
            pattern,
            regularisers: &[],
            cancel: None,
            gpu: None,
            moving_source: None,
            gauge_floor: 0.0,
            lag: None,
            rims: None,
        }
    }
}

/// When each camera records the frame solved, and where the surface was at the frame before: a
/// camera `δ` frames late sees it moved on along its velocity, at `x + δ·(x − previous)/gap`
/// (`gap`: frames from the previous positions to these, 1 but after a stalled frame), so its
/// warp's derivative is an on-time camera's times `1 + δ/gap`. The template frame's pixels are
/// placed the same way (`sequence`), so a steady acceleration's error in this backward
/// difference is the same on both sides and cancels. A camera early by the whole gap sees the
/// previous positions: its pixels then say nothing about `x`.
#[derive(Clone, Copy)]
pub(crate) struct Lag<'a> {
    /// Per camera, in frames: one lag per vertex (a rolling shutter reads each vertex's row at
    /// its own instant, `Camera::lags`), or none when the camera records on time.
    pub offsets: &'a [Vec<f64>],
    pub previous: &'a [Point3<f64>],
    pub gap: f64,
}

impl Lag<'_> {
    /// One lag per camera (0 for one on time), when every camera records all its vertices at
    /// one instant; `None` under a rolling shutter.
    pub(crate) fn per_camera(&self) -> Option<Vec<f64>> {
        self.offsets
            .iter()
            .map(|d| match d.first() {
                None => Some(0.0),
                Some(&a) => d.iter().all(|&b| b == a).then_some(a),
            })
            .collect()
    }

    /// Where a camera `d` frames late sees vertex `v` when the frame's positions are `x`, and
    /// the derivative of that with respect to `x[v]` (a multiple of the identity).
    #[inline]
    fn seen(&self, x: &[Point3<f64>], v: usize, d: f64) -> (Point3<f64>, f64) {
        (
            moved_on(&x[v], &self.previous[v], d, self.gap),
            1.0 + d / self.gap,
        )
    }
}

/// Where a camera `d` frames late sees a point that is at `p` at the frame's time and was at `q`
/// `gap` frames before: moved on along the backward difference, `p + d·(p − q)/gap`. The one
/// formula for the frame solved ([`Lag`]) and for the template frame's pixels (`sequence`).
#[inline]
pub(crate) fn moved_on(p: &Point3<f64>, q: &Point3<f64>, d: f64, gap: f64) -> Point3<f64> {
    p + (p - q) * (d / gap)
}

/// The warp of a patch whose source camera sees the same, moving, mesh (`align`): from pixel
/// `s` of camera i into camera j, `W = P_j·V·(P_i·V)⁻¹` with one `V` — the thesis' Eq. 5.7 with
/// both frames the same. Its pixels store barycentrics `λ₀` taken at `x0`, so per pixel
/// `h = A·λ₀` with `A = S_j·S_i⁻¹·S_i(x0)`, the current (unnormalised) barycentrics are
/// `λ̂ = S_i⁻¹·S_i(x0)·λ₀`, and, differentiating `S_j·S_i⁻¹` in `V`,
/// `∂h/∂X_k = λ̂_k·(M_j − H·M_i)` with `H = S_j·S_i⁻¹`: the tracker's derivative (Eq. 5.11) with
/// `M_j − H·M_i` in place of `M_j`. (Derived here; the thesis warps between frames only.) A
/// test checks it against finite differences.
struct SourceWarp {
    /// Columns: where `λ₀ = e_k` lands (homogeneous), replacing `Y_k`.
    y: [Vector3<f64>; 3],
    /// `M_j − H·M_i`.
    m: Matrix3<f64>,
    /// `S_i⁻¹·S_i(x0)`: stored barycentrics to current ones.
    t: Matrix3<f64>,
}

impl SourceWarp {
    /// The warp with the source camera seeing the triangle at `xi` and the target camera at
    /// `xj`, each corner moving `ai` and `aj` times as far as the unknowns (1 and the same
    /// corners, unless a camera records late or early: [`Lag`]). With `X_i = a_i·x + c_i` and
    /// `X_j = a_j·x + c_j`, `W = S_j(X_j)·S_i(X_i)⁻¹` and `∂h/∂X_k = λ̂_k·(a_j·M_j − a_i·H·M_i)`.
    fn new(
        (xi, ai): (&[Point3<f64>; 3], f64),
        (xj, aj): (&[Point3<f64>; 3], f64),
        xs0: &[Point3<f64>; 3],
        source: &Projection,
        target: &Projection,
    ) -> Option<SourceWarp> {
        let si_inv = source_matrix(source, xi).try_inverse()?;
        let h = source_matrix(target, xj) * si_inv;
        let t = si_inv * source_matrix(source, xs0);
        let a = h * source_matrix(source, xs0);
        let mi: Matrix3<f64> = source.matrix().fixed_view::<3, 3>(0, 0).into_owned() * ai;
        let mj: Matrix3<f64> = target.matrix().fixed_view::<3, 3>(0, 0).into_owned() * aj;
        let m = mj - h * mi;
        let y = [a.column(0).into(), a.column(1).into(), a.column(2).into()];
        (m.iter().chain(t.iter()).all(|v| v.is_finite())).then_some(SourceWarp { y, m, t })
    }
}

/// Why the solver stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The last accepted step lowered the cost by less than `min_relative_decrease`.
    Converged,
    /// No step lowered the cost any more (rolled back to the best positions).
    CostRose,
    /// `max_iterations` reached.
    MaxIterations,
    /// No pixel could be compared (nothing visible).
    NoData,
    /// The cost is not a finite number at the start (e.g. non-finite positions): nothing was
    /// tried.
    NonFinite,
    /// Stopped on request (the run was interrupted); the positions are not a solution.
    Cancelled,
}

/// How well the images pin one vertex down at a solution: the photometric normal equations'
/// 3×3 block of the vertex (robust weights included, summed over the pixels of its triangles in
/// every camera, not normalised) and the residual of those pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VertexConfidence {
    /// The block's smallest eigenvalue, in (image value per scene unit)²: how much the cost
    /// rises when the vertex moves along its worst-constrained direction. 0 when no pixel of any
    /// camera constrains it (unseen, occluded, or every pixel rejected by the loss).
    pub information: f64,
    /// Root mean robust residual of the pixels of its triangles (RGB, image values 0..1).
    pub residual: f64,
    /// Weighted pixels of its triangles that were compared.
    pub pixels: f64,
}

impl VertexConfidence {
    /// One standard deviation of the vertex's position along its worst-constrained direction,
    /// in scene units: `residual / sqrt(information)` (the Gauss–Newton covariance of the vertex
    /// alone, σ²·(JᵀJ)⁻¹, with the residual as σ). Infinite when nothing constrains it.
    pub fn sigma(&self) -> f64 {
        if self.information > 0.0 {
            self.residual / self.information.sqrt()
        } else {
            f64::INFINITY
        }
    }
}

/// One Gauss–Newton iteration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IterationSummary {
    pub iteration: usize,
    /// Cost after the iteration (the best so far).
    pub cost: f64,
    /// Cost change of the tried step (negative = decrease).
    pub cost_change: f64,
    /// Cost change the Gauss–Newton model predicted for the tried step (negative = decrease;
    /// `cost_change / model_change` near 1 means the model was right). Absent in logs written
    /// before it was recorded.
    #[serde(default)]
    pub model_change: f64,
    /// Largest vertex displacement of the tried step, in scene units.
    pub step: f64,
    pub accepted: bool,
    pub damping: f64,
    pub cg_iterations: usize,
    pub seconds: f64,
}

/// Result of one solve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolveSummary {
    /// How the next frame was sampled in this solve (the option as used at this level).
    pub interpolation: Interpolation,
    /// How the mesh was allowed to move.
    pub motion: Motion,
    pub initial_cost: f64,
    pub final_cost: f64,
    /// Pixels compared at the final positions.
    pub pixels: usize,
    /// Pixel comparisons made in all (each is three RGB residuals), over every evaluation.
    pub pixel_evaluations: u64,
    /// Wall time of the solve, seconds.
    pub seconds: f64,
    /// Of which evaluating the photometric cost and its normal equations (the per-pixel work,
    /// on the GPU with `--device gpu`) and the regularisers, seconds. Absent (0) in logs
    /// written before it was recorded.
    #[serde(default)]
    pub evaluation_seconds: f64,
    /// Of which solving the normal equations for the steps (PCG, or the rigid step), seconds.
    #[serde(default)]
    pub linear_solver_seconds: f64,
    pub stop: StopReason,
    pub iterations: Vec<IterationSummary>,
}

/// One triangle's photometric sums over its patches: cost, pixels, and its share of the normal
/// equations (the `PAIRS` blocks and the gradient's three vectors).
#[derive(Clone, Copy)]
pub(crate) struct TriAccum {
    pub cost: f64,
    pub pixels: u32,
    /// Σ of the pixels' weights (the patches' `weight`).
    pub weight: f64,
    /// Pixels the robust loss rejected (Tukey: a residual past its threshold; Huber: none).
    pub rejected: u32,
    pub h: [Matrix3<f64>; 6],
    pub g: [Vector3<f64>; 3],
}

/// Which brightness gains a patch's fit left free (see [`gain_schur`]).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Fitted {
    /// None (off, or clamped at a bound): nothing to project out.
    None,
    /// One gain for the patch.
    Constant,
    /// A gain linear over the triangle (one per corner).
    Linear,
}

/// The part of a patch's position curvature that its fitted gains take away, per vertex pair
/// (`PAIRS` order, block (i, j) with rows of vertex i): `Q_i·H_gg⁻¹·Q_jᵀ`, where
/// `Q_i[a][j] = coupling[i][j][a]` couples coordinate a of vertex i with gain basis j and
/// `gram` is the gains' own curvature. `None` when no gain is free or the gains' curvature
/// cannot be inverted. Written by hand: 3×3 algebra on nalgebra's small matrices.
fn gain_schur(
    coupling: &[[[f64; 3]; 3]; 3],
    gram: &Matrix3<f64>,
    fitted: Fitted,
) -> Option<[Matrix3<f64>; 6]> {
    let q: [Matrix3<f64>; 3] = std::array::from_fn(|i| Matrix3::from_fn(|a, j| coupling[i][j][a]));
    let (left, right): ([Matrix3<f64>; 3], [Matrix3<f64>; 3]) = match fitted {
        Fitted::None => return None,
        Fitted::Linear => {
            let inv = gram.try_inverse()?;
            if !inv.iter().all(|v| v.is_finite()) {
                return None;
            }
            (q.map(|qi| qi * inv), q)
        }
        Fitted::Constant => {
            // One basis function, 1 = Σ_j μ_j: its coupling is the sum over j.
            let h = gram.sum();
            if h.is_nan() || h <= 0.0 {
                return None;
            }
            let col = q.map(|qi| {
                let c = qi.column_sum();
                Matrix3::from_columns(&[c, Vector3::zeros(), Vector3::zeros()])
            });
            (col.map(|c| c / h), col)
        }
    };
    Some(std::array::from_fn(|k| {
        let (i, j) = PAIRS[k];
        left[i] * right[j].transpose()
    }))
}

/// A pixel of a patch after warping: its index in the patch, warped position, `1/h_z`, and the
/// next image's colour and gradients there.
#[derive(Clone, Copy, Default)]
struct Warped {
    index: u32,
    u: f64,
    v: f64,
    inv: f64,
    s: [f32; 9],
}

const PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// A worker's reusable buffers: the warped pixels of a patch, and the residual histogram when
/// one is being collected.
#[derive(Default)]
struct Scratch {
    warped: Vec<Warped>,
    hist: Option<ResidualHistogram>,
}

/// A weighted histogram of residual norms on a log scale, for their median. Weights are summed
/// as integers (fixed point), so the result does not depend on how threads split the work.
pub(crate) struct ResidualHistogram {
    bins: Vec<u64>,
}

/// Bins of the residual histogram (the GPU path fills one of this size).
pub(crate) const HISTOGRAM_BINS: usize = ResidualHistogram::BINS;

/// The squared norms at which the histogram's bins 1, 2, ... begin (the GPU path bins with them).
pub(crate) fn histogram_edges() -> &'static [f64] {
    ResidualHistogram::edges()
}

impl ResidualHistogram {
    const BINS: usize = 160;
    /// Norms from 1e-4 to 10^(−4 + BINS/STEPS) (past the largest RGB difference, √3).
    const LOG_MIN: f64 = -4.0;
    const PER_DECADE: f64 = 36.0;

    fn new() -> Self {
        ResidualHistogram {
            bins: vec![0; Self::BINS],
        }
    }

    /// The squared norms at which bins 1, 2, ... begin: bin `b` holds
    /// `floor((log10(√e²) − LOG_MIN)·PER_DECADE) = b`. Found by a binary search instead of a
    /// logarithm per pixel (which took 5 % of a whole run's time).
    fn edges() -> &'static [f64] {
        static EDGES: std::sync::LazyLock<Vec<f64>> = std::sync::LazyLock::new(|| {
            (1..ResidualHistogram::BINS)
                .map(|b| {
                    let l = ResidualHistogram::LOG_MIN + b as f64 / ResidualHistogram::PER_DECADE;
                    10f64.powf(2.0 * l)
                })
                .collect()
        });
        &EDGES
    }

    /// The bin of squared norm `e2` (NaN and anything below the first edge: bin 0): how many
    /// edges are `<= e2`. The count is started from a table indexed by `e2`'s exponent and its
    /// top `START_BITS` mantissa bits (a 2^-5 of an octave, narrower than a bin, so at most
    /// one edge lies in each) and finished by comparing with the edges: the binary search's
    /// count (the GPU's `hist_bin`), in one or two comparisons instead of eight.
    fn bin(e2: f64) -> usize {
        let edges = Self::edges();
        if e2.is_nan() || e2 < edges[0] {
            return 0;
        }
        if e2 >= edges[edges.len() - 1] {
            return edges.len();
        }
        let (base, starts) = Self::starts();
        let mut b = starts[(e2.to_bits() >> (52 - Self::START_BITS)) as usize - base] as usize;
        while edges[b] <= e2 {
            b += 1;
        }
        b
    }

    /// Mantissa bits of the table [`ResidualHistogram::bin`] starts from.
    const START_BITS: u32 = 5;

    /// The key of the table's first entry, and per key (a positive `f64`'s bits shifted right
    /// by `52 − START_BITS`, from the first edge's key to the last's) how many edges are
    /// below the least number with that key.
    fn starts() -> (usize, &'static [u8]) {
        static STARTS: std::sync::LazyLock<(usize, Vec<u8>)> = std::sync::LazyLock::new(|| {
            let edges = ResidualHistogram::edges();
            let shift = 52 - ResidualHistogram::START_BITS;
            let key = |v: f64| (v.to_bits() >> shift) as usize;
            let (first, last) = (key(edges[0]), key(edges[edges.len() - 1]));
            let starts = (first..=last)
                .map(|k| {
                    let least = f64::from_bits((k as u64) << shift);
                    edges.partition_point(|&e| e < least) as u8
                })
                .collect();
            (first, starts)
        });
        (STARTS.0, &STARTS.1)
    }

    /// A weight as the integer units the bins count (at least one), so that a patch's weight is
    /// converted once, not per pixel.
    fn units(weight: f64) -> u64 {
        (weight * 1024.0).round().max(1.0) as u64
    }

    fn add_units(&mut self, e2: f64, units: u64) {
        self.bins[Self::bin(e2)] += units;
    }

    fn from_bins(bins: Vec<u64>) -> Self {
        debug_assert_eq!(bins.len(), Self::BINS);
        ResidualHistogram { bins }
    }

    fn merge(mut self, other: Self) -> Self {
        for (a, b) in self.bins.iter_mut().zip(other.bins) {
            *a += b;
        }
        self
    }

    /// The weighted median norm (interpolated within its bin), or `None` when empty.
    fn median(&self) -> Option<f64> {
        let total: u64 = self.bins.iter().sum();
        if total == 0 {
            return None;
        }
        let half = total as f64 / 2.0;
        let mut below = 0.0;
        for (i, &n) in self.bins.iter().enumerate() {
            let n = n as f64;
            if below + n >= half {
                let f = if n > 0.0 { (half - below) / n } else { 0.0 };
                return Some(10f64.powf(Self::LOG_MIN + (i as f64 + f) / Self::PER_DECADE));
            }
            below += n;
        }
        None
    }
}

impl Problem<'_> {
    /// The weighted median RGB residual norm at `x` (`None` when no pixel compares).
    pub fn median_residual(&self, x: &[Point3<f64>], opts: &SolverOptions) -> Option<f64> {
        if let Some(bins) = self.gpu.and_then(|g| g.histogram(x, opts)) {
            return ResidualHistogram::from_bins(bins).median();
        }
        self.by_triangle
            .par_iter()
            .with_min_len(16)
            .fold(
                || Scratch {
                    warped: Vec::new(),
                    hist: Some(ResidualHistogram::new()),
                },
                |mut scratch, (t, r)| {
                    self.triangle(*t, r, x, opts, false, &mut scratch);
                    scratch
                },
            )
            .filter_map(|s| s.hist)
            .reduce(ResidualHistogram::new, ResidualHistogram::merge)
            .median()
    }

    /// The options a solve starting at `x` runs with: with [`Loss::Tukey`], its threshold set
    /// from the residuals there (in `huber`).
    pub fn solve_options(&self, x: &[Point3<f64>], opts: &SolverOptions) -> SolverOptions {
        match opts.loss {
            Loss::Huber => *opts,
            Loss::Tukey => {
                let m = self.median_residual(x, opts).unwrap_or(opts.huber);
                self.tukey_options(m, opts)
            }
        }
    }

    /// The options of a Tukey solve whose residuals at the start have the median `m`.
    fn tukey_options(&self, m: f64, opts: &SolverOptions) -> SolverOptions {
        SolverOptions {
            huber: (opts.tukey_k * m).max(opts.tukey_min),
            ..*opts
        }
    }

    fn weighted_pixels(&self) -> f64 {
        weighted_pixels_of(self.patches)
    }

    /// Photometric cost and (optionally) its normal-equation contribution of one triangle.
    fn triangle(
        &self,
        t: u32,
        range: &std::ops::Range<usize>,
        x: &[Point3<f64>],
        opts: &SolverOptions,
        system: bool,
        scratch: &mut Scratch,
    ) -> TriAccum {
        let Scratch {
            warped: scratch,
            hist,
        } = scratch;
        let huber = opts.huber;
        let tri = self.triangles[t as usize];
        let xs = tri.map(|v| x[v as usize]);
        let mut acc = TriAccum {
            cost: 0.0,
            pixels: 0,
            weight: 0.0,
            rejected: 0,
            h: [Matrix3::zeros(); 6],
            g: [Vector3::zeros(); 3],
        };
        let hub2 = huber * huber;
        let tol2 = opts.tukey_px * opts.tukey_px;
        // Tukey's patch scale, as a fraction of the pixels' own thresholds (see below).
        let patch2 = match opts.loss {
            Loss::Tukey => opts.patch_scale * opts.patch_scale,
            Loss::Huber => 0.0,
        };
        for patch in &self.patches[range.clone()] {
            let cam = patch.camera as usize;
            let proj = &self.projections[cam];
            let img = self.targets[cam];
            let pm = proj.matrix();
            let mut m = [
                [pm[(0, 0)], pm[(0, 1)], pm[(0, 2)]],
                [pm[(1, 0)], pm[(1, 1)], pm[(1, 2)]],
                [pm[(2, 0)], pm[(2, 1)], pm[(2, 2)]],
            ];
            // Where camera `c` sees the triangle, and how far that moves per unit of the
            // unknowns: at its own instant when it records late or early (`Lag`). Under a
            // rolling shutter the corners' instants differ by the rows between them; the
            // derivative takes their mean factor (the corners' factors differ by a few
            // hundredths of a frame's readout over a triangle's height, so the Gauss-Newton
            // model is off by as little and the cost it is checked against is exact).
            let at = |c: usize| match self.lag {
                Some(lag) if lag.offsets.get(c).is_some_and(|d| !d.is_empty()) => {
                    let d = &lag.offsets[c];
                    let seen = tri.map(|v| lag.seen(x, v as usize, d[v as usize]));
                    let a = if seen[1].1 == seen[0].1 && seen[2].1 == seen[0].1 {
                        seen[0].1
                    } else {
                        (seen[0].1 + seen[1].1 + seen[2].1) / 3.0
                    };
                    (seen.map(|(p, _)| p), Some(a))
                }
                _ => (xs, None),
            };
            let (xj, aj) = at(cam);
            if let Some(a) = aj {
                for row in m.iter_mut() {
                    for e in row.iter_mut() {
                        *e *= a;
                    }
                }
            }
            let mut y = xj.map(|p| proj.project_h(&p));
            // A moving source (`align`) changes the warp's columns and derivative, and the
            // barycentrics the derivative is weighted by.
            let mut to_current = None;
            if let Some(x0) = self.moving_source.filter(|_| patch.source != patch.camera) {
                let xs0 = tri.map(|v| x0[v as usize]);
                let src = &self.projections[patch.source as usize];
                // Each camera sees the triangle at its own instant: the source camera where its
                // pixels were taken, the target where it looks for them.
                let (xi, ai) = at(patch.source as usize);
                let (ai, aj) = (ai.unwrap_or(1.0), aj.unwrap_or(1.0));
                let Some(sw) = SourceWarp::new((&xi, ai), (&xj, aj), &xs0, src, proj) else {
                    // The source triangle is edge-on at `x`: its pixels see no surface. They
                    // count at the loss's cap (Huber: its threshold; Tukey: its plateau), so a
                    // trial cannot lower the cost by making triangles vanish.
                    let n = (patch.end - patch.start) as f64;
                    let cap = match opts.loss {
                        Loss::Huber => hub2,
                        Loss::Tukey => hub2 / 3.0,
                    };
                    acc.cost += (patch.weight as f64) * n * cap;
                    acc.pixels += n as u32;
                    acc.weight += (patch.weight as f64) * n;
                    continue;
                };
                y = sw.y;
                for (r, row) in m.iter_mut().enumerate() {
                    for (c, e) in row.iter_mut().enumerate() {
                        *e = sw.m[(r, c)];
                    }
                }
                to_current = Some(sw.t);
            }
            let pw = patch.weight as f64;
            let units = ResidualHistogram::units(pw);
            // Per-patch sums of the six distinct 3×3 vertex-pair blocks, each kept as its six
            // distinct entries (every block is symmetric), folded into the triangle once.
            // Entries 6..9 of each: the pair's share of the positions–gains coupling and of the
            // gains' own curvature (see below), summed in the same loop.
            let mut hp = [[0.0f64; 10]; 6];
            let mut pcost = 0.0f64;
            let mut pd2 = 0.0f64;
            let mut pn = 0u32;
            let mut gp = [[0.0f64; 3]; 3];
            // Pass 1: warp and sample every pixel of the patch, into the first `n` slots of the
            // worker's buffer (grown once, written by index: no per-pixel push).
            if scratch.len() < (patch.end - patch.start) as usize {
                scratch.resize((patch.end - patch.start) as usize, Warped::default());
            }
            let mut n = 0usize;
            // Normal equations of the shading fit: gain(λ) = Σ_i λ_i·g_i (linear over the triangle).
            // Summed as plain numbers (the matrix's six distinct entries), not as nalgebra
            // matrices: the same values, fewer instructions in the per-pixel loop.
            let mut gm6 = [0.0f64; 6];
            let mut gr3 = [0.0f64; 3];
            let pixels = &self.pixels[patch.start as usize..patch.end as usize];
            for (i, px) in pixels.iter().enumerate() {
                let l = [
                    px.lambda[0] as f64,
                    px.lambda[1] as f64,
                    px.lambda[2] as f64,
                ];
                let h = warp_h(&l, &y);
                if h.z.is_nan() || h.z <= 0.0 {
                    continue;
                }
                let inv = 1.0 / h.z;
                let (u, v) = (h.x * inv, h.y * inv);
                let sample = match opts.interpolation {
                    Interpolation::Linear => img.sample_exact(u, v),
                    Interpolation::Cubic => img.sample_cubic(u, v),
                };
                let Some(s) = sample else {
                    continue;
                };
                let mut sc = 0.0f64;
                let mut cc = 0.0f64;
                for k in 0..3 {
                    sc += (s[k] * px.color[k]) as f64;
                    cc += (px.color[k] * px.color[k]) as f64;
                }
                for (e, &(a, b)) in gm6.iter_mut().zip(&PAIRS) {
                    *e += l[a] * l[b] * cc;
                }
                for (e, &a) in gr3.iter_mut().zip(&l) {
                    *e += a * sc;
                }
                scratch[n] = Warped {
                    index: i as u32,
                    u,
                    v,
                    inv,
                    s,
                };
                n += 1;
            }
            let warped = &scratch[..n];
            // Shading changes as the surface turns: compare up to a brightness gain per
            // (triangle, camera), fitted by least squares to the warped pixels — constant, or
            // linear over the triangle (smooth shading). Because the gain is optimal for the
            // current positions, the gradient with respect to them is unchanged (envelope theorem).
            // Which gains were fitted freely (none clamped): their directions are projected out
            // of the normal equations below.
            let gm = Matrix3::new(
                gm6[0], gm6[3], gm6[4], gm6[3], gm6[1], gm6[5], gm6[4], gm6[5], gm6[2],
            );
            let gr = Vector3::from(gr3);
            let lo = 1.0 / opts.gain_range;
            let constant = |gm: &Matrix3<f64>, gr: &Vector3<f64>| {
                let g = gr.sum() / gm.sum();
                let c = g.clamp(lo, opts.gain_range);
                (
                    [c as f32; 3],
                    if c == g {
                        Fitted::Constant
                    } else {
                        Fitted::None
                    },
                )
            };
            let (gains, fitted): ([f32; 3], Fitted) = match opts.gain {
                GainModel::Off => ([1.0; 3], Fitted::None),
                _ if gm.trace() <= 0.0 => ([1.0; 3], Fitted::None),
                GainModel::Linear if warped.len() >= 12 => match gm.try_inverse() {
                    Some(inv) if (inv * gm).iter().all(|v| v.is_finite()) => {
                        let g = inv * gr;
                        let c = g.map(|v| v.clamp(lo, opts.gain_range));
                        let fitted = if c == g { Fitted::Linear } else { Fitted::None };
                        ([c.x as f32, c.y as f32, c.z as f32], fitted)
                    }
                    _ => constant(&gm, &gr),
                },
                _ => constant(&gm, &gr),
            };
            // Σ w·λ_i·μ_j·t and Σ w·μ_i·μ_j·|c|² over the patch (μ: the gain's basis, the
            // stored barycentrics; t: see below): the coupling of positions and gains.
            let mut coupling = [[[0.0f64; 3]; 3]; 3];
            let mut gain_gram = Matrix3::<f64>::zeros();
            // Summed per vertex pair (`PAIRS`, in `hp`) when the gain's basis is the pixels' own
            // barycentrics (every patch but `align`'s, whose pixels slide over the triangle).
            let on_template = system && fitted != Fitted::None && to_current.is_none();
            // Pass 2: residuals, loss, normal equations.
            for wp in warped {
                let px = &pixels[wp.index as usize];
                let mut l = [
                    px.lambda[0] as f64,
                    px.lambda[1] as f64,
                    px.lambda[2] as f64,
                ];
                if let Some(t) = &to_current {
                    let c = t * Vector3::from(l);
                    l = [c.x, c.y, c.z];
                }
                let (u, v, inv, s) = (wp.u, wp.v, wp.inv, wp.s);
                let gain =
                    px.lambda[0] * gains[0] + px.lambda[1] * gains[1] + px.lambda[2] * gains[2];
                let r = [
                    (s[0] - gain * px.color[0]) as f64,
                    (s[1] - gain * px.color[1]) as f64,
                    (s[2] - gain * px.color[2]) as f64,
                ];
                let e2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
                if let Some(h) = hist.as_mut() {
                    h.add_units(e2, units);
                }
                let (rho, w) = match opts.loss {
                    // Huber: ρ(e²) = e² below the threshold, 2δe − δ² above; IRLS weight ρ'.
                    Loss::Huber => {
                        if e2 <= hub2 {
                            (e2, 1.0)
                        } else {
                            let e = e2.sqrt();
                            (2.0 * huber * e - hub2, huber / e)
                        }
                    }
                    // Tukey: ρ(e²) = δ²/3·(1 − (1 − e²/δ²)³) below δ, δ²/3 above; ρ' = (1 − e²/δ²)².
                    // The threshold grows with the image gradient where the pixel lands: a
                    // pixel on a strong edge misaligned by `tukey_px` is kept, so the rejection
                    // picks out what the warp cannot explain, not what it has yet to align.
                    Loss::Tukey => {
                        let mut g2 = 0.0;
                        for k in 3..9 {
                            g2 += (s[k] * s[k]) as f64;
                        }
                        let d2 = hub2 + tol2 * g2;
                        pd2 += d2;
                        if e2 >= d2 {
                            acc.rejected += 1;
                        }
                        tukey(e2, d2)
                    }
                };
                pcost += rho;
                pn += 1;
                acc.pixels += 1;
                acc.weight += pw;
                if !system {
                    continue;
                }
                let gx = [s[3] as f64, s[4] as f64, s[5] as f64];
                let gy = [s[6] as f64, s[7] as f64, s[8] as f64];
                let aa = gx[0] * gx[0] + gx[1] * gx[1] + gx[2] * gx[2];
                let ab = gx[0] * gy[0] + gx[1] * gy[1] + gx[2] * gy[2];
                let bb = gy[0] * gy[0] + gy[1] * gy[1] + gy[2] * gy[2];
                let ra = gx[0] * r[0] + gx[1] * r[1] + gx[2] * r[2];
                let rb = gy[0] * r[0] + gy[1] * r[1] + gy[2] * r[2];
                // ∂û/∂X_i = λ_i·da, ∂v̂/∂X_i = λ_i·db (see `warp::pixel_derivatives`).
                let mut da = [0.0; 3];
                let mut db = [0.0; 3];
                for k in 0..3 {
                    da[k] = (m[0][k] - u * m[2][k]) * inv;
                    db[k] = (m[1][k] - v * m[2][k]) * inv;
                }
                // Σ_c J_cᵀJ_c per unit λ_i·λ_j (Eq. 5.10 summed over RGB): G = p·daᵀ + q·dbᵀ.
                let p = [
                    aa * da[0] + ab * db[0],
                    aa * da[1] + ab * db[1],
                    aa * da[2] + ab * db[2],
                ];
                let q = [
                    ab * da[0] + bb * db[0],
                    ab * da[1] + bb * db[1],
                    ab * da[2] + bb * db[2],
                ];
                let g = [
                    p[0] * da[0] + q[0] * db[0],
                    p[1] * da[1] + q[1] * db[1],
                    p[2] * da[2] + q[2] * db[2],
                    p[0] * da[1] + q[0] * db[1],
                    p[0] * da[2] + q[0] * db[2],
                    p[1] * da[2] + q[1] * db[2],
                ];
                let r3 = [
                    ra * da[0] + rb * db[0],
                    ra * da[1] + rb * db[1],
                    ra * da[2] + rb * db[2],
                ];
                let wl = [w * l[0], w * l[1], w * l[2]];
                // ∂r/∂(gain basis j) = −μ_j·c, so J_Xᵀ·J_g for vertex i, coordinate a and basis j
                // is −λ_i·μ_j·t_a with t = da·(∇_x I·c) + db·(∇_y I·c) (μ: the gain's basis,
                // the stored barycentrics), and J_gᵀ·J_g is μ_i·μ_j·|c|².
                let (t, cc) = if fitted == Fitted::None {
                    ([0.0; 3], 0.0)
                } else {
                    let c = [px.color[0] as f64, px.color[1] as f64, px.color[2] as f64];
                    let xc = gx[0] * c[0] + gx[1] * c[1] + gx[2] * c[2];
                    let yc = gy[0] * c[0] + gy[1] * c[1] + gy[2] * c[2];
                    (
                        [
                            da[0] * xc + db[0] * yc,
                            da[1] * xc + db[1] * yc,
                            da[2] * xc + db[2] * yc,
                        ],
                        c[0] * c[0] + c[1] * c[1] + c[2] * c[2],
                    )
                };
                // With pixels glued to the triangle μ = λ: the coupling is symmetric in the
                // vertex and the basis, and shares the vertex pair's weight.
                let gt = [g[0], g[1], g[2], g[3], g[4], g[5], t[0], t[1], t[2], cc];
                for (k, &(i, j)) in PAIRS.iter().enumerate() {
                    let c = wl[i] * l[j];
                    for e in 0..10 {
                        hp[k][e] += c * gt[e];
                    }
                }
                for i in 0..3 {
                    for k in 0..3 {
                        gp[i][k] += wl[i] * r3[k];
                    }
                }
                if fitted != Fitted::None && !on_template {
                    let mu = [
                        px.lambda[0] as f64,
                        px.lambda[1] as f64,
                        px.lambda[2] as f64,
                    ];
                    for i in 0..3 {
                        for j in 0..3 {
                            let f = wl[i] * mu[j];
                            for a in 0..3 {
                                coupling[i][j][a] += f * t[a];
                            }
                            gain_gram[(i, j)] += w * cc * mu[i] * mu[j];
                        }
                    }
                }
            }
            if on_template {
                for (k, &(i, j)) in PAIRS.iter().enumerate() {
                    let c = [hp[k][6], hp[k][7], hp[k][8]];
                    coupling[i][j] = c;
                    coupling[j][i] = c;
                    gain_gram[(i, j)] = hp[k][9];
                    gain_gram[(j, i)] = hp[k][9];
                }
            }
            // The gains are re-fitted at every evaluation (variable projection), so the
            // Gauss–Newton matrix of the positions alone is the Schur complement
            // H_XX − H_Xg·H_gg⁻¹·H_gX of the joint one. Without it the model sees the positions
            // as stiffer than they are along every motion a gain change mimics (a shading ramp
            // sliding over the triangle) and steps fall short, so the solve creeps. The gradient
            // needs no such term: the gains are optimal (envelope theorem).
            let gain_blocks = if system {
                gain_schur(&coupling, &gain_gram, fitted)
            } else {
                None
            };
            // Per (triangle, camera): a patch whose pixels are all kept but fit systematically
            // worse than its thresholds allow (a highlight or reflection over a whole facet, a
            // shadow: a change the warp and the gain cannot explain, yet small per pixel) is
            // down-weighted as a whole. Its cost is a Cauchy loss of its pixels' mean robust
            // cost m, `n·σ²·ln(1 + m/σ²)`, whose gradient and Gauss–Newton matrix are the
            // pixels' scaled by `1/(1 + m/σ²)`. The scale σ² is `patch_scale²` times the
            // pixels' mean Tukey threshold δ², which grows with the image gradient as the
            // pixels' own do: a well-textured patch, whose residuals are large while it is
            // still being aligned, is not the one judged unreliable.
            let n = pn.max(1) as f64;
            let s2 = patch2 * pd2 / n;
            let (pcost, pf) = if s2 > 0.0 {
                let m = pcost / n;
                (n * s2 * (m / s2).ln_1p(), 1.0 / (1.0 + m / s2))
            } else {
                (pcost, 1.0)
            };
            acc.cost += pw * pcost;
            let pw = pw * pf;
            if system {
                for k in 0..6 {
                    let e = hp[k];
                    let mut h = Matrix3::new(e[0], e[3], e[4], e[3], e[1], e[5], e[4], e[5], e[2]);
                    if let Some(g) = &gain_blocks {
                        h -= g[k];
                    }
                    acc.h[k] += h * pw;
                }
                for i in 0..3 {
                    acc.g[i] += Vector3::from(gp[i]) * pw;
                }
            }
        }
        acc
    }

    /// Cost at `x`; with `system`, also fills `a` and `b` (= −Jᵀr) of the normal equations.
    /// Also returns each triangle's photometric sums (in `by_triangle` order), from which
    /// [`Problem::confidence`] is read without another pass over the pixels.
    pub(crate) fn evaluate(
        &self,
        x: &[Point3<f64>],
        opts: &SolverOptions,
        system: Option<(&mut BlockSparse, &mut Vec<Vector3<f64>>)>,
    ) -> (f64, usize, Vec<TriAccum>) {
        let (cost, pixels, parts, _) = self.evaluate_with(x, opts, system, false);
        (cost, pixels, parts)
    }

    /// [`Problem::evaluate`], and with `median` also the weighted median residual norm at `x`
    /// (what [`Problem::median_residual`] gives, from the same pass).
    fn evaluate_with(
        &self,
        x: &[Point3<f64>],
        opts: &SolverOptions,
        system: Option<(&mut BlockSparse, &mut Vec<Vector3<f64>>)>,
        median: bool,
    ) -> (f64, usize, Vec<TriAccum>, Option<f64>) {
        let want = system.is_some();
        let on_gpu = self.gpu.and_then(|g| {
            if median {
                g.evaluate_with_histogram(x, opts, want)
                    .map(|(p, h)| (p, ResidualHistogram::from_bins(h).median()))
            } else {
                g.evaluate(x, opts, want, false).map(|p| (p, None))
            }
        });
        let (parts, median) = if let Some(done) = on_gpu {
            done
        } else if median {
            // Each worker's histogram is summed in integers, so the median does not depend on
            // how the triangles were split; the parts are put back in triangle order.
            let folded: Vec<_> = self
                .by_triangle
                .par_iter()
                .enumerate()
                .with_min_len(16)
                .fold(
                    || {
                        (
                            Vec::new(),
                            Scratch {
                                warped: Vec::new(),
                                hist: Some(ResidualHistogram::new()),
                            },
                        )
                    },
                    |(mut out, mut scratch), (i, (t, r))| {
                        out.push((i, self.triangle(*t, r, x, opts, want, &mut scratch)));
                        (out, scratch)
                    },
                )
                .map(|(out, scratch)| (out, scratch.hist))
                .collect();
            let mut hist = ResidualHistogram::new();
            let mut indexed = Vec::with_capacity(self.by_triangle.len());
            for (out, h) in folded {
                indexed.extend(out);
                if let Some(h) = h {
                    hist = hist.merge(h);
                }
            }
            indexed.sort_unstable_by_key(|&(i, _)| i);
            (
                indexed.into_iter().map(|(_, acc)| acc).collect(),
                hist.median(),
            )
        } else {
            let parts: Vec<TriAccum> = self
                .by_triangle
                .par_iter()
                .with_min_len(16)
                .map_init(Scratch::default, |scratch, (t, r)| {
                    self.triangle(*t, r, x, opts, want, scratch)
                })
                .collect();
            (parts, None)
        };
        let n = self.weighted_pixels().max(1.0);
        let inv_n = 1.0 / n;
        let mut cost = 0.0;
        let mut pixels = 0usize;
        let mut sys = system;
        if let Some((a, b)) = sys.as_mut() {
            a.clear();
            b.iter_mut().for_each(|v| *v = Vector3::zeros());
        }
        for ((t, _), acc) in self.by_triangle.iter().zip(&parts) {
            cost += acc.cost * inv_n;
            pixels += acc.pixels as usize;
            if let Some((a, b)) = sys.as_mut() {
                let tri = self.triangles[*t as usize].map(|v| v as usize);
                for (k, &(i, j)) in PAIRS.iter().enumerate() {
                    a.add_pair(tri[i], tri[j], &(acc.h[k] * inv_n));
                }
                for i in 0..3 {
                    b[tri[i]] -= acc.g[i] * inv_n;
                }
            }
        }
        for r in self.regularisers {
            cost += r.accumulate(x, sys.as_mut().map(|(a, b)| (&mut **a, &mut b[..])));
        }
        if let Some(rims) = self.rims {
            cost += rims.accumulate(x, sys.as_mut().map(|(a, b)| (&mut **a, &mut **b)), inv_n);
        }
        (cost, pixels, parts, median)
    }

    /// Cost at `x` and the normal equations there: `(cost, JᵀJ, −Jᵀr)` (for tests: the solver
    /// accumulates them in place). The cost's gradient is
    /// `2·Jᵀr`.
    #[cfg(test)]
    pub fn linearize(
        &self,
        x: &[Point3<f64>],
        opts: &SolverOptions,
    ) -> (f64, BlockSparse, Vec<Vector3<f64>>) {
        let mut a = BlockSparse::new(x.len(), self.pattern);
        let mut b = vec![Vector3::zeros(); x.len()];
        let (cost, _, _) = self.evaluate(x, opts, Some((&mut a, &mut b)));
        (cost, a, b)
    }

    /// Per vertex, how well the images constrain it at `x` ([`VertexConfidence`]): one more
    /// linearisation. The tracker reads the same from the solve's last linearisation instead
    /// ([`Problem::confidence`]), which is tested against this; the tracker calls this once, for
    /// the first frame's reference (`FrameReport::information_share`).
    pub fn vertex_confidence(
        &self,
        x: &[Point3<f64>],
        opts: &SolverOptions,
    ) -> Vec<VertexConfidence> {
        let mut a = BlockSparse::new(x.len(), self.pattern);
        let mut b = vec![Vector3::zeros(); x.len()];
        let (_, _, parts) = self.evaluate(x, opts, Some((&mut a, &mut b)));
        self.confidence_from(&parts, x.len())
    }

    /// Per vertex, how well the images constrain it at the positions `lin` was made at (what a
    /// solve returned: its result), summed per vertex in triangle order (deterministic).
    /// The share of the pixels compared at `lin` that its robust loss rejected (0 without
    /// any pixel, and always 0 with the Huber loss, which rejects none).
    pub fn rejected_share(&self, lin: &Linearised) -> f64 {
        let (rejected, pixels) = lin.parts.iter().fold((0u64, 0u64), |(r, p), a| {
            (r + u64::from(a.rejected), p + u64::from(a.pixels))
        });
        if pixels == 0 {
            0.0
        } else {
            rejected as f64 / pixels as f64
        }
    }

    pub fn confidence(&self, lin: &Linearised) -> Vec<VertexConfidence> {
        debug_assert!(
            lin.current,
            "confidence read from an approach stage's result"
        );
        self.confidence_from(&lin.parts, lin.b.len())
    }

    fn confidence_from(&self, parts: &[TriAccum], n: usize) -> Vec<VertexConfidence> {
        let mut block = vec![Matrix3::<f64>::zeros(); n];
        let mut cost = vec![0.0f64; n];
        let mut weight = vec![0.0f64; n];
        for ((t, _), acc) in self.by_triangle.iter().zip(parts) {
            let tri = self.triangles[*t as usize];
            for (i, &v) in tri.iter().enumerate() {
                // PAIRS[i] = (i, i) for i < 3: the vertex's own block.
                block[v as usize] += acc.h[i];
                cost[v as usize] += acc.cost;
                weight[v as usize] += acc.weight;
            }
        }
        (0..n)
            .map(|v| {
                let information = if weight[v] > 0.0 {
                    nalgebra::SymmetricEigen::new(block[v])
                        .eigenvalues
                        .min()
                        .max(0.0)
                } else {
                    0.0
                };
                VertexConfidence {
                    information,
                    residual: if weight[v] > 0.0 {
                        (cost[v] / weight[v]).max(0.0).sqrt()
                    } else {
                        0.0
                    },
                    pixels: weight[v],
                }
            })
            .collect()
    }

    /// Cost at `x` (no system).
    pub fn cost(&self, x: &[Point3<f64>], opts: &SolverOptions) -> f64 {
        self.evaluate(x, opts, None).0
    }

    /// [`Problem::cost`] estimated from every `every`-th triangle's pixels (in the problem's
    /// triangle order; the regularisers in full): what the frame's log reports as the cost
    /// before the frame was solved, at a quarter of a pass's price. On the CPU only.
    pub(crate) fn cost_sampled(
        &self,
        x: &[Point3<f64>],
        opts: &SolverOptions,
        every: usize,
    ) -> f64 {
        let every = every.max(1);
        let parts: Vec<(f64, f64)> = self
            .by_triangle
            .par_iter()
            .step_by(every)
            .with_min_len(16)
            .map_init(Scratch::default, |scratch, (t, r)| {
                let acc = self.triangle(*t, r, x, opts, false, scratch);
                (acc.cost, weighted_pixels_of(&self.patches[r.clone()]))
            })
            .collect();
        // Summed in triangle order: the same bits whatever the thread count.
        let (cost, weight) = parts.iter().fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        let photometric = if weight > 0.0 { cost / weight } else { 0.0 };
        let rims = self.rims.map_or(0.0, |r| {
            r.accumulate(x, None, 1.0 / self.weighted_pixels().max(1.0))
        });
        photometric
            + rims
            + self
                .regularisers
                .iter()
                .map(|r| r.accumulate(x, None))
                .sum::<f64>()
    }

    /// Minimises the cost starting from `start` over every vertex (the outer loop of §6.6).
    #[cfg(test)]
    pub fn solve(
        &self,
        start: &[Point3<f64>],
        opts: &SolverOptions,
    ) -> (Vec<Point3<f64>>, SolveSummary) {
        let (x, summary, _) = self.solve_motion(start, None, opts, Motion::Free);
        (x, summary)
    }

    /// Minimises the cost starting from `start`, moving the mesh as `motion` allows.
    ///
    /// Each iteration solves the damped normal equations for a step, predicts the decrease the
    /// Gauss–Newton model promises, and tries the step. A step that raises the cost is not just
    /// retried with more damping: the next try is also shortened (×¼ per rejection). Damping
    /// alone cannot shorten a step against a term whose curvature the model does not see (the
    /// cubic springs have none at rest), and since the step is a descent direction of the true
    /// cost (the gradient is exact; only the curvature is approximate), a short enough step
    /// always lowers it: this backtracking is what makes "a step that lowers the model lowers
    /// the cost" hold for every regulariser.
    ///
    /// `at_start` is the problem already linearised at `start` (what a previous solve of the
    /// same problem returned), which saves one evaluation; the solve returns the linearisation
    /// at its result.
    pub fn solve_motion(
        &self,
        start: &[Point3<f64>],
        at_start: Option<Linearised>,
        opts: &SolverOptions,
        motion: Motion,
    ) -> (Vec<Point3<f64>>, SolveSummary, Linearised) {
        self.solve_stage(start, at_start, opts, motion, StageRole::default())
    }

    /// [`Problem::solve_motion`] in the role `role` plays in a frame's solve (see [`StageRole`]).
    pub(crate) fn solve_stage(
        &self,
        start: &[Point3<f64>],
        at_start: Option<Linearised>,
        opts: &SolverOptions,
        motion: Motion,
        role: StageRole,
    ) -> (Vec<Point3<f64>>, SolveSummary, Linearised) {
        let collect_median = role.collect_median;
        // An adaptive loss is re-scaled here (from the median the linearisation at the start
        // carries, when it does), so a linearisation made with another scale is not reused.
        let opts = &match (opts.loss, at_start.as_ref().and_then(|l| l.median)) {
            (Loss::Tukey, Some(m)) => self.tukey_options(m, opts),
            _ => self.solve_options(start, opts),
        };
        // Reused only with the same loss, and only when it holds the normal equations there.
        let at_start = at_start.filter(|l| opts.loss == Loss::Huber && l.current);
        let nv = start.len();
        let mut x = start.to_vec();
        let t_solve = Instant::now();
        // The normal equations, cost and per-triangle sums at `x`, kept current as steps are
        // accepted; the solve returns them.
        let mut evaluation_seconds = 0.0;
        let mut linear_solver_seconds = 0.0;
        let (mut cur, mut pixel_evaluations) = match at_start {
            Some(l) => (l, 0u64),
            None => {
                let te = Instant::now();
                let mut a = BlockSparse::new(nv, self.pattern);
                let mut b = vec![Vector3::zeros(); nv];
                let (cost, pixels, parts, median) =
                    self.evaluate_with(&x, opts, Some((&mut a, &mut b)), collect_median);
                evaluation_seconds += te.elapsed().as_secs_f64();
                (
                    Linearised {
                        a,
                        b,
                        cost,
                        pixels,
                        parts,
                        median,
                        current: true,
                    },
                    pixels as u64,
                )
            }
        };
        let initial_cost = cur.cost;
        let mut iterations = Vec::new();
        let summary = |x, cur: Linearised, pixel_evaluations, stop, iterations, (ev, ls)| {
            (
                x,
                SolveSummary {
                    interpolation: opts.interpolation,
                    motion,
                    initial_cost,
                    final_cost: cur.cost,
                    pixels: cur.pixels,
                    pixel_evaluations,
                    seconds: t_solve.elapsed().as_secs_f64(),
                    evaluation_seconds: ev,
                    linear_solver_seconds: ls,
                    stop,
                    iterations,
                },
                cur,
            )
        };
        if (cur.pixels == 0 && self.regularisers.is_empty()) || !cur.cost.is_finite() {
            let stop = if cur.cost.is_finite() {
                StopReason::NoData
            } else {
                StopReason::NonFinite
            };
            return summary(
                x,
                cur,
                pixel_evaluations,
                stop,
                iterations,
                (evaluation_seconds, 0.0),
            );
        }
        let mut lm = opts.damping;
        let mut shrink = 1.0f64;
        let mut rejections = 0;
        let mut stop = StopReason::MaxIterations;
        // Levenberg–Marquardt damping adds lm·(diag(A) + mean diagonal): the relative part
        // respects each vertex's own scale, the absolute part tames directions the images barely
        // see (depth along a narrow baseline, sliding along an edge of the texture) and keeps
        // vertices without any data well posed.
        let mean_diag =
            (0..nv).map(|i| cur.a.diagonal(i).trace()).sum::<f64>() / (3 * nv.max(1)) as f64;
        let mean_diag = mean_diag.max(1e-30);
        let mut ad = vec![Vector3::zeros(); nv];
        // The trial point's system is built here and swapped in when the step is accepted.
        let mut a_new = cur.a.clone();
        let mut b_new = vec![Vector3::zeros(); nv];
        let mut trial = x.clone();
        // The mesh's distance from each camera where the stage starts (its centroid's depth).
        let start_depth: Vec<f64> = {
            let c = centroid(start);
            self.projections.iter().map(|p| p.depth(&c)).collect()
        };
        for it in 0..opts.max_iterations {
            if self.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                stop = StopReason::Cancelled;
                break;
            }
            let t0 = Instant::now();
            let tl = Instant::now();
            // The step (linearised, per vertex) and the trial positions.
            let (delta, cg_iterations, settled) = match motion {
                Motion::Free => {
                    let mut damped = cur.a.clone();
                    damped.damp(lm * mean_diag, lm);
                    // A full step is taken only if it promises a decrease of at least
                    // `min_relative_decrease` (below): the conjugate gradients stop as soon as
                    // their decrease has settled below half of that, which is how most stages
                    // end (the step after the last accepted one only says "converged").
                    let stop = CgStop {
                        unpromising_below: (shrink == 1.0)
                            .then_some(opts.min_relative_decrease * cur.cost),
                        ..CgStop::residual(opts.cg_tolerance, opts.cg_max_iterations)
                    };
                    // On the GPU when the problem's evaluations are there and the system is
                    // large enough: the same step to the bit (`gpu::cg`).
                    let (mut delta, cg) = self
                        .gpu
                        .and_then(|g| g.solve_pcg(&damped, &cur.b, stop))
                        .unwrap_or_else(|| solve_pcg_until(&damped, &cur.b, stop));
                    delta.iter_mut().for_each(|d| *d *= shrink);
                    for ((t, p), d) in trial.iter_mut().zip(&x).zip(&delta) {
                        *t = p + d;
                    }
                    (delta, cg.iterations, cg.unpromising.then_some(cg.decrease))
                }
                Motion::Rigid | Motion::Similarity => {
                    let scale = motion == Motion::Similarity;
                    let rigid = RigidStep::solve(&cur.a, &cur.b, &x, lm, scale, self.gauge_floor);
                    let xi = rigid.xi * shrink;
                    let delta = rigid.linear(&x, &xi);
                    rigid.apply(&x, &xi, &mut trial);
                    (delta, 0, None)
                }
            };
            linear_solver_seconds += tl.elapsed().as_secs_f64();
            let step = delta.iter().map(|d| d.norm()).fold(0.0, f64::max);
            // Decrease predicted by the Gauss–Newton model: 2·δᵀ(−Jᵀr) − δᵀ·JᵀJ·δ; when the
            // conjugate gradients stopped on their own verdict, their settled decrease.
            let predicted: f64 = match settled {
                Some(d) => d,
                None => {
                    cur.a.mul(&delta, &mut ad);
                    delta
                        .iter()
                        .zip(&cur.b)
                        .zip(&ad)
                        .map(|((d, b), ad)| 2.0 * d.dot(b) - d.dot(ad))
                        .sum()
                }
            };
            // A full step that promises almost nothing means convergence; a shortened one only
            // means it is time to stop shortening.
            // (NaN counts as "promises nothing".)
            let promising = predicted > opts.min_relative_decrease * cur.cost;
            if !promising {
                iterations.push(IterationSummary {
                    iteration: it + 1,
                    cost: cur.cost,
                    cost_change: 0.0,
                    model_change: -predicted,
                    step,
                    accepted: false,
                    damping: lm,
                    cg_iterations,
                    seconds: t0.elapsed().as_secs_f64(),
                });
                stop = if shrink < 1.0 {
                    StopReason::CostRose
                } else {
                    StopReason::Converged
                };
                break;
            }
            // An approach stage tries its full steps without building the normal equations at
            // the trial point when the step could end it: if the step lowers the cost as its
            // model promised, the stage ends there (below) and nothing would use them; otherwise
            // they are built then. (Even the least decrease that counts as agreeing must leave
            // the next step's share of it below the threshold.)
            let least = (1.0 - AGREEMENT) * predicted;
            let light = role.approach
                && shrink == 1.0
                && motion == Motion::Free
                && NEXT_SHARE * least <= opts.min_relative_decrease * (cur.cost - least);
            let te = Instant::now();
            let (new_cost, new_pixels, mut new_parts, new_median) = if light {
                self.evaluate_with(&trial, opts, None, collect_median)
            } else {
                self.evaluate_with(&trial, opts, Some((&mut a_new, &mut b_new)), collect_median)
            };
            evaluation_seconds += te.elapsed().as_secs_f64();
            pixel_evaluations += new_pixels as u64;
            let change = new_cost - cur.cost;
            // A step that takes the mesh more than twice as far from a camera, or brings it
            // within half the distance, is refused whatever the cost says: no frame of real
            // footage moves a surface that far along the rays, and the cost can be fooled there
            // (beyond the capture range a rigid step once carried a cloth 40 times as far away,
            // where every template pixel, squeezed into a few blurred ones, fitted about as
            // well as the misaligned surface did).
            let near_start = {
                let c = centroid(&trial);
                self.projections.iter().zip(&start_depth).all(|(p, &d0)| {
                    d0.is_nan() || d0 <= 0.0 || (0.5 * d0..=2.0 * d0).contains(&p.depth(&c))
                })
            };
            let accepted = new_cost < cur.cost && near_start;
            let prev_cost = cur.cost;
            // The step did what its model promised: the model is good to a tenth along it, and
            // the next step, which would start from what the model missed, would promise a
            // small share of this one's decrease (about (9/4)·(1 − agreement)² of it for a cost
            // that departs from its model cubically; at most 1.2 % measured on the bench cloth's
            // approach stages), below what the stage goes on for.
            let ends = light
                && accepted
                && (-change / predicted - 1.0).abs() <= AGREEMENT
                && NEXT_SHARE * -change <= opts.min_relative_decrease * new_cost;
            // An accepted step that decreased the cost by less than the threshold ends the
            // stage in any case (below): no equations are needed there either.
            let small = accepted && -change < opts.min_relative_decrease * prev_cost;
            let ends_light = ends || (light && small);
            if light && accepted && !ends_light {
                // The stage goes on from the trial point: its normal equations are needed.
                let te = Instant::now();
                new_parts = self
                    .evaluate_with(&trial, opts, Some((&mut a_new, &mut b_new)), false)
                    .2;
                evaluation_seconds += te.elapsed().as_secs_f64();
                pixel_evaluations += new_pixels as u64;
            }
            if accepted {
                std::mem::swap(&mut x, &mut trial);
                if ends_light {
                    // The equations held are the previous point's; nothing reuses them.
                    cur.current = false;
                } else {
                    std::mem::swap(&mut cur.a, &mut a_new);
                    std::mem::swap(&mut cur.b, &mut b_new);
                }
                cur.pixels = new_pixels;
                cur.parts = new_parts;
                cur.median = new_median;
                cur.cost = new_cost;
                rejections = 0;
                lm = (lm / 3.0).max(1e-7);
                shrink = (shrink * 4.0).min(1.0);
            } else {
                rejections += 1;
                lm = (lm * 10.0).max(1e-3);
                shrink *= 0.25;
            }
            iterations.push(IterationSummary {
                iteration: it + 1,
                cost: cur.cost,
                cost_change: change,
                model_change: -predicted,
                step,
                accepted,
                damping: lm,
                cg_iterations,
                seconds: t0.elapsed().as_secs_f64(),
            });
            if ends || small {
                stop = StopReason::Converged;
                break;
            }
            if rejections >= opts.max_rejections {
                stop = StopReason::CostRose;
                break;
            }
        }
        summary(
            x,
            cur,
            pixel_evaluations,
            stop,
            iterations,
            (evaluation_seconds, linear_solver_seconds),
        )
    }
}

/// The problem linearised at some positions: the normal equations there, the cost and the
/// pixels compared.
pub(crate) struct Linearised {
    a: BlockSparse,
    b: Vec<Vector3<f64>>,
    cost: f64,
    pixels: usize,
    /// Each triangle's photometric sums there (for [`Problem::confidence`]).
    parts: Vec<TriAccum>,
    /// The weighted median residual norm there, when the solve was asked to collect it.
    median: Option<f64>,
    /// Whether `a` and `b` are the normal equations there. An approach stage that ended on a
    /// step its model predicted ([`StageRole::approach`]) returns the cost, pixels and median at
    /// its result but the equations of the point before; they are not reused.
    current: bool,
}

/// What a stage of a frame's solve is for, besides its own result ([`Problem::solve_stage`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct StageRole {
    /// Every evaluation also takes the median residual, so that the returned linearisation
    /// carries it at the result (a Tukey solve started there then needs no pass of its own
    /// for its threshold).
    pub collect_median: bool,
    /// An approach stage: a finer level or the robust refine follows and linearises afresh,
    /// so the stage ends at its first full step whose decrease agrees with its model within
    /// [`AGREEMENT`], unless a step after it could still promise its threshold, and such a
    /// step is tried without building the normal equations at the trial point (a pass over
    /// the pixels without the Jacobian: about 45 % of one with it).
    pub approach: bool,
}

/// The pixels of `patches` counted at their patches' weights: what the photometric cost is a
/// mean over.
fn weighted_pixels_of(patches: &[Patch]) -> f64 {
    patches
        .iter()
        .map(|p| p.weight as f64 * (p.end - p.start) as f64)
        .sum()
}

/// How closely an approach stage's step must lower the cost as its Gauss–Newton model
/// predicted (relative) for the stage to end on it ([`StageRole::approach`]).
const AGREEMENT: f64 = 0.1;

/// The share of an agreeing step's decrease that the next step is taken to promise at most
/// ([`StageRole::approach`]): about (9/4)·(1 − ρ)² for a model off by 1 − ρ along the step with
/// a cubic departure (2.3 % at ρ = 0.9), with room for the robust loss's weights changing under
/// the step (the bench cloth's approach stages: 0.5–1.2 %).
const NEXT_SHARE: f64 = 0.05;

#[cfg(test)]
impl Linearised {
    pub fn median(&self) -> Option<f64> {
        self.median
    }
}

/// How the mesh may move in one solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Motion {
    /// One rotation and translation of the whole mesh (6 unknowns): the images of every
    /// triangle pull together, so large motion is caught before any vertex moves on its own.
    Rigid,
    /// Every vertex on its own (3 unknowns each), held together by the regularisers.
    Free,
    /// A rigid motion and one uniform scale about the centroid (7 unknowns): `align` with
    /// `--scale`.
    Similarity,
}

/// A rigid step (rotation ω about the centroid `c`, translation v, and with
/// [`Motion::Similarity`] a log-scale σ), from the vertex normal equations projected onto those
/// motions: with `G` the 3N×k map from ξ = (ω, v, σ) to vertex displacements
/// `ω×(X_i − c) + v + σ·(X_i − c)`, it solves `(GᵀAG + λ·diag)·ξ = Gᵀb`. `GᵀAG` is formed from
/// k products `A·g_k` (written by hand: at most 7×7, no crate needed beyond nalgebra's solve).
struct RigidStep {
    c: Vector3<f64>,
    xi: Vector7,
}

type Vector7 = nalgebra::SVector<f64, 7>;
type Matrix7 = nalgebra::SMatrix<f64, 7, 7>;

/// `GᵀAG` and `Gᵀb` of the whole-mesh motions at `x` (see [`RigidStep`]); with `scale` false
/// the seventh row and column are zero.
fn pose_system(
    a: &BlockSparse,
    b: &[Vector3<f64>],
    x: &[Point3<f64>],
    scale: bool,
) -> (Vector3<f64>, Matrix7, Vector7) {
    let c = centroid(x).coords;
    let k = if scale { 7 } else { 6 };
    let g = RigidStep::generators(x, &c, k);
    let mut ag = vec![Vector3::zeros(); x.len()];
    let mut m = Matrix7::zeros();
    let mut r = Vector7::zeros();
    for l in 0..k {
        a.mul(&g[l], &mut ag);
        for i in 0..k {
            m[(i, l)] = g[i].iter().zip(&ag).map(|(u, v)| u.dot(v)).sum();
        }
        r[l] = g[l].iter().zip(b).map(|(u, v)| u.dot(v)).sum();
    }
    (c, (m + m.transpose()) * 0.5, r)
}

/// The diagonal scaling that turns the pose coordinates (ω, v, σ) into length units: a unit
/// rotation or log-scale moves the mesh's points by its RMS radius.
fn length_units(x: &[Point3<f64>], c: &Vector3<f64>) -> Matrix7 {
    let r = rms_radius(x, &Point3::from(*c));
    let inv = if r > 0.0 { 1.0 / r } else { 1.0 };
    Matrix7::from_diagonal(&Vector7::from([inv, inv, inv, 1.0, 1.0, 1.0, inv]))
}

impl RigidStep {
    /// The first `k` generators: rotations about x, y, z through `c`, translations, scale.
    fn generators(x: &[Point3<f64>], c: &Vector3<f64>, k: usize) -> Vec<Vec<Vector3<f64>>> {
        (0..k)
            .map(|k| {
                x.iter()
                    .map(|p| match k {
                        0..=2 => Vector3::ith(k, 1.0).cross(&(p.coords - c)),
                        3..=5 => Vector3::ith(k - 3, 1.0),
                        _ => p.coords - c,
                    })
                    .collect()
            })
            .collect()
    }

    /// With `floor` > 0, the step has no component along the motions whose curvature is below
    /// `floor` times the largest (eigenvectors of the damped `GᵀAG`): motions the images do not
    /// fix stay where they started instead of wandering with noise (`align`). The tracker uses
    /// 0 (a plain Cholesky solve).
    fn solve(
        a: &BlockSparse,
        b: &[Vector3<f64>],
        x: &[Point3<f64>],
        lm: f64,
        scale: bool,
        floor: f64,
    ) -> Self {
        let (c, m, r) = pose_system(a, b, x, scale);
        let tr = m.trace().max(1e-300);
        let mut damped = m;
        for k in 0..7 {
            damped[(k, k)] += lm * m[(k, k)] + 1e-12 * tr;
        }
        if !scale {
            damped[(6, 6)] = 0.0;
        }
        let xi = if floor > 0.0 {
            // In length units (rotations and scale per the mesh's RMS radius), so that the
            // curvatures compare whatever the mesh's size. The motions to leave out are those
            // of the *undamped* curvature (damping would lift a free motion that mixes axes
            // above the floor while it is large); the damped system is then solved within the
            // motions kept.
            let d = length_units(x, &c);
            let mut mu = d * m * d;
            if !scale {
                for k in 0..7 {
                    mu[(6, k)] = 0.0;
                    mu[(k, 6)] = 0.0;
                }
            }
            let eig = mu.symmetric_eigen();
            let top = eig.eigenvalues.max();
            let kept: Vec<usize> = (0..7)
                .filter(|&k| eig.eigenvalues[k] > floor * top)
                .collect();
            let v =
                nalgebra::DMatrix::from_fn(7, kept.len(), |i, j| eig.eigenvectors[(i, kept[j])]);
            let ddd = d * damped * d;
            let dd = nalgebra::DMatrix::from_fn(7, 7, |i, j| ddd[(i, j)]);
            let rd = nalgebra::DVector::from_iterator(7, (d * r).iter().copied());
            let sub = v.transpose() * dd * &v;
            let rhs = v.transpose() * rd;
            sub.cholesky().map(|ch| {
                let eta = &v * ch.solve(&rhs);
                d * Vector7::from_iterator(eta.iter().copied())
            })
        } else {
            if !scale {
                damped[(6, 6)] = 1.0;
            }
            damped.cholesky().map(|ch| ch.solve(&r))
        };
        let xi = xi
            .filter(|v| v.iter().all(|e| e.is_finite()))
            .unwrap_or_else(Vector7::zeros);
        RigidStep { c, xi }
    }

    /// The step's first-order vertex displacements (for the model's predicted decrease).
    fn linear(&self, x: &[Point3<f64>], xi: &Vector7) -> Vec<Vector3<f64>> {
        let w = Vector3::new(xi[0], xi[1], xi[2]);
        let v = Vector3::new(xi[3], xi[4], xi[5]);
        x.iter()
            .map(|p| {
                let d = p.coords - self.c;
                w.cross(&d) + v + d * xi[6]
            })
            .collect()
    }

    /// The exact motion: `c + e^σ·R(ω)(X − c) + v` (edge lengths unchanged when σ = 0).
    fn apply(&self, x: &[Point3<f64>], xi: &Vector7, out: &mut [Point3<f64>]) {
        let r = nalgebra::Rotation3::new(Vector3::new(xi[0], xi[1], xi[2]));
        let v = Vector3::new(xi[3], xi[4], xi[5]);
        let s = xi[6].exp();
        for (o, p) in out.iter_mut().zip(x) {
            *o = Point3::from(self.c + r * (p.coords - self.c) * s + v);
        }
    }
}

/// How firmly the images hold each whole-mesh motion at a linearisation: the eigenvalues of
/// `GᵀJᵀJG` (see [`RigidStep`]; rotations about the centroid, translations and, with `scale`,
/// the log-scale, in length units — see [`length_units`] — so that they compare), smallest
/// first, each relative to the largest, with its eigenvector `(ω·r, v, σ·r)`.
pub(crate) fn pose_stiffness(
    lin: &Linearised,
    x: &[Point3<f64>],
    scale: bool,
) -> Vec<(f64, [f64; 7])> {
    debug_assert!(
        lin.current,
        "pose stiffness read from an approach stage's result"
    );
    let (c, m, _) = pose_system(&lin.a, &lin.b, x, scale);
    let d = length_units(x, &c);
    let m = d * m * d;
    let k = if scale { 7 } else { 6 };
    let e = m.fixed_view::<6, 6>(0, 0).into_owned();
    let mut out: Vec<(f64, [f64; 7])> = if scale {
        let eig = m.symmetric_eigen();
        (0..k)
            .map(|i| {
                let v = eig.eigenvectors.column(i);
                (eig.eigenvalues[i], std::array::from_fn(|j| v[j]))
            })
            .collect()
    } else {
        let eig = e.symmetric_eigen();
        (0..k)
            .map(|i| {
                let v = eig.eigenvectors.column(i);
                (
                    eig.eigenvalues[i],
                    std::array::from_fn(|j| if j < 6 { v[j] } else { 0.0 }),
                )
            })
            .collect()
    };
    let top = out.iter().map(|o| o.0).fold(0.0, f64::max);
    if top.is_nan() || top <= 0.0 {
        return Vec::new();
    }
    for o in &mut out {
        o.0 = (o.0 / top).max(0.0);
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

#[cfg(test)]
mod histogram_tests {
    use super::ResidualHistogram as H;

    #[test]
    fn bins_are_the_logarithmic_ones_found_without_a_logarithm() {
        // The bin the definition gives, floor((log10(√e²) − LOG_MIN)·PER_DECADE) clamped, for
        // norms from 1e-6 to 100 (past both ends), 20 000 of them on a log scale with an
        // irrational step; a norm within 1e-12 of an edge may fall on either side.
        let by_log = |e2: f64| {
            let l = 0.5 * e2.log10();
            ((l - H::LOG_MIN) * H::PER_DECADE)
                .floor()
                .clamp(0.0, (H::BINS - 1) as f64) as usize
        };
        let mut checked = 0;
        for i in 0..20_000 {
            let norm =
                10f64.powf(-6.0 + i as f64 * 8.0 / 20_000.0 * std::f64::consts::FRAC_1_SQRT_2);
            let e2 = norm * norm;
            let near_edge = H::edges().iter().any(|&e| ((e2 - e) / e).abs() < 1e-12);
            if !near_edge {
                assert_eq!(H::bin(e2), by_log(e2), "norm {norm:e}");
                checked += 1;
            }
        }
        assert!(checked > 19_900);
        // The table's start and its comparisons count what a binary search counts, at every
        // edge, one unit in the last place either side of it, and between.
        let search = |e2: f64| H::edges().partition_point(|&edge| edge <= e2);
        for (i, &e) in H::edges().iter().enumerate() {
            for v in [
                e,
                f64::from_bits(e.to_bits() - 1),
                f64::from_bits(e.to_bits() + 1),
                e * 1.01,
                e * 0.99,
            ] {
                assert_eq!(H::bin(v), search(v), "edge {i}: {v:e}");
            }
        }
        for v in [
            0.0,
            -1.0,
            1e-300,
            1e300,
            f64::INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
        ] {
            assert_eq!(H::bin(v), search(v), "{v:e}");
        }
        // Exact zero and NaN go to the first bin, anything huge to the last.
        assert_eq!(H::bin(0.0), 0);
        assert_eq!(H::bin(f64::NAN), 0);
        assert_eq!(H::bin(1e10), H::BINS - 1);
        // The median of one pixel of norm 0.05 lies in that pixel's bin.
        let mut h = H::new();
        h.add_units(0.05 * 0.05, H::units(1.0));
        let m = h.median().unwrap();
        assert!((0.05 / m).log10().abs() < 1.0 / H::PER_DECADE, "{m}");
    }
}

//! The tracker: runs the per-frame solver over a shot (thesis §6.6, "the next frame starts from
//! the solved one").
//!
//! For each new frame it builds image pyramids, compares the new frame against two templates —
//! the previous frame (the thesis' method) and the first frame of the shot (so that small errors
//! do not accumulate into drift; the thesis' Fig. 7.7 shows that they otherwise do) — and solves
//! coarse to fine. Each frame uses every camera's own projection at that frame. A constant-velocity
//! prediction is tried as the starting guess and kept only if it matches the images better than
//! the previous positions.
//!
//! [`Tracker`] works in memory (images in, positions out); `shot::track_scene` drives it over a
//! scene on disk into a run folder.

use crate::base::camera::{Camera, Projection};
use crate::base::image::{BlockMeans, RgbImage};
use crate::base::mesh::Mesh;
use crate::base::raster::{rasterize, IndexBuffer};
use crate::error::{Error, Result};
use crate::tracker::align;
use crate::tracker::align::FirstMeshCheck;
use crate::tracker::balance;
use crate::tracker::consensus::{drop_contradicted_ahead, CameraShare, ConsensusOptions};
use crate::tracker::fold::FoldWatch;
use crate::tracker::gpu::Gpu;
use crate::tracker::health;
use crate::tracker::health::LastFrameCheck;
use crate::tracker::occluder::{self, Ahead, Way};
use crate::tracker::occlusion;
use crate::tracker::offset::{moved_onto_surface, moved_onto_surface_as_checked, SurfaceMove};
use crate::tracker::options::{OptionsUsed, TrackOptions};
use crate::tracker::patch::{CameraPatches, Patch, PatchOptions, PatchSet};
use crate::tracker::pyramid::{camera_level, level_skips, Pyramid};
use crate::tracker::regularise::{self, EdgeSet, FrameContext, Regulariser};
use crate::tracker::rim;
use crate::tracker::shift::CameraShifts;
use crate::tracker::smear::{self, Velocities};
use crate::tracker::solve::{
    moved_on, Interpolation, Lag, Loss, Motion, Problem, SolveSummary, SolverOptions, StageRole,
    StopReason, VertexConfidence,
};
use crate::tracker::steady;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

/// What happened in one frame (the frame and its timing are the caller's: see
/// `run::FrameLog`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameReport {
    /// Gauss–Newton iterations over all levels.
    pub iterations: usize,
    /// Cost at the previous frame's positions (no deformation), finest level.
    pub cost_before: f64,
    /// Cost at the solution, finest level.
    pub cost_after: f64,
    /// Pixels compared at the solution, finest level.
    pub pixels: usize,
    /// Pixels of the previous frame's template at the finest level that every other camera
    /// seeing the same surface point contradicted (an occluder, a highlight), left out
    /// (`TrackOptions::consensus`).
    #[serde(default)]
    pub contradicted: usize,
    /// `contradicted` as a share of the pixels that template took (0 to 1).
    #[serde(default)]
    pub contradicted_share: f64,
    /// The same share for the first frame's template, where the mesh is given lined up: this
    /// footage's own level of disagreement between cameras.
    #[serde(default)]
    pub contradicted_at_first: f64,
    /// `contradicted_share` camera by camera: per camera, the share of its own pixels in that
    /// template that the other cameras contradicted. A camera knocked off its calibration in
    /// front of a plain background (where `moved_cameras` has nothing to see it by) raises the
    /// shares of the cameras whose view of the surface only it checks, frame after frame, while
    /// the rig's share stays within its footage's level ([`health::DISAGREE_RISE`]). Over the
    /// pixels the camera took before the check (the rig's share is over those left after the
    /// still occluders' are left out too). `null` for a camera that took none (left out, blank,
    /// out of view). Absent with one camera, without anchors (`--anchor-weight 0`, no first
    /// frame's template to compare with) and in logs written before 2026-12-03.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub contradicted_by_camera: Vec<Option<f64>>,
    /// The same per camera at the first frame, where the mesh is given lined up.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub contradicted_by_camera_at_first: Vec<Option<f64>>,
    /// Pixels of the finest level's templates (previous frame and anchor) whose surface point
    /// another part of the mesh hides in this frame, or lies at one of the mesh's depth edges
    /// here, judged from the mesh where that level started (an arm in front of the body, a fold
    /// turned over), left out (`TrackOptions::hidden_ahead`). 0 in logs written before it
    /// existed.
    #[serde(default)]
    pub hidden: usize,
    /// Pixels of the finest level's templates (previous frame and anchor) whose way into this
    /// frame crosses an occluder that stands still in front of the surface (a rod, a frame
    /// edge: `tracker::occluder`), left out (`TrackOptions::still_occluders`). 0 in logs
    /// written before it existed.
    #[serde(default)]
    pub near_still: usize,
    /// Pairs of neighbouring triangles that faced within 60° of each other in the first frame's
    /// mesh and face more than 120° apart at the solution: where the mesh has folded over
    /// itself (`tracker::fold`). 0 in logs written before it existed.
    #[serde(default)]
    pub folded: usize,
    /// How much the images constrain the solution, as a share of what the first frame's own
    /// images give its mesh: the sum over the vertices of the smallest eigenvalue of each
    /// vertex's photometric normal-equation block (the confidence file's `information`), at the
    /// solution against the same sum for the first frame's templates compared with the first
    /// frame itself (under an open shutter, times the share of texture the smeared images kept:
    /// `smear::Texture::kept`). Logs written before it existed read as 1.
    #[serde(default = "one")]
    pub information_share: f64,
    /// The frame may be wrong, by its own report (`health::own_concerns`): `contradicted_share`
    /// rose more than [`health::SUSPECT_RISE`] above `contradicted_at_first` (the cameras
    /// disagree about where the previous frame left the surface, so this frame started from a
    /// doubtful place), or `information_share` is below [`health::INFORMATION_FLOOR`] (the mesh
    /// sees next to none of the surface's texture). The previous frame is then in doubt too; the
    /// whole rule is [`health::check_reports`] over reports, `run::frames_to_check` over a run folder. The frame is solved as any
    /// other; reported as a warning.
    #[serde(default)]
    pub suspect: bool,
    /// The share of the pixels compared at the solution, finest level, that the robust loss
    /// rejected as unexplained (0 to 1; 0 with `--loss huber`).
    #[serde(default)]
    pub rejected_share: f64,
    /// The cameras (indices) whose image of this frame is blank (`image::blank_images`: black,
    /// capped, blown out): left out of the frame, as target and as the next frame's template.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub blank_cameras: Vec<u16>,
    /// The cameras (indices) whose image of this frame repeats their image of the previous frame
    /// solved, over the mesh's window, while another camera's view of the mesh changed
    /// (`health::REPEAT_CHANGE`; a dropped frame filled in by the recorder, a stream that
    /// froze): left out of the frame as a blank one is (docs/tracker.md, "Repeated frames").
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub repeated_cameras: Vec<u16>,
    /// The cameras (indices) that repeated a frame and, at this one, agree with the other
    /// cameras' *previous* frame at the previous solution clearly better than with their
    /// frame at this solution (`health::LATE_RATIO`): the camera runs a frame late since the
    /// repeat, and its images pull the mesh back (docs/tracker.md, "Repeated frames").
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub late_cameras: Vec<u16>,
    /// The cameras (indices) found running a frame early (a frame they dropped without
    /// repeating one): their image of the previous frame agreed with the other cameras' images
    /// of this one clearly better than their own image of this frame did
    /// (`health::LATE_RATIO`). From the frame they are found in (solved again) on, each
    /// frame takes their file for the frame before as their image of it; listed at each
    /// (docs/tracker.md, "A camera that runs a frame early").
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub early_cameras: Vec<u16>,
    /// The cameras (indices) found at this frame to have shown the previous frame a frame
    /// ahead: found running early here (also in `early_cameras`), or repeating here what they
    /// showed there after their view leapt (one frame swapped in). The previous frame was
    /// solved with their image a frame ahead, so its mesh is likely off (it is flagged).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ahead_cameras: Vec<u16>,
    /// Per camera, how much its view of the mesh changed since the previous frame solved: the
    /// RMS change of its 8×8-pixel block means (0–1 luminance) over the window the mesh covered
    /// there (`null`: not measured, e.g. a blank image; and for a camera found early or taken
    /// as it is again at this frame, whose image is not the one after the previous frame's). A
    /// camera whose change leaps against the others' (`health::LEAP_RATIO`) is checked at
    /// the next frame for running early.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub view_changes: Vec<Option<f64>>,
    /// The cameras (indices) taken a frame back since an earlier frame that are taken as they
    /// are again from this frame on: their own file of this frame agrees with the other
    /// cameras clearly better than the one taken back (`health::LATE_RATIO`: the alarm was
    /// false, or the camera caught up; the frame is solved again without its template), or
    /// the file it would be taken back to repeats the one the previous frame was solved with
    /// while the others moved (it caught up by writing a frame twice). The frames in between
    /// are in doubt.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rejoined_cameras: Vec<u16>,
    /// The cameras (indices) whose view leapt at this frame (`health::growth_of`): checked at
    /// the next frame for running a frame early (never after a stalled frame, nor a camera
    /// found late).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub leapt_cameras: Vec<u16>,
    /// Per camera, its colour balance against the first frame after this frame (red, green,
    /// blue; luminance 1): what the next frame's images are divided by, so that every
    /// comparison is made in the colours the camera had at the first frame (docs/tracker.md,
    /// "Colour balance"). Absent before the first frame is read, and in logs written before
    /// 2026-11-29 (read as no change).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub colour_balance: Vec<[f64; 3]>,
    /// Per camera, the last readings of its colour balance (up to three, oldest first: what
    /// each of the last frames' images showed) whose median is `colour_balance`; what
    /// `--resume` continues from.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub colour_readings: Vec<Vec<[f64; 3]>>,
    /// The cameras (indices) found turned at this frame by their view of the background, which
    /// moved against their first frame's by more than `steady::MOVED_PX` from where the
    /// tracker had them (a knock on a tripod, a slipping mount): the frame is solved with each
    /// one's pose turned to match, and so is every later frame (docs/tracker.md, "A camera that
    /// moves").
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub moved_cameras: Vec<u16>,
    /// For each of `moved_cameras`, how far its turn moved its image (RMS over the image,
    /// full-resolution pixels).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub moved_px: Vec<f64>,
    /// Per camera, the turn about its own centre since it was calibrated that the tracker uses
    /// at this frame (a rotation vector in the camera's own axes, radians: its world-to-camera
    /// rotation is `exp(turn)·R`); absent while no camera has turned.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub camera_turns: Vec<[f64; 3]>,
    /// How far the solution is from where the previous frames' motion would have put it: the
    /// RMS over the vertices of its distance from the constant-velocity prediction (the
    /// previous frame's motion carried on, from rest after the given mesh), that is of the
    /// change in velocity, as a share of the previous shape's bounding-box diagonal. Above
    /// `health::JUMP_SHARE` the mesh leapt farther in one frame than anything the tracker can
    /// follow does: it slipped onto something else. 0 for a stalled frame and in logs written
    /// before it existed.
    #[serde(default)]
    pub jump: f64,
    /// Why the finest level stopped.
    pub stop: StopReason,
    /// Whether the constant-velocity prediction was used as the start.
    pub predicted: bool,
    /// Where the coarsest level moved the mesh by [`SECOND_START_PX`] or more at the next
    /// level without lowering that level's cost below [`SECOND_START_GAIN`] of its cost at the
    /// coarsest level's start, that level was also solved from the coarsest level's start (as
    /// the coarsest is: its rigid stage first), and the start whose solution costs less there
    /// was kept:
    /// `"kept"` (the second start's: the coarsest level had led off), `"not_kept"`; absent when
    /// not tried (docs/tracker.md, "A second start after the coarsest level"). `levels` then
    /// holds both solves of that level, the second start's after the first's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub second_start: Option<SecondStart>,
    /// The solver could not lower the cost at any level (every step, shortened down to 1/64,
    /// raised it, or the cost was not finite), or no pixel was compared at full resolution
    /// (`pixels` 0: the mesh is out of every camera's view): the mesh kept its starting
    /// positions. Reported as a warning; `--strict` fails the run.
    #[serde(default)]
    pub stalled: bool,
    /// Where the time went: building pyramids, building patches, solving (seconds).
    pub timing: StepTiming,
    /// Per-level solver summaries, coarse to fine.
    pub levels: Vec<SolveSummary>,
    /// Per vertex, how well the finest level's images constrain it at the solution (written
    /// beside the frame's mesh, not into the log).
    #[serde(skip)]
    pub confidence: Vec<VertexConfidence>,
}

fn one() -> f64 {
    1.0
}

/// A template's patches at one level ([`Tracker::template_patches`]).
struct TemplatePatches {
    set: PatchSet,
    /// Pixels the other cameras contradicted, left out.
    contradicted: usize,
    /// Per camera, its pixels contradicted and taken (empty when nothing was checked).
    by_camera: Vec<CameraShare>,
    /// `seen[triangle · cameras + camera]`: whether the template sees that triangle in that
    /// camera, whatever was left out for what the pixels show (a blank image, contradiction).
    seen: Vec<bool>,
    /// The still occluders' marks the cross-camera check found (`occluder`), for the anchor.
    still: Option<occluder::StillMarks>,
    /// Pixels left out because their way crosses one of those marks.
    near_still: usize,
}

/// Time split of one frame's step, seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepTiming {
    /// Building the frame's image pyramids ([`prepare`]); `track_scene` does this while the
    /// previous frame is solved, so it is not on the critical path there.
    pub pyramids: f64,
    /// Building the template patches. Each finer level's are built while the level above it is
    /// solved, so this time overlaps `solve` in part.
    pub patches: f64,
    /// The Gauss–Newton solves.
    pub solve: f64,
    /// Reading the per-vertex confidence from the last linearisation.
    #[serde(default)]
    pub confidence: f64,
}

struct Template {
    positions: Vec<Point3<f64>>,
    pyramids: Vec<Pyramid>,
    frame: u32,
    /// Per camera, whether its image of this frame is left out (blank, `image::blank_images`,
    /// or a repeat of the frame before, [`Tracker::repeated`]): it gives no patches.
    left_out: Vec<bool>,
    /// Per camera, its image's block means (whether the next frame's image repeats it).
    thumbs: Vec<BlockMeans>,
    /// Per camera, the index buffer of `positions` in its full-resolution image, where the
    /// colour balance rasterised it after the solve (`balance::change`); empty otherwise. The
    /// finest template takes it instead of rasterising the same view again. Whatever changes
    /// `positions` makes a new `Template` or clears it.
    buffers: Vec<Option<IndexBuffer>>,
}

/// The first frame as the anchor's smear needs it (`Tracker::first`).
struct FirstFrame {
    positions: Vec<Point3<f64>>,
    pyramids: Vec<Pyramid>,
    frame: u32,
    /// Per vertex, per frame: the forward difference to the next frame solved.
    velocity: Option<Vec<Vector3<f64>>>,
}

/// Frame-by-frame tracker state, in memory.
pub struct Tracker {
    triangles: Vec<[u32; 3]>,
    cameras: Vec<Camera>,
    opts: TrackOptions,
    used: OptionsUsed,
    /// Per camera, how many solve levels it enters later than the largest camera's images
    /// (`pyramid::level_skips`; all 0 when the cameras' images are of one size).
    skips: Vec<usize>,
    /// The mesh's edges: the normal equations' block pattern.
    pattern: Vec<[u32; 2]>,
    regularisers: Vec<Box<dyn Regulariser>>,
    /// The edges that can be rims (`rim`).
    rim_edges: Vec<rim::RimEdge>,
    two_sided: bool,
    cancel: Option<Arc<AtomicBool>>,
    /// When set, the solver's per-pixel work runs on this GPU.
    gpu: Option<Arc<Gpu>>,
    /// Anchor patches per level (built from the first frame; again once its velocity is known,
    /// when cameras record late or early).
    anchor: Vec<PatchSet>,
    /// The share of the first frame's finest template that the other cameras contradict
    /// (`FrameReport::contradicted_at_first`).
    contradicted_at_first: f64,
    /// The same per camera (`FrameReport::contradicted_by_camera_at_first`).
    contradicted_by_camera_at_first: Vec<Option<f64>>,
    /// What the first frame's own images give its mesh (`FrameReport::information_share`).
    information_at_first: f64,
    /// The first frame (where the anchor was taken).
    anchor_frame: u32,
    /// The first frame's mesh and images, and once the frame after it is solved its velocity:
    /// kept when a camera's shutter is open, to smear the anchor's pixels (`smear`).
    first: Option<FirstFrame>,
    prev: Template,
    before_prev: Option<Vec<Point3<f64>>>,
    /// The frame `before_prev` was solved for.
    before_frame: u32,
    /// When the given mesh had vertices at the same place (split along seams, or a triangle
    /// soup): the tracker works on them merged (`Mesh::welded`), and this maps back.
    weld: Option<Weld>,
    /// When the given mesh lay off the surface and was moved onto it (`TrackOptions::onto_surface`).
    first_mesh_moved: Option<SurfaceMove>,
    /// The cameras' image shifts at the first frame (`TrackOptions::shift_cameras`); the
    /// cameras above are shifted by them when applied.
    camera_shifts: Option<CameraShifts>,
    /// Some cameras record colour and some do not (`image::mixes_grey_and_colour`, judged on
    /// the first frame): every image is compared in luminance.
    luminance: bool,
    /// The cameras whose image of the first frame is blank ([`Tracker::blank_at_first`]).
    first_blank: Vec<u16>,
    /// The first frame's neighbouring triangles that face the same way (`FrameReport::folded`).
    folds: FoldWatch,
    /// Each vertex's photometric information in the last frame solved (the bending term's yield
    /// depends on it); `None` before the first, and after a frame in which no pixel was compared.
    information: Option<Vec<f64>>,
    /// Per camera, its colour balance against the first frame (`balance`): the next frame's
    /// images are divided by it.
    balance: Vec<[f64; 3]>,
    /// Per camera, its last [`balance::READINGS`] readings of that balance, oldest first.
    readings: Vec<Vec<[f64; 3]>>,
    /// Per camera, whether it repeated a frame and has not been seen in step since
    /// ([`Tracker::late_cameras`] is asked about it after every frame until it is).
    watch_sync: Vec<bool>,
    /// Per camera, whether it was found running a frame late ([`Tracker::late_cameras`]): left
    /// out of every later frame.
    late: Vec<bool>,
    /// Per camera, whether its view changed at the last frame solved by clearly more than the
    /// others' ([`health::growth_of`]): asked at this frame whether it runs a frame early
    /// ([`Tracker::early_ratios`]); within a frame's passes, whether it is asked again.
    watch_early: Vec<bool>,
    /// Per camera, the frame at which it was found running a frame early: from that frame on,
    /// its image of each frame is its file for the frame before ([`Tracker::held`]).
    early_since: Vec<Option<u32>>,
    /// Per camera, whether the solve under way leaves it out, to ask at its solution whether the
    /// camera runs early (within one frame's solves only).
    early_probe: Vec<bool>,
    /// Per camera, whether this frame found it, taken a frame back until now, agreeing better
    /// with its own file (within one frame's solves only; [`FrameReport::rejoined_cameras`]).
    rejoined: Vec<bool>,
    /// Per camera, its latest image as read (before luminance and colour balance), kept for
    /// the next frame: for a camera running early, its image of the next frame; for one whose
    /// view leapt, its image of the next frame if that frame finds it early.
    held: Vec<Option<Arc<CameraImage>>>,
    /// Per camera, whether its view leapt at the last frame solved: a camera that then repeats
    /// what it showed there had it a frame ahead ([`FrameReport::ahead_cameras`]).
    leapt_before: Vec<bool>,
    /// Per camera, its view's change at the last frame solved ([`FrameReport::view_changes`];
    /// `None` after a stalled frame, which kept its template).
    prev_changes: Vec<Option<f64>>,
    /// Per camera, its first frame's view of its background (`None`: a moving camera, or one
    /// whose first image was blank): whether it has turned since (`steady`).
    steady: Vec<Option<steady::Reference>>,
    /// Per camera, the turn since it was calibrated that the tracker uses
    /// ([`FrameReport::camera_turns`]).
    turns: Vec<Vector3<f64>>,
    /// Per camera, the last frame at which its turn changed, and by how many pixels.
    moved_at: Vec<Option<(u32, f64)>>,
}

/// The mesh as the tracker works on it: vertices at the same place merged
/// ([`Mesh::welded`]; then also, for every given vertex, its merged one) and the triangles
/// wound consistently, closed pieces outward ([`Mesh::facing_outward`]).
pub(crate) fn tracked_mesh(mesh: &Mesh) -> (Mesh, Option<Vec<u32>>) {
    let (merged, of_vertex) = match mesh.welded() {
        Some((m, of)) => (m, Some(of)),
        None => (mesh.clone(), None),
    };
    let triangles = merged.facing_outward().0;
    (
        Mesh {
            triangles,
            ..merged
        },
        of_vertex,
    )
}

/// The given mesh's vertices against the merged ones the tracker works on.
struct Weld {
    /// For every given vertex, its merged vertex.
    of_vertex: Vec<u32>,
    /// The current positions of the given vertices (what [`Tracker::positions`] returns).
    given: Vec<Point3<f64>>,
}

/// Refuses `images` images for `cameras` cameras unless there is one per camera.
pub(crate) fn one_per_camera(cameras: usize, images: usize) -> Result<()> {
    if images != cameras {
        return Err(Error::mismatch(
            "images",
            format!("{cameras} (one per camera)"),
            images,
        ));
    }
    Ok(())
}

/// A camera's projection at pyramid level `level` (`Projection::downscaled` by `2^level`).
pub(crate) fn level_projection(p: &Projection, level: usize) -> Projection {
    if level == 0 {
        p.clone()
    } else {
        p.downscaled(1 << level)
    }
}

impl Tracker {
    /// Camera `c`'s own pyramid level at solve level `level` (`pyramid::camera_level`).
    fn camera_level(&self, c: usize, level: usize) -> usize {
        camera_level(level, self.skips.get(c).copied().unwrap_or(0))
    }

    /// Camera `c`'s projection at `frame`, at solve level `level` (its own pyramid level).
    fn projection_at(&self, c: usize, frame: u32, level: usize) -> Projection {
        level_projection(self.cameras[c].at(frame), self.camera_level(c, level))
    }

    /// Every camera's projection at `frame`, at solve level `level`.
    fn projections_at(&self, frame: u32, level: usize) -> Vec<Projection> {
        (0..self.cameras.len())
            .map(|c| self.projection_at(c, frame, level))
            .collect()
    }

    /// Camera `c`'s image in its pyramid `p` at solve level `level` (`Pyramid::at`).
    fn image_at<'a>(&self, p: &'a Pyramid, c: usize, level: usize) -> &'a RgbImage {
        p.at(level, self.skips.get(c).copied().unwrap_or(0))
    }

    /// Each camera's image in `pyramids` (one per camera) at solve level `level`.
    fn images_at<'a>(&self, pyramids: &'a [Pyramid], level: usize) -> Vec<&'a RgbImage> {
        pyramids
            .iter()
            .enumerate()
            .map(|(c, p)| self.image_at(p, c, level))
            .collect()
    }

    /// A tracker whose mesh lines up with `images` (one per camera) at `frame`.
    pub fn new(
        mesh: &Mesh,
        cameras: Vec<Camera>,
        frame: u32,
        images: &[RgbImage],
        opts: TrackOptions,
    ) -> Result<Self> {
        Self::new_checked(mesh, cameras, frame, images, opts, None)
    }

    /// [`Tracker::new`], given the first-mesh check (`align::first_mesh_check`) the caller
    /// already made on the same mesh, cameras, frame and images (as `track` does, to warn before
    /// tracking): a mesh off the surface is moved onto it from that check instead of measuring
    /// its offset again. `None`: measured here.
    pub fn new_checked(
        mesh: &Mesh,
        cameras: Vec<Camera>,
        frame: u32,
        images: &[RgbImage],
        opts: TrackOptions,
        check: Option<&FirstMeshCheck>,
    ) -> Result<Self> {
        opts.validate()?;
        one_per_camera(cameras.len(), images.len())?;
        for (i, c) in cameras.iter().enumerate() {
            if !(c.time_offset.is_finite() && (-1.0..=1.0).contains(&c.time_offset)) {
                return Err(Error::option(
                    format!("cameras[{i}].time_offset"),
                    c.time_offset,
                    "a lag from -1 to 1 frame",
                ));
            }
        }
        // A rig that mixes colour and monochrome cameras is compared in luminance, from the
        // first look at its images on (the surface check below compares cameras too).
        let compared = crate::base::image::comparable(images);
        let luminance = matches!(compared, std::borrow::Cow::Owned(_));
        let images = &compared[..];
        // A camera whose first image is blank (black, capped) shows nothing to compare: it
        // gives no template or anchor (nor does the check below ask it).
        let thumbs: Vec<BlockMeans> = images.par_iter().map(RgbImage::block_means).collect();
        let blank = crate::base::image::blank_of(
            &thumbs.iter().map(BlockMeans::spread).collect::<Vec<_>>(),
        );
        // A mesh off the surface the cameras agree on is moved onto it first: everything below
        // (rest lengths, templates, the anchor) starts from the moved mesh.
        let moved = match (opts.onto_surface, check) {
            (false, _) => None,
            (true, Some(check)) => {
                moved_onto_surface_as_checked(mesh, &cameras, frame, images, check)
            }
            (true, None) => moved_onto_surface(mesh, &cameras, frame, images),
        };
        let moved_mesh;
        let (mesh, first_mesh_moved) = match moved {
            Some((positions, what)) => {
                moved_mesh = mesh.with_positions(positions);
                (&moved_mesh, Some(what))
            }
            None => (mesh, None),
        };
        // Each camera's images shifted by the fraction of a pixel at which the cameras agree
        // about the (moved) first mesh: what its calibration is off by, which the comparisons
        // between cameras would otherwise put into the mesh.
        let camera_shifts = opts
            .shift_cameras
            .then(|| crate::tracker::shift::camera_shifts(mesh, &cameras, frame, images))
            .flatten();
        let cameras = match &camera_shifts {
            Some(s) if s.applied => cameras
                .iter()
                .zip(&s.shifts)
                .map(|(c, d)| c.shifted(*d))
                .collect(),
            _ => cameras,
        };
        let opts = opts.resolved_for(cameras.iter().map(|c| (c.width, c.height)));
        let used = opts.used();
        let opts = used.options;
        let levels = opts.levels;
        let skips = level_skips(cameras.iter().map(|c| (c.width, c.height)));
        let pyramids = build_pyramids(images, levels, opts.blur);
        // Vertices at the same place merged (`Mesh::welded`), the triangles wound consistently
        // and outward (the facing test needs it); the meshes written keep the user's
        // vertices and triangles, only positions come from here.
        let (tracked, of_vertex) = tracked_mesh(mesh);
        let weld = of_vertex.map(|of_vertex| Weld {
            of_vertex,
            given: mesh.positions.clone(),
        });
        let mesh = &tracked;
        let edges = Arc::new(EdgeSet::new(mesh));
        let mut t = Tracker {
            triangles: mesh.triangles.clone(),
            cameras,
            opts,
            used,
            skips,
            pattern: edges.edges.clone(),
            regularisers: regularise::build(mesh, &edges, &opts.regularisation),
            rim_edges: rim::rim_edges(&mesh.triangles),
            two_sided: !mesh.is_closed(),
            cancel: None,
            gpu: None,
            anchor: Vec::new(),
            contradicted_at_first: 0.0,
            contradicted_by_camera_at_first: Vec::new(),
            information_at_first: 0.0,
            anchor_frame: frame,
            first: None,
            prev: Template {
                positions: mesh.positions.clone(),
                pyramids,
                frame,
                left_out: blank.clone(),
                thumbs,
                buffers: Vec::new(),
            },
            before_prev: None,
            before_frame: frame,
            weld,
            first_mesh_moved,
            camera_shifts,
            luminance,
            first_blank: marked(&blank),
            folds: FoldWatch::new(&mesh.positions, &mesh.triangles),
            information: None,
            balance: Vec::new(),
            readings: Vec::new(),
            watch_sync: Vec::new(),
            late: Vec::new(),
            watch_early: Vec::new(),
            early_since: Vec::new(),
            early_probe: Vec::new(),
            rejoined: Vec::new(),
            held: Vec::new(),
            leapt_before: Vec::new(),
            prev_changes: Vec::new(),
            steady: Vec::new(),
            turns: Vec::new(),
            moved_at: Vec::new(),
        };
        // What each static camera's background looks like at the first frame.
        t.steady = t
            .cameras
            .iter()
            .enumerate()
            .map(|(c, cam)| {
                (t.opts.steady_cameras && !cam.is_moving() && !blank[c]).then(|| {
                    steady::Reference::new(
                        &t.prev.pyramids[c].levels,
                        cam.at(frame),
                        mesh_window(cam, frame, &t.prev.positions),
                    )
                })
            })
            .collect();
        t.turns = vec![Vector3::zeros(); t.cameras.len()];
        t.moved_at = vec![None; t.cameras.len()];
        (
            t.anchor,
            t.contradicted_at_first,
            t.contradicted_by_camera_at_first,
        ) = t.anchor_patches(&t.prev, None);
        t.information_at_first = t.information_at_first();
        if (0..t.cameras.len()).any(|c| t.shutter(c) > 0.0) {
            t.first = Some(FirstFrame {
                positions: t.prev.positions.clone(),
                pyramids: t.prev.pyramids.clone(),
                frame,
                velocity: None,
            });
        }
        Ok(t)
    }

    /// The sum over the vertices of the information (`VertexConfidence::information`) that the
    /// first frame's finest templates, its anchor included, give the mesh when compared with the
    /// first frame's own images: what a perfectly tracked frame of this footage would show.
    fn information_at_first(&self) -> f64 {
        let level = self.opts.finest_level;
        let cb = level == 0 && self.opts.checkerboard;
        let mut set = self
            .template_patches(
                &self.prev,
                None,
                level,
                if cb { 2.0 } else { 1.0 },
                cb,
                None,
            )
            .set;
        if let Some(anchor) = self.anchor.get(level) {
            merge_into(&mut set, anchor.clone());
        }
        let by_triangle = set.by_triangle();
        let problem = Problem::photometric(
            &self.triangles,
            &set,
            &by_triangle,
            self.images_at(&self.prev.pyramids, level),
            self.projections_at(self.prev.frame, level),
            &self.pattern,
        );
        let opts = SolverOptions {
            interpolation: self.used.interpolation_per_level[level],
            ..self.opts.solver
        };
        problem
            .vertex_confidence(
                &self.prev.positions,
                &problem.solve_options(&self.prev.positions, &opts),
            )
            .iter()
            .map(|c| c.information)
            .sum()
    }

    /// Replaces the current frame's vertex positions (e.g. a corrected shape from an artist, or
    /// ground truth in an experiment); the next step starts from them, with no velocity.
    pub fn set_positions(&mut self, positions: Vec<Point3<f64>>) -> Result<()> {
        self.check_positions(&positions)?;
        self.prev.positions = self.merged(positions);
        self.prev.buffers.clear();
        self.before_prev = None;
        self.sync_given();
        Ok(())
    }

    /// Positions of the given mesh's vertices as the merged vertices' (each merged vertex
    /// takes its last given copy's).
    fn merged(&self, positions: Vec<Point3<f64>>) -> Vec<Point3<f64>> {
        match &self.weld {
            None => positions,
            Some(w) => {
                let mut out = self.prev.positions.clone();
                for (&m, p) in w.of_vertex.iter().zip(positions) {
                    out[m as usize] = p;
                }
                out
            }
        }
    }

    /// The given vertices' positions from the merged ones, after these changed.
    fn sync_given(&mut self) {
        if let Some(w) = &mut self.weld {
            for (g, &m) in w.given.iter_mut().zip(&w.of_vertex) {
                *g = self.prev.positions[m as usize];
            }
        }
    }

    /// Puts the tracker in the state it had right after solving `frame`: the frame's images
    /// (as [`prepare`]d), its solved positions and, when there is one, the solved positions of
    /// the frame before it (for the constant-velocity prediction). Continuing from here gives
    /// exactly what an uninterrupted run gives (how `--resume` continues a run) when, for
    /// cameras with a `time_offset` or an open shutter, `first_next` gives the solved positions
    /// of the frame after the first (the anchor is taken where those cameras saw the surface
    /// move, and smeared along that motion); it is read
    /// only on a tracker fresh from [`Tracker::new`]. `confidence` is the frame's
    /// [`FrameReport::confidence`] (on the given mesh's vertices), when it had one.
    pub fn restore(
        &mut self,
        frame: u32,
        prepared: Prepared,
        positions: Vec<Point3<f64>>,
        before: Option<Vec<Point3<f64>>>,
        first_next: Option<Vec<Point3<f64>>>,
        confidence: Option<&[VertexConfidence]>,
    ) -> Result<()> {
        self.check_prepared(&prepared)?;
        self.check_positions(&positions)?;
        if let Some(c) = confidence {
            if c.len() != positions.len() {
                return Err(Error::mismatch(
                    "confidence",
                    format!("{} (one per mesh vertex)", positions.len()),
                    c.len(),
                ));
            }
        }
        if let Some(b) = &before {
            self.check_positions(b)?;
        }
        if let Some(n) = &first_next {
            self.check_positions(n)?;
        }
        let positions = self.merged(positions);
        let before = before.map(|b| self.merged(b));
        let first_next = first_next.map(|n| self.merged(n));
        if let (Some(n), Some(first)) = (&first_next, &mut self.first) {
            if first.velocity.is_none() && self.prev.frame == first.frame {
                first.velocity = Some(velocity_of(&first.positions, n, 1.0));
            }
        }
        if let Some(n) = &first_next {
            if self.prev.frame == self.anchor_frame && self.before_prev.is_none() {
                (
                    self.anchor,
                    self.contradicted_at_first,
                    self.contradicted_by_camera_at_first,
                ) = self.anchor_patches(&self.prev, Some((n, 1.0)));
            }
        }
        // Left out as the run left them: blank, or (`Prepared::with_repeated`) a repeat.
        let left_out = prepared
            .blank
            .iter()
            .zip(&prepared.repeated)
            .map(|(b, r)| b | r)
            .collect();
        let prepared = self.in_luminance(prepared);
        self.prev = Template {
            positions,
            pyramids: prepared.pyramids,
            frame,
            left_out,
            thumbs: prepared.thumbs,
            buffers: Vec::new(),
        };
        self.before_prev = before;
        self.before_frame = frame.saturating_sub(1);
        self.information = confidence.map(|c| match &self.weld {
            None => c.iter().map(|v| v.information).collect(),
            // Every given vertex of a merged one carries its value.
            Some(w) => {
                let mut out = vec![0.0; self.prev.positions.len()];
                for (&m, v) in w.of_vertex.iter().zip(c) {
                    out[m as usize] = v.information;
                }
                out
            }
        });
        self.sync_given();
        Ok(())
    }

    /// A flag that, once set (e.g. on Ctrl-C), makes the current and every later step stop
    /// within one solver iteration with `Error::Interrupted`, leaving the tracker as it was.
    pub fn set_cancel(&mut self, cancel: Arc<AtomicBool>) {
        self.cancel = Some(cancel);
    }

    /// Runs the solver's per-pixel work (warp, sample, loss, normal equations) on `gpu` from
    /// the next frame on; `None`: on the CPU. The meshes agree with the CPU's to rounding
    /// (docs/gpu.md).
    pub fn set_gpu(&mut self, gpu: Option<Arc<Gpu>>) {
        self.gpu = gpu;
    }

    /// The options as used: the given ones resolved, with what they imply.
    pub fn options_used(&self) -> &OptionsUsed {
        &self.used
    }

    fn check_positions(&self, positions: &[Point3<f64>]) -> Result<()> {
        let n = self.positions().len();
        if positions.len() != n {
            return Err(Error::mismatch(
                "positions",
                format!("{n} (one per mesh vertex)"),
                positions.len(),
            ));
        }
        Ok(())
    }

    fn check_prepared(&self, prepared: &Prepared) -> Result<()> {
        if prepared.pyramids.len() != self.cameras.len() {
            return Err(Error::mismatch(
                "images",
                format!("{} (one per camera)", self.cameras.len()),
                prepared.pyramids.len(),
            ));
        }
        let levels = self.opts.levels;
        if prepared.pyramids.iter().any(|p| p.levels.len() < levels)
            || prepared.blur != self.opts.blur
        {
            return Err(Error::mismatch(
                "prepared images",
                format!(
                    "the tracker's options ({levels} pyramid levels, blur {} px)",
                    self.opts.blur
                ),
                format!("images prepared with blur {} px", prepared.blur),
            ));
        }
        Ok(())
    }

    /// When the mesh given to [`Tracker::new`] lay off the surface the cameras agree on and its
    /// vertices were moved onto it before tracking (`TrackOptions::onto_surface`): what the
    /// check found and how far they moved. [`Tracker::positions`] starts from the moved mesh.
    pub fn first_mesh_moved(&self) -> Option<&SurfaceMove> {
        self.first_mesh_moved.as_ref()
    }

    /// The shifts of the cameras' images at which they agree best about the first mesh, as
    /// measured before tracking (`TrackOptions::shift_cameras`; `None`: not measured, or no
    /// two cameras compare the mesh). The tracker sees every camera shifted by them when
    /// [`CameraShifts::applied`].
    pub fn camera_shifts(&self) -> Option<&CameraShifts> {
        self.camera_shifts.as_ref()
    }

    /// The cameras (indices) whose image of the first frame is blank (black, capped, blown out:
    /// `image::blank_images`): they have no anchor, and the check that the mesh lies on the
    /// surface did not ask them.
    pub fn blank_at_first(&self) -> &[u16] {
        &self.first_blank
    }

    /// Whether the rig mixes cameras that record colour with ones that do not, so that every
    /// image is compared in luminance (judged on the first frame's images).
    pub fn compares_luminance(&self) -> bool {
        self.luminance
    }

    /// A frame's pyramids in luminance when the rig is compared so (the blur and the 2×2
    /// reduction are linear per channel, so converting the levels equals building them from the
    /// converted image).
    fn in_luminance(&self, mut prepared: Prepared) -> Prepared {
        if self.luminance {
            for level in prepared.pyramids.iter_mut().flat_map(|p| p.images_mut()) {
                level.to_luminance();
            }
        }
        prepared
    }

    /// Per camera, how much its view changed since the previous frame solved: the change of
    /// its block means within the window the mesh covered there (`windows`); `None` for a blank
    /// image or a mesh out of view. Whether it repeats that frame (`health::repeated_of`: the
    /// recorder filled a dropped frame with the one before, or the stream froze) and whether it
    /// leapt ahead (`health::growth_of`: a frame dropped) are read from it.
    fn view_changes(&self, prepared: &Prepared, windows: &[Option<[f64; 4]>]) -> Vec<Option<f64>> {
        (0..self.cameras.len())
            .map(|c| {
                if prepared.blank[c] {
                    return None;
                }
                prepared.thumbs[c].change_within(&self.prev.thumbs[c], windows[c]?)
            })
            .collect()
    }

    /// Per camera, whether it runs a frame late: for each camera watched since it repeated a
    /// frame, the cameras' comparison with each other ([`Tracker::paired_cost`]) with its image
    /// of `frame` beside the others' previous frame at the previous solution, against the same
    /// with the others' `frame` at its solution `x`; late when the first is below
    /// [`health::LATE_RATIO`] of the second. Cameras left out of either frame take no part.
    fn late_cameras(
        &self,
        frame: u32,
        x: &[Point3<f64>],
        next: &[Pyramid],
        left_out: &[bool],
    ) -> Vec<bool> {
        let n = self.cameras.len();
        let watched = |c: usize| self.watch_sync.get(c).copied().unwrap_or(false);
        (0..n)
            .map(|c| {
                if !watched(c) || left_out[c] {
                    return false;
                }
                // The camera and the others shown in both frames, compared the same way in both.
                let set: Vec<usize> = (0..n)
                    .filter(|&o| o == c || (!left_out[o] && !self.prev.left_out[o]))
                    .collect();
                let now = self.paired_cost(c, &set, x, |o| (frame, &next[o]));
                let behind = self.paired_cost(c, &set, &self.prev.positions, |o| {
                    if o == c {
                        (frame, &next[o])
                    } else {
                        (self.prev.frame, &self.prev.pyramids[o])
                    }
                });
                matches!((now, behind), (Some(a), Some(b)) if b < health::LATE_RATIO * a)
            })
            .collect()
    }

    /// Per camera, whether it seems to run a frame early: for each camera whose view leapt at
    /// the previous frame ([`Tracker::watch_early`]), the cameras' comparison with each other
    /// ([`Tracker::paired_cost`], the median over triangles) at this frame's solution `x` with
    /// its image of the *previous* frame beside the others' `frame`, over the same with its own
    /// image of `frame` (below [`health::LATE_RATIO`]: early, it dropped a frame, and what it
    /// recorded as the previous frame shows this one). For a camera already taken a frame
    /// back, its own file of `frame` (kept in [`Tracker::held`]) against the one taken back
    /// (below: it is in step again). `None` for cameras not asked, or left out of either frame.
    fn early_ratios(
        &self,
        frame: u32,
        x: &[Point3<f64>],
        next: &[Pyramid],
        left_out: &[bool],
    ) -> Vec<Option<f64>> {
        let n = self.cameras.len();
        let watched = |c: usize| self.watch_early.get(c).copied().unwrap_or(false);
        (0..n)
            .map(|c| {
                if !watched(c) || left_out[c] || self.prev.left_out[c] {
                    return None;
                }
                // Taken a frame back since before this frame: asked whether its own file of
                // this frame (kept as read: in this frame's colours) agrees better after all.
                let own = match self.early_since.get(c).copied().flatten() {
                    Some(f) if f < frame => {
                        let mut p = self.held.get(c)?.as_ref()?.pyramid.clone();
                        if self.luminance {
                            p.images_mut().for_each(RgbImage::to_luminance);
                        }
                        if let Some(b) = self.balance.get(c) {
                            balance::divide(&mut p, *b);
                        }
                        Some(p)
                    }
                    _ => None,
                };
                let other = own.as_ref().unwrap_or(&self.prev.pyramids[c]);
                let set: Vec<usize> = (0..n).filter(|&o| o == c || !left_out[o]).collect();
                // Asked at every leap, most frames of real footage. With two cameras a camera a
                // frame early moves the whole mesh in depth (7 to 19 % of its size on the
                // cloths): compared up to 1 280 pixels wide. With more, the others outvote it
                // (0.1 to 1 % on the real board's four cameras): up to 640, a ninth of the
                // solve's time on the board instead of a fifth.
                let widest = if set.len() > 2 { 640 } else { 1280 };
                let now = self.paired_scan(c, &set, x, |o| (frame, &next[o]), widest)?;
                let ahead = self.paired_scan(
                    c,
                    &set,
                    x,
                    |o| {
                        if o == c {
                            (frame, other)
                        } else {
                            (frame, &next[o])
                        }
                    },
                    widest,
                )?;
                let (now, ahead) = (median_per_triangle(&now.1)?, median_per_triangle(&ahead.1)?);
                (now > 0.0).then(|| ahead / now)
            })
            .collect()
    }

    /// The comparisons between camera `c` and the other cameras of `set` (`offset::cross_scan`,
    /// as the first-mesh check compares cameras; at the first pyramid level at most 1 280
    /// pixels wide) at positions `x`, each camera `o` posed at and showing
    /// what `image(o)` gives (a frame, its pyramid). `None` when `set` has no other camera, or
    /// `c` sees no triangle another camera sees.
    fn paired_cost<'a>(
        &'a self,
        c: usize,
        set: &[usize],
        x: &[Point3<f64>],
        image: impl Fn(usize) -> (u32, &'a Pyramid),
    ) -> Option<f64> {
        self.paired_scan(c, set, x, image, 1280)
            .map(|(cost, _)| cost)
    }

    /// [`Tracker::paired_cost`] with its parts (the mean cost per pixel, and per triangle
    /// compared its index, cost and weight), at the first level at most `widest_compared`
    /// pixels wide.
    #[allow(clippy::type_complexity)]
    fn paired_scan<'b>(
        &self,
        c: usize,
        set: &[usize],
        x: &[Point3<f64>],
        image: impl Fn(usize) -> (u32, &'b Pyramid),
        widest_compared: u32,
    ) -> Option<(f64, Vec<(u32, f64, f64)>)> {
        if set.len() < 2 {
            return None;
        }
        // The first solve level at which every camera's own level is that narrow (cameras of
        // different sizes each at their own level: `pyramid::level_skips`).
        let widest = |l: usize| {
            (0..self.cameras.len())
                .map(|c| self.cameras[c].width >> self.camera_level(c, l))
                .max()
                .unwrap_or(0)
        };
        let level = (0..self.opts.levels.max(1))
            .find(|&l| widest(l) <= widest_compared)
            .unwrap_or(self.opts.levels.max(1) - 1);
        let shown: Vec<(u32, &Pyramid)> = set.iter().map(|&o| image(o)).collect();
        crate::tracker::offset::cross_scan(
            x,
            &self.triangles,
            &self.pattern,
            !self.two_sided,
            &set.iter()
                .zip(&shown)
                .map(|(&o, (f, _))| self.cameras[o].at(*f))
                .collect::<Vec<_>>(),
            &set.iter()
                .zip(&shown)
                .map(|(&o, (_, p))| self.image_at(p, o, level))
                .collect::<Vec<_>>(),
            &set.iter()
                .map(|&o| self.camera_level(o, level))
                .collect::<Vec<_>>(),
            set.iter().position(|&o| o == c).unwrap_or(0),
        )
    }

    /// Before `frame` is solved: each static camera's turn since the first frame as its
    /// background in `next` shows it (`steady::read`, the mesh's windows at the previous
    /// solution and at `predicted` left out); a camera whose turn moves its image by more than
    /// [`steady::MOVED_PX`] from the one in use is posed with it from this frame on.
    fn steady_cameras(
        &mut self,
        frame: u32,
        next: &[Pyramid],
        left_out: &[bool],
        prev_windows: &[Option<[f64; 4]>],
        predicted: &[Point3<f64>],
    ) {
        let this = &*self;
        let readings: Vec<Option<steady::Reading>> = (0..this.cameras.len())
            .into_par_iter()
            .map(|c| {
                let reference = this.steady.get(c)?.as_ref()?;
                if left_out[c] {
                    return None;
                }
                let cam = &this.cameras[c];
                let windows: Vec<[f64; 4]> = prev_windows[c]
                    .into_iter()
                    .chain(mesh_window(cam, this.prev.frame, predicted))
                    .collect();
                // The mesh out of this camera's view: its pose does not enter the solve, and
                // its whole image, the moving subject in it too when the camera's calibration
                // is wrong (`input::blind_cameras`), would pass for background. Read again
                // once the mesh is in view (against the same first frame).
                if windows.is_empty() {
                    return None;
                }
                let just_moved = matches!(this.moved_at[c], Some((f, _)) if f == this.prev.frame);
                steady::read(
                    reference,
                    &next[c].levels,
                    &windows,
                    this.turns[c],
                    just_moved,
                )
            })
            .collect();
        for (c, reading) in readings.into_iter().enumerate() {
            let Some(reading) = reading else { continue };
            let (w, h) = (self.cameras[c].width as f64, self.cameras[c].height as f64);
            // Its pose at the first frame is the calibrated one (a turn applies from a later
            // frame on).
            let k = self.cameras[c].at(self.anchor_frame).krt().0;
            let px = steady::motion_px(&k, w, h, &reading.turn, &self.turns[c]);
            if px > steady::MOVED_PX {
                self.turn_camera(c, frame, reading.turn);
                self.moved_at[c] = Some((frame, px));
            }
        }
    }

    /// Poses camera `c` turned by `turn` since its calibration from `frame` on.
    fn turn_camera(&mut self, c: usize, frame: u32, turn: Vector3<f64>) {
        let Some(pose) = steady::turned(self.cameras[c].at(self.anchor_frame), &turn) else {
            return;
        };
        self.cameras[c] = self.cameras[c].with_pose_from(frame, pose);
        self.turns[c] = turn;
    }

    /// Poses each camera turned as the frame a run stopped at used it, and marks those found
    /// turned at that frame ([`FrameReport::camera_turns`], [`FrameReport::moved_cameras`] and
    /// [`FrameReport::moved_px`]): with [`Tracker::restore`], what `--resume` needs to continue
    /// exactly. Turns are ignored unless there is one per camera, indices past the rig.
    pub fn restore_turns(
        &mut self,
        frame: u32,
        turns: &[[f64; 3]],
        moved: &[u16],
        moved_px: &[f64],
    ) {
        if turns.len() == self.cameras.len() {
            for (c, t) in turns.iter().enumerate() {
                let t = Vector3::from(*t);
                if t != Vector3::zeros() && t.iter().all(|v| v.is_finite()) {
                    self.turn_camera(c, frame, t);
                }
            }
        }
        for (i, &c) in moved.iter().enumerate() {
            if let Some(m) = self.moved_at.get_mut(c as usize) {
                *m = Some((frame, moved_px.get(i).copied().unwrap_or(0.0)));
            }
        }
    }

    /// After `frame` is solved (its images and solution are the template now): each camera's
    /// change of colour balance since the first frame, read from the first frame's pixels
    /// carried into this frame's images (`balance::change`), taken into its balance.
    fn update_balance(&mut self, frame: u32) {
        let Some(anchor) = self.anchor.first() else {
            return;
        };
        let projections: Vec<Projection> =
            self.cameras.iter().map(|c| c.at(frame).clone()).collect();
        let images: Vec<&RgbImage> = self.prev.pyramids.iter().map(|p| &p.levels[0]).collect();
        let (change, buffers) = balance::change(
            anchor,
            &self.triangles,
            &self.prev.positions,
            &projections,
            &images,
            &self.prev.left_out,
            self.two_sided,
        );
        // Kept for the next frame's finest template where that is the same view: the camera's
        // full-resolution image (`image_at` at level 0 is another for a camera whose pyramid
        // skips levels).
        self.prev.buffers = buffers
            .into_iter()
            .enumerate()
            .map(|(c, b)| b.filter(|_| self.skips.get(c).copied().unwrap_or(0) == 0))
            .collect();
        if self.balance.is_empty() {
            self.balance = vec![[1.0; 3]; self.cameras.len()];
            self.readings = vec![Vec::new(); self.cameras.len()];
        }
        for ((b, r), d) in self.balance.iter_mut().zip(&mut self.readings).zip(change) {
            if let Some(d) = d {
                // What this frame's images showed: the balance they were divided by, times
                // what was left.
                balance::record(r, std::array::from_fn(|k| b[k] * d[k]));
                *b = balance::applied(balance::of_readings(r));
            }
        }
    }

    /// Marks the cameras found running a frame late ([`FrameReport::late_cameras`]) and those
    /// that repeated the frame a run stopped at ([`FrameReport::repeated_cameras`], watched for
    /// it), as that frame's report gave them: with [`Tracker::restore`], what `--resume` needs
    /// to continue exactly. Indices past the rig are ignored.
    pub fn restore_sync(&mut self, late: &[u16], repeated: &[u16]) {
        let n = self.cameras.len();
        let mark = |list: &[u16]| (0..n).map(|c| list.contains(&(c as u16))).collect();
        self.late = mark(late);
        self.watch_sync = mark(repeated);
    }

    /// Marks the cameras found running a frame early ([`FrameReport::early_cameras`]) and
    /// those whose view leapt ([`FrameReport::leapt_cameras`], checked at the next frame), and
    /// takes each camera's view change ([`FrameReport::view_changes`]), as the frame a run
    /// stopped at gave them (no changes when it `stalled`); `latest` is that frame's images as
    /// read, from which the early and leapt cameras' next images are kept. With
    /// [`Tracker::restore`] (given the early cameras' images of the frame before:
    /// [`Prepared::with_cameras_from`]) and [`Tracker::restore_sync`], what `--resume` needs to
    /// continue exactly. Indices past the rig are ignored.
    pub fn restore_early(
        &mut self,
        frame: u32,
        early: &[u16],
        leapt: &[u16],
        view_changes: &[Option<f64>],
        stalled: bool,
        latest: &Prepared,
    ) {
        let n = self.cameras.len();
        let mark = |list: &[u16], c: usize| list.contains(&(c as u16));
        self.early_since = (0..n).map(|c| mark(early, c).then_some(frame)).collect();
        self.watch_early = (0..n).map(|c| mark(leapt, c)).collect();
        self.leapt_before = self.watch_early.clone();
        // Their images of the next frame (early), or of it if found early there (leapt).
        self.held = (0..n)
            .map(|c| {
                ((mark(early, c) || mark(leapt, c)) && c < latest.pyramids.len())
                    .then(|| Arc::new(latest.camera(c)))
            })
            .collect();
        self.prev_changes = if view_changes.len() == n && !stalled {
            view_changes.to_vec()
        } else {
            vec![None; n]
        };
    }

    /// Sets each camera's colour balance against the first frame and the readings it comes
    /// from, as the frame a run stopped at left them ([`FrameReport::colour_balance`],
    /// [`FrameReport::colour_readings`]): with [`Tracker::restore`], what `--resume` needs to
    /// continue exactly. Ignored unless both have one entry per camera.
    pub fn restore_colour_balance(&mut self, balance: &[[f64; 3]], readings: &[Vec<[f64; 3]>]) {
        let n = self.cameras.len();
        if balance.len() == n && readings.len() == n {
            self.balance = balance.to_vec();
            self.readings = readings.to_vec();
        }
    }

    /// Current vertex positions (the last solved frame), one per vertex of the mesh given to
    /// [`Tracker::new`].
    pub fn positions(&self) -> &[Point3<f64>] {
        match &self.weld {
            Some(w) => &w.given,
            None => &self.prev.positions,
        }
    }

    /// Camera `c`'s shutter, as a fraction of a frame: the options' when they give one, else
    /// the scene's.
    fn shutter(&self, c: usize) -> f64 {
        self.opts.shutter_of(&self.cameras[c])
    }

    /// The velocities the smears of this frame's level are taken from (`smear`), with the mesh
    /// of the frame being solved at `estimate`; `None` when every shutter is closed, or while no
    /// velocity is known yet (the first frame solved, or after `set_positions`: both sides are
    /// then compared as the cameras saw them, which is exact for a steady motion) or the first
    /// frame's is not (the anchor's smear needs it).
    fn smear_velocities(&self, frame: u32, estimate: &[Point3<f64>]) -> Option<Velocities> {
        self.first.as_ref()?.velocity.as_ref()?;
        let before = self.before_prev.as_deref()?;
        let gap_before = self.prev.frame.saturating_sub(self.before_frame).max(1) as f64;
        let gap = frame.saturating_sub(self.prev.frame).max(1) as f64;
        Some(Velocities::new(
            before,
            gap_before,
            &self.prev.positions,
            estimate,
            gap,
        ))
    }

    /// Each camera's image of the frame being solved at `level`, smeared by what it lacks of
    /// each template's smear (`motions`, one image each) where its shutter is open
    /// (`smear::smeared_targets`, with the mesh at `estimate`), and with `measure` the texture
    /// the first smear kept; `None` for a camera left as it is.
    fn smeared_targets(
        &self,
        frame: u32,
        level: usize,
        next: &[Pyramid],
        estimate: &[Point3<f64>],
        motions: &[smear::Motions],
        measure: bool,
    ) -> Vec<Option<(Vec<RgbImage>, Option<smear::Texture>)>> {
        (0..self.cameras.len())
            .into_par_iter()
            .map(|c| {
                let s = self.shutter(c);
                (s > 0.0).then(|| {
                    // A camera that records late or early sees the mesh moved on (`Lag`), each
                    // vertex at its row's instant under a rolling shutter.
                    let d = self.cameras[c].lags(frame, estimate);
                    let gap = frame.saturating_sub(self.prev.frame).max(1) as f64;
                    let seen: std::borrow::Cow<[Point3<f64>]> = if !d.is_empty() {
                        estimate
                            .iter()
                            .zip(&self.prev.positions)
                            .zip(&d)
                            .map(|((x, p), &d)| moved_on(x, p, d, gap))
                            .collect()
                    } else {
                        std::borrow::Cow::Borrowed(estimate)
                    };
                    smear::smeared_targets(
                        self.image_at(&next[c], c, level),
                        &self.projection_at(c, frame, level),
                        &self.triangles,
                        &seen,
                        motions,
                        s,
                        measure,
                    )
                })
            })
            .collect()
    }

    /// The previous frame's and the anchor's pixels of `set` (patches `tpl` the previous
    /// frame's, `anchor` the first frame's) re-read under the smear of the frame being solved,
    /// those whose smear reaches the mesh's outline left out (`smear::smear_templates`).
    fn smear_template_pixels(
        &self,
        set: &mut PatchSet,
        tpl: std::ops::Range<usize>,
        anchor: std::ops::Range<usize>,
        level: usize,
        v: &Velocities,
    ) {
        let shutter: Vec<f64> = (0..self.cameras.len()).map(|c| self.shutter(c)).collect();
        let mut keep: Vec<Vec<bool>> = set
            .patches
            .iter()
            .map(|p| vec![true; (p.end - p.start) as usize])
            .collect();
        // One template's patches `range`, taken from `pyramids` of `frame` with the mesh at
        // `positions`, smeared by its own motion `own`; a camera that records late or early
        // saw the mesh moved along `lag` (as `template_patches` took its pixels).
        let mut reread = |set: &mut PatchSet,
                          range: std::ops::Range<usize>,
                          positions: &[Point3<f64>],
                          lag: &[Vector3<f64>],
                          own: &[Vector3<f64>],
                          frame: u32,
                          pyramids: &[Pyramid]| {
            let seen: Vec<Vec<Point3<f64>>> = self
                .cameras
                .iter()
                .map(|cam| {
                    let d = cam.lags(frame, positions);
                    if d.is_empty() {
                        return positions.to_vec();
                    }
                    positions
                        .iter()
                        .zip(lag)
                        .zip(&d)
                        .map(|((p, v), &d)| p + v * d)
                        .collect()
                })
                .collect();
            let projections = self.projections_at(frame, level);
            let images = self.images_at(pyramids, level);
            let outlines: Vec<IndexBuffer> = (0..self.cameras.len())
                .into_par_iter()
                .map(|c| {
                    let (w, h) = (images[c].width(), images[c].height());
                    rasterize(&seen[c], &self.triangles, &projections[c], w, h)
                })
                .collect();
            let source = smear::Source {
                seen: seen.iter().map(Vec::as_slice).collect(),
                images,
                projections: &projections,
            };
            let motions = smear::Motions {
                template: own,
                target: &v.target,
            };
            let kept = smear::smear_templates(
                set,
                range.clone(),
                &self.triangles,
                &source,
                &outlines,
                &motions,
                &shutter,
            );
            for (k, kept) in keep[range].iter_mut().zip(kept) {
                *k = kept;
            }
        };
        // The previous frame is smeared by its motion there (`v.template`, the central
        // difference); a late camera took its pixels along the backward one.
        if let Some(before) = self.before_prev.as_deref() {
            let gap_before = self.prev.frame.saturating_sub(self.before_frame).max(1) as f64;
            let backward = velocity_of(before, &self.prev.positions, gap_before);
            let prev = &self.prev;
            reread(
                set,
                tpl,
                &prev.positions,
                &backward,
                &v.template,
                prev.frame,
                &prev.pyramids,
            );
        }
        // The first frame by the forward difference, both ways.
        if let Some((first, velocity)) = self
            .first
            .as_ref()
            .and_then(|f| f.velocity.as_ref().map(|v| (f, v)))
        {
            reread(
                set,
                anchor,
                &first.positions,
                velocity,
                velocity,
                first.frame,
                &first.pyramids,
            );
        }
        set.retain_pixels(&keep);
    }

    fn consensus_options(&self) -> ConsensusOptions {
        ConsensusOptions {
            k: self.opts.consensus,
            min: self.opts.solver.tukey_min,
            px: self.opts.solver.tukey_px,
        }
    }

    fn patch_options(&self) -> PatchOptions {
        PatchOptions {
            margin: self.opts.margin,
            min_cos: self.opts.min_cos,
            two_sided: self.two_sided,
            checkerboard: false,
            stride: 1,
        }
    }

    /// The patches of template `tpl` at `level`. With `before` (earlier positions and how many
    /// frames before the template's), a camera that records late or early
    /// (`Camera::time_offset`) is given the surface where it was when that camera saw it: moved
    /// on along its velocity (see `solve::Lag`). Pixels every other camera contradicts are left
    /// out (`consensus`); their count is returned with the patches. With `ahead` (the frame
    /// being solved: its pyramids and the predicted mesh) and `TrackOptions::still_occluders`,
    /// so are the pixels whose way there crosses an occluder that stands still (`occluder`).
    fn template_patches(
        &self,
        tpl: &Template,
        before: Option<(&[Point3<f64>], f64)>,
        level: usize,
        weight: f32,
        checkerboard: bool,
        ahead: Option<(&[Pyramid], &[Point3<f64>])>,
    ) -> TemplatePatches {
        let popts = PatchOptions {
            checkerboard,
            ..self.patch_options()
        };
        let per_cam: Vec<CameraPatches> = self
            .cameras
            .par_iter()
            .enumerate()
            .map(|(c, cam)| {
                let proj = self.projection_at(c, tpl.frame, level);
                // Each vertex at the instant its row was read (`Camera::lags`).
                let d = cam.lags(tpl.frame, &tpl.positions);
                let seen: std::borrow::Cow<[Point3<f64>]> = match before {
                    Some((b, gap)) if !d.is_empty() => tpl
                        .positions
                        .iter()
                        .zip(b)
                        .zip(&d)
                        .map(|((p, q), &d)| moved_on(p, q, d, gap))
                        .collect(),
                    _ => std::borrow::Cow::Borrowed(&tpl.positions),
                };
                // The colour balance's view of the same positions, camera and image, if it made
                // one (`Template::buffers`).
                let image = self.image_at(&tpl.pyramids[c], c, level);
                let made = match (&seen, tpl.buffers.get(c)) {
                    (std::borrow::Cow::Borrowed(_), Some(Some(b)))
                        if self.camera_level(c, level) == 0
                            && (b.width, b.height) == (image.width(), image.height()) =>
                    {
                        Some(b)
                    }
                    _ => None,
                };
                CameraPatches::new(
                    &seen,
                    &self.triangles,
                    &proj,
                    image,
                    c as u16,
                    weight,
                    &popts,
                    None,
                    made,
                )
            })
            .collect();
        // Which (triangle, camera) pairs the template sees, before any pixel is left out for
        // what it shows (a blank image, the other cameras' contradiction): where the anchor is
        // compared (`level_patches`).
        let ncam = self.cameras.len();
        let mut seen = vec![false; self.triangles.len() * ncam];
        for c in &per_cam {
            c.mark_covered(&mut seen, ncam);
        }
        // A blank image gives no patches.
        let per_cam: Vec<CameraPatches> = per_cam
            .into_iter()
            .zip(&tpl.left_out)
            .filter(|(_, b)| !**b)
            .map(|(c, _)| c)
            .collect();
        // Written into one allocation (a merge of the cameras' sets copied every pixel again:
        // 0.65 s of eight 4K cameras' finest template).
        let mut set = PatchSet::from_cameras(&per_cam);
        drop(per_cam);
        let mut contradicted = 0;
        let mut by_camera = Vec::new();
        let mut still = None;
        let mut near_still = 0;
        if self.opts.consensus > 0.0 && self.cameras.len() > 1 {
            let projections = self.projections_at(tpl.frame, level);
            let images = self.images_at(&tpl.pyramids, level);
            let copts = self.consensus_options();
            let next: Vec<&RgbImage> = ahead
                .map(|(next, _)| self.images_at(next, level))
                .unwrap_or_default();
            let ahead = ahead
                .filter(|_| self.opts.still_occluders)
                .map(|(_, predicted)| Ahead {
                    way: Way {
                        from: &tpl.positions,
                        to: predicted,
                        triangles: &self.triangles,
                        projections: &projections,
                    },
                    next: &next,
                    margin: occluder::MARGIN_PX / (1u32 << level) as f64,
                });
            let (stats, marks) = drop_contradicted_ahead(
                &mut set,
                &tpl.positions,
                &self.triangles,
                &projections,
                &images,
                &copts,
                ahead.as_ref(),
            );
            contradicted = stats.dropped;
            by_camera = stats.by_camera;
            near_still = stats.near_still;
            still = marks;
        }
        TemplatePatches {
            set,
            contradicted,
            by_camera,
            seen,
            still,
            near_still,
        }
    }

    /// The cameras' pixels at `level` of the frame being solved (`next`'s pyramids), each
    /// camera's warped into every other camera that sees the triangle (`align::cross_patches`)
    /// with the mesh at `x`; every `stereo_stride`-th source pixel is kept, and its
    /// comparisons share the weight `stereo` times the stride (twice that on the
    /// full-resolution checkerboard).
    fn stereo_patches(
        &self,
        x: &[Point3<f64>],
        frame: u32,
        level: usize,
        images: &[&RgbImage],
    ) -> (PatchSet, Vec<IndexBuffer>) {
        let projections = self.projections_at(frame, level);
        // As in `align`: pixels up to the outline at the coarser levels, where a triangle may
        // be smaller than a pixel.
        let popts = PatchOptions {
            margin: if level == 0 { self.opts.margin } else { 0 },
            // At full resolution every other pixel at twice the weight, as the templates: the
            // same accuracy for half the work (docs/speed.md, 2026-11-26).
            checkerboard: level == 0 && self.opts.checkerboard,
            ..self.patch_options()
        };
        // Every `stereo_stride`-th source pixel at that many times the weight: a source
        // pixel's comparisons are a weaker pull than the templates', and a sparser sample of
        // them holds the surface as well (docs/tracker.md, 2026-11-27).
        let popts = PatchOptions {
            stride: self.opts.stereo_stride.max(1) as usize,
            ..popts
        };
        let cbw = if popts.checkerboard { 2.0 } else { 1.0 } * popts.stride as f64;
        // Each camera's view of `x` at this level, kept for the hidden-surface check of the
        // same level (`leave_out_hidden`), which looks at the same mesh.
        let buffers: Vec<IndexBuffer> = projections
            .par_iter()
            .zip(images)
            .map(|(p, im)| rasterize(x, &self.triangles, p, im.width(), im.height()))
            .collect();
        let mut set = align::cross_patches_in(
            x,
            &self.triangles,
            &projections,
            images,
            Some(&buffers),
            &popts,
            self.opts.stereo_neighbours as usize,
        );
        // Patches of one source pixel range are consecutive, one per other camera.
        let mut i = 0;
        while i < set.patches.len() {
            let (start, end) = (set.patches[i].start, set.patches[i].end);
            let mut j = i;
            while j < set.patches.len()
                && (set.patches[j].start, set.patches[j].end) == (start, end)
            {
                j += 1;
            }
            let w = (cbw * self.opts.stereo / (j - i) as f64) as f32;
            set.patches[i..j].iter_mut().for_each(|p| p.weight = w);
            i = j;
        }
        (set, buffers)
    }

    /// The anchor's patches, every level it is compared at ([`anchored_levels`]), from the first frame's template `first` (none when
    /// the anchor is off). With `next` (the positions solved `gap` frames later), cameras that
    /// record late or early take them where they saw the surface: moved along the first
    /// frame's velocity `(next − first)/gap`. The anchor keeps every other pixel (checkerboard)
    /// at twice the weight: the same total pull for half the work.
    /// The anchor patches per level, and the share of the finest one's pixels that the other
    /// cameras contradicted, all cameras' and each one's (0 and none without anchors).
    fn anchor_patches(
        &self,
        first: &Template,
        next: Option<(&[Point3<f64>], f64)>,
    ) -> (Vec<PatchSet>, f64, Vec<Option<f64>>) {
        if self.opts.anchor_weight <= 0.0 {
            return (Vec::new(), 0.0, Vec::new());
        }
        // `template_patches` moves along `positions − before`: the forward difference here.
        let before: Option<Vec<Point3<f64>>> = next.map(|(n, _)| {
            first
                .positions
                .iter()
                .zip(n)
                .map(|(p, n)| p - (n - p))
                .collect()
        });
        let before = before.as_deref().zip(next.map(|(_, gap)| gap));
        let mut share = 0.0;
        let mut by_camera = Vec::new();
        let sets = (0..anchored_levels(self.opts.levels, self.opts.finest_level))
            .map(|l| {
                if l < self.opts.finest_level {
                    // Not solved: nothing to compare there.
                    return PatchSet::default();
                }
                let TemplatePatches {
                    mut set,
                    contradicted: dropped,
                    by_camera: cams,
                    ..
                } = self.template_patches(
                    first,
                    before,
                    l,
                    2.0 * self.opts.anchor_weight as f32,
                    true,
                    None,
                );
                for p in &mut set.patches {
                    p.first = true;
                }
                if l == self.opts.finest_level {
                    share = share_of(dropped, set.pixels.len());
                    by_camera = cams.iter().map(CameraShare::share).collect();
                }
                set
            })
            .collect();
        (sets, share, by_camera)
    }

    /// Solves for `frame` given its images (one per camera) and makes it the new template.
    pub fn step(&mut self, frame: u32, images: &[RgbImage]) -> Result<FrameReport> {
        let prepared = prepare(images, &self.opts);
        self.step_prepared(frame, prepared)
    }

    /// [`Tracker::step`] with the frame's images already prepared by [`prepare`] (which needs
    /// no tracker, so it can run while the previous frame is being solved).
    pub fn step_prepared(&mut self, frame: u32, prepared: Prepared) -> Result<FrameReport> {
        // What a frame's passes change before they may fail (interrupted, a bad image), put
        // back on failure so that the same frame can be stepped again.
        let kept = (
            self.held.clone(),
            self.early_since.clone(),
            self.early_probe.clone(),
            self.watch_early.clone(),
            self.rejoined.clone(),
            self.late.clone(),
            self.watch_sync.clone(),
            self.prev.left_out.clone(),
        );
        let result = self.solve_frame(frame, prepared);
        if result.is_err() {
            (
                self.held,
                self.early_since,
                self.early_probe,
                self.watch_early,
                self.rejoined,
                self.late,
                self.watch_sync,
                self.prev.left_out,
            ) = kept;
        }
        result
    }

    /// One pass of [`Tracker::step_prepared`]: solves `frame`, and solves it again (a pass of
    /// its own) when a camera is found late or early, or asked again without it.
    fn solve_frame(&mut self, frame: u32, mut prepared: Prepared) -> Result<FrameReport> {
        self.check_prepared(&prepared)?;
        let n = self.cameras.len();
        // While a camera is watched for running late or early, the frame is kept to be solved
        // again without it (late) or with its images a frame back (early) if it is found so.
        let again = (self.watch_sync.iter().chain(&self.watch_early).any(|&w| w))
            .then(|| (prepared.clone(), self.held.clone()));
        // Each camera's window of the previous solution, which the repeat check, the
        // background's (`steady`) and the one below leave out of what they compare.
        let prev_windows: Vec<Option<[f64; 4]>> = self
            .cameras
            .iter()
            .map(|cam| mesh_window(cam, self.prev.frame, &self.prev.positions))
            .collect();
        // A camera found running early (it dropped a frame) shows each frame in its file for
        // the frame before: that file, kept from the last step, is its image of this frame...
        let mut known_early: Vec<bool> = (0..n)
            .map(|c| self.early_since.get(c).is_some_and(Option::is_some))
            .collect();
        self.held.resize(n, None);
        // ... unless that file repeats the one the previous frame was solved with while the
        // others moved: the camera caught up (it repeated a frame, or the drop was one frame
        // swapped in), and its own files are taken from here.
        let taken_back: Vec<bool> = (0..n)
            .map(|c| matches!(self.early_since.get(c), Some(Some(f)) if *f < frame))
            .collect();
        if taken_back.iter().any(|&t| t) {
            let mut changes = self.view_changes(&prepared, &prev_windows);
            for c in (0..n).filter(|&c| taken_back[c]) {
                changes[c] = self.held[c].as_ref().and_then(|h| {
                    h.thumbs
                        .change_within(&self.prev.thumbs[c], prev_windows[c]?)
                });
            }
            let repeats = health::repeated_of(&changes);
            for c in (0..n).filter(|&c| taken_back[c] && repeats[c]) {
                self.early_since[c] = None;
                self.held[c] = None;
                self.rejoined.resize(n, false);
                self.rejoined[c] = true;
                known_early[c] = false;
            }
        }
        for c in (0..n).filter(|&c| known_early[c]) {
            if let Some(h) = self.held[c].take() {
                // Moved when no snapshot shares it (`again`, the state kept against an error).
                let h = Arc::try_unwrap(h).unwrap_or_else(|shared| (*shared).clone());
                self.held[c] = Some(Arc::new(prepared.swap_camera(c, h)));
            }
        }
        let levels = self.opts.levels;
        let pyramid_seconds = prepared.seconds;
        let next_blank = prepared.blank.clone();
        // A camera whose image repeats the previous frame's shows where the surface was, not
        // where it is: left out of this frame as a blank one is.
        let mut view_changes = self.view_changes(&prepared, &prev_windows);
        // Found early at this frame: its image now is the one the previous frame was solved
        // with, so it did not change (and is no repeat).
        for c in (0..n).filter(|&c| {
            self.early_since.get(c) == Some(&Some(frame)) || self.rejoined.get(c) == Some(&true)
        }) {
            view_changes[c] = None;
        }
        let next_repeated = health::repeated_of(&view_changes);
        // A camera found running a frame late pulls the mesh toward where it was: left out of
        // every frame after it was found.
        let known_late: Vec<bool> = (0..self.cameras.len())
            .map(|c| self.late.get(c).copied().unwrap_or(false))
            .collect();
        let next_left_out: Vec<bool> = (0..self.cameras.len())
            .map(|c| next_blank[c] || next_repeated[c] || known_late[c])
            .collect();
        // A camera whose view changed clearly more than the others' since the previous frame
        // may have dropped a frame: it is checked once this frame's successor is solved.
        let growth = health::growth_of(
            &view_changes,
            &self.prev_changes,
            &(0..self.cameras.len())
                .map(|c| next_left_out[c] || self.prev.left_out[c])
                .collect::<Vec<_>>(),
        );
        let leapt: Vec<bool> = growth
            .iter()
            .map(|g| g.is_some_and(|g| g >= health::LEAP_RATIO))
            .collect();
        // Kept for the next frame: a leapt camera's image as read (its image of the next frame
        // if it is found early there); an early camera's is already kept.
        for c in (0..n).filter(|&c| !known_early[c]) {
            self.held[c] = (leapt[c] && !known_late[c]).then(|| Arc::new(prepared.camera(c)));
        }
        // A camera asked again at a solution it takes no part in (`early_probe`): left out of
        // this solve, compared after it.
        let probed: Vec<bool> = (0..n)
            .map(|c| self.early_probe.get(c).copied().unwrap_or(false))
            .collect();
        let checked_left_out = next_left_out;
        let next_left_out: Vec<bool> = (0..n).map(|c| checked_left_out[c] || probed[c]).collect();
        let rim_left_out: Vec<bool> = (0..n)
            .map(|c| next_left_out[c] || self.prev.left_out.get(c).copied().unwrap_or(false))
            .collect();
        let prepared = self.in_luminance(prepared);
        let mut next = prepared.pyramids;
        let next_thumbs = prepared.thumbs;
        // In the colours each camera had at the first frame (`balance`).
        for (p, b) in next.iter_mut().zip(&self.balance) {
            balance::divide(p, *b);
        }
        let mut out = Outcome::new(StepTiming {
            pyramids: pyramid_seconds,
            ..Default::default()
        });
        let mut x = self.prev.positions.clone();
        // The constant-velocity prediction when there is a velocity, the previous shape
        // otherwise: the membrane's reference (it penalises changes of the deformation's rate).
        let predicted_shape: Vec<Point3<f64>> = match &self.before_prev {
            Some(pp) => self
                .prev
                .positions
                .iter()
                .zip(pp)
                .map(|(a, b)| a + (a - b))
                .collect(),
            None => self.prev.positions.clone(),
        };
        // When each camera records each vertex (`Camera::lags`; empty: at the frame's time),
        // its row taken where the prediction puts it, fixed for the frame's solve so that
        // every trial is costed alike.
        let offsets: Vec<Vec<f64>> = self
            .cameras
            .iter()
            .map(|c| c.lags(frame, &predicted_shape))
            .collect();
        let lagged = offsets.iter().any(|d| !d.is_empty());
        // A camera whose background turned since the first frame is solved turned with it.
        self.steady_cameras(
            frame,
            &next,
            &next_left_out,
            &prev_windows,
            &predicted_shape,
        );
        let context = FrameContext {
            previous: &self.prev.positions,
            predicted: &predicted_shape,
            information: self.information.as_deref(),
        };
        for r in &mut self.regularisers {
            r.begin_frame(&context);
        }
        // Levels finer than `finest_level` are not solved (a draft at reduced resolution).
        let finest = self.opts.finest_level;
        let this = &*self;
        // A level's template comes from the previous frame alone, so the next finer level's is
        // built while this level is solved (on the core the solve's serial parts leave idle);
        // the patches are the same whichever thread builds them.
        let build = |level: usize| {
            let tp = Instant::now();
            let built = this.previous_template(level, Some((&next, &predicted_shape)));
            (built, tp.elapsed().as_secs_f64())
        };
        let mut ahead = None;
        for level in (finest..levels).rev() {
            let (template, built_seconds) = match ahead.take() {
                Some(b) => b,
                None => build(level),
            };
            out.timing.patches += built_seconds;
            let tp = Instant::now();
            if level == finest {
                out.contradicted = template.contradicted;
                out.contradicted_share = share_of(template.contradicted, template.set.pixels.len());
                out.contradicted_by_camera =
                    template.by_camera.iter().map(CameraShare::share).collect();
            }
            // Under an open shutter, the template and this frame are compared under their
            // common smear (`smear`), taken with the mesh where this level starts (the
            // prediction at the coarsest level, where it is tried first).
            let estimate: &[Point3<f64>] = if level + 1 == levels {
                &predicted_shape
            } else {
                &x
            };
            let smear_v = self.smear_velocities(frame, estimate);
            // Per camera, this frame smeared against the previous frame's motion and, where
            // the anchor is compared, against the first frame's (`None`: left as it is).
            let smeared = smear_v.as_ref().map(|v| {
                let mut motions = vec![smear::Motions {
                    template: &v.template,
                    target: &v.target,
                }];
                let anchored = self
                    .anchor
                    .get(level)
                    .is_some_and(|a| !a.patches.is_empty());
                if let Some(velocity) = self.first.as_ref().and_then(|f| f.velocity.as_ref()) {
                    if anchored {
                        motions.push(smear::Motions {
                            template: velocity,
                            target: &v.target,
                        });
                    }
                }
                self.smeared_targets(frame, level, &next, estimate, &motions, level == finest)
            });
            let smeared_of = |c: usize, k: usize| {
                smeared
                    .as_ref()
                    .and_then(|s| s[c].as_ref())
                    .and_then(|(images, _)| images.get(k))
            };
            let targets: Vec<&RgbImage> = (0..n)
                .map(|c| smeared_of(c, 0).unwrap_or(self.image_at(&next[c], c, level)))
                .collect();
            let (mut set, near_still, stereo) = self.level_patches(
                frame,
                level,
                template,
                &x,
                &targets,
                &predicted_shape,
                smear_v.as_ref(),
            );
            let (stereo_x0, buffers) = stereo.unzip();
            if level == finest {
                out.near_still = near_still;
                // Under a smear the images show less texture than the first frame's did: the
                // frame's information is measured against the share they kept.
                let textures: Vec<smear::Texture> = smeared
                    .iter()
                    .flatten()
                    .flatten()
                    .filter_map(|(_, t)| *t)
                    .collect();
                out.texture_kept = smear::Texture::kept(&textures).unwrap_or(1.0);
            }
            if next_left_out.iter().any(|&b| b) {
                // A camera whose image of this frame is blank or repeated is compared with
                // nothing.
                set.patches.retain(|p| {
                    !next_left_out[p.camera as usize] && !next_left_out[p.source as usize]
                });
            }
            if self.opts.hidden_ahead {
                // At the coarsest level the mesh has not moved yet: judged at the
                // constant-velocity prediction (the previous shape when none is known).
                // Elsewhere at `x`, whose views the cameras compared with each other were found
                // from (the same buffers).
                let (at, buffers) = if level == levels - 1 {
                    (&predicted_shape, None)
                } else {
                    (&x, buffers)
                };
                let hidden = self.leave_out_hidden(&mut set, frame, level, at, &next, buffers);
                if level == finest {
                    out.hidden = hidden;
                }
            }
            // The first frame's patches are compared with this frame smeared along the first
            // frame's motion: as cameras of their own, `n` after the real ones, posed and timed
            // as they are.
            let first_smeared = (0..n).any(|c| smeared_of(c, 1).is_some());
            let targets: Vec<&RgbImage> = if first_smeared && set.patches.iter().any(|p| p.first) {
                for p in set.patches.iter_mut().filter(|p| p.first) {
                    p.camera += n as u16;
                    p.source += n as u16;
                }
                let firsts: Vec<&RgbImage> = (0..n)
                    .map(|c| smeared_of(c, 1).unwrap_or(targets[c]))
                    .collect();
                targets.iter().copied().chain(firsts).collect()
            } else {
                targets
            };
            let offsets_used: Vec<Vec<f64>> = if targets.len() > n {
                offsets.iter().chain(&offsets).cloned().collect()
            } else {
                offsets.clone()
            };
            let by_triangle = set.by_triangle();
            out.timing.patches += tp.elapsed().as_secs_f64();
            let input = LevelInput {
                left_out: &rim_left_out,
                frame,
                level,
                set: &set,
                by_triangle: &by_triangle,
                stereo_x0: stereo_x0.as_deref(),
                targets: &targets,
                lag: (lagged && self.before_prev.is_some()).then_some(Lag {
                    offsets: &offsets_used,
                    previous: &self.prev.positions,
                    gap: frame.saturating_sub(self.prev.frame).max(1) as f64,
                }),
            };
            // Where the coarsest level moved the mesh far, the next level is solved from where
            // the coarsest started too, and the start whose solution costs less there is kept
            // (docs/tracker.md, "A second start after the coarsest level").
            let second = (level + 2 == levels && level > finest)
                .then(|| out.coarse_start.take())
                .flatten()
                .filter(|s| self.moved_px(frame, level, s, &x) >= SECOND_START_PX);
            let start = match &second {
                Some(s) => LevelStart::Judged(s),
                None => LevelStart::Plain,
            };
            let (solved, built) = rayon::join(
                || self.solve_level(&input, &mut x, &mut out, start),
                || (level > finest).then(|| build(level - 1)),
            );
            let cost = solved?;
            ahead = built;
            if let (Some(mut alt), Some(cost)) = (second, cost) {
                let mut alt_out = Outcome::new(StepTiming::default());
                let alt_cost =
                    self.solve_level(&input, &mut alt, &mut alt_out, LevelStart::AsCoarsest)?;
                let kept = alt_cost.is_some_and(|c| c < cost);
                if kept {
                    x = alt;
                }
                out.summaries.extend(alt_out.summaries);
                out.timing.solve += alt_out.timing.solve;
                out.second_start = Some(if kept {
                    SecondStart::Kept
                } else {
                    SecondStart::NotKept
                });
            }
        }
        let iterations = out.summaries.iter().map(|s| s.iterations.len()).sum();
        let information: f64 = out.confidence.iter().map(|c| c.information).sum();
        let information_share = if self.information_at_first > 0.0 {
            information / (self.information_at_first * out.texture_kept.max(f64::MIN_POSITIVE))
        } else {
            1.0
        };
        let summaries = out.summaries;
        // No pixel compared at full resolution (the mesh left every camera's view, or every
        // template pixel was lost): whatever the steps did, only the regularisers moved the
        // mesh, so the frame counts as stalled and keeps the previous frame's shape.
        let blank_cameras = marked(&next_blank);
        let repeated_cameras = marked(&next_repeated);
        let stalled = out.pixels == 0
            || (!summaries
                .iter()
                .any(|s| s.iterations.iter().any(|i| i.accepted))
                && summaries
                    .iter()
                    .any(|s| matches!(s.stop, StopReason::CostRose | StopReason::NonFinite)));
        let folded = self.folds.folded(&x, &self.triangles);
        let (found_late, early_ratios) = if stalled {
            (vec![false; n], vec![None; n])
        } else {
            (
                self.late_cameras(frame, &x, &next, &checked_left_out),
                self.early_ratios(frame, &x, &next, &checked_left_out),
            )
        };
        // A camera that dropped a frame leaps once, at that frame; at the next its view changes
        // by one frame's motion again. One whose view leaps again here has something coming
        // into it (a rod or a hand entering the surface's view, which its previous image does
        // not show yet): it is not judged here, and is asked again at the next frame, as it
        // leapt here. Judged here, the Blender hard sample's rod coming into camera 1 took it
        // for a camera a frame early at frame 13 whenever the footage was a little other
        // (halved, one camera enlarged), and every later frame read its images a frame back.
        let early_ratios: Vec<Option<f64>> = early_ratios
            .into_iter()
            .enumerate()
            .map(|(c, r)| r.filter(|_| known_early[c] || !leapt[c]))
            .collect();
        let found_early: Vec<bool> = early_ratios
            .iter()
            .map(|r| r.is_some_and(|r| r < health::LATE_RATIO))
            .collect();
        // Not clearly early, but its previous image agrees with the others at least as well as
        // its own: with two or more other cameras, asked again at a solution it took no part
        // in. Solved with it, their solution bends toward its image: a camera a frame early
        // among the limb's four compared 0.83 here, 0.31 there.
        let probe: Vec<bool> = (0..n)
            .map(|c| {
                !probed[c]
                    && !found_early[c]
                    && early_ratios[c].is_some_and(|r| r < 1.0)
                    && (0..n).filter(|&o| o != c && !checked_left_out[o]).count() >= 2
            })
            .collect();
        if found_late
            .iter()
            .chain(&found_early)
            .chain(&probed)
            .chain(&probe)
            .any(|&l| l)
        {
            if let Some((again, held)) = again {
                self.held = held;
                // Solved again without it (late: what it showed pulled this frame toward the
                // last), with its image a frame back (early), or with it (checked, in step).
                let n = self.cameras.len();
                self.late = (0..n).map(|c| known_late[c] || found_late[c]).collect();
                self.watch_sync = (0..n)
                    .map(|c| !found_late[c] && self.watch_sync.get(c).copied().unwrap_or(false))
                    .collect();
                // Found early: taken a frame back from here. Taken a frame back before and its
                // own file agrees better now (a false alarm, or it caught up): taken as it is.
                self.early_since = (0..n)
                    .map(
                        |c| match (self.early_since.get(c).copied().flatten(), found_early[c]) {
                            (Some(_), true) => None,
                            (None, true) => Some(frame),
                            (known, false) => known,
                        },
                    )
                    .collect();
                self.rejoined = (0..n)
                    .map(|c| {
                        self.rejoined.get(c).copied().unwrap_or(false)
                            || (found_early[c] && known_early[c])
                    })
                    .collect();
                // Asked again (probe) or answered (found, in step, or probed).
                self.watch_early = (0..n).map(|c| probe[c]).collect();
                self.early_probe = probe.clone();
                // Its template, the previous frame's image at the previous solution, showed
                // this frame (found early), or is the file it was taken back to, which its own
                // file says it was not (rejoined by the comparison): no patches here.
                for c in (0..n).filter(|&c| found_early[c]) {
                    self.prev.left_out[c] = true;
                }
                drop(next);
                return self.solve_frame(frame, again);
            }
        }
        // A camera that repeated a frame is watched until it is seen in step or found late; one
        // found late stays so (nothing shows it catching up).
        let watched = |c: usize| self.watch_sync.get(c).copied().unwrap_or(false);
        self.watch_sync = (0..self.cameras.len())
            .map(|c| !found_late[c] && (next_repeated[c] || (watched(c) && next_left_out[c])))
            .collect();
        self.late = (0..self.cameras.len())
            .map(|c| known_late[c] || found_late[c])
            .collect();
        let late_cameras = marked(&self.late);
        let early_cameras = marked(&known_early);
        // Found early here, or repeating here what it showed a frame ahead (its view leapt at
        // the previous frame: one frame swapped in, then the right one again): the previous
        // frame was solved with its image a frame ahead.
        let ahead_cameras: Vec<u16> = (0..self.cameras.len() as u16)
            .filter(|&c| {
                let c = c as usize;
                self.early_since.get(c) == Some(&Some(frame))
                    || (next_repeated[c] && self.leapt_before.get(c) == Some(&true))
            })
            .collect();
        // Watched at the next frame: a camera whose view leapt here, unless already left out.
        self.watch_early = (0..self.cameras.len())
            .map(|c| !stalled && leapt[c] && !self.late[c])
            .collect();
        self.leapt_before = self.watch_early.clone();
        let rejoined_cameras = marked(&self.rejoined);
        self.rejoined = Vec::new();
        // What the next frame's leap is measured against (a stalled frame keeps its template,
        // so the next change spans two frames: none).
        self.prev_changes = if stalled {
            vec![None; self.cameras.len()]
        } else {
            view_changes.clone()
        };
        // How far the solution is from the constant-velocity prediction (the membrane's
        // reference above), over the previous shape's size.
        let jump = if stalled {
            0.0
        } else {
            let size = crate::base::mesh::bbox_diagonal(&self.prev.positions);
            if size > 0.0 {
                crate::base::mesh::rms_distance(&x, &predicted_shape) / size
            } else {
                0.0
            }
        };
        // What `--resume` reads back from the frame's confidence file (`Tracker::restore`): the
        // frame's, stalled or not, and none when it has no file (no pixel was compared).
        self.information = (!out.confidence.is_empty())
            .then(|| out.confidence.iter().map(|c| c.information).collect());
        if !stalled {
            let first_motion = self.before_prev.is_none() && self.prev.frame == self.anchor_frame;
            let old = std::mem::replace(
                &mut self.prev,
                Template {
                    positions: x,
                    pyramids: next,
                    frame,
                    left_out: next_left_out,
                    thumbs: next_thumbs,
                    buffers: Vec::new(),
                },
            );
            if let Some(first) = self.first.as_mut().filter(|f| f.velocity.is_none()) {
                if first_motion && old.frame == first.frame {
                    let gap = frame.saturating_sub(old.frame).max(1) as f64;
                    first.velocity = Some(velocity_of(&first.positions, &self.prev.positions, gap));
                }
            }
            if first_motion && lagged {
                // The first frame's velocity is known now: cameras that recorded it late or
                // early saw the surface moved along it, so their anchor pixels are taken again
                // where they saw it.
                let gap = frame.saturating_sub(old.frame).max(1) as f64;
                (
                    self.anchor,
                    self.contradicted_at_first,
                    self.contradicted_by_camera_at_first,
                ) = self.anchor_patches(&old, Some((&self.prev.positions, gap)));
            }
            self.before_prev = Some(old.positions);
            self.before_frame = old.frame;
            self.sync_given();
            self.update_balance(frame);
        }
        let confidence = match &self.weld {
            Some(w) if !out.confidence.is_empty() => w
                .of_vertex
                .iter()
                .map(|&m| out.confidence[m as usize])
                .collect(),
            _ => out.confidence,
        };
        // A stalled frame's images are not made the template: the next frame is compared with
        // the last frame that was solved (its positions are what this frame reports).
        let mut report = FrameReport {
            iterations,
            cost_before: out.cost_before,
            cost_after: out.cost_after,
            pixels: out.pixels,
            contradicted: out.contradicted,
            contradicted_share: out.contradicted_share,
            contradicted_at_first: self.contradicted_at_first,
            contradicted_by_camera: out.contradicted_by_camera,
            contradicted_by_camera_at_first: self.contradicted_by_camera_at_first.clone(),
            hidden: out.hidden,
            near_still: out.near_still,
            folded,
            information_share,
            suspect: false,
            rejected_share: out.rejected_share,
            blank_cameras,
            repeated_cameras,
            late_cameras,
            early_cameras,
            ahead_cameras,
            rejoined_cameras,
            view_changes,
            leapt_cameras: marked(&self.watch_early),
            colour_balance: self.balance.clone(),
            colour_readings: self.readings.clone(),
            moved_cameras: (0..self.cameras.len() as u16)
                .filter(|&c| matches!(self.moved_at[c as usize], Some((f, _)) if f == frame))
                .collect(),
            moved_px: self
                .moved_at
                .iter()
                .filter_map(|m| m.filter(|(f, _)| *f == frame).map(|(_, px)| px))
                .collect(),
            camera_turns: if self.turns.iter().any(|t| *t != Vector3::zeros()) {
                self.turns.iter().map(|t| [t.x, t.y, t.z]).collect()
            } else {
                Vec::new()
            },
            jump,
            stop: out.stop,
            predicted: out.predicted,
            second_start: out.second_start,
            stalled,
            timing: out.timing,
            levels: summaries,
            confidence,
        };
        report.suspect = health::own_concerns(&report)
            .iter()
            .any(health::Concern::is_suspect);
        Ok(report)
    }

    /// The first frame's view lent to the cameras that see a triangle now but did not then
    /// (`TrackOptions::lent_anchor`): for every (triangle, camera) pair the previous frame's
    /// template `cover`s and `anchor` has no patch of its own for, a copy of the triangle's
    /// anchor patch with the most pixels (the first frame's best view of it), warped into this
    /// camera, at `lent_anchor` times the anchor's weight. An object turning in front of the
    /// rig shows each camera sides that another camera saw at the first frame; without their
    /// first-frame appearance those sides are compared with the previous frame only, and drift.
    /// The patch keeps `source == camera`: its pixels are fixed, as any template's are (a
    /// different `source` would make it a moving source under `--stereo`); its own brightness
    /// gain absorbs the two cameras' exposure and the shading between their viewpoints.
    fn lend_anchor(&self, anchor: &PatchSet, cover: &[bool], set: &mut PatchSet) {
        let (ntri, ncam) = (self.triangles.len(), self.cameras.len());
        let own = anchor.coverage(ntri, ncam);
        // The first frame's best view of each triangle: its anchor patch with the most pixels
        // (the lowest camera among equals).
        let size = |p: &crate::tracker::patch::Patch| p.end - p.start;
        let mut best: Vec<Option<usize>> = vec![None; ntri];
        for (i, p) in anchor.patches.iter().enumerate() {
            let b = &mut best[p.triangle as usize];
            if b.is_none_or(|j| size(&anchor.patches[j]) < size(p)) {
                *b = Some(i);
            }
        }
        let weight = self.opts.lent_anchor as f32;
        for (t, b) in best.iter().enumerate() {
            let Some(p) = b.map(|i| anchor.patches[i]) else {
                continue;
            };
            for d in 0..ncam {
                let k = t * ncam + d;
                if !cover[k] || own[k] {
                    continue;
                }
                set.push_copy(
                    anchor,
                    crate::tracker::patch::Patch {
                        camera: d as u16,
                        source: d as u16,
                        weight: p.weight * weight,
                        ..p
                    },
                );
            }
        }
    }

    /// The previous frame's template at `level` (the checkerboard at full resolution, at twice
    /// the weight, when the options say so), and how many of its pixels the other cameras
    /// contradicted (left out).
    fn previous_template(
        &self,
        level: usize,
        ahead: Option<(&[Pyramid], &[Point3<f64>])>,
    ) -> TemplatePatches {
        let cb = level == 0 && self.opts.checkerboard;
        let weight = if cb { 2.0 } else { 1.0 };
        let before = self.before_prev.as_deref().map(|b| {
            (
                b,
                self.prev.frame.saturating_sub(self.before_frame).max(1) as f64,
            )
        });
        self.template_patches(&self.prev, before, level, weight, cb, ahead)
    }

    /// The cross-camera check on the current solution, taken as the next frame's finest
    /// template would take it: the share of its pixels the other cameras contradict, and that
    /// share at the first frame. This is what judges a shot's last frame, which no next frame's
    /// report does (`health`); one template's building, no solve. Also each camera's own
    /// share, now and at the first frame (`FrameReport::contradicted_by_camera`, for the
    /// per-camera rule), as the check on `frame` (the current one).
    pub fn contradicted_now(&self, frame: u32) -> LastFrameCheck {
        let TemplatePatches {
            set,
            contradicted: dropped,
            by_camera,
            ..
        } = self.previous_template(self.opts.finest_level, None);
        LastFrameCheck {
            frame,
            contradicted_share: share_of(dropped, set.pixels.len()),
            contradicted_at_first: self.contradicted_at_first,
            contradicted_by_camera: by_camera.iter().map(CameraShare::share).collect(),
            contradicted_by_camera_at_first: self.contradicted_by_camera_at_first.clone(),
        }
    }

    /// A level's patches: the previous frame's `template`, the first frame's anchor where the
    /// previous frame still sees its triangles (less its pixels whose way to `predicted`
    /// crosses a still occluder the template's check marked), and, with `--stereo` at the
    /// levels it is compared at, the cameras compared with each other at `x` (the mesh where
    /// this level starts; returned too, since the solve's moving source needs it). Also
    /// returned: the pixels left out near still occluders, the template's and the anchor's, and
    /// with `--stereo` each camera's index buffer of `x` at this level (beside `x`, for
    /// `leave_out_hidden`).
    #[allow(clippy::too_many_arguments)]
    fn level_patches(
        &self,
        frame: u32,
        level: usize,
        template: TemplatePatches,
        x: &[Point3<f64>],
        targets: &[&RgbImage],
        predicted: &[Point3<f64>],
        smear: Option<&Velocities>,
    ) -> (PatchSet, usize, Option<StereoView>) {
        let TemplatePatches {
            mut set,
            seen: cover,
            still,
            mut near_still,
            ..
        } = template;
        let ncam = self.cameras.len();
        let from_previous = 0..set.patches.len();
        let mut from_first = set.patches.len()..set.patches.len();
        if let Some(anchor) = self.anchor.get(level) {
            // Anchor patches only where the triangle is seen in the previous frame too
            // (otherwise it has turned away or been covered by another part of the mesh since
            // the first frame); seen, whatever its pixels showed: where an occluder covered it
            // in the previous frame, or its image was blank or a repeat, the first frame's view is what is
            // left to hold it (the robust loss rejects an occluder still there).
            let seen = |p: &&Patch| cover[p.triangle as usize * ncam + p.camera as usize];
            if let Some(marks) = &still {
                // The anchor's pixels next to a still occluder pull toward standing still as
                // the previous frame's do, and harder: their way is all the surface went since
                // the first frame. Judged where the previous frame put them.
                let mut kept = PatchSet::default();
                for p in anchor.patches.iter().filter(seen) {
                    kept.push_copy(anchor, *p);
                }
                let projections = self.projections_at(self.prev.frame, level);
                let way = Way {
                    from: &self.prev.positions,
                    to: predicted,
                    triangles: &self.triangles,
                    projections: &projections,
                };
                near_still += marks.remove_from(&mut kept, &way);
                merge_into(&mut set, kept);
            } else {
                set.pixels.reserve(anchor.pixels.len());
                set.patches.reserve(anchor.patches.len());
                for p in anchor.patches.iter().filter(seen) {
                    set.push_copy(anchor, *p);
                }
            }
            from_first.end = set.patches.len();
            if self.opts.lent_anchor > 0.0 {
                self.lend_anchor(anchor, &cover, &mut set);
            }
        }
        if let Some(v) = smear {
            self.smear_template_pixels(&mut set, from_previous, from_first, level, v);
        }
        let stereo = self.opts.stereo > 0.0
            && ncam > 1
            && stereo_levels(self.opts.levels, self.opts.finest_level).contains(&level);
        if !stereo {
            return (set, near_still, None);
        }
        let x0 = x.to_vec();
        let (stereo, buffers) = self.stereo_patches(&x0, frame, level, targets);
        merge_into(&mut set, stereo);
        (set, near_still, Some((x0, buffers)))
    }

    /// Leaves out of a level's patches the pixels at the mesh's own depth edges in the frame
    /// being solved, with the mesh at `at` (`tracker::occlusion`); returns how many. At the
    /// coarsest level the edges are not grown (only pixels on an edge, or under a nearer
    /// surface): that level catches
    /// large motion from few pixels, and `at` is only the prediction there, whose edges are off
    /// by its error (with the edges' reach the blob shaken 80 px per frame at 1280×720 lost so
    /// many of its coarsest pixels that it was not caught).
    fn leave_out_hidden(
        &self,
        set: &mut PatchSet,
        frame: u32,
        level: usize,
        at: &[Point3<f64>],
        next: &[Pyramid],
        buffers: Option<Vec<IndexBuffer>>,
    ) -> usize {
        let reach = if level + 1 == self.opts.levels {
            0
        } else {
            self.opts.margin + 1
        };
        let projections = self.projections_at(frame, level);
        let sizes: Vec<(usize, usize)> = self
            .images_at(next, level)
            .iter()
            .map(|i| (i.width(), i.height()))
            .collect();
        occlusion::drop_at_depth_edges(
            set,
            at,
            &self.triangles,
            &projections,
            &sizes,
            reach,
            buffers,
        )
    }

    /// How far the mesh moved from `from` to `to`, in pixels at `level`: the RMS over the
    /// vertices of their projected displacement, in the camera where it is largest.
    fn moved_px(&self, frame: u32, level: usize, from: &[Point3<f64>], to: &[Point3<f64>]) -> f64 {
        (0..self.cameras.len())
            .map(|c| {
                let p = self.projection_at(c, frame, level);
                let sum: f64 = from
                    .iter()
                    .zip(to)
                    .filter_map(|(a, b)| Some((p.project(a)? - p.project(b)?).norm_squared()))
                    .sum();
                (sum / from.len().max(1) as f64).sqrt()
            })
            .fold(0.0, f64::max)
    }

    /// Solves one level of a frame from `x` (moved to the level's solution): the prediction
    /// tried at the coarsest level, the rigid stage there (or where `start` says to solve the
    /// level as the coarsest), the Huber solve, and at the finest level the robust refine and
    /// what the frame reports (into `out`). Returns the level's convex cost at its solution
    /// where `start` asks for it to be compared with a second start's.
    fn solve_level(
        &self,
        input: &LevelInput<'_>,
        x: &mut Vec<Point3<f64>>,
        out: &mut Outcome,
        start: LevelStart<'_>,
    ) -> Result<Option<f64>> {
        let LevelInput {
            frame,
            level,
            set,
            by_triangle,
            stereo_x0,
            targets,
            lag,
            left_out,
        } = *input;
        let (levels, finest) = (self.opts.levels, self.opts.finest_level);
        let ts = Instant::now();
        // Every solve but the last one runs with the convex Huber loss; with `Loss::Tukey`
        // a last free solve from the Huber solution rejects what it cannot explain.
        let robust = SolverOptions {
            interpolation: self.used.interpolation_per_level[level],
            ..self.opts.solver
        };
        let refine = robust.loss != Loss::Huber && level == finest;
        // The Huber solves sample bilinearly, also at full resolution when a refine
        // follows: they bring the mesh to within a fraction of a pixel, and the refine,
        // in the chosen interpolation, decides the solution (docs/tracker.md, "Levels").
        // An approach stage (a finer level or the refine follows, and it is not the
        // coarsest level, where large motion is caught) stops at the looser decrease.
        let approach = level + 1 < levels && (refine || level > finest);
        let sopts = SolverOptions {
            loss: Loss::Huber,
            interpolation: if refine {
                Interpolation::Linear
            } else {
                robust.interpolation
            },
            min_relative_decrease: if approach {
                robust
                    .min_relative_decrease
                    .max(self.opts.approach_decrease)
            } else {
                robust.min_relative_decrease
            },
            ..robust
        };
        // The outline against the background, followed from the frame before (`rim`; off
        // unless asked).
        let rims = (self.opts.sticky_edges > 0.0).then(|| {
            let n = self.cameras.len();
            let projections: Vec<Projection> = (0..n)
                .map(|c| self.projection_at(c, frame, level))
                .collect();
            let before_proj: Vec<Projection> = (0..n)
                .map(|c| self.projection_at(c, self.prev.frame, level))
                .collect();
            let before_img: Vec<&RgbImage> = self.images_at(&self.prev.pyramids, level);
            rim::Rims::find(
                x,
                &self.triangles,
                &self.rim_edges,
                &projections,
                &targets[..n],
                (&self.prev.positions[..], &before_proj[..], &before_img[..]),
                left_out,
                self.opts.sticky_edges,
            )
        });
        let mut problem = Problem {
            regularisers: &self.regularisers,
            rims: rims.as_ref(),
            cancel: self.cancel.as_deref(),
            moving_source: stereo_x0,
            // Until a velocity is known the templates are taken as the cameras saw them
            // too, which for a steady motion is exact on both sides.
            lag,
            ..Problem::photometric(
                &self.triangles,
                set,
                by_triangle,
                targets.to_vec(),
                // The first frame's patches' own cameras (`solve_frame`) repeat the rig.
                (0..targets.len())
                    .map(|i| self.projection_at(i % self.cameras.len(), frame, level))
                    .collect(),
                &self.pattern,
            )
        };
        // On the GPU: this level's patches, pixels and images go up once, and every
        // evaluation of the solves below runs there.
        // A rolling shutter's lag differs from vertex to vertex, which the GPU's kernel (one
        // lag per camera) does not take: such a problem is solved on the CPU.
        let uploaded = match &self.gpu {
            Some(g) if problem.lag.is_none_or(|l| l.per_camera().is_some()) => {
                Some(g.upload(&problem)?)
            }
            _ => None,
        };
        problem.gpu = uploaded.as_ref();
        if level == levels - 1 && self.opts.predict {
            if let Some(pp) = &self.before_prev {
                let guess: Vec<Point3<f64>> = x.iter().zip(pp).map(|(a, b)| a + (a - b)).collect();
                if problem.cost(&guess, &sopts) < problem.cost(x, &sopts) {
                    *x = guess;
                    out.predicted = true;
                }
            }
        }
        if level == levels - 1 {
            out.coarse_start = Some(x.clone());
        }
        // Judged against a second start only where the coarsest level's move did not clearly
        // explain this level's images better than its start did (both costs estimated from
        // the same quarter of the triangles, on the CPU whatever the device: the decision is
        // then the same with and without a GPU).
        let judged = match start {
            LevelStart::Plain => false,
            LevelStart::Judged(other) => {
                let at = |p: &[Point3<f64>]| problem.cost_sampled(p, &sopts, COST_BEFORE_EVERY);
                at(x) >= SECOND_START_GAIN * at(other)
            }
            LevelStart::AsCoarsest => true,
        };
        if level == finest {
            // For the log: on the CPU from every fourth triangle's pixels (a full pass was 4 %
            // of the default cloth's frame time); on the GPU the whole pass there.
            out.cost_before = if problem.gpu.is_some() {
                problem.cost(&self.prev.positions, &sopts)
            } else {
                problem.cost_sampled(&self.prev.positions, &sopts, COST_BEFORE_EVERY)
            };
        }
        // A cancelled solve ends the step: the tracker stays at the previous frame and
        // nothing of this step is kept.
        let last_complete = self.prev.frame;
        let solve = |x: &[Point3<f64>], lin, o: &SolverOptions, motion, role| {
            let out = problem.solve_stage(x, lin, o, motion, role);
            if out.1.stop == StopReason::Cancelled {
                Err(Error::Interrupted { last_complete })
            } else {
                Ok(out)
            }
        };
        let mut linearised = None;
        // Whether this level's stages run with the robust loss (the rigid stage's check below).
        let mut free_opts = sopts;
        // The rigid stage at the coarsest level only: that is where a large motion is caught;
        // at the finer levels the coarser solution already holds it, and a rigid stage there
        // found next to nothing (0.7 accepted steps per frame, 2 evaluations each).
        if self.opts.rigid_first && (level == levels - 1 || start == LevelStart::AsCoarsest) {
            let (sol, summary, lin) = solve(x, None, &sopts, Motion::Rigid, StageRole::default())?;
            // The convex loss catches a large motion, but a template with a plain occluder in
            // it (a black card over half of one camera's view of a limb, gone in this frame)
            // pulls it too, and the whole mesh went 6 % of its size off. The rigid move is kept
            // when the robust loss, its threshold taken where the move ends, agrees that it
            // improved on the start; otherwise the same stage with the robust loss is tried, and
            // the better of the two by that loss is kept (docs/tracker.md, "Stages").
            let tukey = SolverOptions {
                loss: Loss::Tukey,
                ..sopts
            };
            let judge = problem.solve_options(&sol, &tukey);
            // Each judged once: a cost evaluation at this level is a pass over its pixels.
            let (at_convex, at_start) = (problem.cost(&sol, &judge), problem.cost(x, &judge));
            if at_convex <= at_start {
                *x = sol;
                linearised = Some(lin);
                out.summaries.push(summary);
            } else {
                let (robust_sol, robust_summary, _) =
                    solve(x, None, &tukey, Motion::Rigid, StageRole::default())?;
                out.summaries.push(summary);
                let at_robust = problem.cost(&robust_sol, &judge);
                if at_robust < at_convex && at_robust < ROBUST_GAIN * at_start {
                    // The robust stage found a motion the convex one was pulled away from (a
                    // clear gain over the start): the free stage below would be pulled the same
                    // way, so it runs with the robust loss too (its threshold from where it
                    // starts), afresh. Without a clear gain the frame barely moved as a whole,
                    // and the convex stage's result stands (the free stage corrects it).
                    *x = robust_sol;
                    free_opts = tukey;
                } else {
                    *x = sol;
                    linearised = Some(lin);
                }
                out.summaries.push(robust_summary);
            }
        }
        // Before a refine, the Huber solve takes the residuals' median at its result as it
        // goes, which sets the refine's threshold without a pass of its own.
        // An approach stage ends at its first step that does what its model promised (the
        // next level or the refine linearises afresh).
        let role = StageRole {
            collect_median: refine,
            approach: approach && self.opts.approach_decrease > 0.0,
        };
        let (sol, mut summary, mut lin) = solve(x, linearised, &free_opts, Motion::Free, role)?;
        *x = sol;
        if refine {
            let (sol, refined, refined_lin) =
                solve(x, Some(lin), &robust, Motion::Free, StageRole::default())?;
            *x = sol;
            lin = refined_lin;
            out.summaries.push(std::mem::replace(&mut summary, refined));
        }
        // The confidence is timed apart.
        let mut own = 0.0;
        if level == finest {
            out.cost_after = summary.final_cost;
            out.pixels = summary.pixels;
            out.stop = summary.stop;
            let tc = Instant::now();
            // Read from the last solve's linearisation, made at `x` with `robust`.
            out.confidence = problem.confidence(&lin);
            out.rejected_share = problem.rejected_share(&lin);
            own = tc.elapsed().as_secs_f64();
            out.timing.confidence = own;
        }
        out.summaries.push(summary);
        out.timing.solve += ts.elapsed().as_secs_f64() - own;
        // A failure on the device was answered by the CPU within the solve; the frame is
        // still refused, so that a broken GPU path is never silent.
        if let Some(e) = uploaded.as_ref().and_then(|u| u.failure()) {
            return Err(e);
        }
        // The level's convex cost where it ended, for comparing two starts of it (the same
        // problem and options whichever start was solved).
        Ok(judged.then(|| problem.cost(x, &sopts)))
    }
}

/// Whether a frame's second start was kept ([`FrameReport::second_start`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SecondStart {
    /// The level after the coarsest, solved from where the coarsest level started, ended at a
    /// lower cost there than from where the coarsest ended: the frame went on from it.
    Kept,
    /// Tried, and the coarsest level's result stood.
    NotKept,
}

/// How far (pixels at the level after the coarsest, RMS over the vertices in the camera where
/// it is most) the coarsest level must have moved the mesh for that level to be solved from
/// the coarsest level's start too ([`FrameReport::second_start`]). A smaller move leaves both
/// starts in the level's own reach, where they end alike; past it the coarsest level may have
/// led into a valley the finer levels cannot climb out of.
pub const SECOND_START_PX: f64 = 1.0;

/// A coarsest level's move that lowers the next level's cost below this share of its cost at
/// the coarsest level's start has followed the images; one that does not leaves a doubt, which
/// a second start settles ([`FrameReport::second_start`]).
pub const SECOND_START_GAIN: f64 = 0.5;

/// How [`Tracker::solve_level`] starts a level.
#[derive(Clone, Copy, Debug, PartialEq)]
enum LevelStart<'a> {
    /// From where the coarser level ended (the prediction's choice at the coarsest level).
    Plain,
    /// As [`LevelStart::Plain`]; where the level's cost is no lower there than at the given
    /// second start, the convex cost where the level ends is returned, and its result is
    /// compared with the second start's.
    Judged(&'a [Point3<f64>]),
    /// From where the coarsest level started, as if this level were the coarsest (its rigid
    /// stage first), the convex cost where it ends returned.
    AsCoarsest,
}

/// At the coarsest level, when the rigid stage with the convex loss made the robust cost worse
/// than not moving, and the same stage with the robust loss lowers it below this share of the
/// start's (and below the convex stage's), its result is taken and the level's free stage runs
/// with the robust loss too (`Tracker::solve_level`): on a limb with a black card over half of
/// one camera's first frame the robust rigid stage lowered it to 0.70 of the start's; on the
/// Blender hard sample's three frames where the convex stage failed the check, to 0.99 (it
/// barely moved; taking it there made the mean error 0.2 % worse).
const ROBUST_GAIN: f64 = 0.9;

/// The frame log's `cost_before` is read from every this many triangles' pixels
/// ([`Problem::cost_sampled`]).
const COST_BEFORE_EVERY: usize = 4;

/// `dropped` pixels as a share of those a template took (`kept` + `dropped`); 0 when it took none.
fn share_of(dropped: usize, kept: usize) -> f64 {
    let taken = kept + dropped;
    if taken > 0 {
        dropped as f64 / taken as f64
    } else {
        0.0
    }
}

/// The mesh a level's cameras are compared with each other at (`--stereo`), and each camera's
/// index buffer of it at that level.
type StereoView = (Vec<Point3<f64>>, Vec<IndexBuffer>);

/// What one level's solve needs besides the tracker: the frame, its patches and images, and the
/// cameras' lag.
#[derive(Clone, Copy)]
struct LevelInput<'a> {
    frame: u32,
    level: usize,
    set: &'a PatchSet,
    by_triangle: &'a [(u32, std::ops::Range<usize>)],
    /// The mesh the `--stereo` comparisons were taken at (their moving source); `None`: none.
    stereo_x0: Option<&'a [Point3<f64>]>,
    /// The images each camera's patches are compared with at this level: the next frame's, smeared
    /// where a shutter is open (`smear`).
    targets: &'a [&'a RgbImage],
    lag: Option<Lag<'a>>,
    /// Per camera, whether its image of this frame or of the frame before is left out (blank,
    /// a repeat, probed): its outline is not followed (`rim`).
    left_out: &'a [bool],
}

/// What a frame's levels have found so far: the [`FrameReport`]'s figures before the frame's
/// verdicts (stalled, information, suspect) are drawn from them.
struct Outcome {
    summaries: Vec<SolveSummary>,
    predicted: bool,
    cost_before: f64,
    cost_after: f64,
    pixels: usize,
    contradicted: usize,
    contradicted_share: f64,
    contradicted_by_camera: Vec<Option<f64>>,
    hidden: usize,
    near_still: usize,
    rejected_share: f64,
    /// Under an open shutter, the share of its weakest texture the finest level's images kept
    /// through the smear (`smear::Texture::kept`); 1 without.
    texture_kept: f64,
    stop: StopReason,
    confidence: Vec<VertexConfidence>,
    timing: StepTiming,
    /// Where the coarsest level started (after the prediction's choice).
    coarse_start: Option<Vec<Point3<f64>>>,
    /// Whether the level after the coarsest was also solved from where the coarsest level
    /// started, and whether that start was kept (`FrameReport::second_start`).
    second_start: Option<SecondStart>,
}

impl Outcome {
    fn new(timing: StepTiming) -> Outcome {
        Outcome {
            summaries: Vec::new(),
            predicted: false,
            cost_before: 0.0,
            cost_after: 0.0,
            pixels: 0,
            contradicted: 0,
            contradicted_share: 0.0,
            contradicted_by_camera: Vec::new(),
            hidden: 0,
            near_still: 0,
            rejected_share: 0.0,
            texture_kept: 1.0,
            stop: StopReason::NoData,
            confidence: Vec::new(),
            timing,
            coarse_start: None,
            second_start: None,
        }
    }
}

/// One frame's images made ready for [`Tracker::step_prepared`]: each camera's smoothed pyramid.
#[derive(Clone)]
pub struct Prepared {
    pyramids: Vec<Pyramid>,
    /// Per camera, whether its image is blank (`image::blank_images`).
    blank: Vec<bool>,
    /// Per camera, its image's block means (whether it repeats the frame before).
    thumbs: Vec<BlockMeans>,
    /// Per camera, whether the tracker left its image out as a repeat when this frame was
    /// solved ([`Prepared::with_repeated`]; only read by [`Tracker::restore`]).
    repeated: Vec<bool>,
    /// The smoothing they were built with (must be the tracker's).
    blur: f64,
    /// Time it took, seconds (reported as the step's `timing.pyramids`).
    seconds: f64,
}

/// One camera's part of a [`Prepared`] frame, as read.
#[derive(Clone)]
pub(crate) struct CameraImage {
    pyramid: Pyramid,
    blank: bool,
    thumbs: BlockMeans,
}

impl Prepared {
    /// Camera `c`'s image (a copy).
    pub(crate) fn camera(&self, c: usize) -> CameraImage {
        CameraImage {
            pyramid: self.pyramids[c].clone(),
            blank: self.blank[c],
            thumbs: self.thumbs[c].clone(),
        }
    }

    /// Puts `image` in as camera `c`'s image; returns the one it replaces.
    pub(crate) fn swap_camera(&mut self, c: usize, image: CameraImage) -> CameraImage {
        CameraImage {
            pyramid: std::mem::replace(&mut self.pyramids[c], image.pyramid),
            blank: std::mem::replace(&mut self.blank[c], image.blank),
            thumbs: std::mem::replace(&mut self.thumbs[c], image.thumbs),
        }
    }

    /// The same frame with the images of `cameras` (indices) taken from `other`: for cameras
    /// found running a frame early, whose image of a frame is their file for the frame before
    /// ([`FrameReport::early_cameras`]), what [`Tracker::restore`] needs to continue where a
    /// run stopped. Indices past the rig are ignored.
    pub fn with_cameras_from(mut self, cameras: &[u16], other: &Prepared) -> Self {
        for &c in cameras {
            let c = c as usize;
            if c < self.pyramids.len() && c < other.pyramids.len() {
                self.swap_camera(c, other.camera(c));
            }
        }
        self
    }

    /// Time it took to build the pyramids, seconds.
    pub fn seconds(&self) -> f64 {
        self.seconds
    }

    /// The same frame, marked with the cameras (indices) that the tracker left out of it as
    /// repeats of the frame before or as running late when it solved it
    /// ([`FrameReport::repeated_cameras`], [`FrameReport::late_cameras`]): what
    /// [`Tracker::restore`] needs to continue exactly where a run stopped. Indices past the
    /// rig are ignored.
    pub fn with_repeated(mut self, cameras: &[u16]) -> Self {
        for &c in cameras {
            if let Some(r) = self.repeated.get_mut(c as usize) {
                *r = true;
            }
        }
        self
    }
}

/// The pyramid levels (the finest ones, `0..n`) at which the first frame is compared as a
/// second template: every level but the coarsest (the only one when there is one). The
/// coarsest level is where a frame's motion is caught, from the blurred images at their
/// smallest, with the convex Huber loss and every vertex free; there the first frame's
/// appearance differs from the frame's most (highlights and reflections that stayed with the
/// lights, shading after a turn, a hand that has moved), and those differences are large blobs
/// that pull the mesh as a whole. Compared there, the first frame folded a corner of the real
/// webcam board out of its plane (frames 12–15) under most small changes of the options; from
/// the next level on, it does what it is for, holding the mesh to the first frame against
/// drift, with pixel-sized residuals (docs/tracker.md, "The first frame as a second template").
/// With `finest` above 0 the levels below it are not solved, and a single level solved keeps
/// the anchor.
pub(crate) fn anchored_levels(levels: usize, finest: usize) -> usize {
    levels.saturating_sub(1).max(finest + 1)
}

/// The levels at which the cameras are compared with each other in the frame being solved
/// (`TrackOptions::stereo`): the two finest solved, never the coarsest (where a frame's motion is
/// caught, from blurred images at their smallest) unless it is the only level solved. Measured
/// on 720p webcams, the third finest level made the board's final error worse (0.369 against
/// 0.322 %).
pub(crate) fn stereo_levels(levels: usize, finest: usize) -> std::ops::Range<usize> {
    let end = (finest + 2).min(levels.saturating_sub(1)).max(finest + 1);
    finest..end
}

/// The pixel window `[x0, y0, x1, y1]` that `positions` project into in `camera`'s image at
/// `frame`, widened by 4 pixels and cut to the image; `None` when no vertex lies in front of the
/// camera or the window misses the image.
pub(crate) fn mesh_window(
    camera: &Camera,
    frame: u32,
    positions: &[Point3<f64>],
) -> Option<[f64; 4]> {
    let p = camera.at(frame);
    let mut w = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for q in positions.iter().filter_map(|x| p.project(x)) {
        w = [w[0].min(q.x), w[1].min(q.y), w[2].max(q.x), w[3].max(q.y)];
    }
    let pad = 4.0;
    let w = [
        (w[0] - pad).max(0.0),
        (w[1] - pad).max(0.0),
        (w[2] + pad).min(camera.width as f64 - 1.0),
        (w[3] + pad).min(camera.height as f64 - 1.0),
    ];
    (w[0] <= w[2] && w[1] <= w[3]).then_some(w)
}

/// The median over `triangles` (index, cost, weight: [`offset::cross_scan`]'s parts) of each
/// one's cost per unit weight: what most of the surface says, whatever an occluder or a highlight
/// over a few triangles does to the mean. `None` when no triangle has weight.
fn median_per_triangle(triangles: &[(u32, f64, f64)]) -> Option<f64> {
    let mut v: Vec<f64> = triangles
        .iter()
        .filter(|(_, _, w)| *w > 0.0)
        .map(|(_, c, w)| c / w)
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len();
    Some(if m % 2 == 1 {
        v[m / 2]
    } else {
        0.5 * (v[m / 2 - 1] + v[m / 2])
    })
}

/// The indices of the cameras `flags` marks (blank, repeated, late).
fn marked(flags: &[bool]) -> Vec<u16> {
    (0..flags.len() as u16)
        .filter(|&c| flags[c as usize])
        .collect()
}

/// `extra`'s patches and pixels appended to `set`'s.
/// Per vertex, `(to − from) / gap`: a velocity per frame.
fn velocity_of(from: &[Point3<f64>], to: &[Point3<f64>], gap: f64) -> Vec<Vector3<f64>> {
    from.iter().zip(to).map(|(a, b)| (b - a) / gap).collect()
}

fn merge_into(set: &mut PatchSet, extra: PatchSet) {
    let off = set.pixels.len() as u32;
    set.pixels.extend(extra.pixels);
    set.patches.extend(
        extra
            .patches
            .into_iter()
            .map(|p| crate::tracker::patch::Patch {
                start: p.start + off,
                end: p.end + off,
                ..p
            }),
    );
}

/// Builds the pyramids the tracker with `opts` needs from one frame's images (one per camera).
pub fn prepare(images: &[RgbImage], opts: &TrackOptions) -> Prepared {
    let t = Instant::now();
    let opts = opts.resolved_for(images.iter().map(|i| (i.width() as u32, i.height() as u32)));
    let pyramids = build_pyramids(images, opts.levels.max(1), opts.blur);
    // (`levels.max(1)` is `TrackOptions::used`'s resolution of the level count.)
    let thumbs: Vec<BlockMeans> = images.par_iter().map(RgbImage::block_means).collect();
    let texture: Vec<f32> = thumbs.iter().map(BlockMeans::spread).collect();
    Prepared {
        pyramids,
        blank: crate::base::image::blank_of(&texture),
        repeated: vec![false; thumbs.len()],
        thumbs,
        blur: opts.blur,
        seconds: t.elapsed().as_secs_f64(),
    }
}

/// Each camera's pyramid, a camera smaller than the largest with the images of the levels it
/// enters late (`pyramid::level_skips`, from the images' sizes as the tracker's from its
/// cameras').
fn build_pyramids(images: &[RgbImage], levels: usize, blur: f64) -> Vec<Pyramid> {
    let skips = level_skips(images.iter().map(|i| (i.width() as u32, i.height() as u32)));
    images
        .par_iter()
        .zip(skips)
        .map(|(img, skip)| Pyramid::with_skip(img, levels, blur, skip))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{anchored_levels, stereo_levels};

    #[test]
    fn the_cameras_are_compared_at_the_two_finest_levels_solved_and_never_the_coarsest() {
        // (levels, finest level solved) → levels compared across cameras.
        assert_eq!(stereo_levels(3, 0), 0..2);
        assert_eq!(stereo_levels(4, 0), 0..2);
        assert_eq!(stereo_levels(2, 0), 0..1);
        assert_eq!(stereo_levels(4, 1), 1..3);
        assert_eq!(stereo_levels(3, 1), 1..2);
        // One level solved: that one, coarsest or not.
        assert_eq!(stereo_levels(1, 0), 0..1);
        assert_eq!(stereo_levels(4, 3), 3..4);
        // The first frame is compared at every level solved but the coarsest, or at the one.
        assert_eq!(anchored_levels(4, 0), 3);
        assert_eq!(anchored_levels(4, 3), 4);
        assert_eq!(anchored_levels(1, 0), 1);
    }
}

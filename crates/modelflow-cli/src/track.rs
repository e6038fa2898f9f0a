//! `modelflow track`: tracks a scene's mesh through its frames and writes one OBJ per frame and a
//! JSON-lines log, with a progress bar (plain lines when stderr is not a terminal).

use crate::progress::Progress;
use crate::runfolder::{run_options, Invocation, OutArgs};
use modelflow::input::Scene;
use modelflow::tracker::{
    track_scene, GainModel, Interpolation, Loss, Regularisation, SolverOptions, TrackOptions,
    TrackSummary,
};
use modelflow::RunOptions;

#[derive(clap::Args, Clone, Debug)]
pub struct TrackArgs {
    /// Pyramid levels solved coarse to fine: a number (1 = full resolution only), or auto:
    /// as many as keep the coarsest level's short side at least 80 px (720 p: 4, 480 p: 3); 1 to 12.
    #[arg(long, default_value = "auto", value_parser = parse_levels)]
    pub levels: usize,
    /// The finest pyramid level solved: 0 = full resolution; 1 = half resolution (a draft or
    /// proxy track, about twice as fast), 2 = a quarter. With --levels auto the coarsest level
    /// stays where the image size puts it; with a number it must be below it.
    #[arg(long, default_value_t = 0)]
    pub finest_level: usize,
    /// Solve every pyramid level per vertex only, without first solving the coarsest one for one
    /// rigid motion of the whole mesh.
    #[arg(long)]
    pub no_rigid_stage: bool,
    /// Weight of the first frame as a second template, compared at every pyramid level but the coarsest (0 = compare with the previous frame only, as in the thesis; 0 to 100).
    #[arg(long, default_value_t = TrackOptions::default().anchor_weight)]
    pub anchor_weight: f64,
    /// Leave out template pixels that every other camera seeing the same surface point contradicts (an occluder in front of the surface in one camera, a highlight): the threshold, as a multiple of the median colour difference between cameras (0 = off; 0 to 1000).
    #[arg(long, default_value_t = TrackOptions::default().consensus)]
    pub consensus: f64,
    /// Weight of the cameras compared with each other in the frame being solved, at the two
    /// finest levels (0 = off; 0 to 100): holds the surface where all cameras agree it is, so
    /// depth does not drift with few cameras or a narrow baseline.
    #[arg(long, default_value_t = TrackOptions::default().stereo)]
    pub stereo: f64,
    /// Of each camera's pixels compared with the other cameras (--stereo), every N-th is kept,
    /// at N times the weight (1 to 64; 1 = all, slower).
    #[arg(long, value_name = "N", default_value_t = TrackOptions::default().stereo_stride)]
    pub stereo_stride: u32,
    /// Compare each camera (--stereo) with at most N other cameras, those whose view of the
    /// mesh is most alike its own (0 = every other camera; 0 to 1000). Rigs of more than
    /// N + 1 cameras then grow in work with the cameras, not with their square.
    #[arg(long, value_name = "N", default_value_t = TrackOptions::default().stereo_neighbours)]
    pub stereo_neighbours: u32,
    /// Spring constant k of the cubic edge springs (Eq. 5.16) on the edges' strain, each edge
    /// weighted by its share of the surface's area, so independent of units and triangulation
    /// (0 = off; 0 to 1e6).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.spring_k)]
    pub spring_k: f64,
    /// Spring threshold T, as a fraction of the rest length (Eq. 5.16; above 0, at most 10).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.spring_t)]
    pub spring_t: f64,
    /// Yield strain of the springs, as a fraction of the rest length: an edge the images held
    /// stretched (or compressed) beyond it in the previous frame has its spring centred on that
    /// length instead of its rest length, so a surface that really stretches is followed (0 =
    /// off: always the rest length, as in the thesis; 0 to 10).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.spring_yield)]
    pub spring_yield: f64,
    /// Beyond the yield strain, how far the spring's centre stands behind the previous frame's
    /// length, toward the rest length, as a fraction of the yield strain, while the surface
    /// shows no stretch (--spring-stretch-share): 1 pulls a strain back by the whole yield every
    /// frame; 0 resists only a change from the previous frame (0 to 1).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.spring_pull_back)]
    pub spring_pull_back: f64,
    /// The share of the mesh's edges that, strained beyond twice the yield in the previous
    /// frame, shows that the surface stretches (a bending limb, a swelling lobe; a cloth or a
    /// rigid object shows none): the springs' pull-back is then 0 for the frame (0 = off:
    /// always --spring-pull-back; 0 to 1).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.spring_stretch_share)]
    pub spring_stretch_share: f64,
    /// Weight of the frame-to-frame membrane term, on the edges' change of rate over the mean
    /// edge length (0 = off; 0 to 1e6).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.membrane)]
    pub membrane: f64,
    /// Keep the membrane's reference in its own orientation instead of turning it with each
    /// piece of the mesh: a change of the object's rotation rate is then resisted too (as
    /// before 2026-12-01; docs/tracker.md, "The membrane follows each piece's turn").
    #[arg(long)]
    pub membrane_resists_turns: bool,
    /// Weight of the bending term that keeps the mesh's local shape close to its rest shape up to
    /// rotation (0 = off; 0 to 1e6).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.bending)]
    pub bending: f64,
    /// Yield of the bending term, as a fraction of the mean edge length: where the previous
    /// frame's local shape was further than this from the rest shape's (a fold, a dent the images
    /// held), the term pulls toward that shape less the yield instead of the rest shape (0 = off:
    /// always the rest shape; 0 to 10).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.bending_yield)]
    pub bending_yield: f64,
    /// The bending term's yield where the previous frame's images pinned the vertex well (see
    /// --bending-seen-share): small, so only what the images hold is followed (0 to 10).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.bending_yield_seen)]
    pub bending_yield_seen: f64,
    /// Where --bending-yield-seen applies instead of --bending-yield: vertices whose information
    /// in the previous frame (the confidence file's `information`) was at least this share of
    /// the median over the vertices seen (0 = off: --bending-yield everywhere; 0 to 10).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.bending_seen_share)]
    pub bending_seen_share: f64,
    /// Gauss-Newton iterations at most per frame and level (1 to 10000).
    #[arg(long, default_value_t = TrackOptions::default().solver.max_iterations)]
    pub max_iterations: usize,
    /// Stop a level when a step lowers the cost by less than this fraction of it (0 to below 1).
    #[arg(long, default_value_t = TrackOptions::default().solver.min_relative_decrease)]
    pub min_decrease: f64,
    /// Stop an approach stage (the Huber solve of every level but the coarsest, when a finer
    /// level or the Tukey refine follows) when a step lowers its cost by less than this fraction
    /// of it; the coarsest level and the last solve use --min-decrease (0 = off; 0 to below 1).
    #[arg(long, default_value_t = TrackOptions::default().approach_decrease)]
    pub approach_decrease: f64,
    /// Weight, relative to the first-frame anchor's, of the first frame's view lent to cameras
    /// that see a triangle now but did not then (an object turned in front of the rig): keeps
    /// the sides that come into view from drifting (0 = off; 0 to 10).
    #[arg(long, default_value_t = TrackOptions::default().lent_anchor)]
    pub lent_anchor: f64,
    /// Every camera's shutter, as a fraction of a frame (0 to 1; 0.5 is a 180° shutter),
    /// instead of the scene's per-camera `shutter`: the template and the frame being solved are
    /// then compared under the smear their motions give both (fast motion under a long
    /// shutter). 0 compares the images as they are. Default: the scene's (0 where it gives none).
    #[arg(long, value_name = "FRACTION")]
    pub shutter: Option<f64>,
    /// Sticky edges (the thesis' §8.4.3): follow the mesh's outline against the background from
    /// frame to frame, each point along it weighed as this many template pixels per pixel of
    /// outline (0 = off, the default; 0 to 100). For a closed object against a plain
    /// background whose top or sides no camera faces; 1 is the setting measured
    /// (docs/tracker.md, "Sticky edges").
    #[arg(long, value_name = "WEIGHT", default_value_t = TrackOptions::default().sticky_edges)]
    pub sticky_edges: f64,
    /// Keep template pixels that another part of the mesh hides in the frame being solved (an
    /// arm in front of the body, a fold turned over); by default they are left out, judged
    /// from the mesh where each pyramid level starts.
    #[arg(long)]
    pub keep_hidden: bool,
    /// Keep template pixels whose way into the frame being solved crosses an occluder that
    /// stands still in front of the surface (a rod, a frame edge: pixels every other camera
    /// contradicts and the next frame shows unchanged); by default they are left out, the
    /// previous frame's and the first frame's, since at the occluder's edge they push the
    /// mesh back toward standing still.
    #[arg(long)]
    pub keep_near_occluders: bool,
    /// Track the first mesh as given even when it lies off the surface the cameras agree on (by
    /// default such a mesh, e.g. a visual hull made from silhouettes, has its vertices moved
    /// along their normals onto the surface before tracking; only a warning then).
    #[arg(long)]
    pub keep_shape: bool,
    /// See every camera as calibrated (by default, each camera's images are shifted by the
    /// fraction of a pixel at which the cameras agree best about the first mesh, when that
    /// makes them agree at least 5 % better: a calibration's error, which comparing the cameras
    /// with each other would otherwise put into the mesh).
    #[arg(long)]
    pub keep_calibration: bool,
    /// Solve every frame with the calibrated poses, even when a camera's view of the background
    /// shows it turned since the first frame (by default such a camera, e.g. a knocked tripod,
    /// is posed turned with it from that frame on; docs/tracker.md, "A camera that moves").
    #[arg(long)]
    pub keep_poses: bool,
    /// Huber threshold on the RGB residual (image values 0..1; above 0, at most 10).
    #[arg(long, default_value_t = TrackOptions::default().solver.huber)]
    pub huber: f64,
    /// Robust loss on each pixel's RGB residual: huber (fixed threshold --huber), or tukey
    /// (rejects pixels beyond --tukey-k times the median residual, at least --tukey-min).
    #[arg(long, value_enum, default_value_t = LossArg::from(TrackOptions::default().solver.loss))]
    pub loss: LossArg,
    /// With --loss tukey: the rejection threshold as a multiple of the median residual (above 0,
    /// at most 1000).
    #[arg(long, default_value_t = TrackOptions::default().solver.tukey_k)]
    pub tukey_k: f64,
    /// With --loss tukey: the smallest rejection threshold (RGB residual, image values 0..1; 0 to
    /// 10).
    #[arg(long, default_value_t = TrackOptions::default().solver.tukey_min)]
    pub tukey_min: f64,
    /// With --loss tukey: the misalignment in pixels a pixel on an edge may have and still be
    /// kept (the threshold grows by this times the local image gradient; 0 to 100).
    #[arg(long, default_value_t = TrackOptions::default().solver.tukey_px)]
    pub tukey_px: f64,
    /// With --loss tukey: a (triangle, camera) patch whose pixels fit worse, on average, than
    /// this fraction of their rejection thresholds (a highlight over a whole facet) is
    /// down-weighted as a whole, by a Cauchy loss of that scale (0 = off; 0 to 100).
    #[arg(long, default_value_t = TrackOptions::default().solver.patch_scale)]
    pub patch_scale: f64,
    /// Gaussian smoothing of the images before gradients are taken: its sigma, in pixels of
    /// each pyramid level (0 to 20).
    #[arg(long, default_value_t = TrackOptions::default().blur)]
    pub blur: f64,
    /// Compare every pixel of the previous frame at full resolution (default: every other one,
    /// a checkerboard at twice the weight, which halves the work at no measurable loss).
    #[arg(long)]
    pub all_pixels: bool,
    /// How the next frame is sampled between pixel centres: Catmull-Rom bicubic, or bilinear
    /// (about a fifth less time per frame, slightly less accurate).
    #[arg(long, value_enum, default_value_t = InterpolationArg::Cubic)]
    pub interpolation: InterpolationArg,
    /// Brightness change allowed between frames per (triangle, camera): none (the thesis'
    /// brightness constancy), one constant gain, or a gain varying linearly over the triangle.
    #[arg(long, value_enum, default_value_t = GainArg::Linear)]
    pub gain: GainArg,
    /// The largest brightness change the gains may take up, as a ratio either way (1 to 100):
    /// shading after a turn under the lights, exposure between cameras.
    #[arg(long, default_value_t = TrackOptions::default().solver.gain_range)]
    pub gain_range: f64,
}

/// `--loss`'s values (the library's `solve::Loss`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LossArg {
    Huber,
    Tukey,
}

impl From<Loss> for LossArg {
    fn from(l: Loss) -> Self {
        match l {
            Loss::Huber => LossArg::Huber,
            Loss::Tukey => LossArg::Tukey,
        }
    }
}

/// `--gain`'s values (the library's `solve::GainModel`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum GainArg {
    Off,
    Constant,
    Linear,
}

/// `--interpolation`'s values (the library's `solve::Interpolation`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum InterpolationArg {
    Cubic,
    Linear,
}

/// `--levels`: `auto` (0 in `TrackOptions`) or a number of levels from 1 to 12.
fn parse_levels(s: &str) -> Result<usize, String> {
    if s == "auto" {
        return Ok(0);
    }
    match s.parse::<usize>() {
        Ok(n) if (1..=12).contains(&n) => Ok(n),
        _ => Err(format!(
            "expected auto or a number of levels from 1 to 12, got {s}"
        )),
    }
}

impl TrackArgs {
    pub fn options(&self) -> TrackOptions {
        let d = TrackOptions::default();
        TrackOptions {
            levels: self.levels,
            finest_level: self.finest_level,
            anchor_weight: self.anchor_weight,
            consensus: self.consensus,
            stereo: self.stereo,
            stereo_stride: self.stereo_stride,
            stereo_neighbours: self.stereo_neighbours,
            approach_decrease: self.approach_decrease,
            lent_anchor: self.lent_anchor,
            shutter: self.shutter,
            sticky_edges: self.sticky_edges,
            hidden_ahead: !self.keep_hidden,
            still_occluders: !self.keep_near_occluders,
            onto_surface: !self.keep_shape,
            shift_cameras: !self.keep_calibration,
            steady_cameras: !self.keep_poses,
            blur: self.blur,
            checkerboard: !self.all_pixels,
            rigid_first: !self.no_rigid_stage,
            regularisation: Regularisation {
                spring_k: self.spring_k,
                spring_t: self.spring_t,
                spring_yield: self.spring_yield,
                spring_pull_back: self.spring_pull_back,
                spring_stretch_share: self.spring_stretch_share,
                membrane: self.membrane,
                membrane_turns: !self.membrane_resists_turns,
                bending: self.bending,
                bending_yield: self.bending_yield,
                bending_yield_seen: self.bending_yield_seen,
                bending_seen_share: self.bending_seen_share,
            },
            solver: SolverOptions {
                max_iterations: self.max_iterations,
                min_relative_decrease: self.min_decrease,
                huber: self.huber,
                loss: match self.loss {
                    LossArg::Huber => Loss::Huber,
                    LossArg::Tukey => Loss::Tukey,
                },
                tukey_k: self.tukey_k,
                tukey_min: self.tukey_min,
                tukey_px: self.tukey_px,
                patch_scale: self.patch_scale,
                interpolation: match self.interpolation {
                    InterpolationArg::Cubic => Interpolation::Cubic,
                    InterpolationArg::Linear => Interpolation::Linear,
                },
                gain: match self.gain {
                    GainArg::Off => GainModel::Off,
                    GainArg::Constant => GainModel::Constant,
                    GainArg::Linear => GainModel::Linear,
                },
                gain_range: self.gain_range,
                ..d.solver
            },
            ..d
        }
    }
}

#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// The scene file (modelflow-scene/1).
    #[arg(long)]
    scene: std::path::PathBuf,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    select: crate::select::SelectArgs,
    #[command(flatten)]
    memory: crate::select::MemoryArgs,
    /// Continue the run in --out from its last complete frame (same scene, same options); the
    /// result is identical to an uninterrupted run.
    #[arg(long, conflicts_with = "force")]
    resume: bool,
    /// Exit with an error (status 3) when any frame stalled: the solver could not lower the
    /// cost at all, so the mesh kept the previous frame's shape (a warning otherwise).
    #[arg(long)]
    strict: bool,
    #[command(flatten)]
    track: TrackArgs,
    #[command(flatten)]
    device: crate::device::DeviceArgs,
}

/// Height over longest edge below which `track` warns of a sliver triangle.
const SLIVER_RATIO: f64 = 1e-3;

/// Share of the seen surface seen by one camera only above which `track` warns (the rig's
/// views barely overlap: depth there is the regularisers' guess).
const ONE_CAMERA_WARN: f64 = 0.5;

/// Before tracking, from the first frame's images: whether the first mesh lies on the surface
/// the cameras agree on (`tracker::surface_offset`; a mesh off it is followed short of every
/// turn; warned only with --keep-shape, since otherwise the tracker itself moves such a mesh
/// onto the surface), and, for a mesh on it, whether it is placed where the images put it
/// (`tracker::placement`: a misplaced mesh is tracked as placed and stays that far off).
fn first_mesh_checks(
    scene: &Scene,
    scene_path: &std::path::Path,
    keep_shape: bool,
    shown: &[modelflow::base::RgbImage],
    blank: &[bool],
) -> anyhow::Result<modelflow::tracker::FirstMeshCheck> {
    // A blank first image gives its camera no first-frame template: the shot's first frame
    // is where the mesh is held to, so say so (later blank frames are warned as they come).
    if blank.iter().any(|&b| b) {
        let names: Vec<&str> = scene
            .cameras
            .iter()
            .zip(blank)
            .filter(|(_, b)| **b)
            .map(|(c, _)| c.name.as_str())
            .collect();
        eprintln!(
            "warning: at frame {}, the image of camera{} {} {} blank (next to one colour over the whole frame: a dropped frame written black, a lens cap): {} left out until {} something, and {} no first-frame template to hold the mesh to (docs/tracker.md, \"Blank frames\"). If the shot starts later, track from there with --frames.",
            scene.first,
            if names.len() > 1 { "s" } else { "" },
            names.join(", "),
            if names.len() > 1 { "are" } else { "is" },
            if names.len() > 1 { "they are" } else { "it is" },
            if names.len() > 1 { "they show" } else { "it shows" },
            if names.len() > 1 { "they have" } else { "it has" },
        );
    }
    // As the tracker compares them: in luminance when colour and monochrome cameras mix.
    let images = modelflow::base::comparable(shown);
    if let std::borrow::Cow::Owned(_) = images {
        let grey: Vec<&str> = scene
            .cameras
            .iter()
            .zip(shown.iter())
            .zip(blank)
            .filter(|((_, i), b)| !**b && i.is_grey())
            .map(|((c, _), _)| c.name.as_str())
            .collect();
        eprintln!(
            "note: camera{} {} record{} no colour: every camera is compared in luminance",
            if grey.len() > 1 { "s" } else { "" },
            grey.join(", "),
            if grey.len() > 1 { "" } else { "s" }
        );
    }
    let len = modelflow::base::Length::of(scene.units);
    if let Some(a) =
        modelflow::tracker::axes_swapped(&scene.mesh, &scene.cameras, scene.first, &images)
    {
        eprintln!(
            "warning: at frame {}, {a} (docs/scene-format.md, \"Convention\"). It is tracked as given.",
            scene.first
        );
    }
    let check =
        modelflow::tracker::first_mesh_check(&scene.mesh, &scene.cameras, scene.first, &images);
    warn_views(scene, &images, check.placement.is_some_and(|p| p.is_off()));
    // Farther off than the tracker moves a mesh onto the surface, or better explained by a
    // rigid move, it is misplaced: the placement check below names it.
    if let Some(off) = check.off_surface(scene.mesh.bbox_diagonal()) {
        // A mesh off the surface pulls the pose the cameras agree on: no placement check.
        if !keep_shape {
            return Ok(check);
        }
        let side = match (off.closed, off.pixels < 0.0) {
            (true, true) => "it lies outside the surface (a visual hull made from silhouettes does), and the tracker will turn it short of every turn of the object",
            (true, false) => "it lies inside the surface, and the tracker will turn it past every turn of the object",
            (false, _) => "it lies off the surface, and the tracker will turn it short of or past every turn of the object",
        };
        eprintln!(
            "warning: at frame {}, the cameras agree best with the mesh moved {}{:.1} px ({} {}) along its normals, {:.1}× better than where it is: {side} (docs/tracker.md, \"The first mesh must lie on the surface\"). Track without --keep-shape to have it moved onto the surface first (or modelflow align --surface).",
            scene.first,
            if off.at_limit { "at least " } else { "" },
            off.pixels,
            len.show(off.length),
            len.unit(),
            off.ratio
        );
        return Ok(check);
    }
    // What a calibration off by less than `MIN_DISPARITY_PX` does too: the cameras' views of
    // the surface shifted by that little relative to each other.
    let hint = "which a calibration off by as much does too (a principal point or a lens model slightly wrong, most of all in a rig whose cameras look from nearly the same side)";
    if let Some(p) = check.placement.filter(|p| p.is_off()) {
        // Along what the images hold loosely (a nearly round object's spin) `align` follows
        // their noise: those motions are not counted (`Placement::loose_left_out`).
        let loose = match p.loose_left_out {
            0 => String::new(),
            1 => ", leaving out a motion the images hold loosely".to_string(),
            n => format!(", leaving out {n} motions the images hold loosely"),
        };
        // `f64::MAX`: no ratio to give (the cameras agree perfectly where `align` ends).
        let gain = if p.agreement_gain < f64::MAX {
            format!("; they agree {:.2} times better there", p.agreement_gain)
        } else {
            String::new()
        };
        let calibration = match p.disparity.filter(|_| p.calibration_may_explain()) {
            Some(d) => format!(" Or a camera's calibration is off: the move shifts where the cameras see the surface relative to each other by only {d:.1} px, {hint}; check it before aligning."),
            None => String::new(),
        };
        eprintln!(
            "warning: at frame {}, the cameras agree best with the mesh moved as a whole by {} {} RMS ({:.1} % of its size; turned {:.1}°, its centre moved {} {}{loose}{gain}): it is not placed where the images put it, and the tracker will keep it that far off in every frame. Line it up first: modelflow align --scene {} --out aligned.obj (with the same --mesh and --frames), then track with --mesh aligned.obj (docs/tracker.md, \"Lining up the first mesh\").{calibration}",
            scene.first,
            len.show(p.rms),
            len.unit(),
            100.0 * p.fraction,
            p.degrees,
            len.show(p.translation),
            len.unit(),
            scene_path.display()
        );
    } else if let Some(s) = check.surface.filter(|s| s.explained_by_calibration()) {
        eprintln!(
            "note: at frame {}, the cameras agree {:.1}× better with the mesh {:.1} px along its normals, but that moves where they see its surface relative to each other by only {:.1} px, {hint}: it is tracked as given (docs/tracker.md, \"The first mesh must lie on the surface\"). A mesh made from silhouettes can be moved onto the surface with modelflow align --surface.",
            scene.first,
            s.ratio,
            s.pixels,
            s.disparity.unwrap_or(0.0),
        );
    }
    Ok(check)
}

/// Says by how much each camera's images were shifted to agree with the others about the first
/// mesh (`tracker::camera_shifts`, applied).
fn note_camera_shifts(scene: &Scene, s: &modelflow::tracker::CameraShifts) {
    let each: Vec<String> = scene
        .cameras
        .iter()
        .zip(&s.shifts)
        .map(|(c, d)| format!("{} ({:+.2}, {:+.2})", c.name, d[0], d[1]))
        .collect();
    eprintln!(
        "note: at frame {}, the cameras agree {:.0} % better about the first mesh with their images shifted by {} px (up to {:.2} px between two cameras): their calibration is good to about that. The tracker sees them shifted, so that comparing the cameras with each other does not put the calibration's error into the mesh (docs/tracker.md, \"Cameras that disagree by a fraction of a pixel\"); --keep-calibration sees them as calibrated.",
        scene.first,
        100.0 * (1.0 - s.cost_after / s.cost_before),
        each.join(", "),
        s.largest(),
    );
}

/// Warns about cameras whose views do not agree with the others' about the first mesh
/// (`tracker::view_agreement`): images that are another camera's, from another frame, or a
/// calibration far off. No camera is named for a mesh the placement check calls `misplaced`:
/// moved as a whole, it disagrees most with the cameras farthest apart, and the placement
/// warning says what is wrong then (that no two agree is still said, among its causes a mesh
/// not lined up).
fn warn_views(scene: &Scene, images: &[modelflow::base::RgbImage], misplaced: bool) {
    let v = modelflow::tracker::view_agreement(&scene.mesh, &scene.cameras, scene.first, images);
    let name = |c: usize| scene.cameras[c].name.as_str();
    let bad = v.disagreeing();
    // A camera is named only where some pair agrees: the best of them is said.
    let best = v
        .pairs
        .iter()
        .max_by(|a, b| a.contrast.total_cmp(&b.contrast));
    if let (false, false, Some(best)) = (bad.is_empty(), misplaced, best) {
        let names: Vec<&str> = bad.iter().map(|&c| name(c)).collect();
        let rest: Vec<&str> = (0..scene.cameras.len())
            .filter(|c| !bad.contains(c))
            .map(name)
            .collect();
        let one = bad.len() == 1;
        eprintln!(
            "warning: at frame {}, the view{} of camera{} {} agree{} with no other camera's about the mesh: {} pixels, warped into the others' through the mesh moved up to {} px along its normals, match theirs at best {:.2}× better than at worst (below {}; {} and {}: {:.1}×). {} images may be another camera's (folders swapped), from another frame (a frame_offset), or {} calibration wrong (pose, K, lens): tracking with {} pulls the mesh off. --cameras {} leaves {} out (docs/tracker.md, \"Cameras that do not agree about the first mesh\").",
            scene.first,
            if one { "" } else { "s" },
            if one { "" } else { "s" },
            names.join(", "),
            if one { "s" } else { "" },
            if one { "its" } else { "their" },
            modelflow::tracker::SURFACE_RANGE_PX,
            v.pairs
                .iter()
                .filter(|p| bad.contains(&p.a) || bad.contains(&p.b))
                .map(|p| p.contrast)
                .fold(0.0, f64::max),
            modelflow::tracker::AGREE_CONTRAST,
            name(best.a),
            name(best.b),
            best.contrast,
            if one { "Its" } else { "Their" },
            if one { "its" } else { "their" },
            if one { "it" } else { "them" },
            rest.join(","),
            if one { "it" } else { "them" },
        );
    } else if v.none_agree() {
        let best = v.pairs.iter().map(|p| p.contrast).fold(0.0, f64::max);
        eprintln!(
            "warning: at frame {}, no two cameras' views agree clearly about the mesh: each pair's pixels, warped into each other through the mesh moved up to {} px along its normals, match at best {best:.2}× better than at worst (below {}). The calibration or the images may be wrong (a lens model that is not the camera's, images from another camera or frame), the mesh may not be lined up with the first frame (modelflow align), or the surface shows too little texture to tell (docs/tracker.md, \"Cameras that do not agree about the first mesh\").",
            scene.first,
            modelflow::tracker::SURFACE_RANGE_PX,
            modelflow::tracker::AGREE_CONTRAST,
        );
    }
}

pub fn run(args: Args, invocation: &Invocation) -> anyhow::Result<()> {
    args.track.options().validate()?;
    let scene = args.select.load(&args.scene)?;
    args.memory.check(&scene)?;
    // Before anything is printed: a GPU asked for and missing ends the command here.
    let gpu = args.device.open()?;
    crate::select::warn_calibration(&scene);
    let slivers = scene.mesh.slivers(SLIVER_RATIO);
    if let Some(&(first, r)) = slivers.first() {
        let [a, b, c] = scene.mesh.triangles[first].map(|v| v + 1);
        // In a mesh of polygons, the face it was cut from (as the file counts faces).
        let which = match scene.mesh.polygons {
            Some(_) => format!(
                "the triangle {a} {b} {c} of face {} (vertices and faces counted from 1 as in OBJ)",
                scene.mesh.face_of_triangle(first) + 1
            ),
            None => format!(
                "triangle {} (vertices {a} {b} {c}, counted from 1 as in OBJ)",
                first + 1
            ),
        };
        eprintln!(
            "warning: the mesh has {} sliver triangle(s), thinner than 1/{} of their longest edge; the first is {which}, {:.1e} of its edge. Slivers are tracked, but own almost no pixels.",
            slivers.len(),
            (1.0 / SLIVER_RATIO) as u32,
            r
        );
    }
    let loose = scene.mesh.loose_vertices();
    if let Some(&first) = loose.first() {
        eprintln!(
            "note: {} of the mesh's {} vertices {} to no triangle (the first is vertex {}, counted from 1 as in OBJ); they carry no surface: no pixel moves them, they follow the mesh's motion as a whole, and the mesh's size (for percentages and the first-frame checks) leaves them out (remove them, e.g. Blender's Mesh > Clean Up > Delete Loose, unless they must stay)",
            loose.len(),
            scene.mesh.positions.len(),
            if loose.len() == 1 { "belongs" } else { "belong" },
            first + 1
        );
    }
    let merged = scene.mesh.welded();
    if let Some((m, _)) = &merged {
        eprintln!(
            "note: {} of the mesh's {} vertices lie exactly where another does (a mesh split along seams, or a triangle soup); the tracker joins them (the meshes written keep your vertices)",
            scene.mesh.positions.len() - m.positions.len(),
            scene.mesh.positions.len()
        );
    }
    let (_, turned) = merged
        .as_ref()
        .map_or(&scene.mesh, |(m, _)| m)
        .facing_outward();
    if turned > 0 {
        eprintln!(
            "note: {turned} of the mesh's {} triangles are wound against their neighbours or face into the closed surface they make; the tracker turns them (the meshes written keep your winding)",
            scene.mesh.triangles.len()
        );
    }
    let opts = args.track.options();
    // The first frame's images: a blank one sees nothing (the tracker leaves it out), so the
    // coverage is counted without its camera.
    let shown = scene.load_images(scene.first)?;
    let blank = modelflow::base::blank_images(&shown);
    let seeing: Vec<_> = scene
        .cameras
        .iter()
        .zip(&blank)
        .filter(|(_, b)| !**b)
        .map(|(c, _)| c.clone())
        .collect();
    let cover = modelflow::tracker::coverage(&scene.mesh, &seeing, scene.first, &opts);
    let left_out = match scene.cameras.len() - seeing.len() {
        0 => String::new(),
        1 => " (the camera whose image is blank left out)".to_string(),
        n => format!(" (the {n} cameras whose images are blank left out)"),
    };
    eprintln!(
        "at frame {}: {:.0} % of the mesh's surface is seen by two or more cameras, {:.0} % by one only, {:.0} % by none{left_out}",
        scene.first,
        100.0 * cover.two_or_more,
        100.0 * cover.one,
        100.0 * cover.none
    );
    if cover.one_camera_share() > ONE_CAMERA_WARN {
        // With a blank camera left out the cause is the image, not the rig.
        let advice = if left_out.is_empty() {
            "Add a camera whose view overlaps, or check the cameras' calibration."
        } else {
            "Counted without the blank image: the rig may see it from more cameras once that image shows something."
        };
        eprintln!(
            "warning: most of the surface the cameras see ({:.0} %) is seen by one camera only; there its depth comes from the regularisers alone and drifts over the shot (docs/tracker.md, \"Where depth comes from\"). {advice}",
            100.0 * cover.one_camera_share()
        );
    }
    // Made once: the tracker moves a mesh off the surface onto it from the same check.
    let check = if args.resume {
        None
    } else {
        Some(first_mesh_checks(
            &scene,
            &args.scene,
            !opts.onto_surface,
            &shown,
            &blank,
        )?)
    };
    let mut run = run_options(args.out.mode(args.resume), invocation);
    run.gpu = gpu;
    run.first_mesh_check = check;
    let summary = run_scene(&scene, &opts, &args.out.out, &run)?;
    if let Some(m) = &summary.first_mesh_moved {
        let len = modelflow::base::Length::of(scene.units);
        eprintln!(
            "note: at frame {}, the cameras agreed best with the mesh moved {}{:.1} px ({} {}) along its normals, {:.1}× better than where it was given: {}. Every vertex was moved along its normal onto the surface before tracking (median {} {}, at most {} {}), and the run starts from there (docs/tracker.md, \"The first mesh must lie on the surface\"); --keep-shape tracks the mesh as given.",
            scene.first,
            if m.found.at_limit { "at least " } else { "" },
            m.found.pixels,
            len.show(m.found.length),
            len.unit(),
            m.found.ratio,
            if !m.found.closed {
                "it lay off the surface"
            } else if m.found.pixels < 0.0 {
                "it lay outside the surface (a visual hull made from silhouettes does)"
            } else {
                "it lay inside the surface"
            },
            len.show(m.median),
            len.unit(),
            len.show(m.max),
            len.unit(),
        );
    }
    if let Some(s) = summary.camera_shifts.as_ref().filter(|s| s.applied) {
        note_camera_shifts(&scene, s);
    }
    let resumed = match summary.resumed_from {
        Some(f) => format!(", resumed after frame {f}"),
        None => String::new(),
    };
    let stalled = match summary.stalled_frames.len() {
        0 => String::new(),
        n => format!(
            ", {n} STALLED (the mesh did not move): frames {}",
            list_frames(&summary.stalled_frames)
        ),
    };
    let suspect = match summary.suspect_frames.len() {
        0 => String::new(),
        n => format!(
            ", {n} SUSPECT (the cameras disagreed about the surface, it showed next to no texture, the mesh folded over itself or leapt away, or a camera's image was blank or a repeat, or a camera turned): frames {}",
            list_frames(&summary.suspect_frames)
        ),
    };
    eprintln!(
        "tracked frames {}..={} ({} solved now{resumed}{stalled}{suspect}) in {:.1} s ({:.0} ms per frame, median; {} iterations per frame, median) -> {}",
        scene.first,
        scene.last,
        summary.solved,
        summary.total_seconds,
        summary.median_frame_seconds * 1e3,
        summary.median_iterations,
        args.out.out.display()
    );
    // A fold on an object that does not fold is drift the bending term let through
    // (docs/tracker.md, "The default since 2026-11-28"): say what to try.
    let folded = summary
        .checks
        .iter()
        .filter(|c| {
            c.concerns
                .iter()
                .any(|k| matches!(k, modelflow::tracker::Concern::Folded { .. }))
        })
        .count();
    if folded > 0 {
        eprintln!(
            "note: the mesh folded over itself in {folded} frame(s); if the object does not fold (a head, a hand-held object, a board), track it again with a stiffer bending term, --bending 0.06 (docs/your-footage.md, \"What the surface is made of\")"
        );
    }
    if args.strict && !summary.stalled_frames.is_empty() {
        return Err(crate::Failure::new(
            3,
            format!(
                "--strict: {} frame(s) stalled ({})",
                summary.stalled_frames.len(),
                list_frames(&summary.stalled_frames)
            ),
        )
        .into());
    }
    Ok(())
}

/// The scene's cameras at `indices`, by name, for a message.
fn camera_names(scene: &Scene, indices: &[u16]) -> String {
    let names: Vec<&str> = indices
        .iter()
        .filter_map(|&c| scene.cameras.get(c as usize))
        .map(|c| c.name.as_str())
        .collect();
    names.join(", ")
}

/// Frame numbers for a message: all of them up to ten, then a count.
fn list_frames(frames: &[u32]) -> String {
    let shown: Vec<String> = frames.iter().take(10).map(|f| f.to_string()).collect();
    match frames.len() {
        n if n > 10 => format!("{} and {} more", shown.join(", "), n - 10),
        _ => shown.join(", "),
    }
}

/// Tracks with a progress bar; shared by `track` and `demo`. An interrupted run says how to
/// continue it.
pub fn run_scene(
    scene: &Scene,
    opts: &TrackOptions,
    out: &std::path::Path,
    run: &RunOptions,
) -> anyhow::Result<TrackSummary> {
    let total = (scene.last - scene.first) as u64;
    let progress = Progress::new("track", total);
    let mut checks = modelflow::tracker::Checks::default();
    // A run of disagreement is flagged at every frame it lasts, and warned about once.
    let mut warned_since = None;
    // A resumed run's rules that span frames go on from the reports before it (read once, at
    // its first solved frame: the frame it resumed after is the one before).
    let mut replayed = run.mode != modelflow::OpenMode::Resume;
    let result = track_scene(scene, opts, out, run, &mut |f| {
        if !replayed {
            replayed = true;
            if let Ok(lines) = modelflow::read_frame_log(out) {
                checks = modelflow::tracker::Checks::resumed(
                    scene.first,
                    f.frame.saturating_sub(1),
                    lines
                        .iter()
                        .filter_map(|l| l.model_flow().map(|r| (l.frame, r))),
                );
            }
        }
        let r = f.model_flow();
        // The concerns this line adds (a slip shows in the next frame's report, so some are
        // about the frame before), one warning each; "started from a contradicted solution"
        // goes without saying after the warning about that solution.
        if let Some(r) = r {
            let added = checks.add(f.frame, scene.first, r);
            let disagreeing = checks.disagreeing();
            for (frame, c) in added {
                use modelflow::tracker::Concern;
                // Which cameras: a dead one shows frame after frame under its name.
                let cameras = match c {
                    Concern::StartedContradicted { .. } => continue,
                    Concern::Disagree { since, .. } => {
                        if warned_since == Some(since) {
                            continue;
                        }
                        warned_since = Some(since);
                        Some(&disagreeing)
                    }
                    Concern::Blank { .. } => Some(&r.blank_cameras),
                    Concern::Repeated { .. } => Some(&r.repeated_cameras),
                    Concern::Late { .. } => Some(&r.late_cameras),
                    Concern::Early { .. } => Some(&r.early_cameras),
                    Concern::Ahead { .. } => Some(&r.ahead_cameras),
                    Concern::Rejoined { .. } => Some(&r.rejoined_cameras),
                    Concern::Moved { .. } => Some(&r.moved_cameras),
                    _ => None,
                };
                let named =
                    cameras.map_or(String::new(), |c| format!(" ({})", camera_names(scene, c)));
                progress.println(&format!("warning: frame {frame}: {}{named}", c.describe()));
            }
        }
        progress.at(
            (f.frame - scene.first) as u64,
            &format!(
                "frame {} · {} it · cost {:.2e} -> {:.2e} · {:.0} ms",
                f.frame,
                r.map_or(0, |r| r.iterations),
                r.map_or(0.0, |r| r.cost_before),
                r.map_or(0.0, |r| r.cost_after),
                f.wall_seconds * 1e3
            ),
        );
    });
    progress.finish();
    // The last frame is judged after the loop (no next frame's report does it): by the rig's
    // share and each camera's, as the summary gives them.
    let last = result
        .as_ref()
        .ok()
        .and_then(|s| s.last_frame_check.as_ref());
    if let Some(v) = last {
        let added = checks.judge_last(scene.first, v);
        let disagreeing = checks.disagreeing();
        for (frame, c) in added {
            let named = match c {
                modelflow::tracker::Concern::Disagree { since, .. } => {
                    if warned_since == Some(since) {
                        continue;
                    }
                    warned_since = Some(since);
                    format!(" ({})", camera_names(scene, &disagreeing))
                }
                _ => String::new(),
            };
            eprintln!("warning: frame {frame}: {}{named}", c.describe());
        }
    }
    result.map_err(|e| {
        match &e {
            modelflow::Error::Interrupted { .. } => anyhow::Error::new(e).context(format!(
                "{} can be continued: run the same command with --resume",
                out.display()
            )),
            // What went wrong first, then what stands and how to go on.
            modelflow::Error::AtFrame { frame, .. } if *frame > scene.first => anyhow::anyhow!(
                "{e}\nframes {first}..={done} are tracked in {}: once the file is repaired, the same command with --resume goes on from there (or leave the camera out with --cameras, or stop before it with --frames {first}..{done})",
                out.display(),
                first = scene.first,
                done = frame - 1,
            ),
            _ => anyhow::Error::new(e),
        }
    })
}

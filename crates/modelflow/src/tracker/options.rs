//! The tracker's options: [`TrackOptions`] as given (what `modelflow track`'s flags set), and
//! [`OptionsUsed`], the same resolved and with what they imply, which the tracker runs with and
//! a run's manifest records (like Ceres' summary, which reports options as given and as used).

use crate::base::camera::Camera;
use crate::error::{Error, Result};
use crate::tracker::pyramid::auto_levels_of;
use crate::tracker::regularise::{self, Regularisation};
use crate::tracker::solve::{Interpolation, SolverOptions};
use serde::{Deserialize, Serialize};

/// Tracker settings. `Default` is what `modelflow track` uses.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackOptions {
    pub solver: SolverOptions,
    /// The regularisers' weights.
    pub regularisation: Regularisation,
    /// Pyramid levels solved, coarse to fine (1 = full resolution only; 0 = chosen from the
    /// image size, see `pyramid::auto_levels`).
    pub levels: usize,
    /// The finest pyramid level solved (0 = full resolution; 1 = half, 2 = a quarter): a draft
    /// or proxy track of high-resolution footage, about 2× faster per level left out, the mesh
    /// then as accurate as the images at that level allow. Counts within `levels`: the coarsest
    /// level stays where `levels` puts it.
    #[serde(default)]
    pub finest_level: usize,
    /// Gaussian smoothing (pixels, at each level's own scale) before gradients are taken.
    pub blur: f64,
    /// Weight of the first-frame template relative to the previous-frame one (0 = thesis only),
    /// compared at every pyramid level but the coarsest (`sequence::anchored_levels`).
    pub anchor_weight: f64,
    /// Silhouette margin in pixels.
    pub margin: usize,
    /// Grazing-angle cut-off (cosine between normal and view direction).
    pub min_cos: f64,
    /// Try a constant-velocity prediction as the starting guess.
    pub predict: bool,
    /// At full resolution, compare every other pixel of the previous frame (a checkerboard, at
    /// twice the weight) instead of all of them. Neighbouring pixels of a smoothed image carry
    /// nearly the same information, so this halves the finest level's work for no measurable
    /// loss of accuracy (the first-frame anchor is always a checkerboard).
    pub checkerboard: bool,
    /// Solve the coarsest pyramid level for one rigid motion of the whole mesh first, then per
    /// vertex (a hierarchy of motion models: large motion is caught by six unknowns that every
    /// triangle's pixels constrain together). The finer levels start from the coarser solution
    /// and solve per vertex only.
    #[serde(default = "yes")]
    pub rigid_first: bool,
    /// Template pixels that every other camera seeing the same surface point contradicts (an
    /// occluder in front of the surface in one camera, a highlight) are left out
    /// (`tracker::consensus`): the threshold, as a multiple of the median residual between
    /// cameras (0 = off).
    #[serde(default = "default_consensus")]
    pub consensus: f64,
    /// Weight of the cameras compared with each other in the frame being solved (0 = off):
    /// each camera's pixels warped into every other camera that sees the triangle, as `align`
    /// does, at the two finest levels solved (not at the coarsest, where the motion is
    /// caught). Each source pixel's comparisons share this weight (the previous frame's pixels
    /// weigh 1). It fixes where the surface is in every frame, so depth along a narrow
    /// baseline does not drift (`sequence::stereo_levels`; docs/tracker.md).
    #[serde(default)]
    pub stereo: f64,
    /// Of the pixels each camera takes for the comparisons with the other cameras (`stereo`),
    /// every `stereo_stride`-th is kept, at that many times the weight: the same pull for a
    /// fraction of the work (docs/tracker.md, "The cameras compared with each other"). Runs
    /// recorded before it existed kept every pixel (1).
    #[serde(default = "legacy_stereo_stride")]
    pub stereo_stride: u32,
    /// Each camera's pixels are compared (`stereo`) with at most this many other cameras:
    /// those whose direction to the mesh is closest to its own (most alike views of the same
    /// surface; `sequence::stereo_pairs`). 0 = every other camera, as runs recorded before it
    /// existed did. With four cameras or fewer the default compares them all; a ring of eight
    /// or sixteen compares each camera with its neighbours instead of the whole ring, whose
    /// comparisons grow with the square of the cameras (docs/tracker.md).
    #[serde(default)]
    pub stereo_neighbours: u32,
    /// An approach stage (the Huber solve of every level but the coarsest, when a finer level
    /// or the Tukey refine still follows) stops once an accepted step lowers its cost by less
    /// than this fraction of it, instead of `solver.min_relative_decrease`: what is left there
    /// is creep that the stage after it re-solves anyway. The coarsest level, which catches
    /// large motion, and the frame's last solve keep `min_relative_decrease`. 0 = off (every
    /// stage to `min_relative_decrease`, as runs made before it existed did).
    #[serde(default)]
    pub approach_decrease: f64,
    /// Weight, relative to the anchor's own, of the first frame's view lent to the cameras that
    /// see a triangle now but did not at the first frame (`Tracker::lend_anchor`): each such
    /// (triangle, camera) is compared with the first frame's best view of the triangle from
    /// another camera, so an object turning in front of the rig does not drift where the
    /// cameras see sides they did not see at first. 0 = off (runs made before it existed).
    #[serde(default)]
    pub lent_anchor: f64,
    /// Template pixels whose surface point another part of the mesh hides in the frame being
    /// solved, or lies at one of the mesh's depth edges there (an arm in front of the body, a
    /// fold turned over), are left out of each level's solve, judged from the mesh where the
    /// level starts (`tracker::occlusion`). Off in runs made before it existed.
    #[serde(default)]
    pub hidden_ahead: bool,
    /// Template pixels, the previous frame's and the anchor's, whose way into the frame being
    /// solved (from where the previous frame put them to where the prediction puts them)
    /// crosses an occluder that stands still there (a patch of pixels every other camera
    /// contradicts and the next frame shows unchanged) are left out (`tracker::occluder`).
    /// Off in runs made before it existed.
    #[serde(default)]
    pub still_occluders: bool,
    /// A first mesh that lies off the surface the cameras agree on (a visual hull made from
    /// silhouettes lies outside it; `tracker::surface_offset`: 1.5 px or more, clearly better
    /// agreement there) has its vertices moved along their normals onto the surface before
    /// tracking (`tracker::onto_surface`, as `align --surface` does), since a mesh off the
    /// surface is turned short of every turn of the object. The triangulation and the vertices'
    /// places along the surface are kept; the run's first mesh is the moved one. Off in runs
    /// made before it existed.
    #[serde(default)]
    pub onto_surface: bool,
    /// A static camera whose view of its background (its image outside the mesh's reach) has
    /// turned against its first frame's by more than half a pixel is posed turned with it from
    /// that frame on (`tracker::steady`: a knocked tripod, a slipping mount). Off in runs made
    /// before it existed.
    #[serde(default)]
    pub steady_cameras: bool,
    /// Each camera's images are shifted by the fraction of a pixel at which the cameras agree
    /// best about the first mesh (`tracker::camera_shifts`: a calibration's error, which
    /// the comparisons between cameras would otherwise turn into an error of the mesh). Off in
    /// runs made before it existed.
    #[serde(default)]
    pub shift_cameras: bool,
    /// Every camera's shutter, as a fraction of a frame (0 to 1), instead of the scene's
    /// per-camera `shutter` (`None`: the scene's; `Some(0.0)`: compare the images as they are,
    /// as runs made before it existed did). With a shutter, each template and the frame being
    /// solved are compared under the smear their motions give both (`tracker::smear`).
    #[serde(default)]
    pub shutter: Option<f64>,
    /// Weight of the sticky edges (`tracker::rim`, the thesis' §8.4.3): the mesh's outline
    /// against the background followed from the frame before, each point along it counting as
    /// this many template pixels per pixel of outline. 0 = off: the default, and runs made
    /// before it existed.
    #[serde(default)]
    pub sticky_edges: f64,
}

fn default_consensus() -> f64 {
    3.0
}

/// The stride of runs recorded before `stereo_stride` existed: every pixel.
fn legacy_stereo_stride() -> u32 {
    1
}

fn yes() -> bool {
    true
}

impl Default for TrackOptions {
    fn default() -> Self {
        TrackOptions {
            solver: SolverOptions::default(),
            regularisation: Regularisation::default(),
            levels: 0,
            finest_level: 0,
            blur: 1.0,
            anchor_weight: 2.0,
            margin: 1,
            min_cos: 0.1,
            predict: true,
            checkerboard: true,
            rigid_first: true,
            consensus: default_consensus(),
            stereo: 0.25,
            stereo_stride: 4,
            stereo_neighbours: 3,
            approach_decrease: 0.03,
            lent_anchor: 1.0,
            hidden_ahead: true,
            still_occluders: true,
            onto_surface: true,
            steady_cameras: true,
            shift_cameras: true,
            shutter: None,
            sticky_edges: 0.0,
        }
    }
}

/// The options a tracker runs with: the given ones resolved, and what they imply.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptionsUsed {
    /// The options after resolution (`levels` at least 1).
    pub options: TrackOptions,
    /// How the next frame is sampled by each pyramid level's last solve, level 0 (full
    /// resolution) first: the chosen interpolation at the finest level solved
    /// (`finest_level`), bilinear at the others (the coarser ones only bring the mesh near the
    /// solution; the finest decides it; levels finer than it are not solved). There a Huber
    /// solve that a Tukey refine follows samples bilinearly too: the refine decides.
    pub interpolation_per_level: Vec<Interpolation>,
    /// The regularisers in the cost, in the order the solver adds them.
    pub regularisers: Vec<String>,
}

/// One checked option: its name as `modelflow track` spells it, its value, and the valid range
/// (lower and upper bound, each inclusive or not), written once for the check and the message.
struct Range {
    option: &'static str,
    value: f64,
    low: (f64, bool),
    high: (f64, bool),
    why: &'static str,
}

impl Range {
    fn check(&self) -> Result<()> {
        let (lo, lo_in) = self.low;
        let (hi, hi_in) = self.high;
        let v = self.value;
        let ok = v.is_finite()
            && (if lo_in { v >= lo } else { v > lo })
            && (if hi_in { v <= hi } else { v < hi });
        if ok {
            return Ok(());
        }
        Err(Error::option(
            self.option,
            v,
            format!(
                "a number in {}{lo}, {hi}{}{}",
                if lo_in { "[" } else { "(" },
                if hi_in { "]" } else { ")" },
                if self.why.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", self.why)
                }
            ),
        ))
    }
}

impl TrackOptions {
    /// A camera's shutter as these options have the tracker take it: theirs when they give one,
    /// else the camera's own (the scene's).
    pub fn shutter_of(&self, camera: &Camera) -> f64 {
        self.shutter.unwrap_or(camera.shutter)
    }

    /// Checks every option against its documented range (`docs/tracker.md`, "Options and their
    /// ranges") before any work, naming the option as `modelflow track` spells it. Non-finite
    /// values are always refused: they would leave the mesh unmoved or never finish.
    pub fn validate(&self) -> Result<()> {
        if let Some(v) = self.shutter {
            Range {
                option: "--shutter",
                value: v,
                low: (0.0, true),
                high: (1.0, true),
                why: "the shutter's opening as a fraction of a frame; 0 = sharp",
            }
            .check()?;
        }
        let s = &self.solver;
        let r = &self.regularisation;
        let ranges = [
            Range {
                option: "--blur",
                value: self.blur,
                low: (0.0, true),
                high: (20.0, true),
                why: "pixels",
            },
            Range {
                option: "--anchor-weight",
                value: self.anchor_weight,
                low: (0.0, true),
                high: (100.0, true),
                why: "",
            },
            Range {
                option: "--sticky-edges",
                value: self.sticky_edges,
                low: (0.0, true),
                high: (100.0, true),
                why: "template pixels per pixel of outline; 0 = off",
            },
            Range {
                option: "--consensus",
                value: self.consensus,
                low: (0.0, true),
                high: (1000.0, true),
                why: "times the median residual between cameras; 0 = off",
            },
            Range {
                option: "--spring-k",
                value: r.spring_k,
                low: (0.0, true),
                high: (1e6, true),
                why: "",
            },
            Range {
                option: "--spring-t",
                value: r.spring_t,
                low: (0.0, false),
                high: (10.0, true),
                why: "a fraction of the rest length",
            },
            Range {
                option: "--spring-yield",
                value: r.spring_yield,
                low: (0.0, true),
                high: (10.0, true),
                why: "a fraction of the rest length; 0 = off",
            },
            Range {
                option: "--spring-pull-back",
                value: r.spring_pull_back,
                low: (0.0, true),
                high: (1.0, true),
                why: "a fraction of the yield strain",
            },
            Range {
                option: "--spring-stretch-share",
                value: r.spring_stretch_share,
                low: (0.0, true),
                high: (1.0, true),
                why: "a share of the edges; 0 = off",
            },
            Range {
                option: "--bending-yield",
                value: r.bending_yield,
                low: (0.0, true),
                high: (10.0, true),
                why: "a fraction of the mean edge length; 0 = off",
            },
            Range {
                option: "--bending-yield-seen",
                value: r.bending_yield_seen,
                low: (0.0, true),
                high: (10.0, true),
                why: "a fraction of the mean edge length; 0 = never",
            },
            Range {
                option: "--bending-seen-share",
                value: r.bending_seen_share,
                low: (0.0, true),
                high: (10.0, true),
                why: "a share of the median information; 0 = off",
            },
            Range {
                option: "--membrane",
                value: r.membrane,
                low: (0.0, true),
                high: (1e6, true),
                why: "",
            },
            Range {
                option: "--bending",
                value: r.bending,
                low: (0.0, true),
                high: (1e6, true),
                why: "",
            },
            Range {
                option: "--min-decrease",
                value: s.min_relative_decrease,
                low: (0.0, true),
                high: (1.0, false),
                why: "a fraction of the cost",
            },
            Range {
                option: "--approach-decrease",
                value: self.approach_decrease,
                low: (0.0, true),
                high: (1.0, false),
                why: "a fraction of the cost; 0 = off",
            },
            Range {
                option: "--lent-anchor",
                value: self.lent_anchor,
                low: (0.0, true),
                high: (10.0, true),
                why: "a weight relative to the anchor's; 0 = off",
            },
            Range {
                option: "--huber",
                value: s.huber,
                low: (0.0, false),
                high: (10.0, true),
                why: "RGB residual, image values 0..1",
            },
            Range {
                option: "--tukey-k",
                value: s.tukey_k,
                low: (0.0, false),
                high: (1000.0, true),
                why: "times the median residual",
            },
            Range {
                option: "--tukey-min",
                value: s.tukey_min,
                low: (0.0, true),
                high: (10.0, true),
                why: "RGB residual",
            },
            Range {
                option: "--tukey-px",
                value: s.tukey_px,
                low: (0.0, true),
                high: (100.0, true),
                why: "pixels",
            },
            Range {
                option: "--patch-scale",
                value: s.patch_scale,
                low: (0.0, true),
                high: (100.0, true),
                why: "fraction of the pixels' thresholds, 0 = off",
            },
            Range {
                option: "--gain-range",
                value: s.gain_range,
                low: (1.0, true),
                high: (100.0, true),
                why: "the largest brightness ratio between template and frame; 1 = no change",
            },
            Range {
                option: "--max-iterations",
                value: s.max_iterations as f64,
                low: (1.0, true),
                high: (10000.0, true),
                why: "",
            },
            Range {
                option: "--levels",
                value: self.levels as f64,
                low: (0.0, true),
                high: (12.0, true),
                why: "0 = automatic",
            },
            Range {
                option: "--stereo",
                value: self.stereo,
                low: (0.0, true),
                high: (100.0, true),
                why: "0 = off",
            },
            Range {
                option: "--stereo-stride",
                value: self.stereo_stride as f64,
                low: (1.0, true),
                high: (64.0, true),
                why: "every N-th pixel compared between cameras",
            },
            Range {
                option: "--stereo-neighbours",
                value: self.stereo_neighbours as f64,
                low: (0.0, true),
                high: (1000.0, true),
                why: "0 = every other camera",
            },
            Range {
                option: "--finest-level",
                value: self.finest_level as f64,
                low: (0.0, true),
                high: (11.0, true),
                why: "0 = full resolution",
            },
            Range {
                option: "min_cos",
                value: self.min_cos,
                low: (0.0, true),
                high: (1.0, false),
                why: "cosine",
            },
            Range {
                option: "margin",
                value: self.margin as f64,
                low: (0.0, true),
                high: (64.0, true),
                why: "pixels",
            },
        ];
        ranges.iter().try_for_each(Range::check)?;
        if self.levels > 0 && self.finest_level >= self.levels {
            return Err(Error::option(
                "--finest-level",
                self.finest_level,
                format!(
                    "a level below --levels {} (levels are numbered from 0, full resolution)",
                    self.levels
                ),
            ));
        }
        Ok(())
    }

    /// These options with `levels = 0` (automatic) resolved for images of the given sizes
    /// (width, height): the smallest image decides, counted at the largest's scale
    /// (`pyramid::auto_levels_of`: a camera half as large enters the levels one later).
    pub fn resolved_for(&self, sizes: impl IntoIterator<Item = (u32, u32)>) -> TrackOptions {
        if self.levels > 0 {
            return *self;
        }
        TrackOptions {
            levels: auto_levels_of(sizes).max(self.finest_level + 1),
            ..*self
        }
    }

    /// These options as a tracker uses them (automatic levels must be resolved first with
    /// [`TrackOptions::resolved_for`]; left at 0 they count as 1).
    pub fn used(&self) -> OptionsUsed {
        let options = TrackOptions {
            levels: self.levels.max(self.finest_level + 1),
            ..*self
        };
        let interpolation_per_level = (0..options.levels)
            .map(|l| {
                if l == options.finest_level {
                    options.solver.interpolation
                } else {
                    Interpolation::Linear
                }
            })
            .collect();
        let regularisers = regularise::names(&options.regularisation)
            .into_iter()
            .map(String::from)
            .collect();
        OptionsUsed {
            options,
            interpolation_per_level,
            regularisers,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default options as a run made before `fields` existed reads them back from its
    /// run.json (the fields left out of the JSON).
    fn read_without(fields: &[&str]) -> TrackOptions {
        let mut old = serde_json::to_value(TrackOptions::default()).expect("options as JSON");
        for f in fields {
            old.as_object_mut()
                .expect("an object")
                .remove(*f)
                .unwrap_or_else(|| panic!("the field {f} is written"));
        }
        serde_json::from_value(old).expect("an old run's options")
    }

    #[test]
    fn a_run_recorded_before_hidden_pixels_were_left_out_resumes_keeping_them() {
        // `--resume` reads the options from run.json: one written before `hidden_ahead` existed
        // names no such field and must go on as it was made (hidden pixels kept), while a new
        // run leaves them out.
        assert!(TrackOptions::default().hidden_ahead);
        let read = read_without(&["hidden_ahead"]);
        assert!(!read.hidden_ahead);
        assert_eq!(
            TrackOptions {
                hidden_ahead: true,
                ..read
            },
            TrackOptions::default()
        );
    }

    #[test]
    fn a_run_recorded_before_still_occluders_were_looked_for_resumes_without() {
        // Its run.json names no `still_occluders`: it must go on keeping the pixels whose way
        // crosses a still occluder, while a new run leaves them out.
        assert!(TrackOptions::default().still_occluders);
        let read = read_without(&["still_occluders"]);
        assert!(!read.still_occluders);
        assert_eq!(
            TrackOptions {
                still_occluders: true,
                ..read
            },
            TrackOptions::default()
        );
    }

    #[test]
    fn a_run_recorded_before_the_gains_range_was_widened_resumes_with_the_old_bound() {
        // Its run.json names no `gain_range`: the gains were held within [1/2, 2] then, and a
        // resumed run must go on so, while a new run takes the wider default.
        assert_eq!(TrackOptions::default().solver.gain_range, 4.0);
        let mut old = serde_json::to_value(TrackOptions::default()).expect("options as JSON");
        old["solver"]
            .as_object_mut()
            .expect("the solver's options")
            .remove("gain_range")
            .expect("the field is written");
        let read: TrackOptions = serde_json::from_value(old).expect("an old run's options");
        assert_eq!(read.solver.gain_range, 2.0);
        let mut now = read;
        now.solver.gain_range = 4.0;
        assert_eq!(now, TrackOptions::default());
    }

    #[test]
    fn a_run_recorded_before_the_cameras_were_compared_by_default_resumes_without_it() {
        // Runs made before `stereo` existed name neither field, and compared no cameras; runs
        // made while it was off by default name `stereo` (0 or the user's weight) but no
        // stride, and compared every pixel. Both resume as they ran; a new run takes the
        // defaults.
        let d = TrackOptions::default();
        assert_eq!((d.stereo, d.stereo_stride), (0.25, 4));
        let read = read_without(&["stereo_stride"]);
        assert_eq!((read.stereo, read.stereo_stride), (0.25, 1));
        let read = read_without(&["stereo_stride", "stereo", "stereo_neighbours"]);
        assert_eq!((read.stereo, read.stereo_stride), (0.0, 1));
        // Runs made before the neighbours were chosen compared every other camera.
        assert_eq!(read.stereo_neighbours, 0);
        assert_eq!(
            TrackOptions {
                stereo: 0.25,
                stereo_stride: 4,
                stereo_neighbours: 3,
                ..read
            },
            d
        );
    }

    #[test]
    fn a_run_recorded_before_first_meshes_were_moved_onto_the_surface_resumes_as_given() {
        // A resumed run rebuilds its first frame's templates from the scene's mesh: one made
        // before the tracker moved a mesh off the surface onto it must rebuild them from the
        // mesh as given, as it was made, while a new run moves it.
        assert!(TrackOptions::default().onto_surface);
        let read = read_without(&["onto_surface"]);
        assert!(!read.onto_surface);
        assert_eq!(
            TrackOptions {
                onto_surface: true,
                steady_cameras: true,
                shift_cameras: true,
                ..read
            },
            TrackOptions::default()
        );
    }

    #[test]
    fn the_shutter_is_the_scene_s_unless_given_and_checked_when_given() {
        // Runs made before the shutter was an option read no field, and compared the images as
        // they were, which is what the scene's shutter (0 in every scene made before it
        // existed) gives them.
        assert_eq!(TrackOptions::default().shutter, None);
        assert_eq!(read_without(&["shutter"]), TrackOptions::default());
        for ok in [0.0, 0.5, 1.0] {
            let o = TrackOptions {
                shutter: Some(ok),
                ..TrackOptions::default()
            };
            o.validate().unwrap();
        }
        for bad in [-0.1, 1.5, f64::NAN] {
            let o = TrackOptions {
                shutter: Some(bad),
                ..TrackOptions::default()
            };
            let msg = o.validate().unwrap_err().to_string();
            assert!(
                msg.contains("--shutter") && msg.contains("fraction of a frame"),
                "{msg}"
            );
        }
    }
}

//! Which frames of a track a user should look at, and why: the rules that turn the tracker's
//! per-frame reports (`FrameReport`, one `log.jsonl` line each) into named concerns, in one place
//! for `track`'s warnings and summary, the report's "Frames to check" and the Python binding.
//!
//! The cross-camera check judges a frame's solution only when the next frame's templates are taken
//! from it (the cameras compared at that solution, in that frame's images). So a slip shows one
//! frame late: the report of frame `t + 1` says that the cameras contradict where frame `t` left
//! the surface. Both are flagged: `t` because its solution is contradicted, `t + 1` because it
//! started from there. The last frame of a shot has no next frame to judge it: `track_scene`
//! takes the same check once the shot is done (`Tracker::contradicted_now`, one template's
//! building), adds it with [`Checks::judge_last`] (the rig's share and each camera's) and keeps
//! it in the manifest (`last_frame_check`), where the report reads it.
//!
//! Knows the reports' fields and the thresholds; nothing of images, files or the solver.

use crate::tracker::sequence::FrameReport;
use serde::{Deserialize, Serialize};

/// How far the share of the previous frame's finest template that the other cameras
/// contradict may rise above that share at the first frame (where the mesh is given lined up)
/// before a frame is reported as suspect (`FrameReport::suspect`). Footage has its own level of
/// disagreement between cameras (highlights that move with the viewpoint, an occluder, blur):
/// the Blender hard sample starts at 0.160 and stays within 0.024 of it, the real board held in
/// two hands within 0.026 of its start; cloths tracked past their capture range rose by 0.19 to
/// 0.37 in the frame after they slipped (docs/tracker.md, "Suspect frames").
pub const SUSPECT_RISE: f64 = 0.1;

/// How far one camera's own share of the previous frame's finest template that the other
/// cameras contradict (`FrameReport::contradicted_by_camera`: counted over the pixels that a
/// camera seeing their triangle alike checked, `consensus::CameraShare`) may rise above its
/// share at the first frame, frame after frame ([`DISAGREE_FRAMES`]), before its view is named
/// as disagreeing with the others' ([`Concern::Disagree`]). Judged in rigs of three cameras or
/// more, and not when every camera rises at once (that is the rig's disagreement with the
/// mesh, which [`SUSPECT_RISE`] judges; two cameras always rise together). A camera knocked
/// 0.5° off its calibration in front of a flat grey background (the blob, 4 cameras: 2.5 px at
/// 320×240, 4 px at 480×360) raised the two cameras that share its part of the surface by
/// 0.09–0.14 and 0.14–0.19 at every frame after (the irregular mesh 0.076–0.094, the crossing
/// 0.12–0.18); the rig's share rose by 0.03–0.07, under [`SUSPECT_RISE`], while the mesh
/// ended 0.76 % of its size off in both (0.20 and 0.35 % unknocked). Tracked clips stay lower
/// or come back within three frames: the Blender hard sample's cameras within 0.06 (one frame
/// 0.24, the rod), the real board's within 0.08 but for single frames up to 0.16 (two frames
/// running above this at most), objects turned all the way round in front of four cameras
/// within 0.1 for a frame or two (docs/tracker.md, "A camera whose view disagrees with the
/// others'").
pub const DISAGREE_RISE: f64 = 0.075;

/// How many reports running a camera's own contradicted share must stay above
/// [`DISAGREE_RISE`] before its view is named (the frames it judged are all flagged then).
pub const DISAGREE_FRAMES: usize = 5;

/// A camera's run of disagreement starts only where its own contradicted share came up
/// suddenly: by more than this above the lowest of its [`DISAGREE_SPAN`] reports before (its
/// first frame's level before those exist). A knock, a camera out of step or something stepping
/// in front raise it within a frame or two (the knocked blob: 0.09–0.14 in one report); a
/// highlight that moves into one camera's view as a glossy object turns raises it by a few
/// thousandths a report (a glossy surface rendered by Mitsuba: 0.09 over 22 frames, never more
/// than 0.02 in four; docs/tracker.md, "Footage from another renderer"), and is the footage's,
/// not a camera's.
pub const DISAGREE_JUMP: f64 = 0.5 * DISAGREE_RISE;

/// How many reports back [`DISAGREE_JUMP`] looks.
pub const DISAGREE_SPAN: usize = 4;

/// A frame is also suspect when the images constrain its solution less than this share of what
/// the first frame's own images give its mesh (`FrameReport::information_share`): the mesh sees
/// next to none of the surface's texture, as when it has slipped off onto the background. Tracked
/// clips keep 0.26 or more (the real board 0.29, the hard sample 0.33 while the rod covers it, a
/// 150-frame synthetic blob 0.26); meshes lost past the capture range fall to 0.00–0.03 once off
/// the surface (docs/tracker.md, "Suspect frames").
pub const INFORMATION_FLOOR: f64 = 0.1;

/// The change of velocity in one frame (RMS over the vertices, as a share of the mesh's
/// bounding-box diagonal) above which a frame is suspect ([`Concern::Jumped`]). The capture
/// range's fastest shake (80 px per frame at 1280×720, the direction random every frame) and
/// every clip tracked stay far below; a cloth pulled off by an occluder's edges in the template
/// leapt 0.81 (docs/tracker.md, "A leap in one frame").
pub const JUMP_SHARE: f64 = 0.5;

/// One reason to look at a frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Concern {
    /// No step lowered the cost at any level: the mesh kept the previous frame's shape.
    /// `no_pixels`: nothing of the mesh was compared at full resolution (out of every view).
    Stalled { no_pixels: bool },
    /// The other cameras contradicted `share` of where this frame left the surface, against
    /// `at_first` at the first frame (found when the next frame's templates were taken from it):
    /// the mesh may have slipped off the surface here, or a large occluder covers it.
    Contradicted { share: f64, at_first: f64 },
    /// This frame started from a solution the cameras contradicted (the previous frame's,
    /// [`Concern::Contradicted`]), so it is in doubt too.
    StartedContradicted { share: f64, at_first: f64 },
    /// The images constrain this frame's solution `share` as much as the first frame's own
    /// images constrain its mesh (below [`INFORMATION_FLOOR`]): it sees next to none of the
    /// surface's texture (slipped onto the background, out of view, turned away, blurred out).
    LittleTexture { share: f64 },
    /// `edges` pairs of neighbouring triangles that faced nearly the same way in the first
    /// frame's mesh face opposite ways at this frame's solution (`tracker::fold`): the mesh has
    /// folded over itself there.
    Folded { edges: usize },
    /// `cameras` cameras' images of this frame are blank (`image::blank_images`: one colour over
    /// the whole frame, as a dropped frame written black, a lens cap or a flash that blew it
    /// out): they were left out of this frame, and the mesh is held by the others only.
    Blank { cameras: usize },
    /// `cameras` cameras' images of this frame repeat their previous frame's over the mesh's
    /// window while another camera saw the mesh move (`repeated_of`: a dropped frame the
    /// recorder filled with the one before, a stream that froze): they show where the surface
    /// was, not where it is, and were left out of this frame.
    Repeated { cameras: usize },
    /// `cameras` cameras that repeated a frame agree with the other cameras' previous frame
    /// better than with this one (`LATE_RATIO`): they run a frame late since, and the mesh
    /// is pulled toward where it was.
    Late { cameras: usize },
    /// `cameras` cameras whose image of the previous frame agrees with the other cameras' images
    /// of this one clearly better than their own image of this frame does (`LATE_RATIO`):
    /// they dropped a frame and run a frame early since; from this frame on each frame takes
    /// their file for the frame before.
    Early { cameras: usize },
    /// `cameras` cameras taken a frame back since they were found running early are taken as
    /// they are from here: their own files of this frame agree with the other cameras clearly
    /// better (`LATE_RATIO`), or the file they would be taken back to repeats the last (they
    /// caught up). The frames since they were taken back are in doubt.
    Rejoined { cameras: usize },
    /// The next frame found `cameras` cameras running a frame early since this one: this frame
    /// was solved with their image a frame ahead of the others', which pulls the mesh.
    Ahead { cameras: usize },
    /// `cameras` cameras' views of their background turned since the first frame, by up to `px`
    /// pixels from where the tracker had them (`tracker::steady`: a knock on a tripod, a mount
    /// that slipped): this frame and the later ones are solved with their poses turned to match.
    Moved { cameras: usize, px: f64 },
    /// `cameras` cameras' own shares of the templates that the other cameras contradict
    /// (`FrameReport::contradicted_by_camera`) have stayed more than [`DISAGREE_RISE`] above
    /// their shares at the first frame, by up to `rise`, at every frame since `since`'s
    /// solution was judged ([`DISAGREE_FRAMES`] or more frames running), while the rig's share
    /// may not have risen much: their views and the others' no longer agree where the surface
    /// is. A camera knocked off its calibration in front of a background too plain to see it
    /// by (`Moved` needs texture behind the surface), a camera out of step with the rig, or an
    /// occluder standing in front of the surface in one camera's view for long.
    Disagree {
        cameras: usize,
        rise: f64,
        since: u32,
    },
    /// The solution is `share` of the mesh's size (RMS over the vertices, above `JUMP_SHARE`)
    /// from where the previous frame's motion carried on would have put it
    /// ([`FrameReport::jump`]): a leap no motion the tracker follows makes in one frame; it
    /// slipped onto something else (after an occluder left, a camera's images came back...).
    Jumped { share: f64 },
}

impl Concern {
    /// Whether this concern makes the frame suspect (as opposed to stalled).
    pub fn is_suspect(&self) -> bool {
        !matches!(self, Concern::Stalled { .. })
    }

    /// One sentence for a user: what was seen and what it may mean.
    pub fn describe(&self) -> String {
        match *self {
            Concern::Stalled { no_pixels: true } => "no pixel of the mesh was compared at full resolution (it is out of every camera's view, or hidden); the mesh kept the previous frame's shape".into(),
            Concern::Stalled { no_pixels: false } => "no step lowered the cost (every step, shortened down to 1/64, raised it); the mesh kept the previous frame's shape".into(),
            Concern::Contradicted { share, at_first } => format!(
                "the other cameras contradict {:.0} % of where this frame left the surface, against {:.0} % at the first frame (a rise of more than {:.0} points): the mesh may have slipped off the surface here (motion beyond the capture range), or a large occluder covers it",
                100.0 * share,
                100.0 * at_first,
                100.0 * SUSPECT_RISE
            ),
            Concern::StartedContradicted { share, at_first } => format!(
                "started from the previous frame's solution, which the other cameras contradict ({:.0} % against {:.0} % at the first frame)",
                100.0 * share,
                100.0 * at_first
            ),
            Concern::LittleTexture { share } => format!(
                "the images constrain the mesh {:.0} % as much as the first frame's own images do (below {:.0} %): it sees next to none of the surface's texture, so it may have slipped off onto the background (motion beyond the capture range), or the surface left the views, turned away or blurred out",
                100.0 * share,
                100.0 * INFORMATION_FLOOR
            ),
            Concern::Blank { cameras } => format!(
                "{} blank (next to one colour over the whole frame: a dropped frame written black, a lens cap, a flash that blew it out), left out of this frame: the mesh is held by the other cameras only",
                counted(cameras, "1 camera's image is", "cameras' images are")
            ),
            Concern::Repeated { cameras } => format!(
                "{} the previous frame's over the mesh while another camera saw it move (a dropped frame filled in with the one before, or a stream that froze), left out of this frame: the mesh is held by the other cameras only (the next frames are checked for the camera running a frame late since)",
                counted(cameras, "1 camera's image repeats", "cameras' images repeat")
            ),
            Concern::Late { cameras } => format!(
                "{} a frame late since repeating a frame (its image agrees with the other cameras' previous frame better than with this one), so the mesh is pulled toward where it was: track from here on with its frame_offset raised by 1 (docs/scene-format.md)",
                counted(cameras, "1 camera runs", "cameras run")
            ),
            Concern::Early { cameras } => format!(
                "{} a frame early since the frame before (its image of that frame agrees with the other cameras' images of this one better than its own image of this one does: it dropped a frame): from this frame on, its image of each frame is taken from its file for the frame before, as its frame_offset lowered by 1 would (docs/scene-format.md; the log's early_cameras)",
                counted(cameras, "1 camera runs", "cameras run")
            ),
            Concern::Rejoined { cameras } => format!(
                "{} since {} found running a frame early now {} with the other cameras better in {} own files (a false alarm, or {} caught up): {} own files are taken from this frame on; the frames since {} taken back are in doubt, check them",
                counted(cameras, "1 camera taken a frame back", "cameras taken a frame back"),
                if cameras == 1 { "it was" } else { "they were" },
                if cameras == 1 { "agrees" } else { "agree" },
                if cameras == 1 { "its" } else { "their" },
                if cameras == 1 { "it" } else { "they" },
                if cameras == 1 { "its" } else { "their" },
                if cameras == 1 { "it was" } else { "they were" },
            ),
            Concern::Ahead { cameras } => format!(
                "solved with {} a frame ahead of the others' (found at the next frame: a frame it dropped, or one swapped in), which pulls the mesh toward where the surface went next: check this frame's mesh",
                counted(cameras, "1 camera's image", "cameras' images")
            ),
            Concern::Moved { cameras, px } => format!(
                "{} since the first frame (its view of the background moved {px:.1} px against its first frame's: a knock on its tripod, a slipping mount); this frame and the later ones are solved with its pose turned to match (the log's camera_turns): check the overlay, and recalibrate it if it keeps moving",
                counted(cameras, "1 camera has turned", "cameras have turned")
            ),
            Concern::Disagree { cameras, rise, since } => format!(
                "{} disagreed with the other cameras' about where the surface is at every frame since frame {since} (the share of {} own pixels the others contradict rose up to {:.0} points above {} first frame's, more than {:.1} points for {} frames or more): a camera may have been knocked off its calibration in front of a background too plain to show it, or run out of step, or something stands in front of the surface in {} view; the mesh is pulled between them: check these cameras' overlays, and recalibrate or leave out (--cameras) the one that moved",
                counted(cameras, "1 camera's view has", "cameras' views have"),
                if cameras == 1 { "its" } else { "their" },
                100.0 * rise,
                if cameras == 1 { "its" } else { "their" },
                100.0 * DISAGREE_RISE,
                DISAGREE_FRAMES,
                if cameras == 1 { "its" } else { "their" },
            ),
            Concern::Jumped { share } => format!(
                "the mesh leapt {:.0} % of its size away from where the previous frame's motion would have put it (more than {:.0} %, past anything the tracker follows in one frame): it has likely slipped off the surface onto something else",
                100.0 * share,
                100.0 * JUMP_SHARE
            ),
            Concern::Folded { edges } => format!(
                "the mesh has folded over itself: {edges} pair{} of neighbouring triangles that faced within {:.0}° of each other at the first frame face more than {:.0}° apart here (usually where part of the surface turned out of every view and came back, or a tight crease collapsed); the vertices there are likely off the surface",
                if edges == 1 { "" } else { "s" },
                crate::tracker::fold::WATCH_BELOW_DEGREES,
                crate::tracker::fold::FOLDED_DEGREES
            ),
        }
    }
}

/// A camera's image repeats the previous frame's when its block means
/// (`image::BlockMeans`, 8×8-pixel luminance means) over the mesh's window changed by less than
/// this, RMS: a twentieth of an 8-bit code value. The same frame written twice (a recorder that
/// fills a dropped frame with the one before, a stream that froze) changes by 0; sensor noise
/// alone changes a real camera's block means by about 10⁻³, so a still camera is not a repeat.
pub const REPEAT_CHANGE: f64 = 2.5e-4;
/// ... and another camera's view of the mesh changed by at least this (ten times as much, and
/// more than sensor noise): the surface moved, and the repeating camera did not see it.
pub const REPEAT_MOVED: f64 = 2.5e-3;

/// A camera that repeated a frame runs a frame late when, at a later frame, its comparison with
/// the other cameras (the pairs it is in) with its image beside their previous frame, at the
/// previous solution, is below this share of the same with their frame, at this solution.
/// Measured at the first frame after the repeat: a camera in step 1/365 (two cameras) of the
/// late comparison, one a frame late 1/300 (two cameras) and 0.45 (a limb's four cameras,
/// whose view-dependent shading both comparisons share); docs/tracker.md, "Repeated frames".
pub const LATE_RATIO: f64 = 2.0 / 3.0;

/// A camera's view leapt when its change since the previous frame grew, against its change at
/// the previous frame, by at least this times the median of the same growth in the other
/// cameras ([`growth_of`]): a frame it dropped shows about twice a frame's motion (1.7 on the
/// shaken cloth; 1.2 at 20 px a frame, where the 8×8-pixel block means no longer follow the
/// motion in proportion), where every camera sees the object speed up or slow down alike.
/// Footage with hands, a rod or glare passing one camera's view leaps too (up to 3.5 on the
/// real board, 12 on the Blender hard sample; views leap on 13 of the real board's 19 frames),
/// which is why a leap is only a reason to ask at the next frame (two comparisons of the
/// cameras; docs/tracker.md, "A camera that runs a frame early").
pub const LEAP_RATIO: f64 = 1.15;

/// Per camera, how its view's change grew since the previous frame against the other cameras':
/// its growth `changes/before` (each camera's view change at this frame and at the previous
/// one, as [`repeated_of`] reads them) over the median growth of the other cameras. `None` for
/// a camera `out` (left out of either frame), one that did not see the mesh move in both frames
/// ([`REPEAT_MOVED`]), or with no other camera to compare with. At least [`LEAP_RATIO`]: the
/// view leapt (a frame dropped shows two frames' motion).
pub fn growth_of(
    changes: &[Option<f64>],
    before: &[Option<f64>],
    out: &[bool],
) -> Vec<Option<f64>> {
    let growth: Vec<Option<f64>> = (0..changes.len())
        .map(|c| {
            let (now, then) = (changes[c]?, before.get(c).copied().flatten()?);
            (!out.get(c).copied().unwrap_or(true) && now >= REPEAT_MOVED && then >= REPEAT_MOVED)
                .then(|| now / then)
        })
        .collect();
    (0..changes.len())
        .map(|c| {
            let g = growth[c]?;
            let mut others: Vec<f64> = (0..changes.len())
                .filter(|&o| o != c)
                .filter_map(|o| growth[o])
                .collect();
            if others.is_empty() {
                return None;
            }
            others.sort_by(f64::total_cmp);
            let m = others.len();
            let median = if m % 2 == 1 {
                others[m / 2]
            } else {
                0.5 * (others[m / 2 - 1] + others[m / 2])
            };
            Some(g / median)
        })
        .collect()
}

/// Which cameras' images of a frame repeat their previous frame's, from each camera's change
/// of its block means over the mesh's window since then (`None`: not measured, e.g. a blank
/// image or a mesh out of view): a change below [`REPEAT_CHANGE`] while another camera's is at
/// least [`REPEAT_MOVED`]. When no camera saw the mesh move (it stood still, or a rig of one),
/// nothing is a repeat: the frame is the same as the last, and comparing it does no harm.
pub fn repeated_of(changes: &[Option<f64>]) -> Vec<bool> {
    changes
        .iter()
        .enumerate()
        .map(|(c, d)| {
            d.is_some_and(|d| {
                d < REPEAT_CHANGE
                    && changes
                        .iter()
                        .enumerate()
                        .any(|(o, e)| o != c && e.is_some_and(|e| e >= REPEAT_MOVED))
            })
        })
        .collect()
}

/// "1 camera's image is" or "N cameras' images are": `one` for one camera, `many` after the count.
fn counted(cameras: usize, one: &str, many: &str) -> String {
    if cameras == 1 {
        one.to_string()
    } else {
        format!("{cameras} {many}")
    }
}

/// A frame to look at and every reason found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameCheck {
    pub frame: u32,
    pub concerns: Vec<Concern>,
}

impl FrameCheck {
    /// Whether the solver could not move the mesh in this frame.
    pub fn stalled(&self) -> bool {
        self.concerns
            .iter()
            .any(|c| matches!(c, Concern::Stalled { .. }))
    }

    /// Whether this frame's solution may be wrong.
    pub fn suspect(&self) -> bool {
        self.concerns.iter().any(Concern::is_suspect)
    }
}

/// Whether a report's templates, taken from the previous frame's solution, show the cameras
/// contradicting that solution (a rise of more than [`SUSPECT_RISE`] over the first frame's level).
pub fn contradicts_previous(r: &FrameReport) -> bool {
    rose(r.contradicted_share, r.contradicted_at_first)
}

/// The one threshold: a contradicted `share` more than [`SUSPECT_RISE`] above `at_first`.
fn rose(share: f64, at_first: f64) -> bool {
    share > at_first + SUSPECT_RISE
}

/// The concerns a frame's own report shows (not yet the next frame's verdict on it).
pub fn own_concerns(r: &FrameReport) -> Vec<Concern> {
    let mut c = Vec::new();
    if r.stalled {
        c.push(Concern::Stalled {
            no_pixels: r.pixels == 0,
        });
    }
    if contradicts_previous(r) {
        c.push(Concern::StartedContradicted {
            share: r.contradicted_share,
            at_first: r.contradicted_at_first,
        });
    }
    // Measured against the first frame seen by every camera: a frame that left a camera out
    // (blank, repeated, late) has less to go on by that alone, and says so below.
    let left_out =
        !r.blank_cameras.is_empty() || !r.repeated_cameras.is_empty() || !r.late_cameras.is_empty();
    if r.information_share < INFORMATION_FLOOR && !left_out {
        c.push(Concern::LittleTexture {
            share: r.information_share,
        });
    }
    if r.folded > 0 {
        c.push(Concern::Folded { edges: r.folded });
    }
    if r.jump > JUMP_SHARE {
        c.push(Concern::Jumped { share: r.jump });
    }
    if !r.blank_cameras.is_empty() {
        c.push(Concern::Blank {
            cameras: r.blank_cameras.len(),
        });
    }
    if !r.repeated_cameras.is_empty() {
        c.push(Concern::Repeated {
            cameras: r.repeated_cameras.len(),
        });
    }
    if !r.late_cameras.is_empty() {
        c.push(Concern::Late {
            cameras: r.late_cameras.len(),
        });
    }
    if !r.rejoined_cameras.is_empty() {
        c.push(Concern::Rejoined {
            cameras: r.rejoined_cameras.len(),
        });
    }
    // Found early here: taken a frame back from here (a camera that repeats what it showed a
    // frame ahead is in `ahead_cameras` without being early).
    let found_early = r
        .ahead_cameras
        .iter()
        .filter(|c| r.early_cameras.contains(c))
        .count();
    if found_early > 0 {
        c.push(Concern::Early {
            cameras: found_early,
        });
    }
    if !r.moved_cameras.is_empty() {
        c.push(Concern::Moved {
            cameras: r.moved_cameras.len(),
            px: r.moved_px.iter().copied().fold(0.0, f64::max),
        });
    }
    c
}

/// The cross-camera check on a run's last frame, as a next frame's templates would have taken
/// it (`Tracker::contradicted_now`), the manifest's `last_frame_check`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LastFrameCheck {
    pub frame: u32,
    /// The share of the template taken from that frame's solution that the other cameras
    /// contradict (0 to 1), as a log line's `contradicted_share`.
    pub contradicted_share: f64,
    /// The same share at the first frame, as a log line's `contradicted_at_first`.
    pub contradicted_at_first: f64,
    /// Each camera's own share, as a log line's `contradicted_by_camera` (`null`: the camera
    /// took no pixels); empty in manifests written before 2026-12-04.
    #[serde(default)]
    pub contradicted_by_camera: Vec<Option<f64>>,
    /// The same at the first frame, as a log line's `contradicted_by_camera_at_first`.
    #[serde(default)]
    pub contradicted_by_camera_at_first: Vec<Option<f64>>,
}

impl LastFrameCheck {
    /// The check on `frame` as the next frame's report `r` took it (a run read back over a
    /// range that ends before the run does).
    pub fn of_report(frame: u32, r: &FrameReport) -> LastFrameCheck {
        LastFrameCheck {
            frame,
            contradicted_share: r.contradicted_share,
            contradicted_at_first: r.contradicted_at_first,
            contradicted_by_camera: r.contradicted_by_camera.clone(),
            contradicted_by_camera_at_first: r.contradicted_by_camera_at_first.clone(),
        }
    }
}

/// Collects the frames to check as reports arrive in frame order.
#[derive(Clone, Debug, Default)]
pub struct Checks {
    list: Vec<FrameCheck>,
    /// Per camera, how many reports running (the last ones added that measured it) showed its
    /// own contradicted share more than [`DISAGREE_RISE`] above its first frame's, and the
    /// frame of the first of them.
    disagree_run: Vec<(usize, u32)>,
    /// Per camera, its rises at the last [`DISAGREE_SPAN`] reports that measured it, oldest
    /// first (for [`DISAGREE_JUMP`]).
    recent_rises: Vec<Vec<f64>>,
    /// The first frame whose solution the current run of disagreement judged (the frame
    /// before the run's first report), while some camera's run is long enough to be named.
    disagree_since: Option<u32>,
    /// A resumed run's frames flagged before the resume ([`Checks::resumed`]): not listed
    /// again, but a run of disagreement that reaches back does not flag them twice.
    before_resume: Vec<FrameCheck>,
}

impl Checks {
    /// Adds frame `frame`'s report. When it shows the cameras contradicting the previous frame's
    /// solution and the previous frame was solved (it is after `first`, the given mesh), that
    /// frame is flagged too
    /// ([`Concern::Contradicted`]). Returns the concerns added, by frame (the previous frame's
    /// first), for warnings.
    pub fn add(&mut self, frame: u32, first: u32, r: &FrameReport) -> Vec<(u32, Concern)> {
        let mut added: Vec<(u32, Concern)> = frame
            .checked_sub(1)
            .and_then(|prev| self.judge(prev, first, r.contradicted_share, r.contradicted_at_first))
            .into_iter()
            .collect();
        added.extend(self.disagreement(
            frame,
            first,
            &r.contradicted_by_camera,
            &r.contradicted_by_camera_at_first,
        ));
        if !r.ahead_cameras.is_empty() && frame > first + 1 {
            // The frame before was solved with the cameras found early here a frame ahead.
            let c = Concern::Ahead {
                cameras: r.ahead_cameras.len(),
            };
            self.push(frame - 1, c);
            added.push((frame - 1, c));
        }
        for c in own_concerns(r) {
            self.push(frame, c);
            added.push((frame, c));
        }
        added
    }

    /// Adds the cross-camera check's verdict on frame `frame`'s solution (`share` contradicted,
    /// against `at_first` at the first frame), as the next frame's report or, for a shot's last
    /// frame, `Tracker::contradicted_now` gives it. Returns the concern when it flags the frame
    /// (never `first`, the given mesh).
    pub fn judge(
        &mut self,
        frame: u32,
        first: u32,
        share: f64,
        at_first: f64,
    ) -> Option<(u32, Concern)> {
        if frame <= first || !rose(share, at_first) {
            return None;
        }
        let c = Concern::Contradicted { share, at_first };
        self.push(frame, c);
        Some((frame, c))
    }

    /// The cross-camera check on a shot's last frame, taken once it is solved
    /// (`Tracker::contradicted_now`; the manifest's `last_frame_check`): the rig's share as
    /// [`Checks::judge`] judges it, and each camera's as the next frame's report would have
    /// given them to the per-camera rule. Returns the concerns added, by frame.
    pub fn judge_last(&mut self, first: u32, check: &LastFrameCheck) -> Vec<(u32, Concern)> {
        let frame = check.frame;
        let mut added: Vec<(u32, Concern)> = self
            .judge(
                frame,
                first,
                check.contradicted_share,
                check.contradicted_at_first,
            )
            .into_iter()
            .collect();
        added.extend(self.disagreement(
            frame + 1,
            first,
            &check.contradicted_by_camera,
            &check.contradicted_by_camera_at_first,
        ));
        added
    }

    /// The per-camera rule ([`Concern::Disagree`]) for report `frame`, which judges the
    /// previous frame's solution: once a camera's run reaches [`DISAGREE_FRAMES`], every
    /// solution the run judged is flagged, and each later one while it lasts.
    fn disagreement(
        &mut self,
        frame: u32,
        first: u32,
        by_camera: &[Option<f64>],
        at_first: &[Option<f64>],
    ) -> Vec<(u32, Concern)> {
        let n = by_camera.len();
        if n == 0 {
            // Nothing checked at this report (a template without patches: the mesh out of
            // view), or a log written before the field existed: the run stands as it was.
            return Vec::new();
        }
        // Per camera, its rise; `None` where it was not measured now or at the first frame
        // (left out, blank, out of view): it neither counts nor breaks its run.
        let rises: Vec<Option<f64>> = (0..n)
            .map(|c| {
                let now = by_camera[c]?;
                Some(now - at_first.get(c).copied().flatten()?)
            })
            .collect();
        let measured = rises.iter().flatten().count();
        if measured < 3 || self.disagree_run.len() != n {
            // Two cameras rise together (each one's pixels are contradicted by the other alone):
            // the rig's share judges them; a rig whose camera count changed starts afresh.
            self.disagree_run = vec![(0, frame); n];
            self.recent_rises = vec![Vec::new(); n];
            self.disagree_since = None;
            if measured < 3 {
                return Vec::new();
            }
        }
        // Every camera up at once is the rig's disagreement with the mesh, not some cameras'
        // with the others: `SUSPECT_RISE` judges that.
        let all_up = rises.iter().flatten().all(|&d| d > DISAGREE_RISE);
        let mut rise: f64 = 0.0;
        for (c, d) in rises.iter().enumerate() {
            let Some(d) = *d else { continue };
            let run = &mut self.disagree_run[c];
            let recent = &mut self.recent_rises[c];
            // The level it came up from: the lowest of its last reports, or the first frame's
            // (a rise of 0) while it has fewer.
            let start = if recent.len() < DISAGREE_SPAN {
                0.0
            } else {
                f64::INFINITY
            };
            let from = recent.iter().copied().fold(start, f64::min);
            let sudden = d - from > DISAGREE_JUMP;
            if d > DISAGREE_RISE && !all_up && (run.0 > 0 || sudden) {
                if run.0 == 0 {
                    run.1 = frame;
                }
                run.0 += 1;
            } else {
                *run = (0, frame);
            }
            recent.push(d);
            if recent.len() > DISAGREE_SPAN {
                recent.remove(0);
            }
            if run.0 >= DISAGREE_FRAMES {
                rise = rise.max(d);
            }
        }
        let cameras = self.disagreeing().len();
        let Some(judged) = frame.checked_sub(1).filter(|&j| j > first) else {
            return Vec::new();
        };
        if cameras == 0 {
            self.disagree_since = None;
            return Vec::new();
        }
        let frames: Vec<u32> = match self.disagree_since {
            Some(_) => vec![judged],
            None => {
                // The run's first report judged the frame before it (never the given mesh).
                let start = self
                    .disagree_run
                    .iter()
                    .filter(|r| r.0 >= DISAGREE_FRAMES)
                    .map(|r| r.1)
                    .min()
                    .unwrap_or(frame);
                let since = start.saturating_sub(1).max(first + 1);
                self.disagree_since = Some(since);
                (since..=judged).collect()
            }
        };
        let since = self.disagree_since.unwrap_or(judged);
        let c = Concern::Disagree {
            cameras,
            rise,
            since,
        };
        // One disagreement per frame (a run that ended and began again flags no frame twice).
        let frames: Vec<u32> = frames
            .into_iter()
            .filter(|&f| !self.flagged_disagreeing(f))
            .collect();
        for &f in &frames {
            self.push(f, c);
        }
        frames.into_iter().map(|f| (f, c)).collect()
    }

    /// Whether `frame` is flagged for [`Concern::Disagree`] already (before a resume too).
    fn flagged_disagreeing(&self, frame: u32) -> bool {
        [&self.list, &self.before_resume].into_iter().any(|list| {
            let at = list.partition_point(|f| f.frame < frame);
            list.get(at).is_some_and(|f| {
                f.frame == frame
                    && f.concerns
                        .iter()
                        .any(|c| matches!(c, Concern::Disagree { .. }))
            })
        })
    }

    /// The cameras whose own contradicted share has risen past [`DISAGREE_RISE`] for
    /// [`DISAGREE_FRAMES`] reports running, as of the last report added (by index).
    pub fn disagreeing(&self) -> Vec<u16> {
        (0..self.disagree_run.len())
            .filter(|&c| self.disagree_run[c].0 >= DISAGREE_FRAMES)
            .map(|c| c as u16)
            .collect()
    }

    fn push(&mut self, frame: u32, c: Concern) {
        // Reports arrive in frame order, but a concern may flag frames before the last one (the
        // previous frame's verdict, a run of disagreement named once it is long enough).
        let at = self.list.partition_point(|f| f.frame < frame);
        match self.list.get_mut(at) {
            Some(f) if f.frame == frame => f.concerns.push(c),
            _ => self.list.insert(
                at,
                FrameCheck {
                    frame,
                    concerns: vec![c],
                },
            ),
        }
    }

    /// The frames flagged, in order.
    pub fn frames(&self) -> &[FrameCheck] {
        &self.list
    }

    pub fn into_frames(self) -> Vec<FrameCheck> {
        self.list
    }

    /// The checks of a run resumed after frame `last`: its reports up to `last` (log lines, any
    /// order, the last line of a frame taken) replayed, so that the rules that span frames (a
    /// camera's run of disagreement) go on across the resume; the frames they flagged are left
    /// out ([`Checks::frames`] lists only what later reports add, as a resumed call's summary
    /// and warnings are about its own frames; a run of disagreement already named flags only
    /// its later frames, and one named after the resume flags no frame flagged before it).
    pub fn resumed<'a>(
        first: u32,
        last: u32,
        reports: impl IntoIterator<Item = (u32, &'a FrameReport)>,
    ) -> Checks {
        let by_frame: std::collections::BTreeMap<u32, &FrameReport> = reports
            .into_iter()
            .filter(|(f, _)| (first..=last).contains(f))
            .collect();
        let mut checks = Checks::default();
        for (f, r) in by_frame {
            checks.add(f, first, r);
        }
        checks.before_resume = std::mem::take(&mut checks.list);
        checks
    }
}

/// The frames to check of a run, from its reports in frame order (`log.jsonl`'s lines); `first`
/// is the scene's first frame (the given mesh, never flagged). The last frame's verdict is not
/// in the reports: add it with [`Checks::judge_last`] (the manifest's `last_frame_check`).
pub fn check_reports<'a>(
    first: u32,
    reports: impl IntoIterator<Item = (u32, &'a FrameReport)>,
) -> Vec<FrameCheck> {
    let mut checks = Checks::default();
    for (f, r) in reports {
        checks.add(f, first, r);
    }
    checks.into_frames()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(contradicted: f64, information: f64, stalled: bool) -> FrameReport {
        let line = serde_json::json!({
            "iterations": 3, "cost_before": 1.0, "cost_after": 0.5,
            "pixels": if stalled { 0 } else { 100 }, "contradicted_share": contradicted,
            "contradicted_at_first": 0.05, "information_share": information,
            "stop": "converged", "predicted": false, "stalled": stalled, "levels": [],
            "timing": {"pyramids": 0.0, "patches": 0.0, "solve": 0.0}
        });
        serde_json::from_value(line).expect("a report")
    }

    #[test]
    fn a_slip_flags_the_frame_it_happened_in_and_the_frames_after_it() {
        // Frame 3's templates (frame 2's solution) are contradicted; frame 4 then sees no texture;
        // frame 5 stalls out of view. Frame 1 and frame 6 are fine; frame 0 is the given mesh.
        let ok = report(0.06, 0.8, false);
        let reps = [
            (1, ok.clone()),
            (2, ok.clone()),
            (3, report(0.30, 0.5, false)),
            (4, report(0.28, 0.02, false)),
            (5, report(0.05, 0.0, true)),
            (6, ok),
        ];
        let checks = check_reports(0, reps.iter().map(|(f, r)| (*f, r)));
        let frames: Vec<u32> = checks.iter().map(|c| c.frame).collect();
        assert_eq!(frames, [2, 3, 4, 5]);
        assert_eq!(
            checks[0].concerns,
            [Concern::Contradicted {
                share: 0.30,
                at_first: 0.05
            }]
        );
        // Frame 3 started from frame 2's contradicted solution, and frame 4's templates show
        // the cameras contradicting frame 3's.
        assert_eq!(
            checks[1].concerns,
            [
                Concern::StartedContradicted {
                    share: 0.30,
                    at_first: 0.05
                },
                Concern::Contradicted {
                    share: 0.28,
                    at_first: 0.05
                }
            ]
        );
        assert!(checks[2].suspect() && !checks[2].stalled());
        assert!(checks[2]
            .concerns
            .contains(&Concern::LittleTexture { share: 0.02 }));
        assert!(checks[3].stalled() && checks[3].suspect());
        assert!(checks[3].concerns[0] == Concern::Stalled { no_pixels: true });
        // Each concern reads as a sentence with its figures.
        assert!(checks[0].concerns[0].describe().starts_with(
            "the other cameras contradict 30 % of where this frame left the surface, against 5 %"
        ));
    }

    #[test]
    fn a_leap_past_half_the_mesh_size_in_one_frame_is_suspect_and_a_fast_move_is_not() {
        let mut leapt = report(0.05, 1.0, false);
        leapt.jump = 0.81;
        let checks = check_reports(0, [(1, &report(0.05, 1.0, false)), (2, &leapt)]);
        assert_eq!(checks.len(), 1, "{checks:?}");
        assert_eq!(checks[0].frame, 2);
        assert_eq!(checks[0].concerns, [Concern::Jumped { share: 0.81 }]);
        assert!(checks[0].suspect());
        assert!(checks[0].concerns[0]
            .describe()
            .contains("leapt 81 % of its size"));
        // The capture range's fastest tracked shake changes velocity by about a tenth.
        let mut fast = report(0.05, 1.0, false);
        fast.jump = 0.1;
        assert!(check_reports(0, [(1, &fast)]).is_empty());
        // Logs written before the field existed read as no leap.
        assert_eq!(report(0.05, 1.0, false).jump, 0.0);
    }

    #[test]
    fn a_camera_that_saw_nothing_change_while_another_saw_the_mesh_move_repeats_its_frame() {
        // The same frame written twice changes by 0; a still real camera's sensor noise by
        // about 1e-3; a moving surface by far more.
        assert_eq!(repeated_of(&[Some(0.0), Some(0.02)]), [true, false]);
        assert_eq!(repeated_of(&[Some(2.4e-4), Some(2.5e-3)]), [true, false]);
        assert_eq!(repeated_of(&[Some(2.5e-4), Some(0.02)]), [false, false]);
        assert_eq!(repeated_of(&[Some(0.0), Some(2.4e-3)]), [false, false]);
        // Nothing moved anywhere (a surface at rest, a static render): no repeat.
        assert_eq!(repeated_of(&[Some(0.0), Some(0.0), Some(1e-4)]), [false; 3]);
        // Not measured (blank, mesh out of view) is neither a repeat nor a witness of motion.
        assert_eq!(repeated_of(&[Some(0.0), None]), [false, false]);
        assert_eq!(
            repeated_of(&[None, Some(0.0), Some(0.05)]),
            [false, true, false]
        );
        // A rig of one has nothing to tell a still surface from a repeat by.
        assert_eq!(repeated_of(&[Some(0.0)]), [false]);
        // Each camera's verdict needs motion seen by another: two frozen of four are both named.
        assert_eq!(
            repeated_of(&[Some(0.0), Some(1e-5), Some(0.03), Some(0.01)]),
            [true, true, false, false]
        );
        // In the frame's report: a suspect frame, named, and the texture test (measured against
        // the first frame with every camera) left to the camera's own concern.
        let mut r = report(0.05, 0.004, false);
        r.repeated_cameras = vec![0];
        let checks = check_reports(0, [(1, &r)]);
        assert_eq!(checks.len(), 1, "{checks:?}");
        assert_eq!(checks[0].concerns, [Concern::Repeated { cameras: 1 }]);
        assert!(checks[0].suspect());
        assert!(checks[0].concerns[0]
            .describe()
            .starts_with("1 camera's image repeats the previous frame's over the mesh"));
        let json = serde_json::to_value(checks[0].concerns[0]).unwrap();
        assert_eq!(json, serde_json::json!({"kind": "repeated", "cameras": 1}));
        // A camera found running late since: left out, named, suspect, its fix given.
        let mut r = report(0.05, 0.004, false);
        r.late_cameras = vec![0];
        let checks = check_reports(0, [(1, &r)]);
        assert_eq!(checks[0].concerns, [Concern::Late { cameras: 1 }]);
        assert!(checks[0].suspect());
        assert!(checks[0].concerns[0]
            .describe()
            .contains("track from here on with its frame_offset raised by 1"));
        // A camera found turned: named with how far, its frames solved turned, suspect.
        let mut r = report(0.05, 0.5, false);
        r.moved_cameras = vec![1];
        r.moved_px = vec![3.25];
        let checks = check_reports(0, [(1, &r)]);
        assert_eq!(
            checks[0].concerns,
            [Concern::Moved {
                cameras: 1,
                px: 3.25
            }]
        );
        assert!(checks[0].suspect());
        assert!(checks[0].concerns[0].describe().starts_with(
            "1 camera has turned since the first frame (its view of the background moved 3.2 px"
        ));
        let json = serde_json::to_value(checks[0].concerns[0]).unwrap();
        assert_eq!(
            json,
            serde_json::json!({"kind": "moved", "cameras": 1, "px": 3.25})
        );
    }

    #[test]
    fn a_view_that_leaps_against_the_others_is_what_a_dropped_frame_looks_like() {
        // The shaken cloth, camera 0 dropping frame 5: its view changes 0.0288 then 0.0495
        // (two frames' motion), camera 1's 0.0286 then 0.0289.
        let g = growth_of(
            &[Some(0.0495), Some(0.0289)],
            &[Some(0.0288), Some(0.0286)],
            &[false, false],
        );
        assert!(g[0].unwrap() >= LEAP_RATIO, "{g:?}");
        assert!(g[1].unwrap() < 1.0, "{g:?}");
        // Both speeding up alike is no leap.
        let alike = growth_of(
            &[Some(0.06), Some(0.058)],
            &[Some(0.03), Some(0.029)],
            &[false, false],
        );
        assert!(
            alike.iter().all(|g| (g.unwrap() - 1.0).abs() < 0.05),
            "{alike:?}"
        );
        // Not measured: a camera left out, a still view, or no other camera to compare with.
        let none = growth_of(
            &[Some(0.06), Some(0.001), Some(0.05)],
            &[Some(0.03), Some(0.001), Some(0.03)],
            &[false, false, true],
        );
        assert_eq!(none, [None, None, None]);
    }

    #[test]
    fn a_camera_found_early_flags_the_frame_before_and_the_frame_it_is_found_in() {
        let ok = report(0.06, 0.8, false);
        let mut found = ok.clone();
        found.early_cameras = vec![1];
        found.ahead_cameras = vec![1];
        let mut after = ok.clone();
        after.early_cameras = vec![1];
        let reps = [(1, ok.clone()), (2, ok), (3, found), (4, after)];
        let checks = check_reports(0, reps.iter().map(|(f, r)| (*f, r)));
        let frames: Vec<u32> = checks.iter().map(|c| c.frame).collect();
        // Taken a frame back from frame 3 on, frame 4 is as good as any.
        assert_eq!(frames, [2, 3]);
        assert_eq!(checks[0].concerns, [Concern::Ahead { cameras: 1 }]);
        assert_eq!(checks[1].concerns, [Concern::Early { cameras: 1 }]);
        assert!(checks.iter().all(FrameCheck::suspect));
        assert!(checks[1].concerns[0]
            .describe()
            .contains("taken from its file for the frame before"));
        let json = serde_json::to_value(checks[0].concerns[0]).unwrap();
        assert_eq!(json, serde_json::json!({"kind": "ahead", "cameras": 1}));
    }

    /// A report whose cameras' own contradicted shares are `at_first` plus `rise`, per camera.
    fn by_camera(rise: &[f64]) -> FrameReport {
        let mut r = report(0.05, 0.8, false);
        r.contradicted_by_camera_at_first = vec![Some(0.03); rise.len()];
        r.contradicted_by_camera = rise.iter().map(|d| Some(0.03 + d)).collect();
        r
    }

    #[test]
    fn a_run_resumed_in_the_middle_of_a_disagreement_names_it_as_the_uninterrupted_run_does() {
        // The knocked blob's reports (cameras 0 and 1 up from report 4), the run interrupted
        // after frame 6 and resumed: the resumed call's checks go on from reports 1..=6 and
        // name the disagreement at report 8, as the whole run does, listing only what reports
        // 7.. add (frames 3..=7 at once, then 8). Started afresh instead, the resumed call
        // would see a run of 3 reports and name nothing.
        let knocked = [0.121, 0.103, -0.008, -0.004];
        let mut reps = vec![(1, by_camera(&[0.0; 4])), (2, by_camera(&[0.0; 4]))];
        reps.push((3, by_camera(&[0.01, 0.0, 0.0, 0.0])));
        for f in 4..=9 {
            reps.push((f, by_camera(&knocked)));
        }
        let mut whole = Checks::default();
        for (f, r) in &reps {
            whole.add(*f, 0, r);
        }
        // The log may hold a frame twice (an interrupted append, a resume): the last counts.
        let log: Vec<(u32, &FrameReport)> = std::iter::once((5, &reps[0].1))
            .chain(reps.iter().map(|(f, r)| (*f, r)))
            .collect();
        let mut resumed = Checks::resumed(0, 6, log.iter().copied());
        assert!(resumed.frames().is_empty());
        for (f, r) in reps.iter().filter(|(f, _)| *f > 6) {
            resumed.add(*f, 0, r);
        }
        assert_eq!(resumed.frames(), whole.frames());
        assert_eq!(resumed.disagreeing(), [0, 1]);
        let mut afresh = Checks::default();
        for (f, r) in reps.iter().filter(|(f, _)| *f > 6) {
            afresh.add(*f, 0, r);
        }
        assert!(afresh.frames().is_empty() && afresh.disagreeing().is_empty());

        // Camera 0 up at reports 4..=9 (frames 3..=8 flagged), camera 1 from report 8 on, named
        // at report 12 with its run reaching back to frame 7: frames 7 and 8 were flagged
        // already, so it adds 9..=11, and report 13 frame 12, resumed after frame 10 as whole.
        let up = |a: bool, b: bool| {
            by_camera(&[
                if a { 0.14 } else { 0.0 },
                if b { 0.14 } else { 0.0 },
                0.0,
                0.0,
            ])
        };
        let reps: Vec<(u32, FrameReport)> = (1..=13)
            .map(|f| (f, up((4..=9).contains(&f), f >= 8)))
            .collect();
        let mut whole = Checks::default();
        for (f, r) in &reps {
            whole.add(*f, 0, r);
        }
        let flagged = |c: &Checks| -> Vec<u32> { c.frames().iter().map(|c| c.frame).collect() };
        assert_eq!(flagged(&whole), (3..=12).collect::<Vec<u32>>());
        assert!(whole.frames().iter().all(|c| c.concerns.len() == 1));
        let mut resumed = Checks::resumed(0, 10, reps.iter().map(|(f, r)| (*f, r)));
        for (f, r) in reps.iter().filter(|(f, _)| *f > 10) {
            resumed.add(*f, 0, r);
        }
        assert_eq!(flagged(&resumed), [9, 10, 11, 12]);
        assert!(resumed.frames().iter().all(|c| c.concerns.len() == 1));
    }

    #[test]
    fn two_cameras_that_disagree_frame_after_frame_are_named_and_every_frame_they_judged_flagged() {
        // The knocked blob at 320×240 (camera 1 turned 0.5° from frame 3): from report 4 on,
        // cameras 0 and 1 rise 0.09–0.14 while the rig's share stays under SUSPECT_RISE.
        let knocked = [0.121, 0.103, -0.008, -0.004];
        let mut reps = vec![(1, by_camera(&[0.0; 4])), (2, by_camera(&[0.0; 4]))];
        reps.push((3, by_camera(&[0.01, 0.0, 0.0, 0.0])));
        for f in 4..=9 {
            reps.push((f, by_camera(&knocked)));
        }
        let mut checks = Checks::default();
        let mut added = Vec::new();
        for (f, r) in &reps {
            added.push((*f, checks.add(*f, 0, r)));
            if *f < 8 {
                assert!(checks.disagreeing().is_empty(), "report {f}");
            }
        }
        // Named at report 8, the fifth running: frames 3..=7, whose solutions reports 4..=8
        // judged, all at once; then frame 8 by report 9.
        let disagree = Concern::Disagree {
            cameras: 2,
            rise: 0.121,
            since: 3,
        };
        for (f, a) in &added[..7] {
            assert!(a.is_empty(), "report {f}: {a:?}");
        }
        let at8: Vec<u32> = added[7].1.iter().map(|(f, _)| *f).collect();
        assert_eq!(at8, [3, 4, 5, 6, 7]);
        assert!(added[7].1.iter().all(|(_, c)| *c == disagree));
        assert_eq!(added[8].1, [(8, disagree)]);
        assert_eq!(checks.disagreeing(), [0, 1]);
        let frames: Vec<u32> = checks.frames().iter().map(|c| c.frame).collect();
        assert_eq!(frames, [3, 4, 5, 6, 7, 8]);
        assert!(checks.frames().iter().all(FrameCheck::suspect));
        assert!(disagree.describe().starts_with(
            "2 cameras' views have disagreed with the other cameras' about where the surface is at every frame since frame 3 (the share of their own pixels the others contradict rose up to 12 points"
        ));
        assert_eq!(
            serde_json::to_value(disagree).unwrap(),
            serde_json::json!({"kind": "disagree", "cameras": 2, "rise": 0.121, "since": 3})
        );
        // Back within the footage's level: the run ends, and a new one starts from nothing.
        let mut after = checks.clone();
        after.add(10, 0, &by_camera(&[0.0; 4]));
        assert!(after.disagreeing().is_empty());
        assert_eq!(after.frames().len(), 6);
    }

    #[test]
    fn a_camera_that_disagrees_for_a_few_frames_or_by_the_footages_own_level_is_not_named() {
        // The real board: one camera rises by up to 0.16 for a frame (a hand, glare) and sits
        // about the threshold around it, then falls back; the hard sample's first cameras sit
        // up to 0.06 above their start for a while.
        let board = [
            [0.006, 0.078, 0.009],
            [0.006, 0.071, 0.077],
            [0.005, 0.076, 0.034],
            [0.026, 0.147, 0.044],
            [0.063, 0.047, 0.040],
            [0.006, 0.019, 0.031],
            [0.012, 0.064, -0.053],
            [0.012, 0.052, -0.021],
            [0.006, 0.158, -0.039],
            [0.005, 0.043, -0.017],
        ];
        let mut reps = Vec::new();
        for (i, d) in board.iter().enumerate() {
            reps.push((i as u32 + 1, by_camera(&[d[0], d[1], 0.005, d[2]])));
        }
        for f in 12..40 {
            reps.push((f, by_camera(&[0.060, 0.031, 0.010])));
        }
        assert!(check_reports(0, reps.iter().map(|(f, r)| (*f, r))).is_empty());
        // At the threshold itself a camera agrees; and one camera, or a log written before
        // the field existed, has nothing to compare.
        let at = by_camera(&[DISAGREE_RISE, 0.0, 0.0]);
        let one = by_camera(&[0.5]);
        let old = report(0.05, 0.8, false);
        // Two cameras rise together whatever happens (the rig's share judges them), and every
        // camera up at once is the rig's disagreement with the mesh, not some cameras'.
        let two = by_camera(&[0.15, 0.15]);
        let all = by_camera(&[0.15, 0.14, 0.16]);
        for r in [&at, &one, &old, &two, &all] {
            let reps: Vec<(u32, &FrameReport)> = (1..20).map(|f| (f, r)).collect();
            assert!(check_reports(0, reps).is_empty());
        }
    }

    #[test]
    fn a_disagreement_that_builds_up_slowly_is_the_footages_and_a_sudden_one_on_top_is_named() {
        // Mitsuba's glossy irregular mesh (docs/tracker.md, "Footage from another renderer"):
        // camera 2's own share rises by a few thousandths a report as the sun's highlight moves
        // into its view, past DISAGREE_RISE from report 23 on; the others stay near their start.
        let drift = [
            0.000, 0.004, 0.009, -0.005, -0.003, 0.000, 0.006, 0.022, 0.026, 0.027, 0.032, 0.034,
            0.042, 0.048, 0.053, 0.050, 0.056, 0.057, 0.059, 0.064, 0.066, 0.071, 0.079, 0.077,
            0.077, 0.080, 0.081, 0.089, 0.091,
        ];
        let glossy =
            |f: usize, knock: f64| by_camera(&[-0.003, 0.010, drift[f - 1] + knock, 0.002]);
        let reps: Vec<(u32, FrameReport)> = (1..=29).map(|f| (f as u32, glossy(f, 0.0))).collect();
        assert!(check_reports(0, reps.iter().map(|(f, r)| (*f, r))).is_empty());
        // The same camera knocked at frame 20: its share up by 0.05 at once on top of the
        // drift, and its neighbour's by 0.09: both named, from the knock.
        let reps: Vec<(u32, FrameReport)> = (1..=29)
            .map(|f| {
                let mut r = glossy(f, if f >= 21 { 0.05 } else { 0.0 });
                if f >= 21 {
                    r.contradicted_by_camera[1] = r.contradicted_by_camera[1].map(|v| v + 0.09);
                }
                (f as u32, r)
            })
            .collect();
        let checks = check_reports(0, reps.iter().map(|(f, r)| (*f, r)));
        assert_eq!(checks.first().map(|c| c.frame), Some(20), "{checks:?}");
        assert!(checks.iter().all(|c| matches!(
            c.concerns[..],
            [Concern::Disagree {
                cameras: 2,
                since: 20,
                ..
            }]
        )));
    }

    #[test]
    fn cameras_not_measured_neither_count_nor_break_a_run_and_a_frame_with_nothing_checked_keeps_it(
    ) {
        let knocked = || by_camera(&[0.14, 0.15, 0.0, 0.0]);
        // Camera 3 left out at report 4 (blank: it took no pixels), report 5 checked nothing
        // (empty), report 6 from a log written before the field existed: the run of cameras
        // 0 and 1 from report 2 goes on, and report 8 is its fifth.
        let mut out3 = knocked();
        out3.contradicted_by_camera[3] = None;
        let nothing = {
            let mut r = knocked();
            r.contradicted_by_camera.clear();
            r.contradicted_by_camera_at_first.clear();
            r
        };
        let reps = [
            (1, by_camera(&[0.0; 4])),
            (2, knocked()),
            (3, knocked()),
            (4, out3),
            (5, nothing.clone()),
            (6, nothing),
            (7, knocked()),
            (8, knocked()),
        ];
        let checks = check_reports(0, reps.iter().map(|(f, r)| (*f, r)));
        let frames: Vec<u32> = checks.iter().map(|c| c.frame).collect();
        assert_eq!(frames, [1, 2, 3, 4, 5, 6, 7]);
        assert!(checks.iter().all(|c| c.concerns
            == [Concern::Disagree {
                cameras: 2,
                rise: 0.15,
                since: 1
            }]));
        // A three-camera rig with one camera left out is two cameras: never named.
        let mut two = by_camera(&[0.14, 0.15, 0.0]);
        two.contradicted_by_camera[2] = None;
        let reps: Vec<(u32, &FrameReport)> = (1..12).map(|f| (f, &two)).collect();
        assert!(check_reports(0, reps).is_empty());
        // A run that ends and begins again is named again from its own first frame, and no
        // frame is flagged twice; a change of camera count starts afresh.
        let mut reps: Vec<(u32, FrameReport)> = Vec::new();
        for f in 1..=6 {
            reps.push((f, knocked()));
        }
        reps.push((7, by_camera(&[0.0; 4])));
        for f in 8..=12 {
            reps.push((f, knocked()));
        }
        for f in 13..=16 {
            reps.push((f, by_camera(&[0.14, 0.15, 0.0, 0.0, 0.0])));
        }
        let checks = check_reports(0, reps.iter().map(|(f, r)| (*f, r)));
        let since: Vec<(u32, u32)> = checks
            .iter()
            .flat_map(|c| {
                c.concerns.iter().map(move |k| match k {
                    Concern::Disagree { since, .. } => (c.frame, *since),
                    _ => panic!("{k:?}"),
                })
            })
            .collect();
        let want: Vec<(u32, u32)> = (1..=5)
            .map(|f| (f, 1))
            .chain((7..=11).map(|f| (f, 7)))
            .collect();
        assert_eq!(since, want);
    }

    #[test]
    fn a_folded_mesh_is_a_frame_to_check_and_says_where_it_folded() {
        let mut folded = report(0.06, 0.8, false);
        folded.folded = 3;
        let checks = check_reports(0, [(1, &report(0.06, 0.8, false)), (2, &folded)]);
        assert_eq!(checks.len(), 1);
        assert_eq!(checks[0].frame, 2);
        assert_eq!(checks[0].concerns, [Concern::Folded { edges: 3 }]);
        assert!(checks[0].suspect() && !checks[0].stalled());
        assert!(checks[0].concerns[0]
            .describe()
            .starts_with("the mesh has folded over itself: 3 pairs of neighbouring triangles"));
        // A log written before the field existed reads as not folded.
        assert_eq!(report(0.06, 0.8, false).folded, 0);
    }

    #[test]
    fn the_first_frame_is_never_flagged_and_a_rise_at_the_threshold_is_not_a_slip() {
        // A rise of exactly SUSPECT_RISE is the footage's own level; the given mesh is not judged.
        let at = report(0.05 + SUSPECT_RISE, 0.5, false);
        assert!(!contradicts_previous(&at));
        let above = report(0.05 + SUSPECT_RISE + 1e-6, 0.5, false);
        let checks = check_reports(10, [(11, &above)]);
        assert_eq!(checks.len(), 1);
        assert_eq!(checks[0].frame, 11);
        // At the information floor itself a frame is not suspect.
        assert!(check_reports(10, [(11, &report(0.05, INFORMATION_FLOOR, false))]).is_empty());
    }
}

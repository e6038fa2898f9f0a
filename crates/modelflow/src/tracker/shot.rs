//! A whole shot: drives the [`Tracker`] over a scene on disk and writes a run folder (`run`): one
//! mesh per frame, one log line per solved frame, the manifest. The next frame's images are read,
//! and their pyramids built, while the current frame is solved. A run can be resumed from its
//! last complete frame, with results identical to an uninterrupted run, and stopped cleanly
//! between solver iterations by a cancel flag.

use crate::error::{Error, Result};
use crate::input::scene::Scene;
use crate::run::{write_run, FrameDetail, FrameLog, LastFrameCheck, Method, RunFolder, RunOptions};
use crate::tracker::health::{Checks, FrameCheck};
use crate::tracker::offset::SurfaceMove;
use crate::tracker::options::TrackOptions;
use crate::tracker::sequence::{prepare, Tracker};
use crate::tracker::shift::CameraShifts;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Summary of a tracked shot.
#[derive(Clone, Debug, Serialize)]
pub struct TrackSummary {
    /// Frames in the run folder, the first (the input mesh) included.
    pub frames: usize,
    /// Frames solved by this call (fewer than `frames - 1` when it resumed a run).
    pub solved: usize,
    /// The last complete frame the run was resumed from, if it was.
    pub resumed_from: Option<u32>,
    pub total_seconds: f64,
    /// Median wall time per frame solved by this call, image loading included.
    pub median_frame_seconds: f64,
    pub median_iterations: f64,
    /// Frames solved by this call in which the solver could not lower the cost at all (see
    /// `FrameReport::stalled`), in order.
    pub stalled_frames: Vec<u32>,
    /// Frames that may be wrong, in order: the cameras contradicted where the frame left the
    /// surface (found with the next frame), the frame started from such a solution, or the mesh
    /// saw next to none of the surface's texture (`health`). With a resumed run, the frame it
    /// was resumed from may be among them, and frames before it when a camera's run of
    /// disagreement that began before the resume is named after it (`Checks::resumed`).
    pub suspect_frames: Vec<u32>,
    /// Every frame to check and why (`health`; `run::frames_to_check` reads them back from the folder), stalled and suspect ones alike.
    pub checks: Vec<FrameCheck>,
    /// When the scene's mesh lay off the surface the cameras agree on and was moved onto it
    /// before tracking (`TrackOptions::onto_surface`); the run's first mesh is the moved one.
    pub first_mesh_moved: Option<SurfaceMove>,
    /// The shifts of the cameras' images at which they agreed best about the first mesh
    /// (`TrackOptions::shift_cameras`; as `run.json`'s `camera_shifts`).
    pub camera_shifts: Option<CameraShifts>,
    /// The cross-camera check on the last frame solved, taken once the shot was done (as
    /// `run.json`'s `last_frame_check`); `None` when this call solved no frame.
    pub last_frame_check: Option<LastFrameCheck>,
}

/// Tracks a whole scene into the run folder `out_dir` (see `run` for the layout and the rules
/// that protect existing files), calling `on_frame` after each solved frame.
pub fn track_scene(
    scene: &Scene,
    opts: &TrackOptions,
    out_dir: &Path,
    run: &RunOptions,
    on_frame: &mut dyn FnMut(&FrameLog),
) -> Result<TrackSummary> {
    let t_start = Instant::now();
    opts.validate()?;
    let opts = &opts.resolved_for(scene.cameras.iter().map(|c| (c.width, c.height)));
    let mut summary = write_run(
        out_dir,
        Method::ModelFlow,
        scene,
        &opts.used(),
        run,
        |folder, resumed| track_into(folder, resumed, scene, opts, run, on_frame),
    )?;
    summary.total_seconds = t_start.elapsed().as_secs_f64();
    Ok(summary)
}

fn track_into(
    folder: &mut RunFolder,
    resumed: Option<u32>,
    scene: &Scene,
    opts: &TrackOptions,
    run: &RunOptions,
    on_frame: &mut dyn FnMut(&FrameLog),
) -> Result<TrackSummary> {
    let first_images = scene.load_images(scene.first)?;
    let mut tracker = Tracker::new_checked(
        &scene.mesh,
        scene.cameras.clone(),
        scene.first,
        &first_images,
        *opts,
        run.first_mesh_check.as_ref(),
    )?;
    drop(first_images);
    if let Some(c) = &run.cancel {
        tracker.set_cancel(c.clone());
    }
    tracker.set_gpu(run.gpu.clone());
    let first_mesh_moved = tracker.first_mesh_moved().copied();
    let camera_shifts = tracker.camera_shifts().cloned();
    let mut checks = Checks::default();
    let start = match resumed {
        None => {
            folder.write_first(&scene.mesh.with_positions(tracker.positions().to_vec()))?;
            if let Some(m) = first_mesh_moved {
                folder.record_first_mesh_moved(m)?;
            }
            if let Some(s) = &camera_shifts {
                folder.record_camera_shifts(s.clone())?;
            }
            scene.first
        }
        Some(last) if last == scene.first => last,
        Some(last) => {
            // The state right after `last` was solved: its images, its positions and those of
            // the frame before (the velocity), read back exactly from the meshes written.
            // The cameras left out of it as repeats of the frame before stay left out, and the
            // colour balance it left goes on.
            let lines = crate::run::read_frame_log(folder.dir())?;
            // The rules that span frames go on from the reports before.
            checks = Checks::resumed(
                scene.first,
                last,
                lines
                    .iter()
                    .filter_map(|l| l.model_flow().map(|r| (l.frame, r))),
            );
            let report = lines
                .into_iter()
                .find(|l| l.frame == last)
                .and_then(|l| l.model_flow().cloned());
            // Left out of it: the cameras that repeated the frame before, and those found late.
            let repeated: Vec<u16> = report
                .as_ref()
                .map(|r| [&r.repeated_cameras[..], &r.late_cameras[..]].concat())
                .unwrap_or_default();
            if let Some(r) = &report {
                tracker.restore_colour_balance(&r.colour_balance, &r.colour_readings);
                // A camera found late stays left out; one that repeated this frame is watched.
                tracker.restore_sync(&r.late_cameras, &r.repeated_cameras);
                // A camera found turned stays turned.
                tracker.restore_turns(last, &r.camera_turns, &r.moved_cameras, &r.moved_px);
            }
            let latest = prepare(&scene.load_images(last)?, opts);
            let early = report
                .as_ref()
                .map(|r| r.early_cameras.clone())
                .unwrap_or_default();
            if let Some(r) = &report {
                // A camera found early goes on a frame back; one whose view leapt is checked
                // at the next frame. Both keep their image of this frame for the next.
                tracker.restore_early(
                    last,
                    &r.early_cameras,
                    &r.leapt_cameras,
                    &r.view_changes,
                    r.stalled,
                    &latest,
                );
            }
            // A camera found early showed this frame in its file for the frame before.
            let latest = if early.is_empty() {
                latest
            } else {
                let before = prepare(&scene.load_images(last - 1)?, opts);
                latest.with_cameras_from(&early, &before)
            };
            let prepared = latest.with_repeated(&repeated);
            let positions = folder.read_positions(last)?;
            let before = folder.read_positions(last - 1)?;
            // Cameras that record late or early took their anchor where the surface had moved
            // by the frame after the first; under an open shutter the anchor is smeared along
            // the first frame's motion (`smear`).
            let first_next = if scene
                .cameras
                .iter()
                .any(|c| c.records_late_or_early() || opts.shutter_of(c) > 0.0)
            {
                Some(folder.read_positions(scene.first + 1)?)
            } else {
                None
            };
            // The bending term's yield depends on the last frame's information.
            let confidence = folder.read_confidence(last)?;
            tracker.restore(
                last,
                prepared,
                positions,
                Some(before),
                first_next,
                confidence.as_deref(),
            )?;
            last
        }
    };
    let mut walls = Vec::new();
    let mut iters = Vec::new();
    let mut last_solved = None;
    // Reads a frame's images and builds their pyramids; runs while the previous frame is solved.
    let load = |frame: u32| {
        let t = Instant::now();
        scene.load_images(frame).map(|imgs| {
            let load_seconds = t.elapsed().as_secs_f64();
            (prepare(&imgs, opts), load_seconds)
        })
    };
    let mut pending = (start < scene.last).then(|| load(start + 1));
    let mut t_frame = Instant::now();
    for frame in start + 1..=scene.last {
        if run.cancelled() {
            return Err(Error::Interrupted {
                last_complete: frame - 1,
            });
        }
        let Some(loaded) = pending.take() else {
            break;
        };
        let (prepared, load_seconds) = loaded.map_err(|e| Error::AtFrame {
            frame,
            error: Box::new(e),
        })?;
        let has_next = frame < scene.last;
        let (stepped, next) = rayon::join(
            || {
                let t = Instant::now();
                let pyramids = prepared.seconds();
                tracker
                    .step_prepared(frame, prepared)
                    .map(|r| (r, pyramids + t.elapsed().as_secs_f64()))
            },
            || has_next.then(|| load(frame + 1)),
        );
        let (report, seconds) = stepped?;
        iters.push(report.iterations as f64);
        checks.add(frame, scene.first, &report);
        last_solved = Some(frame);
        if !report.confidence.is_empty() {
            folder.write_confidence(frame, &report.confidence)?;
        }
        folder.write_mesh(
            frame,
            &scene.mesh.with_positions(tracker.positions().to_vec()),
        )?;
        let wall_seconds = t_frame.elapsed().as_secs_f64();
        let line = FrameLog {
            frame,
            seconds,
            load_seconds,
            wall_seconds,
            detail: FrameDetail::ModelFlow(report),
        };
        folder.append(&line)?;
        t_frame = Instant::now();
        walls.push(wall_seconds);
        on_frame(&line);
        pending = next;
    }
    // The last frame has no next frame whose templates judge it: the same check, taken now.
    let mut last_frame_check = None;
    if let Some(last) = last_solved {
        let check = tracker.contradicted_now(last);
        checks.judge_last(scene.first, &check);
        folder.record_last_frame_check(check.clone());
        last_frame_check = Some(check);
    }
    let checks = checks.into_frames();
    let pick = |f: fn(&FrameCheck) -> bool| -> Vec<u32> {
        checks.iter().filter(|c| f(c)).map(|c| c.frame).collect()
    };
    Ok(TrackSummary {
        frames: (scene.last - scene.first + 1) as usize,
        solved: walls.len(),
        resumed_from: resumed,
        total_seconds: 0.0,
        median_frame_seconds: median(&walls),
        median_iterations: median(&iters),
        stalled_frames: pick(FrameCheck::stalled),
        suspect_frames: pick(FrameCheck::suspect),
        checks,
        first_mesh_moved,
        camera_shifts,
        last_frame_check,
    })
}

/// Median of a list (0 if empty).
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

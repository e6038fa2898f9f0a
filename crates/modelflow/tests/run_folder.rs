//! The run folder as a user relies on it: an interrupted run resumes to exactly the files of an
//! uninterrupted one (also after a crash left a torn log line, a mesh without its line and a
//! temporary file), a folder holding anything but a run of the same scene is refused and left as
//! it was, `Force` replaces only run files, and the manifest records what made the run.

use modelflow::input::Scene;
use modelflow::run::{read_frame_log, FrameDetail, FrameLog, Manifest, Status};
use modelflow::synth::{write_dataset, SynthOptions};
use modelflow::tracker::{track_scene, Regularisation, TrackOptions, Tracker};
use modelflow::{Error, Mesh, OpenMode, RunOptions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

/// A small synthetic cloth (160×120, 2 cameras, 8 frames) and its uninterrupted run, made once.
/// The second camera records each frame a fifth of a frame late (its `time_offset`), so that
/// resuming also restores what the tracker keeps for it (the anchor taken where it saw the
/// surface move).
fn shot() -> &'static (tempfile::TempDir, PathBuf, PathBuf) {
    static SHOT: OnceLock<(tempfile::TempDir, PathBuf, PathBuf)> = OnceLock::new();
    SHOT.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let opts = SynthOptions {
            width: 160,
            height: 120,
            frames: 8,
            sync_error: 0.2,
            ..SynthOptions::default()
        };
        let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
        let reference = dir.path().join("reference");
        track(&scene, &reference, &RunOptions::default()).unwrap();
        (dir, scene, reference)
    })
}

fn track(scene: &Path, out: &Path, run: &RunOptions) -> modelflow::Result<usize> {
    let scene = Scene::load(scene).unwrap();
    track_scene(&scene, &TrackOptions::default(), out, run, &mut |_| {}).map(|s| s.solved)
}

/// Every file of a folder with its bytes.
fn contents(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

/// The frame meshes of a run folder.
fn meshes(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    contents(dir)
        .into_iter()
        .filter(|(n, _)| n.ends_with(".obj"))
        .collect()
}

/// A log line with its measured times zeroed: what must be identical between two runs.
fn without_times(mut l: FrameLog) -> FrameLog {
    l.seconds = 0.0;
    l.load_seconds = 0.0;
    l.wall_seconds = 0.0;
    if let FrameDetail::ModelFlow(r) = &mut l.detail {
        r.timing = Default::default();
        for s in &mut r.levels {
            s.seconds = 0.0;
            s.evaluation_seconds = 0.0;
            s.linear_solver_seconds = 0.0;
            s.iterations.iter_mut().for_each(|i| i.seconds = 0.0);
        }
    }
    l
}

fn logs_without_times(dir: &Path) -> Vec<FrameLog> {
    read_frame_log(dir)
        .unwrap()
        .into_iter()
        .map(without_times)
        .collect()
}

/// Runs into `out` and stops it (as Ctrl-C does) once `frame` is written.
fn interrupted_after(scene: &Path, out: &Path, frame: u32) -> Error {
    let cancel = Arc::new(AtomicBool::new(false));
    let run = RunOptions {
        cancel: Some(cancel.clone()),
        ..RunOptions::default()
    };
    let scene = Scene::load(scene).unwrap();
    track_scene(&scene, &TrackOptions::default(), out, &run, &mut |l| {
        if l.frame == frame {
            cancel.store(true, Ordering::Relaxed);
        }
    })
    .unwrap_err()
}

fn resume() -> RunOptions {
    RunOptions {
        mode: OpenMode::Resume,
        ..RunOptions::default()
    }
}

#[test]
fn an_interrupted_run_resumes_to_the_files_of_an_uninterrupted_one() {
    let (tmp, scene, reference) = shot();
    let out = tmp.path().join("interrupted");
    let err = interrupted_after(scene, &out, 3);
    assert!(
        matches!(err, Error::Interrupted { last_complete: 3 }),
        "{err}"
    );
    let m = Manifest::read(&out.join("run.json")).unwrap();
    assert_eq!(m.status, Status::Interrupted);
    assert_eq!(m.last_complete, Some(3));
    assert_eq!(m.frames_completed, 4);
    assert_eq!(meshes(&out).len(), 4, "frames 0..=3");

    // A rerun without --resume or --force is refused and changes nothing.
    let before = contents(&out);
    let err = track(scene, &out, &RunOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("holds a run of this scene") && err.contains("--resume"),
        "{err}"
    );
    assert_eq!(contents(&out), before);

    assert_eq!(track(scene, &out, &resume()).unwrap(), 4, "frames 4..=7");
    assert_eq!(meshes(&out), meshes(reference), "byte-identical meshes");
    assert_eq!(logs_without_times(&out), logs_without_times(reference));
    let m = Manifest::read(&out.join("run.json")).unwrap();
    assert_eq!(m.status, Status::Complete);
    assert_eq!(m.resumed.len(), 1);
    assert_eq!(m.resumed[0].from_frame, 3);
}

#[test]
fn a_run_stopped_where_a_camera_repeated_or_was_found_late_resumes_to_the_same_files() {
    // Camera 0's frame 4 is its frame 3 again, and it runs a frame late from then on: the
    // tracker leaves it out of frame 4 and of the template frame 5 is compared with, watches
    // it, finds it late at frame 5 and leaves it out from then on. Stopped at either frame, the
    // resumed run must do the same. Camera 0's colours also
    // drift (red up, blue down 5 % a frame), so the resumed run must go on with the colour
    // balance the tracker had read.
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        width: 320,
        height: 240,
        frames: 7,
        shake: 3.0,
        ..SynthOptions::default()
    };
    let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
    let images = scene.parent().unwrap().join("images/cam0");
    for f in 1..7 {
        let path = images.join(format!("{f:04}.png"));
        let mut img = modelflow::input::read_rgb(&path).unwrap();
        let (r, b) = (1.0 + 0.05 * f as f32, 1.0 - 0.05 * f as f32);
        for p in img.pixels_mut() {
            *p = [(p[0] * r).min(1.0), p[1], p[2] * b];
        }
        modelflow::input::write_png(&path, &img).unwrap();
    }
    // Frame 3 written twice, and a frame late from then on.
    for f in (4..7).rev() {
        std::fs::copy(
            images.join(format!("{:04}.png", f - 1)),
            images.join(format!("{f:04}.png")),
        )
        .unwrap();
    }
    let reference = dir.path().join("reference");
    track(&scene, &reference, &RunOptions::default()).unwrap();
    let repeated: Vec<(u32, Vec<u16>)> = read_frame_log(&reference)
        .unwrap()
        .iter()
        .filter_map(|l| match &l.detail {
            FrameDetail::ModelFlow(r) if !r.repeated_cameras.is_empty() => {
                Some((l.frame, r.repeated_cameras.clone()))
            }
            _ => None,
        })
        .collect();
    assert_eq!(repeated, [(4, vec![0])]);
    let log = read_frame_log(&reference).unwrap();
    let balance = &log[3].model_flow().unwrap().colour_balance;
    assert!(balance[0][0] > 1.05, "{balance:?}");
    let late: Vec<u32> = log
        .iter()
        .filter(|l| !l.model_flow().unwrap().late_cameras.is_empty())
        .map(|l| l.frame)
        .collect();
    assert_eq!(late, [5, 6]);
    // Stopped at the repeat (the camera watched) and at the frame it was found late (left out).
    for stop in [4, 5] {
        let out = dir.path().join(format!("interrupted-{stop}"));
        interrupted_after(&scene, &out, stop);
        assert_eq!(track(&scene, &out, &resume()).unwrap(), (6 - stop) as usize);
        assert_eq!(meshes(&out), meshes(&reference), "byte-identical meshes");
        assert_eq!(logs_without_times(&out), logs_without_times(&reference));
    }
}

/// The shaken cloth (two cameras, 480×360, 8 frames) in `dir/footage`, camera 0 losing frame 4:
/// its files 4 to 6 show frames 5 to 7. The scene file's path.
fn cloth_with_camera_0_early_from_4(dir: &Path) -> PathBuf {
    let opts = SynthOptions {
        width: 480,
        height: 360,
        frames: 8,
        shake: 3.0,
        ..SynthOptions::default()
    };
    let scene = write_dataset(&opts, &dir.join("footage"), &|_, _| {}).unwrap();
    let images = scene.parent().unwrap().join("images/cam0");
    for f in 4..7 {
        std::fs::copy(
            images.join(format!("{:04}.png", f + 1)),
            images.join(format!("{f:04}.png")),
        )
        .unwrap();
    }
    scene
}

#[test]
fn a_run_stopped_where_a_camera_dropped_a_frame_or_was_found_early_resumes_to_the_same_files() {
    // Camera 0 loses frame 4 without filling it in (its files 4 to 6 show frames 5 to 7): its
    // view leaps at frame 4, and frame 5 finds it a frame early and leaves it out from then on.
    // Stopped at either frame, the resumed run must do the same.
    let dir = tempfile::tempdir().unwrap();
    let scene = cloth_with_camera_0_early_from_4(dir.path());
    // Frames 0 to 6 only (camera 0 has no frame 7 to show).
    let text = std::fs::read_to_string(&scene).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["frames"]["last"] = serde_json::json!(6);
    std::fs::write(&scene, serde_json::to_string_pretty(&json).unwrap()).unwrap();
    let reference = dir.path().join("reference");
    track(&scene, &reference, &RunOptions::default()).unwrap();
    let log = read_frame_log(&reference).unwrap();
    let listed = |pick: fn(&modelflow::tracker::FrameReport) -> &Vec<u16>| -> Vec<u32> {
        log.iter()
            .filter(|l| !pick(l.model_flow().unwrap()).is_empty())
            .map(|l| l.frame)
            .collect()
    };
    assert_eq!(listed(|r| &r.leapt_cameras), [4]);
    assert_eq!(listed(|r| &r.ahead_cameras), [5]);
    assert_eq!(listed(|r| &r.early_cameras), [5, 6]);
    // Stopped where its view leapt (watched) and where it was found early (left out).
    for stop in [4, 5] {
        let out = dir.path().join(format!("interrupted-{stop}"));
        interrupted_after(&scene, &out, stop);
        assert_eq!(track(&scene, &out, &resume()).unwrap(), (6 - stop) as usize);
        assert_eq!(meshes(&out), meshes(&reference), "byte-identical meshes");
        assert_eq!(logs_without_times(&out), logs_without_times(&reference));
    }
}

#[test]
fn a_cancelled_step_after_a_camera_was_taken_a_frame_back_steps_again_as_if_never_cancelled() {
    // Camera 0 loses frame 4 (its files 4 to 6 show frames 5 to 7); frame 5 finds it early and
    // takes its files a frame back from there. A step cancelled at frame 6 (after its image
    // was taken back, before the solve ends) must leave the tracker so that stepping frame 6
    // again gives what an uncancelled run gives.
    let dir = tempfile::tempdir().unwrap();
    let scene = cloth_with_camera_0_early_from_4(dir.path());
    let s = Scene::load(&scene).unwrap();
    let tracker = || {
        let mut t = Tracker::new(
            &s.mesh,
            s.cameras.clone(),
            0,
            &s.load_images(0).unwrap(),
            TrackOptions::default(),
        )
        .unwrap();
        let mut early = Vec::new();
        for f in 1..=5 {
            early = t.step(f, &s.load_images(f).unwrap()).unwrap().early_cameras;
        }
        assert_eq!(early, [0], "found early by frame 5");
        t
    };
    let mut reference = tracker();
    let want = reference.step(6, &s.load_images(6).unwrap()).unwrap();
    let mut t = tracker();
    t.set_cancel(Arc::new(AtomicBool::new(true)));
    assert!(t.step(6, &s.load_images(6).unwrap()).is_err());
    t.set_cancel(Arc::new(AtomicBool::new(false)));
    let got = t.step(6, &s.load_images(6).unwrap()).unwrap();
    assert_eq!(got.early_cameras, want.early_cameras);
    assert_eq!(t.positions(), reference.positions());
}

#[test]
fn a_run_stopped_after_a_camera_was_found_turned_resumes_to_the_same_files() {
    // Camera 1 is knocked 0.3° off its calibration at frame 3 (a textured wall behind the cloth
    // shows it): the tracker poses it turned from frame 3 on. Stopped at frame 3 or 4, the
    // resumed run must go on with the turned pose, not find it again from the calibrated one.
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        width: 320,
        height: 240,
        frames: 6,
        shake: 3.0,
        backdrop: true,
        bump: Some(modelflow::synth::Bump {
            camera: 1,
            frame: 3,
            degrees: 0.3,
        }),
        ..SynthOptions::default()
    };
    let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
    let reference = dir.path().join("reference");
    track(&scene, &reference, &RunOptions::default()).unwrap();
    let log = read_frame_log(&reference).unwrap();
    let moved: Vec<(u32, Vec<u16>)> = log
        .iter()
        .filter_map(|l| {
            let r = l.model_flow()?;
            (!r.moved_cameras.is_empty()).then(|| (l.frame, r.moved_cameras.clone()))
        })
        .collect();
    assert_eq!(moved, [(3, vec![1])]);
    for stop in [3, 4] {
        let out = dir.path().join(format!("interrupted-{stop}"));
        interrupted_after(&scene, &out, stop);
        assert_eq!(track(&scene, &out, &resume()).unwrap(), (5 - stop) as usize);
        assert_eq!(meshes(&out), meshes(&reference), "byte-identical meshes");
        assert_eq!(logs_without_times(&out), logs_without_times(&reference));
    }
}

#[test]
fn a_run_under_a_long_shutter_resumes_to_the_same_files() {
    // With the shutter open (`motion_blur`, written into the scene), the anchor is smeared
    // along the first frame's motion from frame 2 on: a resumed run takes that motion from the
    // run's frame 1, and goes on exactly as the uninterrupted one.
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        width: 160,
        height: 120,
        frames: 7,
        shake: 4.0,
        motion_blur: 1.0,
        ..SynthOptions::default()
    };
    let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
    assert!(std::fs::read_to_string(&scene)
        .unwrap()
        .contains("\"shutter\": 1.0"));
    let reference = dir.path().join("reference");
    track(&scene, &reference, &RunOptions::default()).unwrap();
    for stop in [1, 3] {
        let out = dir.path().join(format!("interrupted-{stop}"));
        interrupted_after(&scene, &out, stop);
        assert_eq!(track(&scene, &out, &resume()).unwrap(), (6 - stop) as usize);
        assert_eq!(meshes(&out), meshes(&reference), "byte-identical meshes");
        assert_eq!(logs_without_times(&out), logs_without_times(&reference));
    }
}

#[test]
fn a_mesh_split_along_seams_resumes_to_the_files_of_an_uninterrupted_run() {
    // The tracker works on the split vertices merged; the bending term's yield depends on the
    // last frame's per-vertex information, which a resumed run reads back from a confidence
    // file written on the given (split) vertices, so it must land on the merged ones as it was.
    let (tmp, scene_path, _) = shot();
    let mut scene = Scene::load(scene_path).unwrap();
    let mut positions = scene.mesh.positions.clone();
    let mut triangles = scene.mesh.triangles.clone();
    // Every other triangle's first corner becomes a copy of its vertex, at the same place.
    for t in triangles.iter_mut().step_by(2) {
        positions.push(positions[t[0] as usize]);
        t[0] = (positions.len() - 1) as u32;
    }
    scene.mesh = Mesh::new(positions, triangles);
    let run = |out: &Path, run: &RunOptions, stop_after: Option<u32>| {
        let cancel = run.cancel.clone();
        track_scene(&scene, &TrackOptions::default(), out, run, &mut |l| {
            if Some(l.frame) == stop_after {
                cancel.as_ref().unwrap().store(true, Ordering::Relaxed);
            }
        })
    };
    let reference = tmp.path().join("split-reference");
    run(&reference, &RunOptions::default(), None).unwrap();
    let out = tmp.path().join("split-interrupted");
    let stop = RunOptions {
        cancel: Some(Arc::new(AtomicBool::new(false))),
        ..RunOptions::default()
    };
    let err = run(&out, &stop, Some(3)).unwrap_err();
    assert!(
        matches!(err, Error::Interrupted { last_complete: 3 }),
        "{err}"
    );
    assert_eq!(run(&out, &resume(), None).unwrap().solved, 4);
    assert_eq!(meshes(&out), meshes(&reference), "byte-identical meshes");
    assert_eq!(logs_without_times(&out), logs_without_times(&reference));
}

#[test]
fn a_run_whose_first_mesh_was_moved_onto_the_surface_resumes_to_the_same_files() {
    // The blob with its mesh 2 % of its size outside the surface (a visual hull): the tracker
    // moves it onto the surface before tracking, writes the moved mesh as the first frame and
    // records the move; interrupted and resumed, the run rebuilds the same first frame and ends
    // with the uninterrupted run's files.
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        preset: modelflow::synth::Preset::Blob,
        width: 320,
        height: 240,
        frames: 5,
        supersample: 1,
        ..SynthOptions::default()
    };
    let footage = dir.path().join("footage");
    let scene_path = write_dataset(&opts, &footage, &|_, _| {}).unwrap();
    let on = modelflow::input::read_mesh(&footage.join("mesh/initial.obj")).unwrap();
    let normals = on.vertex_normals();
    let size = on.bbox_diagonal();
    let hull = on.with_positions(
        on.positions
            .iter()
            .zip(&normals)
            .map(|(p, n)| p + n * 0.02 * size)
            .collect(),
    );
    modelflow::input::write_obj(&footage.join("mesh/initial.obj"), &hull).unwrap();
    let reference = dir.path().join("reference");
    track(&scene_path, &reference, &RunOptions::default()).unwrap();
    let m = Manifest::read(&reference.join("run.json")).unwrap();
    let moved = m.first_mesh_moved.expect("the move recorded");
    assert!(
        moved.found.pixels < -1.5 && moved.median > 0.01 * size,
        "{moved:?}"
    );
    let first = modelflow::input::read_mesh(&reference.join("0000.obj")).unwrap();
    let median_off = |mesh: &modelflow::base::Mesh| {
        let mut d: Vec<f64> = mesh
            .positions
            .iter()
            .zip(&on.positions)
            .map(|(a, b)| (a - b).norm() / size)
            .collect();
        d.sort_by(f64::total_cmp);
        d[d.len() / 2]
    };
    assert!(median_off(&first) < 0.004, "{}", median_off(&first));
    let out = dir.path().join("interrupted");
    let err = interrupted_after(&scene_path, &out, 2);
    assert!(
        matches!(err, Error::Interrupted { last_complete: 2 }),
        "{err}"
    );
    assert_eq!(
        track(&scene_path, &out, &resume()).unwrap(),
        2,
        "frames 3..=4"
    );
    assert_eq!(meshes(&out), meshes(&reference), "byte-identical meshes");
    assert_eq!(logs_without_times(&out), logs_without_times(&reference));
    assert_eq!(
        Manifest::read(&out.join("run.json"))
            .unwrap()
            .first_mesh_moved,
        Some(moved)
    );
}

#[test]
fn a_crash_s_leftovers_are_dropped_on_resume() {
    let (tmp, scene, reference) = shot();
    let out = tmp.path().join("crashed");
    interrupted_after(scene, &out, 4);
    // What a kill in the middle of frame 5 can leave: frame 5's mesh without its log line, a
    // torn log line, and a temporary file of the next write.
    std::fs::copy(reference.join("0005.obj"), out.join("0005.obj")).unwrap();
    let full = std::fs::read_to_string(reference.join("log.jsonl")).unwrap();
    let line5 = full.lines().nth(4).unwrap();
    let mut log = std::fs::OpenOptions::new()
        .append(true)
        .open(out.join("log.jsonl"))
        .unwrap();
    std::io::Write::write_all(&mut log, &line5.as_bytes()[..line5.len() / 2]).unwrap();
    std::fs::write(out.join(".0006.obj.4242.tmp"), "half a mesh").unwrap();

    assert_eq!(track(scene, &out, &resume()).unwrap(), 3, "frames 5..=7");
    assert_eq!(meshes(&out), meshes(reference));
    assert_eq!(logs_without_times(&out), logs_without_times(reference));
    let names: Vec<String> = contents(&out).into_keys().collect();
    assert!(
        names.iter().all(|n| !n.ends_with(".tmp")),
        "no temporary file is left: {names:?}"
    );
}

#[test]
fn a_folder_of_other_files_is_refused_and_force_replaces_only_run_files() {
    let (tmp, scene, _) = shot();
    let out = tmp.path().join("truth-by-mistake");
    std::fs::create_dir_all(&out).unwrap();
    // A ground truth folder and a user's note.
    let truth = Scene::load(scene).unwrap();
    for f in truth.frames() {
        let m = truth.ground_truth(f).unwrap().unwrap();
        modelflow::input::write_obj(&out.join(format!("{f:04}.obj")), &m).unwrap();
    }
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let before = contents(&out);
    for mode in [OpenMode::New, OpenMode::Resume] {
        let run = RunOptions {
            mode,
            ..RunOptions::default()
        };
        let err = track(scene, &out, &run).unwrap_err().to_string();
        assert!(
            err.contains("not a modelflow run") && err.contains("--force"),
            "{mode:?}: {err}"
        );
        assert_eq!(contents(&out), before, "{mode:?}: nothing in it changes");
    }
    let force = RunOptions {
        mode: OpenMode::Force,
        ..RunOptions::default()
    };
    assert_eq!(track(scene, &out, &force).unwrap(), 7);
    assert_eq!(std::fs::read(out.join("notes.txt")).unwrap(), b"mine");
    assert!(out.join("run.json").is_file());
}

#[test]
fn the_scene_s_own_ground_truth_and_image_folders_are_refused_even_with_force() {
    let (_, scene, _) = shot();
    let footage = scene.parent().unwrap();
    let s = Scene::load(scene).unwrap();
    let truth_dir = s
        .ground_truth
        .as_ref()
        .unwrap()
        .path(s.first)
        .parent()
        .unwrap()
        .to_path_buf();
    let image_dir = s.images[0].path(s.first).parent().unwrap().to_path_buf();
    let force = RunOptions {
        mode: OpenMode::Force,
        ..RunOptions::default()
    };
    for (dir, says) in [
        (truth_dir, "ground-truth folder"),
        (image_dir, "image folder"),
    ] {
        let before = contents(&dir);
        let err = track(scene, &dir, &force).unwrap_err().to_string();
        assert!(err.contains(says), "{err}");
        assert_eq!(
            contents(&dir),
            before,
            "{}: nothing in it changes",
            dir.display()
        );
    }
    assert!(footage.join("scene.json").is_file());
}

#[test]
fn another_scene_s_run_and_other_options_are_refused() {
    let (tmp, scene, reference) = shot();
    // Resuming with other options than the run's.
    let out = tmp.path().join("other-options");
    interrupted_after(scene, &out, 2);
    let before = contents(&out);
    let mut s = Scene::load(scene).unwrap();
    let stiffer = TrackOptions {
        regularisation: Regularisation {
            spring_k: 2.0,
            ..Regularisation::default()
        },
        ..TrackOptions::default()
    };
    let err = track_scene(&s, &stiffer, &out, &resume(), &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("other options") && err.contains("regularisation.spring_k: 1.0 -> 2.0"),
        "{err}"
    );
    assert_eq!(contents(&out), before);
    // A run made before the patches were weighed (its manifest has no `patch_scale`) ran
    // without it: resuming it is refused, naming the option it did not have.
    let old = tmp.path().join("older-build");
    interrupted_after(scene, &old, 2);
    let manifest = old.join("run.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    let solver = m["options"]["used"]["options"]["solver"]
        .as_object_mut()
        .unwrap();
    assert!(solver.remove("patch_scale").is_some());
    std::fs::write(&manifest, serde_json::to_string_pretty(&m).unwrap()).unwrap();
    let err = track_scene(&s, &TrackOptions::default(), &old, &resume(), &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(err.contains("solver.patch_scale: none -> 0.5"), "{err}");
    // The same folder for a shorter shot: the refusal names the frames it was made for.
    s.last -= 1;
    let err = track_scene(
        &s,
        &TrackOptions::default(),
        reference,
        &resume(),
        &mut |_| {},
    )
    .unwrap_err()
    .to_string();
    let want = format!(
        "for frames {}..{}, not {}..{}",
        s.first,
        s.last + 1,
        s.first,
        s.last
    );
    assert!(
        err.contains(&want) && err.contains("nothing to resume"),
        "{err}"
    );
}

#[test]
fn the_manifest_records_what_made_the_run() {
    let (_, scene, reference) = shot();
    let m = Manifest::read(&reference.join("run.json")).unwrap();
    assert_eq!(m.format, "modelflow-run/1");
    assert_eq!(m.tool, format!("modelflow {}", env!("CARGO_PKG_VERSION")));
    assert_eq!(m.status, Status::Complete);
    assert_eq!((m.scene.first, m.scene.last), (0, 7));
    assert_eq!(m.frames_completed, 8);
    assert!(m.scene.path.is_absolute() && m.scene.path.ends_with("scene.json"));
    let s = Scene::load(scene).unwrap();
    assert_eq!(
        m.scene.checksum,
        modelflow::run::inputs_checksum(&s).unwrap()
    );
    assert!(m.scene.checksum.starts_with("sha256:") && m.scene.checksum.len() == 7 + 64);
    assert!(m.ended.is_some() && m.started.ends_with('Z'));
    // Options as used: every tracker option, resolved, with what it implies.
    let used = &m.options.used;
    // `levels` is automatic by default and resolved from the image size: 160×120 → 1 level.
    assert_eq!(used["options"]["levels"], 1);
    assert_eq!(used["options"]["regularisation"]["spring_k"], 1.0);
    assert_eq!(
        used["interpolation_per_level"],
        serde_json::json!(["cubic"])
    );
    assert_eq!(
        used["regularisers"],
        serde_json::json!(["cubic_springs", "membrane", "bending"])
    );
}

#[test]
fn a_cancelled_step_leaves_the_tracker_where_it_was() {
    let (_, scene, _) = shot();
    let s = Scene::load(scene).unwrap();
    let mut t = Tracker::new(
        &s.mesh,
        s.cameras.clone(),
        0,
        &s.load_images(0).unwrap(),
        TrackOptions::default(),
    )
    .unwrap();
    t.step(1, &s.load_images(1).unwrap()).unwrap();
    let at_1 = t.positions().to_vec();
    t.set_cancel(Arc::new(AtomicBool::new(true)));
    let err = t.step(2, &s.load_images(2).unwrap()).unwrap_err();
    assert!(
        matches!(err, Error::Interrupted { last_complete: 1 }),
        "{err}"
    );
    assert_eq!(t.positions(), &at_1[..]);
}

/// The knocked blob of `frames` frames (camera 1 of four turned 0.5° from frame 3, 320×240, a
/// flat background; `track_cli`'s test of the per-camera rule): its folder and scene file.
fn knocked_blob(frames: u32) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        preset: modelflow::synth::Preset::Blob,
        width: 320,
        height: 240,
        frames,
        shake: 4.0,
        bump: Some(modelflow::synth::Bump {
            camera: 1,
            frame: 3,
            degrees: 0.5,
        }),
        ..SynthOptions::default()
    };
    let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
    (dir, scene)
}

/// The frames flagged for the knocked pair's disagreement (cameras 0 and 1, since frame 3).
fn knocked_pair_flagged(checks: &[modelflow::tracker::FrameCheck]) -> Vec<u32> {
    checks
        .iter()
        .filter(|c| {
            c.concerns.iter().any(|k| {
                matches!(
                    k,
                    modelflow::tracker::Concern::Disagree {
                        since: 3,
                        cameras: 2,
                        ..
                    }
                )
            })
        })
        .map(|c| c.frame)
        .collect()
}

#[test]
fn a_run_resumed_in_the_middle_of_a_cameras_disagreement_still_names_it() {
    // The knocked blob (camera 1 of four turned 0.5° from frame 3, 320×240, in front of a flat
    // background; `track_cli`'s test of the per-camera rule): uninterrupted, the rule names
    // cameras 0 and 1 at the fifth report running, frame 8's, and flags frames 3..=8, and the
    // last, 9, once the shot is done (both cameras still up there since their share is judged
    // by the cameras that see alike, 2026-12-06; camera 1 alone before). Interrupted after
    // frame 5 and resumed, the resumed call sees only reports 6..=9: it goes on from the log's
    // reports before, and its summary names the same frames.
    let (dir, scene_path) = knocked_blob(10);
    let out = dir.path().join("interrupted");
    let err = interrupted_after(&scene_path, &out, 5);
    assert!(
        matches!(err, Error::Interrupted { last_complete: 5 }),
        "{err}"
    );
    let scene = Scene::load(&scene_path).unwrap();
    let summary = track_scene(
        &scene,
        &TrackOptions::default(),
        &out,
        &resume(),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(summary.resumed_from, Some(5));
    assert_eq!(
        knocked_pair_flagged(&summary.checks),
        [3, 4, 5, 6, 7, 8, 9],
        "{:?}",
        summary.checks
    );
}

#[test]
fn a_cameras_disagreement_completed_by_the_shots_last_frame_is_named() {
    // The knocked blob cut to frames 0..=7: reports 4..=7 show cameras 0 and 1 up, four
    // running; the fifth is the check on frame 7 taken once the shot is done (no next frame's
    // report judges it). Judged by the rig's share alone until 2026-12-04, the run went unnamed.
    let (dir, scene_path) = knocked_blob(8);
    let scene = Scene::load(&scene_path).unwrap();
    let out = dir.path().join("run");
    let summary = track_scene(
        &scene,
        &TrackOptions::default(),
        &out,
        &RunOptions::default(),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(
        knocked_pair_flagged(&summary.checks),
        [3, 4, 5, 6, 7],
        "{:?}",
        summary.checks
    );
    // The manifest keeps each camera's share of that check; the folder's frames to check read
    // it back.
    let m = Manifest::read(&out.join("run.json")).unwrap();
    let last = m.last_frame_check.expect("the last frame's check");
    assert_eq!((last.frame, last.contradicted_by_camera.len()), (7, 4));
    let back = modelflow::run::frames_to_check(&out, 0, 7)
        .unwrap()
        .unwrap();
    assert_eq!(knocked_pair_flagged(&back), [3, 4, 5, 6, 7]);
}

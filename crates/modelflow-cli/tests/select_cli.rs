//! `--frames`, `--cameras` and `--mesh`: part of a shot, some of its cameras, and going on from
//! an earlier run's mesh, with `eval` scoring exactly what was tracked.

use modelflow::synth::{write_dataset, SynthOptions};
use std::path::Path;
use std::process::{Command, Output};

fn modelflow(args: &[&str], paths: &[(&str, &Path)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_modelflow"));
    c.args(args);
    for (flag, p) in paths {
        c.arg(flag).arg(p);
    }
    c.output().unwrap()
}

/// The blob's four cameras at 160×120 over frames 0..4, written into `dir`; its scene file.
fn blob(dir: &Path) -> std::path::PathBuf {
    let opts = SynthOptions {
        preset: modelflow::synth::Preset::Blob,
        width: 160,
        height: 120,
        frames: 5,
        ..SynthOptions::default()
    };
    write_dataset(&opts, dir, &|_, _| {}).unwrap()
}

#[test]
fn part_of_a_shot_with_some_cameras_goes_on_from_an_earlier_runs_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let scene = blob(&dir.path().join("footage"));
    let (first, second) = (dir.path().join("a"), dir.path().join("b"));
    // Frames 0..2 with three of the four cameras, then 2..4 from that run's last mesh.
    let out = modelflow(
        &["track", "--frames", "0..2", "--cameras", "cam2,cam0,cam1"],
        &[("--scene", &scene), ("--out", &first)],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let names: Vec<String> = std::fs::read_dir(&first)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".obj"))
        .collect();
    assert_eq!(names.len(), 3, "{names:?}");
    let out = modelflow(
        &["track", "--frames", "2..4"],
        &[
            ("--scene", &scene),
            ("--out", &second),
            ("--mesh", &first.join("0002.obj")),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Scored over the frames tracked (with the scene's mesh for the scale): close to the truth.
    let out = modelflow(
        &["eval", "--json", "--frames", "2..4"],
        &[("--scene", &scene), ("--track", &second)],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["frames"], 3);
    let mean = report["rms_mean_pct"].as_f64().unwrap();
    assert!(mean < 0.5, "mean error {mean} % over frames 2..4");
    // Without --frames: the frames the run tracked, as its run.json records them, said so.
    let out = modelflow(
        &["eval", "--json"],
        &[("--scene", &scene), ("--track", &second)],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("evaluating frames 2..=4"), "{err}");
    let again: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(again, report);
    // A folder of meshes without a run.json is scored over the whole scene: which frames lack.
    std::fs::remove_file(second.join("run.json")).unwrap();
    let out = modelflow(&["eval"], &[("--scene", &scene), ("--track", &second)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("no mesh for frame(s) 0, 1"),
        "{err}"
    );
}

#[test]
fn bad_selections_name_the_option_and_what_is_allowed() {
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        width: 96,
        height: 72,
        frames: 3,
        ..SynthOptions::default()
    };
    let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
    let run = dir.path().join("run");
    for (args, want) in [
        (vec!["--frames", "1..9"], "0 <= A <= B <= 2"),
        (vec!["--frames", "2..1"], "expected A..B"),
        (vec!["--cameras", "cam0,cam7"], "cam0, cam1"),
        (vec!["--cameras", "cam0,cam0"], "each camera named once"),
        (vec!["--cameras", "cam1"], "fewer than two cameras"),
    ] {
        let mut a = vec!["track"];
        a.extend(&args);
        let out = modelflow(&a, &[("--scene", &scene), ("--out", &run)]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(want),
            "{args:?}: {err}"
        );
        assert!(!run.exists(), "{args:?}: nothing is written");
    }
}

#[test]
fn a_camera_or_frames_with_broken_footage_can_be_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let footage = dir.path().join("footage");
    let scene = blob(&footage);
    // Camera 3's frame 1 is not an image, and camera 0 lacks frame 4.
    let bad = footage.join("images/cam3/0001.png");
    std::fs::write(&bad, b"not a png").unwrap();
    std::fs::remove_file(footage.join("images/cam0/0004.png")).unwrap();
    let run = dir.path().join("run");
    // The whole scene is refused, naming the first problem.
    let out = modelflow(&["track"], &[("--scene", &scene), ("--out", &run)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("cameras[") && err.contains("images"), "{err}");
    assert!(!run.exists());
    // Leaving out camera 3 and frame 4, the rest is tracked and scored.
    let out = modelflow(
        &["track", "--frames", "0..3", "--cameras", "cam0,cam1,cam2"],
        &[("--scene", &scene), ("--out", &run)],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = modelflow(
        &["eval", "--json"],
        &[("--scene", &scene), ("--track", &run)],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["frames"], 4);
    let mean = report["rms_mean_pct"].as_f64().unwrap();
    assert!(mean < 0.5, "mean error {mean} % over frames 0..3");
    // A camera left in with a broken frame is named by its place in the scene file.
    let out = modelflow(
        &["track", "--frames", "0..3", "--cameras", "cam3,cam1"],
        &[("--scene", &scene), ("--out", &dir.path().join("run2"))],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("cameras[3].images") && err.contains("frame 1"),
        "{err}"
    );
}

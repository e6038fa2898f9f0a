//! `modelflow eval` as a user runs it: exit codes, the table, `--json`, and errors on stderr.

use modelflow::input::{read_mesh, write_obj};
use nalgebra::Vector3;
use std::path::PathBuf;
use std::process::{Command, Output};

fn sample() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/blender-cloth-sample"
    ))
}

fn modelflow(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_modelflow"))
        .args(args)
        .output()
        .unwrap()
}

fn eval(scene: &std::path::Path, track: &std::path::Path, json: bool) -> Output {
    let mut a = vec![
        "eval".as_ref(),
        "--scene".as_ref(),
        scene.as_os_str(),
        "--track".as_ref(),
        track.as_os_str(),
    ];
    if json {
        a.push("--json".as_ref());
    }
    modelflow(&a)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn ground_truth_against_itself_scores_zero() {
    let out = eval(&sample().join("scene.json"), &sample().join("truth"), true);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert_eq!(
        stdout.trim().lines().count(),
        1,
        "one JSON object: {stdout}"
    );
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["frames"], 12);
    assert_eq!(v["rms_mean"], 0.0);
    assert_eq!(v["rms_final"], 0.0);
    assert_eq!(v["per_frame"].as_array().unwrap().len(), 12);
}

#[test]
fn shifted_run_scores_the_shift_in_a_table() {
    let dir = tempfile::tempdir().unwrap();
    write_shifted(dir.path(), 0..=11);
    let out = eval(&sample().join("scene.json"), dir.path(), false);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(table.starts_with(" frame"), "{table}");
    // rms and max per frame, mean and final, mean and final over the seen vertices, and the
    // whole mesh's mean shift (the shape itself is right: 0 % after the rigid fit).
    // Lengths with three significant digits (`base::units::significant`).
    assert_eq!(table.matches(" 0.0100 ").count(), 2 * 12 + 5, "{table}");
    assert!(
        table.contains("shape alone (after each frame's best rigid fit to the truth): rms mean 0.0000 %, final 0.0000 %; that fit turns 0.000° and shifts 0.0100 scene units on average"),
        "{table}"
    );
    assert!(
        table.contains("by cameras seeing a vertex (in the truth), rms mean: "),
        "{table}"
    );
    assert!(
        table.contains("seen vertices (by some camera, in the truth): rms mean 0.0100 scene units"),
        "{table}"
    );
    assert!(table.contains("12 frames"), "{table}");
    assert!(table.contains("rms (scene units)"), "{table}");

    // The same scene saying its unit is the metre: the table shows the same errors in mm.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sample().join("scene.json")).unwrap())
            .unwrap();
    let abs = |rel: &serde_json::Value| sample().join(rel.as_str().unwrap()).display().to_string();
    v["units"] = "m".into();
    v["mesh"] = abs(&v["mesh"]).into();
    v["ground_truth"] = abs(&v["ground_truth"]).into();
    for c in v["cameras"].as_array_mut().unwrap() {
        c["images"] = abs(&c["images"]).into();
    }
    let metres = dir.path().join("metres.json");
    std::fs::write(&metres, v.to_string()).unwrap();
    let out = eval(&metres, dir.path(), false);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(table.contains("rms (mm)"), "{table}");
    assert_eq!(table.matches(" 10.0 ").count(), 2 * 12 + 5, "{table}");
    assert!(table.contains("rms final 10.0 mm (0.3536 %)"), "{table}");
    let out = eval(&metres, dir.path(), true);
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["units"], "m");
    assert!((j["rms_final"].as_f64().unwrap() - 0.01).abs() < 1e-9);

    let out = eval(&sample().join("scene.json"), dir.path(), true);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!((v["rms_final"].as_f64().unwrap() - 0.01).abs() < 1e-9);
    // 100 * 0.01 / (2 * sqrt 2), the cloth's 2 m square bounding-box diagonal.
    assert!((v["rms_final_pct"].as_f64().unwrap() - 1.0 / 8f64.sqrt()).abs() < 1e-6);
}

/// A run folder whose `run.json` says it tracked `first..=last` of the sample (stopped after
/// `last_complete` when given), with the truth's meshes shifted by 1 cm up to there.
fn run_folder(first: u32, last: u32, last_complete: Option<u32>) -> tempfile::TempDir {
    use modelflow::run::{Manifest, Method, Options, Status};
    let dir = tempfile::tempdir().unwrap();
    let scene = modelflow::input::Scene::load(&sample().join("scene.json"))
        .unwrap()
        .with_frames(first, last)
        .unwrap();
    let mut m = Manifest::new(Method::ModelFlow, &scene, vec![], Options::default()).unwrap();
    m.status = if last_complete.is_some() {
        Status::Interrupted
    } else {
        Status::Complete
    };
    m.last_complete = Some(last_complete.unwrap_or(last));
    std::fs::write(
        dir.path().join("run.json"),
        serde_json::to_string_pretty(&m).unwrap(),
    )
    .unwrap();
    write_shifted(dir.path(), first..=last_complete.unwrap_or(last));
    dir
}

/// The sample's true meshes of `frames`, moved by 1 cm (0.6 along y, 0.8 along z), into `dir`.
fn write_shifted(dir: &std::path::Path, frames: std::ops::RangeInclusive<u32>) {
    for f in frames {
        let name = format!("{f:04}.obj");
        let m = read_mesh(&sample().join("truth").join(&name)).unwrap();
        let moved = m
            .positions
            .iter()
            .map(|p| p + Vector3::new(0.0, 0.006, 0.008))
            .collect();
        write_obj(&dir.join(&name), &m.with_positions(moved)).unwrap();
    }
}

#[test]
fn a_run_of_some_frames_is_scored_over_the_frames_it_tracked() {
    // `track --frames 3..8`, then `eval` without --frames: the run's frames, said on stderr.
    let dir = run_folder(3, 8, None);
    let out = eval(&sample().join("scene.json"), dir.path(), true);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frames"], 6);
    assert_eq!(v["per_frame"][0]["frame"], 3);
    assert!((v["rms_final"].as_f64().unwrap() - 0.01).abs() < 1e-9);
    let err = text(&out.stderr);
    assert!(
        err.contains("evaluating frames 3..=8, the frames the run tracked (run.json"),
        "{err}"
    );
    // --frames still chooses.
    let out = modelflow(&[
        "eval".as_ref(),
        "--scene".as_ref(),
        sample().join("scene.json").as_os_str(),
        "--track".as_ref(),
        dir.path().as_os_str(),
        "--frames".as_ref(),
        "3..5".as_ref(),
        "--json".as_ref(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frames"], 3);

    // An interrupted run: up to its last complete frame.
    let dir = run_folder(0, 11, Some(6));
    let out = eval(&sample().join("scene.json"), dir.path(), true);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frames"], 7);
    assert!(text(&out.stderr).contains("it stopped there"));

    // A whole-scene run says nothing.
    let dir = run_folder(0, 11, None);
    let out = eval(&sample().join("scene.json"), dir.path(), true);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(text(&out.stderr), "");
}

#[test]
fn missing_frame_fails_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    for f in [0, 1, 2, 4, 5, 6, 7, 8, 9, 10, 11] {
        let name = format!("{f:04}.obj");
        std::fs::copy(sample().join("truth").join(&name), dir.path().join(&name)).unwrap();
    }
    let out = eval(&sample().join("scene.json"), dir.path(), false);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(err.starts_with("error: "), "{err}");
    assert!(err.contains("frame(s) 3"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_scene_fails_with_a_message_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    std::fs::write(
        &scene,
        "{\"format\": \"modelflow-scene/1\", \"frames\": {\"first\": 0,,}}",
    )
    .unwrap();
    let out = eval(&scene, dir.path(), true);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.contains("scene.json") && err.contains("line 1 column"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(out.stdout.is_empty());

    let out = eval(&dir.path().join("absent.json"), dir.path(), false);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("absent.json"));
}

#[test]
fn missing_argument_is_a_usage_error() {
    let out = modelflow(&["eval".as_ref(), "--scene".as_ref(), "x.json".as_ref()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("--track"));
}

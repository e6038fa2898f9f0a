//! `modelflow baseline` as a user runs it: bad options and a missing scene are clear errors with
//! a failing exit code, and nothing is written.

use std::process::Command;

const SCENE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../fixtures/blender-cloth-sample/scene.json"
);

fn baseline(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_modelflow"))
        .arg("baseline")
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn even_window_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let (ok, err) = baseline(&[
        "--scene",
        SCENE,
        "--out",
        out.to_str().unwrap(),
        "--window",
        "20",
    ]);
    assert!(!ok);
    assert!(
        err.contains("--window 20: expected an odd number of pixels"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
}

#[test]
fn missing_scene_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.json");
    let (ok, err) = baseline(&[
        "--scene",
        missing.to_str().unwrap(),
        "--out",
        dir.path().join("run").to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(err.contains("nope.json"), "{err}");
}

#[test]
fn unknown_seeding_is_a_usage_error() {
    let (ok, err) = baseline(&["--scene", SCENE, "--out", "/tmp/x", "--seeding", "magic"]);
    assert!(!ok);
    assert!(
        err.contains("reprojected") && err.contains("chained"),
        "{err}"
    );
}

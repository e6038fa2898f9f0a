//! `modelflow synth` end to end: a small data set that the scene loader accepts, and clear
//! errors for bad options.

use std::process::Command;

fn modelflow() -> Command {
    Command::new(env!("CARGO_BIN_EXE_modelflow"))
}

#[test]
fn writes_a_loadable_scene_with_images_and_truth() {
    let dir = tempfile::tempdir().unwrap();
    let out = modelflow()
        .args([
            "synth", "--preset", "blob", "--frames", "2", "--width", "96",
        ])
        .args([
            "--height",
            "72",
            "--cameras",
            "3",
            "--supersample",
            "2",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("per-frame vertex motion"), "{stderr}");
    let scene_path = dir.path().join("scene.json");
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).trim(),
        scene_path.display().to_string()
    );
    let scene = modelflow::input::Scene::load(&scene_path).unwrap();
    assert_eq!((scene.first, scene.last, scene.cameras.len()), (0, 1, 3));
    for cam in ["cam0", "cam1", "cam2"] {
        for f in ["0000", "0001"] {
            let p = dir.path().join(format!("images/{cam}/{f}.png"));
            assert_eq!(modelflow::input::image_size(&p).unwrap(), (96, 72));
        }
    }
    assert!(scene.ground_truth(1).unwrap().unwrap().is_closed());
}

#[test]
fn unknown_preset_and_bad_options_fail_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = modelflow()
        .args(["synth", "--preset", "flag", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unknown synthetic preset 'flag'") && err.contains("cloth, blob"),
        "{err}"
    );
    let out = modelflow()
        .args(["synth", "--cameras", "1", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--cameras 1"));
    for (spec, why) in [
        ("-0.3,0.1,0,0", "expected MODEL:c1,c2"),
        ("opencv:-0.3,x,0,0", "\"x\" is not a number"),
        ("opencv:-0.3,0.1", "4, 5, 8, 12 or 14 coefficients"),
    ] {
        let out = modelflow()
            .args(["synth", "--distortion", spec, "--out"])
            .arg(dir.path())
            .output()
            .unwrap();
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--distortion") && err.contains(why),
            "{spec}: {err}"
        );
    }
    assert!(!dir.path().join("scene.json").exists());
}

#[test]
fn renders_through_a_lens_and_records_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = modelflow()
        .args(["synth", "--frames", "1", "--width", "96", "--height", "72"])
        .args(["--distortion", "fisheye:0.05,-0.01,0,0", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("scene.json")).unwrap();
    assert!(text.contains("\"model\": \"fisheye\""), "{text}");
    let scene = modelflow::input::Scene::load(&dir.path().join("scene.json")).unwrap();
    let lens = scene.cameras[1].lens.as_ref().expect("a lens");
    assert_eq!(
        lens.distortion().coefficients(),
        vec![0.05, -0.01, 0.0, 0.0]
    );
}

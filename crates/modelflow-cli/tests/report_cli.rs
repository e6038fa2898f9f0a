//! `modelflow report` as a user runs it: a report from the sample's ground truth and a frame
//! list, and clear errors for malformed `--run` and unknown frames.

use std::path::PathBuf;
use std::process::{Command, Output};

fn scene() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/blender-cloth-sample/scene.json"
    ))
}

fn truth() -> PathBuf {
    scene().parent().unwrap().join("truth")
}

fn modelflow(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_modelflow"))
        .args(args)
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn report_writes_index_and_chosen_frames() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rep");
    let run = format!("truth={}", truth().display());
    let o = modelflow(&[
        "report".as_ref(),
        "--scene".as_ref(),
        scene().as_os_str(),
        "--run".as_ref(),
        run.as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
        "--overlay-frames".as_ref(),
        "2,7".as_ref(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert_eq!(
        text(&o.stdout).trim(),
        out.join("index.html").display().to_string()
    );
    for f in [
        "index.html",
        "error.png",
        "error.svg",
        "overlay_f0002_c0_cam0.png",
        "overlay_f0007_c1_cam1.png",
        "oblique_f0007.png",
        "errormap_f0002.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    assert!(
        !out.join("overlay_f0000_c0_cam0.png").exists(),
        "only the chosen frames are drawn"
    );
}

#[test]
fn malformed_run_and_unknown_frame_are_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rep");
    let o = modelflow(&[
        "report".as_ref(),
        "--scene".as_ref(),
        scene().as_os_str(),
        "--run".as_ref(),
        truth().as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("expected NAME=DIR"),
        "{}",
        text(&o.stderr)
    );

    let run = format!("truth={}", truth().display());
    let o = modelflow(&[
        "report".as_ref(),
        "--scene".as_ref(),
        scene().as_os_str(),
        "--run".as_ref(),
        run.as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
        "--overlay-frames".as_ref(),
        "3,99".as_ref(),
    ]);
    assert!(!o.status.success());
    let err = text(&o.stderr);
    assert!(err.contains("frame 99") && err.contains("0..=11"), "{err}");
    assert!(!out.join("index.html").exists());
}

#[test]
fn a_run_of_some_frames_is_reported_over_the_frames_it_tracked() {
    // `track --frames 2..6` then `report` without --frames: the run's frames, said on stderr.
    use modelflow::run::{Manifest, Method, Options, Status};
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    std::fs::create_dir(&run).unwrap();
    let s = modelflow::input::Scene::load(&scene())
        .unwrap()
        .with_frames(2, 6)
        .unwrap();
    let mut m = Manifest::new(Method::ModelFlow, &s, vec![], Options::default()).unwrap();
    m.status = Status::Complete;
    m.last_complete = Some(6);
    std::fs::write(run.join("run.json"), serde_json::to_string(&m).unwrap()).unwrap();
    for f in 2..=6 {
        let name = format!("{f:04}.obj");
        std::fs::copy(truth().join(&name), run.join(&name)).unwrap();
    }
    let out = tmp.path().join("rep");
    let named = format!("part={}", run.display());
    let o = modelflow(&[
        "report".as_ref(),
        "--scene".as_ref(),
        scene().as_os_str(),
        "--run".as_ref(),
        named.as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
        "--no-flipbook".as_ref(),
        "--overlay-frames".as_ref(),
        "4".as_ref(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("reporting on frames 2..=6, the frames the run tracked"),
        "{}",
        text(&o.stderr)
    );
    assert!(out.join("overlay_f0004_c0_cam0.png").is_file());
}

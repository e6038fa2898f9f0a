//! `modelflow import`: a COLMAP model and an OpenCV file become scene files in our conventions;
//! an existing scene file is kept unless --force.

use modelflow::input::SceneFile;
use std::path::Path;
use std::process::Command;

fn fixtures() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures"))
}

fn import(args: &[&str], input: &Path, out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_modelflow"))
        .arg("import")
        .args(args)
        .arg(input)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn colmap_and_opencv_calibrations_become_scene_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.json");
    let r = import(
        &[
            "colmap",
            "--frames",
            "0..9",
            "--images",
            "footage/{camera}/{frame:04}.jpg",
        ],
        &fixtures().join("colmap/bin"),
        &out,
    );
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    // Not loadable yet (no mesh), and it says so.
    assert!(
        err.contains("does not load yet") && err.contains("mesh"),
        "{err}"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let file = SceneFile::parse(&out, &text).unwrap();
    assert_eq!((file.frames.first, file.frames.last), (0, 9));
    assert_eq!(file.cameras.len(), 7);
    let c = &file.cameras[6];
    assert_eq!(c.images, "footage/cam6/{frame:04}.jpg");
    // COLMAP's principal point (320, 240) with pixel centres at half-integers is our (319.5, 239.5).
    assert_eq!(c.k.unwrap()[0][2], 319.5);
    assert_eq!(c.distortion.as_ref().unwrap().model, "fisheye");
    // Kept unless --force.
    let r = import(&["opencv"], &fixtures().join("opencv/stereo.yml"), &out);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("--force"));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), text);
    let r = import(
        &["opencv", "--force"],
        &fixtures().join("opencv/stereo.yml"),
        &out,
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let file = SceneFile::parse(&out, &std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(file.cameras.len(), 2);
    assert_eq!(file.units, None);
    assert_eq!(
        file.cameras[0].r.unwrap(),
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    );
    // Several cameras need {camera} in the pattern.
    let r = import(
        &["opencv", "--force", "--images", "all/{frame}.png"],
        &fixtures().join("opencv/rig.yml"),
        &out,
    );
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("{camera}"));

    // The unit of the calibration, when given, is written down; a unit we do not know is refused.
    let r = import(
        &["opencv", "--force", "--units", "mm"],
        &fixtures().join("opencv/stereo.yml"),
        &out,
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let file = SceneFile::parse(&out, &std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(file.units, Some(modelflow::base::Units::Millimetres));
    let r = import(
        &["opencv", "--force", "--units", "inch"],
        &fixtures().join("opencv/stereo.yml"),
        &out,
    );
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("m, cm or mm"), "{err}");
}

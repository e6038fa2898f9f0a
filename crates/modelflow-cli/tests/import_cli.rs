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

fn fails(r: &std::process::Output, out: &Path, parts: &[&str]) {
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success(), "should fail: {err}");
    assert!(!out.exists(), "nothing is written when it fails: {err}");
    for p in parts {
        assert!(err.contains(p), "{err:?} should mention {p:?}");
    }
}

#[test]
fn scenes_that_could_never_load_are_not_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.json");
    let stereo = fixtures().join("opencv/stereo.yml");
    for (pattern, why) in [
        (
            "images/{camera}/{frame:4}.png",
            "unknown placeholder {frame:4}",
        ),
        (
            "images/{camera}/{frame:040}.png",
            "bad placeholder {frame:040}",
        ),
        ("images/{camera}/{frame:04}{.png", "unclosed `{`"),
        (
            "images/{camera}/0000.png",
            "no {frame} or {frame:0N} placeholder",
        ),
    ] {
        let r = import(&["opencv", "--images", pattern], &stereo, &out);
        fails(&r, &out, &["--images", why]);
    }
    // A video per camera is a pattern the scene reads.
    let r = import(
        &["opencv", "--images", "videos/{camera}.mp4"],
        &stereo,
        &out,
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let file = SceneFile::parse(&out, &std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(file.cameras[1].images, "videos/cam1.mp4");
    std::fs::remove_file(&out).unwrap();

    // Two Metashape cameras labelled cam0.
    let xml = std::fs::read_to_string(fixtures().join("metashape/cameras.xml")).unwrap();
    let p = dir.path().join("cameras.xml");
    std::fs::write(&p, xml.replace("label=\"cam1\"", "label=\"cam0\"")).unwrap();
    let r = import(&["metashape"], &p, &out);
    fails(
        &r,
        &out,
        &["cameras.xml", "camera \"cam0\": label", "unique"],
    );
}

#[test]
fn metashape_chunks_are_chosen_and_disabled_cameras_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.json");
    let xml = std::fs::read_to_string(fixtures().join("metashape/cameras.xml")).unwrap();
    // A second chunk, its cameras renamed.
    let start = xml.find("  <chunk").unwrap();
    let end = xml.find("</chunk>").unwrap() + "</chunk>\n".len();
    let second = xml[start..end]
        .replace("Chunk 1", "Chunk 2")
        .replace("label=\"cam", "label=\"other");
    let two = format!("{}{second}{}", &xml[..end], &xml[end..]);
    let p = dir.path().join("cameras.xml");
    std::fs::write(&p, &two).unwrap();
    let r = import(&["metashape"], &p, &out);
    fails(
        &r,
        &out,
        &[
            "cameras.xml",
            "2 chunks have aligned cameras",
            "\"Chunk 1\" (id 0",
            "\"Chunk 2\" (id 1",
            "--chunk LABEL_OR_ID",
        ],
    );
    let names = |out: &Path| -> Vec<String> {
        let file = SceneFile::parse(out, &std::fs::read_to_string(out).unwrap()).unwrap();
        file.cameras.into_iter().map(|c| c.name).collect()
    };
    let r = import(&["metashape", "--chunk", "Chunk 2"], &p, &out);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(names(&out), ["other0", "other1"]);
    // The first chunk disabled: the second is read without --chunk.
    std::fs::write(&p, two.replacen("enabled=\"true\"", "enabled=\"false\"", 1)).unwrap();
    let r = import(&["metashape", "--force"], &p, &out);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(names(&out), ["other0", "other1"]);
    // --chunk is Metashape's only.
    let r = import(
        &["opencv", "--force", "--chunk", "0"],
        &fixtures().join("opencv/stereo.yml"),
        &out,
    );
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("--chunk"), "{err}");

    // A camera disabled in Metashape but aligned is kept, and the summary says so.
    std::fs::write(
        &p,
        xml.replace("label=\"cam1\"", "label=\"cam1\" enabled=\"false\""),
    )
    .unwrap();
    let r = import(&["metashape", "--force"], &p, &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert_eq!(names(&out), ["cam0", "cam1"]);
    let line = err
        .lines()
        .find(|l| l.trim_start().starts_with("cam1"))
        .unwrap();
    assert!(line.contains("(disabled in Metashape)"), "{err}");
}

#[test]
fn nerfstudio_transforms_become_scene_files_in_the_world_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.json");
    let input = fixtures().join("nerfstudio/transforms.json");
    let r = import(&["nerfstudio"], &input, &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    // Where the cameras were put is said, with the option for the other world.
    assert!(
        err.contains("applied_transform") && err.contains("--before-applied-transform"),
        "{err}"
    );
    let file = SceneFile::parse(&out, &std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(file.cameras.len(), 6);
    assert_eq!(file.cameras[5].name, "cam6");
    assert_eq!(
        file.cameras[5].distortion.as_ref().unwrap().model,
        "fisheye"
    );
    let in_file_world = file.cameras[0].r.unwrap();
    // The world before the applied transform: COLMAP's, whose cameras the COLMAP importer reads.
    let r = import(
        &["nerfstudio", "--force", "--before-applied-transform"],
        &input,
        &out,
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let file = SceneFile::parse(&out, &std::fs::read_to_string(&out).unwrap()).unwrap();
    let colmap = dir.path().join("colmap.json");
    let r = import(&["colmap"], &fixtures().join("colmap/text"), &colmap);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let from_colmap =
        SceneFile::parse(&colmap, &std::fs::read_to_string(&colmap).unwrap()).unwrap();
    let r0 = file.cameras[0].r.unwrap();
    let c0 = from_colmap.cameras[0].r.unwrap();
    for i in 0..3 {
        for j in 0..3 {
            assert!((r0[i][j] - c0[i][j]).abs() < 1e-12, "{r0:?} against {c0:?}");
        }
    }
    assert!(
        (in_file_world[0][1] - r0[0][1]).abs() > 0.1,
        "the worlds differ"
    );
    // The option belongs to nerfstudio files only; a NeRF synthetic file needs the image size.
    let r = import(
        &["opencv", "--force", "--before-applied-transform"],
        &fixtures().join("opencv/stereo.yml"),
        &out,
    );
    assert!(!r.status.success());
    let synthetic = fixtures().join("nerfstudio/transforms_train.json");
    let r = import(&["nerfstudio", "--force"], &synthetic, &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("--size"), "{err}");
    let r = import(
        &["nerfstudio", "--force", "--size", "800x800"],
        &synthetic,
        &out,
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let file = SceneFile::parse(&out, &std::fs::read_to_string(&out).unwrap()).unwrap();
    let names: Vec<&str> = file.cameras.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["r_0", "r_1"]);
    assert_eq!(file.cameras[0].images, "images/r_0/{frame:04}.png");
}

/// caliscope's `camera_array.toml` (the real board sample's) becomes a scene of its four cameras
/// with their lenses, each camera's recording named as caliscope names it; the format is found by
/// any of the tools' names.
#[test]
fn a_caliscope_camera_array_becomes_a_scene_under_any_of_the_tools_names() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixtures().join("caliscope-board-sample/camera_array.toml");
    for (i, format) in ["caliscope", "toml", "anipose", "auto"].iter().enumerate() {
        let out = dir.path().join(format!("scene{i}.json"));
        let r = import(
            &[
                format,
                "--images",
                "recording/{camera}.mp4",
                "--frames",
                "0..19",
                "--units",
                "m",
            ],
            &input,
            &out,
        );
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "{format}: {err}");
        assert!(err.contains("caliscope") && err.contains("metres"), "{err}");
        let file = SceneFile::parse(&out, &std::fs::read_to_string(&out).unwrap()).unwrap();
        let names: Vec<&str> = file.cameras.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["cam_0", "cam_1", "cam_2", "cam_3"]);
        assert_eq!(file.cameras[3].images, "recording/cam_3.mp4");
        let d = file.cameras[0].distortion.as_ref().unwrap();
        assert_eq!(
            (d.model.as_str(), d.coefficients[0]),
            ("opencv", -0.3320992998866297)
        );
    }
}

/// `import auto` reads each fixture as the format it is, and names the formats when it cannot tell.
#[test]
fn auto_tells_the_formats_apart_and_says_when_it_cannot() {
    let dir = tempfile::tempdir().unwrap();
    for (i, (input, format, cameras)) in [
        ("colmap/bin", "colmap", 7),
        ("opencv/rig.yml", "opencv", 3),
        ("metashape/cameras.xml", "metashape", 2),
        ("kalibr/camchain.yaml", "kalibr", 3),
        ("mrcal", "mrcal", 3),
        ("anipose/calibration.toml", "toml", 3),
        ("alembic/cameras.abc", "alembic", 4),
        ("usd/cameras.usda", "usd", 5),
        ("alicevision/cameras.sfm", "alicevision", 6),
        ("alicevision/legacy.sfm", "alicevision", 2),
    ]
    .into_iter()
    .enumerate()
    {
        let out = dir.path().join(format!("scene{i}.json"));
        let r = import(&["auto"], &fixtures().join(input), &out);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "{input}: {err}");
        assert!(
            err.contains(&format!("read as the {format} format")),
            "{input}: {err}"
        );
        let file = SceneFile::parse(&out, &std::fs::read_to_string(&out).unwrap()).unwrap();
        assert_eq!(file.cameras.len(), cameras, "{input}");
    }
    let out = dir.path().join("none.json");
    let r = import(&["auto"], &fixtures().join("README.md"), &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && !out.exists());
    assert!(
        err.contains("README.md") && err.contains("name it (colmap"),
        "{err}"
    );
}

/// Blender's Alembic cameras become a scene whose cameras (one of them moving: a pose per frame)
/// put known points where Blender renders them (fixtures/alembic, tools/make_alembic_fixture.py).
#[test]
fn alembic_cameras_from_blender_become_a_scene_that_projects_as_blender() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.json");
    let input = fixtures().join("alembic/cameras.abc");
    let r = import(&["alembic", "--frames", "1..5"], &input, &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("moving: a pose per frame at 24 fps"), "{err}");
    assert!(err.contains("Y up") && err.contains("\"side\""), "{err}");
    projects_as(&out, "alembic/expected.json", &["moving"]);
}

/// A USD stage's cameras (written by Pixar's library: transform operations, time samples,
/// render settings) become a scene whose cameras put known points where Pixar's camera model
/// does (fixtures/usd, tools/make_usd_fixture.py); each camera's image size from its render
/// settings.
#[test]
fn usd_cameras_become_a_scene_that_projects_as_pixars_camera_model() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.json");
    let input = fixtures().join("usd/cameras.usda");
    let r = import(&["usd", "--frames", "1..5"], &input, &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("moving: a pose per frame"), "{err}");
    assert!(err.contains("conformed by `cropAperture`"), "{err}");
    projects_as(&out, "usd/cameras-expected.json", &["moving", "tumble"]);
    // The stage's metersPerUnit = 1 is the scene's unit, unless --units says otherwise.
    let units = |out: &std::path::Path| {
        SceneFile::parse(out, &std::fs::read_to_string(out).unwrap())
            .unwrap()
            .units
    };
    assert_eq!(units(&out), Some(modelflow::base::Units::Metres));
    let cm = dir.path().join("cm.json");
    let r = import(&["usd", "--frames", "1..5", "--units", "cm"], &input, &cm);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("the file says its unit is m, --units says cm"),
        "{err}"
    );
    assert_eq!(units(&cm), Some(modelflow::base::Units::Centimetres));
    // Blender's USD export gives no image size: refused until --size gives it.
    let input = fixtures().join("usd/blender.usda");
    let out = dir.path().join("blender.json");
    let r = import(&["usd", "--frames", "1..5"], &input, &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && !out.exists());
    assert!(
        err.contains("blender.usda") && err.contains("--size WxH"),
        "{err}"
    );
    let r = import(
        &["usd", "--frames", "1..5", "--size", "1280x720"],
        &input,
        &out,
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    projects_as(&out, "usd/blender-expected.json", &["moving"]);
}

/// The scene file `out`'s cameras put the points of the fixture `expected` (points, and views of
/// camera, frame and pixels) where the package that wrote it does, to a thousandth of a pixel;
/// the cameras `moving` with a pose per frame, the others still.
fn projects_as(out: &std::path::Path, expected: &str, moving: &[&str]) {
    let file = SceneFile::parse(out, &std::fs::read_to_string(out).unwrap()).unwrap();
    let cameras = file.cameras_of(out).unwrap();
    let want: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixtures().join(expected)).unwrap()).unwrap();
    let points: Vec<nalgebra::Point3<f64>> = want["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            nalgebra::Point3::new(
                p[0].as_f64().unwrap(),
                p[1].as_f64().unwrap(),
                p[2].as_f64().unwrap(),
            )
        })
        .collect();
    for view in want["views"].as_array().unwrap() {
        let name = view["camera"].as_str().unwrap();
        let frame = view["frame"].as_u64().unwrap() as u32;
        let cam = cameras.iter().find(|c| c.name == name).unwrap();
        assert_eq!(cam.is_moving(), moving.contains(&name), "{name}");
        for (p, px) in points.iter().zip(view["pixels"].as_array().unwrap()) {
            let got = cam.at(frame).project(p).unwrap();
            let e = (got.x - px[0].as_f64().unwrap()).hypot(got.y - px[1].as_f64().unwrap());
            assert!(e < 1e-3, "{name} frame {frame}: {e} px from {expected}");
        }
    }
}

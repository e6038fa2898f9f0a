//! Scene loading: a good synthetic scene loads; every kind of bad input gives an error that
//! names the file and the field at fault (and never panics).

mod common;

use common::*;
use modelflow::input::write_png;
use modelflow::input::{FramePattern, PoseEntry, Scene, SceneFile};
use nalgebra::Point3;
use std::path::Path;

fn load_err(path: &Path) -> String {
    match Scene::load(path) {
        Ok(_) => panic!("{} loaded but should not", path.display()),
        Err(e) => e.to_string(),
    }
}

/// Writes the synthetic scene, lets `edit` change the scene file, and returns the load error.
fn broken(edit: impl FnOnce(&mut SceneFile, &Path)) -> String {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    edit(&mut file, dir.path());
    file.write(&path).unwrap();
    load_err(&path)
}

fn assert_names(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "{msg:?} should mention {p:?}");
    }
}

#[test]
fn synthetic_scene_loads_with_images_and_truth() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.frames(), 0..=FRAMES - 1);
    assert_eq!(scene.mesh, mesh());
    assert_eq!(scene.cameras.len(), 2);
    assert_eq!(scene.cameras[1].name, "cam1");
    let imgs = scene.load_images(1).unwrap();
    assert_eq!(imgs.len(), 2);
    assert_eq!(imgs[0].width(), W as usize);
    // 8-bit round trip: x/64 quantised to 1/255 steps.
    assert!((imgs[1].get(32, 0)[0] - 0.5).abs() <= 0.5 / 255.0 + 1e-6);
    let gt = scene.ground_truth(2).unwrap().unwrap();
    assert_eq!(gt, truth(2));
    assert!(scene.load_images(FRAMES).is_err(), "frame out of range");
}

#[test]
fn frame_pattern_pads_to_any_width() {
    let p = FramePattern::new("/s", "a/{frame:04}.png").unwrap();
    assert_eq!(p.path(7), Path::new("/s/a/0007.png"));
    assert_eq!(p.path(123456), Path::new("/s/a/123456.png"));
    let p = FramePattern::new("/s", "f{frame}_{frame:012}.exr").unwrap();
    assert_eq!(p.path(42), Path::new("/s/f42_000000000042.exr"));
    assert!(FramePattern::new("/s", "a.png").is_err());
    assert!(FramePattern::new("/s", "{frame:4}.png").is_err());
    assert!(FramePattern::new("/s", "{frame.png").is_err());
    assert!(FramePattern::new("/s", "{frames}.png").is_err());
}

#[test]
fn scene_file_write_reads_back_equal() {
    let dir = tempfile::tempdir().unwrap();
    let (path, file) = write_scene(dir.path());
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(SceneFile::parse(&path, &text).unwrap(), file);
    assert!(text.contains("\n  \"frames\""), "pretty-printed");
}

#[test]
fn scene_file_write_refuses_non_finite_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    let before = std::fs::read(&path).unwrap();
    file.cameras[1].t.as_mut().unwrap()[0] = f64::NAN;
    let msg = file.write(&path).unwrap_err().to_string();
    assert_names(&msg, &["scene.json", "cameras[1].t", "non-finite"]);
    assert_eq!(
        std::fs::read(&path).unwrap(),
        before,
        "the old file is kept"
    );
}

#[test]
fn bad_json_names_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, text.replacen("\"mesh\":", "\"mesh\" ", 1)).unwrap();
    let msg = load_err(&path);
    assert_names(&msg, &["scene.json", "line 7 column", "invalid JSON"]);
}

#[test]
fn wrong_format_tag() {
    let msg = broken(|f, _| f.format = "modelflow-scene/2".into());
    assert_names(
        &msg,
        &[
            "scene.json",
            "format",
            "modelflow-scene/2",
            "modelflow-scene/1",
        ],
    );
}

#[test]
fn unknown_field_and_wrong_type_name_the_camera() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, text.replacen("\"width\": 64", "\"widht\": 64", 2)).unwrap();
    assert_names(&load_err(&path), &["scene.json", "cameras[0]", "widht"]);
    std::fs::write(&path, text.replace("\"height\": 48", "\"height\": \"48\"")).unwrap();
    assert_names(
        &load_err(&path),
        &["scene.json", "cameras[0]", "invalid type"],
    );
}

#[test]
fn frames_out_of_order() {
    let msg = broken(|f, _| {
        f.frames.first = 2;
        f.frames.last = 1;
    });
    assert_names(
        &msg,
        &["scene.json", "frames", "first (2) is after last (1)"],
    );
}

#[test]
fn frames_beyond_the_images() {
    let msg = broken(|f, _| f.frames.last = FRAMES);
    assert_names(
        &msg,
        &[
            "scene.json",
            "cameras[0].images",
            "frame 3",
            "not found",
            "0003.png",
        ],
    );
}

#[test]
fn missing_image() {
    let msg = broken(|_, d| std::fs::remove_file(d.join("images/cam1/0001.png")).unwrap());
    assert_names(
        &msg,
        &[
            "scene.json",
            "cameras[1].images",
            "frame 1",
            "images/cam1/0001.png",
        ],
    );
}

#[test]
fn wrong_image_size() {
    let msg = broken(|_, d| {
        let small = modelflow::base::RgbImage::new(32, 48);
        write_png(&d.join("images/cam0/0002.png"), &small).unwrap();
    });
    assert_names(
        &msg,
        &[
            "scene.json",
            "cameras[0].images",
            "frame 2",
            "32x48",
            "64x48",
        ],
    );
}

#[test]
fn wrong_image_size_at_load_images() {
    // The header check at load time passes; the file is replaced afterwards.
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    write_png(
        &dir.path().join("images/cam1/0000.png"),
        &modelflow::base::RgbImage::new(10, 10),
    )
    .unwrap();
    let msg = scene.load_images(0).unwrap_err().to_string();
    assert_names(&msg, &["images/cam1/0000.png", "size", "10x10", "cam1"]);
}

#[test]
fn image_pattern_without_frame() {
    let msg = broken(|f, _| f.cameras[1].images = "images/cam1/still.png".into());
    assert_names(&msg, &["scene.json", "cameras[1].images", "{frame}"]);
}

/// Validates an edited scene file in memory (JSON itself cannot hold NaN or infinity).
fn broken_in_memory(edit: impl FnOnce(&mut SceneFile)) -> String {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    edit(&mut file);
    match Scene::from_file(&path, &file) {
        Ok(_) => panic!("should not validate"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn non_finite_k() {
    let msg = broken_in_memory(|f| f.cameras[0].k.as_mut().unwrap()[0][2] = f64::NAN);
    assert_names(&msg, &["scene.json", "cameras[0].K", "non-finite"]);
    // In the file, an overflowing literal is caught by the JSON reader, with its position.
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, text.replacen("60.0", "1e999", 1)).unwrap();
    assert_names(
        &load_err(&path),
        &["scene.json", "line 15 column", "numbers must be finite"],
    );
}

#[test]
fn singular_k() {
    let msg = broken(|f, _| f.cameras[1].k.as_mut().unwrap()[1][1] = 0.0);
    assert_names(&msg, &["scene.json", "cameras[1].K", "singular", "fy = 0"]);
}

#[test]
fn k_not_upper_triangular() {
    let msg = broken(|f, _| f.cameras[0].k.as_mut().unwrap()[2] = [0.0, 0.1, 1.0]);
    assert_names(&msg, &["scene.json", "cameras[0].K", "[0, 0, 1]"]);
    let msg = broken(|f, _| f.cameras[0].k.as_mut().unwrap()[1][0] = 3.0);
    assert_names(&msg, &["scene.json", "cameras[0].K", "upper-triangular"]);
}

#[test]
fn r_not_a_rotation() {
    let msg = broken(|f, _| f.cameras[1].r.as_mut().unwrap()[0][0] += 0.2);
    assert_names(
        &msg,
        &["scene.json", "cameras[1].R", "not a rotation matrix"],
    );
    // A mirror is orthonormal but not a rotation.
    let msg = broken(|f, _| {
        let r = f.cameras[0].r.as_mut().unwrap();
        r[0] = r[0].map(|v| -v);
    });
    assert_names(&msg, &["scene.json", "cameras[0].R", "det R = -1"]);
}

#[test]
fn float32_rotation_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    for c in &mut file.cameras {
        let r = c.r.as_mut().unwrap();
        *r = r.map(|row| row.map(|v| v as f32 as f64));
    }
    file.write(&path).unwrap();
    Scene::load(&path).unwrap();
}

#[test]
fn non_finite_t() {
    let msg = broken_in_memory(|f| f.cameras[1].t.as_mut().unwrap()[2] = f64::INFINITY);
    assert_names(&msg, &["scene.json", "cameras[1].t", "non-finite"]);
}

#[test]
fn non_finite_r_and_p() {
    let msg = broken_in_memory(|f| f.cameras[1].r.as_mut().unwrap()[1][1] = f64::NAN);
    assert_names(&msg, &["scene.json", "cameras[1].R", "non-finite"]);
    let msg = broken_in_memory(|f| {
        to_p(f, 0, 3);
        f.cameras[0].p.as_mut().unwrap()[2][0][3] = f64::NAN;
    });
    assert_names(&msg, &["scene.json", "cameras[0].P[2]", "non-finite"]);
}

#[test]
fn duplicate_camera_name() {
    let msg = broken(|f, _| f.cameras[1].name = "cam0".into());
    assert_names(
        &msg,
        &["scene.json", "cameras[1].name", "\"cam0\"", "unique"],
    );
}

#[test]
fn zero_width() {
    let msg = broken(|f, _| f.cameras[0].width = 0);
    assert_names(&msg, &["scene.json", "cameras[0].width", "positive"]);
}

#[test]
fn pose_forms_are_exclusive() {
    let msg = broken(|f, _| {
        let c = &f.cameras[0];
        let p = vec![
            [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 2.0]
            ];
            3
        ];
        f.cameras[0] = modelflow::input::CameraEntry {
            p: Some(p),
            ..c.clone()
        };
    });
    assert_names(&msg, &["scene.json", "cameras[0].P", "exactly one of"]);
    let msg = broken(|f, _| f.cameras[1].k = None);
    assert_names(&msg, &["scene.json", "cameras[1].K", "missing"]);
    let msg = broken(|f, _| f.cameras[1].t = None);
    assert_names(&msg, &["scene.json", "cameras[1].t", "missing"]);
    let msg = broken(|f, _| {
        let c = &mut f.cameras[1];
        c.poses = Some(vec![PoseEntry {
            frame: 0,
            r: c.r.unwrap(),
            t: c.t.unwrap(),
        }]);
    });
    assert_names(&msg, &["scene.json", "cameras[1].poses", "not both"]);
}

fn to_poses(f: &mut SceneFile, cam: usize, frames: &[u32]) {
    let c = &mut f.cameras[cam];
    let (r, t) = (c.r.take().unwrap(), c.t.take().unwrap());
    c.poses = Some(
        frames
            .iter()
            .map(|&frame| PoseEntry { frame, r, t })
            .collect(),
    );
}

#[test]
fn moving_camera_poses() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    to_poses(&mut file, 1, &[2, 0, 1]);
    file.write(&path).unwrap();
    let scene = Scene::load(&path).unwrap();
    assert!(scene.cameras[1].is_moving());
    assert_eq!(scene.cameras[1].at(2), scene.cameras[1].at(0));

    let msg = broken(|f, _| to_poses(f, 1, &[0, 1]));
    assert_names(
        &msg,
        &["scene.json", "cameras[1].poses", "no pose for frame(s) 2"],
    );
    let msg = broken(|f, _| to_poses(f, 0, &[0, 1, 1, 2]));
    assert_names(
        &msg,
        &[
            "scene.json",
            "cameras[0].poses[2].frame",
            "more than one pose",
        ],
    );
    let msg = broken(|f, _| to_poses(f, 0, &[0, 1, 2, 7]));
    assert_names(
        &msg,
        &["scene.json", "cameras[0].poses[3].frame", "frame 7 outside"],
    );
    let msg = broken(|f, _| {
        to_poses(f, 0, &[0, 1, 2]);
        f.cameras[0].poses.as_mut().unwrap()[1].r[2][2] = 5.0;
    });
    assert_names(
        &msg,
        &["scene.json", "cameras[0].poses[1].R", "not a rotation"],
    );
}

fn to_p(f: &mut SceneFile, cam: usize, n: usize) {
    let c = &mut f.cameras[cam];
    let (k, r, t) = (
        c.k.take().unwrap(),
        c.r.take().unwrap(),
        c.t.take().unwrap(),
    );
    let mut p = [[0.0; 4]; 3];
    for i in 0..3 {
        for j in 0..4 {
            p[i][j] = (0..3)
                .map(|m| k[i][m] * if j < 3 { r[m][j] } else { t[m] })
                .sum();
        }
    }
    c.p = Some(vec![p; n]);
}

#[test]
fn projection_matrices_per_frame() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    let krt = Scene::load(&path).unwrap();
    to_p(&mut file, 0, FRAMES as usize);
    file.write(&path).unwrap();
    let scene = Scene::load(&path).unwrap();
    let x = Point3::new(0.2, -0.1, 0.05);
    let a = krt.cameras[0].at(1).project(&x).unwrap();
    let b = scene.cameras[0].at(1).project(&x).unwrap();
    assert!((a - b).norm() < 1e-9, "{a} vs {b}");

    let msg = broken(|f, _| to_p(f, 0, 2));
    assert_names(
        &msg,
        &[
            "scene.json",
            "cameras[0].P",
            "one matrix per frame",
            "found 2",
        ],
    );
    let msg = broken(|f, _| {
        to_p(f, 1, 3);
        f.cameras[1].p.as_mut().unwrap()[1] = [
            [1.0, 2.0, 3.0, 0.0],
            [2.0, 4.0, 6.0, 0.0],
            [0.0, 0.0, 1.0, 1.0],
        ];
    });
    assert_names(&msg, &["scene.json", "cameras[1].P[1]", "singular"]);
}

#[test]
fn missing_mesh_file() {
    let msg = broken(|f, _| f.mesh = "mesh/nope.obj".into());
    assert_names(&msg, &["scene.json", "mesh", "not found", "mesh/nope.obj"]);
}

#[test]
fn mesh_index_out_of_range() {
    let msg = broken(|_, d| {
        let p = d.join("mesh/initial.obj");
        let mut text = std::fs::read_to_string(&p).unwrap();
        text.push_str("f 1 2 99\n");
        std::fs::write(&p, text).unwrap();
    });
    // Header line + 25 v + 25 vt + 32 f lines, then the bad face.
    assert_names(&msg, &["initial.obj", "line 84", "99", "out of range"]);
}

#[test]
fn mesh_degenerate_triangle() {
    let msg = broken(|_, d| {
        let p = d.join("mesh/initial.obj");
        let mut text = std::fs::read_to_string(&p).unwrap();
        // Three collinear grid vertices (first row).
        text.push_str("f 1 2 3\n");
        std::fs::write(&p, text).unwrap();
    });
    assert_names(&msg, &["initial.obj", "line 84", "degenerate", "zero area"]);
}

#[test]
fn ground_truth_missing_and_mismatched() {
    let msg = broken(|_, d| std::fs::remove_file(d.join("truth/0002.obj")).unwrap());
    assert_names(
        &msg,
        &["scene.json", "ground_truth", "frame 2", "truth/0002.obj"],
    );

    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    let small = modelflow::base::grid(2, 2, |u, v| Point3::new(u, v, 0.0));
    modelflow::input::write_obj(&dir.path().join("truth/0001.obj"), &small).unwrap();
    let msg = scene.ground_truth(1).unwrap().unwrap_err().to_string();
    assert_names(&msg, &["truth/0001.obj", "4 vertices", "25"]);
}

#[test]
fn mesh_seen_by_fewer_than_two_cameras() {
    // cam1 turned around: it looks away from the mesh.
    let msg = broken(|f, _| {
        let eye = Point3::new(0.4, 0.3, 2.0);
        let (r, t) =
            modelflow::base::look_at(&eye, &Point3::new(0.8, 0.6, 4.0), &nalgebra::Vector3::y());
        f.cameras[1].r = Some([0, 1, 2].map(|i| [0, 1, 2].map(|j| r[(i, j)])));
        f.cameras[1].t = Some([t.x, t.y, t.z]);
    });
    assert_names(
        &msg,
        &[
            "scene.json",
            "cameras",
            "fewer than two cameras",
            "cam0 sees 100%",
            "cam1 sees 0%",
        ],
    );
}

#[test]
fn missing_scene_file() {
    let msg = load_err(Path::new("/nonexistent/scene.json"));
    assert_names(&msg, &["/nonexistent/scene.json"]);
}

/// Cutting the scene file anywhere, or flipping one byte, gives an error or a scene, never a
/// panic. (One scene on disk; each case rewrites only scene.json.)
#[test]
fn damaged_scene_file_never_panics() {
    use proptest::prelude::*;
    use proptest::test_runner::{Config, TestRunner};
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let good = std::fs::read(&path).unwrap();
    let mut runner = TestRunner::new(Config {
        cases: 256,
        ..Config::default()
    });
    runner
        .run(
            &(0usize..4000, 0usize..4000, any::<u8>()),
            |(cut, pos, byte)| {
                let mut text = good.clone();
                let p = pos % text.len();
                text[p] = byte;
                text.truncate(cut.min(text.len()));
                std::fs::write(&path, &text).unwrap();
                let _ = Scene::load(&path);
                Ok(())
            },
        )
        .unwrap();
}

#[test]
fn huge_frame_range_fails_fast_without_allocating_it() {
    let t = std::time::Instant::now();
    let msg = broken(|f, _| f.frames.last = u32::MAX);
    assert_names(
        &msg,
        &["scene.json", "cameras[0].images", "frame 3", "not found"],
    );
    let msg = broken(|f, _| {
        to_poses(f, 1, &[0, 1, 2]);
        f.frames.last = u32::MAX;
    });
    assert_names(
        &msg,
        &[
            "scene.json",
            "cameras[1].poses",
            "no pose for frame(s) 3, 4",
        ],
    );
    assert!(t.elapsed().as_secs_f64() < 5.0, "{:?}", t.elapsed());
}

#[test]
fn scene_with_ply_mesh_exr_and_tiff_images() {
    use image::{DynamicImage, ImageBuffer, ImageFormat, Rgb};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (path, mut file) = write_scene(d);
    // The same mesh as binary PLY.
    let m = mesh();
    let mut ply = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    )
    .into_bytes();
    for p in &m.positions {
        for c in [p.x, p.y, p.z] {
            ply.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &m.triangles {
        ply.push(3);
        for i in t {
            ply.extend_from_slice(&i.to_le_bytes());
        }
    }
    std::fs::write(d.join("mesh/initial.ply"), ply).unwrap();
    file.mesh = "mesh/initial.ply".into();
    // cam0: float EXR with values above 1; cam1: 16-bit TIFF.
    for f in 0..FRAMES {
        let hdr = ImageBuffer::from_fn(W, H, |x, _| Rgb([x as f32 * 0.05, 2.5, f as f32]));
        DynamicImage::ImageRgb32F(hdr)
            .save_with_format(d.join(format!("images/cam0/{f}.exr")), ImageFormat::OpenExr)
            .unwrap();
        let t16 = ImageBuffer::from_fn(W, H, |_, y| Rgb([y as u16 * 1000, 65535, 0]));
        DynamicImage::ImageRgb16(t16)
            .save_with_format(d.join(format!("images/cam1/{f:03}.tif")), ImageFormat::Tiff)
            .unwrap();
    }
    file.cameras[0].images = "images/cam0/{frame}.exr".into();
    file.cameras[1].images = "images/cam1/{frame:03}.tif".into();
    file.write(&path).unwrap();
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.mesh.positions, m.positions);
    assert_eq!(scene.mesh.triangles, m.triangles);
    let imgs = scene.load_images(2).unwrap();
    // The EXR's values are scene-linear (`"transfer": "auto"`): encoded with the sRGB curve;
    // the TIFF's integers are kept as stored.
    let srgb = modelflow::input::transfer::srgb_encode;
    assert_eq!(imgs[0].get(10, 3), [srgb(0.5), srgb(2.5), srgb(2.0)]);
    assert!((imgs[0].get(10, 3)[0] - 0.735_357).abs() < 1e-5);
    assert_eq!(imgs[1].get(10, 3), [3000.0 / 65535.0, 1.0, 0.0]);

    // Said otherwise in the scene: the EXR as stored, the TIFF's values taken as linear.
    use modelflow::input::transfer::Transfer;
    file.cameras[0].transfer = Transfer::Encoded;
    file.cameras[1].transfer = Transfer::Linear;
    file.write(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\"transfer\": \"encoded\""), "{text}");
    let imgs = Scene::load(&path).unwrap().load_images(2).unwrap();
    assert_eq!(imgs[0].get(10, 3), [0.5, 2.5, 2.0]);
    assert_eq!(imgs[1].get(10, 3), [srgb(3000.0 / 65535.0), srgb(1.0), 0.0]);

    // An unknown value names the camera, the field and the choices.
    let bad = text.replace("\"transfer\": \"encoded\"", "\"transfer\": \"log\"");
    std::fs::write(&path, bad).unwrap();
    let msg = load_err(&path);
    assert_names(
        &msg,
        &["scene.json", "cameras[0]", "auto", "linear", "encoded"],
    );
}

#[test]
fn frame_offset_reads_a_later_file_for_each_frame() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    // cam1 started 2 frames early: its file number f + 2 shows scene frame f. Files 2..=4 are
    // a distinct image each (the red channel holds the file number).
    for n in 0..FRAMES + 2 {
        let img = modelflow::RgbImage::from_fn(W as usize, H as usize, |_, _| {
            [n as f32 / 10.0, 0.0, 0.0]
        });
        write_png(&dir.path().join(format!("images/cam1/{n:04}.png")), &img).unwrap();
    }
    file.cameras[1].frame_offset = 2;
    file.write(&path).unwrap();
    let scene = Scene::load(&path).unwrap();
    for f in 0..FRAMES {
        let red = scene.load_images(f).unwrap()[1].get(3, 3)[0];
        assert!(
            (red - (f + 2) as f32 / 10.0).abs() < 0.003,
            "frame {f}: {red}"
        );
    }
    // Reading past the last file is the usual missing-image error, naming the file.
    std::fs::remove_file(
        dir.path()
            .join(format!("images/cam1/{:04}.png", FRAMES + 1)),
    )
    .unwrap();
    assert_names(
        &load_err(&path),
        &["cameras[1].images", "0004.png", "image not found"],
    );
    // A negative offset that reaches before file 0 is refused with its field.
    file.cameras[1].frame_offset = -1;
    file.write(&path).unwrap();
    assert_names(
        &load_err(&path),
        &["cameras[1].frame_offset", "file number -1 for frame 0"],
    );
}

#[test]
fn time_offset_is_read_written_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    // cam1 records each frame a quarter of a frame late (a rig that is not genlocked).
    file.cameras[1].time_offset = 0.25;
    file.write(&path).unwrap();
    assert!(std::fs::read_to_string(&path)
        .unwrap()
        .contains("\"time_offset\": 0.25"));
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.cameras[0].time_offset, 0.0);
    assert_eq!(scene.cameras[1].time_offset, 0.25);
    // On time is the default and is not written.
    file.cameras[1].time_offset = 0.0;
    file.write(&path).unwrap();
    assert!(!std::fs::read_to_string(&path)
        .unwrap()
        .contains("time_offset"));
    for bad in [1.5, -2.0, f64::NAN] {
        let msg = broken_in_memory(|f| f.cameras[1].time_offset = bad);
        assert_names(&msg, &["cameras[1].time_offset", "-1 to 1 frame"]);
    }
}

#[test]
fn shutter_is_read_written_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    // cam0's shutter stays open half of each frame (a 180° shutter).
    file.cameras[0].shutter = 0.5;
    file.write(&path).unwrap();
    assert!(std::fs::read_to_string(&path)
        .unwrap()
        .contains("\"shutter\": 0.5"));
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.cameras[0].shutter, 0.5);
    assert_eq!(scene.cameras[1].shutter, 0.0);
    // Sharp (0) is the default and is not written.
    file.cameras[0].shutter = 0.0;
    file.write(&path).unwrap();
    assert!(!std::fs::read_to_string(&path).unwrap().contains("shutter"));
    for bad in [1.5, -0.1, f64::NAN] {
        let msg = broken_in_memory(|f| f.cameras[0].shutter = bad);
        assert_names(&msg, &["cameras[0].shutter", "from 0 to 1", "180°"]);
    }
}

#[test]
fn a_rolling_shutter_is_read_written_checked_and_puts_each_row_at_its_instant() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    // cam0 reads its rows over 0.6 frame (20 ms at 30 fps) and records 0.1 frame late.
    file.cameras[0].rolling_shutter = 0.6;
    file.cameras[0].time_offset = 0.1;
    file.write(&path).unwrap();
    assert!(std::fs::read_to_string(&path)
        .unwrap()
        .contains("\"rolling_shutter\": 0.6"));
    let scene = Scene::load(&path).unwrap();
    let (cam, other) = (&scene.cameras[0], &scene.cameras[1]);
    assert_eq!((cam.rolling_shutter, other.rolling_shutter), (0.6, 0.0));
    // Row y (pixel centres at integers) of h is read at time_offset + rs·((y + 0.5)/h − 1/2):
    // the middle of the frame at the camera's own time, the top row's centre half a row after
    // the readout starts, the bottom row's half a row before it ends.
    let h = cam.height as f64;
    let at = |y: f64| cam.lag_at_row(y);
    assert!((at(h / 2.0 - 0.5) - 0.1).abs() < 1e-15);
    assert!((at(0.0) - (0.1 - 0.3 + 0.6 * 0.5 / h)).abs() < 1e-15);
    assert!((at(h - 1.0) - (0.1 + 0.3 - 0.6 * 0.5 / h)).abs() < 1e-15);
    // A global-shutter camera reads every row at its time_offset.
    assert_eq!(other.lag_at_row(0.0), other.time_offset);
    // Per vertex: the row each projects to.
    let x = scene.mesh.positions[0];
    let row = cam.project_raw(scene.first, &x).unwrap().y;
    assert_eq!(cam.lags(scene.first, &[x]), vec![cam.lag_at_row(row)]);
    assert!(other.lags(scene.first, &[x]).is_empty(), "on time: no lags");
    // A global shutter (0) is the default and is not written.
    file.cameras[0].rolling_shutter = 0.0;
    file.write(&path).unwrap();
    assert!(!std::fs::read_to_string(&path)
        .unwrap()
        .contains("rolling_shutter"));
    for bad in [1.5, -0.1, f64::NAN] {
        let msg = broken_in_memory(|f| f.cameras[0].rolling_shutter = bad);
        assert_names(
            &msg,
            &["cameras[0].rolling_shutter", "from 0 to 1", "top row"],
        );
    }
}

#[test]
fn a_shorter_range_other_cameras_or_another_mesh_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    let part = scene.with_frames(1, 2).unwrap();
    assert_eq!(
        (part.first, part.last, part.mesh.clone()),
        (1, 2, scene.mesh.clone())
    );
    assert!(scene
        .with_frames(1, FRAMES)
        .unwrap_err()
        .to_string()
        .contains("--frames"));
    let swapped = scene.with_cameras(&["cam1".into(), "cam0".into()]).unwrap();
    assert_eq!(swapped.cameras[0].name, "cam1");
    assert_eq!(swapped.images[0], scene.images[1]);
    let e = scene
        .with_cameras(&["cam0".into()])
        .unwrap_err()
        .to_string();
    assert!(e.contains("fewer than two cameras"), "{e}");
    // Another mesh must match the ground truth's vertex count.
    let small = dir.path().join("small.obj");
    std::fs::write(&small, "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n").unwrap();
    assert_names(
        &scene.with_mesh(&small).unwrap_err().to_string(),
        &["small.obj", "3 vertices", "ground truth"],
    );
}

#[test]
fn structural_errors_name_the_json_path_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let text = std::fs::read_to_string(&path).unwrap();
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    let with = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = value.clone();
        edit(&mut v);
        std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
        load_err(&path)
    };
    let e = with(&|v| v["cameras"][0]["K"] = serde_json::json!([[1, 0], [0, 1]]));
    assert_names(
        &e,
        &["scene.json", "cameras[0].K[0] (line ", "invalid length 2"],
    );
    let e = with(&|v| v["cameras"][0]["t"] = serde_json::json!([1, 2]));
    assert_names(&e, &["cameras[0].t (line ", "invalid length 2"]);
    let e = with(&|v| v["cameras"][1]["width"] = serde_json::json!(-640));
    assert_names(&e, &["cameras[1].width (line ", "-640"]);
    let e = with(&|v| v["frames"]["last"] = serde_json::json!("2"));
    assert_names(&e, &["frames.last (line ", "invalid type"]);
}

#[test]
fn paths_that_are_not_regular_files_say_what_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    // The scene "file" is a folder.
    assert_names(
        &load_err(dir.path()),
        &["scene file", "is a folder, not a regular file"],
    );
    // An image that is a folder.
    let img = dir.path().join("images/cam1/0001.png");
    std::fs::remove_file(&img).unwrap();
    std::fs::create_dir(&img).unwrap();
    assert_names(
        &load_err(&path),
        &[
            "cameras[1].images",
            "frame 1",
            "0001.png is a folder, not an image file",
        ],
    );
    // A FIFO would block a reader forever.
    #[cfg(unix)]
    {
        let fifo = dir.path().join("fifo.json");
        let ok = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            assert_names(&load_err(&fifo), &["fifo.json", "is a FIFO"]);
        }
    }
}

#[test]
fn a_frame_offset_beyond_any_frame_number_is_refused_not_wrapped() {
    let msg = broken(|f, _| f.cameras[1].frame_offset = i64::MAX);
    assert_names(
        &msg,
        &["cameras[1].frame_offset", "beyond any frame number"],
    );
}

#[test]
fn a_value_of_the_wrong_kind_names_its_field_not_the_json_syntax() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let text = std::fs::read_to_string(&path).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["units"] = serde_json::json!(1);
    std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let msg = load_err(&path);
    assert_names(&msg, &["units", "wrong kind"]);
    assert!(!msg.contains("invalid JSON"), "{msg}");
    // An object where a struct is expected is said as JSON, not as a Rust type name.
    v["units"] = serde_json::json!("mm");
    v["cameras"][0]["distortion"] = serde_json::json!(1);
    std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let msg = load_err(&path);
    assert_names(&msg, &["cameras[0].distortion", "a JSON object"]);
    assert!(!msg.contains("struct "), "{msg}");
}

#[test]
fn a_byte_order_mark_before_the_scene_file_is_read_past() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, format!("\u{feff}{text}")).unwrap();
    assert_eq!(Scene::load(&path).unwrap().mesh, mesh());
}

#[test]
fn a_mesh_path_that_is_a_folder_is_named_as_one() {
    let msg = broken(|f, dir| {
        std::fs::create_dir_all(dir.join("meshdir")).unwrap();
        f.mesh = "meshdir".into();
    });
    assert_names(&msg, &["mesh", "meshdir", "is a folder"]);
}

#[test]
fn a_camera_that_sees_none_of_the_mesh_is_named_with_why() {
    use modelflow::base::{Camera, Projection};
    use modelflow::input::{blind_cameras, Blind};
    use nalgebra::{Matrix3, Vector3};
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    assert!(scene.blind_cameras().is_empty(), "both cameras see it");
    let good = &scene.cameras[0];
    let (k, r, t) = good.at(0).krt();
    let camera = |name: &str, k: &Matrix3<f64>, r: &Matrix3<f64>, t: &Vector3<f64>| {
        Camera::fixed(name, W, H, Projection::from_krt(k, r, t).unwrap())
    };
    // The same pose in OpenGL's convention (looking down −z, y up): the mesh is behind it.
    let flip = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
    let gl = camera("gl", &k, &(flip * r), &(flip * t));
    // The principal point ten image widths off: in front, outside the image.
    let mut shifted = k;
    shifted[(0, 2)] += 10.0 * W as f64;
    let off = camera("off", &shifted, &r, &t);
    let cams = vec![good.clone(), gl, off, scene.cameras[1].clone()];
    let blind = blind_cameras(&cams, 0, &scene.mesh);
    assert_eq!(
        blind.iter().map(|b| b.index).collect::<Vec<_>>(),
        vec![1, 2]
    );
    assert_eq!(blind[0].why, Blind::Behind);
    assert_names(
        &blind[0].to_string(),
        &[
            "camera gl sees none of the mesh at frame 0: every vertex is behind it",
            "x = R·X + t",
            "negate the second and third rows of its R and entries of its t",
        ],
    );
    match blind[1].why {
        Blind::OutsideImage { centre: Some(c) } => {
            assert!(c.x > 9.0 * W as f64, "{c}");
        }
        ref other => panic!("{other:?}"),
    }
    assert_names(
        &blind[1].to_string(),
        &[
            "camera off sees none of the mesh at frame 0",
            "projects outside its 64×48 image",
            "Check its K",
        ],
    );
    // With two cameras, one of them turned the wrong way round, the scene is refused, and the
    // error says why that camera sees nothing.
    let e = broken(|file, _| {
        let c = &mut file.cameras[1];
        let (r, t) = (c.r.as_mut().unwrap(), c.t.as_mut().unwrap());
        for i in 1..3 {
            r[i] = r[i].map(|v| -v);
            t[i] = -t[i];
        }
    });
    assert_names(
        &e,
        &[
            "fewer than two cameras",
            "cam1 sees 0%",
            "camera cam1 sees none of the mesh at frame 0: every vertex is behind it",
        ],
    );
}

#[test]
fn a_mesh_in_another_unit_than_the_calibration_is_named() {
    use modelflow::input::mesh_out_of_scale;
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    // The 1 m sheet is about 50 px across in the 64×48 images: nothing to say.
    assert_eq!(scene.mesh_out_of_scale(), None);
    let m = mesh();
    let c = modelflow::base::centroid(&m.positions);
    let scaled = |f: f64| m.with_positions(m.positions.iter().map(|p| c + (p - c) * f).collect());
    // In millimetres' worth of metres: a twentieth of a pixel.
    let tiny = mesh_out_of_scale(&scene.cameras, 0, &scaled(1e-3)).unwrap();
    assert!(tiny.pixels < 0.1, "{tiny:?}");
    assert_names(
        &tiny.to_string(),
        &[
            "px across in the cameras' images at frame 0",
            "too small to track",
            "same unit",
        ],
    );
    // A thousand times too large: the cameras stand inside it.
    let huge = mesh_out_of_scale(&scene.cameras, 0, &scaled(1e3)).unwrap();
    assert!(huge.pixels > 10.0 * huge.image, "{huge:?}");
    assert_names(
        &huge.to_string(),
        &["times their size", "1000 times larger"],
    );
    // Such a mesh is seen by no camera, and the load error says why.
    let obj = dir.path().join("huge.obj");
    let mut text = String::new();
    for p in &scaled(1e3).positions {
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for t in &m.triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(&obj, text).unwrap();
    assert_names(
        &scene.with_mesh(&obj).unwrap_err().to_string(),
        &["fewer than two cameras", "times their size", "same unit"],
    );
}

#[test]
fn a_mesh_written_with_another_up_axis_out_of_view_is_named_with_the_swap() {
    use modelflow::base::AxisSwap;
    use modelflow::input::write_obj;
    use nalgebra::{Matrix3, Vector3};
    // The rig and the sheet moved 5 m down the world's z axis, and the sheet written Y-up
    // (as Blender's OBJ export does from a Z-up world): it lands behind both cameras.
    let shift = Vector3::new(0.0, 0.0, -5.0);
    let e = broken(|file, dir| {
        for c in &mut file.cameras {
            let r = Matrix3::from_fn(|i, j| c.r.unwrap()[i][j]);
            let t = Vector3::from(c.t.unwrap()) - r * shift;
            c.t = Some([t.x, t.y, t.z]);
        }
        let m = mesh();
        let written: Vec<_> = m
            .positions
            .iter()
            .map(|p| AxisSwap::ZUpToYUp.apply(&(p + shift)))
            .collect();
        write_obj(&dir.join("mesh/initial.obj"), &m.with_positions(written)).unwrap();
    });
    assert_names(
        &e,
        &[
            "fewer than two cameras",
            "with its axes turned from Y-up to Z-up, (x, y, z) → (x, −z, y)",
            "2 cameras would see it",
        ],
    );
}

#[test]
fn a_k_made_at_another_resolution_is_named_by_its_principal_point() {
    use modelflow::base::{Camera, Projection};
    use modelflow::input::off_centre_principal_points;
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    assert!(scene.off_centre_principal_points().is_empty());
    // cam0 calibrated on 96×72 stills (K scaled by 1.5) and filmed at 64×48.
    let (k, r, t) = scene.cameras[0].at(0).krt();
    let mut big = k * 1.5;
    big[(2, 2)] = 1.0;
    big[(0, 2)] = 47.5;
    big[(1, 2)] = 35.5;
    let cam = Camera::fixed("stills", W, H, Projection::from_krt(&big, &r, &t).unwrap());
    let off = off_centre_principal_points(&[scene.cameras[1].clone(), cam], 0);
    assert_eq!(off.len(), 1);
    assert_eq!(off[0].index, 1);
    assert!(
        (off[0].cx - 47.5).abs() < 1e-9 && (off[0].cy - 35.5).abs() < 1e-9,
        "{off:?}"
    );
    assert_names(
        &off[0].to_string(),
        &[
            "camera stills: its principal point (47.5, 35.5) lies 25 % of the width and 25 % of the height from the centre of its 64×48 image (31.5, 23.5)",
            "(cx, cy) is the centre of a 96×72 image: scale K's first two rows by 64/96",
        ],
    );
}

/// A camera's JPEGs with colour at half resolution (4:2:0, as webcams, phones and most encoders
/// write them) are loaded with their colour smoothed by [1 2 1]/4 and their luma as decoded
/// (docs/scene-format.md, "JPEG colour"); `read_rgb` gives the file as decoded.
#[test]
fn a_4_2_0_jpegs_colour_is_smoothed_at_load_and_its_luma_kept() {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/caliscope-board-sample/scene.json"
    ));
    let scene = Scene::load(path).unwrap();
    let loaded = scene.load_raw_images(scene.first).unwrap();
    let file = path
        .parent()
        .unwrap()
        .join(format!("images_undist/cam0/{:04}.jpg", scene.first));
    let decoded = modelflow::input::read_rgb(&file).unwrap();
    let mut smoothed = decoded.clone();
    smoothed.smooth_chroma(true, true);
    assert_eq!(loaded[0].pixels(), smoothed.pixels());
    let y = |p: &[f32; 3]| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
    let (mut luma, mut colour) = (0.0f32, 0.0f32);
    for (a, b) in loaded[0].pixels().iter().zip(decoded.pixels()) {
        luma = luma.max((y(a) - y(b)).abs());
        colour = colour.max((a[0] - b[0]).abs().max((a[2] - b[2]).abs()));
    }
    assert!(luma < 1e-5, "the luma moved by {luma}");
    assert!(colour > 0.01, "the colour was not smoothed ({colour})");
}

/// `bytes` (a JPEG) with an EXIF segment saying `orientation` (1–8) inserted after its
/// start-of-image marker, as a phone writes one: TIFF little-endian, one IFD entry (0x0112).
fn with_exif_orientation(bytes: &[u8], orientation: u8) -> Vec<u8> {
    let mut app1 = vec![0xFF, 0xE1, 0x00, 34];
    app1.extend(b"Exif\0\0");
    app1.extend([0x49, 0x49, 0x2A, 0x00, 0x08, 0x00, 0x00, 0x00]);
    app1.extend([0x01, 0x00]);
    app1.extend([
        0x12,
        0x01,
        0x03,
        0x00,
        0x01,
        0x00,
        0x00,
        0x00,
        orientation,
        0,
        0,
        0,
    ]);
    app1.extend([0x00; 4]);
    let mut out = bytes[..2].to_vec();
    out.extend(app1);
    out.extend(&bytes[2..]);
    out
}

/// JPEGs whose EXIF orientation asks viewers to turn them (a phone shot held upright): the
/// scene names the camera and the turn, and the pixels are read as stored.
#[test]
fn image_files_that_ask_to_be_shown_turned_are_named_and_read_as_stored() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    assert!(Scene::load(&path).unwrap().turned_images().is_empty());
    for f in file.frames.first..=file.frames.last {
        let png = dir.path().join(format!("images/cam1/{f:04}.png"));
        let img = modelflow::input::read_rgb(&png).unwrap();
        let jpg = dir.path().join(format!("images/cam1/{f:04}.jpg"));
        modelflow::input::write_jpeg(&jpg, &img, 95).unwrap();
        let bytes = std::fs::read(&jpg).unwrap();
        std::fs::write(&jpg, with_exif_orientation(&bytes, 3)).unwrap();
    }
    file.cameras[1].images = "images/cam1/{frame:04}.jpg".into();
    file.write(&path).unwrap();
    let scene = Scene::load(&path).unwrap();
    let turned = scene.turned_images();
    assert_eq!(turned.len(), 1, "{turned:?}");
    let msg = turned[0].to_string();
    assert_names(
        &msg,
        &["camera cam1", "0000.jpg", "turned 180°", "as stored"],
    );
    // Read as stored: the same pixels as the file without the EXIF segment.
    let stored = modelflow::input::read_rgb(&dir.path().join("images/cam1/0000.jpg")).unwrap();
    let plain = dir.path().join("plain.jpg");
    let bytes = std::fs::read(dir.path().join("images/cam1/0000.jpg")).unwrap();
    std::fs::write(&plain, [&bytes[..2], &bytes[2 + 36..]].concat()).unwrap();
    assert_eq!(
        stored.pixels(),
        modelflow::input::read_rgb(&plain).unwrap().pixels()
    );
    // The EXIF values are told apart.
    let base = [&bytes[..2], &bytes[2 + 36..]].concat();
    for (value, words) in [
        (1, None),
        (6, Some("90° clockwise")),
        (8, Some("90° anticlockwise")),
        (2, Some("mirrored")),
    ] {
        std::fs::write(&plain, with_exif_orientation(&base, value)).unwrap();
        let got = modelflow::input::image_orientation(&plain);
        match words {
            None => assert_eq!(got, None),
            Some(w) => assert!(got.is_some_and(|g| g.contains(w)), "{value}: {got:?}"),
        }
    }
}

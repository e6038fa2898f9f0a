//! A small synthetic scene written into a temporary folder with the library's own writers, and
//! helpers to break it one field at a time.
#![allow(dead_code)]

use modelflow::base::look_at;
use modelflow::base::RgbImage;
use modelflow::base::{grid, Mesh};
use modelflow::input::write_obj;
use modelflow::input::write_png;
use modelflow::input::{CameraEntry, FrameRange, SceneFile, FORMAT};
use nalgebra::{Point3, Vector3};
use std::path::{Path, PathBuf};

pub const W: u32 = 64;
pub const H: u32 = 48;
pub const FRAMES: u32 = 3;

pub fn mesh() -> Mesh {
    grid(5, 5, |u, v| Point3::new(u - 0.5, v - 0.5, 0.0))
}

/// The ground truth of `frame`: the mesh moved by 0.01·frame along x.
pub fn truth(frame: u32) -> Mesh {
    let m = mesh();
    let p = m
        .positions
        .iter()
        .map(|p| p + Vector3::new(0.01 * frame as f64, 0.0, 0.0))
        .collect();
    m.with_positions(p)
}

pub fn k() -> [[f64; 3]; 3] {
    [[60.0, 0.0, 31.5], [0.0, 60.0, 23.5], [0.0, 0.0, 1.0]]
}

pub fn camera(name: &str, eye: Point3<f64>) -> CameraEntry {
    let (r, t) = look_at(&eye, &Point3::origin(), &Vector3::y());
    CameraEntry {
        name: name.into(),
        width: W,
        height: H,
        k: Some(k()),
        r: Some([0, 1, 2].map(|i| [0, 1, 2].map(|j| r[(i, j)]))),
        t: Some([t.x, t.y, t.z]),
        poses: None,
        p: None,
        distortion: None,
        frame_offset: 0,
        time_offset: 0.0,
        shutter: 0.0,
        rolling_shutter: 0.0,
        images: format!("images/{name}/{{frame:04}}.png"),
        transfer: Default::default(),
    }
}

pub fn image() -> RgbImage {
    RgbImage::from_fn(W as usize, H as usize, |x, y| {
        [x as f32 / W as f32, y as f32 / H as f32, 0.5]
    })
}

/// Writes the scene (mesh, images, ground truth, scene.json) into `dir`; returns the scene
/// path and the file as written.
pub fn write_scene(dir: &Path) -> (PathBuf, SceneFile) {
    write_obj(&dir.join("mesh/initial.obj"), &mesh()).unwrap();
    let cams = vec![
        camera("cam0", Point3::new(-0.4, 0.3, 2.0)),
        camera("cam1", Point3::new(0.4, 0.3, 2.0)),
    ];
    for c in &cams {
        for f in 0..FRAMES {
            write_png(&dir.join(format!("images/{}/{f:04}.png", c.name)), &image()).unwrap();
        }
    }
    for f in 0..FRAMES {
        write_obj(&dir.join(format!("truth/{f:04}.obj")), &truth(f)).unwrap();
    }
    let file = SceneFile {
        format: FORMAT.into(),
        frames: FrameRange {
            first: 0,
            last: FRAMES - 1,
        },
        mesh: "mesh/initial.obj".into(),
        cameras: cams,
        ground_truth: Some("truth/{frame:04}.obj".into()),
        units: Some(modelflow::base::Units::Metres),
    };
    let path = dir.join("scene.json");
    file.write(&path).unwrap();
    (path, file)
}

/// Tracks `scene` from its first frame with the default options, in memory, and returns the RMS
/// vertex error of every later frame against the ground truth, in % of the mesh's size.
pub fn track_errors(scene: &modelflow::input::Scene) -> Vec<f64> {
    let mut tr = modelflow::tracker::Tracker::new(
        &scene.mesh,
        scene.cameras.clone(),
        scene.first,
        &scene.load_images(scene.first).unwrap(),
        modelflow::tracker::TrackOptions::default(),
    )
    .unwrap();
    let diag = scene.mesh.bbox_diagonal();
    (scene.first + 1..=scene.last)
        .map(|f| {
            tr.step(f, &scene.load_images(f).unwrap()).unwrap();
            let truth = scene.ground_truth(f).unwrap().unwrap();
            let sq: f64 = tr
                .positions()
                .iter()
                .zip(&truth.positions)
                .map(|(p, q)| (p - q).norm_squared())
                .sum();
            100.0 * (sq / truth.positions.len() as f64).sqrt() / diag
        })
        .collect()
}

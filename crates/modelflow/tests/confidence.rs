//! Per-vertex confidence as a user reads it: a vertex no camera sees has information 0 (and an
//! infinite sigma); the seen ones have finite sigmas; the file reads back exactly.

use modelflow::input::{read_mesh, write_obj, Scene};
use modelflow::run::{confidence_file, read_confidence};
use modelflow::{track_scene, RunOptions, TrackOptions};
use nalgebra::Point3;
use std::path::PathBuf;

fn sample() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/blender-cloth-sample"
    ))
}

#[test]
fn an_unseen_vertex_has_zero_information_and_the_seen_ones_a_finite_sigma() {
    let dir = tempfile::tempdir().unwrap();
    // The cloth plus one triangle far outside every camera's view (no ground truth then).
    let mut m = read_mesh(&sample().join("mesh/initial.obj")).unwrap();
    let n = m.positions.len() as u32;
    m.positions.extend([
        Point3::new(100.0, 100.0, 100.0),
        Point3::new(100.1, 100.0, 100.0),
        Point3::new(100.0, 100.1, 100.0),
    ]);
    m.triangles.push([n, n + 1, n + 2]);
    write_obj(&dir.path().join("mesh.obj"), &m).unwrap();
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sample().join("scene.json")).unwrap())
            .unwrap();
    v.as_object_mut().unwrap().remove("ground_truth");
    v["mesh"] = dir.path().join("mesh.obj").display().to_string().into();
    v["frames"]["last"] = 2.into();
    for c in v["cameras"].as_array_mut().unwrap() {
        c["images"] = sample()
            .join(c["images"].as_str().unwrap())
            .display()
            .to_string()
            .into();
    }
    let scene_path = dir.path().join("scene.json");
    std::fs::write(&scene_path, v.to_string()).unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    let run = dir.path().join("run");
    track_scene(
        &scene,
        &TrackOptions::default(),
        &run,
        &RunOptions::default(),
        &mut |_| {},
    )
    .unwrap();
    let c = read_confidence(&run.join(confidence_file(2))).unwrap();
    assert_eq!(c.len(), n as usize + 3);
    for far in &c[n as usize..] {
        assert_eq!((far.information, far.pixels), (0.0, 0.0));
        assert!(far.sigma().is_infinite());
    }
    assert!(c[..n as usize]
        .iter()
        .all(|c| c.information > 0.0 && c.sigma().is_finite() && c.residual < 0.05));
    let text = std::fs::read_to_string(run.join(confidence_file(2))).unwrap();
    assert!(text.starts_with("vertex,information,residual,sigma,pixels\n0,"));
    assert!(
        text.trim_end().ends_with(&format!("{},0,0,inf,0", n + 2)),
        "{}",
        &text[text.len() - 80..]
    );
}

#[test]
fn a_damaged_confidence_file_is_named_by_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("0001.confidence.csv");
    std::fs::write(
        &p,
        "vertex,information,residual,sigma,pixels\n0,1,0.1,0.1,4\n1,x,0,0,0\n",
    )
    .unwrap();
    let e = read_confidence(&p).unwrap_err().to_string();
    assert!(
        e.contains("0001.confidence.csv") && e.contains("line 3"),
        "{e}"
    );
}

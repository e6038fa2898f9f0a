//! `modelflow track` on an input mesh with a modelling slip: a sliver triangle is tracked, and
//! named in a warning so the artist can find it.

use modelflow::synth::{write_dataset, SynthOptions};
use std::process::Command;

#[test]
fn a_sliver_triangle_is_tracked_and_named_in_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        width: 160,
        height: 120,
        frames: 3,
        ..SynthOptions::default()
    };
    let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
    // Three more vertices on the cloth's top edge forming a triangle 1e-7 m high on a 2.5 cm
    // edge (written without `vt`, so the file's faces use plain indices).
    let obj = dir.path().join("footage/mesh/initial.obj");
    let mesh = modelflow::input::read_mesh(&obj).unwrap();
    let n = mesh.positions.len();
    let (a, b) = (mesh.positions[0], mesh.positions[1]);
    let mut text = String::new();
    for p in &mesh.positions {
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    let m = nalgebra::center(&a, &b);
    for p in [a, b, m + nalgebra::Vector3::new(0.0, 1e-7, 0.0)] {
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for t in &mesh.triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    text += &format!("f {} {} {}\n", n + 1, n + 2, n + 3);
    std::fs::write(&obj, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_modelflow"))
        .arg("track")
        .arg("--scene")
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("run"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let want = format!(
        "1 sliver triangle(s), thinner than 1/1000 of their longest edge; the first is triangle {} (vertices {} {} {}",
        mesh.triangles.len() + 1,
        n + 1,
        n + 2,
        n + 3
    );
    assert!(err.contains(&want), "{err}");
    assert!(!err.contains("STALLED"), "{err}");
}

#[test]
fn results_are_the_same_whatever_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/blender-cloth-sample/scene.json"
    );
    let run = |threads: &str| {
        let out = dir.path().join(format!("t{threads}"));
        let o = Command::new(env!("CARGO_BIN_EXE_modelflow"))
            .args([
                "--threads",
                threads,
                "track",
                "--frames",
                "0..3",
                "--scene",
                scene,
                "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (1..=3)
            .map(|f| std::fs::read(out.join(format!("{f:04}.obj"))).unwrap())
            .collect::<Vec<_>>()
    };
    assert!(
        run("1") == run("2"),
        "one and two threads give different meshes"
    );
    let o = Command::new(env!("CARGO_BIN_EXE_modelflow"))
        .args(["--threads", "0", "track", "--scene", scene, "--out"])
        .arg(dir.path().join("none"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--threads 0: expected 1 to 1024"));
}

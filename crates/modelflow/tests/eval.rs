//! Evaluation against ground truth: exact zero for the truth itself, the known offset for a
//! shifted copy, and clear errors for incomplete runs.

mod common;

use common::*;
use modelflow::input::write_obj;
use modelflow::input::Scene;
use modelflow::{evaluate, read_run, run::frame_number};
use nalgebra::Vector3;

fn write_run(dir: &std::path::Path, offset: Vector3<f64>) {
    for f in 0..FRAMES {
        let t = truth(f);
        let moved = t.positions.iter().map(|p| p + offset).collect();
        write_obj(&dir.join(format!("{f:04}.obj")), &t.with_positions(moved)).unwrap();
    }
    std::fs::write(dir.join("log.jsonl"), "{\"frame\": 1, \"seconds\": 0.1}\n").unwrap();
}

#[test]
fn frame_number_is_the_last_run_of_digits() {
    assert_eq!(frame_number("0007"), Some(7));
    assert_eq!(frame_number("take2_frame_0012"), Some(12));
    assert_eq!(frame_number("mesh12b"), Some(12));
    assert_eq!(frame_number("mesh"), None);
}

#[test]
fn truth_against_itself_is_exactly_zero() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    let run = read_run(&dir.path().join("truth")).unwrap();
    let r = evaluate(&scene, &run).unwrap();
    assert_eq!(r.frames, FRAMES as usize);
    assert_eq!(
        r.per_frame.iter().map(|e| e.frame).collect::<Vec<_>>(),
        vec![0, 1, 2]
    );
    assert!(r
        .per_frame
        .iter()
        .all(|e| e.rms == 0.0 && e.max == 0.0 && e.rms_pct == 0.0));
    assert_eq!((r.rms_mean, r.rms_final), (0.0, 0.0));
    assert_eq!(r.scale, 2f64.sqrt());
}

#[test]
fn how_much_of_each_frame_s_motion_a_run_followed_is_measured() {
    // The truth moves 0.01 along x per frame. The truth itself and a copy held at a constant
    // offset follow all of it; a run that moves half as far, half; one that stands still, none.
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    let followed = |name: &str, step: f64, offset: Vector3<f64>| {
        let run_dir = dir.path().join(name);
        for f in 0..FRAMES {
            let m = mesh();
            let moved = m
                .positions
                .iter()
                .map(|p| p + offset + Vector3::new(step * f as f64, 0.0, 0.0))
                .collect();
            write_obj(
                &run_dir.join(format!("{f:04}.obj")),
                &m.with_positions(moved),
            )
            .unwrap();
        }
        let r = evaluate(&scene, &read_run(&run_dir).unwrap()).unwrap();
        assert_eq!(
            r.per_frame[0].followed, None,
            "{name}: the first frame has no step"
        );
        (
            r.per_frame[1..]
                .iter()
                .map(|e| e.followed.unwrap())
                .collect::<Vec<_>>(),
            r.followed_median.unwrap(),
        )
    };
    for (name, step, offset, want) in [
        ("truth", 0.01, Vector3::zeros(), 1.0),
        ("offset", 0.01, Vector3::new(0.02, -0.01, 0.03), 1.0),
        ("half", 0.005, Vector3::zeros(), 0.5),
        ("still", 0.0, Vector3::zeros(), 0.0),
        ("overshoot", 0.015, Vector3::zeros(), 1.5),
    ] {
        let (per_frame, median) = followed(name, step, offset);
        for f in &per_frame {
            assert!((f - want).abs() < 1e-9, "{name}: {per_frame:?}");
        }
        assert!((median - want).abs() < 1e-9, "{name}: median {median}");
    }
    // A truth that does not move has nothing to follow.
    let still_dir = tempfile::tempdir().unwrap();
    let (still_path, _) = write_scene(still_dir.path());
    for f in 0..FRAMES {
        write_obj(&still_dir.path().join(format!("truth/{f:04}.obj")), &mesh()).unwrap();
    }
    let still = Scene::load(&still_path).unwrap();
    let r = evaluate(&still, &read_run(&still_dir.path().join("truth")).unwrap()).unwrap();
    assert!(r.per_frame.iter().all(|e| e.followed.is_none()));
    assert_eq!(r.followed_median, None);
}

#[test]
fn known_offset_is_measured() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    let run_dir = dir.path().join("run");
    write_run(&run_dir, Vector3::new(0.03, 0.0, -0.04));
    std::fs::write(run_dir.join("notes.txt"), "ignored").unwrap();
    let r = evaluate(&scene, &read_run(&run_dir).unwrap()).unwrap();
    for e in &r.per_frame {
        assert!((e.rms - 0.05).abs() < 1e-12, "{e:?}");
        assert!((e.max - 0.05).abs() < 1e-12, "{e:?}");
        assert!((e.rms_pct - 5.0 / 2f64.sqrt()).abs() < 1e-9, "{e:?}");
        // Both cameras see the whole sheet: the seen-vertex figure is the same.
        assert_eq!(e.seen, 25, "{e:?}");
        assert!((e.seen_rms - 0.05).abs() < 1e-12, "{e:?}");
        assert_eq!(e.by_views.len(), 1, "{e:?}");
        assert_eq!((e.by_views[0].cameras, e.by_views[0].vertices), (2, 25));
        assert!((e.by_views[0].rms - 0.05).abs() < 1e-12, "{e:?}");
        // A shift of the whole mesh is a misplacement, not a misshaping.
        assert!(e.shape_rms < 1e-12, "{e:?}");
        assert!(
            (e.pose_shift - 0.05).abs() < 1e-12 && e.pose_turn_deg < 1e-6,
            "{e:?}"
        );
    }
    assert!(r.shape_rms_mean < 1e-12 && (r.pose_shift_mean - 0.05).abs() < 1e-12);
    assert_eq!(r.by_views.len(), 1);
    assert_eq!(r.by_views[0].vertices_mean, 25.0);
    assert!((r.rms_mean - 0.05).abs() < 1e-12 && (r.rms_final - 0.05).abs() < 1e-12);
    assert!((r.rms_final_pct - 5.0 / 2f64.sqrt()).abs() < 1e-9);
    let json = serde_json::to_value(&r).unwrap();
    for key in [
        "frames",
        "per_frame",
        "rms_mean",
        "rms_final",
        "rms_mean_pct",
        "rms_final_pct",
        "seen_rms_mean_pct",
        "seen_rms_final_pct",
        "followed_median",
        "shape_rms_mean_pct",
        "pose_turn_deg_mean",
        "by_views",
        "scale",
    ] {
        assert!(json.get(key).is_some(), "{key}");
    }
}

#[test]
fn one_vertex_off_gives_rms_and_max() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    let mut run = read_run(&dir.path().join("truth")).unwrap();
    run[2].1.positions[7].z += 0.5;
    let r = evaluate(&scene, &run).unwrap();
    let e = &r.per_frame[2];
    assert_eq!(e.max, 0.5);
    assert!((e.rms - (0.25f64 / 25.0).sqrt()).abs() < 1e-15);
    // A dent is a misshaping: the best rigid fit takes out only part of it.
    assert!(e.shape_rms > 0.5 * e.rms && e.shape_rms < e.rms, "{e:?}");
    assert_eq!(r.rms_final, e.rms);
    assert!((r.rms_mean - e.rms / 3.0).abs() < 1e-15);
}

#[test]
fn collapsed_triangles_in_a_run_are_scored_not_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    let run_dir = dir.path().join("run");
    write_run(&run_dir, Vector3::zeros());
    // Vertex 1 collapsed onto vertex 0 in the last frame.
    let mut m = truth(2);
    m.positions[1] = m.positions[0];
    write_obj(&run_dir.join("0002.obj"), &m).unwrap();
    assert!(modelflow::input::read_mesh(&run_dir.join("0002.obj")).is_err());
    let r = evaluate(&scene, &read_run(&run_dir).unwrap()).unwrap();
    assert!((r.per_frame[2].max - 0.25).abs() < 1e-12);
}

#[test]
fn run_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    let scene = Scene::load(&path).unwrap();
    let run_dir = dir.path().join("run");
    write_run(&run_dir, Vector3::zeros());

    // A duplicate frame.
    std::fs::copy(run_dir.join("0001.obj"), run_dir.join("frame_1.obj")).unwrap();
    let msg = read_run(&run_dir).unwrap_err().to_string();
    assert!(
        msg.contains("frame 1") && msg.contains("two meshes"),
        "{msg}"
    );
    std::fs::remove_file(run_dir.join("frame_1.obj")).unwrap();

    // A missing frame.
    std::fs::remove_file(run_dir.join("0001.obj")).unwrap();
    let msg = evaluate(&scene, &read_run(&run_dir).unwrap())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("no mesh for frame(s) 1"), "{msg}");

    // Vertex count mismatch.
    let mut run = read_run(&dir.path().join("truth")).unwrap();
    run[1].1 = modelflow::base::grid(2, 2, |u, v| nalgebra::Point3::new(u, v, 0.0));
    let msg = evaluate(&scene, &run).unwrap_err().to_string();
    assert!(
        msg.contains("frame 1") && msg.contains("4 vertices"),
        "{msg}"
    );

    // No ground truth.
    file.ground_truth = None;
    file.write(&path).unwrap();
    let scene = Scene::load(&path).unwrap();
    let msg = evaluate(&scene, &run).unwrap_err().to_string();
    assert!(
        msg.contains("scene.json") && msg.contains("ground_truth"),
        "{msg}"
    );

    // Not a folder.
    assert!(read_run(&dir.path().join("nope"))
        .unwrap_err()
        .to_string()
        .contains("nope"));
}

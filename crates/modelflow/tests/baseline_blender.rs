//! The optical-flow baseline end to end on the Blender-rendered sample: `baseline::run` writes
//! one OBJ per frame and a log in the format of `track`, and its result is far closer to the
//! ground truth than standing still.

use modelflow::baseline::{self, BaselineOptions};
use modelflow::input::Scene;
use modelflow::{evaluate, read_run, RunOptions};
use std::path::Path;
use std::sync::atomic::{AtomicU32, Ordering};

const SCENE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../fixtures/blender-cloth-sample/scene.json"
);

#[test]
fn baseline_follows_the_blender_cloth() {
    let mut scene = Scene::load(Path::new(SCENE)).unwrap();
    // The first five frames keep the test quick.
    scene.last = scene.first + 4;
    let dir = tempfile::tempdir().unwrap();
    let calls = AtomicU32::new(0);
    let summary = baseline::run(
        &scene,
        &BaselineOptions::default(),
        dir.path(),
        &RunOptions::default(),
        &|_| {
            calls.fetch_add(1, Ordering::Relaxed);
        },
    )
    .unwrap();
    assert_eq!(
        calls.load(Ordering::Relaxed),
        4,
        "progress once per solved frame, as the tracker's"
    );
    assert_eq!(summary.frames.len(), 4);

    // Output layout: {frame:04}.obj for every frame, the first equal to the input mesh.
    let run = read_run(dir.path()).unwrap();
    assert_eq!(
        run.iter().map(|(f, _)| *f).collect::<Vec<_>>(),
        vec![0, 1, 2, 3, 4]
    );
    assert_eq!(run[0].1.triangles, scene.mesh.triangles);
    for (a, b) in run[0].1.positions.iter().zip(&scene.mesh.positions) {
        assert!((a - b).norm() < 1e-6);
    }
    // log.jsonl: one line per solved frame with frame, seconds, tracked, triangulated.
    let log = std::fs::read_to_string(dir.path().join("log.jsonl")).unwrap();
    let lines: Vec<serde_json::Value> = log
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 4);
    let n = scene.mesh.vertex_count() as u64;
    for (i, l) in lines.iter().enumerate() {
        assert_eq!(l["frame"], i as u64 + 1);
        assert!(l["seconds"].as_f64().unwrap() > 0.0);
        // Both cameras see the whole cloth: nearly every vertex is tracked twice and triangulated.
        assert!(l["tracked"].as_u64().unwrap() > 2 * n * 95 / 100, "{l}");
        assert!(l["triangulated"].as_u64().unwrap() > n * 95 / 100, "{l}");
    }

    // Accuracy: well under the error of not moving at all.
    let report = evaluate(&scene, &run).unwrap();
    let still: Vec<_> = (scene.first..=scene.last)
        .map(|f| (f, scene.mesh.clone()))
        .collect();
    let still = evaluate(&scene, &still).unwrap();
    assert!(
        report.rms_final < 0.5 * still.rms_final,
        "baseline {} vs standing still {}",
        report.rms_final,
        still.rms_final
    );
}

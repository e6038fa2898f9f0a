//! A run writes each of its files once: the bytes a whole run writes are the bytes it leaves in
//! its folder (plus the manifest written twice), so the log costs O(N) bytes for N frames. (It
//! used to be rewritten after every frame: O(N²), about 115 GB for a 10 000-frame shot.)
//!
//! Measured with Linux's per-process write counter (`wchar` in /proc/self/io), so this file holds
//! one test: nothing else in the process writes while it runs.

#![cfg(target_os = "linux")]

use modelflow::input::Scene;
use modelflow::synth::{write_dataset, SynthOptions};
use modelflow::tracker::{track_scene, TrackOptions};
use modelflow::RunOptions;

fn bytes_written() -> u64 {
    let io = std::fs::read_to_string("/proc/self/io").expect("/proc/self/io is readable");
    io.lines()
        .find_map(|l| l.strip_prefix("wchar: "))
        .and_then(|v| v.trim().parse().ok())
        .expect("a wchar line")
}

#[test]
fn a_run_writes_its_log_once() {
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        width: 96,
        height: 72,
        frames: 40,
        ..SynthOptions::default()
    };
    let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
    let scene = Scene::load(&scene).unwrap();
    let out = dir.path().join("run");
    let before = bytes_written();
    track_scene(
        &scene,
        &TrackOptions::default(),
        &out,
        &RunOptions::default(),
        &mut |_| {},
    )
    .unwrap();
    let written = bytes_written() - before;
    let size = |name: &str| std::fs::metadata(out.join(name)).unwrap().len();
    let left: u64 = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().metadata().unwrap().len())
        .sum();
    let log = size("log.jsonl");
    let manifest = size("run.json");
    assert_eq!(
        std::fs::read_to_string(out.join("log.jsonl"))
            .unwrap()
            .lines()
            .count(),
        39
    );
    // The manifest is written when the run starts and again when it ends.
    assert!(
        written <= left + 2 * manifest,
        "wrote {written} bytes for a folder of {left} (log {log}, manifest {manifest})"
    );
    // A log rewritten per frame would have cost about 20× its size here.
    assert!(written >= left, "{written} < {left}");
}

//! `modelflow track` interrupted as users interrupt it — `kill -9` and Ctrl-C (SIGINT) in the
//! middle of a shot — then `--resume`d: the folder ends byte-identical (meshes) to an
//! uninterrupted run, with no temporary file left. Ctrl-C exits 130 and says how to continue; a
//! rerun without `--resume`/`--force` and an `--out` full of other files are refused and change
//! nothing.

#![cfg(unix)]

use modelflow::synth::{write_dataset, SynthOptions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// A 320×240 two-camera cloth of 40 frames (long enough to be interrupted in the middle) and its
/// uninterrupted run, made once.
fn shot() -> &'static (tempfile::TempDir, PathBuf, PathBuf) {
    static SHOT: OnceLock<(tempfile::TempDir, PathBuf, PathBuf)> = OnceLock::new();
    SHOT.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let opts = SynthOptions {
            width: 320,
            height: 240,
            frames: 40,
            ..SynthOptions::default()
        };
        let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
        let reference = dir.path().join("reference");
        let out = track(&scene, &reference, &[]).output().unwrap();
        assert!(out.status.success(), "{}", text(&out.stderr));
        (dir, scene, reference)
    })
}

fn track(scene: &Path, out: &Path, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_modelflow"));
    c.arg("track")
        .arg("--scene")
        .arg(scene)
        .arg("--out")
        .arg(out)
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    c
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

fn meshes(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    files(dir)
        .into_iter()
        .filter(|(n, _)| n.ends_with(".obj"))
        .collect()
}

/// Starts a run and waits until `frames` frames are logged; fails if the run ends first.
fn start_and_wait(scene: &Path, out: &Path, frames: usize) -> Child {
    let mut child = track(scene, out, &[]).spawn().unwrap();
    let t0 = Instant::now();
    loop {
        let logged = std::fs::read_to_string(out.join("log.jsonl"))
            .map(|l| l.lines().count())
            .unwrap_or(0);
        if logged >= frames {
            return child;
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before {frames} frames were logged");
        }
        assert!(t0.elapsed() < Duration::from_secs(300), "no progress");
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn resume_and_compare(scene: &Path, out: &Path, reference: &Path) {
    let logged = std::fs::read_to_string(out.join("log.jsonl")).unwrap_or_default();
    assert!(
        logged.lines().count() < 39,
        "the run was interrupted before its end"
    );
    let o: Output = track(scene, out, &["--resume"]).output().unwrap();
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("resumed after frame"),
        "{}",
        text(&o.stderr)
    );
    assert_eq!(meshes(out), meshes(reference), "byte-identical meshes");
    let names: Vec<String> = files(out).into_keys().collect();
    assert!(names.iter().all(|n| !n.ends_with(".tmp")), "{names:?}");
    let log = std::fs::read_to_string(out.join("log.jsonl")).unwrap();
    let frames: Vec<u64> = log
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).unwrap()["frame"]
                .as_u64()
                .unwrap()
        })
        .collect();
    assert_eq!(
        frames,
        (1..40).collect::<Vec<u64>>(),
        "one log line per frame"
    );
}

#[test]
fn kill_9_then_resume_gives_the_uninterrupted_files() {
    let (tmp, scene, reference) = shot();
    let out = tmp.path().join("killed");
    let mut child = start_and_wait(scene, &out, 3);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    resume_and_compare(scene, &out, reference);
}

#[test]
fn ctrl_c_exits_130_and_leaves_a_resumable_folder() {
    let (tmp, scene, reference) = shot();
    let out = tmp.path().join("interrupted");
    let child = start_and_wait(scene, &out, 3);
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    assert!(
        err.contains("--resume") && err.contains("interrupted"),
        "{err}"
    );
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("run.json")).unwrap()).unwrap();
    assert_eq!(manifest["status"], "interrupted");
    resume_and_compare(scene, &out, reference);
}

#[test]
fn a_rerun_and_a_folder_of_other_files_are_refused_and_unchanged() {
    let (tmp, scene, reference) = shot();
    let before = files(reference);
    let o = track(scene, reference, &[]).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = text(&o.stderr);
    assert!(err.contains("--resume") && err.contains("--force"), "{err}");
    assert_eq!(files(reference), before);

    // --out pointed at a folder of someone else's meshes by mistake.
    let other = tmp.path().join("truth");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("0000.obj"), "v 0 0 0\n").unwrap();
    std::fs::write(other.join("0001.obj"), "v 1 0 0\n").unwrap();
    let before = files(&other);
    for extra in [&[][..], &["--resume"][..]] {
        let o = track(scene, &other, extra).output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{extra:?}");
        let err = text(&o.stderr);
        assert!(
            err.contains("not a modelflow run") && !err.contains("panicked"),
            "{err}"
        );
        assert_eq!(files(&other), before, "{extra:?}: nothing changes");
    }
    let o = track(scene, &other, &["--force", "--resume"])
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(2),
        "--force and --resume exclude each other"
    );
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let dest = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &dest);
        } else {
            std::fs::copy(e.path(), dest).unwrap();
        }
    }
}

#[test]
fn a_frame_that_does_not_read_stops_the_run_and_resume_goes_on_once_it_is_repaired() {
    let (tmp, scene, reference) = shot();
    // A copy of the footage whose camera 1 frame 20 was cut short in a transfer.
    let footage = tmp.path().join("footage-cut");
    copy_dir(scene.parent().unwrap(), &footage);
    let scene = footage.join(scene.file_name().unwrap());
    let cut = footage.join("images/cam1/0020.png");
    let good = std::fs::read(&cut).unwrap();
    std::fs::write(&cut, &good[..good.len() / 2]).unwrap();
    let out = tmp.path().join("cut");
    let o = track(&scene, &out, &[]).output().unwrap();
    let err = text(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("frame 20") && err.contains("0020.png") && err.contains("0..=19"),
        "{err}"
    );
    assert!(err.contains("--resume"), "{err}");
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("run.json")).unwrap()).unwrap();
    assert_eq!(manifest["status"], "failed");
    assert_eq!(manifest["last_complete"], 19);
    // An image of a frame already tracked changed too: not a continuation of the same inputs.
    let early = footage.join("images/cam0/0005.png");
    let early_good = std::fs::read(&early).unwrap();
    std::fs::write(&cut, &good).unwrap();
    std::fs::write(&early, &early_good[..early_good.len() - 1]).unwrap();
    let o = track(&scene, &out, &["--resume"]).output().unwrap();
    let err = text(&o.stderr);
    assert!(!o.status.success() && err.contains("other inputs"), "{err}");
    // Only the frame that stopped it repaired: it goes on, to the uninterrupted run's meshes.
    std::fs::write(&early, &early_good).unwrap();
    let o = track(&scene, &out, &["--resume"]).output().unwrap();
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("resumed after frame 19"));
    assert_eq!(meshes(&out), meshes(reference), "byte-identical meshes");
}

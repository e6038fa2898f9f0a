//! Every numeric option is checked against its range before any work: a value outside it (NaN,
//! infinite, negative, absurdly large) stops the command with exit code 1, a message naming the
//! option, the value and the range, and nothing written; never a panic, a hang or an abort.

use std::path::Path;
use std::process::Command;

fn fixture_scene() -> &'static Path {
    Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/blender-cloth-sample/scene.json"
    ))
}

fn refused(cmd: &[&str], extra: &[&str], option: &str, range: &str) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_modelflow"))
        .args(cmd)
        .arg("--scene")
        .arg(fixture_scene())
        .arg("--out")
        .arg(&out)
        .args(extra)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{cmd:?} {extra:?}: {err}");
    assert!(
        err.contains(option) && err.contains(range) && !err.contains("panicked"),
        "{cmd:?} {extra:?}: {err}"
    );
    assert!(!out.exists(), "{cmd:?} {extra:?} wrote {}", out.display());
}

#[test]
fn track_options_out_of_range_are_refused_by_name() {
    for (opt, value, range) in [
        ("--blur", "inf", "[0, 20]"),
        ("--blur", "1000000", "[0, 20]"),
        ("--huber", "NaN", "(0, 10]"),
        ("--huber", "-1", "(0, 10]"),
        ("--anchor-weight", "-1", "[0, 100]"),
        ("--consensus", "-1", "[0, 1000]"),
        ("--spring-k", "NaN", "[0, 1000000]"),
        ("--spring-t", "0", "(0, 10]"),
        ("--spring-yield", "-0.01", "[0, 10]"),
        ("--spring-pull-back", "1.5", "[0, 1]"),
        ("--spring-stretch-share", "-0.1", "[0, 1]"),
        ("--bending-yield", "NaN", "[0, 10]"),
        ("--bending-yield-seen", "-1", "[0, 10]"),
        ("--bending-seen-share", "inf", "[0, 10]"),
        ("--membrane", "-0.5", "[0, 1000000]"),
        ("--min-decrease", "NaN", "[0, 1)"),
        ("--approach-decrease", "1", "[0, 1)"),
        ("--lent-anchor", "11", "[0, 10]"),
        ("--sticky-edges", "-0.5", "[0, 100]"),
        ("--sticky-edges", "NaN", "[0, 100]"),
        ("--shutter", "1.5", "[0, 1]"),
        ("--shutter", "NaN", "[0, 1]"),
        ("--max-iterations", "0", "[1, 10000]"),
        ("--tukey-k", "inf", "(0, 1000]"),
        ("--finest-level", "12", "[0, 11]"),
        ("--stereo", "-1", "[0, 100]"),
        ("--stereo-stride", "0", "[1, 64]"),
        ("--stereo-neighbours", "1001", "[0, 1000]"),
        ("--gain-range", "0.5", "[1, 100]"),
        ("--gain-range", "NaN", "[1, 100]"),
    ] {
        refused(&["track"], &[opt, value], &format!("{opt} {value}"), range);
    }
    // The finest level solved must be one of the pyramid's.
    refused(
        &["track"],
        &["--levels", "2", "--finest-level", "2"],
        "--finest-level 2",
        "below --levels 2",
    );
}

#[test]
fn baseline_and_report_options_out_of_range_are_refused_by_name() {
    for (opt, value, range) in [
        ("--window", "100001", "3 to 101"),
        ("--window", "4", "odd"),
        ("--levels", "0", "1 to 12"),
        ("--fb", "NaN", "[0, 1000]"),
        ("--max-reprojection", "-2", "(0, 1000]"),
    ] {
        refused(
            &["baseline"],
            &[opt, value],
            &format!("{opt} {value}"),
            range,
        );
    }
    for value in ["NaN", "inf", "-400"] {
        refused(
            &["report", "--run", "a=/nonexistent"],
            &["--oblique-degrees", value],
            &format!("--oblique-degrees {value}"),
            "[-180, 180]",
        );
    }
}

#[test]
fn a_scene_that_needs_more_memory_than_allowed_is_refused_before_loading_frames() {
    // The fixture: two 320x240 cameras, about 47 MiB by the estimate.
    refused(
        &["track"],
        &["--max-memory", "0.01"],
        "--max-memory 10 MiB: expected at least ",
        "MiB: tracking 2 camera(s) of 320x240, 320x240 needs about that much (100 bytes per pixel)",
    );
    refused(
        &["baseline"],
        &["--max-memory", "NaN"],
        "--max-memory NaN",
        "a positive number of GiB",
    );
}

#[test]
fn capture_range_speeds_must_be_finite_and_ascending() {
    for speeds in ["10,NaN", "20,10", "-5"] {
        let o = Command::new(env!("CARGO_BIN_EXE_modelflow"))
            .args(["bench", "--capture-range", "--speeds", speeds])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{speeds}: {err}");
        assert!(
            err.contains("--speeds") && err.contains("ascending speeds from 0 to 1000"),
            "{speeds}: {err}"
        );
    }
}

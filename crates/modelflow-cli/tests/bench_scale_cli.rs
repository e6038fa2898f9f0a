//! `modelflow bench --scale`: the cost model runs a grid point per combination and reports each
//! with its time, iterations and peak memory; bad grid values are refused with the option named.

use std::process::Command;

#[test]
fn a_small_grid_reports_every_point() {
    let o = Command::new(env!("CARGO_BIN_EXE_modelflow"))
        .args([
            "bench",
            "--scale",
            "--json",
            "--scale-cameras",
            "2,3",
            "--scale-sizes",
            "96x72",
            "--scale-vertices",
            "36",
            "--frames",
            "2",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rows = r["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for (row, cams) in rows.iter().zip([2, 3]) {
        assert_eq!(row["cameras"], cams);
        assert_eq!(
            (row["width"].as_u64(), row["height"].as_u64()),
            (Some(96), Some(72))
        );
        assert_eq!(row["vertices"], 36);
        let mpx = row["megapixels"].as_f64().unwrap();
        assert!((mpx - cams as f64 * 96.0 * 72.0 / 1e6).abs() < 1e-12);
        assert!(row["ms_per_frame"].as_f64().unwrap() > 0.0);
        assert!(row["iterations"].as_f64().unwrap() >= 1.0);
        if cfg!(target_os = "linux") {
            // The peak of a process that rendered and tracked images: more than nothing, less
            // than the machine.
            let peak = row["peak_mib"].as_f64().unwrap();
            assert!(peak > 1.0 && peak < 4096.0, "{peak}");
        }
    }
    // Two points varying in pixels only: no fit.
    assert!(r["fit"].is_null());
}

#[test]
fn bad_grid_values_are_refused_by_name() {
    for (args, expected) in [
        (&["--scale-cameras", "1"][..], "--scale-cameras 1"),
        (&["--scale-vertices", "4"][..], "--scale-vertices 4"),
        (&["--scale-sizes", "640"][..], "WIDTHxHEIGHT"),
        (&["--frames", "1"][..], "--frames 1"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_modelflow"))
            .args(["bench", "--scale"])
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} was accepted");
        assert!(err.contains(expected), "{args:?}: {err}");
    }
}

//! End-to-end tests of `write_report` on the Blender cloth sample (with and without its ground
//! truth), with runs made from the truth: an exact copy and a copy drifting by a known amount.

use super::*;
use crate::input::meshio;
use crate::report::plot::tests::assert_well_formed;
use nalgebra::Vector3;

const SAMPLE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../fixtures/blender-cloth-sample/scene.json"
);

/// Writes a run folder: the ground truth of every frame moved by `drift · (frame − first)` in x,
/// plus a log with the given seconds per frame.
fn make_run(scene: &Scene, dir: &Path, drift: f64, seconds: Option<&[f64]>) {
    for f in scene.frames() {
        let gt = scene.ground_truth(f).unwrap().unwrap();
        let d = Vector3::new(drift * (f - scene.first) as f64, 0.0, 0.0);
        let moved = gt.with_positions(gt.positions.iter().map(|p| p + d).collect());
        meshio::write_obj(&dir.join(format!("{f:04}.obj")), &moved).unwrap();
    }
    if let Some(s) = seconds {
        let log: String = s
            .iter()
            .enumerate()
            .map(|(i, s)| {
                format!(
                    "{{\"frame\": {}, \"seconds\": {s}, \"load_seconds\": 0, \"wall_seconds\": {s}, \
                     \"method\": \"baseline\", \"tracked\": 1, \"triangulated\": 1}}\n",
                    i + 1
                )
            })
            .collect();
        std::fs::write(dir.join("log.jsonl"), log).unwrap();
    }
}

/// The values of every `src="..."` and `href="..."` attribute.
fn links(html: &str) -> Vec<String> {
    let mut out = Vec::new();
    for attr in ["src=\"", "href=\""] {
        let mut rest = html;
        while let Some(i) = rest.find(attr) {
            let after = &rest[i + attr.len()..];
            let j = after.find('"').expect("attribute closed");
            out.push(after[..j].to_string());
            rest = &after[j..];
        }
    }
    out
}

fn check_links(out: &Path, html: &str) -> Vec<String> {
    assert!(
        !html.contains("http://") && !html.contains("https://"),
        "the page fetches nothing from the network"
    );
    let links = links(html);
    assert!(!links.is_empty());
    for l in &links {
        assert!(
            !l.contains("//") && !l.starts_with('/'),
            "relative link expected: {l}"
        );
        let p = out.join(l);
        assert!(p.is_file(), "{l} is linked but missing");
        if l.ends_with(".png") {
            let img = imageio::read_rgb(&p).unwrap_or_else(|e| panic!("{l} does not decode: {e}"));
            assert!(img.width() > 100 && img.height() > 100);
        } else if l.ends_with(".svg") {
            assert_well_formed(&std::fs::read_to_string(&p).unwrap());
        }
    }
    links
}

#[test]
fn report_with_ground_truth_shows_errors_overlays_and_only_local_decodable_files() {
    let scene = Scene::load(Path::new(SAMPLE)).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let (exact, drift, out) = (
        tmp.path().join("exact"),
        tmp.path().join("drift"),
        tmp.path().join("report"),
    );
    make_run(&scene, &exact, 0.0, None);
    make_run(&scene, &drift, 0.01, Some(&[0.5, 0.7, 0.9]));
    let runs = vec![
        ("exact".to_string(), exact),
        ("drift & co".to_string(), drift),
    ];
    let summary = write_report(&scene, &runs, &ReportOptions::default(), &out).unwrap();

    assert_eq!(summary.frames, vec![0, 5, 11]);
    assert_eq!(summary.index, out.join("index.html"));
    let html = std::fs::read_to_string(&summary.index).unwrap();
    let links = check_links(&out, &html);
    for f in [0, 5, 11] {
        for c in ["c0_cam0", "c1_cam1"] {
            assert!(
                links.contains(&format!("overlay_f{f:04}_{c}.png")),
                "overlay of frame {f} {c}"
            );
        }
        assert!(links.contains(&format!("oblique_f{f:04}.png")));
        assert!(links.contains(&format!("errormap_f{f:04}.png")));
    }
    assert!(links.contains(&"error.png".to_string()) && links.contains(&"error.svg".to_string()));
    // The residual image of the last frame, against frame 10 and the first: the run on the
    // surface leaves far less than the one sliding 1 cm per frame (10 cm by frame 10), and more
    // against the first frame than the previous one (it has slid further since).
    assert!(links.contains(&"residual_f0011.png".to_string()));
    let rms = |run: &str, reference: u32| {
        summary
            .residual
            .iter()
            .find(|r| r.run == run && r.reference == reference && r.frame == 11)
            .unwrap_or_else(|| panic!("residual row {run} / {reference}"))
            .rms
    };
    assert_eq!(summary.residual.len(), 4);
    assert!(rms("exact", 10) < 0.02, "{:?}", summary.residual);
    assert!(
        rms("drift & co", 10) > 2.0 * rms("exact", 10),
        "{:?}",
        summary.residual
    );
    assert!(
        rms("drift & co", 0) > rms("drift & co", 10),
        "{:?}",
        summary.residual
    );
    assert!(html.contains("Photometric residual at frame 11"));
    for f in &summary.files {
        assert!(f.is_file() && f.starts_with(&out));
    }

    let svg = std::fs::read_to_string(out.join("error.svg")).unwrap();
    assert!(
        svg.contains(">exact</text>") && svg.contains(">drift &amp; co</text>"),
        "legend names every run"
    );
    assert!(svg.contains("RMS vertex error (% of bbox diagonal)"));
    assert!(html.contains("drift &amp; co") && html.contains("cam1"));

    // Exact copy: zero error. Drift: RMS = 0.01·frame exactly (OBJ keeps 1e-6 or better).
    let e0 = summary.runs[0].error.as_ref().unwrap();
    assert_eq!(e0.rms_mean, 0.0);
    let e1 = summary.runs[1].error.as_ref().unwrap();
    for fe in &e1.per_frame {
        assert!((fe.rms - 0.01 * fe.frame as f64).abs() < 1e-5, "{fe:?}");
    }
    assert!((e1.rms_final_pct - 100.0 * 0.11 / scene.mesh.bbox_diagonal()).abs() < 1e-3);
    assert_eq!(summary.runs[0].seconds_per_frame, None);
    assert!((summary.runs[1].seconds_per_frame.unwrap() - 0.7).abs() < 1e-12);
    assert!(
        html.contains("<td>700</td>") && html.contains("(ms, median)"),
        "time per frame in the table"
    );

    // The title names the scene by its folder and file, not "scene.json".
    assert!(html.contains("<h1>modelflow report — blender-cloth-sample / scene</h1>"));
    // Both cameras see the whole sheet: its depth comes from the images everywhere.
    assert!(
        html.contains("<th>surface seen at frame 0</th><td>by two or more cameras 100 %, by one only 0 %, by none 0 %"),
        "{html}"
    );
    // The flipbook: one JPEG per frame with every camera, scrubbed by a slider.
    let book: Vec<u32> = (0..12).collect();
    assert!(
        html.contains("const F=[0,1,2,3,4,5,6,7,8,9,10,11]"),
        "frame list"
    );
    assert!(html.contains("id=\"fb-slider\"") && html.contains("max=\"11\""));
    for f in &book {
        let p = out.join(format!("flipbook/f{f:04}.jpg"));
        assert!(summary.files.contains(&p), "flipbook frame {f}");
        let img = imageio::read_rgb(&p).unwrap();
        // Two 320-pixel cameras side by side (the sample is 320 × 240).
        assert!(
            img.width() > 2 * 320 && img.height() > 240,
            "{}",
            img.width()
        );
    }
    // The error plot also in length (scene units here: the sample gives no unit), with the
    // drawn frames marked.
    let len_svg = std::fs::read_to_string(out.join("error_length.svg")).unwrap();
    assert_well_formed(&len_svg);
    assert!(len_svg.contains("RMS vertex error (scene units)"));
    assert_eq!(
        svg.matches("stroke-dasharray").count(),
        3,
        "frames 0, 5, 11 marked"
    );
    assert!(links.contains(&"error_length.png".to_string()));
    // The error's spread over the mesh: three lines per run; the drifting run's vertices all
    // move by the same amount, so its median, 90th percentile and max coincide (0.11 at 11).
    let bands = std::fs::read_to_string(out.join("vertex_error_bands.svg")).unwrap();
    assert_well_formed(&bands);
    for name in [
        "exact median",
        "drift &amp; co 90th percentile",
        "drift &amp; co max",
    ] {
        assert!(bands.contains(&format!(">{name}</text>")), "{name}");
    }
    assert!(links.contains(&"vertex_error_bands.png".to_string()));
    // Where the error lies: the drifting run is the truth shifted, so its shape alone is exact
    // (0) while all its vertices are off; every vertex of the sheet is seen, so there is no
    // line for the unseen ones.
    let place = std::fs::read_to_string(out.join("error_where.svg")).unwrap();
    assert_well_formed(&place);
    for name in [
        "exact all",
        "exact shape alone",
        "drift &amp; co all",
        "drift &amp; co shape alone",
    ] {
        assert!(place.contains(&format!(">{name}</text>")), "{name}");
    }
    assert!(!place.contains("seen by none"));
    // The shape alone is dashed, so it reads apart from the whole error in grey too.
    assert!(place.contains(r#"stroke-dasharray="10 5""#));
    assert!(links.contains(&"error_where.png".to_string()));

    // Error maps: each run on its own scale (a colour bar per run) unless shared (one bar).
    let shared_out = tmp.path().join("shared");
    let shared = ReportOptions {
        shared_error_scale: true,
        flipbook: false,
        ..ReportOptions::default()
    };
    write_report(&scene, &runs, &shared, &shared_out).unwrap();
    let own = imageio::read_rgb(&out.join("errormap_f0005.png")).unwrap();
    let one = imageio::read_rgb(&shared_out.join("errormap_f0005.png")).unwrap();
    assert!(
        own.width() > one.width() + 100,
        "{} vs {}",
        own.width(),
        one.width()
    );
    assert!(!shared_out.join("flipbook").exists());
    assert!(!std::fs::read_to_string(shared_out.join("index.html"))
        .unwrap()
        .contains("fb-slider"));
}

#[test]
fn report_without_ground_truth_plots_photometric_cost() {
    let mut scene = Scene::load(Path::new(SAMPLE)).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let (exact, drift, out) = (
        tmp.path().join("exact"),
        tmp.path().join("drift"),
        tmp.path().join("report"),
    );
    make_run(&scene, &exact, 0.0, None);
    make_run(&scene, &drift, 0.02, None);
    scene.ground_truth = None;
    let runs = vec![("exact".to_string(), exact), ("drift".to_string(), drift)];
    let opts = ReportOptions {
        frames: Some(vec![11, 3]),
        ..ReportOptions::default()
    };
    let summary = write_report(&scene, &runs, &opts, &out).unwrap();
    assert_eq!(summary.frames, vec![3, 11]);
    let html = std::fs::read_to_string(&summary.index).unwrap();
    let links = check_links(&out, &html);
    assert!(
        links.contains(&"photometric.png".to_string())
            && links.contains(&"photometric.svg".to_string())
    );
    assert!(!out.join("error.png").exists() && !links.iter().any(|l| l.starts_with("errormap")));
    assert!(links.contains(&"overlay_f0011_c1_cam1.png".to_string()));
    assert!(html.contains("Photometric cost") && !html.contains("RMS error"));
    let svg = std::fs::read_to_string(out.join("photometric.svg")).unwrap();
    assert!(svg.contains(">exact</text>") && svg.contains(">drift</text>"));

    let exact = summary.runs[0].photometric.as_ref().unwrap();
    let drift = summary.runs[1].photometric.as_ref().unwrap();
    assert_eq!(exact.len(), 12);
    assert!(summary.runs.iter().all(|r| r.error.is_none()));
    // Frame 0 compares the first frame with itself.
    assert_eq!(exact[0], Some(0.0));
    // The exact run keeps its colours far better than the one sliding off the cloth.
    let (e, d) = (exact[11].unwrap(), drift[11].unwrap());
    eprintln!("photometric cost at frame 11: exact {e}, drift {d}");
    assert!(d > 3.0 * e && d > 1e-3, "exact {e}, drift {d}");
}

#[test]
fn bad_runs_and_logs_are_named() {
    let scene = Scene::load(Path::new(SAMPLE)).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    make_run(&scene, &run, 0.0, None);
    std::fs::remove_file(run.join("0005.obj")).unwrap();
    let out = tmp.path().join("report");
    let err = write_report(
        &scene,
        &[("r".into(), run.clone())],
        &ReportOptions::default(),
        &out,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("0005.obj") && err.contains("run"), "{err}");

    make_run(&scene, &run, 0.0, None);
    std::fs::write(
        run.join("log.jsonl"),
        "{\"frame\": 1, \"seconds\": 0.2, \"load_seconds\": 0, \"wall_seconds\": 0.2, \
         \"method\": \"baseline\", \"tracked\": 1, \"triangulated\": 1}\n{\"frame\": 2}\n",
    )
    .unwrap();
    let err = write_report(
        &scene,
        &[("r".into(), run.clone())],
        &ReportOptions::default(),
        &out,
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("log.jsonl") && err.contains("line 2") && err.contains("seconds"),
        "{err}"
    );

    let err = write_report(
        &scene,
        &[("r".into(), run.clone()), ("r".into(), run.clone())],
        &ReportOptions::default(),
        &out,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("two runs are named"), "{err}");
    let opts = ReportOptions {
        frames: Some(vec![40]),
        ..ReportOptions::default()
    };
    let err = write_report(&scene, &[("r".into(), run.clone())], &opts, &out)
        .unwrap_err()
        .to_string();
    assert!(err.contains("frame 40") && err.contains("0..=11"), "{err}");
    let opts = ReportOptions {
        residual_frame: Some(0),
        ..ReportOptions::default()
    };
    let err = write_report(&scene, &[("r".into(), run.clone())], &opts, &out)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("--residual-frame") && err.contains("1..=11"),
        "{err}"
    );
    assert!(
        !out.join("index.html").exists(),
        "nothing written on bad input"
    );
}

/// A tracker log for frames 1..=11 of the sample: every frame fine but for `contradicted` (frame,
/// share of its templates the other cameras contradict) and `stalled` (a frame out of every view).
fn tracker_log(dir: &Path, contradicted: (u32, f64), stalled: u32) {
    let log: String = (1..=11u32)
        .map(|f| {
            let share = if f == contradicted.0 { contradicted.1 } else { 0.02 };
            let (pixels, information) = if f == stalled { (0, 0.0) } else { (5000, 0.7) };
            format!(
                "{{\"frame\": {f}, \"seconds\": 0.1, \"load_seconds\": 0, \"wall_seconds\": 0.1, \
                 \"method\": \"model_flow\", \"iterations\": 9, \"cost_before\": 1e-3, \
                 \"cost_after\": 1e-4, \"pixels\": {pixels}, \"contradicted_share\": {share}, \
                 \"contradicted_at_first\": 0.02, \"information_share\": {information}, \
                 \"stop\": \"converged\", \"predicted\": false, \"stalled\": {}, \
                 \"timing\": {{\"pyramids\": 0, \"patches\": 0, \"solve\": 0.1}}, \"levels\": []}}\n",
                f == stalled
            )
        })
        .collect();
    std::fs::write(dir.join("log.jsonl"), log).unwrap();
}

#[test]
fn frames_the_tracker_doubts_are_listed_shaded_plotted_and_drawn() {
    let scene = Scene::load(Path::new(SAMPLE)).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let (tracked, clean, baseline, out) = (
        tmp.path().join("tracked"),
        tmp.path().join("clean"),
        tmp.path().join("baseline"),
        tmp.path().join("report"),
    );
    // Frame 5's templates show the cameras contradicting frame 4's solution; frame 8 stalls.
    make_run(&scene, &tracked, 0.0, None);
    tracker_log(&tracked, (5, 0.4), 8);
    make_run(&scene, &clean, 0.0, None);
    tracker_log(&clean, (0, 0.0), 0);
    // The clean run's first mesh was moved onto the surface before tracking (its manifest says so).
    let mut manifest = crate::run::Manifest::new(
        crate::run::Method::ModelFlow,
        &scene,
        Vec::new(),
        crate::run::Options {
            given: Default::default(),
            used: serde_json::Value::Null,
        },
    )
    .unwrap();
    manifest.first_mesh_moved = Some(crate::tracker::SurfaceMove {
        found: crate::tracker::SurfaceOffset {
            pixels: -4.93,
            length: -0.0187,
            ratio: 12.8,
            at_limit: false,
            closed: true,
            compared: 41_200.0,
            texture_kept: 1.1,
            disparity: Some(4.4),
        },
        median: 0.0181,
        max: 0.0266,
    });
    std::fs::write(
        clean.join(crate::run::MANIFEST),
        serde_json::to_string(&manifest).unwrap(),
    )
    .unwrap();
    make_run(&scene, &baseline, 0.0, Some(&[0.1; 11]));
    let runs = vec![
        ("tracked".to_string(), tracked),
        ("clean".to_string(), clean),
        ("baseline".to_string(), baseline),
    ];
    let summary = write_report(&scene, &runs, &ReportOptions::default(), &out).unwrap();
    let checks = summary.runs[0].checks.as_ref().unwrap();
    let frames: Vec<u32> = checks.iter().map(|c| c.frame).collect();
    assert_eq!(frames, [4, 5, 8]);
    assert!(checks[2].stalled() && checks[0].suspect() && !checks[0].stalled());
    assert_eq!(summary.runs[1].checks.as_deref(), Some(&[][..]));
    assert!(summary.runs[2].checks.is_none());
    // The first frame to check is drawn beside the first, middle and last.
    assert_eq!(summary.frames, [0, 4, 5, 11]);
    let html = std::fs::read_to_string(&summary.index).unwrap();
    let links = check_links(&out, &html);
    for l in [
        "checks_information.png",
        "checks_contradicted.svg",
        "overlay_f0004_c0_cam0.png",
    ] {
        assert!(links.contains(&l.to_string()), "{l} not linked");
    }
    assert!(html.contains("<b>3 frames to check</b> (1 stalled, 3 suspect), from frame 4."));
    assert!(html.contains(
        "the other cameras contradict 40 % of where this frame left the surface, against 2 % at the first frame"
    ));
    assert!(html.contains("clean: <b>no frame to check</b>"));
    assert!(
        summary.runs[1].first_mesh_moved.is_some() && summary.runs[0].first_mesh_moved.is_none()
    );
    assert!(html.contains("clean: the scene's mesh lay 4.9 px outside the surface the cameras agree on at the first frame (they agreed 12.8× better there), so the tracker moved every vertex along its normal onto it before tracking (median 0.0181 scene units, at most 0.0266 scene units)"), "{html}");
    assert!(html.contains("baseline: no tracker log"));
    // The error plot shades the flagged frames: 4–5 suspect, 8 stalled.
    let svg = std::fs::read_to_string(out.join("error.svg")).unwrap();
    assert_eq!(svg.matches("class=\"band\"").count(), 2);
    assert!(svg.contains(">suspect frames</text>") && svg.contains(">stalled frames</text>"));
    let svg = std::fs::read_to_string(out.join("checks_contradicted.svg")).unwrap();
    assert!(svg.contains(">suspect above 10 points</text>"));
    // Two cameras have no per-camera plot (their logs have no per-camera shares here, and two
    // cameras rise together anyway).
    assert!(!out.join("checks_cameras.png").exists());
    assert!(!html.contains("checks_cameras"));
}

#[test]
fn each_cameras_own_disagreement_is_plotted_and_a_camera_named_by_it_is_listed() {
    // The real board's four cameras, runs made from the truth; the tracker's log has camera 1
    // (and camera 0, which shares its view) rising 8 points above its first frame's share from
    // frame 6 on, as a knocked camera does, while the rig's share stays low.
    let scene = Scene::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/caliscope-board-sample/scene.json"
    )))
    .unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let (run, out) = (tmp.path().join("knocked"), tmp.path().join("report"));
    make_run(&scene, &run, 0.0, None);
    let log: String = (1..=19u32)
        .map(|f| {
            let up = if f >= 6 { 0.15 } else { 0.0 };
            format!(
                "{{\"frame\": {f}, \"seconds\": 0.1, \"load_seconds\": 0, \"wall_seconds\": 0.1, \
                 \"method\": \"model_flow\", \"iterations\": 9, \"cost_before\": 1e-3, \
                 \"cost_after\": 1e-4, \"pixels\": 5000, \"contradicted_share\": 0.04, \
                 \"contradicted_at_first\": 0.02, \"information_share\": 0.7, \
                 \"contradicted_by_camera\": [{}, {}, 0.02, 0.02], \
                 \"contradicted_by_camera_at_first\": [0.02, 0.02, 0.02, 0.02], \
                 \"stop\": \"converged\", \"predicted\": false, \"stalled\": false, \
                 \"timing\": {{\"pyramids\": 0, \"patches\": 0, \"solve\": 0.1}}, \"levels\": []}}\n",
                0.02 + up,
                0.02 + up
            )
        })
        .collect();
    std::fs::write(run.join("log.jsonl"), log).unwrap();
    let opts = ReportOptions {
        flipbook: false,
        ..ReportOptions::default()
    };
    let summary = write_report(&scene, &[("knocked".into(), run)], &opts, &out).unwrap();
    let html = std::fs::read_to_string(&summary.index).unwrap();
    let links = check_links(&out, &html);
    assert!(
        links.contains(&"checks_cameras.png".to_string()),
        "{links:?}"
    );
    assert!(
        links.contains(&"checks_cameras.svg".to_string()),
        "{links:?}"
    );
    let svg = std::fs::read_to_string(out.join("checks_cameras.svg")).unwrap();
    assert_well_formed(&svg);
    for name in ["cam0", "cam1", "cam2", "cam3"] {
        assert!(
            svg.contains(&format!(">{name}</text>")),
            "{name} not in the legend"
        );
    }
    assert!(svg.contains(">named above 7.5 points for 5 frames</text>"));
    // Reports 6..=10 rise: the fifth names frames 5..=9 (the solutions they judged), and every
    // later one the frame before it.
    let frames: Vec<u32> = summary.runs[0]
        .checks
        .as_ref()
        .unwrap()
        .iter()
        .map(|c| c.frame)
        .collect();
    assert_eq!(frames, (5..=18).collect::<Vec<u32>>());
    assert!(html.contains(
        "2 cameras&#39; views have disagreed with the other cameras&#39; about where the surface is at every frame since frame 5"
    ) || html.contains(
        "2 cameras' views have disagreed with the other cameras' about where the surface is at every frame since frame 5"
    ), "{html}");
}

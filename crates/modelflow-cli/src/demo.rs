//! `modelflow demo`: the whole pipeline on embedded synthetic footage — synthesise the default
//! cloth, line a deliberately misplaced copy of its first mesh back up (`align`), track it with
//! Model Flow, run the optical-flow baseline, score both against ground truth, and write the HTML
//! report. Each step is one library call.

use crate::progress::Progress;
use anyhow::Context;
use modelflow::base::{rms_distance, Length};
use modelflow::baseline::{self, BaselineOptions};
use modelflow::input::Scene;
use modelflow::report::{alignment_picture, write_report, ReportOptions};
use modelflow::synth::{write_dataset, SynthOptions};
use modelflow::tracker::{align, median, perturb, AlignOptions, TrackOptions};
use modelflow::{evaluate, read_run, EvalReport};
use modelflow::{OpenMode, RunOptions};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// Folder for the footage, the runs and the report.
    #[arg(long, default_value = "modelflow-demo")]
    out: PathBuf,
    /// Synthetic preset (cloth or blob).
    #[arg(long, default_value = "cloth")]
    preset: String,
    /// Number of frames (default: the preset's 120).
    #[arg(long)]
    frames: Option<u32>,
    /// Skip the baseline (and show Model Flow alone in the report).
    #[arg(long)]
    no_baseline: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut synth = SynthOptions::preset(&args.preset)?;
    if let Some(f) = args.frames {
        synth.frames = f;
    }
    let footage = args.out.join("footage");
    eprintln!(
        "1/5 synthesising the '{}' preset into {}",
        args.preset,
        footage.display()
    );
    let p = Progress::new("synth", 0);
    let scene_path = write_dataset(&synth, &footage, &|done, total| {
        p.set(done as u64, total as u64)
    })?;
    p.finish();
    let scene = Scene::load(&scene_path)?;

    eprintln!(
        "2/5 lining up a copy of the first mesh misplaced by 5 % of its size and 10° (align)"
    );
    let t = std::time::Instant::now();
    let misplaced = scene
        .mesh
        .with_positions(perturb(&scene.mesh, 0.05, 10.0, 1));
    let first = scene.load_images(scene.first)?;
    let aligned = align(
        &misplaced,
        &scene.cameras,
        scene.first,
        &first,
        &AlignOptions::default(),
    )?;
    let align_seconds = t.elapsed().as_secs_f64();
    let picture = args.out.join("align.png");
    modelflow::input::write_png(
        &picture,
        &alignment_picture(
            &scene.cameras,
            scene.first,
            &first,
            &misplaced,
            &misplaced.with_positions(aligned.positions.clone()),
        )?,
    )?;
    let rms = |x: &[nalgebra::Point3<f64>]| {
        100.0 * rms_distance(x, &scene.mesh.positions) / scene.mesh.bbox_diagonal()
    };
    let (align_before, align_after) = (rms(&misplaced.positions), rms(&aligned.positions));

    eprintln!("3/5 tracking with Model Flow");
    let mf_dir = args.out.join("runs").join("modelflow");
    // The demo's folder is its own: each demo replaces its runs (other files are kept).
    let own = RunOptions {
        mode: OpenMode::Force,
        command: std::env::args().collect(),
        ..RunOptions::default()
    };
    let mf = crate::track::run_scene(&scene, &TrackOptions::default(), &mf_dir, &own)?;
    let mut runs = vec![(
        "Model Flow".to_string(),
        mf_dir.clone(),
        mf.median_frame_seconds,
    )];

    if !args.no_baseline {
        eprintln!("4/5 tracking with the optical-flow baseline (Lucas-Kanade + triangulation)");
        let bl_dir = args.out.join("runs").join("baseline");
        let p = Progress::new("baseline", (scene.last - scene.first) as u64);
        let bl = baseline::run(&scene, &BaselineOptions::default(), &bl_dir, &own, &|f| {
            p.at(
                (f.frame - scene.first) as u64,
                &format!("frame {}", f.frame),
            )
        })
        .context("running the baseline")?;
        p.finish();
        runs.push(("LK baseline".to_string(), bl_dir, median(&bl.seconds)));
    }

    eprintln!("5/5 scoring and writing the report");
    let report_dir = args.out.join("report");
    let named: Vec<(String, PathBuf)> = runs
        .iter()
        .map(|(n, d, _)| (n.clone(), d.clone()))
        .collect();
    let summary = write_report(&scene, &named, &ReportOptions::default(), &report_dir)?;

    println!(
        "{:<12} {:>14} {:>14} {:>16}",
        "run", "mean error", "final error", "time per frame"
    );
    let len = Length::of(scene.units);
    for (name, dir, secs) in &runs {
        let e = score(&scene, dir)?;
        println!(
            "{:<12} {:>7.2} {u} {:>4.2}% {:>6.2} {u} {:>4.2}% {:>12.0} ms",
            name,
            len.value(e.rms_mean),
            e.rms_mean_pct,
            len.value(e.rms_final),
            e.rms_final_pct,
            secs * 1e3,
            u = len.unit()
        );
    }
    println!("(errors: RMS vertex distance to ground truth, mean over frames and last frame; % of the first mesh's bounding-box diagonal; time: median per frame, image loading included)");
    println!(
        "align: the first mesh misplaced by {align_before:.2}% came back to {align_after:.3}% in {:.1} s ({})",
        align_seconds,
        picture.display()
    );
    println!("report: {}", summary.index.display());
    Ok(())
}

fn score(scene: &Scene, dir: &Path) -> anyhow::Result<EvalReport> {
    Ok(evaluate(scene, &read_run(dir)?)?)
}

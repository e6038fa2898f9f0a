//! `modelflow bench`: the tracker's speed on the default 640×480 two-camera cloth (or any scene):
//! milliseconds per frame end to end (image loading included, and also shown apart), per solver
//! iteration, and pixel residuals evaluated per second — medians over the sequence. With
//! `--capture-range`, the largest per-frame motion tracked instead (see `capture`); with
//! `--scale`, the cost model over cameras, image sizes and vertices (see `scale`).

use crate::capture;
use crate::progress::Progress;
use modelflow::input::Scene;
use modelflow::synth::{write_dataset, SynthOptions};
use modelflow::tracker::{median, track_scene, FrameReport, TrackOptions};
use modelflow::{FrameLog, OpenMode, RunOptions};
use serde::Serialize;
use std::path::PathBuf;

#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Scene to time (default: the synthetic default cloth, written once into --work).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Folder for the synthetic footage and the run.
    #[arg(long, default_value = "target/bench")]
    work: PathBuf,
    /// Frames of synthetic footage (default: the preset's 120; with --capture-range, 7 per speed).
    #[arg(long)]
    frames: Option<u32>,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
    /// Measure the capture range instead: the largest hand-held motion per frame (synth
    /// --shake) tracked with every frame within 1 % of the object's size.
    #[arg(long)]
    capture_range: bool,
    /// Capture range: synthetic preset.
    #[arg(long, default_value = "blob")]
    preset: String,
    /// Capture range: image size.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Capture range: speeds tried, pixels per frame, comma-separated, ascending.
    #[arg(long, value_delimiter = ',', default_value = "5,10,20,30,40,50,60,80")]
    speeds: Vec<f64>,
    /// Measure the cost model instead: ms per frame and peak memory over a grid of camera
    /// counts, image sizes and vertex counts (synthetic cloth in memory, default 3 frames per
    /// point), and the fitted growth with pixels and vertices.
    #[arg(long)]
    scale: bool,
    /// Cost model: camera counts, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "2,4,8")]
    scale_cameras: Vec<usize>,
    /// Cost model: image sizes, comma-separated WIDTHxHEIGHT.
    #[arg(long, value_delimiter = ',', default_value = "640x480,1920x1080,3840x2160", value_parser = crate::scale::parse_size)]
    scale_sizes: Vec<(u32, u32)>,
    /// Cost model: mesh vertex counts, comma-separated (rounded to a square grid).
    #[arg(long, value_delimiter = ',', default_value = "1681,10000,40000")]
    scale_vertices: Vec<usize>,
    #[command(flatten)]
    device: crate::device::DeviceArgs,
}

/// The figures `bench` reports.
#[derive(Serialize)]
struct BenchReport {
    scene: PathBuf,
    frames: usize,
    threads: usize,
    /// Where the solver's per-pixel work ran: `cpu`, or the GPU's name.
    device: String,
    /// Median wall time per frame, image loading included (loading overlaps the previous solve).
    ms_per_frame: f64,
    /// Median time to read one frame's images (all cameras); overlaps the previous solve.
    ms_load: f64,
    /// Median time to build one frame's image pyramids; overlaps the previous solve too.
    ms_pyramids: f64,
    /// Median solve time per frame (template patches and Gauss–Newton).
    ms_solve: f64,
    /// Of the solve: building the template patches.
    ms_patches: f64,
    /// Of the solve: evaluating the cost and its normal equations (the per-pixel work).
    ms_evaluation: f64,
    /// Of the solve: solving the normal equations (PCG, rigid steps).
    ms_linear_solver: f64,
    /// Median time per Gauss–Newton iteration (all levels).
    ms_per_iteration: f64,
    /// With `--device gpu`: where the GPU path's time went, over the whole run.
    gpu: Option<modelflow::tracker::GpuStats>,
    /// Median iterations per frame.
    iterations: f64,
    /// RGB residuals evaluated per second inside the solver (3 per pixel comparison).
    residuals_per_second: f64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.scale {
        if let Some(c) = args.scale_cameras.iter().find(|c| !(2..=16).contains(*c)) {
            anyhow::bail!("--scale-cameras {c}: expected 2 to 16 cameras");
        }
        if let Some(v) = args
            .scale_vertices
            .iter()
            .find(|v| !(9..=1_000_000).contains(*v))
        {
            anyhow::bail!("--scale-vertices {v}: expected 9 to 1000000 vertices");
        }
        let report = crate::scale::measure(&crate::scale::ScaleOptions {
            cameras: args.scale_cameras,
            sizes: args.scale_sizes,
            vertices: args.scale_vertices,
            frames: args.frames.unwrap_or(3),
            gpu: args.device.open()?,
        })?;
        if args.json {
            println!("{}", serde_json::to_string(&report)?);
        } else {
            crate::scale::print(&report);
        }
        return Ok(());
    }
    if args.capture_range {
        if args.speeds.is_empty()
            || args
                .speeds
                .iter()
                .any(|v| !(v.is_finite() && (0.0..=1000.0).contains(v)))
            || args.speeds.windows(2).any(|w| w[0] >= w[1])
        {
            anyhow::bail!(
                "--speeds {:?}: expected ascending speeds from 0 to 1000 pixels per frame",
                args.speeds
            );
        }
        let report = capture::measure(&capture::CaptureOptions {
            preset: args.preset,
            width: args.width,
            height: args.height,
            frames: args.frames.unwrap_or(7),
            speeds: args.speeds,
            track: TrackOptions::default(),
        })?;
        if args.json {
            println!("{}", serde_json::to_string(&report)?);
        } else {
            capture::print(&report);
        }
        return Ok(());
    }
    let scene_path = match &args.scene {
        Some(s) => s.clone(),
        None => {
            let mut o = SynthOptions::default();
            if let Some(f) = args.frames {
                o.frames = f;
            }
            let dir = args.work.join(format!("cloth-{}", o.frames));
            let path = dir.join("scene.json");
            if Scene::load(&path).is_err() {
                eprintln!("writing the default cloth into {} (once)", dir.display());
                let p = Progress::new("synth", 0);
                write_dataset(&o, &dir, &|d, t| p.set(d as u64, t as u64))?;
                p.finish();
            }
            path
        }
    };
    let scene = Scene::load(&scene_path)?;
    let out = args.work.join("run");
    let mut logs: Vec<FrameLog> = Vec::new();
    let p = Progress::new("bench", (scene.last - scene.first) as u64);
    // The run folder is the benchmark's own: each run replaces the last.
    let run = RunOptions {
        mode: OpenMode::Force,
        gpu: args.device.open()?,
        ..RunOptions::default()
    };
    let device = run
        .gpu
        .as_ref()
        .map_or_else(|| "cpu".to_string(), |g| g.name().to_string());
    track_scene(&scene, &TrackOptions::default(), &out, &run, &mut |f| {
        p.tick(&format!("frame {} {:.0} ms", f.frame, f.wall_seconds * 1e3));
        logs.push(f.clone());
    })?;
    p.finish();
    let rows: Vec<(&FrameLog, &FrameReport)> = logs
        .iter()
        .filter_map(|l| l.model_flow().map(|r| (l, r)))
        .collect();
    type Row<'a> = (&'a FrameLog, &'a FrameReport);
    let per = |f: &dyn Fn(&Row) -> f64| median(&rows.iter().map(f).collect::<Vec<_>>());
    let solve_secs: f64 = rows
        .iter()
        .flat_map(|(_, r)| &r.levels)
        .map(|s| s.seconds)
        .sum();
    let evaluations: u64 = rows
        .iter()
        .flat_map(|(_, r)| &r.levels)
        .map(|s| s.pixel_evaluations)
        .sum();
    let report = BenchReport {
        scene: scene_path,
        frames: rows.len(),
        threads: rayon::current_num_threads(),
        device,
        ms_per_frame: per(&|(l, _)| l.wall_seconds) * 1e3,
        ms_load: per(&|(l, _)| l.load_seconds) * 1e3,
        ms_pyramids: per(&|(_, r)| r.timing.pyramids) * 1e3,
        ms_solve: per(&|(_, r)| r.timing.patches + r.timing.solve) * 1e3,
        ms_patches: per(&|(_, r)| r.timing.patches) * 1e3,
        ms_evaluation: per(&|(_, r)| r.levels.iter().map(|s| s.evaluation_seconds).sum()) * 1e3,
        ms_linear_solver: per(&|(_, r)| r.levels.iter().map(|s| s.linear_solver_seconds).sum())
            * 1e3,
        ms_per_iteration: per(&|(_, r)| {
            let it = r
                .levels
                .iter()
                .map(|s| s.iterations.len())
                .sum::<usize>()
                .max(1);
            r.levels.iter().map(|s| s.seconds).sum::<f64>() / it as f64
        }) * 1e3,
        iterations: per(&|(_, r)| r.iterations as f64),
        gpu: run.gpu.as_ref().map(|g| g.stats()),
        residuals_per_second: 3.0 * evaluations as f64 / solve_secs.max(1e-12),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!("scene                {}", report.scene.display());
        println!(
            "frames solved        {} ({} threads, per-pixel work on {})",
            report.frames, report.threads, report.device
        );
        println!(
            "per frame, end to end {:8.1} ms  (median; image loading included)",
            report.ms_per_frame
        );
        println!(
            "  image loading       {:8.1} ms  (median; overlapped with the previous solve)",
            report.ms_load
        );
        println!(
            "  image pyramids      {:8.1} ms  (median; also overlapped with the previous solve)",
            report.ms_pyramids
        );
        println!(
            "  solve               {:8.1} ms  (median; template patches and Gauss-Newton)",
            report.ms_solve
        );
        println!(
            "    template patches  {:8.1} ms  (median; the finer levels' overlapped with the coarser solves)",
            report.ms_patches
        );
        println!(
            "    evaluations       {:8.1} ms  (median; cost and normal equations, on {})",
            report.ms_evaluation, report.device
        );
        let solves_on = match &report.gpu {
            Some(g) if g.linear_solves > 0 => "the GPU's for the larger systems",
            _ => "on the CPU",
        };
        println!(
            "    linear solves     {:8.1} ms  (median; PCG and rigid steps, {solves_on})",
            report.ms_linear_solver
        );
        println!(
            "per solver iteration  {:8.2} ms  (median; {} iterations per frame)",
            report.ms_per_iteration, report.iterations
        );
        println!(
            "residuals per second  {:8.1} M",
            report.residuals_per_second / 1e6
        );
        if let Some(g) = &report.gpu {
            let per_frame = |s: f64| s * 1e3 / report.frames.max(1) as f64;
            println!(
                "on the GPU, per frame (mean): kernels {:.1} ms in {:.1} evaluations, positions up and sums back {:.1} ms, uploads {:.1} ms host + {:.1} ms copy ({:.1} per frame)",
                per_frame(g.kernel_seconds),
                g.evaluations as f64 / report.frames.max(1) as f64,
                per_frame(g.transfer_seconds),
                per_frame(g.upload_host_seconds),
                per_frame(g.upload_copy_seconds),
                g.uploads as f64 / report.frames.max(1) as f64
            );
            if g.linear_solves > 0 {
                println!(
                    "linear solves on the GPU, per frame (mean): {:.1} solves, {:.0} CG iterations, {:.1} ms, of which {:.1} ms set-up (the preconditioner built on the CPU, the system uploaded)",
                    g.linear_solves as f64 / report.frames.max(1) as f64,
                    g.cg_iterations as f64 / report.frames.max(1) as f64,
                    per_frame(g.linear_solve_seconds),
                    per_frame(g.linear_setup_seconds)
                );
            }
        }
    }
    Ok(())
}

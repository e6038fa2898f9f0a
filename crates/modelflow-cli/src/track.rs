//! `modelflow track`: tracks a scene's mesh through its frames and writes one OBJ per frame and a
//! JSON-lines log, with a progress bar (plain lines when stderr is not a terminal).

use crate::progress::Progress;
use modelflow::scene::Scene;
use modelflow::solve::{Interpolation, SolverOptions};
use modelflow::springs::SpringParams;
use modelflow::track::{track_scene, TrackOptions};
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug)]
pub struct TrackArgs {
    /// Pyramid levels solved coarse to fine (1 = full resolution only).
    #[arg(long, default_value_t = TrackOptions::default().levels)]
    pub levels: usize,
    /// Weight of the first frame as a second template (0 = compare with the previous frame only, as in the thesis).
    #[arg(long, default_value_t = TrackOptions::default().anchor_weight)]
    pub anchor_weight: f64,
    /// Spring constant k of the cubic edge springs (Eq. 5.16).
    #[arg(long, default_value_t = TrackOptions::default().solver.springs.k)]
    pub spring_k: f64,
    /// Spring threshold T, as a fraction of the rest length (Eq. 5.16).
    #[arg(long, default_value_t = TrackOptions::default().solver.springs.t)]
    pub spring_t: f64,
    /// Weight of the frame-to-frame membrane term (0 = off).
    #[arg(long, default_value_t = TrackOptions::default().solver.springs.membrane)]
    pub membrane: f64,
    /// Weight of the bending term that keeps the mesh's local shape close to its rest shape up to
    /// rotation (0 = off).
    #[arg(long, default_value_t = TrackOptions::default().solver.springs.bending)]
    pub bending: f64,
    /// Gauss-Newton iterations at most per frame and level.
    #[arg(long, default_value_t = TrackOptions::default().solver.max_iterations)]
    pub max_iterations: usize,
    /// Stop a level when a step lowers the cost by less than this fraction.
    #[arg(long, default_value_t = TrackOptions::default().solver.min_relative_decrease)]
    pub min_decrease: f64,
    /// Huber threshold on the RGB residual (image values 0..1).
    #[arg(long, default_value_t = TrackOptions::default().solver.huber)]
    pub huber: f64,
    /// Gaussian smoothing of the images, in pixels.
    #[arg(long, default_value_t = TrackOptions::default().blur)]
    pub blur: f64,
    /// Compare every pixel of the previous frame at full resolution (default: every other one,
    /// a checkerboard at twice the weight, which halves the work at no measurable loss).
    #[arg(long)]
    pub all_pixels: bool,
    /// How the next frame is sampled between pixel centres: Catmull-Rom bicubic, or bilinear
    /// (about a fifth less time per frame, slightly less accurate).
    #[arg(long, value_enum, default_value_t = InterpolationArg::Cubic)]
    pub interpolation: InterpolationArg,
}

/// `--interpolation`'s values (the library's `solve::Interpolation`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum InterpolationArg {
    Cubic,
    Linear,
}

impl TrackArgs {
    pub fn options(&self) -> TrackOptions {
        let d = TrackOptions::default();
        TrackOptions {
            levels: self.levels,
            anchor_weight: self.anchor_weight,
            blur: self.blur,
            checkerboard: !self.all_pixels,
            solver: SolverOptions {
                springs: SpringParams {
                    k: self.spring_k,
                    t: self.spring_t,
                    membrane: self.membrane,
                    bending: self.bending,
                },
                max_iterations: self.max_iterations,
                min_relative_decrease: self.min_decrease,
                huber: self.huber,
                interpolation: match self.interpolation {
                    InterpolationArg::Cubic => Interpolation::Cubic,
                    InterpolationArg::Linear => Interpolation::Linear,
                },
                ..d.solver
            },
            ..d
        }
    }
}

#[derive(clap::Args)]
pub struct Args {
    /// The scene file (modelflow-scene/1).
    #[arg(long)]
    scene: PathBuf,
    /// Output folder: {frame:04}.obj per frame and log.jsonl.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    track: TrackArgs,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let scene = Scene::load(&args.scene)?;
    let summary = run_scene(&scene, &args.track.options(), &args.out)?;
    eprintln!(
        "tracked {} frames in {:.1} s ({:.0} ms per frame, median; {} iterations per frame, median) -> {}",
        summary.frames,
        summary.total_seconds,
        summary.median_frame_seconds * 1e3,
        summary.median_iterations,
        args.out.display()
    );
    Ok(())
}

/// Tracks with a progress bar; shared by `track` and `demo`.
pub fn run_scene(
    scene: &Scene,
    opts: &TrackOptions,
    out: &std::path::Path,
) -> anyhow::Result<modelflow::track::TrackSummary> {
    let total = (scene.last - scene.first) as u64;
    let progress = Progress::new("track", total);
    let summary = track_scene(scene, opts, out, &mut |f| {
        progress.tick(&format!(
            "frame {} · {} it · cost {:.2e} -> {:.2e} · {:.0} ms",
            f.report.frame,
            f.report.iterations,
            f.report.cost_before,
            f.report.cost_after,
            f.wall_seconds * 1e3
        ));
    })?;
    progress.finish();
    Ok(summary)
}

//! `modelflow track`: tracks a scene's mesh through its frames and writes one OBJ per frame and a
//! JSON-lines log, with a progress bar (plain lines when stderr is not a terminal).

use crate::progress::Progress;
use crate::runfolder::{run_options, Invocation, OutArgs};
use modelflow::input::Scene;
use modelflow::tracker::{
    track_scene, Interpolation, Regularisation, SolverOptions, TrackOptions, TrackSummary,
};
use modelflow::RunOptions;

#[derive(clap::Args, Clone, Debug)]
pub struct TrackArgs {
    /// Pyramid levels solved coarse to fine (1 = full resolution only).
    #[arg(long, default_value_t = TrackOptions::default().levels)]
    pub levels: usize,
    /// Weight of the first frame as a second template (0 = compare with the previous frame only, as in the thesis).
    #[arg(long, default_value_t = TrackOptions::default().anchor_weight)]
    pub anchor_weight: f64,
    /// Spring constant k of the cubic edge springs (Eq. 5.16).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.spring_k)]
    pub spring_k: f64,
    /// Spring threshold T, as a fraction of the rest length (Eq. 5.16).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.spring_t)]
    pub spring_t: f64,
    /// Weight of the frame-to-frame membrane term (0 = off).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.membrane)]
    pub membrane: f64,
    /// Weight of the bending term that keeps the mesh's local shape close to its rest shape up to
    /// rotation (0 = off).
    #[arg(long, default_value_t = TrackOptions::default().regularisation.bending)]
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
            regularisation: Regularisation {
                spring_k: self.spring_k,
                spring_t: self.spring_t,
                membrane: self.membrane,
                bending: self.bending,
            },
            solver: SolverOptions {
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
    scene: std::path::PathBuf,
    #[command(flatten)]
    out: OutArgs,
    /// Continue the run in --out from its last complete frame (same scene, same options); the
    /// result is identical to an uninterrupted run.
    #[arg(long, conflicts_with = "force")]
    resume: bool,
    #[command(flatten)]
    track: TrackArgs,
}

pub fn run(args: Args, invocation: &Invocation) -> anyhow::Result<()> {
    let scene = Scene::load(&args.scene)?;
    let run = run_options(args.out.mode(args.resume), invocation);
    let summary = run_scene(&scene, &args.track.options(), &args.out.out, &run)?;
    let resumed = match summary.resumed_from {
        Some(f) => format!(", resumed after frame {f}"),
        None => String::new(),
    };
    eprintln!(
        "tracked frames {}..={} ({} solved now{resumed}) in {:.1} s ({:.0} ms per frame, median; {} iterations per frame, median) -> {}",
        scene.first,
        scene.last,
        summary.solved,
        summary.total_seconds,
        summary.median_frame_seconds * 1e3,
        summary.median_iterations,
        args.out.out.display()
    );
    Ok(())
}

/// Tracks with a progress bar; shared by `track` and `demo`. An interrupted run says how to
/// continue it.
pub fn run_scene(
    scene: &Scene,
    opts: &TrackOptions,
    out: &std::path::Path,
    run: &RunOptions,
) -> anyhow::Result<TrackSummary> {
    let total = (scene.last - scene.first) as u64;
    let progress = Progress::new("track", total);
    let result = track_scene(scene, opts, out, run, &mut |f| {
        let r = f.model_flow();
        progress.at(
            (f.frame - scene.first) as u64,
            &format!(
                "frame {} · {} it · cost {:.2e} -> {:.2e} · {:.0} ms",
                f.frame,
                r.map_or(0, |r| r.iterations),
                r.map_or(0.0, |r| r.cost_before),
                r.map_or(0.0, |r| r.cost_after),
                f.wall_seconds * 1e3
            ),
        );
    });
    progress.finish();
    result.map_err(|e| {
        let interrupted = matches!(e, modelflow::Error::Interrupted { .. });
        let e = anyhow::Error::new(e);
        if interrupted {
            e.context(format!(
                "{} can be continued: run the same command with --resume",
                out.display()
            ))
        } else {
            e
        }
    })
}

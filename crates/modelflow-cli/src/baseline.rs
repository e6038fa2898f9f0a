//! `modelflow baseline`: the optical-flow-then-triangulation baseline ("Universal Capture") over a
//! scene, written like `track`'s output so that `eval` can score it.

use crate::progress::Progress;
use crate::runfolder::{run_options, Invocation, OutArgs};
use anyhow::Context;
use modelflow::baseline::{self, BaselineOptions, LkOptions, Seeding};
use std::path::PathBuf;

#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// The scene file (modelflow-scene/1 JSON).
    #[arg(long)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub select: crate::select::SelectArgs,
    #[command(flatten)]
    memory: crate::select::MemoryArgs,
    #[command(flatten)]
    pub out: OutArgs,
    /// Where each frame's 2D tracks start: `reprojected` (from the triangulated vertex) or
    /// `chained` (each camera's own 2D track continues, as Universal Capture did).
    #[arg(long, default_value = "reprojected", value_parser = ["reprojected", "chained"])]
    pub seeding: String,
    /// Lucas-Kanade window side in pixels (odd, 3 to 101).
    #[arg(long, default_value_t = 21)]
    pub window: usize,
    /// Pyramid levels including full resolution (1 to 12).
    #[arg(long, default_value_t = 4)]
    pub levels: usize,
    /// Forward-backward check threshold in pixels (0 disables it; at most 1000).
    #[arg(long, default_value_t = 1.0)]
    pub fb: f64,
    /// Largest accepted reprojection error of a triangulated vertex, in pixels (above 0, at most
    /// 1000).
    #[arg(long, default_value_t = 2.0)]
    pub max_reprojection: f64,
}

pub fn run(args: Args, invocation: &Invocation) -> anyhow::Result<()> {
    if args.window % 2 == 0 || !(3..=101).contains(&args.window) {
        return Err(modelflow::Error::option(
            "--window",
            args.window,
            "an odd number of pixels from 3 to 101",
        )
        .into());
    }
    if !(args.fb.is_finite() && (0.0..=1000.0).contains(&args.fb)) {
        return Err(modelflow::Error::option(
            "--fb",
            args.fb,
            "a number in [0, 1000] pixels (0 = off)",
        )
        .into());
    }
    let defaults = BaselineOptions::default();
    let opts = BaselineOptions {
        seeding: if args.seeding == "chained" {
            Seeding::Chained
        } else {
            Seeding::Reprojected
        },
        lk: LkOptions {
            window_radius: args.window / 2,
            levels: args.levels,
            forward_backward: (args.fb > 0.0).then_some(args.fb),
            ..defaults.lk.clone()
        },
        max_reprojection_error: args.max_reprojection,
        ..defaults
    };
    opts.validate()?;
    let scene = args.select.load(&args.scene)?;
    args.memory.check(&scene)?;
    crate::select::warn_calibration(&scene);
    let run = run_options(args.out.mode(false), invocation);
    let progress = Progress::new("baseline", (scene.last - scene.first) as u64);
    let result = baseline::run(&scene, &opts, &args.out.out, &run, &|f| {
        progress.at(
            (f.frame - scene.first) as u64,
            &format!("frame {} · {:.0} ms", f.frame, f.wall_seconds * 1e3),
        );
    });
    progress.finish();
    let summary = result.with_context(|| format!("baseline on {}", args.scene.display()))?;
    eprintln!(
        "wrote frames {}..={} to {} ({:.0} ms per frame, median)",
        scene.first,
        scene.last,
        summary.out_dir.display(),
        modelflow::tracker::median(&summary.seconds) * 1e3
    );
    Ok(())
}

//! `modelflow baseline`: the optical-flow-then-triangulation baseline ("Universal Capture") over a
//! scene, written like `track`'s output so that `eval` can score it.

use crate::progress::Progress;
use anyhow::Context;
use modelflow::baseline::{self, BaselineOptions, Seeding};
use modelflow::lk::LkOptions;
use modelflow::scene::Scene;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// The scene file (modelflow-scene/1 JSON).
    #[arg(long)]
    pub scene: PathBuf,
    /// Output folder: {frame:04}.obj per frame and log.jsonl.
    #[arg(long)]
    pub out: PathBuf,
    /// Where each frame's 2D tracks start: `reprojected` (from the triangulated vertex) or
    /// `chained` (each camera's own 2D track continues, as Universal Capture did).
    #[arg(long, default_value = "reprojected", value_parser = ["reprojected", "chained"])]
    pub seeding: String,
    /// Lucas-Kanade window side in pixels (odd).
    #[arg(long, default_value_t = 21)]
    pub window: usize,
    /// Pyramid levels including full resolution.
    #[arg(long, default_value_t = 4)]
    pub levels: usize,
    /// Forward-backward check threshold in pixels (0 disables it).
    #[arg(long, default_value_t = 1.0)]
    pub fb: f64,
    /// Largest accepted reprojection error of a triangulated vertex, in pixels.
    #[arg(long, default_value_t = 2.0)]
    pub max_reprojection: f64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.window < 3 || args.window % 2 == 0 {
        anyhow::bail!(
            "--window must be an odd number of pixels >= 3, got {}",
            args.window
        );
    }
    if !(args.fb >= 0.0 && args.max_reprojection > 0.0) {
        anyhow::bail!("--fb must be >= 0 and --max-reprojection > 0");
    }
    let scene = Scene::load(&args.scene)?;
    let defaults = BaselineOptions::default();
    let opts = BaselineOptions {
        seeding: if args.seeding == "chained" {
            Seeding::Chained
        } else {
            Seeding::Reprojected
        },
        lk: LkOptions {
            window_radius: args.window / 2,
            levels: args.levels.max(1),
            forward_backward: (args.fb > 0.0).then_some(args.fb),
            ..defaults.lk.clone()
        },
        max_reprojection_error: args.max_reprojection,
        ..defaults
    };
    let progress = Progress::new("baseline", (scene.last - scene.first + 1) as u64);
    let summary = baseline::run(&scene, &opts, &args.out, &|frame| {
        progress.tick(&format!("frame {frame}"));
    })
    .with_context(|| format!("baseline on {}", args.scene.display()))?;
    progress.finish();
    let n = summary.seconds.len().max(1) as f64;
    eprintln!(
        "wrote {} frames to {} ({:.3} s per frame)",
        summary.frames.len() + 1,
        summary.out_dir.display(),
        summary.seconds.iter().sum::<f64>() / n
    );
    Ok(())
}

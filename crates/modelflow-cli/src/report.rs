//! `modelflow report`: writes an HTML report (error or photometric-cost plot, wireframe overlays,
//! oblique views, error and confidence maps, a flipbook of every frame) comparing runs on a scene.

use anyhow::{bail, Context};
use modelflow::input::SceneFile;
use modelflow::report::{write_report, ReportOptions};
use std::path::PathBuf;

#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// The scene file.
    #[arg(long)]
    scene: PathBuf,
    #[command(flatten)]
    select: crate::select::SelectArgs,
    /// A run to show, as NAME=DIR (DIR holds one OBJ per frame and optionally log.jsonl);
    /// repeat for several runs.
    #[arg(long = "run", value_name = "NAME=DIR", required = true)]
    runs: Vec<String>,
    /// The report folder (created if missing); index.html is written there.
    #[arg(long)]
    out: PathBuf,
    /// Frames to draw overlays for, comma separated (default: first, middle, last, and each
    /// run's first frame to check).
    #[arg(long, value_delimiter = ',')]
    overlay_frames: Option<Vec<u32>>,
    /// Degrees the oblique camera is turned about the vertical axis (-180 to 180).
    #[arg(long, default_value_t = 60.0)]
    oblique_degrees: f64,
    /// Put every run's error map on one colour scale (default: each run on its own, so that a
    /// good run's map stays readable beside a bad one).
    #[arg(long)]
    shared_scale: bool,
    /// The frame whose photometric residual image is drawn, against the previous frame and the
    /// first (default: the last frame; must come after the first).
    #[arg(long, value_name = "N")]
    residual_frame: Option<u32>,
    /// Leave out the flipbook (every frame's overlays as JPEGs, scrubbable in the page).
    #[arg(long)]
    no_flipbook: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut runs = Vec::new();
    for r in &args.runs {
        let Some((name, dir)) = r.split_once('=') else {
            bail!("--run {r:?}: expected NAME=DIR");
        };
        if name.is_empty() || dir.is_empty() {
            bail!("--run {r:?}: expected NAME=DIR with both parts non-empty");
        }
        runs.push((name.to_string(), PathBuf::from(dir)));
    }
    let file = SceneFile::read(&args.scene)?;
    let dirs: Vec<&std::path::Path> = runs.iter().map(|(_, d)| d.as_path()).collect();
    let scene = args
        .select
        .or_the_runs(&file, &dirs, "reporting on")?
        .load(&args.scene)?;
    let opts = ReportOptions {
        frames: args.overlay_frames,
        oblique_degrees: args.oblique_degrees,
        shared_error_scale: args.shared_scale,
        flipbook: !args.no_flipbook,
        residual_frame: args.residual_frame,
        ..ReportOptions::default()
    };
    let summary = write_report(&scene, &runs, &opts, &args.out)
        .with_context(|| format!("writing the report into {}", args.out.display()))?;
    println!("{}", summary.index.display());
    Ok(())
}

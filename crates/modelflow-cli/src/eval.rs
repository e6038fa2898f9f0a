//! `modelflow eval`: scores a run folder (one OBJ per frame) against a scene's ground truth and
//! prints a table, or one JSON object with `--json`.

use anyhow::Context;
use modelflow::input::Scene;
use modelflow::{evaluate, read_run, EvalReport};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// The scene file (must have ground truth).
    #[arg(long)]
    scene: PathBuf,
    #[command(flatten)]
    select: crate::select::SelectArgs,
    /// The run folder: one OBJ per frame (frame = last number in the file name).
    #[arg(long)]
    track: PathBuf,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let scene = args.select.apply(Scene::load(&args.scene)?)?;
    let run = read_run(&args.track)?;
    let report =
        evaluate(&scene, &run).with_context(|| format!("evaluating {}", args.track.display()))?;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", table(&report));
    }
    Ok(())
}

fn table(r: &EvalReport) -> String {
    let mut s = format!(
        "{:>6}  {:>12}  {:>8}  {:>12}  {:>8}  {:>6}\n",
        "frame", "rms", "rms %", "max", "seen %", "seen"
    );
    for e in &r.per_frame {
        s += &format!(
            "{:>6}  {:>12.6}  {:>8.4}  {:>12.6}  {:>8.4}  {:>6}\n",
            e.frame, e.rms, e.rms_pct, e.max, e.seen_rms_pct, e.seen
        );
    }
    s += &format!(
        "{} frames, scale (bbox diagonal) {:.6}\nrms mean  {:.6} ({:.4} %)\nrms final {:.6} ({:.4} %)\n",
        r.frames, r.scale, r.rms_mean, r.rms_mean_pct, r.rms_final, r.rms_final_pct
    );
    s += &format!(
        "seen vertices (by some camera, in the truth): rms mean {:.6} ({:.4} %), final {:.6} ({:.4} %)\n",
        r.seen_rms_mean, r.seen_rms_mean_pct, r.seen_rms_final, r.seen_rms_final_pct
    );
    s
}

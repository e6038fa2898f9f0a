//! `modelflow eval`: scores a run folder (one OBJ per frame) against a scene's ground truth and
//! prints a table, or one JSON object with `--json`.

use anyhow::Context;
use modelflow::base::Length;
use modelflow::input::SceneFile;
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
    let file = SceneFile::read(&args.scene)?;
    let chosen = args.select.frames.is_some();
    let select = args
        .select
        .or_the_runs(&file, &[&args.track], "evaluating")?;
    let scene = select.load(&args.scene)?;
    let mut run = read_run(&args.track)?;
    if let Some(other) = modelflow::run::made_from_another_scene(&args.track, &args.scene) {
        eprintln!(
            "warning: {} was made from {}, and is scored here against {}",
            args.track.display(),
            other.display(),
            args.scene.display()
        );
    }
    if chosen {
        // `--frames` scores part of a run: the frames outside it are left aside, not refused.
        run.retain(|(f, _)| scene.frames().contains(f));
    }
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
    let len = Length::of(r.units);
    let u = len.unit();
    let mut s = format!(
        "{:>6}  {:>14}  {:>8}  {:>14}  {:>8}  {:>6}  {:>8}  {:>8}\n",
        "frame",
        format!("rms ({u})"),
        "rms %",
        format!("max ({u})"),
        "seen %",
        "seen",
        "followed",
        "shape %"
    );
    for e in &r.per_frame {
        s += &format!(
            "{:>6}  {:>14}  {:>8.4}  {:>14}  {:>8.4}  {:>6}  {:>8}  {:>8.4}\n",
            e.frame,
            len.show(e.rms),
            e.rms_pct,
            len.show(e.max),
            e.seen_rms_pct,
            e.seen,
            e.followed.map_or("-".to_string(), |f| format!("{f:.3}")),
            e.shape_rms_pct
        );
    }
    s += &format!(
        "{} frames, scale (bbox diagonal) {} {u}\nrms mean  {} {u} ({:.4} %)\nrms final {} {u} ({:.4} %)\n",
        r.frames,
        len.show(r.scale),
        len.show(r.rms_mean),
        r.rms_mean_pct,
        len.show(r.rms_final),
        r.rms_final_pct
    );
    s += &format!(
        "seen vertices (by some camera, in the truth): rms mean {} {u} ({:.4} %), final {} {u} ({:.4} %)\n",
        len.show(r.seen_rms_mean),
        r.seen_rms_mean_pct,
        len.show(r.seen_rms_final),
        r.seen_rms_final_pct
    );
    s += &format!(
        "shape alone (after each frame's best rigid fit to the truth): rms mean {:.4} %, final {:.4} %; that fit turns {:.3}° and shifts {} {u} on average\n",
        r.shape_rms_mean_pct,
        r.shape_rms_final_pct,
        r.pose_turn_deg_mean,
        len.show(r.pose_shift_mean)
    );
    let groups: Vec<String> = r
        .by_views
        .iter()
        .map(|v| {
            format!(
                "{} ({:.0} vertices): {:.4} %",
                v.cameras, v.vertices_mean, v.rms_mean_pct
            )
        })
        .collect();
    s += &format!(
        "by cameras seeing a vertex (in the truth), rms mean: {}\n",
        groups.join(", ")
    );
    if let Some(f) = r.followed_median {
        s += &format!(
            "motion followed per frame (seen vertices, the truth's step as 1): median {f:.3}\n"
        );
    }
    s
}

//! The `modelflow` command: parses arguments and dispatches to the library. Each subcommand lives
//! in its own module (`<name>.rs`) holding its clap `Args` and a `run` function; no algorithm
//! lives in the binary.

use clap::{Parser, Subcommand};

mod baseline;
mod bench;
mod demo;
mod eval;
mod progress;
mod report;
mod synth;
mod track;

#[derive(Parser)]
#[command(
    name = "modelflow",
    version,
    about = "Markerless capture of deforming geometry from calibrated multi-view footage"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the whole pipeline on embedded synthetic footage: synth, track, baseline, report.
    Demo(demo::Args),
    /// Time the tracker on the default 640x480 two-camera cloth (or a given scene).
    Bench(bench::Args),
    /// Optical flow per camera then triangulation (the Universal Capture baseline).
    Baseline(baseline::Args),
    /// Score a run folder against the scene's ground truth.
    Eval(eval::Args),
    /// Write an HTML report comparing runs: error plot, overlays, oblique and error views.
    Report(report::Args),
    /// Track the scene's mesh through every frame (Model Flow).
    Track(track::Args),
    /// Write synthetic multi-view footage with ground truth (presets: cloth, blob).
    Synth(synth::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result: anyhow::Result<()> = match cli.command {
        Command::Baseline(args) => baseline::run(args),
        Command::Bench(a) => bench::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Eval(a) => eval::run(a),
        Command::Report(a) => report::run(a),
        Command::Track(a) => track::run(a),
        Command::Synth(a) => synth::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

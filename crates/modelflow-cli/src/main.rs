//! The `modelflow` command: parses arguments and dispatches to the library. Each subcommand lives
//! in its own module (`<name>.rs`) holding its clap `Args` and a `run` function; no algorithm
//! lives in the binary.

use clap::{CommandFactory, FromArgMatches, Subcommand};

mod align;
mod baseline;
mod bench;
mod capture;
mod demo;
mod device;
mod eval;
mod export;
mod import;
mod progress;
mod report;
mod runfolder;
mod scale;
mod select;
mod synth;
mod track;

#[derive(clap::Parser)]
#[command(
    name = "modelflow",
    version,
    about = "Markerless capture of deforming geometry from calibrated multi-view footage"
)]
struct Cli {
    /// Worker threads (default: one per CPU core). Results are the same whatever the count.
    #[arg(long, global = true, value_name = "N")]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Line up a roughly placed mesh with the first frame: its pose (and --scale) from all cameras.
    Align(align::Args),
    /// Run the whole pipeline on embedded synthetic footage: synth, track, baseline, report.
    Demo(demo::Args),
    /// Time the tracker on the default 640x480 two-camera cloth (or a given scene).
    Bench(bench::Args),
    /// Optical flow per camera then triangulation (the Universal Capture baseline).
    Baseline(baseline::Args),
    /// Score a run folder against the scene's ground truth.
    Eval(eval::Args),
    /// Write a run as one animated file for a 3D package: USD, glTF, PC2 or MDD.
    Export(export::Args),
    /// Write a scene file from a calibration made by another tool (COLMAP, OpenCV, Metashape,
    /// nerfstudio, anipose / Pose2Sim / FreeMoCap, caliscope, Kalibr, mrcal).
    Import(import::Args),
    /// Write an HTML report comparing runs: error plot, overlays, oblique and error views.
    Report(report::Args),
    /// Track the scene's mesh through every frame (Model Flow).
    Track(track::Args),
    /// Write synthetic multi-view footage with ground truth (presets: cloth, blob, irregular, limb, crossing).
    Synth(synth::Args),
}

fn main() -> std::process::ExitCode {
    let definition = Cli::command();
    let matches = definition.clone().get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    // The subcommand's definition and matches tell which options the user set (for manifests).
    let (name, sub_matches) = matches.subcommand().unwrap_or(("", &matches));
    let sub_command = definition.find_subcommand(name).unwrap_or(&definition);
    let sub = runfolder::Invocation {
        command: sub_command,
        matches: sub_matches,
    };
    if let Some(n) = cli.threads {
        if !(1..=1024).contains(&n) {
            eprintln!("error: --threads {n}: expected 1 to 1024");
            return std::process::ExitCode::from(1);
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            eprintln!("error: --threads {n}: {e}");
            return std::process::ExitCode::from(1);
        }
    }
    let result: anyhow::Result<()> = match cli.command {
        Command::Align(a) => align::run(a),
        Command::Baseline(args) => baseline::run(args, &sub),
        Command::Bench(a) => bench::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Eval(a) => eval::run(a),
        Command::Export(a) => export::run(a),
        Command::Import(a) => import::run(a),
        Command::Report(a) => report::run(a),
        Command::Track(a) => track::run(a, &sub),
        Command::Synth(a) => synth::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            // 130 = 128 + SIGINT: stopped on request (the run folder can be resumed).
            let interrupted = e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<modelflow::Error>(),
                    Some(modelflow::Error::Interrupted { .. })
                )
            });
            let code = e
                .chain()
                .find_map(|c| c.downcast_ref::<Failure>().map(|f| f.code))
                .unwrap_or(if interrupted { 130 } else { 1 });
            std::process::ExitCode::from(code)
        }
    }
}

/// An error that asks for a particular exit status (e.g. `track --strict`: 3 when frames
/// stalled).
#[derive(Debug)]
pub struct Failure {
    pub code: u8,
    message: String,
}

impl Failure {
    pub fn new(code: u8, message: String) -> Self {
        Failure { code, message }
    }
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Failure {}

#[cfg(test)]
mod tests {
    #[test]
    fn the_command_line_definition_is_consistent() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}

//! What `track` and `baseline` share about their output folder: the `--out`, `--resume` and
//! `--force` flags, the options the user gave (for the run's manifest), and Ctrl-C, which stops a
//! run cleanly so that its folder can be resumed.

use clap::parser::ValueSource;
use modelflow::{OpenMode, RunOptions};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

#[derive(clap::Args, Clone, Debug)]
pub struct OutArgs {
    /// Run folder: {frame:04}.obj per frame, log.jsonl, run.json. It must be new or empty, unless
    /// --resume or --force.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the run files in --out (frame meshes, log.jsonl, run.json); other files are kept.
    #[arg(long)]
    pub force: bool,
}

impl OutArgs {
    pub fn mode(&self, resume: bool) -> OpenMode {
        if self.force {
            OpenMode::Force
        } else if resume {
            OpenMode::Resume
        } else {
            OpenMode::New
        }
    }
}

/// The options of `cmd` set on the command line, as written (`--name` -> value; flags ->
/// `true`).
pub fn given_options(cmd: &clap::Command, matches: &clap::ArgMatches) -> BTreeMap<String, String> {
    let mut given = BTreeMap::new();
    for arg in cmd.get_arguments() {
        let id = arg.get_id().as_str();
        if matches.value_source(id) != Some(ValueSource::CommandLine) {
            continue;
        }
        // A list given as one comma-separated value (`--cameras a,b`) is written back so, and
        // read back so (`select::SelectArgs::or_the_runs`).
        let sep = arg
            .get_value_delimiter()
            .map_or(" ".to_string(), |c| c.to_string());
        let value = matches
            .get_raw(id)
            .map(|vals| {
                vals.map(|v| v.to_string_lossy().into_owned())
                    .collect::<Vec<_>>()
                    .join(&sep)
            })
            .filter(|v| !v.is_empty())
            .unwrap_or_else(|| "true".into());
        let name = arg
            .get_long()
            .map_or_else(|| id.to_string(), |l| format!("--{l}"));
        given.insert(name, value);
    }
    given
}

/// What the command line said: the subcommand's definition and what the user gave it.
pub struct Invocation<'a> {
    pub command: &'a clap::Command,
    pub matches: &'a clap::ArgMatches,
}

/// The run options for a command: the folder mode, the command line, the options as given, and
/// a cancel flag set by Ctrl-C.
pub fn run_options(mode: OpenMode, invocation: &Invocation) -> RunOptions {
    RunOptions {
        mode,
        command: std::env::args().collect(),
        given: given_options(invocation.command, invocation.matches),
        cancel: Some(ctrl_c()),
        gpu: None,
        first_mesh_check: None,
    }
}

/// A flag set on the first Ctrl-C: the run stops within one solver iteration, abandons the frame
/// it was solving, records itself as interrupted and exits 130. A second Ctrl-C quits at once
/// (the folder is still resumable: every file is written atomically).
fn ctrl_c() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    let f = flag.clone();
    let installed = ctrlc::set_handler(move || {
        if f.swap(true, Ordering::SeqCst) {
            std::process::exit(130);
        }
        eprintln!("\nstopping after the current solver iteration (Ctrl-C again to quit at once)");
    });
    if let Err(e) = installed {
        eprintln!("warning: Ctrl-C will not stop the run cleanly: {e}");
    }
    flag
}

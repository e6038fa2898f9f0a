//! Progress display: an indicatif bar with an ETA on a terminal, plain lines otherwise (logs, CI).

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};

pub struct Progress {
    bar: Option<ProgressBar>,
    label: String,
    total: AtomicU64,
    done: AtomicU64,
    /// Last tenth reported in plain mode (for `set`).
    tenth: AtomicU64,
}

impl Progress {
    pub fn new(label: &str, total: u64) -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let b = ProgressBar::new(total);
            b.set_style(
                ProgressStyle::with_template(
                    "{prefix:>9} [{bar:32.cyan/blue}] {pos}/{len} {elapsed_precise} ETA {eta} {msg}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            b.set_prefix(label.to_string());
            b
        });
        Progress {
            bar,
            label: label.to_string(),
            total: total.into(),
            done: 0.into(),
            tenth: 0.into(),
        }
    }

    /// One more item done, with a message (a line per item when not on a terminal).
    pub fn tick(&self, msg: &str) {
        let n = self.done.load(Ordering::Relaxed) + 1;
        self.at(n, msg);
    }

    /// `n` items done, the last with a message (a line per call when not on a terminal).
    pub fn at(&self, n: u64, msg: &str) {
        self.done.store(n, Ordering::Relaxed);
        match &self.bar {
            Some(b) => {
                b.set_message(msg.to_string());
                b.set_position(n);
            }
            None => eprintln!(
                "{} {}/{}: {}",
                self.label,
                n,
                self.total.load(Ordering::Relaxed),
                msg
            ),
        }
    }

    /// `done` of `total` items (a line per tenth when not on a terminal).
    pub fn set(&self, done: u64, total: u64) {
        self.total.store(total, Ordering::Relaxed);
        match &self.bar {
            Some(b) => {
                b.set_length(total);
                b.set_position(done);
            }
            None => {
                let t = done * 10 / total.max(1);
                if self.tenth.fetch_max(t, Ordering::Relaxed) < t {
                    eprintln!("{} {done}/{total}", self.label);
                }
            }
        }
    }

    /// A line printed above the bar (or on its own when not on a terminal): warnings.
    pub fn println(&self, line: &str) {
        match &self.bar {
            Some(b) => b.println(line),
            None => eprintln!("{line}"),
        }
    }

    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

//! The run log `log.jsonl`: one JSON object per solved frame, the same schema for the tracker and
//! the baseline (see `docs/run-folder.md`). Lines are appended, one write per frame, so a run of
//! N frames writes O(N) bytes of log; a line torn by a crash is recognised and dropped when the
//! run is resumed.

use crate::baseline::BaselineFrame;
use crate::error::{Error, Result};
use crate::tracker::FrameReport;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};

/// One line of `log.jsonl`. The timing fields mean the same for every method, so runs compare
/// like with like.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameLog {
    /// The frame solved.
    pub frame: u32,
    /// Computing time of the frame's step, seconds: everything after its images were read
    /// (the tracker: pyramids, templates, solve; the baseline: optical flow and triangulation).
    pub seconds: f64,
    /// Time spent reading the frame's images, seconds (the tracker reads the next frame while it
    /// solves the current one, so this overlaps the previous step there).
    pub load_seconds: f64,
    /// Wall time from the end of the previous frame to the end of this one, seconds: what a user
    /// waits per frame.
    pub wall_seconds: f64,
    /// What the method did (with a `"method"` tag: `model_flow` or `baseline`).
    #[serde(flatten)]
    pub detail: FrameDetail,
}

/// The method-specific part of a log line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "snake_case")]
// One line per frame, read or written once: the tracker's report kept inline rather than boxed
// (the variants are matched by value across the API and the Python bindings).
#[allow(clippy::large_enum_variant)]
pub enum FrameDetail {
    /// The Model Flow tracker's report of the frame: iterations, costs, stop reason, per-level
    /// solver summaries.
    ModelFlow(FrameReport),
    /// The optical-flow baseline's counts.
    Baseline(BaselineFrame),
}

impl FrameLog {
    /// The tracker's report, when this line is the tracker's.
    pub fn model_flow(&self) -> Option<&FrameReport> {
        match &self.detail {
            FrameDetail::ModelFlow(r) => Some(r),
            FrameDetail::Baseline(_) => None,
        }
    }
}

/// Appends log lines to a run's `log.jsonl`.
pub(crate) struct LogWriter {
    path: PathBuf,
    file: std::fs::File,
}

impl LogWriter {
    /// Opens `path` for appending (creating it).
    pub fn append_to(path: &Path) -> Result<Self> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        Ok(LogWriter {
            path: path.to_path_buf(),
            file,
        })
    }

    /// Appends one line (one `write` call, no rewrite of what is there).
    pub fn append(&mut self, line: &FrameLog) -> Result<()> {
        let mut text = serde_json::to_string(line).map_err(|e| {
            Error::invalid(&self.path, format!("frame {}", line.frame), e.to_string())
        })?;
        text.push('\n');
        self.file
            .write_all(text.as_bytes())
            .map_err(|e| Error::io(&self.path, e))
    }
}

/// Reads the log of the run folder `dir`: its lines in order (none if the folder has no log).
/// A last line torn by a crash is left out; any other line that is not a log line is an error
/// naming the file and the line.
pub fn read_frame_log(dir: &Path) -> Result<Vec<FrameLog>> {
    Ok(read_log(&dir.join(super::LOG))?.lines)
}

/// The lines of a log as read back.
pub(crate) struct ReadLog {
    pub lines: Vec<FrameLog>,
    /// Length in bytes of the complete, valid lines (a torn last line lies past it).
    pub valid_len: u64,
}

/// Reads a run's log. A last line without its newline was torn by a crash and is left out (it
/// lies past `valid_len`); any other line that is not a log line is an error naming it.
pub(crate) fn read_log(path: &Path) -> Result<ReadLog> {
    let text = match std::fs::read(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(Error::io(path, e)),
    };
    let mut lines = Vec::new();
    let mut pos = 0usize;
    let mut number = 0usize;
    while pos < text.len() {
        number += 1;
        let (end, complete) = match text[pos..].iter().position(|&c| c == b'\n') {
            Some(i) => (pos + i, true),
            None => (text.len(), false),
        };
        if !complete {
            // Each line is written with its newline in one call: without it, the line was torn.
            break;
        }
        let line = std::str::from_utf8(&text[pos..end])
            .map_err(|e| e.to_string())
            .and_then(|l| serde_json::from_str::<FrameLog>(l).map_err(|e| e.to_string()))
            .map_err(|e| {
                Error::invalid(
                    path,
                    format!("line {number}"),
                    format!("not a log line: {e}"),
                )
            })?;
        lines.push(line);
        pos = end + 1;
    }
    Ok(ReadLog {
        lines,
        valid_len: pos.min(text.len()) as u64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(frame: u32) -> FrameLog {
        FrameLog {
            frame,
            seconds: 0.25,
            load_seconds: 0.01,
            wall_seconds: 0.3,
            detail: FrameDetail::Baseline(BaselineFrame {
                tracked: 10,
                triangulated: 5,
            }),
        }
    }

    #[test]
    fn lines_are_appended_and_a_torn_last_line_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.jsonl");
        let mut w = LogWriter::append_to(&path).unwrap();
        w.append(&line(1)).unwrap();
        w.append(&line(2)).unwrap();
        let whole = std::fs::read(&path).unwrap();
        let text = String::from_utf8(whole.clone()).unwrap();
        assert_eq!(text.lines().count(), 2);
        assert!(text.contains("\"method\":\"baseline\"") && text.contains("\"tracked\":10"));
        let read = read_log(&path).unwrap();
        assert_eq!(read.lines, vec![line(1), line(2)]);
        assert_eq!(read.valid_len, whole.len() as u64);
        // A crash in the middle of the third line.
        let third = serde_json::to_string(&line(3)).unwrap();
        let mut torn = whole.clone();
        torn.extend_from_slice(&third.as_bytes()[..third.len() / 2]);
        std::fs::write(&path, &torn).unwrap();
        let read = read_log(&path).unwrap();
        assert_eq!(read.lines.len(), 2);
        assert_eq!(read.valid_len, whole.len() as u64);
        // A bad line in the middle is an error naming it.
        let mut bad = b"{\"frame\": 1}\n".to_vec();
        bad.extend_from_slice(&whole);
        std::fs::write(&path, &bad).unwrap();
        let err = read_log(&path).err().unwrap().to_string();
        assert!(err.contains("line 1") && err.contains("log.jsonl"), "{err}");
    }
}

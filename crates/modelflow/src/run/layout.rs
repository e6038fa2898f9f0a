//! The run folder's layout, spelt once: which names a run writes, how a file name tells the
//! frame, and reading the frame meshes of a folder (a run of ours, or any folder of numbered
//! OBJs such as a ground truth).

use crate::base::mesh::Mesh;
use crate::error::{Error, Result};
use crate::input::meshio::{read_mesh_with, Checks};
use crate::tracker::VertexConfidence;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The run's manifest.
pub const MANIFEST: &str = "run.json";
/// The run's per-frame log, one JSON object per line.
pub const LOG: &str = "log.jsonl";

/// Name of a frame's mesh in a run folder: `{frame:04}.obj`.
pub fn frame_file(frame: u32) -> String {
    format!("{frame:04}.obj")
}

/// Name of a solved frame's per-vertex confidence in a run folder: `{frame:04}.confidence.csv`.
pub fn confidence_file(frame: u32) -> String {
    format!("{frame:04}.confidence.csv")
}

/// The header line of a confidence file.
pub(crate) const CONFIDENCE_HEADER: &str = "vertex,information,residual,sigma,pixels";

/// The frame of a file named as a run names its confidence files, or `None`.
pub(crate) fn layout_confidence(name: &str) -> Option<u32> {
    let stem = name.strip_suffix(".confidence.csv")?;
    (stem.len() >= 4 && stem.bytes().all(|c| c.is_ascii_digit()))
        .then(|| stem.parse().ok())
        .flatten()
}

/// Writes a frame's per-vertex confidence as CSV (atomically): one row per vertex, numbers in
/// their shortest round-trip form, `inf` for the sigma of a vertex nothing constrains.
pub fn write_confidence(path: &Path, confidence: &[VertexConfidence]) -> Result<()> {
    crate::fsutil::write_atomic_with(path, |w| {
        use std::io::Write;
        writeln!(w, "{CONFIDENCE_HEADER}")?;
        for (i, c) in confidence.iter().enumerate() {
            writeln!(
                w,
                "{i},{},{},{},{}",
                c.information,
                c.residual,
                c.sigma(),
                c.pixels
            )?;
        }
        Ok(())
    })
}

/// Reads a confidence file written by [`write_confidence`]; errors name the file and line.
pub fn read_confidence(path: &Path) -> Result<Vec<VertexConfidence>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut lines = text.lines();
    if lines.next() != Some(CONFIDENCE_HEADER) {
        return Err(Error::invalid(
            path,
            "line 1",
            format!("expected the header {CONFIDENCE_HEADER:?}"),
        ));
    }
    let mut out = Vec::new();
    for (i, line) in lines.enumerate() {
        let bad = || {
            Error::invalid(
                path,
                format!("line {}", i + 2),
                format!("expected 5 comma-separated fields for vertex {i}, got {line:?}"),
            )
        };
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 5 || f[0].parse::<usize>().ok() != Some(i) {
            return Err(bad());
        }
        let num = |k: usize| f[k].parse::<f64>().map_err(|_| bad());
        out.push(VertexConfidence {
            information: num(1)?,
            residual: num(2)?,
            pixels: num(4)?,
        });
    }
    Ok(out)
}

/// The frame number in a file stem: its last run of ASCII digits (`0007` -> 7, `frame_12` -> 12).
pub fn frame_number(stem: &str) -> Option<u32> {
    let b = stem.as_bytes();
    let end = b.iter().rposition(|c| c.is_ascii_digit())? + 1;
    let start = b[..end]
        .iter()
        .rposition(|c| !c.is_ascii_digit())
        .map_or(0, |i| i + 1);
    stem[start..end].parse().ok()
}

/// The frame of a file named as a run names its frame meshes (`{frame:04}.obj`: four or more
/// digits, nothing else), or `None`.
pub(crate) fn layout_frame(name: &str) -> Option<u32> {
    let stem = name.strip_suffix(".obj")?;
    (stem.len() >= 4 && stem.bytes().all(|c| c.is_ascii_digit()))
        .then(|| stem.parse().ok())
        .flatten()
}

/// Whether a file name belongs to the run-folder layout: the manifest, the log, a frame mesh,
/// or a temporary file of one of them (`fsutil`'s `.{name}.{pid}.tmp`, left by a crash).
pub(crate) fn is_layout_file(name: &str) -> bool {
    name == MANIFEST
        || name == LOG
        || layout_frame(name).is_some()
        || layout_confidence(name).is_some()
        || layout_temporary(name)
}

/// Whether `name` is `fsutil`'s temporary for a layout file.
pub(crate) fn layout_temporary(name: &str) -> bool {
    let Some(inner) = name.strip_prefix('.').and_then(|n| n.strip_suffix(".tmp")) else {
        return false;
    };
    let Some((target, pid)) = inner.rsplit_once('.') else {
        return false;
    };
    !pid.is_empty()
        && pid.bytes().all(|c| c.is_ascii_digit())
        && (target == MANIFEST
            || target == LOG
            || layout_frame(target).is_some()
            || layout_confidence(target).is_some())
}

/// Reads a folder of frame meshes: every `.obj` file whose stem holds a number (the frame: the
/// last run of digits) is read; other files are ignored. Sorted by frame; two files for one frame
/// is an error. Degenerate triangles are allowed (a failing run may collapse some).
pub fn read_run(dir: &Path) -> Result<Vec<(u32, Mesh)>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut files: Vec<(u32, PathBuf)> = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let p = entry.path();
        let is_obj = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"));
        if !is_obj || !p.is_file() {
            continue;
        }
        let Some(frame) = p
            .file_stem()
            .and_then(|s| s.to_str())
            .and_then(frame_number)
        else {
            continue;
        };
        files.push((frame, p));
    }
    files.sort();
    if let Some(w) = files.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Error::invalid(
            dir,
            format!("frame {}", w[0].0),
            format!(
                "two meshes for one frame: {} and {}",
                w[0].1.display(),
                w[1].1.display()
            ),
        ));
    }
    files
        .par_iter()
        .map(|(f, p)| Ok((*f, read_mesh_with(p, Checks::Structure)?)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_names() {
        assert_eq!(frame_file(7), "0007.obj");
        assert_eq!(frame_file(12345), "12345.obj");
        assert_eq!(layout_frame("0007.obj"), Some(7));
        assert_eq!(layout_frame("12345.obj"), Some(12345));
        assert_eq!(layout_frame("007.obj"), None);
        assert_eq!(layout_frame("frame_0007.obj"), None);
        assert!(is_layout_file("run.json") && is_layout_file("log.jsonl"));
        assert!(is_layout_file(".0003.obj.4242.tmp") && is_layout_file(".log.jsonl.1.tmp"));
        assert!(!is_layout_file(".notes.txt.1.tmp") && !is_layout_file("notes.obj"));
        assert!(!is_layout_file(".0003.obj.tmp"));
    }
}

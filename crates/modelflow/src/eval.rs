//! Scoring a run against a scene's ground truth: reading a run folder (one OBJ per frame) and
//! measuring, per frame, the RMS and maximum vertex distance to the ground-truth mesh, also as a
//! percentage of the scene mesh's size (its bounding-box diagonal).

use crate::error::{Error, Result};
use crate::mesh::Mesh;
use crate::meshio::{read_mesh_with, Checks};
use crate::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

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

/// Name of a frame's mesh in a run folder (`{frame:04}.obj`): the one place the layout is spelt.
pub fn frame_file(frame: u32) -> String {
    format!("{frame:04}.obj")
}

/// Removes, from a run folder about to be written, frame meshes left by an earlier run that lie
/// outside `first..=last` (files named as a run names them: digits only, `.obj`), so that the
/// folder ends up holding exactly one run. Other files are left alone. Returns how many went.
pub fn remove_stale_frames(dir: &Path, first: u32, last: u32) -> Result<usize> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(0);
    };
    let mut removed = 0;
    for entry in entries {
        let p = entry.map_err(|e| Error::io(dir, e))?.path();
        let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        let is_frame_file = p.extension().is_some_and(|e| e == "obj")
            && !stem.is_empty()
            && stem.bytes().all(|c| c.is_ascii_digit());
        if let (true, Some(f)) = (is_frame_file, frame_number(stem)) {
            if f < first || f > last {
                std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
                removed += 1;
            }
        }
    }
    Ok(removed)
}

/// Reads a run folder: every `.obj` file whose stem holds a number (the frame: the last run of
/// digits) is read; other files are ignored. Sorted by frame; two files for one frame is an
/// error. Degenerate triangles are allowed (a failing run may collapse some).
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

/// Error of one frame, in world units (and percent of the scene mesh's bounding-box diagonal).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameError {
    pub frame: u32,
    /// sqrt(mean over vertices of the squared distance to the ground truth).
    pub rms: f64,
    pub rms_pct: f64,
    /// Largest vertex distance.
    pub max: f64,
}

/// The score of a run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EvalReport {
    pub frames: usize,
    pub per_frame: Vec<FrameError>,
    /// Mean of the per-frame RMS.
    pub rms_mean: f64,
    /// RMS of the last frame.
    pub rms_final: f64,
    pub rms_mean_pct: f64,
    pub rms_final_pct: f64,
    /// The bounding-box diagonal of the scene mesh (frame `first`), the 100 % of the `_pct` values.
    pub scale: f64,
}

/// Compares a run (as from [`read_run`]) with the scene's ground truth, frame by frame over all
/// the scene's frames. Every scene frame must be in the run and no other.
pub fn evaluate(scene: &Scene, run: &[(u32, Mesh)]) -> Result<EvalReport> {
    if scene.ground_truth.is_none() {
        return Err(Error::invalid(
            &scene.path,
            "ground_truth",
            "the scene has no ground truth to evaluate against",
        ));
    }
    if let Some((f, _)) = run.iter().find(|(f, _)| !scene.frames().contains(f)) {
        return Err(Error::Usage(format!(
            "the run has a mesh for frame {f}, outside the scene's frames {}..={}",
            scene.first, scene.last
        )));
    }
    let have: std::collections::BTreeSet<u32> = run.iter().map(|(f, _)| *f).collect();
    let missing: Vec<u32> = scene.frames().filter(|f| !have.contains(f)).collect();
    if !missing.is_empty() {
        let mut shown: Vec<String> = missing.iter().take(10).map(|f| f.to_string()).collect();
        if missing.len() > 10 {
            shown.push(format!("... ({} frames in all)", missing.len()));
        }
        return Err(Error::Usage(format!(
            "the run has no mesh for frame(s) {} (the scene has frames {}..={})",
            shown.join(", "),
            scene.first,
            scene.last
        )));
    }
    let scale = scene.mesh.bbox_diagonal();
    let by_frame: std::collections::BTreeMap<u32, &Mesh> =
        run.iter().map(|(f, m)| (*f, m)).collect();
    let per_frame = scene
        .frames()
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&frame| {
            let mesh = by_frame[&frame];
            let truth = scene
                .ground_truth(frame)
                .unwrap_or_else(|| unreachable!("checked above"))?;
            if mesh.positions.len() != truth.positions.len() {
                return Err(Error::Usage(format!(
                    "frame {frame}: the run's mesh has {} vertices, the ground truth {}",
                    mesh.positions.len(),
                    truth.positions.len()
                )));
            }
            let (mut sum, mut max) = (0.0f64, 0.0f64);
            for (a, b) in mesh.positions.iter().zip(&truth.positions) {
                let d2 = (a - b).norm_squared();
                sum += d2;
                max = max.max(d2);
            }
            let rms = (sum / mesh.positions.len() as f64).sqrt();
            Ok(FrameError {
                frame,
                rms,
                rms_pct: pct(rms, scale),
                max: max.sqrt(),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let rms_mean = per_frame.iter().map(|e| e.rms).sum::<f64>() / per_frame.len() as f64;
    let rms_final = per_frame.last().map_or(0.0, |e| e.rms);
    Ok(EvalReport {
        frames: per_frame.len(),
        per_frame,
        rms_mean,
        rms_final,
        rms_mean_pct: pct(rms_mean, scale),
        rms_final_pct: pct(rms_final, scale),
        scale,
    })
}

fn pct(v: f64, scale: f64) -> f64 {
    if scale > 0.0 {
        100.0 * v / scale
    } else {
        0.0
    }
}

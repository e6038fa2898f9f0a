//! Scoring a run (its frame meshes, as `run::read_run` reads them) against a scene's ground
//! truth: per frame, the RMS and maximum vertex distance to the ground-truth mesh, also as a
//! percentage of the scene mesh's size (its bounding-box diagonal).

use crate::base::mesh::Mesh;
use crate::error::{Error, Result};
use crate::input::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;

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
        return Err(Error::mismatch(
            "the run's frames",
            format!("the scene's frames {}..={}", scene.first, scene.last),
            format!("a mesh for frame {f}"),
        ));
    }
    let have: std::collections::BTreeSet<u32> = run.iter().map(|(f, _)| *f).collect();
    let missing: Vec<u32> = scene.frames().filter(|f| !have.contains(f)).collect();
    if !missing.is_empty() {
        let mut shown: Vec<String> = missing.iter().take(10).map(|f| f.to_string()).collect();
        if missing.len() > 10 {
            shown.push(format!("... ({} frames in all)", missing.len()));
        }
        return Err(Error::mismatch(
            "the run's frames",
            format!(
                "a mesh for every scene frame {}..={}",
                scene.first, scene.last
            ),
            format!("no mesh for frame(s) {}", shown.join(", ")),
        ));
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
                return Err(Error::mismatch(
                    format!("frame {frame}: the run's mesh"),
                    format!("{} vertices (as the ground truth)", truth.positions.len()),
                    format!("{} vertices", mesh.positions.len()),
                ));
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

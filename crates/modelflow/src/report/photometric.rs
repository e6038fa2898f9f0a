//! A per-frame quality measure that needs no ground truth, for reports on real footage: how much
//! the colour under each vertex changed since the first frame. A vertex that stays on its surface
//! point keeps its colour (up to lighting), a drifting one does not.
//!
//! Cost of a run at frame `t`, per camera: over the vertices visible (front-most by a depth test
//! against the run's own mesh, and inside the image) both at the first frame and at `t`, the mean
//! of `|I_t(x_t) − I_first(x_first)|² / 3` (squared RGB difference averaged over channels, images
//! in 0..1, bilinear samples at the projected positions). The frame's cost is the mean over the
//! cameras that see at least one such vertex; `None` when none does.

use crate::base::image::RgbImage;
use crate::base::mesh::Mesh;
use crate::error::Result;
use crate::input::scene::Scene;
use crate::synth::render;
use rayon::prelude::*;

/// Relative depth slack of the visibility test.
const DEPTH_TOLERANCE: f64 = 0.01;

/// The colour under each vertex of `mesh` seen by camera `c` at `frame`, `None` where the vertex
/// is hidden or outside the image.
fn vertex_colours(
    scene: &Scene,
    c: usize,
    frame: u32,
    mesh: &Mesh,
    img: &RgbImage,
) -> Result<Vec<Option<[f32; 3]>>> {
    let proj = scene.cameras[c].at(frame);
    let (w, h) = (img.width(), img.height());
    let depth = render::depth_map(mesh, proj, w, h)?;
    Ok(mesh
        .positions
        .iter()
        .map(|x| {
            let hx = proj.project_h(x);
            if hx.z <= 0.0 {
                return None;
            }
            let (u, v) = (hx.x / hx.z, hx.y / hx.z);
            if !img.inside(u, v) {
                return None;
            }
            let d = depth[v.round() as usize * w + u.round() as usize];
            // A vertex on the mesh's outline may miss the nearest pixel centre (infinite depth).
            (d.is_infinite() || hx.z <= d * (1.0 + DEPTH_TOLERANCE))
                .then(|| img.sample_unchecked(u, v))
        })
        .collect())
}

/// The photometric cost of each run (its mesh per scene frame, in order) at every scene frame:
/// `result[run][frame - first]`. Frames are processed in parallel, each loading its own images.
pub fn cost_per_frame(scene: &Scene, runs: &[Vec<&Mesh>]) -> Result<Vec<Vec<Option<f64>>>> {
    let first_images = scene.load_images(scene.first)?;
    // reference[run][camera][vertex]
    let reference: Vec<Vec<Vec<Option<[f32; 3]>>>> = runs
        .par_iter()
        .map(|meshes| {
            (0..scene.cameras.len())
                .map(|c| vertex_colours(scene, c, scene.first, meshes[0], &first_images[c]))
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<_>>()?;
    drop(first_images);
    let frames: Vec<u32> = scene.frames().collect();
    let per_frame: Vec<Vec<Option<f64>>> = frames
        .par_iter()
        .map(|&t| {
            let images = scene.load_images(t)?;
            runs.iter()
                .zip(&reference)
                .map(|(meshes, refs)| {
                    let mesh = meshes[(t - scene.first) as usize];
                    let (mut sum, mut n) = (0.0f64, 0usize);
                    for (c, img) in images.iter().enumerate() {
                        let now = vertex_colours(scene, c, t, mesh, img)?;
                        let (mut cs, mut cn) = (0.0f64, 0usize);
                        for (a, b) in refs[c].iter().zip(&now) {
                            if let (Some(a), Some(b)) = (a, b) {
                                let d: f32 = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum();
                                cs += d as f64 / 3.0;
                                cn += 1;
                            }
                        }
                        if cn > 0 {
                            sum += cs / cn as f64;
                            n += 1;
                        }
                    }
                    Ok((n > 0).then(|| sum / n as f64))
                })
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<_>>()?;
    // Transpose to per run.
    Ok((0..runs.len())
        .map(|r| per_frame.iter().map(|f| f[r]).collect())
        .collect())
}

//! The report's flipbook: for every frame (every k-th past [`MAX_FRAMES`]), one JPEG with all
//! cameras side by side, each camera's footage shrunk to a thumbnail with every run's wireframe
//! on it in the run's colour (hidden edges faint), so that a supervisor can scrub through the
//! shot and see where a mesh slips. The page plays them with a slider (`html`).

use crate::base::image::RgbImage;
use crate::error::Result;
use crate::input::imageio;
use crate::input::scene::Scene;
use crate::report::colormap;
use crate::report::draw;
use crate::report::overlay::{self, WireStyle};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Frames drawn at most; longer shots show every k-th frame.
pub(crate) const MAX_FRAMES: usize = 400;
/// Width of one camera's thumbnail, pixels (smaller footage is not enlarged).
const THUMB_WIDTH: usize = 400;

/// The frames the flipbook shows: all of the scene's, or every k-th (and the last).
pub(crate) fn frames(scene: &Scene) -> Vec<u32> {
    let all: Vec<u32> = scene.frames().collect();
    if all.len() <= MAX_FRAMES {
        return all;
    }
    let k = all.len().div_ceil(MAX_FRAMES);
    let mut f: Vec<u32> = all.iter().step_by(k).copied().collect();
    if f.last() != all.last() {
        f.push(*all.last().expect("a scene has frames"));
    }
    f
}

/// `img` shrunk by about `s` (≤ 1): 2×2 averaging while it halves cleanly, then bilinear; returns
/// the image and the exact scale reached, for [`overlay::magnified`].
fn shrink(img: &RgbImage, s: f64) -> (RgbImage, f64) {
    let mut out = img.clone();
    let mut reached = 1.0;
    while reached * 0.5 >= s && out.width() >= 4 && out.height() >= 4 {
        out = out.downsample2();
        reached *= 0.5;
    }
    let rest = s / reached;
    if (rest - 1.0).abs() > 1e-9 {
        out = overlay::magnify_image(&out, rest);
        reached *= rest;
    }
    (out, reached)
}

/// Writes `flipbook/fNNNN.jpg` under `out_dir` for each of `frames`; `runs` are (name, mesh at
/// each of `frames`). Returns the files.
pub(crate) fn write(
    scene: &Scene,
    runs: &[(&str, Vec<&crate::base::mesh::Mesh>)],
    frames: &[u32],
    out_dir: &Path,
) -> Result<Vec<PathBuf>> {
    let dir = out_dir.join("flipbook");
    std::fs::create_dir_all(&dir).map_err(|e| crate::error::Error::io(&dir, e))?;
    frames
        .par_iter()
        .enumerate()
        .map(|(k, &f)| {
            let images = scene.load_images(f)?;
            let panels = scene
                .cameras
                .iter()
                .zip(&images)
                .map(|(cam, img)| {
                    let s = (THUMB_WIDTH as f64 / cam.width as f64).min(1.0);
                    let (mut thumb, s) = shrink(img, s);
                    let proj = overlay::magnified(cam.at(f), s);
                    for (i, (_, meshes)) in runs.iter().enumerate() {
                        let mesh = meshes[k];
                        let style = WireStyle {
                            colour: colormap::overlay_colour(i),
                            width: 1.0,
                            alpha: 0.7,
                            hidden_alpha: 0.12,
                        };
                        overlay::wireframe_self_hidden(&mut thumb, mesh, &proj, &style)?;
                    }
                    draw::label(
                        &mut thumb,
                        &format!("{} — frame {f}", cam.name),
                        4.0,
                        4.0,
                        12.0,
                    );
                    Ok(thumb)
                })
                .collect::<Result<Vec<_>>>()?;
            let sheet = overlay::side_by_side(&panels, 4, [0.15; 3]);
            let path = dir.join(format!("f{f:04}.jpg"));
            imageio::write_jpeg(&path, &sheet, 85)?;
            Ok(path)
        })
        .collect()
}

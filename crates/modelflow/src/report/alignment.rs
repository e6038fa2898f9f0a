//! The picture of an alignment (`modelflow align --picture`): every camera's frame with the mesh
//! as it was placed (orange, faint) and as `align` left it (cyan), two cameras per row, so that a
//! user sees at a glance whether the mesh now sits on the surface in every view before tracking
//! from it.

use crate::base::camera::Camera;
use crate::base::image::RgbImage;
use crate::base::mesh::Mesh;
use crate::error::{Error, Result};
use crate::report::colormap;
use crate::report::draw;
use crate::report::overlay::{self, WireStyle};
use rayon::prelude::*;

/// Panels narrower than this are magnified (whole factors), so that lines and labels stay legible.
const MIN_PANEL_WIDTH: usize = 640;
const SHEET_BG: draw::Rgb = [0.15, 0.15, 0.15];

/// `before` and `after` drawn over each camera's image of `frame` (one image per camera, as the
/// tracker sees them), edges hidden by the mesh's own surface faint.
pub fn alignment_picture(
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
    before: &Mesh,
    after: &Mesh,
) -> Result<RgbImage> {
    if images.len() != cameras.len() {
        return Err(Error::mismatch(
            "images",
            format!("{} (one per camera)", cameras.len()),
            images.len(),
        ));
    }
    let placed = WireStyle {
        colour: colormap::overlay_colour(1),
        width: 1.0,
        alpha: 0.45,
        hidden_alpha: 0.0,
    };
    let aligned = WireStyle {
        colour: colormap::overlay_colour(0),
        width: 1.0,
        alpha: 0.8,
        hidden_alpha: 0.15,
    };
    let panels = cameras
        .par_iter()
        .zip(images)
        .map(|(cam, img)| {
            let w = cam.width as usize;
            let s = if w < MIN_PANEL_WIDTH {
                (MIN_PANEL_WIDTH as f64 / w as f64).ceil()
            } else {
                1.0
            };
            let proj = overlay::magnified(cam.at(frame), s);
            let mut p = overlay::magnify_image(img, s);
            overlay::wireframe_self_hidden(&mut p, before, &proj, &placed)?;
            overlay::wireframe_self_hidden(&mut p, after, &proj, &aligned)?;
            draw::label(
                &mut p,
                &format!(
                    "{} — frame {frame} — placed (orange), aligned (cyan)",
                    cam.name
                ),
                6.0,
                6.0,
                14.0,
            );
            Ok(p)
        })
        .collect::<Result<Vec<_>>>()?;
    let rows: Vec<RgbImage> = panels
        .chunks(2)
        .map(|pair| overlay::side_by_side(pair, 6, SHEET_BG))
        .collect();
    Ok(overlay::stacked(&rows, 0, SHEET_BG))
}

//! Template pixels that the mesh itself hides in the frame being solved (self-occlusion on the
//! target side; the thesis' §8.4.1 names occlusion its major gap). A template is z-buffered in
//! its own frame (`patch`), so every pixel sees its triangle there; but between that frame and
//! the one being solved another part of the same mesh may move in front of the surface point
//! (an arm swinging across the body, a fold of cloth turning over, the near side of a turning
//! object covering what was at its silhouette). Compared there, such a pixel would be matched
//! against the occluder's colour and pull its triangle toward it, or at best be rejected by the
//! robust loss only after it has pulled.
//!
//! Before each pyramid level is solved, the mesh where that level starts (the coarser level's
//! solution; at the coarsest level the constant-velocity prediction) is z-buffered in every
//! camera at the level's resolution, and each template pixel's surface point (`Σ λ_k·X_k` at
//! those positions) is projected into its camera. The pixel is left out of the level's solve
//! when another triangle more than the tolerance nearer covers its pixel (it is hidden), or when
//! its pixel lies within `reach` pixels of a depth edge of the index buffer (two neighbouring
//! pixels whose depths differ by more than the tolerance; `reach` 0 at the coarsest level: on
//! the edge itself): on either side of an occluding edge whose two sides move differently.
//! Either way the sample there, smoothed and interpolated, mixes two surfaces' colours; the
//! templates keep the same distance from such edges in their own frame
//! (`base::raster::trackable_mask`). The tolerance (twice the mesh's mean edge length) keeps a
//! surface seen at a slant, whose neighbouring pixels differ in depth by the slant over one
//! pixel, from counting as an edge. Decided once per level, so that the cost a level's steps
//! compare is one function. Hand-written: the tracker's own index buffers (`base::raster`) on
//! its own warps. Deterministic whatever the thread count.

use crate::base::camera::Projection;
use crate::base::raster::{rasterize, IndexBuffer, Window, NONE};
use crate::tracker::patch::PatchSet;
use nalgebra::Point3;
use rayon::prelude::*;

/// The depth tolerance in mean edge lengths of the mesh: another surface must lie this much
/// nearer or farther than a template pixel's own for the two to form a depth edge.
const TOLERANCE_EDGES: f64 = 2.0;

/// Drops from `set` the pixels whose surface point, with the mesh at `positions`, lies at one of
/// the mesh's own depth edges in its camera (see the module documentation); `projections[c]` and
/// `sizes[c]` are camera `c`'s at the level solved, `reach` the distance (pixels) from an edge
/// within which a point is left out. Returns how many pixels were dropped.
pub(crate) fn drop_at_depth_edges(
    set: &mut PatchSet,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    projections: &[Projection],
    sizes: &[(usize, usize)],
    reach: usize,
) -> usize {
    if set.patches.is_empty() {
        return 0;
    }
    let tolerance = TOLERANCE_EDGES * mean_edge_length(positions, triangles);
    if tolerance.is_nan() || tolerance <= 0.0 {
        return 0;
    }
    let views: Vec<View> = projections
        .par_iter()
        .zip(sizes)
        .map(|(p, &(w, h))| View::new(rasterize(positions, triangles, p, w, h), tolerance, reach))
        .collect();
    let pixels = &set.pixels;
    let keep: Vec<Vec<bool>> = set
        .patches
        .par_iter()
        .map(|p| {
            let tri = triangles[p.triangle as usize].map(|v| positions[v as usize]);
            let (proj, view) = (&projections[p.camera as usize], &views[p.camera as usize]);
            pixels[p.start as usize..p.end as usize]
                .iter()
                .map(|s| {
                    let l = s.lambda.map(f64::from);
                    let x = Point3::from(
                        tri[0].coords * l[0] + tri[1].coords * l[1] + tri[2].coords * l[2],
                    );
                    !view.at_depth_edge(proj, &x, p.triangle, tolerance)
                })
                .collect()
        })
        .collect();
    if keep.iter().all(|k| k.iter().all(|&k| k)) {
        return 0;
    }
    set.retain_pixels(&keep)
}

/// One camera's index buffer of the mesh, and which of its pixels lie within `reach` of a depth
/// edge: two neighbouring covered pixels (4-connected) whose depths differ by more than the
/// tolerance, both sides marked, then grown by `reach` pixels (Chebyshev). Along a slanted
/// surface neighbouring pixels differ by the slant over one pixel only, far below the tolerance.
struct View {
    ib: IndexBuffer,
    /// The index buffer's window grown by `reach` (within the image): where `near_edge` lies.
    area: Window,
    near_edge: Vec<bool>,
}

impl View {
    fn new(ib: IndexBuffer, tolerance: f64, reach: usize) -> Self {
        let (win, area) = (ib.window, ib.window.grown(reach, ib.width, ib.height));
        let tol = tolerance as f32;
        let mut edge = vec![false; area.len()];
        // Only covered pixels mark an edge, and all of them lie in the window: each pixel of
        // the window against its right and lower neighbours there (`i`: the window's index,
        // `j`: the area's).
        let (owner, depth) = (ib.owners(), ib.depths());
        let (dx, dy) = (win.x0 - area.x0, win.y0 - area.y0);
        for wy in 0..win.height {
            for wx in 0..win.width {
                let i = wy * win.width + wx;
                if owner[i] == NONE {
                    continue;
                }
                let j = (wy + dy) * area.width + wx + dx;
                let mut mark = |ni: usize, nj: usize| {
                    if owner[ni] != NONE && (depth[i] - depth[ni]).abs() > tol {
                        edge[j] = true;
                        edge[nj] = true;
                    }
                };
                if wx + 1 < win.width {
                    mark(i + 1, j + 1);
                }
                if wy + 1 < win.height {
                    mark(i + win.width, j + area.width);
                }
            }
        }
        View {
            near_edge: grow(&edge, area.width, area.height, reach),
            area,
            ib,
        }
    }

    /// Whether surface point `x` of triangle `own` is hidden (another triangle more than
    /// `tolerance` nearer at its pixel) or lies within the reach of a depth edge. A point behind
    /// the camera, or off the image, is not judged here (other rules do).
    fn at_depth_edge(&self, proj: &Projection, x: &Point3<f64>, own: u32, tolerance: f64) -> bool {
        let h = proj.project_h(x);
        if h.z.is_nan() || h.z <= 0.0 {
            return false;
        }
        // Pixel centres at integer coordinates (docs/scene-format.md): the nearest one, by
        // truncation of the shifted, non-negative coordinates (no call to `round`).
        let (u, v) = (h.x / h.z + 0.5, h.y / h.z + 0.5);
        let ib = &self.ib;
        if !(u >= 0.0 && v >= 0.0 && u < ib.width as f64 && v < ib.height as f64) {
            return false;
        }
        let (px, py) = (u as usize, v as usize);
        let owner = ib.owner_at(px, py);
        self.area.index(px, py).is_some_and(|i| self.near_edge[i])
            || (owner != NONE && owner != own && f64::from(ib.depth_at(px, py)) < h.z - tolerance)
    }
}

/// `mask` grown by `r` pixels in every direction (a `2r+1` square), row pass then column pass.
fn grow(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    if r == 0 {
        return mask.to_vec();
    }
    let mut rows = vec![false; w * h];
    for y in 0..h {
        let row = &mask[y * w..(y + 1) * w];
        for (x, &m) in row.iter().enumerate() {
            if m {
                rows[y * w + x.saturating_sub(r)..y * w + (x + r).min(w - 1) + 1].fill(true);
            }
        }
    }
    let mut out = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            if rows[y * w + x] {
                for yy in y.saturating_sub(r)..=(y + r).min(h - 1) {
                    out[yy * w + x] = true;
                }
            }
        }
    }
    out
}

/// The mean length of the triangles' edges (interior edges counted twice).
fn mean_edge_length(positions: &[Point3<f64>], triangles: &[[u32; 3]]) -> f64 {
    let mut sum = 0.0;
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            sum += (positions[a] - positions[b]).norm();
        }
    }
    if triangles.is_empty() {
        0.0
    } else {
        sum / (3 * triangles.len()) as f64
    }
}

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
/// within which a point is left out; `buffers`, when given, each camera's index buffer of
/// `positions` at that level (`rasterize`), already made for another use of the same view.
/// Returns how many pixels were dropped.
pub(crate) fn drop_at_depth_edges(
    set: &mut PatchSet,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    projections: &[Projection],
    sizes: &[(usize, usize)],
    reach: usize,
    buffers: Option<Vec<IndexBuffer>>,
) -> usize {
    if set.patches.is_empty() {
        return 0;
    }
    let tolerance = TOLERANCE_EDGES * mean_edge_length(positions, triangles);
    if tolerance.is_nan() || tolerance <= 0.0 {
        return 0;
    }
    let views: Vec<View> = match buffers {
        Some(b) => b
            .into_par_iter()
            .map(|ib| View::new(ib, tolerance, reach))
            .collect(),
        None => projections
            .par_iter()
            .zip(sizes)
            .map(|(p, &(w, h))| {
                View::new(rasterize(positions, triangles, p, w, h), tolerance, reach)
            })
            .collect(),
    };
    let keep = keep_of(
        set,
        positions,
        triangles,
        projections,
        &views,
        tolerance,
        true,
    );
    if keep
        .iter()
        .all(|k| k.as_ref().is_none_or(|k| k.iter().all(|&k| k)))
    {
        return 0;
    }
    let keep: Vec<Vec<bool>> = keep
        .into_iter()
        .zip(&set.patches)
        .map(|(k, p)| k.unwrap_or_else(|| vec![true; (p.end - p.start) as usize]))
        .collect();
    set.retain_pixels(&keep)
}

/// Per patch, which of its pixels to keep (`None`: all of them). With `whole`, a patch whose
/// triangle's projection (grown by a pixel) meets no depth edge and no surface nearer than the
/// triangle's farthest corner by the tolerance ([`View::clear_of`]) is kept whole without
/// looking at its pixels; every other patch is judged pixel by pixel, so the result is the same
/// either way (tested).
fn keep_of(
    set: &PatchSet,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    projections: &[Projection],
    views: &[View],
    tolerance: f64,
    whole: bool,
) -> Vec<Option<Vec<bool>>> {
    let pixels = &set.pixels;
    set.patches
        .par_iter()
        .map(|p| {
            let tri = triangles[p.triangle as usize].map(|v| positions[v as usize]);
            let (proj, view) = (&projections[p.camera as usize], &views[p.camera as usize]);
            if whole && view.clear_of(proj, &tri, tolerance) {
                return None;
            }
            Some(
                pixels[p.start as usize..p.end as usize]
                    .iter()
                    .map(|s| {
                        let l = s.lambda.map(f64::from);
                        let x = Point3::from(
                            tri[0].coords * l[0] + tri[1].coords * l[1] + tri[2].coords * l[2],
                        );
                        !view.at_depth_edge(proj, &x, p.triangle, tolerance)
                    })
                    .collect(),
            )
        })
        .collect()
}

/// The side of the square tiles [`View`] summarises its index buffer in.
const TILE: usize = 8;

/// One camera's index buffer of the mesh, and which of its pixels lie within `reach` of a depth
/// edge: two neighbouring covered pixels (4-connected) whose depths differ by more than the
/// tolerance, both sides marked, then grown by `reach` pixels (Chebyshev). Along a slanted
/// surface neighbouring pixels differ by the slant over one pixel only, far below the tolerance.
struct View {
    ib: IndexBuffer,
    /// The index buffer's window grown by `reach` (within the image): where `near_edge` lies.
    area: Window,
    near_edge: Vec<bool>,
    /// Per `TILE`×`TILE` tile of the image (row-major, `tiles_x` per row): whether any of its
    /// pixels is near an edge, and the least depth any triangle has in it (infinite where none
    /// covers it).
    tiles_x: usize,
    tile_edge: Vec<bool>,
    tile_depth: Vec<f32>,
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
        let near_edge = grow(&edge, area.width, area.height, reach);
        let tiles_x = ib.width.div_ceil(TILE);
        let tiles = tiles_x * ib.height.div_ceil(TILE);
        let mut tile_edge = vec![false; tiles];
        let mut tile_depth = vec![f32::INFINITY; tiles];
        for (i, &e) in near_edge.iter().enumerate() {
            if e {
                let (x, y) = area.pixel(i);
                tile_edge[(y / TILE) * tiles_x + x / TILE] = true;
            }
        }
        for (i, &d) in depth.iter().enumerate() {
            let (x, y) = win.pixel(i);
            let t = &mut tile_depth[(y / TILE) * tiles_x + x / TILE];
            *t = t.min(d);
        }
        View {
            near_edge,
            area,
            ib,
            tiles_x,
            tile_edge,
            tile_depth,
        }
    }

    /// Whether no point of triangle `tri` can be at a depth edge or hidden
    /// ([`View::at_depth_edge`]): every corner in front of the camera, and the tiles under its
    /// projection, grown by a pixel (a template pixel's barycentrics are `f32`), hold no pixel
    /// near an edge and no surface nearer than the farthest corner less the tolerance (with a
    /// relative margin of 10⁻⁶ for the barycentrics' rounding). `false` says nothing: the
    /// pixels are then judged one by one.
    fn clear_of(&self, proj: &Projection, tri: &[Point3<f64>; 3], tolerance: f64) -> bool {
        let (mut u0, mut u1, mut v0, mut v1, mut zmax) =
            (f64::MAX, f64::MIN, f64::MAX, f64::MIN, 0.0f64);
        for x in tri {
            let h = proj.project_h(x);
            if !h.z.is_finite() || h.z <= 0.0 || !h.x.is_finite() || !h.y.is_finite() {
                return false;
            }
            let (u, v) = (h.x / h.z + 0.5, h.y / h.z + 0.5);
            (u0, u1, v0, v1) = (u0.min(u), u1.max(u), v0.min(v), v1.max(v));
            zmax = zmax.max(h.z);
        }
        let (w, h) = (self.ib.width as f64, self.ib.height as f64);
        // The pixels a point may fall in, within the image (a point off it is not judged).
        let (u0, v0) = ((u0 - 1.0).max(0.0), (v0 - 1.0).max(0.0));
        let (u1, v1) = ((u1 + 1.0).min(w - 1.0), (v1 + 1.0).min(h - 1.0));
        if !(u0 <= u1 && v0 <= v1) {
            return true;
        }
        let limit = zmax * (1.0 + 1e-6) - tolerance;
        let (tx0, tx1) = (u0 as usize / TILE, u1 as usize / TILE);
        let (ty0, ty1) = (v0 as usize / TILE, v1 as usize / TILE);
        (ty0..=ty1).all(|ty| {
            (tx0..=tx1).all(|tx| {
                let t = ty * self.tiles_x + tx;
                !self.tile_edge[t] && f64::from(self.tile_depth[t]) >= limit
            })
        })
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::camera::look_at;
    use crate::base::image::RgbImage;
    use crate::base::mesh::grid;
    use crate::tracker::patch::PatchOptions;
    use nalgebra::{Matrix3, Vector3};

    /// A triangle whose projection meets no depth edge and no nearer surface is kept whole
    /// without looking at its pixels, and that decides nothing: a sheet with a strip of the
    /// same mesh in front of it, the strip moved on, seen at two pyramid levels' sizes and
    /// reaches, gives every pixel the verdict the pixel-by-pixel check gives, while most
    /// patches take the shortcut and the pixels along the strip's edges are dropped.
    #[test]
    fn patches_kept_whole_are_the_ones_no_pixel_of_which_is_dropped() {
        // The sheet's triangles about 10 px across at 320×240, the strip 25 cm (about 100 px)
        // wide: some of the sheet lies behind the strip's middle, far from any edge.
        let sheet = grid(25, 25, |s, t| {
            Point3::new(-0.3 + 0.6 * s, 0.1, -0.25 + 0.5 * t)
        });
        let strip = grid(4, 9, |s, t| {
            Point3::new(-0.25 + 0.25 * s, -0.15, -0.3 + 0.6 * t)
        });
        let n = sheet.positions.len() as u32;
        let mut positions = sheet.positions.clone();
        positions.extend(&strip.positions);
        let mut triangles = sheet.triangles.clone();
        triangles.extend(strip.triangles.iter().map(|t| t.map(|v| v + n)));
        // The strip swept 4 cm on (about 15 px): its edges now lie over other template pixels.
        let moved: Vec<Point3<f64>> = positions
            .iter()
            .enumerate()
            .map(|(i, p)| p + Vector3::new(if i as u32 >= n { 0.04 } else { 0.002 }, 0.0, 0.0))
            .collect();
        for (w, h, reach) in [(320usize, 240usize, 2usize), (160, 120, 0)] {
            let f = 600.0 * w as f64 / 320.0;
            let k = Matrix3::new(
                f,
                0.0,
                (w as f64 - 1.0) / 2.0,
                0.0,
                f,
                (h as f64 - 1.0) / 2.0,
                0.0,
                0.0,
                1.0,
            );
            let (r, t) = look_at(
                &Point3::new(-0.1, -1.6, 0.1),
                &Point3::origin(),
                &Vector3::z(),
            );
            let proj = Projection::from_krt(&k, &r, &t).unwrap();
            let mut set = PatchSet::default();
            let opts = PatchOptions {
                margin: reach,
                min_cos: 0.1,
                two_sided: true,
                checkerboard: false,
                stride: 1,
            };
            let image = RgbImage::new(w, h);
            set.add_camera(&positions, &triangles, &proj, &image, 0, 1.0, &opts, None);
            let tolerance = TOLERANCE_EDGES * mean_edge_length(&moved, &triangles);
            let views = [View::new(
                rasterize(&moved, &triangles, &proj, w, h),
                tolerance,
                reach,
            )];
            let projections = [proj];
            let keep = |whole| {
                keep_of(
                    &set,
                    &moved,
                    &triangles,
                    &projections,
                    &views,
                    tolerance,
                    whole,
                )
            };
            let (fast, slow) = (keep(true), keep(false));
            let (mut whole, mut dropped) = (0, 0);
            for ((f, s), p) in fast.iter().zip(&slow).zip(&set.patches) {
                let s = s.as_ref().unwrap();
                match f {
                    Some(f) => assert_eq!(f, s, "{w}×{h}: triangle {}", p.triangle),
                    None => {
                        whole += 1;
                        assert!(
                            s.iter().all(|&k| k),
                            "{w}×{h}: triangle {} kept whole",
                            p.triangle
                        );
                    }
                }
                dropped += s.iter().filter(|&&k| !k).count();
            }
            eprintln!(
                "{w}×{h}: {whole} of {} patches kept whole, {dropped} pixels dropped",
                set.patches.len()
            );
            assert!(
                whole * 2 > set.patches.len(),
                "{w}×{h}: {whole} of {} kept whole",
                set.patches.len()
            );
            assert!(dropped > 20, "{w}×{h}: {dropped} pixels dropped");
        }
    }
}

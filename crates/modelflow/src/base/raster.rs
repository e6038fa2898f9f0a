//! Scan-line rasterization of a mesh's projection into a z-buffered *index buffer*: for every
//! pixel, the nearest triangle whose projection covers the pixel centre (the thesis' index patches,
//! §6.2.3, with the z-buffer of §8.4.1 so that a pixel belongs to at most one triangle). Also
//! decides which of those pixels are safe to use for tracking: not on a back-facing or grazing
//! triangle, and not next to a silhouette or an occlusion boundary.
//!
//! Hand-written: it is part of the product (the tracker and the baseline's visibility test share
//! it) and must follow the pixel-centre convention of `camera` exactly.

use crate::base::camera::Projection;
use nalgebra::Point3;

/// Marks a pixel covered by no triangle.
pub const NONE: u32 = u32::MAX;

/// Pixels of a row whose depths the rasteriser computes before it z-tests them.
const SPAN_RUN: usize = 64;

/// A rectangle of an image's pixels: columns `x0..x0 + width`, rows `y0..y0 + height`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub x0: usize,
    pub y0: usize,
    pub width: usize,
    pub height: usize,
}

impl Window {
    /// The index of pixel `(x, y)` in a row-major buffer of the window, if it lies inside.
    #[inline]
    pub fn index(&self, x: usize, y: usize) -> Option<usize> {
        let (dx, dy) = (x.wrapping_sub(self.x0), y.wrapping_sub(self.y0));
        (dx < self.width && dy < self.height).then(|| dy * self.width + dx)
    }

    /// The image pixel `(x, y)` of index `i` of a row-major buffer of the window.
    #[inline]
    pub fn pixel(&self, i: usize) -> (usize, usize) {
        (self.x0 + i % self.width, self.y0 + i / self.width)
    }

    /// The number of pixels in the window.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// The window grown by `r` pixels on every side, within a `w`×`h` image.
    pub fn grown(&self, r: usize, w: usize, h: usize) -> Window {
        if self.len() == 0 {
            return *self;
        }
        let (x0, y0) = (self.x0.saturating_sub(r), self.y0.saturating_sub(r));
        let x1 = (self.x0 + self.width - 1 + r).min(w - 1);
        let y1 = (self.y0 + self.height - 1 + r).min(h - 1);
        Window {
            x0,
            y0,
            width: x1 + 1 - x0,
            height: y1 + 1 - y0,
        }
    }
}

/// Per-pixel owner triangle and depth of one camera's view of a mesh.
///
/// Only the *window* of the image that the mesh's projection covers is stored (every covered
/// pixel lies in it; the rest of the image is covered by no triangle): the work of building,
/// masking and sorting a template grows with the pixels the mesh covers, not with the image.
#[derive(Clone, Debug)]
pub struct IndexBuffer {
    /// The image's size.
    pub width: usize,
    pub height: usize,
    /// Where `owner` and `depth` lie in the image.
    pub window: Window,
    /// Owner triangle per pixel of the window (row-major), or [`NONE`].
    owner: Vec<u32>,
    /// Depth (camera z) per pixel of the window; `f32::INFINITY` where no triangle.
    depth: Vec<f32>,
    /// Per triangle, its plane's inverse depth as an affine function of the pixel position:
    /// `1/z = a·x + b·y + c` (`[a, b, c]`; NaN for a triangle not rasterized).
    pub planes: Vec<[f64; 3]>,
    /// The size of a pixel seen at unit depth (1 / the focal length in pixels).
    pub footprint: f64,
}

impl IndexBuffer {
    /// The triangle that owns pixel `(x, y)` of the image, or [`NONE`].
    #[inline]
    pub fn owner_at(&self, x: usize, y: usize) -> u32 {
        self.window.index(x, y).map_or(NONE, |i| self.owner[i])
    }

    /// The depth seen at pixel `(x, y)` of the image (`f32::INFINITY` where no triangle).
    #[inline]
    pub fn depth_at(&self, x: usize, y: usize) -> f32 {
        self.window
            .index(x, y)
            .map_or(f32::INFINITY, |i| self.depth[i])
    }

    /// The owners of the window's pixels, row-major ([`IndexBuffer::window`]).
    pub fn owners(&self) -> &[u32] {
        &self.owner
    }

    /// The depths of the window's pixels, row-major.
    pub fn depths(&self) -> &[f32] {
        &self.depth
    }
}

/// Screen-space data of one projected triangle: corners in pixels, `1/z` at each, signed area.
pub(crate) struct Projected {
    p: [[f64; 2]; 3],
    inv_z: [f64; 3],
    area: f64,
}

impl Projected {
    /// The area it covers, in square pixels.
    pub(crate) fn pixel_area(&self) -> f64 {
        0.5 * self.area.abs()
    }

    /// The perspective-correct barycentric coordinates of pixel centre `(x, y)` on the 3-D
    /// triangle (weights of its corners for the surface point seen there).
    pub(crate) fn surface_barycentric(&self, x: f64, y: f64) -> [f64; 3] {
        let l = screen_barycentric(&self.p, self.area, x, y);
        let w: [f64; 3] = std::array::from_fn(|k| l[k] * self.inv_z[k]);
        let sum = w[0] + w[1] + w[2];
        w.map(|v| v / sum)
    }
}

/// Projects triangle `tri` by `proj`; `None` when a corner is not in front of the camera or the
/// projection is degenerate (such a triangle covers no pixel).
pub(crate) fn project_triangle(
    positions: &[Point3<f64>],
    tri: &[u32; 3],
    proj: &Projection,
) -> Option<Projected> {
    let mut p = [[0.0; 2]; 3];
    let mut inv_z = [0.0; 3];
    for k in 0..3 {
        let h = proj.project_h(&positions[tri[k] as usize]);
        // No near-plane clipping: a triangle reaching behind the camera is skipped.
        if h.z.is_nan() || h.z <= 1e-9 {
            return None;
        }
        p[k] = [h.x / h.z, h.y / h.z];
        inv_z[k] = 1.0 / h.z;
    }
    let area =
        (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]);
    (area.abs() > 1e-12 && area.is_finite()).then_some(Projected { p, inv_z, area })
}

/// Rasterizes every triangle (in index order; on equal depth the earlier triangle keeps the
/// pixel, so the result is deterministic). A pixel `(x, y)` is covered when its centre lies inside
/// or on the boundary of the projected triangle.
pub fn rasterize(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    proj: &Projection,
    width: usize,
    height: usize,
) -> IndexBuffer {
    // The focal length from the matrix alone (any scale of P): with M = λ·K·R, the cross
    // product of its first and last rows is λ²·f·(r₁ × r₃).
    let m = proj.matrix();
    let (r1, r3) = (
        nalgebra::Vector3::new(m[(0, 0)], m[(0, 1)], m[(0, 2)]),
        nalgebra::Vector3::new(m[(2, 0)], m[(2, 1)], m[(2, 2)]),
    );
    let focal = r1.cross(&r3).norm() / r3.norm_squared();
    let projected: Vec<Option<Projected>> = triangles
        .iter()
        .map(|tri| project_triangle(positions, tri, proj))
        .collect();
    // The window: the pixel rows and columns the triangles' corners span, one column wider on
    // each side than their extremes' pixel centres (a covered column is found from the edges'
    // crossings, which can round past a corner's own coordinate); the spans are held to it.
    let (mut x0, mut y0, mut x1, mut y1) = (
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    );
    for t in projected.iter().flatten() {
        for q in &t.p {
            (x0, x1, y0, y1) = (x0.min(q[0]), x1.max(q[0]), y0.min(q[1]), y1.max(q[1]));
        }
    }
    let (x0, x1) = (
        (ceil(x0) - 1.0).max(0.0),
        (floor(x1) + 1.0).min(width as f64 - 1.0),
    );
    let (y0, y1) = (ceil(y0).max(0.0), floor(y1).min(height as f64 - 1.0));
    let window = if x0 <= x1 && y0 <= y1 {
        Window {
            x0: x0 as usize,
            y0: y0 as usize,
            width: (x1 - x0) as usize + 1,
            height: (y1 - y0) as usize + 1,
        }
    } else {
        Window {
            x0: 0,
            y0: 0,
            width: 0,
            height: 0,
        }
    };
    let mut ib = IndexBuffer {
        width,
        height,
        window,
        owner: vec![NONE; window.len()],
        depth: vec![f32::INFINITY; window.len()],
        planes: vec![[f64::NAN; 3]; triangles.len()],
        footprint: 1.0 / focal,
    };
    for (ti, t) in projected.iter().enumerate() {
        let Some(t) = t else {
            continue;
        };
        // 1/z is affine in the image over a plane: read it at three pixel positions.
        let inv_z = |x: f64, y: f64| {
            let b = screen_barycentric(&t.p, t.area, x, y);
            b[0] * t.inv_z[0] + b[1] * t.inv_z[1] + b[2] * t.inv_z[2]
        };
        let c = inv_z(0.0, 0.0);
        ib.planes[ti] = [inv_z(1.0, 0.0) - c, inv_z(0.0, 1.0) - c, c];
        if window.len() == 0 {
            continue;
        }
        let (wx0, wx1) = (window.x0, window.x0 + window.width);
        for_each_span(t, width, height, |y, xa, xb| {
            let yf = y as f64;
            let row = (y - window.y0) * window.width;
            let (mut x, end) = (xa.max(wx0), xb.min(wx1 - 1) + 1);
            // A run of depths first (no branch: the compiler computes them two or four
            // abreast), then the z-test; the same arithmetic per pixel as one at a time.
            let mut zs = [0.0f32; SPAN_RUN];
            while x < end {
                let n = (end - x).min(SPAN_RUN);
                let x0 = x as f64;
                for (k, z) in zs[..n].iter_mut().enumerate() {
                    let b = screen_barycentric(&t.p, t.area, x0 + k as i32 as f64, yf);
                    let inv_z = b[0] * t.inv_z[0] + b[1] * t.inv_z[1] + b[2] * t.inv_z[2];
                    *z = (1.0 / inv_z) as f32;
                }
                let at = row + x - window.x0;
                let (depth, owner) = (&mut ib.depth[at..at + n], &mut ib.owner[at..at + n]);
                for ((d, o), &z) in depth.iter_mut().zip(owner.iter_mut()).zip(&zs[..n]) {
                    if z < *d {
                        *d = z;
                        *o = ti as u32;
                    }
                }
                x += n;
            }
        });
    }
    ib
}

/// Calls `f(y, x_first, x_last)` for every row `y` of a `width`×`height` image in which the
/// projected triangle covers pixel centres, with the first and last covered column.
#[inline]
fn for_each_span(
    t: &Projected,
    width: usize,
    height: usize,
    mut f: impl FnMut(usize, usize, usize),
) {
    let ymin = ceil(t.p.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min)).max(0.0);
    let ymax =
        floor(t.p.iter().map(|q| q[1]).fold(f64::NEG_INFINITY, f64::max)).min(height as f64 - 1.0);
    if ymin > ymax {
        return;
    }
    let s = t.area.signum();
    for y in ymin as usize..=ymax as usize {
        let yf = y as f64;
        // Each edge function E(x) = A·x + B must be >= 0 (times the orientation sign).
        let (mut xl, mut xr) = (0.0f64, width as f64 - 1.0);
        let mut empty = false;
        for k in 0..3 {
            let [xi, yi] = t.p[k];
            let [xj, yj] = t.p[(k + 1) % 3];
            // E(x, y) = (xj - xi)(y - yi) - (yj - yi)(x - xi): positive inside for area > 0.
            let a = -s * (yj - yi);
            let b = s * ((xj - xi) * (yf - yi) + (yj - yi) * xi);
            if a > 0.0 {
                xl = xl.max(-b / a);
            } else if a < 0.0 {
                xr = xr.min(-b / a);
            } else if b < 0.0 {
                empty = true;
            }
        }
        if empty {
            continue;
        }
        let (x0, x1) = (ceil(xl), floor(xr));
        if x0 > x1 {
            continue;
        }
        f(y, x0 as usize, x1 as usize);
    }
}

#[inline]
fn screen_barycentric(p: &[[f64; 2]; 3], area: f64, x: f64, y: f64) -> [f64; 3] {
    let e = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
    [
        e(p[1], p[2]) / area,
        e(p[2], p[0]) / area,
        e(p[0], p[1]) / area,
    ]
}

/// Which triangles may contribute pixels in one camera: front-facing enough to be trusted.
///
/// A triangle is *usable* when the cosine between its normal and the direction to the camera is
/// at least `min_cos`. For a closed mesh, orientation matters (back faces are never used); an open
/// sheet is two-sided, so only grazing triangles are dropped.
pub fn usable_triangles(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    proj: &Projection,
    two_sided: bool,
    min_cos: f64,
) -> Vec<bool> {
    facing_cosines(positions, triangles, proj)
        .into_iter()
        .map(|cos| {
            if two_sided {
                cos.abs() >= min_cos
            } else {
                cos >= min_cos
            }
        })
        .collect()
}

/// Per triangle, the cosine between its normal (by its corners' order) and the way from its
/// centroid to the camera: positive where the camera sees its front, negative its back, NaN for
/// a degenerate triangle or one whose centroid is the camera's centre.
pub(crate) fn facing_cosines(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    proj: &Projection,
) -> Vec<f64> {
    let c = proj.center();
    triangles
        .iter()
        .map(|t| {
            let [a, b, d] = t.map(|v| positions[v as usize]);
            let n = (b - a).cross(&(d - a));
            let centroid = Point3::from((a.coords + b.coords + d.coords) / 3.0);
            let to_cam = c - centroid;
            let denom = n.norm() * to_cam.norm();
            if denom <= 0.0 {
                return f64::NAN;
            }
            n.dot(&to_cam) / denom
        })
        .collect()
}

/// A triangle seen more edge-on than this (the cosine between its normal and the way to the
/// camera) shows a camera little of its surface: its pixels mix the surface with what lies
/// beyond its outline, and a small error in the mesh moves where they fall a long way. What a
/// camera *reads* of a surface (the colour balance, one camera's disagreement with the others)
/// is read only where it faces the camera at least this much.
pub(crate) const WELL_FACING: f64 = 0.25;

/// How far (in pixels seen at that depth) a neighbouring pixel's surface may lie off the plane
/// of a pixel's triangle and still count as the same surface (see [`trackable_mask`]).
const CONTINUOUS_PX: f64 = 1.5;

/// Pixels that are safe to track: owned by a usable triangle, and every pixel within `margin`
/// (Chebyshev distance) shows the same surface: it is owned by the same triangle, by a mesh
/// neighbour of it (one that shares a vertex), or by a triangle whose depth there lies within
/// `CONTINUOUS_PX` pixels (at that depth) of this triangle's plane. Pixels near the background,
/// near an occluding fold or on a silhouette are dropped, because there the colour mixes two
/// surfaces and the warp of one triangle does not hold. The depth test is what keeps a finely
/// triangulated mesh at a coarse pyramid level, where a pixel's neighbours belong to triangles
/// several rings away on the same smooth surface: with mesh neighbours alone a 10 000-vertex
/// cloth kept no pixel at all at the coarsest level of its 640×480 footage.
///
/// With `checkerboard`, only pixels with even `x + y` are considered (the rest are `false`
/// without being tested): the tracker keeps only those at full resolution.
///
/// The mask covers the index buffer's window ([`IndexBuffer::window`], row-major): no pixel
/// outside it is covered, so none is trackable.
pub fn trackable_mask(
    ib: &IndexBuffer,
    triangles: &[[u32; 3]],
    usable: &[bool],
    margin: usize,
    checkerboard: bool,
) -> Vec<bool> {
    let (w, h) = (ib.width, ib.height);
    let win = ib.window;
    let mut mask = vec![false; win.len()];
    let m = margin as isize;
    let step = if checkerboard { 2 } else { 1 };
    let owner = &ib.owner[..];
    // Whether neighbour `o` at `(xx, yy)` (inside the image, not `t` itself) shows the same
    // surface as triangle `t` (corners `tv`).
    let same = |t: u32, tv: &[u32; 3], o: u32, xx: usize, yy: usize| {
        if o == t {
            return true;
        }
        if o == NONE {
            return false;
        }
        if triangles[o as usize].iter().any(|v| tv.contains(v)) {
            return true;
        }
        // Not a mesh neighbour: the same surface only if the depth seen there lies on this
        // triangle's plane (within the tolerance).
        let [a, b, c] = ib.planes[t as usize];
        let z = ib.depth_at(xx, yy) as f64;
        let inv = a * xx as f64 + b * yy as f64 + c;
        inv > 0.0 && (1.0 / inv - z).abs() <= CONTINUOUS_PX * ib.footprint * z
    };
    let side = 2 * margin + 1;
    // `level[i]`: the `side` owners of pixel `i`'s row centred on it are all the same (false
    // within `margin` of the window's sides). Computed once per row, in a pass the compiler
    // vectorises, it lets a pixel inside a triangle pass with one test per row.
    let mut level = vec![false; win.len()];
    if win.width > 2 * margin {
        for (o, l) in owner
            .chunks_exact(win.width)
            .zip(level.chunks_exact_mut(win.width))
        {
            let l = &mut l[margin..win.width - margin];
            if margin == 1 {
                for (l, w) in l.iter_mut().zip(o.windows(3)) {
                    *l = (w[0] == w[1]) & (w[2] == w[1]);
                }
            } else {
                for (l, w) in l.iter_mut().zip(o.windows(side)) {
                    *l = w.iter().all(|&v| v == w[margin]);
                }
            }
        }
    }
    for y in win.y0..win.y0 + win.height {
        let row = (y - win.y0) * win.width;
        let rows_inside = y >= win.y0 + margin && y + margin < win.y0 + win.height;
        // The checkerboard keeps the pixels with even x + y of the image.
        let first = if checkerboard {
            win.x0 + (win.x0 + y) % 2
        } else {
            win.x0
        };
        // The last two triangles found to be mesh neighbours of `cached_for` (which is one
        // itself): pixels along an edge meet the same neighbour again and again, and whether
        // two triangles share a corner depends on them alone.
        let (mut cached_for, mut near) = (NONE, [NONE; 2]);
        let mut x = first;
        while x < win.x0 + win.width {
            let i = row + x - win.x0;
            let t = owner[i];
            x += step;
            if t == NONE || !usable[t as usize] {
                continue;
            }
            let tv = triangles[t as usize];
            let xc = x - step;
            let ok = if rows_inside && xc >= win.x0 + margin && xc + margin < win.x0 + win.width {
                // The whole neighbourhood lies in the window (so in the image): read the
                // owners by offset, row by row, and look closer only where one differs.
                if cached_for != t {
                    (cached_for, near) = (t, [t, t]);
                }
                let corner = i - margin * win.width - margin;
                let inside = (0..side).all(|r| {
                    let j = corner + margin + r * win.width;
                    level[j] && owner[j] == t
                });
                let neighbour =
                    |o: u32| o != NONE && triangles[o as usize].iter().any(|v| tv.contains(v));
                let deep =
                    |r: usize, c: usize, o: u32| same(t, &tv, o, xc - margin + c, y - margin + r);
                let block = Block {
                    corner,
                    width: win.width,
                    t,
                };
                match margin {
                    _ if inside => true,
                    // The same test, unrolled by the compiler for the usual margins.
                    1 => rows_show(owner, &block, 3, &mut near, neighbour, deep),
                    2 => rows_show(owner, &block, 5, &mut near, neighbour, deep),
                    _ => rows_show(owner, &block, side, &mut near, neighbour, deep),
                }
            } else {
                (-m..=m).all(|dy| {
                    (-m..=m).all(|dx| {
                        let (xx, yy) = (xc as isize + dx, y as isize + dy);
                        if xx < 0 || yy < 0 || xx >= w as isize || yy >= h as isize {
                            return false;
                        }
                        let (xx, yy) = (xx as usize, yy as usize);
                        same(t, &tv, ib.owner_at(xx, yy), xx, yy)
                    })
                })
            };
            mask[i] = ok;
        }
    }
    mask
}

/// A square of an index buffer's window: its top-left index, the window's row length, and
/// the triangle whose neighbourhood it is.
struct Block {
    corner: usize,
    width: usize,
    t: u32,
}

/// Whether every pixel of the `side`×`side` square `b` of `owner` shows the surface of
/// triangle `b.t`: owned by it, by one of `near` (triangles already found to be its mesh
/// neighbours; one found by `neighbour` is put there), or accepted by `deep(row, column,
/// owner)`. A row owned by `b.t` alone, the common case inside a triangle, is one pass of
/// compares. Inlined always, so that a constant `side` unrolls the rows.
#[inline(always)]
fn rows_show(
    owner: &[u32],
    b: &Block,
    side: usize,
    near: &mut [u32; 2],
    neighbour: impl Fn(u32) -> bool,
    deep: impl Fn(usize, usize, u32) -> bool,
) -> bool {
    for r in 0..side {
        let start = b.corner + r * b.width;
        let row = &owner[start..start + side];
        if row.iter().all(|&o| o == b.t) {
            continue;
        }
        for (c, &o) in row.iter().enumerate() {
            if o == near[0] || o == near[1] {
                continue;
            }
            if neighbour(o) {
                *near = [o, near[0]];
            } else if !deep(r, c, o) {
                return false;
            }
        }
    }
    true
}

/// `x.floor()`, to the bit (NaN, infinities and the sign of zero included), without the call
/// into the software `floor` that `f64::floor` makes on x86-64 without SSE 4.1: the
/// rasteriser rounds both ends of every row of every triangle, and the calls were 0.8 % of the
/// hard sample's instructions (docs/speed.md, 2026-12-06).
#[inline(always)]
fn floor(x: f64) -> f64 {
    // From 2^52 on every f64 is an integer; below, the conversion to i64 is exact.
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = x as i64 as f64;
        if t == x {
            x
        } else if t > x {
            t - 1.0
        } else {
            t
        }
    } else {
        x
    }
}

/// `x.ceil()`, to the bit, as [`floor`].
#[inline(always)]
fn ceil(x: f64) -> f64 {
    -floor(-x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    /// Whether image pixel `(x, y)` is kept by `mask` (over `ib`'s window).
    fn at(ib: &IndexBuffer, mask: &[bool], x: usize, y: usize) -> bool {
        ib.window.index(x, y).is_some_and(|i| mask[i])
    }

    fn camera() -> Projection {
        let k = Matrix3::new(100.0, 0.0, 31.5, 0.0, 100.0, 23.5, 0.0, 0.0, 1.0);
        Projection::from_krt(&k, &Matrix3::identity(), &Vector3::zeros()).unwrap()
    }

    #[test]
    fn covers_exactly_the_pixel_centres_inside() {
        // A right triangle with vertices on pixel centres (10,10), (20,10), (10,20) at depth 1.
        let p = camera();
        let to3 = |u: f64, v: f64| Point3::new((u - 31.5) / 100.0, (v - 23.5) / 100.0, 1.0);
        let pos = vec![to3(10.0, 10.0), to3(20.0, 10.0), to3(10.0, 20.0)];
        let ib = rasterize(&pos, &[[0, 1, 2]], &p, 64, 48);
        let covered: usize = ib.owners().iter().filter(|&&o| o == 0).count();
        // Pixel centres with x>=10, y>=10, (x-10)+(y-10) <= 10: 11+10+...+1 = 66.
        assert_eq!(covered, 66);
        assert_eq!(ib.owner_at(10, 10), 0);
        assert_eq!(ib.owner_at(20, 10), 0);
        assert_eq!(ib.owner_at(15, 15), 0);
        assert_eq!(ib.owner_at(16, 15), NONE);
        assert_eq!(ib.owner_at(9, 10), NONE);
        assert!((ib.depth_at(12, 15) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn only_the_window_the_mesh_spans_is_stored_and_every_covered_pixel_lies_in_it() {
        // Two triangles near the top-left corner of a 640×480 image, one of them reaching past
        // its left edge: the buffer stores the rows whose centres the corners span (11 to 41)
        // and their columns, one more on each side (0 to 51), and reads outside as uncovered.
        let k = Matrix3::new(100.0, 0.0, 319.5, 0.0, 100.0, 239.5, 0.0, 0.0, 1.0);
        let p = Projection::from_krt(&k, &Matrix3::identity(), &Vector3::zeros()).unwrap();
        let to3 = |u: f64, v: f64| Point3::new((u - 319.5) / 100.0, (v - 239.5) / 100.0, 1.0);
        let pos = vec![
            to3(-20.3, 10.2),
            to3(30.7, 12.0),
            to3(5.5, 40.6),
            to3(50.2, 41.0),
        ];
        let tris = [[0u32, 1, 2], [1, 3, 2]];
        let ib = rasterize(&pos, &tris, &p, 640, 480);
        assert_eq!(
            ib.window,
            Window {
                x0: 0,
                y0: 11,
                width: 52,
                height: 31
            }
        );
        assert_eq!(ib.owners().len(), 52 * 31);
        // Every pixel of the image: covered exactly where a centre lies inside a triangle
        // (none on an edge here), and only inside the window.
        let inside = |t: &[u32; 3], x: f64, y: f64| {
            let q = t.map(|v| {
                let h = p.project(&pos[v as usize]).unwrap();
                [h.x, h.y]
            });
            let e =
                |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
            let s = [e(q[0], q[1]), e(q[1], q[2]), e(q[2], q[0])];
            s.iter().all(|&v| v > 0.0) || s.iter().all(|&v| v < 0.0)
        };
        let mut covered = 0;
        for y in 0..480 {
            for x in 0..640 {
                let want = tris.iter().position(|t| inside(t, x as f64, y as f64));
                let got = ib.owner_at(x, y);
                assert_eq!(got, want.map_or(NONE, |t| t as u32), "pixel ({x}, {y})");
                if got != NONE {
                    covered += 1;
                    assert!(ib.window.index(x, y).is_some());
                    assert!((ib.depth_at(x, y) - 1.0).abs() < 1e-6);
                } else {
                    assert_eq!(ib.depth_at(x, y), f32::INFINITY);
                }
            }
        }
        assert!(covered > 1000);
        // Nothing in front of the camera: an empty window, and nothing covered.
        let behind: Vec<_> = pos.iter().map(|q| Point3::new(q.x, q.y, -1.0)).collect();
        let ib = rasterize(&behind, &tris, &p, 640, 480);
        assert_eq!(ib.window.len(), 0);
        assert_eq!(ib.owner_at(20, 20), NONE);
        let mask = trackable_mask(&ib, &tris, &[true, true], 1, false);
        assert!(mask.is_empty());
    }

    #[test]
    fn nearest_triangle_wins_and_depth_is_perspective_correct() {
        let p = camera();
        let quad = |z: f64| {
            vec![
                Point3::new(-0.2 * z, -0.2 * z, z),
                Point3::new(0.2 * z, -0.2 * z, z),
                Point3::new(0.0, 0.2 * z, z),
            ]
        };
        let mut pos = quad(3.0);
        pos.extend(quad(2.0));
        let ib = rasterize(&pos, &[[0, 1, 2], [3, 4, 5]], &p, 64, 48);
        assert_eq!(
            ib.owner_at(31, 24),
            1,
            "the nearer triangle (index 1) owns the centre"
        );
        // A slanted triangle: depth at a pixel equals the ray's intersection with the plane.
        let pos = vec![
            Point3::new(-1.0, -1.0, 2.0),
            Point3::new(1.0, -1.0, 4.0),
            Point3::new(0.0, 1.0, 3.0),
        ];
        let ib = rasterize(&pos, &[[0, 1, 2]], &p, 64, 48);
        // Plane: z = 3 + x (through all three points). Ray through pixel (u,v): x = z(u-31.5)/100.
        let (u, v) = (35usize, 20usize);
        let rx = (u as f64 - 31.5) / 100.0;
        let z = 3.0 / (1.0 - rx);
        let _ = v;
        assert!(
            (ib.depth_at(u, v) as f64 - z).abs() < 1e-5,
            "{} vs {z}",
            ib.depth_at(u, v)
        );
    }

    /// A square grid of `n × n` vertices spanning pixels `[u0, u1] × [v0, v1]` at depth `z`
    /// (facing the camera), as positions and triangles (indices offset by `base`).
    fn grid(
        n: u32,
        (u0, u1): (f64, f64),
        (v0, v1): (f64, f64),
        z: f64,
        base: u32,
    ) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let mut pos = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let u = u0 + (u1 - u0) * i as f64 / (n - 1) as f64;
                let v = v0 + (v1 - v0) * j as f64 / (n - 1) as f64;
                pos.push(Point3::new(
                    (u - 31.5) / 100.0 * z,
                    (v - 23.5) / 100.0 * z,
                    z,
                ));
            }
        }
        let mut tris = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = base + j * n + i;
                tris.push([a, a + 1, a + n]);
                tris.push([a + 1, a + n + 1, a + n]);
            }
        }
        (pos, tris)
    }

    #[test]
    fn sub_pixel_triangles_of_one_smooth_surface_keep_their_pixels_and_folds_do_not() {
        // 0.25-pixel triangles: a pixel's neighbours are owned by triangles several rings away
        // on the mesh, yet it is one surface, so the interior is trackable.
        let p = camera();
        let (pos, tris) = grid(121, (10.0, 40.0), (8.0, 38.0), 1.0, 0);
        let ib = rasterize(&pos, &tris, &p, 64, 48);
        let usable = vec![true; tris.len()];
        let mask = trackable_mask(&ib, &tris, &usable, 1, false);
        let interior = (12..37).flat_map(|y| (12..39).map(move |x| (x, y)));
        let (n, kept) = interior.fold((0, 0), |(n, k), (x, y)| {
            (n + 1, k + at(&ib, &mask, x, y) as usize)
        });
        assert_eq!(kept, n, "every interior pixel of the fine grid is kept");
        assert!(
            !at(&ib, &mask, 20, 8),
            "the border next to the background is not"
        );
        // A second fine sheet half as far again behind it, sticking out on the right: where the
        // near sheet ends in front of it, the depth jumps and those pixels are dropped on both
        // sides; far from that edge the far sheet's pixels are kept.
        let (far, far_tris) = grid(121, (25.0, 55.0), (8.0, 38.0), 1.5, pos.len() as u32);
        let mut all = pos.clone();
        all.extend(far);
        let mut all_tris = tris.clone();
        all_tris.extend(far_tris);
        let ib = rasterize(&all, &all_tris, &p, 64, 48);
        let usable = vec![true; all_tris.len()];
        let mask = trackable_mask(&ib, &all_tris, &usable, 1, false);
        // The checkerboard tests only the pixels with even x + y, and keeps exactly those of them
        // the full mask keeps.
        let half = trackable_mask(&ib, &all_tris, &usable, 1, true);
        for (i, (&full, &cb)) in mask.iter().zip(&half).enumerate() {
            let (x, y) = ib.window.pixel(i);
            assert_eq!(cb, full && (x + y) % 2 == 0, "pixel ({x}, {y})");
        }
        assert!(half.iter().any(|&k| k));
        assert!(
            !at(&ib, &mask, 40, 20),
            "the near sheet's edge over the far sheet"
        );
        assert!(
            !at(&ib, &mask, 41, 20),
            "the far sheet next to the near one's edge"
        );
        assert!(
            at(&ib, &mask, 30, 20) && at(&ib, &mask, 48, 20),
            "both sheets away from the edge"
        );
    }

    #[test]
    fn silhouette_and_backfacing_pixels_are_not_trackable() {
        let p = camera();
        let to3 = |u: f64, v: f64| Point3::new((u - 31.5) / 100.0, (v - 23.5) / 100.0, 1.0);
        // Counter-clockwise in the image with v down means the normal points away from the camera.
        let pos = vec![to3(5.0, 5.0), to3(40.0, 5.0), to3(5.0, 40.0)];
        let tris = [[0u32, 1, 2]];
        let ib = rasterize(&pos, &tris, &p, 64, 48);
        let facing = usable_triangles(&pos, &tris, &p, false, 0.1);
        let flipped = usable_triangles(&pos, &[[0, 2, 1]], &p, false, 0.1);
        assert_ne!(
            facing[0], flipped[0],
            "exactly one winding faces the camera"
        );
        let two_sided = usable_triangles(&pos, &tris, &p, true, 0.1);
        assert!(two_sided[0]);
        let mask = trackable_mask(&ib, &tris, &two_sided, 1, false);
        assert!(at(&ib, &mask, 10, 10), "interior pixel is trackable");
        assert!(
            !at(&ib, &mask, 20, 5),
            "pixel on the border next to the background is not"
        );
        let none = trackable_mask(&ib, &tris, &[false], 1, false);
        assert!(none.iter().all(|&m| !m));
    }

    proptest::proptest! {
        /// The rasteriser's own rounding is the standard library's, to the bit.
        #[test]
        fn floor_and_ceil_are_the_standard_ones_to_the_bit(
            x in proptest::num::f64::ANY,
            k in -2_000_000i64..2_000_000,
        ) {
            for v in [x, k as f64, k as f64 + 0.5, k as f64 - 1e-9, k as f64 * 1e-3] {
                if v.is_nan() {
                    proptest::prop_assert!(floor(v).is_nan() && ceil(v).is_nan());
                    continue;
                }
                proptest::prop_assert_eq!(floor(v).to_bits(), v.floor().to_bits(), "floor {}", v);
                proptest::prop_assert_eq!(ceil(v).to_bits(), v.ceil().to_bits(), "ceil {}", v);
            }
        }
    }

    #[test]
    fn floor_and_ceil_keep_zeros_signs_infinities_and_nan() {
        for v in [
            0.0,
            -0.0,
            -0.5,
            0.5,
            -1.0,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            4_503_599_627_370_496.0,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
        ] {
            assert_eq!(floor(v).to_bits(), v.floor().to_bits(), "floor {v}");
            assert_eq!(ceil(v).to_bits(), v.ceil().to_bits(), "ceil {v}");
        }
        assert!(floor(f64::NAN).is_nan() && ceil(f64::NAN).is_nan());
    }
}

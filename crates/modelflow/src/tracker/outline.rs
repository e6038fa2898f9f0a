//! Fitting an open mesh's border to the outline the cameras see (`modelflow align --outline`):
//! what photo-consistency cannot do for a flat sheet, whose place within its own plane no
//! camera pair can tell (see `align`).
//!
//! Only the whole-mesh motions the images leave free are searched (for a plane: two
//! translations in it and the rotation about its normal), so the surface photo-consistency found
//! stays where it is. The score is the image contrast *across* the border: at points along
//! every border edge, the squared derivative of each camera's smoothed image along the border's
//! outward normal (projected into that camera), summed over RGB and averaged over points and
//! cameras. It peaks when the border lies on the object's outline against its background, and
//! is maximised by a coarse-to-fine pattern search (a handful of unknowns, so no derivatives
//! needed), from steps of two pixels of the coarsest level down to a twentieth of a pixel of the
//! finest.
//!
//! It is only right when the mesh's border *is* the outline (a cloth, a sheet of paper, a flag);
//! a mesh whose border lies inside a surface (a face mask) has no edge to find, which is why
//! `align` leaves it off unless asked.
//!
//! Invariant: no I/O.

use crate::base::camera::{Camera, Projection};
use crate::base::image::RgbImage;
use crate::base::mesh::{centroid, Mesh};
use crate::tracker::align::move_along;
use nalgebra::{Point3, Vector3};

/// Points sampled on every border edge.
const PER_EDGE: usize = 4;

/// A point on the border: on edge `(a, b)` at `t`, with `opp` the triangle's third vertex.
#[derive(Clone, Copy)]
struct BorderPoint {
    a: u32,
    b: u32,
    opp: u32,
    t: f64,
}

/// The border of a mesh: its edges with one triangle.
pub(crate) struct Border {
    points: Vec<BorderPoint>,
}

impl Border {
    /// `None` for a closed mesh.
    pub(crate) fn of(mesh: &Mesh) -> Option<Border> {
        let edges = mesh.border_edges();
        let points: Vec<BorderPoint> = edges
            .iter()
            .flat_map(|&([a, b], opp)| {
                (0..PER_EDGE).map(move |i| BorderPoint {
                    a,
                    b,
                    opp,
                    t: (i as f64 + 0.5) / PER_EDGE as f64,
                })
            })
            .collect();
        (!points.is_empty()).then_some(Border { points })
    }
}

/// One camera at one pyramid level: its projection and the smoothed image's gradients.
pub(crate) struct EdgeView {
    pub proj: Projection,
    pub gx: RgbImage,
    pub gy: RgbImage,
}

impl EdgeView {
    pub(crate) fn new(proj: Projection, image: &RgbImage) -> EdgeView {
        let (gx, gy) = image.gradients();
        EdgeView { proj, gx, gy }
    }
}

/// Mean squared contrast across the border at positions `x`, over every border point and camera
/// (a point outside a camera's image counts as no contrast, so leaving the image never pays).
fn score(border: &Border, x: &[Point3<f64>], views: &[EdgeView], step: f64) -> f64 {
    let mut sum = 0.0;
    let mut n = 0usize;
    for bp in &border.points {
        let (a, b, o) = (x[bp.a as usize], x[bp.b as usize], x[bp.opp as usize]);
        let p = a + (b - a) * bp.t;
        let e = (b - a).normalize();
        let d = p - o;
        let out = d - e * e.dot(&d);
        let Some(out) = out.try_normalize(1e-300) else {
            continue;
        };
        let q = p + out * step;
        for v in views {
            n += 1;
            let (Some(u), Some(uq)) = (v.proj.project(&p), v.proj.project(&q)) else {
                continue;
            };
            let Some(m) = (uq - u).try_normalize(1e-12) else {
                continue;
            };
            let (Some(gx), Some(gy)) = (v.gx.sample(u.x, u.y), v.gy.sample(u.x, u.y)) else {
                continue;
            };
            for k in 0..3 {
                let dn = gx[k] as f64 * m.x + gy[k] as f64 * m.y;
                sum += dn * dn;
            }
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// The result of [`fit`].
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct OutlineFit {
    pub positions: Vec<Point3<f64>>,
    /// The contrast score at the start and at the end (finest level).
    pub before: f64,
    pub after: f64,
}

/// Searches the motions `free` for the placement of `border` with the most contrast across it.
/// `levels[l]` are the cameras at pyramid level `l` (0 = full resolution), searched coarse to
/// fine; `px` is how many full-resolution pixels one scene unit of motion moves the mesh.
pub(crate) fn fit(
    border: &Border,
    x: &[Point3<f64>],
    free: &[[f64; 7]],
    levels: &[Vec<EdgeView>],
    px: f64,
    frame_size: f64,
) -> OutlineFit {
    let h = 1e-4 * frame_size.max(1e-300);
    let mut alpha = vec![0.0; free.len()];
    let mut before = 0.0;
    let mut after = 0.0;
    for (l, views) in levels.iter().enumerate().rev() {
        let level_px = px / f64::from(1u32 << l);
        let eval = |a: &[f64]| score(border, &move_along(x, free, a), views, h);
        let mut best = eval(&alpha);
        if l == 0 {
            before = score(border, x, views, h);
        }
        // From two pixels of this level down to a twentieth of one.
        let mut step = 2.0 / level_px;
        while step * level_px >= 0.05 {
            let mut improved = false;
            for k in 0..alpha.len() {
                for sign in [1.0, -1.0] {
                    let mut trial = alpha.clone();
                    trial[k] += sign * step;
                    let s = eval(&trial);
                    if s > best {
                        best = s;
                        alpha = trial;
                        improved = true;
                        break;
                    }
                }
            }
            if !improved {
                step *= 0.5;
            }
        }
        if l == 0 {
            after = best;
        }
    }
    OutlineFit {
        positions: move_along(x, free, &alpha),
        before,
        after,
    }
}

/// Full-resolution pixels per scene unit of motion at `x`'s centroid: the median over cameras of
/// the image motion of a small step along each world axis.
pub(crate) fn pixels_per_unit(cameras: &[Camera], frame: u32, x: &[Point3<f64>]) -> f64 {
    let c = centroid(x);
    let eps = 1e-4 * crate::base::mesh::bbox_diagonal(x).max(1e-300);
    let mut v: Vec<f64> = cameras
        .iter()
        .filter_map(|cam| {
            let p = cam.at(frame);
            let u = p.project(&c)?;
            let m = (0..3)
                .filter_map(|k| Some((p.project(&(c + Vector3::ith(k, eps)))? - u).norm()))
                .fold(0.0, f64::max);
            Some(m / eps)
        })
        .collect();
    if v.is_empty() {
        return 1.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

//! Sticky edges (the thesis' §8.4.3, "Sticky Edges"; our addition, off by default:
//! `TrackOptions::sticky_edges`): the mesh's outline against the background followed from
//! frame to frame. The photometric term leaves out every pixel near a silhouette (a pixel there
//! mixes the surface with what lies beyond it), so where a surface turns away from every
//! camera — the top and bottom of an object that a ring of cameras sees only edge-on — the
//! images say nothing of where it goes and only the regularisers carry it. Its outline says it.
//!
//! A *rim* is an interior edge between a triangle facing the camera and one facing away whose
//! outline is against the background: the pixel just inside belongs to a triangle at the edge
//! and the pixel just beyond shows nothing of the mesh; it is followed where that background
//! was plain in the frame before ([`PLAIN_BEYOND`]). At the start of each pyramid level,
//! points are taken every [`SPACING_PX`] pixels along every rim of every camera. Each point's
//! profile across the outline in the frame before (the same material point of the mesh, where
//! the previous frame's solution put it: from [`INSIDE_PX`] inside to [`OUTSIDE_PX`] beyond,
//! every half pixel, bicubic) is looked for along the rim's outward normal in the frame being
//! solved, within [`SEARCH_PX`] either way: the offset with the least summed squared
//! difference, refined by a parabola. Where that puts the outline is the point's target for the
//! level: its residual is the distance along the normal from the point's projection to it,
//! times the profile's change across the outline (so that it is in the photometric residuals'
//! units), robust (Tukey, nothing beyond the search range), each point counting as `weight`
//! template pixels per pixel of rim.
//!
//! Matching the outline's own profile, rather than looking for the strongest edge, follows what
//! moves with the outline (the surface's shading and texture next to it) and is not drawn to a
//! darker band or a texture edge a pixel inside (docs/tracker.md, "Sticky edges").
//!
//! Knows cameras, images and the mesh; no I/O. Hand-written: it is part of the product.
//! Deterministic whatever the thread count (points found and summed in one fixed order).

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::base::raster::{facing_cosines, rasterize, IndexBuffer, NONE};
use crate::tracker::solve::tukey;
use crate::tracker::sparse::BlockSparse;
use nalgebra::{Point2, Point3, Vector2, Vector3};

/// Pixels of the level between two points along a rim's projection.
const SPACING_PX: f64 = 2.0;
/// How far (pixels of the level) the profile is looked for, either way.
const SEARCH_PX: f64 = 1.5;
/// How far inside the outline the profile reaches (pixels of the level).
const INSIDE_PX: f64 = 2.5;
/// How far beyond it (what lies behind the surface does not move with it: kept short).
const OUTSIDE_PX: f64 = 1.0;
/// The least change of colour across the outline (RGB norm, image units, over two pixels) for
/// a profile to hold a point: a surface against a background of its own colour shows none.
const MIN_CHANGE: f64 = 0.05;
/// How much (RGB norm, image units) the background may vary from 2.5 to 4.5 pixels beyond the
/// outline in the frame before (past the tail of the level's smoothing of the outline) for a
/// point to be followed: a textured background stays where it is while the outline moves over
/// it, and the match would follow the background.
const PLAIN_BEYOND: f64 = 0.03;

/// Samples in a profile: every half pixel from [`INSIDE_PX`] inside to [`OUTSIDE_PX`] beyond.
const PROFILE: usize = ((INSIDE_PX + OUTSIDE_PX) / 0.5) as usize + 1;
/// Quarter-pixel offsets tried either way of the outline: [`SEARCH_PX`] of them.
const STEPS: usize = (SEARCH_PX / 0.25) as usize;

/// Squared RGB distance.
fn distance2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// An interior edge of the mesh: its vertices, its two triangles (one runs the edge forward,
/// the other backward) and their third vertices.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RimEdge {
    pub a: u32,
    pub b: u32,
    pub triangles: [u32; 2],
    pub thirds: [u32; 2],
}

/// The edges of `triangles` that can be rims.
pub(crate) fn rim_edges(triangles: &[[u32; 3]]) -> Vec<RimEdge> {
    let sides = crate::base::mesh::EdgeSides::new(triangles);
    sides
        .edges()
        .filter(|s| s.len() == 2 && s[0].forward != s[1].forward)
        .map(|s| RimEdge {
            a: s[0].edge[0],
            b: s[0].edge[1],
            triangles: [s[0].triangle, s[1].triangle],
            thirds: [s[0].third, s[1].third],
        })
        .collect()
}

/// One point on a rim and where its outline was found.
#[derive(Clone, Copy, Debug)]
struct Point {
    camera: u16,
    a: u32,
    b: u32,
    /// Where on the edge: `(1 − t)·X_a + t·X_b`.
    t: f64,
    /// The rim's outward normal in the image.
    normal: [f64; 2],
    /// `normal · q` at the outline found.
    target: f64,
    /// The profile's change across the outline, per pixel.
    contrast: f64,
}

/// The rims of one pyramid level and where their outlines were found.
pub(crate) struct Rims {
    points: Vec<Point>,
    projections: Vec<Projection>,
    /// Each point's weight, in template pixels.
    weight: f64,
}

/// Edge `e` seen through `proj` at `x`: its first end, its direction (to the second end) and
/// its outward normal (away from `inner`, the third vertex of the triangle facing the camera).
fn projected(
    x: &[Point3<f64>],
    e: &RimEdge,
    inner: u32,
    proj: &Projection,
) -> Option<(Point2<f64>, Vector2<f64>, [f64; 2])> {
    let pa = proj.project(&x[e.a as usize])?;
    let pb = proj.project(&x[e.b as usize])?;
    let pi = proj.project(&x[inner as usize])?;
    let d = pb - pa;
    let len = d.norm();
    if len < 1e-9 {
        return None;
    }
    let mut n = [-d.y / len, d.x / len];
    if (pi.x - pa.x) * n[0] + (pi.y - pa.y) * n[1] > 0.0 {
        n = [-n[0], -n[1]];
    }
    Some((pa, d, n))
}

/// The image's colour at `(u, v)` (bicubic), inside it.
fn value(img: &RgbImage, u: f64, v: f64) -> Option<[f64; 3]> {
    if !img.inside(u, v) {
        return None;
    }
    let c = img.sample_cubic_value(u as f32, v as f32);
    Some([c[0] as f64, c[1] as f64, c[2] as f64])
}

impl Rims {
    /// The rims of `x` seen through `projections` (one per camera, at the level) against the
    /// cameras' `images` of the frame being solved, each point's profile taken from `before`
    /// (the previous frame's positions, projections and images at the level). Cameras marked in
    /// `left_out` are not asked.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn find(
        x: &[Point3<f64>],
        triangles: &[[u32; 3]],
        edges: &[RimEdge],
        projections: &[Projection],
        images: &[&RgbImage],
        before: (&[Point3<f64>], &[Projection], &[&RgbImage]),
        left_out: &[bool],
        weight: f64,
    ) -> Rims {
        let (xp, pp, ip) = before;
        let mut points = Vec::new();
        for (c, (proj, img)) in projections.iter().zip(images).enumerate() {
            if left_out.get(c).copied().unwrap_or(false) {
                continue;
            }
            let facing = facing_cosines(x, triangles, proj);
            let ib = rasterize(x, triangles, proj, img.width(), img.height());
            for e in edges {
                let [f0, f1] = e.triangles.map(|t| facing[t as usize]);
                // A rim: one side faces the camera, the other away (NaN: a degenerate side).
                if f0.is_nan() || f1.is_nan() || f0 * f1 >= 0.0 {
                    continue;
                }
                let inner = if f0 > 0.0 { e.thirds[0] } else { e.thirds[1] };
                let Some((pa, d, n)) = projected(x, e, inner, proj) else {
                    continue;
                };
                let Some((qa, dq, m)) = projected(xp, e, inner, &pp[c]) else {
                    continue;
                };
                let count = (d.norm() / SPACING_PX).ceil().max(1.0) as usize;
                for k in 0..count {
                    let t = (k as f64 + 0.5) / count as f64;
                    let q = pa + d * t;
                    if !visible(&ib, triangles, e, [q.x, q.y], n) {
                        continue;
                    }
                    let qt = qa + dq * t;
                    if let Some((s, contrast)) = matched(img, ip[c], [q.x, q.y], n, [qt.x, qt.y], m)
                    {
                        points.push(Point {
                            camera: c as u16,
                            a: e.a,
                            b: e.b,
                            t,
                            normal: n,
                            target: n[0] * (q.x + s * n[0]) + n[1] * (q.y + s * n[1]),
                            contrast,
                        });
                    }
                }
            }
        }
        Rims {
            points,
            projections: projections.to_vec(),
            weight: weight * SPACING_PX,
        }
    }

    /// The term's cost at `x`, scaled by `inv_n` (one over the photometric term's weighted
    /// pixel count, so that a point costs what its template pixels would); with `system`, adds
    /// its `JᵀJ` and `−Jᵀr` there.
    pub(crate) fn accumulate(
        &self,
        x: &[Point3<f64>],
        mut system: Option<(&mut BlockSparse, &mut Vec<Vector3<f64>>)>,
        inv_n: f64,
    ) -> f64 {
        let scale = self.weight * inv_n;
        let mut cost = 0.0;
        for p in &self.points {
            let proj = &self.projections[p.camera as usize];
            let (xa, xb) = (x[p.a as usize], x[p.b as usize]);
            let xq = Point3::from(xa.coords * (1.0 - p.t) + xb.coords * p.t);
            let hh = proj.project_h(&xq);
            let delta = SEARCH_PX * p.contrast;
            if hh.z.is_nan() || hh.z <= 0.0 {
                cost += scale * delta * delta / 3.0;
                continue;
            }
            let inv = 1.0 / hh.z;
            let (u, v) = (hh.x * inv, hh.y * inv);
            let r = p.contrast * (p.normal[0] * u + p.normal[1] * v - p.target);
            let (rho, wgt) = tukey(r * r, delta * delta);
            cost += scale * rho;
            if wgt == 0.0 {
                continue;
            }
            let Some((a, b)) = system.as_mut() else {
                continue;
            };
            // ∂(n·π(X))/∂X = (n_u·(m₀ − u·m₂) + n_v·(m₁ − v·m₂)) / h_z.
            let m = proj.matrix();
            let row = |i: usize| Vector3::new(m[(i, 0)], m[(i, 1)], m[(i, 2)]);
            let g = ((row(0) - row(2) * u) * p.normal[0] + (row(1) - row(2) * v) * p.normal[1])
                * (inv * p.contrast);
            let s = scale * wgt;
            let gg = g * g.transpose() * s;
            let (wa, wb) = (1.0 - p.t, p.t);
            let (ia, ib) = (p.a as usize, p.b as usize);
            a.add_pair(ia, ia, &(gg * (wa * wa)));
            a.add_pair(ib, ib, &(gg * (wb * wb)));
            a.add_pair(ia, ib, &(gg * (wa * wb)));
            b[ia] -= g * (s * r * wa);
            b[ib] -= g * (s * r * wb);
        }
        cost
    }
}

/// Whether the rim point at `q` (image, outward normal `n`) is the mesh's outline against the
/// background there: the pixel just inside belongs to a triangle at the rim's edge, and the
/// pixel just beyond shows nothing of the mesh.
fn visible(
    ib: &IndexBuffer,
    triangles: &[[u32; 3]],
    e: &RimEdge,
    q: [f64; 2],
    n: [f64; 2],
) -> bool {
    let pixel = |s: f64| {
        let (x, y) = ((q[0] + s * n[0]).round(), (q[1] + s * n[1]).round());
        (x >= 0.0 && y >= 0.0 && (x as usize) < ib.width && (y as usize) < ib.height)
            .then_some((x as usize, y as usize))
    };
    let (Some(inside), Some(outside)) = (pixel(-1.0), pixel(1.5)) else {
        return false;
    };
    let owner = ib.owner_at(inside.0, inside.1);
    owner != NONE
        && triangles[owner as usize]
            .iter()
            .any(|&v| v == e.a || v == e.b)
        && ib.owner_at(outside.0, outside.1) == NONE
}

/// The offset along `n` from `q` at which `img` shows the profile across the outline that
/// `before` showed at `qt` (outward normal `m`): samples from [`INSIDE_PX`] inside to
/// [`OUTSIDE_PX`] beyond, every half pixel, compared by their summed squared difference,
/// minimised over [`SEARCH_PX`] either way every quarter pixel and refined by a parabola; with
/// the profile's change across the outline, per pixel. `None` where the profile shows no
/// outline ([`MIN_CHANGE`]), the background beyond it is not plain ([`PLAIN_BEYOND`]), it
/// leaves an image, or it fits best at the range's end.
pub(crate) fn matched(
    img: &RgbImage,
    before: &RgbImage,
    q: [f64; 2],
    n: [f64; 2],
    qt: [f64; 2],
    m: [f64; 2],
) -> Option<(f64, f64)> {
    // Fixed-size buffers: no allocation per point.
    let mut tpl = [(0.0f64, [0.0f64; 3]); PROFILE];
    for (k, slot) in tpl.iter_mut().enumerate() {
        let s = -INSIDE_PX + 0.5 * k as f64;
        *slot = (s, value(before, qt[0] + s * m[0], qt[1] + s * m[1])?);
    }
    let far = value(before, qt[0] + 4.5 * m[0], qt[1] + 4.5 * m[1])?;
    for k in [2.5, 3.0, 3.5, 4.0] {
        let v = value(before, qt[0] + k * m[0], qt[1] + k * m[1])?;
        if distance2(&v, &far).sqrt() > PLAIN_BEYOND {
            return None;
        }
    }
    let o = value(before, qt[0] + m[0], qt[1] + m[1])?;
    let i = value(before, qt[0] - m[0], qt[1] - m[1])?;
    let change = distance2(&o, &i).sqrt();
    if change < MIN_CHANGE {
        return None;
    }
    let steps = STEPS as i32;
    let mut ssd = [0.0f64; 2 * STEPS + 1];
    for (slot, k) in ssd.iter_mut().zip(-steps..=steps) {
        let off = k as f64 * 0.25;
        let mut sum = 0.0;
        for (sp, t) in &tpl {
            let v = value(img, q[0] + (off + sp) * n[0], q[1] + (off + sp) * n[1])?;
            sum += distance2(&v, t);
        }
        *slot = sum;
    }
    let (at, _) = ssd.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    if at == 0 || at == ssd.len() - 1 {
        return None;
    }
    let (l, c, r) = (ssd[at - 1], ssd[at], ssd[at + 1]);
    let den = l - 2.0 * c + r;
    let frac = if den > 0.0 {
        (0.5 * (l - r) / den).clamp(-1.0, 1.0)
    } else {
        0.0
    };
    Some(((at as f64 - steps as f64 + frac) * 0.25, change / 2.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A soft vertical edge (a surface's colour left of `at`, the background's right of it,
    /// with a darker band just inside as a lit surface shows at its outline) and some texture
    /// inside.
    fn edge_image(at: f64) -> RgbImage {
        RgbImage::from_fn(40, 20, |x, _| {
            let x = x as f64;
            let cover = (0.5 - (x - at)).clamp(0.0, 1.0);
            // Both move with the outline.
            let band = 1.0 - 0.4 * (-(at - x - 1.0).powi(2) / 0.5).exp();
            let texture = 0.1 * ((x - at) * 1.7).sin();
            let surface = [0.8 * band + texture, 0.5 * band, 0.3 * band - texture];
            let bg = [0.1, 0.1, 0.1];
            std::array::from_fn(|k| (cover * surface[k] + (1.0 - cover) * bg[k]) as f32)
        })
    }

    #[test]
    fn an_outline_that_moved_by_a_fraction_of_a_pixel_is_found_where_it_went() {
        let before = edge_image(20.0).blurred(1.0);
        for shift in [-1.2, -0.6, -0.25, 0.0, 0.3, 0.7, 1.1] {
            let now = edge_image(20.0 + shift).blurred(1.0);
            // The point's profile: at x = 20 in the frame before, outward to +x; looked for
            // from x = 20 now.
            let (s, contrast) = matched(
                &now,
                &before,
                [20.0, 10.0],
                [1.0, 0.0],
                [20.0, 10.0],
                [1.0, 0.0],
            )
            .unwrap_or_else(|| panic!("moved {shift}: no outline matched"));
            assert!((s - shift).abs() < 0.06, "moved {shift}, found {s}");
            assert!(contrast > 0.1, "contrast {contrast}");
        }
    }

    #[test]
    fn the_terms_gradient_is_the_finite_difference_of_its_cost() {
        use crate::base::camera::{look_at, Projection};
        use nalgebra::Matrix3;
        let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 480.0, 240.0, 0.0, 0.0, 1.0);
        let (r, t) = look_at(
            &Point3::new(0.3, -0.2, -4.0),
            &Point3::origin(),
            &Vector3::new(0.0, -1.0, 0.0),
        );
        let proj = Projection::from_krt(&k, &r, &t).unwrap();
        let x = vec![
            Point3::new(-0.5, 0.1, 0.2),
            Point3::new(0.4, -0.3, 0.1),
            Point3::new(0.1, 0.6, -0.2),
        ];
        let pattern = [[0u32, 1], [0, 2], [1, 2]];
        // Two points on edge (0, 1), inside the Tukey range; one on (1, 2), beyond it.
        let point = |a: u32, b: u32, t: f64, off: f64| {
            let xq = Point3::from(x[a as usize].coords * (1.0 - t) + x[b as usize].coords * t);
            let q = proj.project(&xq).unwrap();
            let n = [0.6, 0.8];
            Point {
                camera: 0,
                a,
                b,
                t,
                normal: n,
                target: n[0] * q.x + n[1] * q.y + off,
                contrast: 0.2,
            }
        };
        let rims = Rims {
            points: vec![
                point(0, 1, 0.3, 0.7),
                point(0, 1, 0.8, -1.1),
                point(1, 2, 0.5, 2.0),
            ],
            projections: vec![proj],
            weight: 1.5,
        };
        let inv_n = 0.01;
        let mut a = BlockSparse::new(3, &pattern);
        let mut b = vec![Vector3::zeros(); 3];
        let cost = rims.accumulate(&x, Some((&mut a, &mut b)), inv_n);
        assert!(cost > 0.0);
        let h = 1e-6;
        for v in 0..3 {
            for c in 0..3 {
                let mut xp = x.clone();
                let mut xm = x.clone();
                xp[v][c] += h;
                xm[v][c] -= h;
                let fd = (rims.accumulate(&xp, None, inv_n) - rims.accumulate(&xm, None, inv_n))
                    / (2.0 * h);
                // The cost's gradient is 2·Jᵀ·W·r = −2·b.
                let g = -2.0 * b[v][c];
                assert!(
                    (fd - g).abs() <= 1e-6 * fd.abs().max(1e-3),
                    "vertex {v} coordinate {c}: finite difference {fd}, assembled {g}"
                );
            }
        }
    }

    #[test]
    fn an_outline_before_a_textured_background_is_not_followed() {
        let textured = |at: f64| {
            RgbImage::from_fn(40, 20, |x, y| {
                let base = edge_image(at).get(x, 0);
                if (x as f64) > at + 1.0 {
                    let t = 0.1 * ((x * 7 + y * 3) % 5) as f32;
                    [base[0] + t, base[1] + t, base[2]]
                } else {
                    base
                }
            })
            .blurred(1.0)
        };
        let (before, now) = (textured(20.0), textured(20.5));
        assert!(matched(
            &now,
            &before,
            [20.0, 10.0],
            [1.0, 0.0],
            [20.0, 10.0],
            [1.0, 0.0]
        )
        .is_none());
    }

    #[test]
    fn a_flat_profile_holds_no_point_and_a_far_outline_is_not_taken() {
        let flat = RgbImage::from_fn(40, 20, |_, _| [0.4, 0.4, 0.4]);
        assert!(matched(
            &flat,
            &flat,
            [20.0, 10.0],
            [1.0, 0.0],
            [20.0, 10.0],
            [1.0, 0.0]
        )
        .is_none());
        let before = edge_image(20.0).blurred(1.0);
        let far = edge_image(24.0).blurred(1.0);
        assert!(
            matched(
                &far,
                &before,
                [20.0, 10.0],
                [1.0, 0.0],
                [20.0, 10.0],
                [1.0, 0.0]
            )
            .is_none(),
            "an outline 4 px away is beyond the search range"
        );
    }
}

//! Motion blur: the template and the frame being solved compared under their common smear (our
//! addition to the thesis, after Jin, Favaro and Cipolla, "Visual tracking in the presence of
//! motion blur", CVPR 2005). A camera whose shutter stays open for a fraction `s` of a frame
//! records a moving surface smeared along its image motion over that time: the frame being
//! solved along the surface's velocity there, a template along the velocity at the template's
//! own frame. When the velocity turns or changes speed between the two, the same texture is
//! compared under two different smears, and the difference pulls the mesh (a hand-held circle
//! at 40 px per frame with the shutter open all frame: 1.85 % of the object's size against 0.20
//! % sharp, docs/tracker.md).
//!
//! Each side is smeared by what it lacks of the other's smear, so that both have the same second
//! moments ([`common`]): the frame being solved per pixel, from the motions of the triangle that
//! the mesh puts there ([`smeared_targets`]), and each template pixel's colour re-read as the
//! mean of its image over its part ([`smear_templates`]); a pixel whose smears reach past the
//! mesh's outline is left out. (Smearing each side by the other's whole smear, as Jin et al.
//! do, matches more than the second moments but blurs away texture both sides still show.) The
//! previous frame and the first frame (the anchor) moved differently, so the frame being solved
//! is smeared once for each, and each patch is compared with the one of its template
//! (`Patch::first`).
//!
//! The velocities are the solved meshes' differences: at the frame being solved the
//! second-order backward difference through its current estimate (the prediction at the
//! coarsest level, the coarser level's solution below it), at the template's frame the central
//! one. A smear is a box of `taps` bilinear samples spaced at most [`TAP_PX`] apart (at most
//! [`MAX_TAPS`] along one motion), centred on the pixel: the shutter is taken as centred on the
//! frame's time, as renderers and most cameras' timestamps have it. Hand-written: the tracker's
//! own warps; deterministic whatever the thread count (every pixel is computed alone).

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::base::raster::{rasterize, IndexBuffer, NONE};
use crate::tracker::patch::{Patch, PatchSet};
use nalgebra::{Point2, Point3, Vector2, Vector3};
use rayon::prelude::*;

/// A smear shorter than this (pixels of the level) is left alone.
const MIN_SMEAR_PX: f64 = 0.25;
/// The largest spacing of a smear's samples (pixels of the level): the pyramid's images are
/// smoothed with a sigma of a pixel, so samples this far apart average them without aliasing.
const TAP_PX: f64 = 1.0;
/// The most samples along one smear (a longer one samples more sparsely).
const MAX_TAPS: usize = 24;

/// Per-vertex velocities, in scene units per frame, around the frame being solved.
pub(crate) struct Velocities {
    /// At the template's frame (the previous one): the central difference.
    pub template: Vec<Vector3<f64>>,
    /// At the frame being solved: the second-order backward difference.
    pub target: Vec<Vector3<f64>>,
}

impl Velocities {
    /// From the mesh `gap_before` frames before the template (`before`), the template's
    /// (`prev`) and the estimate of the frame being solved, `gap` frames after it (`x`).
    pub(crate) fn new(
        before: &[Point3<f64>],
        gap_before: f64,
        prev: &[Point3<f64>],
        x: &[Point3<f64>],
        gap: f64,
    ) -> Self {
        let (template, target) = before
            .iter()
            .zip(prev)
            .zip(x)
            .map(|((b, p), x)| {
                let d0 = (p - b) / gap_before;
                let d1 = (x - p) / gap;
                ((d0 + d1) * 0.5, d1 + (d1 - d0) * 0.5)
            })
            .unzip();
        Velocities { template, target }
    }
}

/// The image smear of the surface point `p` moving at `v` (per frame) while a shutter of `s`
/// frames is open, seen through `proj`: from where it was as the shutter opened to where it was
/// as it closed (pixels); `None` where either end is behind the camera.
fn smear(proj: &Projection, p: &Point3<f64>, v: &Vector3<f64>, s: f64) -> Option<Vector2<f64>> {
    let h = v * (0.5 * s);
    Some(proj.project(&(p + h))? - proj.project(&(p - h))?)
}

/// How many samples a smear of `len` pixels takes (1 below [`MIN_SMEAR_PX`]).
fn taps(len: f64) -> usize {
    if len < MIN_SMEAR_PX {
        1
    } else {
        ((len / TAP_PX).ceil() as usize + 1).min(MAX_TAPS)
    }
}

/// Bilinear sample with the position clamped into the image (a smear that runs off its edge
/// repeats the edge, as the image's own border does).
#[inline]
fn clamped(img: &RgbImage, u: f64, v: f64) -> [f32; 3] {
    let u = u.clamp(0.0, (img.width() - 1) as f64);
    let v = v.clamp(0.0, (img.height() - 1) as f64);
    img.sample_unchecked(u, v)
}

/// The mean of `img` over the box smears `a` and `b` (pixels; `b` zero for one) centred on
/// `q`: the midpoints of `taps` equal parts of each.
pub(crate) fn along(img: &RgbImage, q: Point2<f64>, a: Vector2<f64>, b: Vector2<f64>) -> [f32; 3] {
    let (na, nb) = (taps(a.norm()), taps(b.norm()));
    if na == 1 && nb == 1 {
        return clamped(img, q.x, q.y);
    }
    let mut sum = [0.0f64; 3];
    for i in 0..na {
        let ta = (i as f64 + 0.5) / na as f64 - 0.5;
        for j in 0..nb {
            let tb = (j as f64 + 0.5) / nb as f64 - 0.5;
            let p = q + a * ta + b * tb;
            let c = clamped(img, p.x, p.y);
            for k in 0..3 {
                sum[k] += c[k] as f64;
            }
        }
    }
    let n = (na * nb) as f64;
    sum.map(|s| (s / n) as f32)
}

/// Where a template's pixels came from: its mesh as each camera saw it (`seen[c]`; moved along
/// the velocity for a camera that records late or early), its images and projections at the
/// level.
pub(crate) struct Source<'a> {
    pub seen: Vec<&'a [Point3<f64>]>,
    pub images: Vec<&'a RgbImage>,
    pub projections: &'a [Projection],
}

/// The two motions a template is compared under, per vertex, per frame: its own frame's
/// (`template`: the previous frame's, or the first frame's for the anchor) and the frame being
/// solved's (`target`).
pub(crate) struct Motions<'a> {
    pub template: &'a [Vector3<f64>],
    pub target: &'a [Vector3<f64>],
}

/// What each side lacks of the other's smear: the template's own smear `own` and the frame
/// being solved's `other` (pixels, the box's whole length) have second moments `b·bᵀ/12`; their
/// difference is split into its positive part, which the template is smeared by, and its
/// negative part, which the frame being solved is smeared by, each as up to two boxes along its
/// eigenvectors. Both sides then have the same second moments: for a steady motion nothing is
/// smeared; a template recorded at rest takes the frame's whole smear; two smears turned
/// against each other meet in between. (Matching the moments rather than convolving each side
/// with the other's whole smear keeps the texture that both still show.)
pub(crate) fn common(
    own: Vector2<f64>,
    other: Vector2<f64>,
) -> ([Vector2<f64>; 2], [Vector2<f64>; 2]) {
    let (a, b, c) = (
        (other.x * other.x - own.x * own.x) / 12.0,
        (other.x * other.y - own.x * own.y) / 12.0,
        (other.y * other.y - own.y * own.y) / 12.0,
    );
    let (m, r) = (0.5 * (a + c), (0.25 * (a - c) * (a - c) + b * b).sqrt());
    let e1 = if b.abs() > 1e-12 * (a.abs() + c.abs()).max(1e-300) {
        Vector2::new(m + r - c, b).normalize()
    } else if a >= c {
        Vector2::new(1.0, 0.0)
    } else {
        Vector2::new(0.0, 1.0)
    };
    let e2 = Vector2::new(-e1.y, e1.x);
    let (mut template, mut target) = ([Vector2::zeros(); 2], [Vector2::zeros(); 2]);
    for (k, (l, e)) in [(m + r, e1), (m - r, e2)].into_iter().enumerate() {
        let len = (12.0 * l.abs()).sqrt();
        if l > 0.0 {
            template[k] = e * len;
        } else {
            target[k] = e * len;
        }
    }
    (template, target)
}

/// `img` (one camera's image of the frame being solved, at one level) smeared, once for each
/// template's `motions`, by what it lacks of that template's smear ([`common`]) for a shutter of
/// `shutter` frames, wherever the mesh at `x` covers it (`proj`: that camera at that level;
/// one z-buffer for all): per pixel, from the motions of the centroid of the triangle the
/// z-buffer puts there. The rest of the image, which no template pixel is compared with, is
/// left as it is. With `measure`, also the texture the first smear left there ([`Texture`]).
pub(crate) fn smeared_targets(
    img: &RgbImage,
    proj: &Projection,
    triangles: &[[u32; 3]],
    x: &[Point3<f64>],
    motions: &[Motions],
    shutter: f64,
    measure: bool,
) -> (Vec<RgbImage>, Option<Texture>) {
    let (w, h) = (img.width(), img.height());
    let ib = rasterize(x, triangles, proj, w, h);
    let win = ib.window;
    let owners = ib.owners();
    let smeared: Vec<RgbImage> = motions
        .iter()
        .map(|m| {
            let mut out = img.clone();
            if win.width == 0 {
                return out;
            }
            let per_triangle: Vec<[Vector2<f64>; 2]> = triangles
                .iter()
                .map(|t| {
                    let mean = |v: &[Vector3<f64>]| {
                        (v[t[0] as usize] + v[t[1] as usize] + v[t[2] as usize]) / 3.0
                    };
                    let c = Point3::from(
                        (x[t[0] as usize].coords
                            + x[t[1] as usize].coords
                            + x[t[2] as usize].coords)
                            / 3.0,
                    );
                    let zero = Vector2::zeros();
                    let own = smear(proj, &c, &mean(m.template), shutter).unwrap_or(zero);
                    let other = smear(proj, &c, &mean(m.target), shutter).unwrap_or(zero);
                    common(own, other).1
                })
                .collect();
            out.pixels_mut()
                .par_chunks_mut(w)
                .enumerate()
                .skip(win.y0)
                .take(win.height)
                .for_each(|(y, row)| {
                    let own = &owners[(y - win.y0) * win.width..(y - win.y0 + 1) * win.width];
                    for (i, &t) in own.iter().enumerate() {
                        if t == NONE {
                            continue;
                        }
                        let x = win.x0 + i;
                        let [a, b] = per_triangle[t as usize];
                        if a.norm() >= MIN_SMEAR_PX || b.norm() >= MIN_SMEAR_PX {
                            row[x] = along(img, Point2::new(x as f64, y as f64), a, b);
                        }
                    }
                });
            out
        })
        .collect();
    let texture = (measure && win.width > 0)
        .then(|| smeared.first())
        .flatten()
        .map(|after| Texture {
            before: structure(img, &ib),
            after: structure(after, &ib),
        });
    (smeared, texture)
}

/// How much texture a smear left where the mesh is: the structure tensor (`Σ ∇I·∇Iᵀ` over the
/// pixels the mesh covers, the colour channels summed; `[xx, xy, yy]`) of the image before and
/// after it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Texture {
    pub before: [f64; 3],
    pub after: [f64; 3],
}

impl Texture {
    /// The share of the weakest direction's texture the smears kept, over several cameras'
    /// (each camera's weakest direction, summed): what the frame's `information_share`, the
    /// least-constrained direction of each vertex, is measured against under a smear.
    pub(crate) fn kept(textures: &[Texture]) -> Option<f64> {
        let least = |t: [f64; 3]| {
            let (m, r) = (
                0.5 * (t[0] + t[2]),
                (0.25 * (t[0] - t[2]).powi(2) + t[1] * t[1]).sqrt(),
            );
            (m - r).max(0.0)
        };
        let before: f64 = textures.iter().map(|t| least(t.before)).sum();
        let after: f64 = textures.iter().map(|t| least(t.after)).sum();
        (before > 0.0).then(|| (after / before).min(1.0))
    }
}

/// The structure tensor of `img` over the pixels `ib` covers (central differences; the
/// image's border pixels left out).
fn structure(img: &RgbImage, ib: &IndexBuffer) -> [f64; 3] {
    let (w, h) = (img.width(), img.height());
    let win = ib.window;
    let owners = ib.owners();
    (win.y0.max(1)..(win.y0 + win.height).min(h.saturating_sub(1)))
        .into_par_iter()
        .map(|y| {
            let mut t = [0.0f64; 3];
            for x in win.x0.max(1)..(win.x0 + win.width).min(w.saturating_sub(1)) {
                if owners[(y - win.y0) * win.width + x - win.x0] == NONE {
                    continue;
                }
                let (l, r) = (img.get(x - 1, y), img.get(x + 1, y));
                let (u, d) = (img.get(x, y - 1), img.get(x, y + 1));
                for k in 0..3 {
                    let gx = 0.5 * (r[k] - l[k]) as f64;
                    let gy = 0.5 * (d[k] - u[k]) as f64;
                    t[0] += gx * gx;
                    t[1] += gx * gy;
                    t[2] += gy * gy;
                }
            }
            t
        })
        .collect::<Vec<_>>()
        .into_iter()
        // Summed in row order: the same whatever the thread count.
        .fold([0.0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]])
}

/// Re-reads the colour of every pixel of `patches` (a template's, whose pixels come from
/// `source`: `patch.source == patch.camera`) as the mean of its image over what it lacks of
/// the frame being solved's smear (`motions`; [`common`]); `shutter[c]` is camera `c`'s.
/// Returns, per patch of the range, which pixels to keep: not those within either smear's reach
/// of the template's outline (where the mesh's view ends, `outline[c]` its index buffer), whose
/// smeared colour mixes the surface with what lies beyond it, which does not move with it.
pub(crate) fn smear_templates(
    set: &mut PatchSet,
    patches: std::ops::Range<usize>,
    triangles: &[[u32; 3]],
    source: &Source,
    outline: &[IndexBuffer],
    motions: &Motions,
    shutter: &[f64],
) -> Vec<Vec<bool>> {
    let read: Vec<(Vec<[f32; 3]>, Vec<bool>)> = set.patches[patches.clone()]
        .par_iter()
        .map(|p: &Patch| {
            let c = p.camera as usize;
            let s = shutter[c];
            let pixels = &set.pixels[p.start as usize..p.end as usize];
            if s <= 0.0 || p.source != p.camera {
                return (
                    pixels.iter().map(|px| px.color).collect(),
                    vec![true; pixels.len()],
                );
            }
            let ib = &outline[c];
            let on_surface = |q: Point2<f64>| {
                let (x, y) = (q.x.round(), q.y.round());
                x >= 0.0 && y >= 0.0 && ib.owner_at(x as usize, y as usize) != NONE
            };
            let t = triangles[p.triangle as usize];
            let seen = source.seen[c];
            let proj = &source.projections[c];
            let img = source.images[c];
            let corner = |k: usize| seen[t[k] as usize].coords;
            let lerp = |vs: &[Vector3<f64>], l: &[f32; 3]| {
                vs[t[0] as usize] * l[0] as f64
                    + vs[t[1] as usize] * l[1] as f64
                    + vs[t[2] as usize] * l[2] as f64
            };
            pixels
                .iter()
                .map(|px| {
                    let l = &px.lambda;
                    let point = Point3::from(
                        corner(0) * l[0] as f64 + corner(1) * l[1] as f64 + corner(2) * l[2] as f64,
                    );
                    let Some(q) = proj.project(&point) else {
                        return (px.color, false);
                    };
                    let zero = Vector2::zeros();
                    let own = smear(proj, &point, &lerp(motions.template, l), s).unwrap_or(zero);
                    let other = smear(proj, &point, &lerp(motions.target, l), s).unwrap_or(zero);
                    // The corners and sides' middles of the box both smears sweep.
                    let inside = [-0.5, 0.0, 0.5].iter().all(|&i| {
                        [-0.5, 0.0, 0.5]
                            .iter()
                            .all(|&j| on_surface(q + own * i + other * j))
                    });
                    let [a, b] = common(own, other).0;
                    (along(img, q, a, b), inside)
                })
                .unzip()
        })
        .collect();
    let mut keep = Vec::with_capacity(read.len());
    for (p, (cs, k)) in set.patches[patches].iter().zip(read) {
        for (px, c) in set.pixels[p.start as usize..p.end as usize]
            .iter_mut()
            .zip(cs)
        {
            px.color = c;
        }
        keep.push(k);
    }
    keep
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_edge_smeared_across_becomes_a_ramp_of_the_smears_length() {
        // A vertical edge at x = 10 (0 left, 1 right), smeared 4 px along x: the mean over
        // [x − 2, x + 2] of the bilinear step, which rises from x = 8 to x = 12.
        let img = RgbImage::from_fn(24, 8, |x, _| [if x >= 10 { 1.0 } else { 0.0 }; 3]);
        let a = Vector2::new(4.0, 0.0);
        let at = |x: f64| along(&img, Point2::new(x, 4.0), a, Vector2::zeros())[0];
        assert!(at(7.0).abs() < 1e-6, "{}", at(7.0));
        assert!((at(13.0) - 1.0).abs() < 1e-6, "{}", at(13.0));
        // Halfway up at the edge's middle (9.5), and rising steadily.
        assert!((at(9.5) - 0.5).abs() < 0.03, "{}", at(9.5));
        assert!(at(9.0) < at(9.5) && at(9.5) < at(10.0) && at(10.0) < at(11.0));
        // Along the edge nothing changes.
        let along_edge = along(
            &img,
            Point2::new(9.0, 4.0),
            Vector2::new(0.0, 4.0),
            Vector2::zeros(),
        );
        assert!((along_edge[0] - img.get(9, 4)[0]).abs() < 1e-6);
        // Two smears in a row are the box of both: 4 px along x, then 4 px along x again,
        // spread the ramp over 8 px.
        let both = |x: f64| along(&img, Point2::new(x, 4.0), a, a)[0];
        assert!(both(5.5) < 1e-6 && (both(14.5) - 1.0).abs() < 1e-6);
        assert!(both(7.0) > 0.0 && both(12.0) < 1.0);
    }

    /// `Σ b·bᵀ` of a set of box smears (their second moments, times 12).
    fn moments(bs: &[Vector2<f64>]) -> nalgebra::Matrix2<f64> {
        bs.iter().map(|b| b * b.transpose()).sum()
    }

    #[test]
    fn each_side_is_smeared_by_what_it_lacks_of_the_other_s_smear() {
        let zero = Vector2::zeros();
        // A steady motion: the two smears are alike, nothing is added.
        let b = Vector2::new(12.0, -5.0);
        let (tpl, tgt) = common(b, b);
        assert!(
            tpl.iter().chain(&tgt).all(|v| v.norm() < 1e-6),
            "{tpl:?} {tgt:?}"
        );
        // A template recorded at rest takes the frame's whole smear; the frame nothing.
        let (tpl, tgt) = common(zero, b);
        assert!((moments(&tpl) - b * b.transpose()).norm() < 1e-9, "{tpl:?}");
        assert!(tgt.iter().all(|v| v.norm() < 1e-9));
        // And the other way round.
        let (tpl, tgt) = common(b, zero);
        assert!(tpl.iter().all(|v| v.norm() < 1e-9));
        assert!((moments(&tgt) - b * b.transpose()).norm() < 1e-9, "{tgt:?}");
        // Turned or changed in length: both sides end with the same second moments.
        for (own, other) in [
            (Vector2::new(20.0, 0.0), Vector2::new(17.3, 10.0)),
            (Vector2::new(3.0, 4.0), Vector2::new(-8.0, 1.0)),
            (Vector2::new(0.0, 6.0), Vector2::new(0.0, 9.0)),
            (Vector2::new(5.0, 5.0), Vector2::new(5.0, -5.0)),
        ] {
            let (tpl, tgt) = common(own, other);
            let lhs = own * own.transpose() + moments(&tpl);
            let rhs = other * other.transpose() + moments(&tgt);
            assert!(
                (lhs - rhs).norm() < 1e-9 * lhs.norm(),
                "{own:?} {other:?}: {lhs} {rhs}"
            );
        }
    }

    #[test]
    fn the_texture_kept_is_the_weakest_direction_s_summed_over_cameras() {
        // Camera 0 textured alike in x and y, its smear along x keeping a quarter of the x
        // texture; camera 1 unsmeared, with twice the texture. The weakest directions: 1 + 2
        // before, 0.25 + 2 after.
        let t = [
            Texture {
                before: [1.0, 0.0, 1.0],
                after: [0.25, 0.0, 1.0],
            },
            Texture {
                before: [2.0, 0.0, 2.0],
                after: [2.0, 0.0, 2.0],
            },
        ];
        let kept = Texture::kept(&t).unwrap();
        assert!((kept - 2.25 / 3.0).abs() < 1e-12, "{kept}");
        // Rotated tensors keep their eigenvalues: a 45° smear of an isotropic texture.
        let r = Texture {
            before: [1.0, 0.0, 1.0],
            after: [0.625, -0.375, 0.625],
        };
        assert!((Texture::kept(&[r]).unwrap() - 0.25).abs() < 1e-12);
        // Nothing to keep where there was no texture.
        assert_eq!(Texture::kept(&[Texture::default()]), None);
    }

    #[test]
    fn a_smear_shorter_than_a_quarter_pixel_reads_the_pixel_itself() {
        let img = RgbImage::from_fn(8, 8, |x, y| [x as f32 * 0.1, y as f32 * 0.1, 0.5]);
        let c = along(
            &img,
            Point2::new(3.0, 4.0),
            Vector2::new(0.2, 0.0),
            Vector2::zeros(),
        );
        assert_eq!(c, img.get(3, 4));
    }
}

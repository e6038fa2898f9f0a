//! The photometric residual image of one frame: what the tracker minimised, pixel by pixel, so
//! that a supervisor sees *where* a run leaves the footage unexplained (a sliding patch, an
//! occluder, a highlight) rather than only how much.
//!
//! For camera `c`, a run's mesh `M_t` at frame `t` and a reference frame `r` (the previous frame,
//! whose pixels the tracker warps into `t`, or the first frame, its anchor against drift): every
//! pixel `x` whose centre the mesh covers at `t` (front-most triangle, z-buffered by
//! `base::raster`) lies on one surface point, barycentric `b` in its triangle (perspective
//! correct). The same `b` on the same triangle of `M_r`, projected by the camera at `r`, is where
//! that surface point was; the residual is `I_t(x) − g·I_r(x_r)` (bilinear at `x_r`), shown as its
//! RMS over the three channels (images in 0..1), with `g` the triangle's brightness gain fitted
//! by least squares as the tracker fits it, so that shading which changes as the surface turns is
//! not mistaken for misregistration. A pixel whose surface point was hidden at `r`
//! (behind the mesh by more than 1 % of its depth) or outside the reference image has no
//! residual. This is the inverse of the tracker's warp (it maps `r` into `t`); both compare the
//! same pairs of colours up to which image is sampled between pixel centres.

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::base::mesh::Mesh;
use crate::base::raster::{self, NONE};
use crate::tracker::solve::DEFAULT_GAIN_RANGE;
use rayon::prelude::*;

/// Relative depth slack of the visibility test at the reference frame.
const DEPTH_TOLERANCE: f32 = 0.01;

/// One camera's residual image of one run: per pixel of the frame, `None` where the mesh does not
/// cover it or its surface point is not seen at the reference frame.
pub(crate) struct ResidualMap {
    pub width: usize,
    pub height: usize,
    pub values: Vec<Option<f32>>,
}

impl ResidualMap {
    /// RMS of the residual over the pixels that have one, and how many there are.
    pub fn rms(&self) -> (f64, usize) {
        let (s, n) = self
            .values
            .iter()
            .flatten()
            .fold((0.0f64, 0usize), |(s, n), &v| {
                (s + (v as f64).powi(2), n + 1)
            });
        (if n > 0 { (s / n as f64).sqrt() } else { 0.0 }, n)
    }
}

/// A compared pixel: its triangle, its colour at the frame drawn and the reference's colour.
type Pair = (u32, [f32; 3], [f32; 3]);

/// The residual image of `mesh_t` over `img_t` (camera `proj_t`) against the reference frame
/// (`mesh_r`, `proj_r`, `img_r`); see the module documentation. Rows in parallel; the result does
/// not depend on the thread count.
pub(crate) fn residual_map(
    mesh_t: &Mesh,
    proj_t: &Projection,
    img_t: &RgbImage,
    mesh_r: &Mesh,
    proj_r: &Projection,
    img_r: &RgbImage,
) -> ResidualMap {
    let (w, h) = (img_t.width(), img_t.height());
    let ib_t = raster::rasterize(&mesh_t.positions, &mesh_t.triangles, proj_t, w, h);
    let (wr, hr) = (img_r.width(), img_r.height());
    let ib_r = raster::rasterize(&mesh_r.positions, &mesh_r.triangles, proj_r, wr, hr);
    let screens: Vec<Option<raster::Projected>> = mesh_t
        .triangles
        .par_iter()
        .map(|t| raster::project_triangle(&mesh_t.positions, t, proj_t))
        .collect();
    // Pass 1: per pixel, its triangle and the two colours compared.
    let mut pairs: Vec<Option<Pair>> = vec![None; w * h];
    pairs
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let tri = ib_t.owner_at(x, y);
                if tri == NONE {
                    continue;
                }
                let Some(s) = &screens[tri as usize] else {
                    continue;
                };
                let b = s.surface_barycentric(x as f64, y as f64);
                let corners = mesh_r.triangles[tri as usize];
                let point = (0..3).fold(nalgebra::Vector3::zeros(), |a, k| {
                    a + mesh_r.positions[corners[k] as usize].coords * b[k]
                });
                let hr_ = proj_r.project_h(&nalgebra::Point3::from(point));
                if hr_.z.is_nan() || hr_.z <= 1e-9 {
                    continue;
                }
                let (u, v) = (hr_.x / hr_.z, hr_.y / hr_.z);
                if !img_r.inside(u, v) {
                    continue;
                }
                let d = ib_r.depth_at(u.round() as usize, v.round() as usize);
                // A point on the outline may miss the nearest pixel centre (infinite depth).
                if d.is_finite() && hr_.z as f32 > d * (1.0 + DEPTH_TOLERANCE) {
                    continue;
                }
                *out = Some((tri, img_t.get(x, y), img_r.sample_unchecked(u, v)));
            }
        });
    // Pass 2: the brightness gain of each triangle, as the tracker fits it (shading changes as
    // the surface turns: `I_t ≈ g·I_r`, least squares, within the tracker's default range, not
    // the run's own: the sheet compares runs of any tracker), summed in pixel order so the
    // result does not depend on the thread count; then the residuals.
    let mut sums = vec![[0.0f64; 2]; mesh_t.triangles.len()];
    for (t, a, r) in pairs.iter().flatten() {
        let s = &mut sums[*t as usize];
        for k in 0..3 {
            s[0] += (a[k] * r[k]) as f64;
            s[1] += (r[k] * r[k]) as f64;
        }
    }
    let gains: Vec<f32> = sums
        .iter()
        .map(|[ar, rr]| {
            if *rr > 0.0 {
                (ar / rr).clamp(1.0 / DEFAULT_GAIN_RANGE, DEFAULT_GAIN_RANGE) as f32
            } else {
                1.0
            }
        })
        .collect();
    let values = pairs
        .iter()
        .map(|p| {
            p.map(|(t, a, r)| {
                let g = gains[t as usize];
                ((0..3).map(|k| (a[k] - g * r[k]).powi(2)).sum::<f32>() / 3.0).sqrt()
            })
        })
        .collect();
    ResidualMap {
        width: w,
        height: h,
        values,
    }
}

/// The top of the colour scale for a set of maps: the 98th percentile of all their residuals,
/// rounded up to 1, 2 or 5 times a power of ten (so the scale reads well and equal footage gets
/// equal scales); 0.1 when there is none.
pub(crate) fn scale(maps: &[&ResidualMap]) -> f64 {
    let mut all: Vec<f32> = maps
        .iter()
        .flat_map(|m| m.values.iter().flatten().copied())
        .collect();
    if all.is_empty() {
        return 0.1;
    }
    let k = ((all.len() - 1) as f64 * 0.98) as usize;
    let (_, p, _) = all.select_nth_unstable_by(k, f32::total_cmp);
    let p = (*p as f64).max(1e-4);
    let e = 10f64.powf(p.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * e)
        .find(|&v| v >= p * (1.0 - 1e-6))
        .unwrap_or(10.0 * e)
}

/// `map` drawn over a dimmed grey copy of `img`: residual coloured by `colour(value / top)`,
/// pixels the mesh covers without a residual (hidden at the reference frame) in flat grey.
pub(crate) fn picture(
    map: &ResidualMap,
    img: &RgbImage,
    top: f64,
    colour: impl Fn(f64) -> [f32; 3],
) -> RgbImage {
    let mut out = RgbImage::new(map.width, map.height);
    for y in 0..map.height {
        for x in 0..map.width {
            let c = img.get(x, y);
            let grey = 0.35 * (0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]);
            out.set(x, y, [grey; 3]);
        }
    }
    for (i, v) in map.values.iter().enumerate() {
        if let Some(v) = v {
            out.pixels_mut()[i] = colour((*v as f64 / top).clamp(0.0, 1.0));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::camera::look_at;
    use crate::synth::render::{self, RenderOptions, Surface};
    use nalgebra::{Matrix3, Point3, Vector3};

    /// A square 2 units in front of the camera, facing it, moved by `offset`.
    fn square(offset: Vector3<f64>) -> Mesh {
        let p = |x: f64, y: f64| Point3::new(x, y, 2.0) + offset;
        Mesh::new(
            vec![p(-0.5, -0.5), p(0.5, -0.5), p(0.5, 0.5), p(-0.5, 0.5)],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    /// A 160×120 pinhole camera at the origin looking down +z.
    fn camera() -> Projection {
        let k = Matrix3::new(150.0, 0.0, 79.5, 0.0, 150.0, 59.5, 0.0, 0.0, 1.0);
        let (r, t) = look_at(
            &Point3::origin(),
            &Point3::new(0.0, 0.0, 2.0),
            &-Vector3::y(),
        );
        Projection::from_krt(&k, &r, &t).unwrap()
    }

    /// The rest square textured with a checker in its UVs, rendered through `proj`, moved by
    /// `offset` (the texture moves with it).
    fn frame(offset: Vector3<f64>, proj: &Projection) -> RgbImage {
        let rest = square(Vector3::zeros());
        let moved = square(offset);
        let colours: Vec<[f32; 3]> = rest
            .positions
            .iter()
            .map(|p| [(p.x + 0.5) as f32, (p.y + 0.5) as f32, 0.5])
            .collect();
        render::render(
            &moved,
            &[],
            &Surface::VertexColors(&colours),
            proj,
            160,
            120,
            &RenderOptions::default(),
        )
        .unwrap()
    }

    #[test]
    fn a_mesh_on_its_surface_leaves_no_residual_and_a_slipped_one_does() {
        let proj = camera();
        let shift = Vector3::new(0.1, 0.0, 0.0);
        let (img_r, img_t) = (frame(Vector3::zeros(), &proj), frame(shift, &proj));
        // The mesh that followed the surface: residual ~0 (bilinear vs render differences only).
        let good = residual_map(
            &square(shift),
            &proj,
            &img_t,
            &square(Vector3::zeros()),
            &proj,
            &img_r,
        );
        let (_, n) = good.rms();
        assert!(n > 3000, "covered pixels: {n}");
        // Median: the outline's pixels blend with the background differently in the two renders.
        let median = |m: &ResidualMap| {
            let mut v: Vec<f32> = m.values.iter().flatten().copied().collect();
            v.sort_by(f32::total_cmp);
            v[v.len() / 2]
        };
        let good_median = median(&good);
        assert!(
            good_median < 0.003,
            "tracked mesh leaves residual {good_median}"
        );
        // The mesh that stayed put while the surface moved: colour ramps disagree by 0.1·ramp.
        let stuck = residual_map(
            &square(Vector3::zeros()),
            &proj,
            &img_t,
            &square(Vector3::zeros()),
            &proj,
            &img_r,
        );
        let stuck_median = median(&stuck);
        assert!(
            stuck_median > 0.03,
            "stuck {stuck_median} vs tracked {good_median}"
        );
        // Pixels outside the mesh have none.
        assert!(good.values[0].is_none());
        // Shading that changes as the surface turns is a brightness gain, not misregistration:
        // the same frame 20 % brighter leaves the tracked mesh's residual where it was.
        let mut brighter = img_t.clone();
        brighter
            .pixels_mut()
            .iter_mut()
            .for_each(|p| *p = p.map(|v| v * 1.2));
        let lit = residual_map(
            &square(shift),
            &proj,
            &brighter,
            &square(Vector3::zeros()),
            &proj,
            &img_r,
        );
        let lit_median = median(&lit);
        assert!(lit_median < 0.004, "a brighter frame leaves {lit_median}");
    }

    #[test]
    fn scale_rounds_up_to_one_two_five() {
        let m = |v: f32| ResidualMap {
            width: 1,
            height: 1,
            values: vec![Some(v)],
        };
        assert!((scale(&[&m(0.031)]) - 0.05).abs() < 1e-12);
        assert!((scale(&[&m(0.2)]) - 0.2).abs() < 1e-12);
        assert!((scale(&[&m(0.11)]) - 0.2).abs() < 1e-12);
        assert!((scale(&[]) - 0.1).abs() < 1e-12);
    }
}

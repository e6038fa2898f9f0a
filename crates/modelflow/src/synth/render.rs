//! A software renderer written for this project: it draws a triangle mesh seen by one
//! [`Projection`] into an [`RgbImage`], exactly under the camera convention of `camera` (pixel
//! centres at integer coordinates; pixel `(i, j)` covers `[i-0.5, i+0.5] × [j-0.5, j+0.5]`). It
//! makes the synthetic footage the tracker is tested on and the report's per-vertex error
//! pictures, so what matters is geometric exactness and determinism, not speed records.
//!
//! How: each triangle is rasterised with 2-D homogeneous edge functions (Olano & Greer): with
//! `h_i = P·[X_i; 1]`, `e = [h_0 h_1 h_2]⁻¹ · (u, v, 1)` is affine in the image position, a sample
//! is inside iff all `e_i ≥ 0` (which also rejects the part behind the camera, so no clipping is
//! needed), `λ_i = e_i / Σe` are the perspective-correct barycentric coordinates and `Σe` is the
//! inverse depth, used for the z-buffer (nearest wins; ties go to the earlier triangle).
//! Anti-aliasing: `n × n` subsamples per pixel at `(i - 0.5 + (a + 0.5)/n, j - 0.5 + (b + 0.5)/n)`,
//! averaged with equal weights (a box filter over the pixel footprint). Visibility is resolved
//! first (a per-subsample triangle id and barycentrics), then only visible subsamples are shaded
//! from the [`Surface`] (vertex colours, a baked texture, or a procedural function of material
//! coordinates) and optionally lit by a directional light with two-sided smooth-normal diffuse
//! shading. The image is split into bands of rows rendered in parallel with rayon; each band is
//! independent, so the result does not depend on the number of threads.

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::base::mesh::Mesh;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// A surface's colour as a function of its material coordinates (one `[f64; 3]` per vertex,
/// interpolated perspective-correctly). The renderer knows nothing else of textures: procedural
/// patterns and baked maps (`synth::texture`) implement this, and so does any `Fn`.
pub trait Material: Sync {
    /// The albedo at material point `m`.
    fn albedo(&self, m: &[f64; 3]) -> [f32; 3];
}

impl<F: Fn(&[f64; 3]) -> [f32; 3] + Sync> Material for F {
    fn albedo(&self, m: &[f64; 3]) -> [f32; 3] {
        self(m)
    }
}

/// What colours the surface.
#[derive(Clone, Copy)]
pub enum Surface<'a> {
    /// One RGB colour per vertex, interpolated across triangles (material coordinates unused;
    /// pass an empty slice).
    VertexColors(&'a [[f32; 3]]),
    /// A [`Material`] looked up at the interpolated material coordinates of every visible
    /// subsample (a baked texture, a procedural pattern, any function).
    Material(&'a dyn Material),
    /// One colour everywhere.
    Uniform([f32; 3]),
    /// Two surfaces in one mesh: the triangles before index `at` coloured by `first`, the rest
    /// by `rest` (an object and the wall behind it, rendered together so that the z-buffer and
    /// the anti-aliasing treat them as one scene).
    Split {
        at: u32,
        first: &'a Surface<'a>,
        rest: &'a Surface<'a>,
    },
}

/// A directional light: colour = albedo · (ambient + diffuse · |n·l|), with `n` the interpolated
/// vertex normal (two-sided: back faces are lit like front faces).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Direction towards the light, in world coordinates (need not be unit length).
    pub direction: Vector3<f64>,
    pub ambient: f32,
    pub diffuse: f32,
}

/// Rendering options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Subsamples per pixel along each axis (1 = no anti-aliasing).
    pub supersample: u32,
    /// Colour where no surface is seen.
    pub background: [f32; 3],
    /// Directional light, or `None` for unlit (albedo only).
    pub light: Option<Light>,
    /// Nearest depth drawn, in world units.
    pub near: f64,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            supersample: 3,
            background: [0.0; 3],
            light: None,
            near: 1e-3,
        }
    }
}

/// Rows per parallel band.
const BAND: usize = 8;
const NONE: u32 = u32::MAX;

/// A triangle ready to rasterise: edge-function coefficients `e_i = a·u + b·v + c` per row of
/// `coef`, and its bounding box in pixels (inclusive, clamped to the image).
struct Setup {
    coef: [[f64; 3]; 3],
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
}

/// Per-subsample visibility of the whole image, band by band.
struct Raster {
    setups: Vec<Option<Setup>>,
    bins: Vec<Vec<u32>>,
    width: usize,
    height: usize,
    n: usize,
    near: f64,
}

/// Visibility of one band: for each subsample (row-major over the band's `BAND·n` sub-rows and
/// `width·n` sub-columns) the inverse depth, triangle id (or `NONE`) and barycentrics `λ1, λ2`.
struct BandBuf {
    inv_depth: Vec<f64>,
    tri: Vec<u32>,
    bary: Vec<[f32; 2]>,
}

impl Raster {
    fn new(
        mesh: &Mesh,
        proj: &Projection,
        width: usize,
        height: usize,
        n: usize,
        near: f64,
    ) -> Self {
        let h: Vec<Vector3<f64>> = mesh.positions.iter().map(|p| proj.project_h(p)).collect();
        let (wf, hf) = (width as f64, height as f64);
        let setups: Vec<Option<Setup>> = mesh
            .triangles
            .par_iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| h[i as usize]);
                if a.z <= near && b.z <= near && c.z <= near {
                    return None;
                }
                let m = Matrix3::from_columns(&[a, b, c]);
                let scale = a.norm() * b.norm() * c.norm();
                if m.determinant().abs() <= 1e-13 * scale {
                    return None;
                }
                let inv = m.try_inverse()?;
                let coef = [
                    [inv[(0, 0)], inv[(0, 1)], inv[(0, 2)]],
                    [inv[(1, 0)], inv[(1, 1)], inv[(1, 2)]],
                    [inv[(2, 0)], inv[(2, 1)], inv[(2, 2)]],
                ];
                let (x0, x1, y0, y1) = if a.z > near && b.z > near && c.z > near {
                    let us = [a.x / a.z, b.x / b.z, c.x / c.z];
                    let vs = [a.y / a.z, b.y / b.z, c.y / c.z];
                    (
                        us.iter().cloned().fold(f64::INFINITY, f64::min),
                        us.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
                        vs.iter().cloned().fold(f64::INFINITY, f64::min),
                        vs.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
                    )
                } else {
                    // Crosses the near plane: the projected box is unbounded; scan the image.
                    (-0.5, wf - 0.5, -0.5, hf - 0.5)
                };
                if x1 < -0.5 || y1 < -0.5 || x0 > wf - 0.5 || y0 > hf - 0.5 {
                    return None;
                }
                Some(Setup {
                    coef,
                    x0: x0.max(-0.5),
                    x1: x1.min(wf - 0.5),
                    y0: y0.max(-0.5),
                    y1: y1.min(hf - 0.5),
                })
            })
            .collect();
        let nbands = height.div_ceil(BAND);
        let mut bins = vec![Vec::new(); nbands];
        for (i, s) in setups.iter().enumerate() {
            if let Some(s) = s {
                let b0 = ((s.y0 + 0.5).floor().max(0.0) as usize / BAND).min(nbands - 1);
                let b1 = ((s.y1 + 0.5).floor().max(0.0) as usize / BAND).min(nbands - 1);
                for bin in &mut bins[b0..=b1] {
                    bin.push(i as u32);
                }
            }
        }
        Raster {
            setups,
            bins,
            width,
            height,
            n,
            near,
        }
    }

    /// Sub-pixel coordinate of subsample index `s` (along one axis).
    #[inline]
    fn sub(&self, s: usize) -> f64 {
        (s as f64 + 0.5) / self.n as f64 - 0.5
    }

    /// First and last subsample index whose coordinate lies in `[lo, hi]`, within `0..count`.
    #[inline]
    fn sub_range(&self, lo: f64, hi: f64, count: usize) -> Option<(usize, usize)> {
        let n = self.n as f64;
        let a = ((lo + 0.5) * n - 0.5).ceil().max(0.0);
        let b = ((hi + 0.5) * n - 0.5).floor().min(count as f64 - 1.0);
        (a <= b).then_some((a as usize, b as usize))
    }

    fn band(&self, band: usize, buf: &mut BandBuf) {
        let n = self.n;
        let sw = self.width * n;
        let row0 = band * BAND * n;
        let rows = (BAND.min(self.height - band * BAND)) * n;
        buf.inv_depth.clear();
        buf.inv_depth.resize(rows * sw, 0.0);
        buf.tri.clear();
        buf.tri.resize(rows * sw, NONE);
        buf.bary.clear();
        buf.bary.resize(rows * sw, [0.0; 2]);
        let min_inv = 1.0 / self.near;
        for &ti in &self.bins[band] {
            let s = self.setups[ti as usize]
                .as_ref()
                .expect("binned triangles have setups");
            let Some((sy0, sy1)) = self.sub_range(s.y0, s.y1, self.height * n) else {
                continue;
            };
            let Some((sx0, sx1)) = self.sub_range(s.x0, s.x1, sw) else {
                continue;
            };
            let sy0 = sy0.max(row0);
            let sy1 = sy1.min(row0 + rows - 1);
            let [c0, c1, c2] = &s.coef;
            for sy in sy0..=sy1 {
                let v = self.sub(sy);
                let line = (sy - row0) * sw;
                for sx in sx0..=sx1 {
                    let u = self.sub(sx);
                    let e0 = c0[0] * u + c0[1] * v + c0[2];
                    let e1 = c1[0] * u + c1[1] * v + c1[2];
                    let e2 = c2[0] * u + c2[1] * v + c2[2];
                    if e0 < 0.0 || e1 < 0.0 || e2 < 0.0 {
                        continue;
                    }
                    let sum = e0 + e1 + e2;
                    // Inverse depth: positive in front of the camera, at most 1/near.
                    if sum <= 0.0 || sum > min_inv {
                        continue;
                    }
                    let k = line + sx;
                    if sum > buf.inv_depth[k] {
                        buf.inv_depth[k] = sum;
                        buf.tri[k] = ti;
                        buf.bary[k] = [(e1 / sum) as f32, (e2 / sum) as f32];
                    }
                }
            }
        }
    }

    fn new_buf(&self) -> BandBuf {
        let cap = BAND * self.n * self.width * self.n;
        BandBuf {
            inv_depth: Vec::with_capacity(cap),
            tri: Vec::with_capacity(cap),
            bary: Vec::with_capacity(cap),
        }
    }
}

/// Area-weighted unit vertex normals (zero for vertices on no non-degenerate triangle).
pub fn vertex_normals(mesh: &Mesh) -> Vec<Vector3<f64>> {
    let mut n = vec![Vector3::zeros(); mesh.positions.len()];
    for (i, t) in mesh.triangles.iter().enumerate() {
        let tn = mesh.triangle_normal(i);
        for &v in t {
            n[v as usize] += tn;
        }
    }
    for v in &mut n {
        let l = v.norm();
        if l > 0.0 {
            *v /= l;
        }
    }
    n
}

fn check_inputs(
    mesh: &Mesh,
    material: &[[f64; 3]],
    surface: &Surface,
    width: usize,
    height: usize,
    n: u32,
) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::option(
            "render: image size",
            format!("{width}x{height}"),
            "a positive width and height",
        ));
    }
    if n == 0 || n > 16 {
        return Err(Error::option("render: supersample", n, "1 to 16"));
    }
    let nv = mesh.positions.len();
    if let Some(t) = mesh
        .triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= nv))
    {
        return Err(Error::mismatch(
            format!("render: triangle {t:?}"),
            format!("vertex indices below {nv}"),
            format!("{t:?}"),
        ));
    }
    check_surface(surface, nv, material.len())
}

fn check_surface(surface: &Surface, nv: usize, materials: usize) -> Result<()> {
    match surface {
        Surface::VertexColors(c) if c.len() != nv => Err(Error::mismatch(
            "render: vertex colours",
            format!("{nv} (one per vertex)"),
            c.len(),
        )),
        Surface::Material(_) if materials != nv => Err(Error::mismatch(
            "render: material coordinates",
            format!("{nv} (one per vertex)"),
            materials,
        )),
        Surface::Split { first, rest, .. } => {
            check_surface(first, nv, materials)?;
            check_surface(rest, nv, materials)
        }
        _ => Ok(()),
    }
}

/// Renders `mesh` seen through `proj` into a `width × height` image. `material` holds one
/// material coordinate per vertex for the textured surfaces (ignored, may be empty, for
/// [`Surface::VertexColors`] and [`Surface::Uniform`]). Errors (never panics) on inconsistent
/// sizes.
pub fn render(
    mesh: &Mesh,
    material: &[[f64; 3]],
    surface: &Surface,
    proj: &Projection,
    width: usize,
    height: usize,
    opts: &RenderOptions,
) -> Result<RgbImage> {
    check_inputs(mesh, material, surface, width, height, opts.supersample)?;
    let n = opts.supersample as usize;
    let raster = Raster::new(mesh, proj, width, height, n, opts.near);
    let normals = opts.light.map(|_| vertex_normals(mesh));
    let light = opts.light.map(|l| {
        let d = l.direction.norm();
        let dir = if d > 0.0 {
            l.direction / d
        } else {
            Vector3::zeros()
        };
        (dir, l.ambient, l.diffuse)
    });
    let mut data = vec![[0.0f32; 3]; width * height];
    let inv_n2 = 1.0 / (n * n) as f32;
    data.par_chunks_mut(width * BAND).enumerate().for_each_init(
        || raster.new_buf(),
        |buf, (band, out)| {
            raster.band(band, buf);
            let sw = width * n;
            let rows = out.len() / width;
            for py in 0..rows {
                for px in 0..width {
                    let mut acc = [0.0f32; 3];
                    for sy in py * n..py * n + n {
                        for sx in px * n..px * n + n {
                            let k = sy * sw + sx;
                            let ti = buf.tri[k];
                            let c = if ti == NONE {
                                opts.background
                            } else {
                                shade(
                                    mesh,
                                    material,
                                    surface,
                                    normals.as_deref(),
                                    light,
                                    ti,
                                    buf.bary[k],
                                )
                            };
                            acc[0] += c[0];
                            acc[1] += c[1];
                            acc[2] += c[2];
                        }
                    }
                    out[py * width + px] = acc.map(|a| a * inv_n2);
                }
            }
        },
    );
    Ok(RgbImage::from_pixels(width, height, data).expect("sizes match"))
}

#[inline]
fn shade(
    mesh: &Mesh,
    material: &[[f64; 3]],
    surface: &Surface,
    normals: Option<&[Vector3<f64>]>,
    light: Option<(Vector3<f64>, f32, f32)>,
    ti: u32,
    bary: [f32; 2],
) -> [f32; 3] {
    let t = mesh.triangles[ti as usize];
    let (l1, l2) = (bary[0] as f64, bary[1] as f64);
    let l0 = 1.0 - l1 - l2;
    let [i0, i1, i2] = t.map(|i| i as usize);
    let albedo = albedo_of(surface, material, [i0, i1, i2], ti, [l0, l1, l2]);
    match (normals, light) {
        (Some(ns), Some((dir, ambient, diffuse))) => {
            let nv = ns[i0] * l0 + ns[i1] * l1 + ns[i2] * l2;
            let len = nv.norm();
            let cos = if len > 0.0 {
                (nv.dot(&dir) / len).abs()
            } else {
                1.0
            };
            let k = ambient + diffuse * cos as f32;
            albedo.map(|a| a * k)
        }
        _ => albedo,
    }
}

/// The albedo of triangle `ti` (corners `i`) at barycentrics `l`.
#[inline]
fn albedo_of(
    surface: &Surface,
    material: &[[f64; 3]],
    i: [usize; 3],
    ti: u32,
    l: [f64; 3],
) -> [f32; 3] {
    let [i0, i1, i2] = i;
    let [l0, l1, l2] = l;
    match surface {
        Surface::VertexColors(c) => {
            let (a, b, cc) = (c[i0], c[i1], c[i2]);
            let (l0, l1, l2) = (l0 as f32, l1 as f32, l2 as f32);
            [
                l0 * a[0] + l1 * b[0] + l2 * cc[0],
                l0 * a[1] + l1 * b[1] + l2 * cc[1],
                l0 * a[2] + l1 * b[2] + l2 * cc[2],
            ]
        }
        Surface::Uniform(c) => *c,
        Surface::Material(m) => {
            let (a, b, c) = (&material[i0], &material[i1], &material[i2]);
            m.albedo(&[
                l0 * a[0] + l1 * b[0] + l2 * c[0],
                l0 * a[1] + l1 * b[1] + l2 * c[1],
                l0 * a[2] + l1 * b[2] + l2 * c[2],
            ])
        }
        Surface::Split { at, first, rest } => {
            let s = if ti < *at { first } else { rest };
            albedo_of(s, material, i, ti, l)
        }
    }
}

/// Depth (along the optical axis, world units) of the nearest surface at every pixel centre,
/// row-major, `f64::INFINITY` where none is seen. Uses the same rasteriser as [`render`], so it
/// agrees with the rendered images exactly.
pub fn depth_map(mesh: &Mesh, proj: &Projection, width: usize, height: usize) -> Result<Vec<f64>> {
    check_inputs(mesh, &[], &Surface::Uniform([0.0; 3]), width, height, 1)?;
    let raster = Raster::new(mesh, proj, width, height, 1, 1e-3);
    let mut depth = vec![f64::INFINITY; width * height];
    depth
        .par_chunks_mut(width * BAND)
        .enumerate()
        .for_each_init(
            || raster.new_buf(),
            |buf, (band, out)| {
                raster.band(band, buf);
                for (o, (&inv, &t)) in out.iter_mut().zip(buf.inv_depth.iter().zip(&buf.tri)) {
                    if t != NONE {
                        *o = 1.0 / inv;
                    }
                }
            },
        );
    Ok(depth)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::camera::look_at;
    use nalgebra::Point3;

    fn k(w: usize, h: usize, f: f64) -> Matrix3<f64> {
        Matrix3::new(
            f,
            0.0,
            (w as f64 - 1.0) / 2.0,
            0.0,
            f,
            (h as f64 - 1.0) / 2.0,
            0.0,
            0.0,
            1.0,
        )
    }

    fn camera(eye: [f64; 3], target: [f64; 3], w: usize, h: usize, f: f64) -> Projection {
        let (r, t) = look_at(&Point3::from(eye), &Point3::from(target), &Vector3::z());
        Projection::from_krt(&k(w, h, f), &r, &t).unwrap()
    }

    /// A quad in the plane y = 0 over x ∈ [x0, x1], z ∈ [z0, z1] (two triangles).
    fn quad(x0: f64, x1: f64, z0: f64, z1: f64, y: f64) -> Mesh {
        Mesh::new(
            vec![
                Point3::new(x0, y, z0),
                Point3::new(x1, y, z0),
                Point3::new(x1, y, z1),
                Point3::new(x0, y, z1),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    fn material(m: &Mesh) -> Vec<[f64; 3]> {
        m.positions.iter().map(|p| [p.x, p.y, p.z]).collect()
    }

    fn lum(p: [f32; 3]) -> f64 {
        (p[0] + p[1] + p[2]) as f64 / 3.0
    }

    #[test]
    fn a_dot_lands_where_the_projection_says() {
        // A slanted, off-centre camera; a Gaussian dot (sigma 12 mm ≈ 1 px) at a known material
        // point: the intensity-weighted centroid of the rendered dot is its projection.
        let (w, h) = (160, 120);
        let proj = camera([0.7, -1.8, 0.5], [0.05, 0.0, -0.03], w, h, 150.0);
        let m = quad(-0.5, 0.5, -0.4, 0.4, 0.0);
        for &(dx, dz) in &[(0.1234, -0.0567), (-0.2, 0.15), (0.013, 0.2)] {
            let f = move |p: &[f64; 3]| {
                let r2 = (p[0] - dx).powi(2) + (p[2] - dz).powi(2);
                let v = (-r2 / (2.0 * 0.012f64.powi(2))).exp() as f32;
                [v, v, v]
            };
            let opts = RenderOptions {
                supersample: 4,
                ..Default::default()
            };
            let img = render(
                &m,
                &material(&m),
                &Surface::Material(&f),
                &proj,
                w,
                h,
                &opts,
            )
            .unwrap();
            let want = proj.project(&Point3::new(dx, 0.0, dz)).unwrap();
            let (cx, cy) = (want.x.round() as i64, want.y.round() as i64);
            let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
            for y in cy - 6..=cy + 6 {
                for x in cx - 6..=cx + 6 {
                    let l = lum(img.get(x as usize, y as usize));
                    sw += l;
                    su += l * x as f64;
                    sv += l * y as f64;
                }
            }
            assert!(sw > 1.0, "dot visible");
            let (u, v) = (su / sw, sv / sw);
            assert!(
                (u - want.x).abs() < 0.03 && (v - want.y).abs() < 0.03,
                "centroid ({u:.3}, {v:.3}) vs projection ({:.3}, {:.3})",
                want.x,
                want.y
            );
        }
    }

    #[test]
    fn pixel_footprint_convention_for_a_screen_aligned_edge() {
        // A fronto-parallel quad whose left edge projects exactly to u = 10.0 (the centre of
        // pixel column 10): column 10 is half covered, 9 empty, 11 full.
        let (w, h) = (32, 24);
        let k = k(w, h, 100.0);
        // Camera at origin looking down +z (world = camera frame).
        let proj = Projection::from_krt(&k, &Matrix3::identity(), &Vector3::zeros()).unwrap();
        let z = 2.0;
        let x0 = (10.0 - k[(0, 2)]) * z / 100.0;
        let m = Mesh::new(
            vec![
                Point3::new(x0, -1.0, z),
                Point3::new(5.0, -1.0, z),
                Point3::new(5.0, 1.0, z),
                Point3::new(x0, 1.0, z),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let opts = RenderOptions {
            supersample: 4,
            ..Default::default()
        };
        let img = render(&m, &[], &Surface::Uniform([1.0; 3]), &proj, w, h, &opts).unwrap();
        assert_eq!(img.get(9, 12), [0.0; 3]);
        assert_eq!(img.get(10, 12), [0.5; 3]);
        assert_eq!(img.get(11, 12), [1.0; 3]);
    }

    #[test]
    fn z_buffer_keeps_the_nearest_surface_in_any_order() {
        let (w, h) = (64, 48);
        let proj = camera([0.0, -2.0, 0.0], [0.0, 0.0, 0.0], w, h, 60.0);
        let near = quad(-0.3, 0.3, -0.3, 0.3, -0.2);
        let far = quad(-0.5, 0.5, -0.5, 0.5, 0.2);
        for order in [[&near, &far], [&far, &near]] {
            let mut pos = order[0].positions.clone();
            pos.extend(order[1].positions.iter());
            let tris = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
            let m = Mesh::new(pos, tris);
            let near_first = std::ptr::eq(order[0], &near);
            let red = [1.0, 0.0, 0.0];
            let blue = [0.0, 0.0, 1.0];
            let cols: Vec<[f32; 3]> = (0..8)
                .map(|i| if (i < 4) == near_first { red } else { blue })
                .collect();
            let img = render(
                &m,
                &[],
                &Surface::VertexColors(&cols),
                &proj,
                w,
                h,
                &RenderOptions::default(),
            )
            .unwrap();
            assert_eq!(img.get(32, 24), red, "centre shows the near quad");
            // Beyond the near quad's extent only the far one is seen.
            let edge = proj.project(&Point3::new(0.4, 0.2, 0.0)).unwrap();
            assert_eq!(img.get(edge.x.round() as usize, 24), blue);
            let d = depth_map(&m, &proj, w, h).unwrap();
            assert!((d[24 * w + 32] - 1.8).abs() < 1e-9, "{}", d[24 * w + 32]);
            assert_eq!(d[0], f64::INFINITY);
        }
    }

    #[test]
    fn texture_interpolation_is_perspective_correct() {
        // Stripes of 0.1 m along x on a plane seen at a grazing angle: each stripe boundary is
        // found in the image where the projection of its 3-D position says (within 0.1 px);
        // affine (screen-space) interpolation would be off by many pixels.
        let (w, h) = (200, 60);
        let proj = camera([-1.2, -0.9, 0.0], [0.2, 0.0, 0.0], w, h, 160.0);
        let m = quad(-0.5, 0.5, -0.3, 0.3, 0.0);
        let stripes = |p: &[f64; 3]| {
            let v = if ((p[0] + 10.0) / 0.1).floor() as i64 % 2 == 0 {
                1.0
            } else {
                0.0
            };
            [v, v, v]
        };
        let opts = RenderOptions {
            supersample: 8,
            ..Default::default()
        };
        let img = render(
            &m,
            &material(&m),
            &Surface::Material(&stripes),
            &proj,
            w,
            h,
            &opts,
        )
        .unwrap();
        let mut checked = 0;
        for b in [-0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.4] {
            let p = proj.project(&Point3::new(b, 0.0, 0.0)).unwrap();
            let row = p.y.round() as usize;
            let x = p.x.floor() as usize;
            // Integrate coverage over a window: for a step from a to b (left side value a), the
            // edge position = left - 0.5 + (sum - n_b) / (a - b) where n_b = count * b.
            let left = x - 3;
            let right = x + 3;
            let l_val = lum(img.get(left, row));
            let r_val = lum(img.get(right, row));
            if (l_val - r_val).abs() < 0.9 {
                continue;
            }
            let sum: f64 = (left..=right).map(|i| lum(img.get(i, row))).sum();
            let count = (right - left + 1) as f64;
            let edge = left as f64 - 0.5 + (sum - count * r_val) / (l_val - r_val);
            // Where the boundary crosses this row exactly: solve along the line x = b on the plane.
            let mut lo = -0.3f64;
            let mut hi = 0.3f64;
            let vy = |z: f64| proj.project(&Point3::new(b, 0.0, z)).unwrap().y;
            let dir = vy(hi) > vy(lo);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if (vy(mid) < row as f64) == dir {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let want = proj
                .project(&Point3::new(b, 0.0, 0.5 * (lo + hi)))
                .unwrap()
                .x;
            assert!(
                (edge - want).abs() < 0.1,
                "boundary {b}: found {edge:.3}, want {want:.3}"
            );
            checked += 1;
        }
        assert!(checked >= 6, "only {checked} boundaries checked");
    }

    #[test]
    fn vertex_colours_are_interpolated_perspective_correctly() {
        // At the projection of a 3-D point with barycentrics (0.2, 0.3, 0.5) on a steeply
        // slanted triangle, the colour is the same mix of vertex colours.
        let (w, h) = (120, 90);
        let proj = camera([0.9, -1.0, 0.3], [0.0, 0.0, 0.0], w, h, 100.0);
        let p = [
            Point3::new(-0.6, 0.0, -0.4),
            Point3::new(0.6, 0.3, -0.3),
            Point3::new(0.0, -0.2, 0.5),
        ];
        let m = Mesh::new(p.to_vec(), vec![[0, 1, 2]]);
        let cols = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let l = [0.2, 0.3, 0.5];
        let x = Point3::from(p[0].coords * l[0] + p[1].coords * l[1] + p[2].coords * l[2]);
        // Put the point exactly on a pixel centre by rendering with supersample 1 and
        // shifting the camera's principal point.
        let q = proj.project(&x).unwrap();
        let shift = nalgebra::Matrix3::new(
            1.0,
            0.0,
            q.x.round() - q.x,
            0.0,
            1.0,
            q.y.round() - q.y,
            0.0,
            0.0,
            1.0,
        );
        let proj = Projection::from_matrix(&(shift * proj.matrix())).unwrap();
        let q = proj.project(&x).unwrap();
        let opts = RenderOptions {
            supersample: 1,
            ..Default::default()
        };
        let img = render(&m, &[], &Surface::VertexColors(&cols), &proj, w, h, &opts).unwrap();
        let got = img.get(q.x.round() as usize, q.y.round() as usize);
        for ch in 0..3 {
            assert!((got[ch] as f64 - l[ch]).abs() < 1e-4, "{got:?} vs {l:?}");
        }
    }

    #[test]
    fn supersampling_antialiases_edges() {
        let (w, h) = (40, 30);
        let proj = camera([0.0, -2.0, 0.0], [0.0, 0.0, 0.0], w, h, 40.0);
        let m = Mesh::new(
            vec![
                Point3::new(-0.6, 0.0, -0.5),
                Point3::new(0.7, 0.0, -0.4),
                Point3::new(0.1, 0.0, 0.6),
            ],
            vec![[0, 1, 2]],
        );
        let count_mid = |n: u32| {
            let opts = RenderOptions {
                supersample: n,
                ..Default::default()
            };
            let img = render(&m, &[], &Surface::Uniform([1.0; 3]), &proj, w, h, &opts).unwrap();
            img.pixels()
                .iter()
                .filter(|p| p[0] > 0.02 && p[0] < 0.98)
                .count()
        };
        assert_eq!(count_mid(1), 0, "no anti-aliasing: only 0 or 1");
        assert!(count_mid(4) > 20, "edges get intermediate values");
    }

    #[test]
    fn diffuse_light_is_two_sided_and_depends_on_orientation() {
        let (w, h) = (40, 30);
        let proj = camera([0.0, -2.0, 0.0], [0.0, 0.0, 0.0], w, h, 40.0);
        let front = quad(-0.5, 0.5, -0.5, 0.5, 0.0);
        let mut back = front.clone();
        back.triangles = vec![[0, 2, 1], [0, 3, 2]];
        let light = |d: Vector3<f64>| RenderOptions {
            light: Some(Light {
                direction: d,
                ambient: 0.2,
                diffuse: 0.8,
            }),
            ..Default::default()
        };
        let px = |m: &Mesh, o: &RenderOptions| {
            render(m, &[], &Surface::Uniform([0.5; 3]), &proj, w, h, o)
                .unwrap()
                .get(20, 15)[0]
        };
        let head_on = light(Vector3::new(0.0, -1.0, 0.0));
        assert!((px(&front, &head_on) - 0.5).abs() < 1e-6);
        assert!((px(&back, &head_on) - 0.5).abs() < 1e-6);
        let oblique = light(Vector3::new(1.0, -1.0, 0.0));
        let want = 0.5 * (0.2 + 0.8 * std::f32::consts::FRAC_1_SQRT_2);
        assert!((px(&front, &oblique) - want).abs() < 1e-5);
    }

    #[test]
    fn same_image_whatever_the_thread_count() {
        let (w, h) = (100, 70);
        let proj = camera([0.3, -2.0, 0.4], [0.0, 0.0, 0.0], w, h, 90.0);
        let m = crate::base::mesh::grid(9, 9, |u, v| {
            Point3::new(u - 0.5, 0.1 * (6.0 * u).sin(), v - 0.5)
        });
        let tex = crate::synth::texture::Texture::new(4, 0.01).bake_plane(
            [-0.5, -0.5],
            [1.0, 1.0],
            200.0,
        );
        let mat: Vec<[f64; 3]> = m.positions.iter().map(|p| [p.x, p.z, 0.0]).collect();
        let opts = RenderOptions::default();
        let a = render(&m, &mat, &Surface::Material(&tex), &proj, w, h, &opts).unwrap();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let b = pool
            .install(|| render(&m, &mat, &Surface::Material(&tex), &proj, w, h, &opts).unwrap());
        assert_eq!(a, b);
    }

    #[test]
    fn inconsistent_inputs_are_errors() {
        let proj = camera([0.0, -2.0, 0.0], [0.0, 0.0, 0.0], 10, 10, 10.0);
        let m = quad(-0.5, 0.5, -0.5, 0.5, 0.0);
        let o = RenderOptions::default();
        let e = render(
            &m,
            &[],
            &Surface::VertexColors(&[[0.0; 3]]),
            &proj,
            10,
            10,
            &o,
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("vertex colours: expected 4 (one per vertex), found 1"),
            "{e}"
        );
        let f = |_: &[f64; 3]| [0.0f32; 3];
        assert!(render(&m, &[], &Surface::Material(&f), &proj, 10, 10, &o).is_err());
        assert!(render(&m, &[], &Surface::Uniform([0.0; 3]), &proj, 0, 10, &o).is_err());
    }
}

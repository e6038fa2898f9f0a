//! Procedural surface texture for synthetic footage: a colourful, non-periodic pattern defined on
//! 3-D material coordinates (metres), deterministic for a seed, with detail at several scales so
//! that an image-based tracker finds gradients everywhere. It is the sum of several octaves of
//! hashed-lattice value noise per channel (each octave randomly rotated and shifted so that no
//! lattice axis or period shows) over a slowly varying vivid base hue, with three layers of
//! randomly placed, randomly coloured soft-edged ellipsoidal spots ("blobs") on top.
//!
//! Evaluating the pattern is too slow to do per rendered subsample, so it is baked once into an
//! image and sampled bilinearly: [`PlaneTexture`] for flat sheets (material coordinates `x, y`),
//! [`CubeTexture`] (a cube map of the pattern on a sphere) for closed surfaces whose material
//! coordinates are rest positions around the origin. Written by hand because the pattern is ours
//! and the bakes must be bit-for-bit deterministic; no noise crate gives both.

use crate::base::image::RgbImage;
use crate::synth::render::Material;
use rayon::prelude::*;

/// SplitMix64 finaliser: a fast, well-mixed 64-bit hash step.
#[inline]
pub(crate) fn mix64(mut h: u64) -> u64 {
    h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^ (h >> 31)
}

#[inline]
fn hash3(seed: u64, x: i64, y: i64, z: i64) -> u64 {
    let h = mix64(
        seed.wrapping_add(x as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15),
    );
    let h = mix64(h.wrapping_add(y as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    mix64(h.wrapping_add(z as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// Three values in [-1, 1] from one hash (21 bits each).
#[inline]
fn unit3(h: u64) -> [f64; 3] {
    const M: f64 = ((1u64 << 21) - 1) as f64;
    [
        (h & 0x1F_FFFF) as f64 / M * 2.0 - 1.0,
        ((h >> 21) & 0x1F_FFFF) as f64 / M * 2.0 - 1.0,
        ((h >> 42) & 0x1F_FFFF) as f64 / M * 2.0 - 1.0,
    ]
}

/// Uniform in [0, 1) from the top 53 bits.
#[inline]
fn unit(h: u64) -> f64 {
    (h >> 11) as f64 / (1u64 << 53) as f64
}

#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// A random rotation (from a hashed unit quaternion) as row-major 3×3.
fn random_rotation(seed: u64) -> [[f64; 3]; 3] {
    // Marsaglia-style: normalise a 4-vector of hashed values (rejecting tiny norms).
    let mut k = 0u64;
    let (w, x, y, z) = loop {
        let a = unit3(mix64(seed ^ k));
        let b = unit3(mix64(seed ^ k ^ 0xA5A5_A5A5));
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + b[0] * b[0]).sqrt();
        if n > 0.1 && n <= 1.0 {
            break (a[0] / n, a[1] / n, a[2] / n, b[0] / n);
        }
        k += 1;
    };
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// One lattice of the pattern: a rotated, shifted, scaled frame with its own hash seed.
#[derive(Clone, Debug)]
struct Lattice {
    rot: [[f64; 3]; 3],
    offset: [f64; 3],
    inv_spacing: f64,
    seed: u64,
}

impl Lattice {
    fn new(seed: u64, spacing: f64) -> Self {
        let o = unit3(mix64(seed ^ 0x5151));
        Lattice {
            rot: random_rotation(seed),
            offset: [o[0] * 1000.0, o[1] * 1000.0, o[2] * 1000.0],
            inv_spacing: 1.0 / spacing,
            seed,
        }
    }

    /// The point in lattice units.
    #[inline]
    fn local(&self, p: &[f64; 3]) -> [f64; 3] {
        let r = &self.rot;
        let s = self.inv_spacing;
        [
            (r[0][0] * p[0] + r[0][1] * p[1] + r[0][2] * p[2]) * s + self.offset[0],
            (r[1][0] * p[0] + r[1][1] * p[1] + r[1][2] * p[2]) * s + self.offset[1],
            (r[2][0] * p[0] + r[2][1] * p[1] + r[2][2] * p[2]) * s + self.offset[2],
        ]
    }

    /// Value noise, three channels, each in about [-1, 1], C2-smooth.
    #[inline]
    fn noise(&self, p: &[f64; 3]) -> [f64; 3] {
        let q = self.local(p);
        let (fx, fy, fz) = (q[0].floor(), q[1].floor(), q[2].floor());
        let (ix, iy, iz) = (fx as i64, fy as i64, fz as i64);
        let (tx, ty, tz) = (fade(q[0] - fx), fade(q[1] - fy), fade(q[2] - fz));
        let mut out = [0.0; 3];
        for dz in 0..2 {
            let wz = if dz == 0 { 1.0 - tz } else { tz };
            for dy in 0..2 {
                let wy = if dy == 0 { 1.0 - ty } else { ty };
                for dx in 0..2 {
                    let wx = if dx == 0 { 1.0 - tx } else { tx };
                    let v = unit3(hash3(self.seed, ix + dx, iy + dy, iz + dz));
                    let w = wx * wy * wz;
                    out[0] += w * v[0];
                    out[1] += w * v[1];
                    out[2] += w * v[2];
                }
            }
        }
        out
    }

    /// One soft-edged ellipsoidal spot per lattice cell (with probability `density`), fitting
    /// inside its cell. Returns (coverage in [0, 1], the spot's colour).
    #[inline]
    fn spot(&self, p: &[f64; 3], density: f64, edge: f64) -> (f64, [f64; 3]) {
        let q = self.local(p);
        let c = [q[0].floor(), q[1].floor(), q[2].floor()];
        let h = hash3(self.seed ^ 0xB10B, c[0] as i64, c[1] as i64, c[2] as i64);
        if unit(h) >= density {
            return (0.0, [0.0; 3]);
        }
        let h2 = mix64(h);
        let h3 = mix64(h2);
        let shape = unit3(h2);
        // Semi-axes (cell units): one long, two shorter, up to 3:1.
        let a = 0.22 + 0.22 * (0.5 + 0.5 * shape[0]);
        let b = a * (0.35 + 0.65 * (0.5 + 0.5 * shape[1]));
        let jit = unit3(h3);
        let centre = [
            c[0] + 0.5 + jit[0] * (0.5 - a),
            c[1] + 0.5 + jit[1] * (0.5 - a),
            c[2] + 0.5 + jit[2] * (0.5 - a),
        ];
        // Orientation: the long axis along a hashed unit direction.
        let dir = {
            let d = unit3(mix64(h3 ^ 0xD1));
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-6);
            [d[0] / n, d[1] / n, d[2] / n]
        };
        let d = [q[0] - centre[0], q[1] - centre[1], q[2] - centre[2]];
        let along = d[0] * dir[0] + d[1] * dir[1] + d[2] * dir[2];
        let perp2 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - along * along).max(0.0);
        let r = ((along / a).powi(2) + perp2 / (b * b)).sqrt();
        // Signed distance (approx., cell units) to the rim, then a linear ramp of width `edge`.
        let dist = (r - 1.0) * b;
        let cover = (0.5 - dist / edge).clamp(0.0, 1.0);
        let hue = unit(mix64(h3 ^ 0xC0));
        let hv = unit3(mix64(h3 ^ 0xC1));
        let val = if hv[0] < -0.75 {
            0.15
        } else {
            0.65 + 0.35 * hv[1].abs()
        };
        let sat = 0.6 + 0.4 * hv[2].abs();
        (cover, hsv(hue, sat, val))
    }
}

/// HSV (all in [0, 1]) to RGB.
fn hsv(h: f64, s: f64, v: f64) -> [f64; 3] {
    let h6 = (h - h.floor()) * 6.0;
    let i = h6.floor();
    let f = h6 - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match i as i32 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

/// The procedural pattern. `finest` is the size of its smallest features in material units
/// (metres): choose about two pixels' worth at the footage's viewing distance. Features range
/// from `finest` to about 64·`finest`.
#[derive(Clone, Debug)]
pub struct Texture {
    hue: [Lattice; 2],
    detail: Vec<Lattice>,
    spots: Vec<(Lattice, f64)>,
    edge: f64,
}

impl Texture {
    pub fn new(seed: u64, finest: f64) -> Self {
        assert!(
            finest > 0.0 && finest.is_finite(),
            "finest feature size must be positive"
        );
        let s = mix64(seed ^ 0x7E47_0E5E);
        let lat = |k: u64, spacing: f64| Lattice::new(mix64(s.wrapping_add(k)), spacing);
        Texture {
            hue: [lat(1, finest * 64.0), lat(2, finest * 28.0)],
            detail: (0..6)
                .map(|i| lat(10 + i as u64, finest * 1.2 * 2f64.powi(i)))
                .collect(),
            spots: vec![
                (lat(20, finest * 26.0), 0.55),
                (lat(21, finest * 11.0), 0.6),
                (lat(22, finest * 4.5), 0.65),
            ],
            edge: 0.35 * finest,
        }
    }

    /// The colour at material point `p` (each channel in [0, 1]).
    pub fn eval(&self, p: &[f64; 3]) -> [f32; 3] {
        let h0 = self.hue[0].noise(p);
        let h1 = self.hue[1].noise(p);
        let hue = 0.5 + 0.9 * h0[0] + 0.35 * h1[0];
        let sat = (0.62 + 0.3 * h0[1] + 0.2 * h1[1]).clamp(0.25, 0.95);
        let base = hsv(hue, sat, 0.9);
        // Detail: roughly equal contrast per octave, so gradients exist at every scale.
        let mut d = [0.0f64; 3];
        for (i, l) in self.detail.iter().enumerate() {
            let amp = if i == 0 { 0.8 } else { 1.0 };
            let n = l.noise(p);
            d[0] += amp * n[0];
            d[1] += amp * n[1];
            d[2] += amp * n[2];
        }
        let k = 1.0 / (self.detail.len() as f64).sqrt();
        let (l, c1, c2) = (d[0] * k * 1.6, d[1] * k, d[2] * k);
        let mut c = [
            base[0] * (0.72 + 0.34 * l) + 0.16 * c1,
            base[1] * (0.72 + 0.34 * l) + 0.16 * c2,
            base[2] * (0.72 + 0.34 * l) - 0.11 * (c1 + c2),
        ];
        for (lat, density) in &self.spots {
            let edge = self.edge * lat.inv_spacing;
            let (a, col) = lat.spot(p, *density, edge);
            if a > 0.0 {
                // Keep a little of the underlying detail inside spots.
                let a = 0.92 * a;
                for ch in 0..3 {
                    let inner = col[ch] * (0.85 + 0.3 * (c[ch] - 0.5));
                    c[ch] = c[ch] * (1.0 - a) + inner * a;
                }
            }
        }
        c.map(|v| v.clamp(0.0, 1.0) as f32)
    }

    /// Bakes the pattern on the plane `z = 0` over `[origin, origin + size]` at `density`
    /// texels per material unit.
    pub fn bake_plane(&self, origin: [f64; 2], size: [f64; 2], density: f64) -> PlaneTexture {
        let w = ((size[0] * density).ceil() as usize).max(2);
        let h = ((size[1] * density).ceil() as usize).max(2);
        let texel = [size[0] / w as f64, size[1] / h as f64];
        let mut data = vec![[0.0f32; 3]; w * h];
        data.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
            let y = origin[1] + (j as f64 + 0.5) * texel[1];
            for (i, px) in row.iter_mut().enumerate() {
                let x = origin[0] + (i as f64 + 0.5) * texel[0];
                *px = self.eval(&[x, y, 0.0]);
            }
        });
        PlaneTexture {
            image: RgbImage::from_pixels(w, h, data).expect("sizes match"),
            origin,
            texel,
        }
    }

    /// Bakes the pattern on the capsule whose axis runs along x from `−half_length` to
    /// `half_length`, with radius `radius`, at `density` texels per material unit (along the axis
    /// and round the cylinder's circumference).
    pub fn bake_capsule(&self, half_length: f64, radius: f64, density: f64) -> CapsuleTexture {
        let extent = half_length + radius;
        let cols = ((2.0 * extent * density).ceil() as usize).max(2);
        let around = ((2.0 * std::f64::consts::PI * radius * density).ceil() as usize).max(8);
        let dx = 2.0 * extent / cols as f64;
        let dtheta = 2.0 * std::f64::consts::PI / around as f64;
        let rows = around + 2;
        let data: Vec<[f32; 3]> = (0..rows * cols)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k % cols, k / cols);
                let x = -extent + (i as f64 + 0.5) * dx;
                let theta = -std::f64::consts::PI + (j as f64 - 0.5) * dtheta;
                // The surface's distance from the axis at x: the cylinder's, or the cap's.
                let beyond = (x.abs() - half_length).max(0.0);
                let rho = (radius * radius - beyond * beyond).max(0.0).sqrt();
                self.eval(&[x, rho * theta.cos(), rho * theta.sin()])
            })
            .collect();
        CapsuleTexture {
            image: RgbImage::from_pixels(cols, rows, data).expect("sizes match"),
            x0: -extent,
            dx,
            dtheta,
        }
    }

    /// Bakes the pattern on the sphere of radius `radius` around the origin into a cube map with
    /// `res × res` texels per face.
    pub fn bake_cube(&self, radius: f64, res: usize) -> CubeTexture {
        let res = res.max(2);
        let faces = (0..6)
            .into_par_iter()
            .map(|f| {
                let mut data = vec![[0.0f32; 3]; res * res];
                for (k, px) in data.iter_mut().enumerate() {
                    let (i, j) = (k % res, k / res);
                    let s = (i as f64 + 0.5) / res as f64 * 2.0 - 1.0;
                    let t = (j as f64 + 0.5) / res as f64 * 2.0 - 1.0;
                    let d = cube_direction(f, s, t);
                    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    *px = self.eval(&d.map(|c| c / n * radius));
                }
                RgbImage::from_pixels(res, res, data).expect("sizes match")
            })
            .collect();
        CubeTexture { faces, res }
    }
}

/// The pattern baked on a capsule (a cylinder along x with hemispherical caps) as a map over
/// `(x, θ)`, θ the angle about the x axis from +y toward +z: texel `(i, j)` holds the colour at
/// the surface point with `x = x0 + (i + ½)·dx` and `θ = −π + (j − ½)·dθ`. Its first and last
/// rows repeat the last and first angles, so a bilinear sample wraps round the axis without a
/// seam (the colours come from the same 3D points).
#[derive(Clone, Debug)]
pub struct CapsuleTexture {
    image: RgbImage,
    x0: f64,
    dx: f64,
    dtheta: f64,
}

impl CapsuleTexture {
    /// Bilinear sample at the surface point in the direction of `m` from the x axis, at `m`'s x.
    #[inline]
    pub fn sample(&self, m: &[f64; 3]) -> [f32; 3] {
        let theta = m[2].atan2(m[1]);
        let u = (m[0] - self.x0) / self.dx - 0.5;
        // θ ∈ [−π, π] lands in rows [½, n + ½], inside the n + 2 rows.
        let v = (theta + std::f64::consts::PI) / self.dtheta + 0.5;
        bilinear_clamped(&self.image, u, v)
    }
}

impl Material for CapsuleTexture {
    /// Looked up at material point `m`'s position along the axis and angle about it.
    fn albedo(&self, m: &[f64; 3]) -> [f32; 3] {
        self.sample(m)
    }
}

/// The pattern baked on a plane: texel `(i, j)` covers material `[origin + (i, j)·texel,
/// origin + (i+1, j+1)·texel]` and holds the colour at its centre.
#[derive(Clone, Debug)]
pub struct PlaneTexture {
    pub image: RgbImage,
    pub origin: [f64; 2],
    /// Texel size in material units along x and y.
    pub texel: [f64; 2],
}

impl PlaneTexture {
    /// Bilinear sample at material point `(x, y)`, clamped at the borders.
    #[inline]
    pub fn sample(&self, x: f64, y: f64) -> [f32; 3] {
        let u = (x - self.origin[0]) / self.texel[0] - 0.5;
        let v = (y - self.origin[1]) / self.texel[1] - 0.5;
        bilinear_clamped(&self.image, u, v)
    }
}

impl Material for PlaneTexture {
    /// Looked up at material `(x, y)`.
    fn albedo(&self, m: &[f64; 3]) -> [f32; 3] {
        self.sample(m[0], m[1])
    }
}

/// Bilinear sample at `(u, v)` (texel centres at integers), clamped to the border texels. The
/// renderer's hot path: one clamp, then `RgbImage`'s own unchecked bilinear sample.
#[inline]
fn bilinear_clamped(img: &RgbImage, u: f64, v: f64) -> [f32; 3] {
    let u = u.clamp(0.0, (img.width() - 1) as f64);
    let v = v.clamp(0.0, (img.height() - 1) as f64);
    img.sample_unchecked(u, v)
}

/// Direction for face `f` (+x, -x, +y, -y, +z, -z) at face coordinates `s, t ∈ [-1, 1]`.
#[inline]
fn cube_direction(f: usize, s: f64, t: f64) -> [f64; 3] {
    match f {
        0 => [1.0, s, t],
        1 => [-1.0, s, t],
        2 => [s, 1.0, t],
        3 => [s, -1.0, t],
        4 => [s, t, 1.0],
        _ => [s, t, -1.0],
    }
}

/// The pattern baked on a sphere as a cube map (six square faces; see `cube_direction`).
#[derive(Clone, Debug)]
pub struct CubeTexture {
    faces: Vec<RgbImage>,
    res: usize,
}

impl CubeTexture {
    /// Bilinear sample in direction `d` (need not be normalised; the zero vector gives face +x's
    /// centre).
    #[inline]
    pub fn sample(&self, d: &[f64; 3]) -> [f32; 3] {
        let a = d.map(f64::abs);
        let (f, m, s, t) = if a[0] >= a[1] && a[0] >= a[2] {
            (if d[0] >= 0.0 { 0 } else { 1 }, a[0], d[1], d[2])
        } else if a[1] >= a[2] {
            (if d[1] >= 0.0 { 2 } else { 3 }, a[1], d[0], d[2])
        } else {
            (if d[2] >= 0.0 { 4 } else { 5 }, a[2], d[0], d[1])
        };
        let m = if m > 0.0 { m } else { 1.0 };
        let r = self.res as f64;
        let u = (s / m + 1.0) * 0.5 * r - 0.5;
        let v = (t / m + 1.0) * 0.5 * r - 0.5;
        bilinear_clamped(&self.faces[f], u, v)
    }
}

impl Material for CubeTexture {
    /// Looked up in the direction of the material point from the origin.
    fn albedo(&self, m: &[f64; 3]) -> [f32; 3] {
        self.sample(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_for_a_seed_and_different_across_seeds() {
        let a = Texture::new(7, 0.005);
        let b = Texture::new(7, 0.005);
        let c = Texture::new(8, 0.005);
        let pts: Vec<[f64; 3]> = (0..200)
            .map(|i| [i as f64 * 0.013, (i * 7 % 31) as f64 * 0.021, 0.0])
            .collect();
        let ea: Vec<_> = pts.iter().map(|p| a.eval(p)).collect();
        let eb: Vec<_> = pts.iter().map(|p| b.eval(p)).collect();
        let ec: Vec<_> = pts.iter().map(|p| c.eval(p)).collect();
        assert_eq!(ea, eb);
        assert!(ea.iter().zip(&ec).filter(|(x, y)| x != y).count() > 150);
    }

    #[test]
    fn has_gradients_everywhere_and_colour() {
        // Over a 0.5 m square at 2 mm texels (finest 5 mm): nearly every 8×8 texel window
        // (16 mm) has contrast, and the colours cover the hue circle.
        let t = Texture::new(3, 0.005).bake_plane([0.0, 0.0], [0.5, 0.5], 500.0);
        let img = &t.image;
        let (w, h) = (img.width(), img.height());
        let mut flat = 0;
        let mut windows = 0;
        for by in (0..h - 8).step_by(8) {
            for bx in (0..w - 8).step_by(8) {
                let (mut lo, mut hi) = (f32::MAX, f32::MIN);
                for y in by..by + 8 {
                    for x in bx..bx + 8 {
                        let p = img.get(x, y);
                        let l = p[0] + p[1] + p[2];
                        lo = lo.min(l);
                        hi = hi.max(l);
                    }
                }
                windows += 1;
                if hi - lo < 0.06 {
                    flat += 1;
                }
            }
        }
        assert!(
            (flat as f64) < 0.03 * windows as f64,
            "{flat} of {windows} windows flat"
        );
        let mut dominant = [0usize; 3];
        for p in img.pixels() {
            let i = (0..3).max_by(|&a, &b| p[a].total_cmp(&p[b])).unwrap();
            dominant[i] += 1;
        }
        for d in dominant {
            assert!(d > img.pixels().len() / 10, "{dominant:?}");
        }
    }

    #[test]
    fn baked_plane_holds_texel_centre_values() {
        let tex = Texture::new(1, 0.01);
        let t = tex.bake_plane([-0.5, 0.25], [0.4, 0.2], 100.0);
        assert_eq!((t.image.width(), t.image.height()), (40, 20));
        // Texel (3, 5) has its centre at (-0.5 + 3.5 * 0.01, 0.25 + 5.5 * 0.01).
        let (x, y) = (-0.5 + 3.5 * 0.01, 0.25 + 5.5 * 0.01);
        assert_eq!(t.sample(x, y), tex.eval(&[x, y, 0.0]));
        assert_eq!(t.sample(x, y), t.image.get(3, 5));
    }

    #[test]
    fn plane_sampling_is_bilinear_between_texel_centres_and_clamped_outside() {
        let t = Texture::new(5, 0.01).bake_plane([0.0, 0.0], [0.04, 0.03], 100.0);
        let g = |i: usize, j: usize| t.image.get(i, j);
        // Material (0.02, 0.012) is texel coordinate (1.5, 0.7).
        let s = t.sample(0.02, 0.012);
        for ch in 0..3 {
            let top = 0.5 * (g(1, 0)[ch] + g(2, 0)[ch]);
            let bot = 0.5 * (g(1, 1)[ch] + g(2, 1)[ch]);
            let want = top + 0.7 * (bot - top);
            assert!((s[ch] - want).abs() < 1e-5, "{s:?}");
        }
        assert_eq!(t.sample(-1.0, -1.0), g(0, 0));
        assert_eq!(t.sample(1.0, 1.0), g(3, 2));
    }

    #[test]
    fn cube_map_matches_pattern_at_texel_centres() {
        let tex = Texture::new(2, 0.01);
        let cube = tex.bake_cube(0.4, 16);
        // Face -y (3), texel (4, 11): s = 9/32*2-1, t = 23/32*2-1.
        let (s, t): (f64, f64) = (9.0 / 16.0 - 1.0, 23.0 / 16.0 - 1.0);
        let d = [s, -1.0, t];
        let n = (s * s + 1.0 + t * t).sqrt();
        let want = tex.eval(&d.map(|c| c / n * 0.4));
        let got = cube.sample(&d.map(|c| c * 3.0));
        for ch in 0..3 {
            assert!((got[ch] - want[ch]).abs() < 1e-6, "{got:?} {want:?}");
        }
    }
}

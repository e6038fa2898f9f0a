//! Index patches and pixel patches (thesis §6.2.3–6.2.4): for every (triangle, camera) of a
//! *template* frame, the pixels the triangle owns after z-buffering and silhouette erosion, each
//! with its barycentric coordinates on the triangle and its colour. These are what the solver
//! warps into the next frame.
//!
//! A template is any frame whose mesh and images are known: the previous frame (the thesis'
//! "current" frame) and, to stop drift, the first frame of the shot.

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::base::raster::{rasterize, trackable_mask, usable_triangles, IndexBuffer, Window, NONE};
use crate::tracker::warp::{barycentric, source_matrix};
use nalgebra::{Matrix3, Point3};
use rayon::prelude::*;

/// One source pixel: barycentric coordinates on its triangle and its RGB value. Laid out as six
/// `f32` (the GPU path uploads the slice as it is).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct PixelSample {
    pub lambda: [f32; 3],
    pub color: [f32; 3],
}

/// The pixels of one (triangle, camera) of one template: `pixels[start..end]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    pub triangle: u32,
    /// The camera whose image the pixels are warped into.
    pub camera: u16,
    /// The camera the pixels were taken from (the same as `camera` for a template frame's
    /// patch; another one in `align`, which compares cameras with each other).
    pub source: u16,
    /// Weight of the template this patch comes from.
    pub weight: f32,
    /// Whether the pixels come from the shot's first frame (the anchor, and its views lent to
    /// other cameras): under an open shutter they are compared with the frame being solved
    /// smeared along the first frame's motion, not the previous frame's (`smear`).
    pub first: bool,
    pub start: u32,
    pub end: u32,
}

/// Options deciding which pixels are trusted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchOptions {
    /// Pixels closer than this (in pixels, Chebyshev) to a silhouette, the background or an
    /// occluding surface are left out.
    pub margin: usize,
    /// Triangles seen at a grazing angle (cosine below this) or from behind (closed meshes) are
    /// left out.
    pub min_cos: f64,
    /// Whether the surface is two-sided (an open sheet) or has an outside (a closed mesh).
    pub two_sided: bool,
    /// Keep only pixels with even `x + y` (half the pixels, evenly spread).
    pub checkerboard: bool,
    /// Of each patch's pixels (in the image's row order), keep every `stride`-th (1 = all):
    /// the tracker's comparisons between cameras (`--stereo-stride`).
    pub stride: usize,
}

/// The index buffer of `positions` seen through `proj` in a `w`×`h` image, and which of its
/// pixels may be compared (`opts`; over the buffer's window): what every template, and the
/// rig's coverage, start from.
pub(crate) fn trackable_pixels(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    proj: &Projection,
    (w, h): (usize, usize),
    opts: &PatchOptions,
) -> (IndexBuffer, Vec<bool>) {
    let ib = rasterize(positions, triangles, proj, w, h);
    let mask = trackable_in(&ib, positions, triangles, proj, opts);
    (ib, mask)
}

/// Which pixels of `ib` (the index buffer of `positions` seen through `proj`) may be compared
/// (`opts`; over the buffer's window): [`trackable_pixels`] on a buffer already rasterised.
fn trackable_in(
    ib: &IndexBuffer,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    proj: &Projection,
    opts: &PatchOptions,
) -> Vec<bool> {
    let usable = usable_triangles(positions, triangles, proj, opts.two_sided, opts.min_cos);
    trackable_mask(ib, triangles, &usable, opts.margin, opts.checkerboard)
}

/// All patches of a problem, ordered by triangle, with their pixels.
#[derive(Clone, Debug, Default)]
pub struct PatchSet {
    pub patches: Vec<Patch>,
    pub pixels: Vec<PixelSample>,
}

/// One camera's view of a template, ready to be written out as patches: which pixels each
/// triangle owns (counting-sorted by triangle), and each kept triangle's inverse source matrix.
/// Taken apart from the writing so that several cameras, prepared in parallel, are written
/// into one set without a copy ([`PatchSet::from_cameras`]).
pub(crate) struct CameraPatches<'a> {
    /// Where the index buffer lay in the image (the buffer itself is not kept).
    window: Window,
    /// Kept pixels (indices into the index buffer's window) of triangle `t`:
    /// `order[count[t]..count[t + 1]]`.
    count: Vec<u32>,
    order: Vec<u32>,
    /// Per triangle with pixels, its inverse source matrix (`None`: skipped).
    s_inv: Vec<Option<Matrix3<f64>>>,
    image: &'a RgbImage,
    camera: u16,
    weight: f32,
    stride: usize,
    /// Pixels and patches it will write.
    pixels: usize,
    patches: usize,
}

impl<'a> CameraPatches<'a> {
    /// The pixels of `positions` seen through `proj` in `image` that `opts` trusts, for the
    /// triangles `only` accepts (all without it). `buffer`, when given, is that view's index
    /// buffer already rasterised for another use of it (the cameras compared with each other
    /// and the hidden-surface check of the same level and mesh); rasterised here otherwise.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        positions: &[Point3<f64>],
        triangles: &[[u32; 3]],
        proj: &Projection,
        image: &'a RgbImage,
        camera: u16,
        weight: f32,
        opts: &PatchOptions,
        only: Option<&dyn Fn(u32) -> bool>,
        buffer: Option<&IndexBuffer>,
    ) -> Self {
        let made;
        let ib = match buffer {
            Some(b) => b,
            None => {
                made = rasterize(positions, triangles, proj, image.width(), image.height());
                &made
            }
        };
        debug_assert_eq!((ib.width, ib.height), (image.width(), image.height()));
        let mask = trackable_in(ib, positions, triangles, proj, opts);
        let owners = ib.owners();
        // Counting sort of the kept pixels by owner triangle (indices into the index buffer's
        // window, which holds every covered pixel, row-major: the image's order).
        let mut count = vec![0u32; triangles.len() + 1];
        for (i, &m) in mask.iter().enumerate() {
            if m {
                debug_assert!(owners[i] != NONE);
                count[owners[i] as usize + 1] += 1;
            }
        }
        for t in 0..triangles.len() {
            count[t + 1] += count[t];
        }
        let mut order = vec![0u32; count[triangles.len()] as usize];
        let mut next = count.clone();
        for (i, &m) in mask.iter().enumerate() {
            if m {
                let t = owners[i] as usize;
                order[next[t] as usize] = i as u32;
                next[t] += 1;
            }
        }
        let stride = opts.stride.max(1);
        let (mut pixels, mut patches) = (0, 0);
        let s_inv = (0..triangles.len())
            .map(|t| {
                let n = (count[t + 1] - count[t]) as usize;
                if n == 0 || only.is_some_and(|f| !f(t as u32)) {
                    return None;
                }
                let x = triangles[t].map(|v| positions[v as usize]);
                let inv = source_matrix(proj, &x).try_inverse()?;
                pixels += n.div_ceil(stride);
                patches += 1;
                Some(inv)
            })
            .collect();
        CameraPatches {
            window: ib.window,
            count,
            order,
            s_inv,
            image,
            camera,
            weight,
            stride,
            pixels,
            patches,
        }
    }

    /// Marks `covered[t · cameras + camera]` for every triangle `t` this camera has a patch of.
    pub(crate) fn mark_covered(&self, covered: &mut [bool], cameras: usize) {
        for (t, s) in self.s_inv.iter().enumerate() {
            if s.is_some() {
                covered[t * cameras + self.camera as usize] = true;
            }
        }
    }

    /// Writes the patches (pixel ranges from `offset`) and their pixels into `pixels`, which
    /// holds exactly [`CameraPatches::pixels`] of them.
    fn write(&self, offset: u32, pixels: &mut [PixelSample], patches: &mut Vec<Patch>) {
        debug_assert_eq!(pixels.len(), self.pixels);
        let mut k = 0usize;
        for (t, s_inv) in self.s_inv.iter().enumerate() {
            let Some(s_inv) = s_inv else {
                continue;
            };
            let (a, b) = (self.count[t] as usize, self.count[t + 1] as usize);
            let start = k;
            for &pi in self.order[a..b].iter().step_by(self.stride) {
                let (px, py) = self.window.pixel(pi as usize);
                let l = barycentric(s_inv, px as f64, py as f64);
                pixels[k] = PixelSample {
                    lambda: [l[0] as f32, l[1] as f32, l[2] as f32],
                    color: self.image.get(px, py),
                };
                k += 1;
            }
            patches.push(Patch {
                triangle: t as u32,
                camera: self.camera,
                source: self.camera,
                weight: self.weight,
                first: false,
                start: offset + start as u32,
                end: offset + k as u32,
            });
        }
    }
}

impl PatchSet {
    /// Adds the patches of one camera of one template frame (the tests' way; the tracker
    /// writes its cameras at once with [`PatchSet::from_cameras`]).
    #[cfg(test)]
    #[allow(clippy::too_many_arguments)]
    pub fn add_camera(
        &mut self,
        positions: &[Point3<f64>],
        triangles: &[[u32; 3]],
        proj: &Projection,
        image: &RgbImage,
        camera: u16,
        weight: f32,
        opts: &PatchOptions,
        only: Option<&dyn Fn(u32) -> bool>,
    ) {
        let c = CameraPatches::new(
            positions, triangles, proj, image, camera, weight, opts, only, None,
        );
        let offset = self.pixels.len();
        self.pixels
            .resize(offset + c.pixels, PixelSample::default());
        self.patches.reserve(c.patches);
        c.write(offset as u32, &mut self.pixels[offset..], &mut self.patches);
    }

    /// The patches of several cameras, in the order given: what adding each with
    /// [`PatchSet::add_camera`] gives, written in parallel into one allocation.
    pub(crate) fn from_cameras(cameras: &[CameraPatches<'_>]) -> PatchSet {
        let total: usize = cameras.iter().map(|c| c.pixels).sum();
        let mut pixels = vec![PixelSample::default(); total];
        let mut chunks = Vec::with_capacity(cameras.len());
        let (mut rest, mut offset) = (&mut pixels[..], 0u32);
        for c in cameras {
            let (head, tail) = rest.split_at_mut(c.pixels);
            chunks.push((offset, head));
            offset += c.pixels as u32;
            rest = tail;
        }
        let per_camera: Vec<Vec<Patch>> = cameras
            .par_iter()
            .zip(chunks)
            .map(|(c, (offset, chunk))| {
                let mut patches = Vec::with_capacity(c.patches);
                c.write(offset, chunk, &mut patches);
                patches
            })
            .collect();
        PatchSet {
            patches: per_camera.concat(),
            pixels,
        }
    }

    /// The pixels its patches compare (a pixel warped into two cameras counts twice; pixels no
    /// patch lists, not at all).
    pub(crate) fn compared_pixels(&self) -> usize {
        self.patches
            .iter()
            .map(|p| (p.end - p.start) as usize)
            .sum()
    }

    /// Sorts patches by triangle (stable) and returns, for each triangle that has patches, the
    /// range of its patches.
    pub fn by_triangle(&mut self) -> Vec<(u32, std::ops::Range<usize>)> {
        self.patches.sort_by_key(|p| p.triangle);
        let mut out = Vec::new();
        let mut i = 0;
        while i < self.patches.len() {
            let t = self.patches[i].triangle;
            let mut j = i;
            while j < self.patches.len() && self.patches[j].triangle == t {
                j += 1;
            }
            out.push((t, i..j));
            i = j;
        }
        out
    }

    /// Appends patch `p`, whose pixels are `from.pixels[p.start..p.end]`, with a copy of them.
    pub fn push_copy(&mut self, from: &PatchSet, p: Patch) {
        let start = self.pixels.len() as u32;
        self.pixels
            .extend_from_slice(&from.pixels[p.start as usize..p.end as usize]);
        self.patches.push(Patch {
            start,
            end: self.pixels.len() as u32,
            ..p
        });
    }

    /// Keeps the pixels `keep[i][j]` says to keep (pixel `j` of patch `i`), and the patches
    /// with any left; returns how many pixels were dropped. Nothing moves when every pixel is
    /// kept and no patch is empty; otherwise the pixels are moved down in place when the patches' ranges are in
    /// increasing order (as built; a copy when not).
    pub fn retain_pixels(&mut self, keep: &[Vec<bool>]) -> usize {
        debug_assert_eq!(keep.len(), self.patches.len());
        if keep.iter().all(|k| !k.is_empty() && k.iter().all(|&k| k)) {
            return 0;
        }
        let in_order = self.patches.windows(2).all(|w| w[0].end <= w[1].start);
        let mut out = if in_order {
            PatchSet::default()
        } else {
            PatchSet {
                patches: Vec::with_capacity(self.patches.len()),
                pixels: Vec::with_capacity(self.pixels.len()),
            }
        };
        let (mut to, mut kept_patches, mut dropped) = (0usize, 0usize, 0usize);
        for (i, keep) in keep.iter().enumerate() {
            let p = self.patches[i];
            let (a, b) = (p.start as usize, p.end as usize);
            let start = if in_order { to } else { out.pixels.len() };
            for (j, _) in keep.iter().enumerate().filter(|k| *k.1) {
                if in_order {
                    // `to <= a + j`: the ranges are in order, so nothing unread is overwritten.
                    self.pixels[to] = self.pixels[a + j];
                    to += 1;
                } else {
                    out.pixels.push(self.pixels[a + j]);
                }
            }
            let end = if in_order { to } else { out.pixels.len() };
            dropped += (b - a) - (end - start);
            if end > start {
                let q = Patch {
                    start: start as u32,
                    end: end as u32,
                    ..p
                };
                if in_order {
                    self.patches[kept_patches] = q;
                    kept_patches += 1;
                } else {
                    out.patches.push(q);
                }
            }
        }
        if in_order {
            self.pixels.truncate(to);
            self.patches.truncate(kept_patches);
        } else {
            *self = out;
        }
        dropped
    }

    /// `covered[triangle * cameras + camera]`: whether that pair has a patch.
    pub fn coverage(&self, triangles: usize, cameras: usize) -> Vec<bool> {
        let mut c = vec![false; triangles * cameras];
        for p in &self.patches {
            c[p.triangle as usize * cameras + p.camera as usize] = true;
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::{Patch, PatchSet, PixelSample};

    /// Three patches of 5, 0 and 7 pixels, pixel `i` tagged by its colour; the patches' ranges
    /// in the order built, or with the last two swapped (as after sorting by triangle).
    fn set(in_order: bool) -> PatchSet {
        let pixels: Vec<PixelSample> = (0..12)
            .map(|i| PixelSample {
                lambda: [1.0, 0.0, 0.0],
                color: [i as f32, 0.0, 0.0],
            })
            .collect();
        let patch = |triangle, start, end| Patch {
            triangle,
            camera: 0,
            source: 0,
            weight: 1.0,
            first: false,
            start,
            end,
        };
        let mut patches = vec![patch(0, 0, 5), patch(1, 5, 5), patch(2, 5, 12)];
        if !in_order {
            patches.swap(1, 2);
        }
        PatchSet { patches, pixels }
    }

    fn colours(s: &PatchSet) -> Vec<Vec<f32>> {
        s.patches
            .iter()
            .map(|p| {
                s.pixels[p.start as usize..p.end as usize]
                    .iter()
                    .map(|x| x.color[0])
                    .collect()
            })
            .collect()
    }

    #[test]
    fn retaining_pixels_keeps_the_marked_ones_in_order_and_drops_emptied_patches() {
        for in_order in [true, false] {
            let mut s = set(in_order);
            let (a, b) = (vec![true, false, true, false, false], vec![false; 7]);
            let keep = if in_order {
                vec![a, vec![], b]
            } else {
                vec![a, b, vec![]]
            };
            assert_eq!(s.retain_pixels(&keep), 10, "in order: {in_order}");
            assert_eq!(colours(&s), vec![vec![0.0, 2.0]], "in order: {in_order}");
            let mut s = set(in_order);
            let c = vec![false, true, true, false, true, false, true];
            let keep = if in_order {
                vec![vec![true; 5], vec![], c]
            } else {
                vec![vec![true; 5], c, vec![]]
            };
            assert_eq!(s.retain_pixels(&keep), 3, "in order: {in_order}");
            assert_eq!(
                colours(&s),
                vec![vec![0.0, 1.0, 2.0, 3.0, 4.0], vec![6.0, 7.0, 9.0, 11.0]],
                "in order: {in_order}"
            );
            assert_eq!(s.pixels.len(), 9);
            // Every pixel kept: only the empty patch goes.
            let mut s = set(in_order);
            let before = colours(&s);
            let keep: Vec<Vec<bool>> = s
                .patches
                .iter()
                .map(|p| vec![true; (p.end - p.start) as usize])
                .collect();
            assert_eq!(s.retain_pixels(&keep), 0);
            let mut expected = before.clone();
            expected.retain(|c| !c.is_empty());
            assert_eq!(colours(&s), expected, "in order: {in_order}");
            assert_eq!(s.pixels.len(), 12);
            let s = set(in_order);
            let keep: Vec<Vec<bool>> = s
                .patches
                .iter()
                .filter(|p| p.end > p.start)
                .map(|p| vec![true; (p.end - p.start) as usize])
                .collect();
            let mut s = PatchSet {
                patches: s.patches.into_iter().filter(|p| p.end > p.start).collect(),
                pixels: s.pixels,
            };
            let before = s.clone();
            assert_eq!(s.retain_pixels(&keep), 0);
            assert_eq!((s.patches, s.pixels), (before.patches, before.pixels));
        }
    }
}

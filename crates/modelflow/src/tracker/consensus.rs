//! Template pixels that the other cameras contradict (our addition to the thesis, for occluders
//! and highlights). A template pixel is meant to be the colour of one surface point; every other
//! camera that sees the same triangle sees that point too, through the triangle's plane (the
//! point `Σ λ_k·X_k` of its barycentric coordinates, projected: the cross-camera warp of
//! `align`). Where an occluder stands in front of the surface in one camera (a rod, a hand) or a
//! highlight sits on it, that camera's pixel disagrees with what the others see there, while the
//! surface's own texture agrees. Such a pixel would carry the occluder or the highlight into the
//! next frame (or, from the first frame's template, into every frame) and pull the mesh with it,
//! so it is left out of the template.
//!
//! The colours are compared up to gains: per ordered pair of cameras one per channel (exposure,
//! white balance), fitted on every fourth pixel of the template (sparser with more than four
//! cameras: [`stride`]), times one per (triangle, camera, other camera) within [2/3, 3/2] (a
//! glossy surface is brighter from one side; the bound keeps an occluder's flat colour from
//! being explained away), fitted twice, the second time without the pixels the first fit
//! rejected. A pixel is contradicted by a camera when its RGB residual exceeds `k` times the
//! median residual (of the same pixels; at least `min`), widened by `px` pixels of misalignment
//! times the image gradient there (the mesh is only as good as the last solve). It is dropped
//! when *every* other camera that sees its triangle contradicts it, and a patch most of whose
//! checked pixels are dropped is dropped whole (what agrees in it agrees by chance); a pixel no
//! other camera can check is kept. The cameras are asked one at a time, no further once every
//! pixel of the patch has agreed with one of them (the verdict cannot change then).
//! Hand-written: the tracker's own data on its own warps. Deterministic whatever the thread
//! count.

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::base::raster::{facing_cosines, project_triangle, WELL_FACING};
use crate::tracker::occluder::{Ahead, StillMarks};
use crate::tracker::patch::{Patch, PatchSet, PixelSample};
use nalgebra::Point3;
use rayon::prelude::*;

/// How disagreement between cameras is judged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ConsensusOptions {
    /// Threshold as a multiple of the median cross-camera residual.
    pub k: f64,
    /// Smallest threshold (image units).
    pub min: f64,
    /// Misalignment (pixels of the level) a pixel may have and still agree.
    pub px: f64,
}

/// What the check did to one template.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct ConsensusStats {
    /// Pixels dropped as contradicted.
    pub dropped: usize,
    /// Pixels dropped because their way into the frame being solved crosses a still occluder
    /// (`occluder`; only when asked, with [`drop_contradicted_ahead`]).
    pub near_still: usize,
    /// Per camera (the patches' `source`), of its own pixels that a camera seeing their
    /// triangle alike ([`Footprint::alike`]) checked, those that every such camera contradicted: what
    /// tells one camera's disagreement with the others from the whole rig's (`health`'s
    /// cameras that disagree). Empty when nothing was checked (one camera, no patches).
    pub by_camera: Vec<CameraShare>,
}

/// One camera's part of a template's cross-camera check, as the cameras that see the surface as
/// it does judge it ([`Footprint::alike`]). A camera that sees a triangle nearly edge-on, or
/// much more obliquely than another, contradicts much of what the other sees however well both
/// are calibrated (its pixels blur or mix the surface with what lies beyond the outline, and the
/// mesh's own error moves where they fall a long way): an object turning in front of the rig
/// brings such views and takes them away again, frame after frame, and a share counted over
/// them rose and fell with the turn by as much as a knocked camera's.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct CameraShare {
    /// Its pixels that every camera seeing their triangle alike contradicted.
    pub dropped: usize,
    /// Its pixels that a camera seeing their triangle alike checked.
    pub taken: usize,
}

impl CameraShare {
    /// `dropped` as a share of `taken`; `None` when none was checked so (left out, blank, out of
    /// view, or seen alike by no other camera): not measured.
    pub fn share(&self) -> Option<f64> {
        (self.taken > 0).then(|| self.dropped as f64 / self.taken as f64)
    }
}

/// The statistics (pair gains, median residual) are taken on every `stride`-th pixel of each
/// patch, sampled in every other camera that sees its triangle: every 4th with up to four
/// cameras, sparser with more, so that they sample about three of every four source pixels'
/// worth whatever the camera count (each pixel is sampled once per other camera; with eight
/// cameras at 4K the statistics' sampling had become most of a template's building, and a
/// ratio of sums over tens of thousands of samples per camera pair needs no more).
fn stride(cameras: usize) -> usize {
    (4 * cameras.saturating_sub(1)).div_ceil(3).max(4)
}

/// Range of the per-patch gain on top of the pair's.
const PATCH_GAIN: f64 = 1.5;

/// Drops from `set` the pixels every other camera contradicts. `positions` is the template's
/// mesh, `projections[c]` and `images[c]` camera `c`'s at the template's frame and the set's
/// level (the patches' `source` indexes them). With `ahead`, also the pixels whose way into
/// the frame being solved crosses an occluder that stands still there (`occluder`, judged from
/// this check's verdict and limit), and the marks it found, for the anchor.
#[allow(clippy::too_many_arguments)]
pub(crate) fn drop_contradicted_ahead(
    set: &mut PatchSet,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    projections: &[Projection],
    images: &[&RgbImage],
    opts: &ConsensusOptions,
    ahead: Option<&Ahead>,
) -> (ConsensusStats, Option<StillMarks>) {
    drop_contradicted_asking(
        set,
        positions,
        triangles,
        projections,
        images,
        opts,
        false,
        ahead,
    )
}

/// [`drop_contradicted_ahead`]; `ask_all` asks every other camera about every pixel, the
/// verdict's early end left out (tests: what it must give the same result as).
#[allow(clippy::too_many_arguments)]
pub(crate) fn drop_contradicted_asking(
    set: &mut PatchSet,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    projections: &[Projection],
    images: &[&RgbImage],
    opts: &ConsensusOptions,
    ask_all: bool,
    ahead: Option<&Ahead>,
) -> (ConsensusStats, Option<StillMarks>) {
    let ncam = projections.len();
    if ncam < 2 || set.patches.is_empty() {
        return (ConsensusStats::default(), None);
    }
    let covered = set.coverage(triangles.len(), ncam);
    let footprints: Vec<Footprint> = projections
        .par_iter()
        .map(|p| Footprint {
            facing: facing_cosines(positions, triangles, p),
            area: projected_areas(positions, triangles, p),
        })
        .collect();
    let view = View {
        footprints: &footprints,
        stride: stride(ncam),
        pixels: &set.pixels,
        positions,
        triangles,
        projections,
        images,
        covered: &covered,
    };
    let patches = &set.patches;
    let limit = |median: f64| Limit {
        d2: ((opts.k * median).max(opts.min)).powi(2) as f32,
        tol2: (opts.px * opts.px) as f32,
    };
    // The statistics twice: the second time without what the first rejected. Both rounds read
    // the same samples (only the gains applied to them differ), so they are taken once.
    let sampled = view.sample_strided(patches);
    let gains = view.pair_gains(patches, &sampled, None);
    let first = limit(view.median_residual(patches, &sampled, &gains));
    let gains = view.pair_gains(patches, &sampled, Some((&gains, &first)));
    let limit = limit(view.median_residual(patches, &sampled, &gains));
    let verdicts: Vec<Verdict> = patches
        .par_iter()
        .map_init(Scratch::default, |scratch, p| {
            view.verdict(p, &gains, &limit, scratch, ask_all, ahead.is_some())
        })
        .collect();
    // Counted before the still occluders' pixels are left out: those are not contradicted.
    let mut by_camera = vec![CameraShare::default(); ncam];
    for (p, v) in patches.iter().zip(&verdicts) {
        let c = &mut by_camera[p.source as usize];
        c.taken += v.alike.taken;
        c.dropped += v.alike.dropped;
    }
    let (mut keep, contradicted): (Vec<Vec<bool>>, Vec<Vec<bool>>) = verdicts
        .into_iter()
        .map(|v| (v.keep, v.contradicted))
        .unzip();
    let marks = ahead.and_then(|a| a.still_marks(set, &contradicted, &limit));
    let near_still = match (ahead, &marks) {
        (Some(a), Some(m)) => m.leave_out(set, &mut keep, &a.way),
        _ => 0,
    };
    let all = set.retain_pixels(&keep);
    (
        ConsensusStats {
            dropped: all - near_still,
            near_still,
            by_camera,
        },
        marks,
    )
}

/// A residual's limit: `d2 + tol2·|∇|²` on its squared RGB size.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Limit {
    pub d2: f32,
    pub tol2: f32,
}

impl Limit {
    fn admits(&self, e2: f32, g2: f32) -> bool {
        e2 <= self.d2 + self.tol2 * g2
    }

    /// Whether template pixel `a` matches the bilinear sample `b` (`RgbImage::sample_exact`'s
    /// layout) of the same camera, no gain between them: what `occluder` asks of the next frame.
    pub(crate) fn matches(&self, a: &PixelSample, b: &[f32; 9]) -> bool {
        let seen = Seen::new(b, &[1.0; 3]);
        self.admits(residual2(a, &seen, 1.0), seen.g2)
    }
}

/// One other camera's sample of a template pixel's surface point: its colour times the pair's
/// gains, and the squared gradient norm summed over channels (same gains).
#[derive(Clone, Copy)]
struct Seen {
    b: [f32; 3],
    g2: f32,
}

impl Seen {
    /// A bilinear sample (`RgbImage::sample_exact`'s layout) under the pair's gains `g`.
    fn new(b: &[f32; 9], g: &[f32; 3]) -> Seen {
        let mut g2 = 0.0;
        for ch in 0..3 {
            let (gx, gy) = (g[ch] * b[3 + ch], g[ch] * b[6 + ch]);
            g2 += gx * gx + gy * gy;
        }
        Seen {
            b: [0, 1, 2].map(|ch| g[ch] * b[ch]),
            g2,
        }
    }
}

/// The samples the statistics are taken on: per patch, `[j·others + slot]` for its
/// `j·stride`-th pixel in the `slot`-th other camera (`None`: not covered there, or outside
/// that camera's image). Not kept past `STRIDED_BYTES_PER_PIXEL` per pixel of the cameras'
/// images: the statistics then sample the images again in each of their four passes, with the
/// same result.
struct Strided {
    per_patch: Option<Vec<Vec<Option<[f32; 9]>>>>,
}

impl Strided {
    fn patch(&self, k: usize) -> Option<&[Option<[f32; 9]>]> {
        self.per_patch.as_ref().map(|v| &v[k][..])
    }
}

/// Patches per chunk of the pair gains' fixed-order sums (also how a chunk's patches are found
/// among the kept samples).
const PAIR_CHUNK: usize = 256;

/// The most memory the statistics' samples may take, in bytes per pixel of the cameras' images
/// at the level checked. Since the stride grows with the cameras ([`stride`]), the samples of
/// patches larger than the stride take at most about 15 bytes per image pixel at full
/// resolution (a template keeps every other pixel it covers, each sample is 40 bytes) and 30 at
/// the coarser levels, whatever the camera count; a patch smaller than the stride still gives
/// one sample per other camera (a dense mesh at a coarse level), hence the margin. Within the
/// 100 bytes per pixel and camera that `--max-memory` reserves. (A fixed 256 MiB had left eight
/// cameras at 4K sampling again in every pass: 2.6 s of a 16 s frame.)
const STRIDED_BYTES_PER_PIXEL: usize = 48;

/// The template's patches' pixels and mesh, and the other cameras' views of the same frame.
struct View<'a> {
    pixels: &'a [PixelSample],
    positions: &'a [Point3<f64>],
    triangles: &'a [[u32; 3]],
    projections: &'a [Projection],
    images: &'a [&'a RgbImage],
    covered: &'a [bool],
    /// Per camera, how it sees each triangle.
    footprints: &'a [Footprint],
    /// The statistics' stride ([`stride`]).
    stride: usize,
}

impl View<'_> {
    /// Every `stride`-th pixel of `p` as each other camera that sees its triangle samples it:
    /// `f(pixel index, its colour, the sample, other camera, slot)`; `None` where the point
    /// falls outside that camera's image.
    fn each_sample(
        &self,
        p: &Patch,
        stride: usize,
        mut f: impl FnMut(usize, [f32; 3], Option<[f32; 9]>, usize, usize),
    ) {
        let src = p.source as usize;
        let ncam = self.projections.len();
        for (slot, other) in (0..ncam).filter(|&c| c != src).enumerate() {
            self.each_sample_in(p, stride, other, |i, c, smp| f(i, c, smp, other, slot));
        }
    }

    /// [`View::each_sample`] in one other camera: nothing when it does not see the triangle.
    fn each_sample_in(
        &self,
        p: &Patch,
        stride: usize,
        other: usize,
        mut f: impl FnMut(usize, [f32; 3], Option<[f32; 9]>),
    ) {
        let ncam = self.projections.len();
        let t = p.triangle as usize;
        if !self.covered[t * ncam + other] {
            return;
        }
        let x = self.triangles[t].map(|v| self.positions[v as usize]);
        let px = &self.pixels[p.start as usize..p.end as usize];
        let proj = &self.projections[other];
        let img = self.images[other];
        for (i, s) in px.iter().enumerate().step_by(stride) {
            let l = s.lambda;
            let pt = Point3::from(
                x[0].coords * l[0] as f64 + x[1].coords * l[1] as f64 + x[2].coords * l[2] as f64,
            );
            let smp = proj.project(&pt).and_then(|q| img.sample_exact(q.x, q.y));
            f(i, s.color, smp);
        }
    }

    /// Per ordered camera pair `(source, other)` (index `source·n + other`), the per-channel gain
    /// `Σ a·b / Σ b²` over every `stride`-th pixel both see; with `first` (earlier gains and a
    /// limit), only over the pixels that fit within the limit under those gains.
    fn pair_gains(
        &self,
        patches: &[Patch],
        sampled: &Strided,
        first: Option<(&[[f32; 3]], &Limit)>,
    ) -> Vec<[f32; 3]> {
        let ncam = self.projections.len();
        let others = ncam - 1;
        let ones = vec![[1.0f32; 3]; ncam * ncam];
        // Summed in fixed chunks, then in order: the same sums whatever the thread count.
        let chunks: Vec<Vec<[f64; 6]>> = patches
            .par_chunks(PAIR_CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                let mut out = vec![[0.0; 6]; ncam * ncam];
                let mut buf = Vec::new();
                for (k, p) in chunk.iter().enumerate() {
                    let px = &self.pixels[p.start as usize..p.end as usize];
                    let src = p.source as usize;
                    let (g, limit) = match first {
                        Some((g, l)) => (g, Some(l)),
                        None => (&ones[..], None),
                    };
                    self.gather_strided(p, sampled.patch(c * PAIR_CHUNK + k), g, &mut buf);
                    for (slot, other) in (0..ncam).filter(|&c| c != src).enumerate() {
                        let s = limit.map(|_| own_gain(px, &buf, others, slot, self.stride, None));
                        let gi = &g[src * ncam + other];
                        for (j, a) in px.iter().step_by(self.stride).enumerate() {
                            let Some(seen) = buf[j * others + slot] else {
                                continue;
                            };
                            if let (Some(l), Some(s)) = (limit, s) {
                                if residual2(a, &seen, s) > l.d2 + l.tol2 * seen.g2 {
                                    continue;
                                }
                            }
                            let o = &mut out[src * ncam + other];
                            for ch in 0..3 {
                                // Undo the gains the samples were gathered with.
                                let b = (seen.b[ch] / gi[ch]) as f64;
                                o[ch] += a.color[ch] as f64 * b;
                                o[3 + ch] += b * b;
                            }
                        }
                    }
                }
                out
            })
            .collect();
        let mut pair = vec![[0.0f64; 6]; ncam * ncam];
        for c in &chunks {
            for (x, y) in pair.iter_mut().zip(c) {
                for k in 0..6 {
                    x[k] += y[k];
                }
            }
        }
        pair.iter()
            .map(|s| {
                [0, 1, 2].map(|ch| {
                    if s[3 + ch] > 1e-12 {
                        (s[ch] / s[3 + ch]).clamp(0.25, 4.0) as f32
                    } else {
                        1.0
                    }
                })
            })
            .collect()
    }

    /// The median RGB residual over every `stride`-th pixel and the other cameras that see it,
    /// each patch with its own gain fitted on those pixels.
    fn median_residual(&self, patches: &[Patch], sampled: &Strided, gains: &[[f32; 3]]) -> f64 {
        // Each worker appends to one vector of its own (the median of the multiset does not
        // depend on the order): a vector per patch, flattened, cost more than the residuals.
        let mut all: Vec<f32> = patches
            .par_iter()
            .enumerate()
            .fold(
                || (Vec::new(), Vec::new()),
                |(mut buf, mut e), (k, p)| {
                    let others = self.projections.len() - 1;
                    let px = &self.pixels[p.start as usize..p.end as usize];
                    self.gather_strided(p, sampled.patch(k), gains, &mut buf);
                    for slot in 0..others {
                        let s = own_gain(px, &buf, others, slot, self.stride, None);
                        for (j, a) in px.iter().step_by(self.stride).enumerate() {
                            if let Some(seen) = buf[j * others + slot] {
                                e.push(residual2(a, &seen, s).sqrt());
                            }
                        }
                    }
                    (buf, e)
                },
            )
            .map(|(_, e)| e)
            .reduce(Vec::new, |mut a, b| {
                a.extend(b);
                a
            });
        if all.is_empty() {
            return 0.0;
        }
        let mid = all.len() / 2;
        let (_, m, _) = all.select_nth_unstable_by(mid, f32::total_cmp);
        *m as f64
    }

    /// Fills `buf[j·others + slot]` with what the other cameras see of `p`'s every `stride`-th
    /// pixel, the `j`-th of them (`None` where a camera does not see it).
    fn gather(&self, p: &Patch, gains: &[[f32; 3]], stride: usize, buf: &mut Vec<Option<Seen>>) {
        let ncam = self.projections.len();
        let others = ncam - 1;
        let n = (p.end - p.start) as usize;
        let src = p.source as usize;
        buf.clear();
        buf.resize(n.div_ceil(stride) * others, None);
        self.each_sample(p, stride, |i, _, smp, other, slot| {
            if let Some(b) = smp {
                buf[(i / stride) * others + slot] = Some(Seen::new(&b, &gains[src * ncam + other]));
            }
        });
    }

    /// Every `stride`-th pixel of every patch as the other cameras sample it, in `patches`'
    /// order (what [`View::gather_strided`] reads back).
    fn sample_strided(&self, patches: &[Patch]) -> Strided {
        let others = self.projections.len() - 1;
        let entries: usize = patches
            .iter()
            .map(|p| ((p.end - p.start) as usize).div_ceil(self.stride) * others)
            .sum();
        let image_pixels: usize = self.images.iter().map(|i| i.width() * i.height()).sum();
        if entries * std::mem::size_of::<Option<[f32; 9]>>()
            > STRIDED_BYTES_PER_PIXEL * image_pixels
        {
            return Strided { per_patch: None };
        }
        let per_patch: Vec<Vec<Option<[f32; 9]>>> = patches
            .par_iter()
            .map(|p| {
                let n = (p.end - p.start) as usize;
                let mut out = vec![None; n.div_ceil(self.stride) * others];
                self.each_sample(p, self.stride, |i, _, smp, _, slot| {
                    out[(i / self.stride) * others + slot] = smp;
                });
                out
            })
            .collect();
        Strided {
            per_patch: Some(per_patch),
        }
    }

    /// [`View::gather`] with the statistics' stride, from the samples `sample_strided` took of `p`.
    fn gather_strided(
        &self,
        p: &Patch,
        samples: Option<&[Option<[f32; 9]>]>,
        gains: &[[f32; 3]],
        buf: &mut Vec<Option<Seen>>,
    ) {
        let Some(samples) = samples else {
            return self.gather(p, gains, self.stride, buf);
        };
        let ncam = self.projections.len();
        let others = ncam - 1;
        let n = (p.end - p.start) as usize;
        let src = p.source as usize;
        buf.clear();
        buf.resize(n.div_ceil(self.stride) * others, None);
        for (slot, other) in (0..ncam).filter(|&c| c != src).enumerate() {
            let g = &gains[src * ncam + other];
            for j in 0..n.div_ceil(self.stride) {
                if let Some(b) = &samples[j * others + slot] {
                    buf[j * others + slot] = Some(Seen::new(b, g));
                }
            }
        }
    }

    /// Which of `p`'s pixels to keep, and, with `contradictions`, which every camera that checked
    /// it contradicted (the pixel's own verdict, whatever its patch's: what `occluder` marks
    /// from; empty without). The other cameras are asked one at a time, and no
    /// further once every pixel has agreed with one of them: a pixel is dropped only when every
    /// camera that checks it contradicts it, and a patch dropped whole has most of its checked
    /// pixels contradicted, so the cameras not yet asked cannot change the verdict then (on
    /// footage without occluders most patches are settled by the first camera asked, which
    /// matters with many cameras). `ask_all` asks them all anyway (tests). The cameras that see
    /// the triangle as the patch's camera does ([`Footprint::alike`]) are asked first, in camera
    /// order, then the rest: the verdict does not depend on the order, and what those cameras
    /// alone say of each pixel (the camera's share, [`CameraShare`]) is then settled before any
    /// early end.
    fn verdict(
        &self,
        p: &Patch,
        gains: &[[f32; 3]],
        limit: &Limit,
        scratch: &mut Scratch,
        ask_all: bool,
        contradictions: bool,
    ) -> Verdict {
        let Scratch { seen: buf, marks } = scratch;
        let ncam = self.projections.len();
        let n = (p.end - p.start) as usize;
        let src = p.source as usize;
        let t = p.triangle as usize;
        let px = &self.pixels[p.start as usize..p.end as usize];
        let sees_alike = |c: usize| self.footprints[src].alike(&self.footprints[c], t);
        let order = (0..ncam)
            .filter(|&c| c != src && sees_alike(c))
            .chain((0..ncam).filter(|&c| c != src && !sees_alike(c)));
        // Per pixel: checked by some camera, agreed with by one, and the same by the cameras
        // that see the triangle alike (bits; reused from patch to patch).
        const CHECKED: u8 = 1;
        const AGREED: u8 = 2;
        const CHECKED_ALIKE: u8 = 4;
        const AGREED_ALIKE: u8 = 8;
        marks.clear();
        marks.resize(n, 0);
        let mut open = n;
        for other in order {
            if open == 0 && !ask_all {
                break;
            }
            // What this camera sees of every pixel (`buf[i]`, `None` where it does not).
            buf.clear();
            buf.resize(n, None);
            let g = &gains[src * ncam + other];
            self.each_sample_in(p, 1, other, |i, _, smp| {
                if let Some(b) = smp {
                    buf[i] = Some(Seen::new(&b, g));
                }
            });
            // Fitted on all pixels, then again on those that fit.
            let s0 = own_gain(px, buf, 1, 0, 1, None);
            let fits = |i: usize, s: f32| {
                buf[i].is_some_and(|seen| limit.admits(residual2(&px[i], &seen, s), seen.g2))
            };
            let s = own_gain(px, buf, 1, 0, 1, Some(&|i| fits(i, s0)));
            let alike = if sees_alike(other) { CHECKED_ALIKE } else { 0 };
            for (i, m) in marks.iter_mut().enumerate() {
                if buf[i].is_some() {
                    let fit = fits(i, s);
                    *m |= CHECKED | alike;
                    if fit {
                        if *m & AGREED == 0 {
                            open -= 1;
                        }
                        *m |= AGREED | if alike != 0 { AGREED_ALIKE } else { 0 };
                    }
                }
            }
        }
        let count = |mask: u8, want: u8| marks.iter().filter(|&&m| m & mask == want).count();
        let nc = count(CHECKED, CHECKED);
        let nd = count(CHECKED | AGREED, CHECKED);
        let whole = 2 * nd > nc;
        let keep = marks
            .iter()
            .map(|&m| m & CHECKED == 0 || (m & AGREED != 0 && !whole))
            .collect();
        let contradicted = if contradictions {
            marks
                .iter()
                .map(|&m| m & (CHECKED | AGREED) == CHECKED)
                .collect()
        } else {
            Vec::new()
        };
        Verdict {
            keep,
            contradicted,
            alike: CameraShare {
                taken: count(CHECKED_ALIKE, CHECKED_ALIKE),
                dropped: count(CHECKED_ALIKE | AGREED_ALIKE, CHECKED_ALIKE),
            },
        }
    }
}

/// How one camera sees each triangle of the template's mesh.
struct Footprint {
    /// The cosine of its facing the camera ([`facing_cosines`]).
    facing: Vec<f64>,
    /// Its projection's area in pixels of the level (NaN when a corner is behind the camera or
    /// the projection is degenerate).
    area: Vec<f64>,
}

/// How much larger one camera's image of a triangle may be than another's for the two to see
/// its surface at comparable detail: each pixel of one spans at most three of the other's.
const AREA_RATIO: f64 = 3.0;

impl Footprint {
    /// Whether `other` sees triangle `t` as this camera does: the same side of it, both facing
    /// it well ([`WELL_FACING`]), and at comparable detail ([`AREA_RATIO`]). Where a camera sees
    /// the surface much more obliquely or from much further than the other, its pixels blur
    /// what the other's show sharp, and the mesh's own error moves them further: its checks
    /// contradict the other's pixels however well both are calibrated.
    fn alike(&self, other: &Footprint, t: usize) -> bool {
        let (a, b) = (self.facing[t], other.facing[t]);
        let r = other.area[t] / self.area[t];
        a * b > 0.0
            && a.abs() >= WELL_FACING
            && b.abs() >= WELL_FACING
            && r <= AREA_RATIO
            && r * AREA_RATIO >= 1.0
    }
}

/// Per triangle, the area of its projection through `proj` (`raster::project_triangle`'s; NaN
/// when a corner is behind the camera or the projection is degenerate).
fn projected_areas(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    proj: &Projection,
) -> Vec<f64> {
    triangles
        .iter()
        .map(|t| project_triangle(positions, t, proj).map_or(f64::NAN, |p| p.pixel_area()))
        .collect()
}

/// What [`View::verdict`] writes per pixel, reused from patch to patch: what the camera being
/// asked sees of each pixel, and the pixel's marks.
#[derive(Default)]
struct Scratch {
    seen: Vec<Option<Seen>>,
    marks: Vec<u8>,
}

/// One patch's verdict ([`View::verdict`]).
struct Verdict {
    /// Per pixel, whether it is kept.
    keep: Vec<bool>,
    /// Per pixel, whether every camera that checked it contradicted it (empty unless asked).
    contradicted: Vec<bool>,
    /// What the cameras seeing the triangle alike said of its pixels.
    alike: CameraShare,
}

/// The patch's own gain on top of the pair's for one other camera (`slot`), over its every
/// `stride`-th pixel (as [`View::gather`] fills `buf`) that `use_pixel` accepts (given the
/// pixel's index; all with `None`), within `[1/PATCH_GAIN, PATCH_GAIN]`.
fn own_gain(
    px: &[PixelSample],
    buf: &[Option<Seen>],
    others: usize,
    slot: usize,
    stride: usize,
    use_pixel: Option<&dyn Fn(usize) -> bool>,
) -> f32 {
    let (mut ab, mut bb) = (0.0f64, 0.0f64);
    for (j, a) in px.iter().step_by(stride).enumerate() {
        let Some(seen) = buf[j * others + slot] else {
            continue;
        };
        if use_pixel.is_none_or(|f| f(j * stride)) {
            for ch in 0..3 {
                ab += a.color[ch] as f64 * seen.b[ch] as f64;
                bb += seen.b[ch] as f64 * seen.b[ch] as f64;
            }
        }
    }
    if bb > 1e-12 {
        (ab / bb).clamp(1.0 / PATCH_GAIN, PATCH_GAIN) as f32
    } else {
        1.0
    }
}

/// Squared RGB residual of a template pixel against another camera's sample times gain `s`.
fn residual2(a: &PixelSample, seen: &Seen, s: f32) -> f32 {
    let mut e2 = 0.0;
    for ch in 0..3 {
        let r = a.color[ch] - s * seen.b[ch];
        e2 += r * r;
    }
    e2
}

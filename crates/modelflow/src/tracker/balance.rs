//! Each camera's colour balance against its first frame: a camera whose white balance drifts
//! (auto white balance, a light whose colour changes for one camera) shows the same surface in
//! other colours as the shot goes on, which no brightness gain per (triangle, camera) can undo
//! (a gain scales the three channels alike), and the first frame's template then pulls the mesh
//! wherever the colour change looks like motion. After each frame is solved, the first frame's
//! pixels are carried by the solution into that frame's image and each camera's change of
//! colour balance is read from them: per (triangle, camera) patch, the change of its mean
//! chromaticity (each channel's share of the patch's mean colour), then the pixel-weighted
//! median over the camera's patches, so that a highlight or an occluder over a minority of the
//! surface does not count. A first-frame pixel is read only where the frame's mesh shows its
//! triangle in that camera (z-buffered): a side that turned away or behind another part of the
//! surface would read the colours of whatever is in front of it. The next frame's images are
//! divided by the balance before they are compared, so that every comparison (with the
//! previous frame, with the first, between cameras) is made in the colours the camera had at
//! the first frame (docs/tracker.md, "Colour balance").
//!
//! Written by hand: it is the tracker's own use of its templates.

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::base::raster::{rasterize, usable_triangles, IndexBuffer, NONE, WELL_FACING};
use crate::tracker::patch::PatchSet;
use crate::tracker::pyramid::Pyramid;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// Pixels summed per read: a patch's, or consecutive small patches' together (a mean over
/// fewer is noise).
const GROUP: usize = 32;
/// A camera whose first-frame patches still in view cover fewer pixels than this keeps its
/// balance: too little of the surface to read a colour change from.
const MIN_TOTAL: usize = 400;
/// Of a patch of at least `GROUP · STEP` pixels only every `STEP`-th is read: a mean needs few.
const STEP: usize = 4;
/// A channel whose patch mean is below this (in either frame) says nothing about its balance
/// (a dark or saturated-away channel: a ratio of noise).
const MIN_MEAN: f64 = 0.02;
/// Rec. 709 luminance weights: the balance is normalised to keep luminance, which the
/// per-patch gains follow.
const LUMA: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// The change of each camera's colour balance (per channel, luminance kept) that carries the
/// first frame's colours (`anchor`, its finest-level patches) to `images` (the frame's
/// finest-level images, already divided by the balance so far) where `positions` (the frame's
/// solution) puts them: `None` for a camera `skip`ped, or with too little of the first frame's
/// surface in view to read it from. A pixel is read only where the solution, rasterised into
/// the camera, shows its triangle or one touching it (the nearest pixel centre's owner): a
/// part of the surface that turned away, or behind another part, is not what the camera
/// shows there (an open surface's back, which no facing test leaves out, read the front's
/// colours as a change of balance once an object had turned far enough: the `synth` irregular
/// preset turned 4° a frame read up to 80 % more blue in one camera and ended 3 % off).
///
/// Also returns, per camera read, that index buffer: the next frame's finest template views the
/// same mesh through the same camera and takes it rather than rasterising it again.
pub(crate) fn change(
    anchor: &PatchSet,
    triangles: &[[u32; 3]],
    positions: &[Point3<f64>],
    projections: &[Projection],
    images: &[&RgbImage],
    skip: &[bool],
    two_sided: bool,
) -> (Vec<Option<[f64; 3]>>, Vec<Option<IndexBuffer>>) {
    // Per camera: (ratio per channel, pixels read) of each group read, and the group being
    // summed: consecutive patches (neighbouring triangles, mostly) until it holds `GROUP`
    // pixels, so that small triangles count together and a large one alone.
    let ncam = projections.len();
    // Per camera read: the solution's view (which triangle each pixel shows) and which
    // triangles face it, for a closed surface its outside, more than edge-on.
    let views: Vec<Option<(IndexBuffer, Vec<bool>)>> = (0..ncam)
        .into_par_iter()
        .map(|c| {
            (!skip.get(c).copied().unwrap_or(true)).then(|| {
                let proj = &projections[c];
                let (w, h) = (images[c].width(), images[c].height());
                (
                    rasterize(positions, triangles, proj, w, h),
                    usable_triangles(positions, triangles, proj, two_sided, WELL_FACING),
                )
            })
        })
        .collect();
    let mut reads: Vec<Vec<([f64; 3], usize)>> = vec![Vec::new(); ncam];
    let mut sums = vec![([0.0f64; 3], [0.0f64; 3], 0usize); ncam];
    let flush = |(a, b, n): &mut ([f64; 3], [f64; 3], usize), out: &mut Vec<([f64; 3], usize)>| {
        let (sa, sb) = (a.iter().sum::<f64>(), b.iter().sum::<f64>());
        let enough = |x: &[f64; 3]| x.iter().all(|v| *v >= MIN_MEAN * *n as f64);
        if *n > 0 && enough(a) && enough(b) {
            out.push((std::array::from_fn(|k| (b[k] / sb) / (a[k] / sa)), *n));
        }
        *a = [0.0; 3];
        *b = [0.0; 3];
        *n = 0;
    };
    for p in &anchor.patches {
        let c = p.camera as usize;
        if p.source != p.camera || skip.get(c).copied().unwrap_or(true) {
            continue;
        }
        let pixels = &anchor.pixels[p.start as usize..p.end as usize];
        let step = if pixels.len() >= GROUP * STEP {
            STEP
        } else {
            1
        };
        let t = triangles[p.triangle as usize];
        let proj = &projections[c];
        let y: [Vector3<f64>; 3] =
            std::array::from_fn(|i| proj.project_h(&positions[t[i] as usize]));
        // In front of the camera, and for a closed surface its outside facing it (the back,
        // hidden behind the front, would read the front's colours); either side of an open
        // one. Not seen edge-on: there a pixel mixes the surface with what lies beyond it.
        let Some((view, usable)) = &views[c] else {
            continue;
        };
        if y.iter().any(|v| v.z <= 0.0) || !usable[p.triangle as usize] {
            continue;
        }
        let img = images[c];
        // What the camera shows at a pixel centre is this triangle's surface when the
        // triangle, or one sharing a corner with it (the point lies near its edge), owns it.
        let shown = |x: f64, y: f64| {
            if !(x >= 0.0 && y >= 0.0) {
                return false;
            }
            let o = view.owner_at(x.round() as usize, y.round() as usize);
            o == p.triangle || (o != NONE && triangles[o as usize].iter().any(|v| t.contains(v)))
        };
        let (a, b, n) = &mut sums[c];
        for s in pixels.iter().step_by(step) {
            let l = s.lambda;
            let h = y[0] * l[0] as f64 + y[1] * l[1] as f64 + y[2] * l[2] as f64;
            if h.z <= 0.0 {
                continue;
            }
            let (u, v) = (h.x / h.z, h.y / h.z);
            if !shown(u, v) {
                continue;
            }
            if let Some(v) = img.sample(u, v) {
                for k in 0..3 {
                    a[k] += s.color[k] as f64;
                    b[k] += v[k] as f64;
                }
                *n += 1;
            }
        }
        if *n >= GROUP {
            flush(&mut sums[c], &mut reads[c]);
        }
    }
    for (s, r) in sums.iter_mut().zip(&mut reads) {
        if s.2 >= GROUP / 2 {
            flush(s, r);
        }
    }
    let changes = reads
        .into_iter()
        .map(|r| {
            if r.iter().map(|(_, n)| n).sum::<usize>() < MIN_TOTAL {
                return None;
            }
            let d: [f64; 3] = std::array::from_fn(|k| {
                weighted_median(&mut r.iter().map(|(q, n)| (q[k], *n)).collect::<Vec<_>>())
            });
            let luma: f64 = (0..3).map(|k| LUMA[k] * d[k]).sum();
            (luma > 0.0 && d.iter().all(|v| v.is_finite() && *v > 0.0)).then(|| d.map(|v| v / luma))
        })
        .collect();
    (
        changes,
        views.into_iter().map(|v| v.map(|(ib, _)| ib)).collect(),
    )
}

/// How many of a camera's latest readings its balance is the median of: a white balance moves
/// smoothly, while an occluder or a highlight over much of the surface for one frame reads as a
/// jump the next frame does not confirm (the Blender hard sample's rod, in one camera for one
/// frame: 4 % red, −7 % blue).
pub(crate) const READINGS: usize = 3;

/// A balance within this of no change (per channel) is not applied, and one beyond it is
/// applied less this: what the per-patch brightness gains and the robust loss absorb, and more
/// than the readings' own noise on footage whose white balance holds (up to 0.9 % on the
/// glossy Blender hard sample under its sun and sky, whose track swings with sub-percent changes
/// of its input). The real webcam board reads up to 9 %.
pub(crate) const DEAD_BAND: f64 = 0.02;

/// The balance applied for `reading`: each channel's departure from 1 less [`DEAD_BAND`].
pub(crate) fn applied(reading: [f64; 3]) -> [f64; 3] {
    reading.map(|v| {
        let d = v - 1.0;
        1.0 + d.signum() * (d.abs() - DEAD_BAND).max(0.0)
    })
}

/// Keeps `reading` as the latest of `readings`, at most [`READINGS`] of them.
pub(crate) fn record(readings: &mut Vec<[f64; 3]>, reading: [f64; 3]) {
    readings.push(reading);
    if readings.len() > READINGS {
        readings.remove(0);
    }
}

/// The balance from a camera's latest readings: their median per channel (the mean of the
/// middle two of an even count; no change without any).
pub(crate) fn of_readings(readings: &[[f64; 3]]) -> [f64; 3] {
    if readings.is_empty() {
        return [1.0; 3];
    }
    std::array::from_fn(|k| {
        let mut v: Vec<f64> = readings.iter().map(|r| r[k]).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    })
}

/// The value at which the weights below and above balance (the lower one on a tie).
fn weighted_median(v: &mut [(f64, usize)]) -> f64 {
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: usize = v.iter().map(|(_, n)| n).sum();
    let mut acc = 0;
    for &(x, n) in v.iter() {
        acc += n;
        if 2 * acc >= total {
            return x;
        }
    }
    f64::NAN
}

/// `pyramid` divided by `balance` per channel at every level (the smoothing and the reduction
/// are linear per channel, so this equals building it from the divided image).
pub(crate) fn divide(pyramid: &mut Pyramid, balance: [f64; 3]) {
    if balance == [1.0; 3] {
        return;
    }
    let inv = balance.map(|b| (1.0 / b) as f32);
    for level in pyramid.images_mut() {
        for p in level.pixels_mut() {
            for k in 0..3 {
                p[k] *= inv[k];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_balance_is_the_median_of_the_last_three_readings() {
        let mut r = Vec::new();
        assert_eq!(of_readings(&r), [1.0; 3]);
        record(&mut r, [1.01, 1.0, 0.99]);
        assert_eq!(of_readings(&r), [1.01, 1.0, 0.99]);
        record(&mut r, [1.03, 1.0, 0.97]);
        assert!((of_readings(&r)[0] - 1.02).abs() < 1e-12);
        // A one-frame jump (an occluder read as a colour change) is outvoted...
        record(&mut r, [1.20, 0.9, 0.80]);
        assert_eq!(of_readings(&r), [1.03, 1.0, 0.97]);
        // ... and forgotten once it is the oldest of three and falls out.
        record(&mut r, [1.04, 1.0, 0.96]);
        record(&mut r, [1.05, 1.0, 0.95]);
        assert_eq!(r.len(), READINGS);
        assert_eq!(of_readings(&r), [1.05, 1.0, 0.95]);
    }

    #[test]
    fn a_balance_within_two_percent_of_none_is_not_applied() {
        assert_eq!(applied([1.009, 0.995, 1.0]), [1.0; 3]);
        let a = applied([1.10, 0.95, 1.02]);
        assert!((a[0] - 1.08).abs() < 1e-12 && (a[1] - 0.97).abs() < 1e-12 && a[2] == 1.0);
    }

    #[test]
    fn the_weighted_median_is_where_half_the_weight_lies_below() {
        assert_eq!(weighted_median(&mut [(3.0, 1), (1.0, 1), (2.0, 1)]), 2.0);
        // One heavy patch outweighs two light ones.
        assert_eq!(weighted_median(&mut [(1.0, 1), (2.0, 1), (5.0, 10)]), 5.0);
        assert_eq!(weighted_median(&mut [(1.0, 2), (2.0, 2)]), 1.0);
    }
}

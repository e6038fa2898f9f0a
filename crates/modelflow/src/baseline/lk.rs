//! Pyramidal iterative Lucas–Kanade point tracking, after J.-Y. Bouguet, "Pyramidal
//! implementation of the Lucas Kanade feature tracker" (Intel, 2000) — the algorithm behind
//! OpenCV's `calcOpticalFlowPyrLK`. It is the 2D optical flow of the "Universal Capture" baseline
//! (`baseline`): each camera's footage is tracked on its own, then the tracks are triangulated.
//!
//! It is written here rather than taken from a crate because the baseline must follow the
//! project's pixel-centre convention at every pyramid level (`camera::Projection::downscaled`),
//! track all three colour channels, and stay pure Rust (no OpenCV build on CI). Per level `L` a
//! full-resolution position `u` sits at `(u + 0.5) / 2^L - 0.5`, the rule the levels of
//! [`pyramid`] follow (Gaussian low-pass, then 2×2 averaging by [`RgbImage::downsample2`]); the
//! levels are stored with their gradients (`pyramid::GradientPyramid`). Samples are bilinear.
//! Window pixels off either image are left out of the sums (a replicated or mirrored border
//! would be structure that does not move). A track fails when its window has too little texture
//! (smallest eigenvalue of the gradient matrix), when it leaves the image, or when tracking it
//! back does not return to its start (forward–backward check). Points are tracked in parallel;
//! each result depends on its own point only, so the output does not depend on the thread count.

use crate::base::image::RgbImage;
use crate::baseline::gradient::{GradientImage, GradientPyramid};
use nalgebra::Point2;
use rayon::prelude::*;

/// Parameters of the tracker. The defaults mirror OpenCV's (`winSize` 21×21, `maxLevel` 3, 30
/// iterations, ε = 0.01 px, `minEigThreshold` 1e-4 converted to this module's units) plus a
/// forward–backward check of 1 px.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LkOptions {
    /// Half the window side: the window is `(2r+1)²` pixels (10 gives 21×21).
    pub window_radius: usize,
    /// Number of pyramid levels including the full-resolution one (4 = OpenCV's `maxLevel` 3).
    /// Fewer are used when the image becomes smaller than a window.
    pub levels: usize,
    /// Gauss–Newton iterations per level at most.
    pub max_iterations: usize,
    /// Stop iterating on a level once an update is shorter than this (pixels of that level).
    pub epsilon: f64,
    /// Smallest eigenvalue of the window's gradient matrix, divided by the window's pixel count,
    /// below which the window is too flat to track (intensities in 0..1, gradients per pixel,
    /// summed over the three channels). 5e-6 ≈ OpenCV's default 1e-4 in its own scaling.
    pub min_eigenvalue: f64,
    /// Maximum distance in pixels between a start point and the point obtained by tracking its
    /// result back to the first image (starting there with zero flow, like the forward track);
    /// `None` disables the check.
    pub forward_backward: Option<f64>,
    /// Gaussian blur (pixels of each level) applied to every pyramid level before its gradients
    /// are taken (see `pyramid`); 0 uses the images as they are.
    pub pyramid_sigma: f64,
}

impl Default for LkOptions {
    fn default() -> Self {
        LkOptions {
            window_radius: 10,
            levels: 4,
            max_iterations: 30,
            epsilon: 0.01,
            min_eigenvalue: 5e-6,
            forward_backward: Some(1.0),
            pyramid_sigma: 0.5,
        }
    }
}

/// The image pyramid the tracker with `opts` needs, colour and gradients per level:
/// `opts.levels` levels, fewer when a level would be smaller than a window. As in Bouguet's
/// (and OpenCV's) pyramid, each level is low-passed before the 2× reduction (Gaussian of σ = 1
/// pixel, then 2×2 averaging, [`RgbImage::downsample2`]) so coarse levels do not alias; each
/// level is then smoothed by `opts.pyramid_sigma` before its gradients are taken.
pub fn pyramid(image: &RgbImage, opts: &LkOptions) -> GradientPyramid {
    let min_side = 2 * opts.window_radius + 1;
    let mut levels = vec![GradientImage::new(&image.blurred(opts.pyramid_sigma))];
    let mut cur = image.clone();
    while levels.len() < opts.levels.max(1)
        && cur.width().div_ceil(2) >= min_side
        && cur.height().div_ceil(2) >= min_side
    {
        cur = cur.blurred(ANTI_ALIAS_SIGMA).downsample2();
        levels.push(GradientImage::new(&cur.blurred(opts.pyramid_sigma)));
    }
    GradientPyramid { levels }
}

/// Low-pass applied to a level before it is halved (pixels of that level).
const ANTI_ALIAS_SIGMA: f64 = 1.0;

/// Whether a bilinear sample at `(u, v)` stays inside a level.
#[inline]
fn in_level(img: &GradientImage, u: f64, v: f64) -> bool {
    u >= 0.0 && v >= 0.0 && u <= (img.width() - 1) as f64 && v <= (img.height() - 1) as f64
}

/// Bilinear sample of colour only at a position inside `[0, w-1] × [0, h-1]` (the inner loop's
/// fetch; callers check `in_level` first).
#[inline]
fn color_at(img: &GradientImage, u: f64, v: f64) -> [f32; 3] {
    img.sample_color(u, v).unwrap_or([0.0; 3])
}

/// Whether a full-resolution position is inside an image of this size (pixel centres at integers).
#[inline]
fn inside(p: Point2<f64>, w: usize, h: usize) -> bool {
    p.x >= -0.5 && p.y >= -0.5 && p.x < w as f64 - 0.5 && p.y < h as f64 - 0.5
}

/// Tracks `start` (in `prev`) into `next`, beginning the search at `guess`. `None` if it fails.
fn track_one(
    prev: &GradientPyramid,
    next: &GradientPyramid,
    start: Point2<f64>,
    guess: Point2<f64>,
    opts: &LkOptions,
    window: &mut Vec<[f32; 9]>,
) -> Option<Point2<f64>> {
    let (w0, h0) = (prev.levels[0].width(), prev.levels[0].height());
    if !inside(start, w0, h0) || !guess.x.is_finite() || !guess.y.is_finite() {
        return None;
    }
    let r = opts.window_radius as isize;
    let levels = prev
        .levels
        .len()
        .min(next.levels.len())
        .min(opts.levels.max(1));
    let mut q = guess;
    for l in (0..levels).rev() {
        let scale = (1u32 << l) as f64;
        let down = |x: f64| (x + 0.5) / scale - 0.5;
        let up = |x: f64| (x + 0.5) * scale - 0.5;
        let (li, lj) = (&prev.levels[l], &next.levels[l]);
        let (px, py) = (down(start.x), down(start.y));
        // Template and its gradient matrix G, over the window pixels inside the image (a
        // border replicated or mirrored into the window would be structure that does not move).
        window.clear();
        let (mut gxx, mut gxy, mut gyy) = (0.0f64, 0.0f64, 0.0f64);
        let mut valid = 0usize;
        for dy in -r..=r {
            for dx in -r..=r {
                let (u, v) = (px + dx as f64, py + dy as f64);
                match li.sample(u, v) {
                    Some(t) => {
                        for c in 0..3 {
                            let (a, b) = (t[3 + c] as f64, t[6 + c] as f64);
                            gxx += a * a;
                            gxy += a * b;
                            gyy += b * b;
                        }
                        valid += 1;
                        window.push(t);
                    }
                    None => window.push([f32::NAN; 9]),
                }
            }
        }
        let half_trace = 0.5 * (gxx + gyy);
        let lambda_min = half_trace - (0.25 * (gxx - gyy).powi(2) + gxy * gxy).sqrt();
        if 2 * valid < window.len() || lambda_min / (valid as f64) < opts.min_eigenvalue {
            if l == 0 {
                return None;
            }
            continue; // too flat (or mostly off the image) at this scale: refine on finer levels
        }
        let (mut qx, mut qy) = (down(q.x), down(q.y));
        let mut prev_step = (0.0f64, 0.0f64);
        for it in 0..opts.max_iterations {
            // Normal equations over the pixels inside both images.
            let (mut bx, mut by) = (0.0f64, 0.0f64);
            let (mut hxx, mut hxy, mut hyy) = (0.0f64, 0.0f64, 0.0f64);
            let mut used = 0usize;
            let mut accumulate = |t: &[f32; 9], j: [f32; 3]| {
                used += 1;
                for c in 0..3 {
                    let (a, b) = (t[3 + c] as f64, t[6 + c] as f64);
                    let e = (t[c] - j[c]) as f64;
                    bx += e * a;
                    by += e * b;
                    hxx += a * a;
                    hxy += a * b;
                    hyy += b * b;
                }
            };
            let (lw, lh) = (lj.width(), lj.height());
            let side = 2 * r as usize + 1;
            if qx - r as f64 >= 0.0
                && qy - r as f64 >= 0.0
                && qx + (r as f64) < (lw - 1) as f64
                && qy + (r as f64) < (lh - 1) as f64
            {
                // The whole window is inside: every sample shares one set of bilinear weights.
                let (ox, oy) = (qx - r as f64, qy - r as f64);
                let (x0, y0) = (ox.floor() as usize, oy.floor() as usize);
                let (fx, fy) = ((ox - x0 as f64) as f32, (oy - y0 as f64) as f32);
                let w = [
                    (1.0 - fx) * (1.0 - fy),
                    fx * (1.0 - fy),
                    (1.0 - fx) * fy,
                    fx * fy,
                ];
                for (j, row) in window.chunks_exact(side).enumerate() {
                    for (i, t) in row.iter().enumerate() {
                        if t[0].is_nan() {
                            continue;
                        }
                        let (x, y) = (x0 + i, y0 + j);
                        let (a, b) = (lj.color(x, y), lj.color(x + 1, y));
                        let (c, d) = (lj.color(x, y + 1), lj.color(x + 1, y + 1));
                        let mut s = [0.0f32; 3];
                        for k in 0..3 {
                            s[k] = w[0] * a[k] + w[1] * b[k] + w[2] * c[k] + w[3] * d[k];
                        }
                        accumulate(t, s);
                    }
                }
            } else {
                let mut k = 0;
                for dy in -r..=r {
                    for dx in -r..=r {
                        let t = &window[k];
                        k += 1;
                        if t[0].is_nan() {
                            continue;
                        }
                        let (u, v) = (qx + dx as f64, qy + dy as f64);
                        if in_level(lj, u, v) {
                            accumulate(t, color_at(lj, u, v));
                        }
                    }
                }
            }
            let det = hxx * hyy - hxy * hxy;
            // The window has slid off the second image, or what is left of it is flat.
            if 2 * used < valid || det.is_nan() || det <= f64::EPSILON * (hxx + hyy).powi(2) {
                return None;
            }
            let (gxx, gxy, gyy) = (hxx, hxy, hyy);
            let sx = (gyy * bx - gxy * by) / det;
            let sy = (gxx * by - gxy * bx) / det;
            // Oscillating between two positions: settle in the middle (as OpenCV does).
            if it > 0 && (sx + prev_step.0).abs() < 0.01 && (sy + prev_step.1).abs() < 0.01 {
                qx += 0.5 * sx;
                qy += 0.5 * sy;
                break;
            }
            qx += sx;
            qy += sy;
            prev_step = (sx, sy);
            if sx * sx + sy * sy < opts.epsilon * opts.epsilon {
                break;
            }
        }
        q = Point2::new(up(qx), up(qy));
    }
    (q.x.is_finite() && q.y.is_finite() && inside(q, w0, h0)).then_some(q)
}

/// Tracks each point of `points` from the image of `prev` to the image of `next`, starting the
/// search at the same position (zero initial flow). Returns the new positions, `None` for tracks
/// that failed (flat window, left the image, forward–backward mismatch).
pub fn track(
    prev: &GradientPyramid,
    next: &GradientPyramid,
    points: &[Point2<f64>],
    opts: &LkOptions,
) -> Vec<Option<Point2<f64>>> {
    track_with_guesses(prev, next, points, points, opts)
}

/// Like [`track`], starting the search of point `i` at `guesses[i]` (a predicted position).
pub fn track_with_guesses(
    prev: &GradientPyramid,
    next: &GradientPyramid,
    points: &[Point2<f64>],
    guesses: &[Point2<f64>],
    opts: &LkOptions,
) -> Vec<Option<Point2<f64>>> {
    assert_eq!(points.len(), guesses.len(), "one guess per point");
    points
        .par_iter()
        .zip(guesses.par_iter())
        .map_init(Vec::new, |window, (&p, &g)| {
            let q = track_one(prev, next, p, g, opts, window)?;
            if let Some(max_fb) = opts.forward_backward {
                let back = track_one(next, prev, q, q, opts, window)?;
                if (back - p).norm() > max_fb {
                    return None;
                }
            }
            Some(q)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth colour texture defined everywhere, so that a shifted copy is exact.
    fn texture(x: f64, y: f64) -> [f32; 3] {
        let f = |a: f64, b: f64, c: f64, d: f64| (a * x + b * y + c).sin() * d;
        // Several scales, like natural texture, so that every pyramid level has detail.
        [
            (0.5 + f(0.31, 0.12, 0.3, 0.1) + f(-0.09, 0.21, 1.1, 0.1) + f(0.047, 0.061, 2.0, 0.15))
                as f32,
            (0.5 + f(0.05, -0.37, 0.7, 0.1) + f(0.14, 0.02, 0.1, 0.1) + f(-0.06, 0.04, 0.4, 0.15))
                as f32,
            (0.5 + f(0.26, 0.28, 1.9, 0.1) + f(-0.13, 0.09, 0.5, 0.1) + f(0.03, -0.07, 1.3, 0.15))
                as f32,
        ]
    }

    /// The texture moved by `(dx, dy)`: the content at `p` moves to `p + d`.
    fn shifted(w: usize, h: usize, dx: f64, dy: f64) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| texture(x as f64 - dx, y as f64 - dy))
    }

    fn grid_points() -> Vec<Point2<f64>> {
        let mut pts = Vec::new();
        for j in 0..4 {
            for i in 0..5 {
                pts.push(Point2::new(
                    40.0 + 30.0 * i as f64 + 0.3,
                    40.0 + 25.0 * j as f64 + 0.7,
                ));
            }
        }
        pts
    }

    fn check_translation(dx: f64, dy: f64, tol: f64) {
        let opts = LkOptions::default();
        let a = pyramid(&shifted(200, 160, 0.0, 0.0), &opts);
        let b = pyramid(&shifted(200, 160, dx, dy), &opts);
        let pts = grid_points();
        let out = track(&a, &b, &pts, &opts);
        for (p, q) in pts.iter().zip(&out) {
            let q = q.unwrap_or_else(|| panic!("track of {p:?} lost"));
            let err = ((q.x - p.x - dx).powi(2) + (q.y - p.y - dy).powi(2)).sqrt();
            assert!(err < tol, "{p:?} -> {q:?}: error {err} px for ({dx}, {dy})");
        }
    }

    #[test]
    fn recovers_subpixel_translation() {
        check_translation(1.3, -0.7, 0.02);
    }

    #[test]
    fn recovers_large_translation_through_the_pyramid() {
        check_translation(8.2, 5.6, 0.02);
        check_translation(-13.4, 9.7, 0.02);
        // Without the pyramid a 21×21 window loses most of these.
        let opts = LkOptions {
            levels: 1,
            ..LkOptions::default()
        };
        let a = pyramid(&shifted(200, 160, 0.0, 0.0), &opts);
        let b = pyramid(&shifted(200, 160, -13.4, 9.7), &opts);
        let pts = grid_points();
        let good = track(&a, &b, &pts, &opts)
            .iter()
            .zip(&pts)
            .filter(|(q, p)| {
                q.is_some_and(|q| (q - *p - nalgebra::Vector2::new(-13.4, 9.7)).norm() < 0.02)
            })
            .count();
        assert!(
            good < pts.len() * 3 / 4,
            "{good} of {} tracked without a pyramid",
            pts.len()
        );
    }

    #[test]
    fn pyramid_stops_before_levels_smaller_than_a_window() {
        let opts = LkOptions::default();
        // 200×160: levels of 200, 100, 50, 25 px wide but 160, 80, 40, 20 high: 20 < 21.
        assert_eq!(pyramid(&shifted(200, 160, 0.0, 0.0), &opts).levels.len(), 3);
        assert_eq!(pyramid(&shifted(320, 240, 0.0, 0.0), &opts).levels.len(), 4);
    }

    #[test]
    fn track_leaving_the_image_is_rejected() {
        let opts = LkOptions::default();
        let a = pyramid(&shifted(200, 160, 0.0, 0.0), &opts);
        let b = pyramid(&shifted(200, 160, -9.0, 0.0), &opts);
        let pts = [Point2::new(5.0, 80.0), Point2::new(100.0, 80.0)];
        let out = track(&a, &b, &pts, &opts);
        assert!(
            out[0].is_none(),
            "point moved to x = -4 must be lost: {:?}",
            out[0]
        );
        let q = out[1].expect("interior point tracked");
        assert!(
            (q.x - 91.0).abs() < 0.02 && (q.y - 80.0).abs() < 0.02,
            "{q:?}"
        );
    }

    #[test]
    fn flat_window_is_rejected() {
        let opts = LkOptions::default();
        let flat = RgbImage::from_fn(120, 120, |x, y| {
            if x < 60 {
                [0.4, 0.4, 0.4]
            } else {
                texture(x as f64, y as f64)
            }
        });
        let a = pyramid(&flat, &opts);
        let out = track(
            &a,
            &a,
            &[Point2::new(20.0, 60.0), Point2::new(95.0, 60.0)],
            &opts,
        );
        assert!(out[0].is_none(), "a flat window has no flow");
        let q = out[1].expect("textured window tracked");
        assert!((q - Point2::new(95.0, 60.0)).norm() < 1e-3, "{q:?}");
    }

    #[test]
    fn forward_backward_rejects_an_occluded_point() {
        // The patch around the point is replaced by an unrelated texture in the second image:
        // whatever the forward track finds, tracking back must not come home.
        let opts = LkOptions::default();
        let a = shifted(160, 160, 0.0, 0.0);
        let b = RgbImage::from_fn(160, 160, |x, y| {
            let (fx, fy) = (x as f64, y as f64);
            if (fx - 80.0).abs() < 16.0 && (fy - 80.0).abs() < 16.0 {
                let t = texture(3.7 * fy + 11.0, 2.9 * fx - 5.0);
                [t[2], t[0], t[1]]
            } else {
                texture(fx, fy)
            }
        });
        let (pa, pb) = (pyramid(&a, &opts), pyramid(&b, &opts));
        let p = [Point2::new(80.0, 80.0)];
        let with = track(&pa, &pb, &p, &opts);
        let without = track(
            &pa,
            &pb,
            &p,
            &LkOptions {
                forward_backward: None,
                ..opts.clone()
            },
        );
        // Without the check the tracker reports a wrong match; with it the track is dropped.
        let q = without[0].expect("forward track alone reports a match");
        assert!((q - p[0]).norm() > 2.0, "{q:?}");
        assert_eq!(with[0], None);
    }

    #[test]
    fn result_does_not_depend_on_thread_count() {
        let opts = LkOptions::default();
        let a = pyramid(&shifted(200, 160, 0.0, 0.0), &opts);
        let b = pyramid(&shifted(200, 160, 2.4, -1.1), &opts);
        let pts = grid_points();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| track(&a, &b, &pts, &opts));
        let many = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap()
            .install(|| track(&a, &b, &pts, &opts));
        assert_eq!(one, many);
    }
}

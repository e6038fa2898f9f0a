//! Pyramidal iterative Lucas–Kanade point tracking, after J.-Y. Bouguet, "Pyramidal
//! implementation of the Lucas Kanade feature tracker" (Intel, 2000) — the algorithm behind
//! OpenCV's `calcOpticalFlowPyrLK`. It is the 2D optical flow of the "Universal Capture" baseline
//! (`baseline`): each camera's footage is tracked on its own, then the tracks are triangulated.
//!
//! It is written here rather than taken from a crate because the baseline must follow the
//! project's pixel-centre convention at every pyramid level (`camera::Projection::downscaled`),
//! track all three colour channels, and stay pure Rust (no OpenCV build on CI). Per level `L` a
//! full-resolution position `u` sits at `(u + 0.5) / 2^L - 0.5`; each level is the previous one
//! lightly blurred and reduced by [`RgbImage::downsample2`], whose pixel centres follow exactly
//! that rule. Samples are bilinear; window samples falling off the image are clamped to its border.
//! A track fails when its window has too little texture (smallest eigenvalue of the gradient
//! matrix), when it leaves the image, or when tracking it back does not return to its start
//! (forward–backward check). Points are tracked in parallel; each result depends on its own point
//! only, so the output does not depend on the thread count.

use crate::image::RgbImage;
use nalgebra::Point2;
use rayon::prelude::*;

/// Parameters of the tracker. The defaults mirror OpenCV's (`winSize` 21×21, `maxLevel` 3, 30
/// iterations, ε = 0.01 px, `minEigThreshold` 1e-4 converted to this module's units) plus a
/// forward–backward check of 1 px.
#[derive(Clone, Debug, PartialEq)]
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
    /// result back to the first image; `None` disables the check.
    pub forward_backward: Option<f64>,
    /// Gaussian blur (pixels of the finer level) applied before each 2× reduction.
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

/// One image of a pyramid with its gradients.
#[derive(Clone, Debug)]
struct Level {
    image: RgbImage,
    gx: RgbImage,
    gy: RgbImage,
}

/// An image pyramid with per-level gradients, built once per image and shared by all points.
#[derive(Clone, Debug)]
pub struct Pyramid {
    levels: Vec<Level>,
}

impl Pyramid {
    /// Builds up to `levels` levels (at least one), stopping early when a side would drop below
    /// `min_side` pixels. Level `k+1` is level `k` blurred by `sigma` and reduced 2×.
    pub fn new(image: &RgbImage, levels: usize, sigma: f64, min_side: usize) -> Pyramid {
        let make = |img: RgbImage| {
            let (gx, gy) = img.gradients();
            Level { image: img, gx, gy }
        };
        let mut out = vec![make(image.clone())];
        while out.len() < levels.max(1) {
            let prev = &out[out.len() - 1].image;
            if prev.width().div_ceil(2) < min_side || prev.height().div_ceil(2) < min_side {
                break;
            }
            out.push(make(prev.blurred(sigma).downsample2()));
        }
        Pyramid { levels: out }
    }

    /// The pyramid the tracker with `opts` needs.
    pub fn for_tracking(image: &RgbImage, opts: &LkOptions) -> Pyramid {
        Pyramid::new(
            image,
            opts.levels,
            opts.pyramid_sigma,
            2 * opts.window_radius + 1,
        )
    }

    /// Number of levels actually built.
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    /// Always false: a pyramid has at least its full-resolution level.
    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    /// The image of level `i` (0 = full resolution).
    pub fn level(&self, i: usize) -> &RgbImage {
        &self.levels[i].image
    }

    fn width(&self) -> usize {
        self.levels[0].image.width()
    }

    fn height(&self) -> usize {
        self.levels[0].image.height()
    }
}

/// Bilinear sample with the position clamped into the image (border replication).
#[inline]
fn sample_clamped(img: &RgbImage, u: f64, v: f64) -> [f32; 3] {
    let u = u.clamp(0.0, (img.width() - 1) as f64);
    let v = v.clamp(0.0, (img.height() - 1) as f64);
    img.sample_unchecked(u, v)
}

/// Whether a full-resolution position is inside an image of this size (pixel centres at integers).
#[inline]
fn inside(p: Point2<f64>, w: usize, h: usize) -> bool {
    p.x >= -0.5 && p.y >= -0.5 && p.x < w as f64 - 0.5 && p.y < h as f64 - 0.5
}

/// One window pixel of the template: intensity and gradient per channel.
#[derive(Clone, Copy, Default)]
struct TemplatePixel {
    value: [f32; 3],
    gx: [f32; 3],
    gy: [f32; 3],
}

/// Tracks `start` (in `prev`) into `next`, beginning the search at `guess`. `None` if it fails.
fn track_one(
    prev: &Pyramid,
    next: &Pyramid,
    start: Point2<f64>,
    guess: Point2<f64>,
    opts: &LkOptions,
    window: &mut Vec<TemplatePixel>,
) -> Option<Point2<f64>> {
    if !inside(start, prev.width(), prev.height()) || !guess.x.is_finite() || !guess.y.is_finite() {
        return None;
    }
    let r = opts.window_radius as isize;
    let n = ((2 * r + 1) * (2 * r + 1)) as f64;
    let levels = prev.len().min(next.len()).min(opts.levels.max(1));
    let mut q = guess;
    for l in (0..levels).rev() {
        let scale = (1u32 << l) as f64;
        let down = |x: f64| (x + 0.5) / scale - 0.5;
        let up = |x: f64| (x + 0.5) * scale - 0.5;
        let (li, lj) = (&prev.levels[l], &next.levels[l]);
        let (px, py) = (down(start.x), down(start.y));
        // Template and its gradient matrix G.
        window.clear();
        let (mut gxx, mut gxy, mut gyy) = (0.0f64, 0.0f64, 0.0f64);
        for dy in -r..=r {
            for dx in -r..=r {
                let (u, v) = (px + dx as f64, py + dy as f64);
                let t = TemplatePixel {
                    value: sample_clamped(&li.image, u, v),
                    gx: sample_clamped(&li.gx, u, v),
                    gy: sample_clamped(&li.gy, u, v),
                };
                for c in 0..3 {
                    let (a, b) = (t.gx[c] as f64, t.gy[c] as f64);
                    gxx += a * a;
                    gxy += a * b;
                    gyy += b * b;
                }
                window.push(t);
            }
        }
        let half_trace = 0.5 * (gxx + gyy);
        let lambda_min = half_trace - (0.25 * (gxx - gyy).powi(2) + gxy * gxy).sqrt();
        let det = gxx * gyy - gxy * gxy;
        if lambda_min / n < opts.min_eigenvalue || det <= f64::EPSILON {
            if l == 0 {
                return None;
            }
            continue; // too flat at this scale: keep the estimate, refine on finer levels
        }
        let (mut qx, mut qy) = (down(q.x), down(q.y));
        let (lw, lh) = (lj.image.width() as f64, lj.image.height() as f64);
        let mut prev_step = (0.0f64, 0.0f64);
        for it in 0..opts.max_iterations {
            // A window entirely off the image has nothing left to match.
            if qx < -(r as f64) - 0.5
                || qy < -(r as f64) - 0.5
                || qx > lw - 0.5 + r as f64
                || qy > lh - 0.5 + r as f64
            {
                return None;
            }
            let (mut bx, mut by) = (0.0f64, 0.0f64);
            let mut k = 0;
            for dy in -r..=r {
                for dx in -r..=r {
                    let t = &window[k];
                    k += 1;
                    let j = sample_clamped(&lj.image, qx + dx as f64, qy + dy as f64);
                    for c in 0..3 {
                        let e = (t.value[c] - j[c]) as f64;
                        bx += e * t.gx[c] as f64;
                        by += e * t.gy[c] as f64;
                    }
                }
            }
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
    (q.x.is_finite() && q.y.is_finite() && inside(q, next.width(), next.height())).then_some(q)
}

/// Tracks each point of `points` from the image of `prev` to the image of `next`, starting the
/// search at the same position (zero initial flow). Returns the new positions, `None` for tracks
/// that failed (flat window, left the image, forward–backward mismatch).
pub fn track(
    prev: &Pyramid,
    next: &Pyramid,
    points: &[Point2<f64>],
    opts: &LkOptions,
) -> Vec<Option<Point2<f64>>> {
    track_with_guesses(prev, next, points, points, opts)
}

/// Like [`track`], starting the search of point `i` at `guesses[i]` (a predicted position).
pub fn track_with_guesses(
    prev: &Pyramid,
    next: &Pyramid,
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
                let back = track_one(next, prev, q, p, opts, window)?;
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
        let a = Pyramid::for_tracking(&shifted(200, 160, 0.0, 0.0), &opts);
        let b = Pyramid::for_tracking(&shifted(200, 160, dx, dy), &opts);
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
        let a = Pyramid::for_tracking(&shifted(200, 160, 0.0, 0.0), &opts);
        let b = Pyramid::for_tracking(&shifted(200, 160, -13.4, 9.7), &opts);
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
    fn pyramid_levels_follow_pixel_centre_convention() {
        // A ramp in u keeps value = u at every level: level L pixel i sits at 2^L (i + 0.5) - 0.5.
        let img = RgbImage::from_fn(64, 32, |x, _| [x as f32, 0.0, 0.0]);
        let p = Pyramid::new(&img, 3, 0.0, 4);
        assert_eq!(p.len(), 3);
        assert_eq!(p.level(2).get(3, 1)[0], 4.0 * 3.5 - 0.5);
    }

    #[test]
    fn track_leaving_the_image_is_rejected() {
        let opts = LkOptions::default();
        let a = Pyramid::for_tracking(&shifted(200, 160, 0.0, 0.0), &opts);
        let b = Pyramid::for_tracking(&shifted(200, 160, -9.0, 0.0), &opts);
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
        let a = Pyramid::for_tracking(&flat, &opts);
        let out = track(
            &a,
            &a,
            &[Point2::new(20.0, 60.0), Point2::new(95.0, 60.0)],
            &opts,
        );
        assert!(out[0].is_none(), "a flat window has no flow");
        assert_eq!(out[1], Some(Point2::new(95.0, 60.0)));
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
        let (pa, pb) = (
            Pyramid::for_tracking(&a, &opts),
            Pyramid::for_tracking(&b, &opts),
        );
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
        let a = Pyramid::for_tracking(&shifted(200, 160, 0.0, 0.0), &opts);
        let b = Pyramid::for_tracking(&shifted(200, 160, 2.4, -1.1), &opts);
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

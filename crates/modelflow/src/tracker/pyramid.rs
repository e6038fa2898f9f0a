//! The tracker's per-frame image pyramids: Gaussian-smoothed RGB levels only. The solver
//! differentiates the interpolant itself (`RgbImage::sample_cubic`, or `sample_exact` for
//! bilinear), so stored gradients would be dead weight in its cache-bound inner loop.
//!
//! Level 0 is full resolution; level `l` is reduced `2^l` times, following the pixel-centre
//! convention of `camera` (`Projection::downscaled`).

use crate::base::image::RgbImage;

/// The shortest side, in pixels, that the coarsest automatically chosen level keeps.
pub const AUTO_COARSEST_PIXELS: u32 = 80;
/// Most levels chosen automatically.
pub const AUTO_MAX_LEVELS: usize = 6;

/// Pyramid levels for images whose shortest side is `short_side` pixels: as many as keep the
/// coarsest level at least [`AUTO_COARSEST_PIXELS`] on its short side (720 → 4 levels down to
/// 90 px, 480 → 3, 240 → 2, 120 → 1). A motion of `m` pixels is `m/2^(L−1)` at the coarsest
/// level, where the smoothed image's basin of convergence is a pixel or two: 4 levels bring
/// 40 px at 1280×720 down to 5 px, which the rigid stage there (see `solve::Motion`) catches.
pub fn auto_levels(short_side: u32) -> usize {
    let mut levels = 1;
    while levels < AUTO_MAX_LEVELS && short_side >> levels >= AUTO_COARSEST_PIXELS {
        levels += 1;
    }
    levels
}

/// How many levels each camera of a rig enters the solve later than the largest camera's
/// images (short side): the nearest power of two between its images and the largest's
/// (1 080 beside 2 160 → 1, 720 beside 1 080 → 1, equal sizes → 0). Solve level `l` compares
/// camera `c` at its own pyramid level `l − skip[c]` (at least 0: [`camera_level`]), so that at
/// every level each camera's pixels are about as large on the surface as the others', and a
/// smaller camera is compared at full resolution at the finest levels. Without it a camera of
/// half the size was compared at half the scale at every level, and the smallest camera
/// decided how many levels the rig had (docs/tracker.md, "Cameras of different sizes").
pub fn level_skips(sizes: impl IntoIterator<Item = (u32, u32)>) -> Vec<usize> {
    let shorts: Vec<u32> = sizes.into_iter().map(|(w, h)| w.min(h)).collect();
    let largest = shorts.iter().copied().max().unwrap_or(0);
    shorts
        .iter()
        .map(|&s| {
            if s == 0 || largest == 0 {
                return 0;
            }
            let r = (f64::from(largest) / f64::from(s)).log2().round();
            (r.max(0.0) as usize).min(AUTO_MAX_LEVELS)
        })
        .collect()
}

/// A camera's own pyramid level at solve level `level`, for its [`level_skips`] entry `skip`.
pub fn camera_level(level: usize, skip: usize) -> usize {
    level.saturating_sub(skip)
}

/// Pyramid levels for a rig of images of the given sizes: as [`auto_levels`] for the smallest
/// short side, each counted at the scale of the largest (`short · 2^skip`, [`level_skips`]),
/// so that a small witness camera does not take a level away from the others.
pub fn auto_levels_of(sizes: impl IntoIterator<Item = (u32, u32)>) -> usize {
    let sizes: Vec<(u32, u32)> = sizes.into_iter().collect();
    let skips = level_skips(sizes.iter().copied());
    let short = sizes
        .iter()
        .zip(&skips)
        .map(|(&(w, h), &k)| (u64::from(w.min(h)) << k).min(u64::from(u32::MAX)) as u32)
        .min()
        .unwrap_or(0);
    auto_levels(short)
}

/// The tracker's pyramid of one camera's image at one frame: smoothed colour per level.
#[derive(Clone, Debug)]
pub struct Pyramid {
    /// Its own levels: `levels[l]` is the image reduced `2^l` times.
    pub levels: Vec<RgbImage>,
    /// For a camera that enters the solve `skip` levels late ([`level_skips`]): its
    /// full-resolution image again for each solve level `l < skip`, smoothed by `sigma·2^(l−skip)`
    /// of its own pixels — `sigma` pixels of the largest camera's images at that level, as
    /// they are smoothed. Empty otherwise.
    pub fine: Vec<RgbImage>,
}

impl Pyramid {
    /// `levels` levels (at least one): level `l` is level `l−1` reduced by 2×2 averaging
    /// (before smoothing), then smoothed with `sigma` pixels at its own scale.
    pub fn new(img: &RgbImage, levels: usize, sigma: f64) -> Self {
        let mut out = Vec::with_capacity(levels.max(1));
        let mut cur = std::borrow::Cow::Borrowed(img);
        for l in 0..levels.max(1) {
            if l > 0 {
                cur = std::borrow::Cow::Owned(cur.downsample2());
            }
            out.push(cur.blurred(sigma));
        }
        Pyramid {
            levels: out,
            fine: Vec::new(),
        }
    }

    /// [`Pyramid::new`] for a camera that enters the solve `skip` levels late, with the
    /// images its solve levels finer than `skip` compare ([`Pyramid::at`]).
    pub fn with_skip(img: &RgbImage, levels: usize, sigma: f64, skip: usize) -> Self {
        let mut p = Pyramid::new(img, levels, sigma);
        p.fine = (0..skip)
            .map(|l| img.blurred(sigma / f64::from(1u32 << (skip - l).min(31))))
            .collect();
        p
    }

    /// The image solve level `level` compares of a camera that enters the solve `skip`
    /// levels late: its own level `level − skip`, or at the finer levels its full resolution,
    /// smoothed for that level (`fine`).
    pub fn at(&self, level: usize, skip: usize) -> &RgbImage {
        match self.fine.get(level) {
            Some(img) if level < skip => img,
            _ => &self.levels[camera_level(level, skip).min(self.levels.len() - 1)],
        }
    }

    /// Every image it holds, its levels and the finer levels' (`fine`).
    pub fn images_mut(&mut self) -> impl Iterator<Item = &mut RgbImage> {
        self.levels.iter_mut().chain(self.fine.iter_mut())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_follow_the_pixel_centre_convention() {
        let img = RgbImage::from_fn(16, 12, |x, y| [0.01 * x as f32, 0.02 * y as f32, 0.5]);
        let p = Pyramid::new(&img, 3, 0.0);
        assert_eq!((p.levels[2].width(), p.levels[2].height()), (4, 3));
        // Level 1 pixel (2, 3) is centred at (4.5, 6.5) of level 0.
        let c = p.levels[1].get(2, 3);
        assert!((c[0] - 0.045).abs() < 1e-6 && (c[1] - 0.13).abs() < 1e-6);
    }

    #[test]
    fn a_smaller_camera_enters_the_levels_by_the_nearest_power_of_two_of_its_size() {
        // Equal sizes: every camera at every level, as a one-size rig always was.
        assert_eq!(level_skips([(1280, 720), (1280, 720)]), [0, 0]);
        assert_eq!(auto_levels_of([(1280, 720), (1280, 720)]), auto_levels(720));
        // A witness camera of half the size: one level later; the rig keeps the large
        // cameras' levels (the smallest decided before: 2 levels at 240×180).
        assert_eq!(level_skips([(480, 360), (240, 180), (480, 360)]), [0, 1, 0]);
        assert_eq!(auto_levels_of([(480, 360), (240, 180), (480, 360)]), 3);
        // A camera of twice the size: the others one level later, and the rig one level deeper.
        assert_eq!(level_skips([(480, 360), (960, 720)]), [1, 0]);
        assert_eq!(auto_levels_of([(480, 360), (960, 720)]), 4);
        // The nearest power of two: 720 beside 1 080 (1.5×) is one level, 1 000 beside
        // 1 080 none, 4K beside 720p (3×) two.
        assert_eq!(
            level_skips([(1920, 1080), (1280, 720), (1920, 1000)]),
            [0, 1, 0]
        );
        assert_eq!(level_skips([(3840, 2160), (1280, 720)]), [0, 2]);
        assert_eq!(
            (camera_level(0, 1), camera_level(1, 1), camera_level(3, 1)),
            (0, 0, 2)
        );
    }

    #[test]
    fn a_camera_entering_a_level_late_is_compared_at_full_resolution_smoothed_for_the_level() {
        let img = RgbImage::from_fn(32, 24, |x, y| {
            [((x * 7 + y * 3) % 5) as f32 * 0.2, 0.5, 0.1]
        });
        let p = Pyramid::with_skip(&img, 3, 1.0, 1);
        // Solve level 0: full resolution smoothed by half a pixel (a pixel of the larger
        // camera's images); level 1: its own level 0, smoothed by a pixel; level 2: its level 1.
        assert_eq!(p.at(0, 1).pixels(), img.blurred(0.5).pixels());
        assert_eq!(p.at(1, 1).pixels(), p.levels[0].pixels());
        assert_eq!(p.at(2, 1).pixels(), p.levels[1].pixels());
        assert_eq!((p.at(0, 1).width(), p.at(2, 1).width()), (32, 16));
        // No skip: its own levels, as `Pyramid::new`.
        let q = Pyramid::with_skip(&img, 3, 1.0, 0);
        assert!(q.fine.is_empty());
        assert_eq!(
            q.at(1, 0).pixels(),
            Pyramid::new(&img, 3, 1.0).levels[1].pixels()
        );
    }
}

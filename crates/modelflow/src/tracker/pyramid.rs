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

/// The tracker's pyramid of one camera's image at one frame: smoothed colour per level.
#[derive(Clone, Debug)]
pub struct Pyramid {
    pub levels: Vec<RgbImage>,
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
        Pyramid { levels: out }
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
}

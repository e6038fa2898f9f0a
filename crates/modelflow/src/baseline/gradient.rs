//! The Lucas–Kanade baseline's image pyramids: per pixel and interleaved, the RGB value and its
//! u and v derivatives (nine floats), so that one bilinear fetch gives it everything at a
//! position. Level 0 is full resolution; level `l` is reduced `2^l` times (built by
//! `lk::pyramid`, following the pixel-centre convention of `camera`).

use crate::base::image::RgbImage;

/// An image with its gradients: per pixel `[r, g, b, ∂r/∂u, ∂g/∂u, ∂b/∂u, ∂r/∂v, ∂g/∂v, ∂b/∂v]`.
#[derive(Clone, Debug)]
pub struct GradientImage {
    width: usize,
    height: usize,
    data: Vec<[f32; 9]>,
}

impl GradientImage {
    pub fn new(img: &RgbImage) -> Self {
        let (gx, gy) = img.gradients();
        let data = img
            .pixels()
            .iter()
            .zip(gx.pixels())
            .zip(gy.pixels())
            .map(|((c, x), y)| [c[0], c[1], c[2], x[0], x[1], x[2], y[0], y[1], y[2]])
            .collect();
        GradientImage {
            width: img.width(),
            height: img.height(),
            data,
        }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Colour at a pixel centre.
    #[inline]
    pub fn color(&self, x: usize, y: usize) -> [f32; 3] {
        let p = &self.data[y * self.width + x];
        [p[0], p[1], p[2]]
    }

    /// The four pixels around `(u, v)` and the fractional position between them, or `None`
    /// unless `(u, v)` lies in `[0, w-1] × [0, h-1]`.
    #[inline]
    fn taps(&self, u: f64, v: f64) -> Option<([&[f32; 9]; 4], f32, f32)> {
        if !(u >= 0.0 && v >= 0.0 && u <= (self.width - 1) as f64 && v <= (self.height - 1) as f64)
        {
            return None;
        }
        let x0 = (u as usize).min(self.width.saturating_sub(2));
        let y0 = (v as usize).min(self.height.saturating_sub(2));
        let x1 = (x0 + 1).min(self.width - 1);
        let y1 = (y0 + 1).min(self.height - 1);
        let fx = (u - x0 as f64) as f32;
        let fy = (v - y0 as f64) as f32;
        let row0 = y0 * self.width;
        let row1 = y1 * self.width;
        let t = [
            &self.data[row0 + x0],
            &self.data[row0 + x1],
            &self.data[row1 + x0],
            &self.data[row1 + x1],
        ];
        Some((t, fx, fy))
    }

    /// Bilinear sample of colour and of the stored (central-difference) gradients, or `None`
    /// unless `(u, v)` lies in `[0, w-1] × [0, h-1]`.
    #[inline]
    pub fn sample(&self, u: f64, v: f64) -> Option<[f32; 9]> {
        let ([a, b, c, d], fx, fy) = self.taps(u, v)?;
        let w = [
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        ];
        let mut out = [0.0f32; 9];
        for k in 0..9 {
            out[k] = w[0] * a[k] + w[1] * b[k] + w[2] * c[k] + w[3] * d[k];
        }
        Some(out)
    }

    /// Bilinear sample of the colour alone.
    #[inline]
    pub fn sample_color(&self, u: f64, v: f64) -> Option<[f32; 3]> {
        let ([a, b, c, d], fx, fy) = self.taps(u, v)?;
        let mut out = [0.0f32; 3];
        for k in 0..3 {
            let top = a[k] + (b[k] - a[k]) * fx;
            let bottom = c[k] + (d[k] - c[k]) * fx;
            out[k] = top + (bottom - top) * fy;
        }
        Some(out)
    }
}

/// The Lucas–Kanade baseline's pyramid: colour and gradients per level (built by `lk::pyramid`).
#[derive(Clone, Debug)]
pub struct GradientPyramid {
    pub levels: Vec<GradientImage>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_gives_value_and_gradient_of_a_linear_image() {
        let img = RgbImage::from_fn(16, 12, |x, y| [0.01 * x as f32, 0.02 * y as f32, 0.5]);
        let g = GradientImage::new(&img);
        let s = g.sample(5.25, 7.5).unwrap();
        assert!((s[0] - 0.0525).abs() < 1e-6 && (s[1] - 0.15).abs() < 1e-6);
        assert!((s[3] - 0.01).abs() < 1e-6 && (s[7] - 0.02).abs() < 1e-6 && s[5].abs() < 1e-6);
        assert!(g.sample(15.01, 3.0).is_none());
    }
}

//! How a camera's stored pixel values relate to light (`"transfer"` in the scene file), and the
//! one conversion the loader makes: scene-linear values (what renderers write to OpenEXR) are
//! encoded with the sRGB curve before anything compares them, so that the tracker's thresholds,
//! set on display-encoded footage, mean the same on a render's EXR as on a camera's JPEG.
//! Integer images (8/16-bit PNG, JPEG, TIFF, DPX, video) are already encoded and are kept as
//! stored. Written by hand: one curve, no colour management library needed for it.

use crate::base::RgbImage;
use serde::{Deserialize, Serialize};

/// What a camera's stored values are (docs/scene-format.md, "Images").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Transfer {
    /// Floating-point images (OpenEXR, float TIFF) are scene-linear, integer ones encoded.
    #[default]
    Auto,
    /// Scene-linear, whatever the file type: encoded with the sRGB curve at load.
    Linear,
    /// Already encoded (sRGB, Rec. 709, log ...): used as stored.
    Encoded,
}

impl Transfer {
    pub fn is_auto(&self) -> bool {
        *self == Transfer::Auto
    }

    /// Whether an image stored as floating point (`float`) or as integers is encoded at load.
    pub fn encodes(&self, float: bool) -> bool {
        match self {
            Transfer::Auto => float,
            Transfer::Linear => true,
            Transfer::Encoded => false,
        }
    }
}

/// The sRGB encoding of a linear value (IEC 61966-2-1): `12.92·v` up to 0.0031308, then
/// `1.055·v^(1/2.4) − 0.055`. Values above 1 (highlights in a render) follow the same curve,
/// which keeps growing but ever more slowly; values below 0 (from a renderer's filter) stay on
/// the linear segment.
pub fn srgb_encode(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Encodes every value of a scene-linear image with [`srgb_encode`].
pub(crate) fn encode_linear(img: &mut RgbImage) {
    for p in img.pixels_mut() {
        *p = p.map(srgb_encode);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_srgb_curve_has_its_standard_values() {
        // Linear 18 % grey is sRGB 118/255 (0.4613); the curve's knee is continuous.
        assert!((srgb_encode(0.18) - 0.461_356).abs() < 1e-5);
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_encode(0.003_130_8) - 0.040_45).abs() < 1e-5);
        let above = 1.055 * 0.003_130_81f32.powf(1.0 / 2.4) - 0.055;
        assert!((above - srgb_encode(0.003_130_8)).abs() < 1e-5);
        // Beyond white it keeps growing; below black it stays linear.
        assert!((srgb_encode(4.0) - (1.055 * 4f32.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6);
        assert!(srgb_encode(4.0) > srgb_encode(2.0) && srgb_encode(2.0) > 1.0);
        assert_eq!(srgb_encode(-0.01), -0.1292);
    }

    #[test]
    fn auto_encodes_floating_point_images_only() {
        assert!(Transfer::Auto.encodes(true));
        assert!(!Transfer::Auto.encodes(false));
        assert!(Transfer::Linear.encodes(false));
        assert!(!Transfer::Encoded.encodes(true));
    }
}

//! Colours of the report: a categorical palette telling runs apart (Okabe–Ito, readable by people
//! with the common colour-vision deficiencies) and the perceptual viridis map for error magnitudes.
//!
//! Viridis is interpolated linearly between nine published samples of matplotlib's table (at
//! 0, 1/8, …, 1): between neighbouring samples the map is close to linear in sRGB, so this keeps its
//! perceptual ordering without a 256-entry table or a plotting crate.

use crate::report::draw::{hex, Rgb};

/// Distinct colours for runs, in order (cycled past the end).
const RUNS: [Rgb; 7] = [
    hex(0x0072b2), // blue
    hex(0xd55e00), // vermillion
    hex(0x009e73), // bluish green
    hex(0xcc79a7), // reddish purple
    hex(0xe69f00), // orange
    hex(0x56b4e9), // sky blue
    hex(0x000000), // black
];

/// The colour of run number `i`.
pub fn run_colour(i: usize) -> Rgb {
    RUNS[i % RUNS.len()]
}

/// `c` lightened toward white by `t` (0: itself, 1: white): a run's secondary lines.
pub fn lighter(c: Rgb, t: f32) -> Rgb {
    c.map(|v| v + (1.0 - v) * t)
}

/// Bright colours for drawing runs over photographs (same order as [`run_colour`]).
const OVERLAY: [Rgb; 6] = [
    hex(0x00e5ff), // cyan
    hex(0xff5a1f), // orange-red
    hex(0x39ff14), // green
    hex(0xff4fd8), // magenta
    hex(0xffd400), // yellow
    hex(0xffffff), // white
];

/// The colour of run number `i` over an image.
pub fn overlay_colour(i: usize) -> Rgb {
    OVERLAY[i % OVERLAY.len()]
}

/// The colour of ground truth in wireframe views.
pub const TRUTH: Rgb = hex(0xb0b0b0);

const VIRIDIS: [Rgb; 9] = [
    hex(0x440154),
    hex(0x472d7b),
    hex(0x3b528b),
    hex(0x2c728e),
    hex(0x21918c),
    hex(0x28ae80),
    hex(0x5ec962),
    hex(0xaddc30),
    hex(0xfde725),
];

/// Viridis at `t` in [0, 1] (clamped; NaN maps to the low end).
pub fn viridis(t: f64) -> Rgb {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = (x - i as f64) as f32;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [
        a[0] + (b[0] - a[0]) * f,
        a[1] + (b[1] - a[1]) * f,
        a[2] + (b[2] - a[2]) * f,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_ends_and_monotone_lightness() {
        assert_eq!(viridis(0.0), hex(0x440154));
        assert_eq!(viridis(1.0), hex(0xfde725));
        assert_eq!(viridis(-3.0), viridis(0.0));
        let luma = |c: Rgb| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let mut prev = -1.0;
        for k in 0..=100 {
            let l = luma(viridis(k as f64 / 100.0));
            assert!(l > prev, "lightness rises along viridis");
            prev = l;
        }
    }

    #[test]
    fn run_colours_are_distinct() {
        for i in 0..RUNS.len() {
            for j in 0..i {
                assert_ne!(run_colour(i), run_colour(j));
            }
        }
    }
}

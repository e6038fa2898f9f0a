//! 2-D drawing onto an [`RgbImage`] for the report's figures: alpha blending, anti-aliased lines of
//! any width, filled and outlined rectangles, copying one image into another, and text (from the
//! embedded DejaVu Sans subset in `assets/fonts`, rasterised by `ab_glyph`).
//!
//! Lines are hand-written as exact coverage of a round-capped "capsule" (distance from the pixel
//! centre to the segment, with a one-pixel linear ramp at the edge) rather than taken from a crate:
//! Wu's algorithm only does 1-px lines, the drawing crates that do more pull in a large dependency
//! tree (or system fonts) for about forty lines of code, and the capsule test is also what makes a
//! wireframe edge land exactly where the camera convention projects it (pixel centres at integer
//! coordinates), which the tests check. Each row of a line touches one interval of pixels, found
//! analytically, so a long line costs its area, not its bounding box.

use crate::base::image::RgbImage;
use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
use std::sync::OnceLock;

/// An RGB colour with channels in [0, 1].
pub type Rgb = [f32; 3];

/// A colour from its `0xrrggbb` value.
pub const fn hex(c: u32) -> Rgb {
    [
        ((c >> 16) & 0xff) as f32 / 255.0,
        ((c >> 8) & 0xff) as f32 / 255.0,
        (c & 0xff) as f32 / 255.0,
    ]
}

/// `#rrggbb` text for a colour (for SVG and HTML).
pub fn css(c: Rgb) -> String {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    format!("#{:02x}{:02x}{:02x}", q(c[0]), q(c[1]), q(c[2]))
}

/// Blends `colour` over the pixel `(x, y)` with opacity `alpha`; ignores pixels outside the image.
#[inline]
pub fn blend(img: &mut RgbImage, x: i64, y: i64, colour: Rgb, alpha: f32) {
    if x < 0 || y < 0 || x >= img.width() as i64 || y >= img.height() as i64 || alpha <= 0.0 {
        return;
    }
    let a = alpha.min(1.0);
    let w = img.width();
    let p = &mut img.pixels_mut()[y as usize * w + x as usize];
    for c in 0..3 {
        p[c] += (colour[c] - p[c]) * a;
    }
}

/// Fills the pixels whose centres lie in `[x0, x1) × [y0, y1)`.
pub fn fill_rect(img: &mut RgbImage, x0: f64, y0: f64, x1: f64, y1: f64, colour: Rgb, alpha: f32) {
    let xa = x0.ceil().max(0.0) as i64;
    let ya = y0.ceil().max(0.0) as i64;
    let xb = (x1.ceil() as i64).min(img.width() as i64);
    let yb = (y1.ceil() as i64).min(img.height() as i64);
    for y in ya..yb {
        for x in xa..xb {
            blend(img, x, y, colour, alpha);
        }
    }
}

/// The outline of a rectangle, `width` pixels wide, centred on its border.
pub fn stroke_rect(
    img: &mut RgbImage,
    x0: f64,
    y0: f64,
    x1: f64,
    y1: f64,
    colour: Rgb,
    width: f64,
) {
    let h = width / 2.0;
    fill_rect(img, x0 - h, y0 - h, x1 + h, y0 + h, colour, 1.0);
    fill_rect(img, x0 - h, y1 - h, x1 + h, y1 + h, colour, 1.0);
    fill_rect(img, x0 - h, y0 + h, x0 + h, y1 - h, colour, 1.0);
    fill_rect(img, x1 - h, y0 + h, x1 + h, y1 - h, colour, 1.0);
}

/// An anti-aliased segment from `a` to `b` (pixel coordinates, centres at integers), `width` pixels
/// wide with round caps, blended with opacity `alpha`.
pub fn line(img: &mut RgbImage, a: [f64; 2], b: [f64; 2], colour: Rgb, width: f64, alpha: f32) {
    if !(a.iter().chain(&b).all(|v| v.is_finite())) || width <= 0.0 {
        return;
    }
    let r = width / 2.0;
    // Pixels whose centre is within r + 0.5 of the segment get some coverage.
    let reach = r + 0.5;
    let (w, h) = (img.width() as i64, img.height() as i64);
    let y_lo = ((a[1].min(b[1]) - reach).ceil() as i64).max(0);
    let y_hi = ((a[1].max(b[1]) + reach).floor() as i64).min(h - 1);
    if y_lo > y_hi {
        return;
    }
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    for y in y_lo..=y_hi {
        let yf = y as f64;
        let Some((x0, x1)) = capsule_row(a, b, d, len2, reach, yf) else {
            continue;
        };
        let xa = (x0.ceil() as i64).max(0);
        let xb = (x1.floor() as i64).min(w - 1);
        for x in xa..=xb {
            let dist = segment_distance(a, d, len2, [x as f64, yf]);
            let cov = (reach - dist).clamp(0.0, 1.0) as f32;
            // Lines thinner than a pixel fade instead of thinning further.
            let cov = if width < 1.0 { cov * width as f32 } else { cov };
            blend(img, x, y, colour, cov * alpha);
        }
    }
}

/// A polyline through `pts`.
pub fn polyline(img: &mut RgbImage, pts: &[[f64; 2]], colour: Rgb, width: f64, alpha: f32) {
    for s in pts.windows(2) {
        line(img, s[0], s[1], colour, width, alpha);
    }
}

/// A polyline drawn dashed: `[on, off]` pixels measured along the whole path (the pattern
/// carries over from one segment to the next, as SVG's `stroke-dasharray` does), opaque.
pub fn dashed_polyline(
    img: &mut RgbImage,
    pts: &[[f64; 2]],
    colour: Rgb,
    width: f64,
    dash: [f64; 2],
) {
    let [on, off] = dash;
    if !(on > 0.0 && off >= 0.0 && on.is_finite() && off.is_finite()) {
        return polyline(img, pts, colour, width, 1.0);
    }
    let period = on + off;
    // How far into the pattern the path is at the start of each segment.
    let mut phase = 0.0f64;
    for s in pts.windows(2) {
        let (a, b) = (s[0], s[1]);
        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        if !len.is_finite() || len == 0.0 {
            continue;
        }
        let at = |d: f64| {
            [
                a[0] + (b[0] - a[0]) * d / len,
                a[1] + (b[1] - a[1]) * d / len,
            ]
        };
        let mut d = 0.0;
        while d < len {
            let into = phase % period;
            let (drawn, left) = if into < on {
                (true, on - into)
            } else {
                (false, period - into)
            };
            // At least a millionth of a pixel a step, so that rounding at a dash's end cannot
            // stall the walk.
            let end = (d + left.max(1e-6)).min(len);
            if drawn {
                line(img, at(d), at(end), colour, width, 1.0);
            }
            phase += end - d;
            d = end;
        }
    }
}

#[inline]
fn segment_distance(a: [f64; 2], d: [f64; 2], len2: f64, p: [f64; 2]) -> f64 {
    let ap = [p[0] - a[0], p[1] - a[1]];
    let t = if len2 > 0.0 {
        ((ap[0] * d[0] + ap[1] * d[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let q = [ap[0] - t * d[0], ap[1] - t * d[1]];
    (q[0] * q[0] + q[1] * q[1]).sqrt()
}

/// The x interval where the row `y` meets the capsule of radius `rad` around segment `a`–`b`
/// (convex, so the meeting is one interval: the union of the two end discs and the band).
fn capsule_row(
    a: [f64; 2],
    b: [f64; 2],
    d: [f64; 2],
    len2: f64,
    rad: f64,
    y: f64,
) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for c in [a, b] {
        let dy = y - c[1];
        let s = rad * rad - dy * dy;
        if s >= 0.0 {
            let s = s.sqrt();
            lo = lo.min(c[0] - s);
            hi = hi.max(c[0] + s);
        }
    }
    if len2 > 0.0 {
        // Band: 0 <= d·(p-a) <= len2 and |n·(p-a)| <= rad·|d|, with n = (-d_y, d_x); each is
        // linear in x on this row: coef·x + k within [lo_k, hi_k].
        let len = len2.sqrt();
        let mut blo = f64::NEG_INFINITY;
        let mut bhi = f64::INFINITY;
        let mut ok = true;
        for (coef, k, min, max) in [
            (d[0], -a[0] * d[0] + (y - a[1]) * d[1], 0.0, len2),
            (
                -d[1],
                a[0] * d[1] + (y - a[1]) * d[0],
                -rad * len,
                rad * len,
            ),
        ] {
            if coef.abs() < 1e-12 {
                if k < min || k > max {
                    ok = false;
                }
            } else {
                let (u, v) = ((min - k) / coef, (max - k) / coef);
                blo = blo.max(u.min(v));
                bhi = bhi.min(u.max(v));
            }
        }
        if ok && blo <= bhi {
            lo = lo.min(blo);
            hi = hi.max(bhi);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// Copies `src` into `dst` with its top-left pixel at `(x, y)` (clipped).
pub fn blit(dst: &mut RgbImage, src: &RgbImage, x: i64, y: i64) {
    for sy in 0..src.height() {
        let dy = y + sy as i64;
        if dy < 0 || dy >= dst.height() as i64 {
            continue;
        }
        for sx in 0..src.width() {
            let dx = x + sx as i64;
            if dx >= 0 && dx < dst.width() as i64 {
                dst.set(dx as usize, dy as usize, src.get(sx, sy));
            }
        }
    }
}

/// An image filled with one colour.
pub fn filled(width: usize, height: usize, colour: Rgb) -> RgbImage {
    RgbImage::from_pixels(width, height, vec![colour; width * height]).expect("sides > 0")
}

static FONT_BYTES: &[u8] = include_bytes!("../../../../assets/fonts/DejaVuSans-subset.ttf");

fn font() -> &'static FontRef<'static> {
    static FONT: OnceLock<FontRef<'static>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(FONT_BYTES).expect("the embedded font parses"))
}

/// Where a text's anchor point sits relative to the text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Anchor {
    /// `x` is the left end of the text.
    Left,
    /// `x` is the middle of the text.
    Centre,
    /// `x` is the right end of the text.
    Right,
}

/// The advance width in pixels of `text` at `size` px.
pub fn text_width(text: &str, size: f32) -> f64 {
    let f = font().as_scaled(PxScale::from(size));
    let mut w = 0.0f32;
    let mut prev = None;
    for ch in text.chars() {
        let id = f.glyph_id(ch);
        if let Some(p) = prev {
            w += f.kern(p, id);
        }
        w += f.h_advance(id);
        prev = Some(id);
    }
    w as f64
}

/// Rasterises `text` at `size` px into a coverage mask (row-major, `w × h`, values 0..1); the
/// mask's height is the font's line height.
fn text_mask(text: &str, size: f32) -> (usize, usize, Vec<f32>) {
    let f = font().as_scaled(PxScale::from(size));
    let w = text_width(text, size).ceil() as usize + 2;
    let h = (f.ascent() - f.descent()).ceil() as usize + 1;
    let mut mask = vec![0.0f32; w * h];
    let mut x = 1.0f32;
    let mut prev = None;
    for ch in text.chars() {
        let id = f.glyph_id(ch);
        if let Some(p) = prev {
            x += f.kern(p, id);
        }
        let glyph = id.with_scale_and_position(size, ab_glyph::point(x, f.ascent()));
        if let Some(og) = font().outline_glyph(glyph) {
            let bb = og.px_bounds();
            og.draw(|gx, gy, c| {
                let px = bb.min.x as i64 + gx as i64;
                let py = bb.min.y as i64 + gy as i64;
                if px >= 0 && py >= 0 && (px as usize) < w && (py as usize) < h {
                    let m = &mut mask[py as usize * w + px as usize];
                    *m = (*m + c).min(1.0);
                }
            });
        }
        x += f.h_advance(id);
        prev = Some(id);
    }
    (w, h, mask)
}

/// Draws `text` at `size` px with its vertical middle at `y` and `x` placed per `anchor`.
pub fn text(img: &mut RgbImage, s: &str, x: f64, y: f64, size: f32, colour: Rgb, anchor: Anchor) {
    let (w, h, mask) = text_mask(s, size);
    let left = match anchor {
        Anchor::Left => x,
        Anchor::Centre => x - w as f64 / 2.0,
        Anchor::Right => x - w as f64,
    }
    .round() as i64;
    let top = (y - h as f64 / 2.0).round() as i64;
    for j in 0..h {
        for i in 0..w {
            blend(
                img,
                left + i as i64,
                top + j as i64,
                colour,
                mask[j * w + i],
            );
        }
    }
}

/// Draws `text` rotated 90° counter-clockwise (reading bottom to top), centred on `(x, y)`.
pub fn text_vertical(img: &mut RgbImage, s: &str, x: f64, y: f64, size: f32, colour: Rgb) {
    let (w, h, mask) = text_mask(s, size);
    // Mask pixel (i, j) goes to (left + j, bottom - i).
    let left = (x - h as f64 / 2.0).round() as i64;
    let bottom = (y + w as f64 / 2.0).round() as i64;
    for j in 0..h {
        for i in 0..w {
            blend(
                img,
                left + j as i64,
                bottom - i as i64,
                colour,
                mask[j * w + i],
            );
        }
    }
}

/// A label on a dark translucent box, for readability over photographs: top-left corner at (x, y).
pub fn label(img: &mut RgbImage, s: &str, x: f64, y: f64, size: f32) {
    let w = text_width(s, size);
    let h = size as f64 * 1.35;
    fill_rect(img, x, y, x + w + 8.0, y + h, [0.0; 3], 0.65);
    text(img, s, x + 4.0, y + h / 2.0, size, [1.0; 3], Anchor::Left);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn horizontal_line_covers_its_row_only() {
        let mut img = filled(20, 10, [0.0; 3]);
        line(&mut img, [2.0, 5.0], [15.0, 5.0], [1.0; 3], 1.0, 1.0);
        for x in 2..=15 {
            assert_eq!(img.get(x, 5), [1.0; 3], "x={x}");
            assert_eq!(img.get(x, 3), [0.0; 3]);
            assert_eq!(img.get(x, 7), [0.0; 3]);
        }
        // Half-pixel coverage one row away (distance 1 from a half-width-0.5 line, 1 px ramp).
        assert_eq!(img.get(8, 4), [0.0; 3]);
        assert_eq!(img.get(18, 5), [0.0; 3]);
    }

    #[test]
    fn diagonal_line_hits_every_pixel_it_crosses_and_is_antialiased() {
        let mut img = filled(40, 40, [0.0; 3]);
        line(&mut img, [3.3, 4.1], [33.7, 29.2], [1.0; 3], 1.5, 1.0);
        let mut partial = 0;
        for t in 0..=100 {
            let t = t as f64 / 100.0;
            let (u, v) = (3.3 + t * 30.4, 4.1 + t * 25.1);
            assert!(img.get(u.round() as usize, v.round() as usize)[0] > 0.5);
        }
        for p in img.pixels() {
            if p[0] > 0.0 && p[0] < 1.0 {
                partial += 1;
            }
        }
        assert!(
            partial > 20,
            "edges are anti-aliased ({partial} partial pixels)"
        );
    }

    #[test]
    fn text_puts_ink_in_its_box() {
        let mut img = filled(120, 30, [1.0; 3]);
        text(
            &mut img,
            "frame 12",
            60.0,
            15.0,
            14.0,
            [0.0; 3],
            Anchor::Centre,
        );
        let w = text_width("frame 12", 14.0);
        assert!(w > 40.0 && w < 80.0, "{w}");
        let ink: Vec<(usize, usize)> = (0..30)
            .flat_map(|y| (0..120).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get(x, y)[0] < 0.5)
            .collect();
        assert!(ink.len() > 40);
        assert!(ink
            .iter()
            .all(|&(x, y)| (x as f64 - 60.0).abs() <= w / 2.0 + 2.0 && (3..27).contains(&y)));
    }
}

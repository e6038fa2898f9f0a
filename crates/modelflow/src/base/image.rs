//! In-memory images: RGB, `f32` per channel, interleaved, row-major, values nominally in [0, 1]
//! (the file's encoded values, not linearised). Sampling follows the pixel-centre convention of
//! `camera`: pixel `(i, j)` has its centre at `(u, v) = (i, j)`.
//!
//! Bilinear and bicubic sampling (each with its interpolant's exact derivatives), gradients,
//! blurring and 2× reduction are written here by hand because the tracker's inner loop needs them
//! fused and allocation-free, which no image crate offers.

use wide::f32x4;

/// Catmull–Rom weights of the four taps at offsets −1, 0, 1, 2 for a sample at fraction `t` in
/// `[0, 1]` between taps 0 and 1, and their derivatives with respect to `t`.
#[inline]
fn catmull_rom(t: f32) -> ([f32; 4], [f32; 4]) {
    let t2 = t * t;
    let t3 = t2 * t;
    (
        [
            0.5 * (-t3 + 2.0 * t2 - t),
            0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
            0.5 * (-3.0 * t3 + 4.0 * t2 + t),
            0.5 * (t3 - t2),
        ],
        [
            0.5 * (-3.0 * t2 + 4.0 * t - 1.0),
            0.5 * (9.0 * t2 - 10.0 * t),
            0.5 * (-9.0 * t2 + 8.0 * t + 1.0),
            0.5 * (3.0 * t2 - 2.0 * t),
        ],
    )
}

/// Whether a rig mixes cameras that record colour with ones that do not ([`RgbImage::is_grey`]
/// on each camera's `images`): comparing a colour camera's pixels with a grey one's colours would
/// find no match where the surface's hues differ and a false one on any grey background, so such
/// a rig is compared in luminance throughout ([`RgbImage::to_luminance`]).
/// Cameras whose images are blank ([`blank_images`]) do not count: a black frame records no
/// colour, and neither does a lens cap.
pub fn mixes_grey_and_colour(images: &[RgbImage]) -> bool {
    let blank = blank_images(images);
    let seen = images.iter().zip(&blank).filter(|(_, b)| !**b);
    let (grey, all) = seen.fold((0, 0), |(g, n), (i, _)| (g + i.is_grey() as usize, n + 1));
    grey > 0 && grey < all
}

/// A [`RgbImage::texture`] below this is blank whatever the other cameras show: less than a
/// twentieth of a code value of an 8-bit file over the whole frame.
pub const BLANK_TEXTURE: f32 = 2e-4;
/// A camera whose [`RgbImage::texture`] is below this share of the most textured camera's at the
/// same frame is blank: a black frame with sensor noise, a lens cap, a frame blown out to white.
/// A frame a fifth as bright as the others (an exposure flicker) keeps a fifth of their texture.
pub const BLANK_SHARE: f32 = 0.05;

/// An image's luminance at an eighth of its resolution ([`RgbImage::block_means`]): what a
/// frame shows at all ([`BlockMeans::spread`]) and whether it changed since another frame of the
/// same camera ([`BlockMeans::change_within`]), read without the sensor noise of single pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockMeans {
    /// Pixels per block side (8; 1 for a frame smaller than a block).
    block: usize,
    /// Blocks per row and per column.
    width: usize,
    height: usize,
    /// Row-major, NaN for a block without a finite pixel.
    means: Vec<f64>,
}

impl BlockMeans {
    /// The standard deviation of the block means over the frame ([`RgbImage::texture`]): 0 for
    /// a frame of one colour, about 0.1 to 0.3 for footage of a scene.
    pub fn spread(&self) -> f32 {
        let (mut sum, mut sum2, mut n) = (0.0f64, 0.0f64, 0u64);
        for &m in self.means.iter().filter(|m| !m.is_nan()) {
            sum += m;
            sum2 += m * m;
            n += 1;
        }
        if n == 0 {
            return 0.0;
        }
        let mean = sum / n as f64;
        (sum2 / n as f64 - mean * mean).max(0.0).sqrt() as f32
    }

    /// The RMS change of the block means from `earlier` (the same camera's image of another
    /// frame) over the blocks that meet the pixel window `[x0, x1] × [y0, y1]`; `None` when the
    /// two differ in size or no block with a finite mean meets the window.
    pub fn change_within(&self, earlier: &BlockMeans, window: [f64; 4]) -> Option<f64> {
        if (self.block, self.width, self.height) != (earlier.block, earlier.width, earlier.height) {
            return None;
        }
        let [x0, y0, x1, y1] = window;
        if !(x0 <= x1 && y0 <= y1) {
            return None;
        }
        let b = self.block as f64;
        // Blocks whose pixels (centres at integer coordinates) reach into the window.
        let range = |lo: f64, hi: f64, n: usize| {
            let a = (lo / b).floor().max(0.0) as usize;
            let z = ((hi / b).floor() + 1.0).clamp(0.0, n as f64) as usize;
            a..z.max(a)
        };
        let (xs, ys) = (range(x0, x1, self.width), range(y0, y1, self.height));
        let (mut sum, mut n) = (0.0f64, 0usize);
        for y in ys {
            let row = y * self.width;
            for x in xs.clone() {
                let d = self.means[row + x] - earlier.means[row + x];
                if d.is_finite() {
                    sum += d * d;
                    n += 1;
                }
            }
        }
        (n > 0).then(|| (sum / n as f64).sqrt())
    }
}

/// Which of one frame's images (one per camera) are blank: they show nothing to compare (a
/// dropped frame written black, a lens cap, a flash that blew the frame out). The tracker leaves
/// a blank image out of that frame, as template and as target (docs/tracker.md, "Blank
/// frames"); an image is blank when its [`RgbImage::texture`] is below `BLANK_TEXTURE`, or
/// below `BLANK_SHARE` of the most textured camera's.
pub fn blank_images(images: &[RgbImage]) -> Vec<bool> {
    let texture: Vec<f32> = images.iter().map(RgbImage::texture).collect();
    blank_of(&texture)
}

/// [`blank_images`] from the images' textures.
pub(crate) fn blank_of(texture: &[f32]) -> Vec<bool> {
    let most = texture.iter().copied().fold(0.0f32, f32::max);
    texture
        .iter()
        .map(|&t| !(t >= BLANK_TEXTURE && t >= BLANK_SHARE * most))
        .collect()
}

/// One frame's images (one per camera) as the cameras are compared with each other: in
/// luminance when the rig [mixes grey and colour](mixes_grey_and_colour), as given otherwise.
pub fn comparable(images: &[RgbImage]) -> std::borrow::Cow<'_, [RgbImage]> {
    if mixes_grey_and_colour(images) {
        std::borrow::Cow::Owned(
            images
                .iter()
                .map(|i| {
                    let mut i = i.clone();
                    i.to_luminance();
                    i
                })
                .collect(),
        )
    } else {
        std::borrow::Cow::Borrowed(images)
    }
}

/// An RGB image with `f32` channels.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    width: usize,
    height: usize,
    data: Vec<[f32; 3]>,
}

impl RgbImage {
    /// A black image. Panics if a side is zero (callers validate sizes first).
    pub fn new(width: usize, height: usize) -> Self {
        assert!(width > 0 && height > 0, "image sides must be positive");
        RgbImage {
            width,
            height,
            data: vec![[0.0; 3]; width * height],
        }
    }

    /// From row-major interleaved pixels; `None` if the length does not match.
    pub fn from_pixels(width: usize, height: usize, data: Vec<[f32; 3]>) -> Option<Self> {
        (width > 0 && height > 0 && data.len() == width * height).then_some(RgbImage {
            width,
            height,
            data,
        })
    }

    /// Fills each pixel from a function of its integer coordinates.
    pub fn from_fn(
        width: usize,
        height: usize,
        mut f: impl FnMut(usize, usize) -> [f32; 3],
    ) -> Self {
        let mut img = RgbImage::new(width, height);
        for y in 0..height {
            for x in 0..width {
                img.data[y * width + x] = f(x, y);
            }
        }
        img
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    pub fn pixels(&self) -> &[[f32; 3]] {
        &self.data
    }

    pub fn pixels_mut(&mut self) -> &mut [[f32; 3]] {
        &mut self.data
    }

    #[inline]
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        self.data[y * self.width + x]
    }

    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: [f32; 3]) {
        self.data[y * self.width + x] = v;
    }

    /// Whether the image records no colour: every pixel's three channels equal (a monochrome
    /// camera, or a file decoded from one channel), allowing 2/255 of spread in 1 pixel of
    /// 1 000 (compression noise).
    pub fn is_grey(&self) -> bool {
        let spread = |p: &[f32; 3]| p[0].max(p[1]).max(p[2]) - p[0].min(p[1]).min(p[2]);
        let coloured = self.data.iter().filter(|p| spread(p) > 2.0 / 255.0).count();
        coloured * 1000 < self.data.len()
    }

    /// How much the image shows: the standard deviation of its luminance (Rec. 709) over
    /// blocks of 8×8 pixels (their means, so that sensor noise counts for an eighth of what it
    /// does per pixel), over the whole frame. 0 for a frame of one colour; about 0.1 to 0.3 for
    /// footage of a scene. Blocks cut by the right and bottom edges are left out (a frame
    /// smaller than a block is measured per pixel), and so are non-finite pixels.
    pub fn texture(&self) -> f32 {
        self.block_means().spread()
    }

    /// The image's luminance (Rec. 709) at an eighth of its resolution: the mean of each block
    /// of 8×8 pixels (of each pixel when the frame is smaller than a block), so that sensor
    /// noise counts for an eighth of what it does per pixel. Blocks cut by the right and bottom
    /// edges are left out; a block without a finite pixel is NaN.
    pub fn block_means(&self) -> BlockMeans {
        let b = if self.width >= 8 && self.height >= 8 {
            8
        } else {
            1
        };
        let (bw, bh) = (self.width / b, self.height / b);
        let mut means = Vec::with_capacity(bw * bh);
        // Per block of the current row: the sum of its finite luminances and their count (a
        // non-finite pixel, which the file readers refuse, is not "one colour": it is left out).
        let mut row = vec![(0.0f64, 0u32); bw];
        for by in 0..bh {
            row.iter_mut().for_each(|r| *r = (0.0, 0));
            for y in by * b..(by + 1) * b {
                let line = &self.data[y * self.width..y * self.width + bw * b];
                for (x, p) in line.iter().enumerate() {
                    let l = (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) as f64;
                    if l.is_finite() {
                        let r = &mut row[x / b];
                        r.0 += l;
                        r.1 += 1;
                    }
                }
            }
            means.extend(
                row.iter()
                    .map(|&(s, k)| if k > 0 { s / k as f64 } else { f64::NAN }),
            );
        }
        BlockMeans {
            block: b,
            width: bw,
            height: bh,
            means,
        }
    }

    /// Every pixel replaced by its luminance (Rec. 709 weights) in all three channels: what a
    /// colour camera and a monochrome one can both be compared in.
    pub fn to_luminance(&mut self) {
        for p in &mut self.data {
            let y = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
            *p = [y; 3];
        }
    }

    /// Smooths the colour (BT.601 Cb and Cr, as JPEG stores it) with the binomial `[1 2 1] / 4`
    /// along each axis asked for, and keeps the luma as it is: what a file whose chroma was stored
    /// at half resolution (JPEG 4:2:0 or 4:2:2) holds is the luma's detail, and colour whose
    /// finest detail the decoder's interpolation made up on the file's pixel grid, different in
    /// every camera. The filter is zero at the full grid's Nyquist frequency. Since RGB → YCbCr
    /// is linear, this is the smoothed RGB plus the luma the smoothing took away, in all three
    /// channels. Borders repeat their edge pixel. (Hand-written: a 3-tap filter on our own type.)
    pub fn smooth_chroma(&mut self, horizontal: bool, vertical: bool) {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 || !(horizontal || vertical) {
            return;
        }
        let luma = |p: [f32; 3]| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
        let tap3 = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| {
            [0, 1, 2].map(|k| 0.25 * a[k] + 0.5 * b[k] + 0.25 * c[k])
        };
        // The horizontal pass into one buffer; the vertical pass (or the buffer itself) and the
        // luma put back written straight into the image, row by row.
        let mut rows = self.data.clone();
        if horizontal {
            for (src, dst) in self.data.chunks_exact(w).zip(rows.chunks_exact_mut(w)) {
                for (x, out) in dst.iter_mut().enumerate() {
                    *out = tap3(src[x.saturating_sub(1)], src[x], src[(x + 1).min(w - 1)]);
                }
            }
        }
        for (y, dst) in self.data.chunks_exact_mut(w).enumerate() {
            let (up, down) = (y.saturating_sub(1) * w, (y + 1).min(h - 1) * w);
            for (x, p) in dst.iter_mut().enumerate() {
                let s = if vertical {
                    tap3(rows[up + x], rows[y * w + x], rows[down + x])
                } else {
                    rows[y * w + x]
                };
                let dy = luma(*p) - luma(s);
                *p = [s[0] + dy, s[1] + dy, s[2] + dy];
            }
        }
    }

    /// Whether a bilinear sample at `(u, v)` touches only pixels inside the image.
    #[inline]
    pub fn inside(&self, u: f64, v: f64) -> bool {
        u >= 0.0 && v >= 0.0 && u <= (self.width - 1) as f64 && v <= (self.height - 1) as f64
    }

    /// Bilinear sample at `(u, v)`, or `None` outside `[0, w-1] × [0, h-1]`.
    #[inline]
    pub fn sample(&self, u: f64, v: f64) -> Option<[f32; 3]> {
        if !self.inside(u, v) {
            return None;
        }
        Some(self.sample_unchecked(u, v))
    }

    /// Bilinear sample at a point known to be inside (see [`RgbImage::inside`]).
    #[inline]
    pub fn sample_unchecked(&self, u: f64, v: f64) -> [f32; 3] {
        let ([a, b, c, d], fx, fy) = self.taps(u, v);
        let mut out = [0.0f32; 3];
        for ch in 0..3 {
            let top = a[ch] + (b[ch] - a[ch]) * fx;
            let bot = c[ch] + (d[ch] - c[ch]) * fx;
            out[ch] = top + (bot - top) * fy;
        }
        out
    }

    /// Bilinear sample of the colour with the *exact* derivatives of that bilinear interpolant,
    /// `[r, g, b, ∂r/∂u, ∂g/∂u, ∂b/∂u, ∂r/∂v, ∂g/∂v, ∂b/∂v]`, or `None` outside
    /// `[0, w-1] × [0, h-1]`. The tracker uses this: its Jacobian is then the true derivative of
    /// the cost it evaluates, so Gauss–Newton's fixed point is the cost's own stationary point
    /// rather than one shifted by a gradient approximation. It reads only the four colours around
    /// `(u, v)`, so the tracker's images need no stored gradients.
    #[inline(always)]
    pub fn sample_exact(&self, u: f64, v: f64) -> Option<[f32; 9]> {
        if !self.inside(u, v) {
            return None;
        }
        let ([a, b, c, d], fx, fy) = self.taps(u, v);
        let mut out = [0.0f32; 9];
        for k in 0..3 {
            let top = a[k] + (b[k] - a[k]) * fx;
            let bottom = c[k] + (d[k] - c[k]) * fx;
            out[k] = top + (bottom - top) * fy;
            out[3 + k] = (1.0 - fy) * (b[k] - a[k]) + fy * (d[k] - c[k]);
            out[6 + k] = bottom - top;
        }
        Some(out)
    }

    /// Bicubic sample of the colour with the exact derivatives of that bicubic interpolant, in the
    /// layout of [`RgbImage::sample_exact`], or `None` outside `[0, w-1] × [0, h-1]`.
    ///
    /// The kernel is Catmull–Rom's (Keys' cubic convolution with `a = −½`): it passes through
    /// the pixel values, reproduces quadratics exactly, and its derivatives are continuous across
    /// pixel boundaries. The tracker uses it because a sub-pixel shift of the bilinear interpolant
    /// is not a shift of the image: its error depends on the sample's phase in the pixel and its
    /// derivative jumps from one pixel to the next, which leaves a small, texture-dependent bias
    /// in the solved positions (on the Blender sample it shows as depth error across the narrow
    /// baseline). It reads the 4×4 pixels around `(u, v)`; beyond the border the edge pixels are
    /// repeated.
    #[inline(always)]
    pub fn sample_cubic(&self, u: f64, v: f64) -> Option<[f32; 9]> {
        if !self.inside(u, v) {
            return None;
        }
        let (w, h) = (self.width, self.height);
        let x0 = (u as usize).min(w.saturating_sub(2));
        let y0 = (v as usize).min(h.saturating_sub(2));
        let (wx, dwx) = catmull_rom((u - x0 as f64) as f32);
        let (wy, dwy) = catmull_rom((v - y0 as f64) as f32);
        // The 4×4 block around the sample, one row of four RGB pixels (12 numbers) at a time,
        // as three 4-lane vectors: the vertical pass runs on whole vectors (SSE on any x86-64;
        // the compiler left the flat loop scalar, docs/speed.md 2026-11-28). Each lane sees the
        // same multiplications and additions in the same order as a scalar loop would, so the
        // result is the same to the bit (`cubic_lanes_match_the_scalar_sample_to_the_bit`).
        let mut block = [[f32x4::ZERO; 3]; 4];
        if x0 >= 1 && x0 + 2 < w && y0 >= 1 && y0 + 2 < h {
            for (j, row) in block.iter_mut().enumerate() {
                let start = (y0 + j - 1) * w + x0 - 1;
                let p = &self.data[start..start + 4];
                *row = [
                    f32x4::new([p[0][0], p[0][1], p[0][2], p[1][0]]),
                    f32x4::new([p[1][1], p[1][2], p[2][0], p[2][1]]),
                    f32x4::new([p[2][2], p[3][0], p[3][1], p[3][2]]),
                ];
            }
        } else {
            for (j, row) in block.iter_mut().enumerate() {
                let y = (y0 + j).saturating_sub(1).min(h - 1);
                let mut flat = [0.0f32; 12];
                for (i, px) in flat.chunks_exact_mut(3).enumerate() {
                    px.copy_from_slice(&self.data[y * w + (x0 + i).saturating_sub(1).min(w - 1)]);
                }
                *row =
                    [0, 4, 8].map(|k| f32x4::new([flat[k], flat[k + 1], flat[k + 2], flat[k + 3]]));
            }
        }
        // Vertical pass (value weights and their derivative), then horizontal.
        let mut col = [f32x4::ZERO; 3];
        let mut col_dv = [f32x4::ZERO; 3];
        for (j, row) in block.iter().enumerate() {
            let (a, da) = (f32x4::splat(wy[j]), f32x4::splat(dwy[j]));
            for q in 0..3 {
                col[q] += a * row[q];
                col_dv[q] += da * row[q];
            }
        }
        // Pixel `i`'s three channels are lanes 3i..3i+3 of the twelve (padded to sixteen, so
        // that each pixel's channels load as one vector; the fourth lane is not used).
        let flat = |v: [f32x4; 3]| {
            let mut f = [0.0f32; 16];
            for (q, v) in v.iter().enumerate() {
                f[4 * q..4 * q + 4].copy_from_slice(&v.to_array());
            }
            f
        };
        let (c, cdv) = (flat(col), flat(col_dv));
        let at = |f: &[f32; 16], i: usize| {
            f32x4::new([f[3 * i], f[3 * i + 1], f[3 * i + 2], f[3 * i + 3]])
        };
        let (mut val, mut du, mut dv) = (f32x4::ZERO, f32x4::ZERO, f32x4::ZERO);
        for i in 0..4 {
            let (ci, cdi) = (at(&c, i), at(&cdv, i));
            val += f32x4::splat(wx[i]) * ci;
            du += f32x4::splat(dwx[i]) * ci;
            dv += f32x4::splat(wx[i]) * cdi;
        }
        let (val, du, dv) = (val.to_array(), du.to_array(), dv.to_array());
        let mut out = [0.0f32; 9];
        out[..3].copy_from_slice(&val[..3]);
        out[3..6].copy_from_slice(&du[..3]);
        out[6..].copy_from_slice(&dv[..3]);
        Some(out)
    }

    /// Catmull–Rom bicubic sample of the colour alone (no derivatives) at `(u, v)` within
    /// `[0, w-1] × [0, h-1]` (clamped into it); beyond the border the edge pixels are repeated.
    /// Used to resample whole frames (undistortion), where the derivatives are not needed.
    pub fn sample_cubic_value(&self, u: f32, v: f32) -> [f32; 3] {
        let (w, h) = (self.width, self.height);
        let u = u.clamp(0.0, (w - 1) as f32);
        let v = v.clamp(0.0, (h - 1) as f32);
        let x0 = (u as usize).min(w.saturating_sub(2));
        let y0 = (v as usize).min(h.saturating_sub(2));
        let (wx, _) = catmull_rom(u - x0 as f32);
        let (wy, _) = catmull_rom(v - y0 as f32);
        let mut out = [0.0f32; 3];
        if x0 >= 1 && x0 + 2 < w && y0 >= 1 && y0 + 2 < h {
            // Inside: four contiguous taps per row, no clamping.
            for (j, wyj) in wy.iter().enumerate() {
                let start = (y0 + j - 1) * w + x0 - 1;
                let taps = &self.data[start..start + 4];
                let mut acc = [0.0f32; 3];
                for (px, wxi) in taps.iter().zip(&wx) {
                    for k in 0..3 {
                        acc[k] += wxi * px[k];
                    }
                }
                for k in 0..3 {
                    out[k] += wyj * acc[k];
                }
            }
            return out;
        }
        for (j, wyj) in wy.iter().enumerate() {
            let y = (y0 + j).saturating_sub(1).min(h - 1);
            let row = &self.data[y * w..(y + 1) * w];
            let mut acc = [0.0f32; 3];
            for (i, wxi) in wx.iter().enumerate() {
                let px = row[(x0 + i).saturating_sub(1).min(w - 1)];
                for k in 0..3 {
                    acc[k] += wxi * px[k];
                }
            }
            for k in 0..3 {
                out[k] += wyj * acc[k];
            }
        }
        out
    }

    /// The four pixels around a point inside the image and the fractional position between them.
    #[inline(always)]
    fn taps(&self, u: f64, v: f64) -> ([[f32; 3]; 4], f32, f32) {
        let x0 = (u as usize).min(self.width.saturating_sub(2));
        let y0 = (v as usize).min(self.height.saturating_sub(2));
        let fx = (u - x0 as f64) as f32;
        let fy = (v - y0 as f64) as f32;
        let x1 = (x0 + 1).min(self.width - 1);
        let y1 = (y0 + 1).min(self.height - 1);
        let (r0, r1) = (y0 * self.width, y1 * self.width);
        (
            [
                self.data[r0 + x0],
                self.data[r0 + x1],
                self.data[r1 + x0],
                self.data[r1 + x1],
            ],
            fx,
            fy,
        )
    }

    /// Central-difference gradients `(∂I/∂u, ∂I/∂v)` per channel (one-sided at the border).
    pub fn gradients(&self) -> (RgbImage, RgbImage) {
        let (w, h) = (self.width, self.height);
        let mut gx = RgbImage::new(w, h);
        let mut gy = RgbImage::new(w, h);
        for y in 0..h {
            let (ym, yp) = (y.saturating_sub(1), (y + 1).min(h - 1));
            for x in 0..w {
                let (xm, xp) = (x.saturating_sub(1), (x + 1).min(w - 1));
                let sx = if xp > xm { 1.0 / (xp - xm) as f32 } else { 0.0 };
                let sy = if yp > ym { 1.0 / (yp - ym) as f32 } else { 0.0 };
                let (l, r) = (self.get(xm, y), self.get(xp, y));
                let (u, d) = (self.get(x, ym), self.get(x, yp));
                gx.set(
                    x,
                    y,
                    [(r[0] - l[0]) * sx, (r[1] - l[1]) * sx, (r[2] - l[2]) * sx],
                );
                gy.set(
                    x,
                    y,
                    [(d[0] - u[0]) * sy, (d[1] - u[1]) * sy, (d[2] - u[2]) * sy],
                );
            }
        }
        (gx, gy)
    }

    /// The image enlarged twice along each axis by Catmull–Rom interpolation (the sampler the
    /// tracker compares with): pixel `j` of the result is centred at `j / 2 - 0.25` of this
    /// one, matching [`crate::base::camera::Projection::upscaled`]; beyond the border the edge
    /// pixels are repeated.
    pub fn enlarged2(&self) -> RgbImage {
        RgbImage::from_fn(2 * self.width, 2 * self.height, |x, y| {
            self.sample_cubic_value(x as f32 * 0.5 - 0.25, y as f32 * 0.5 - 0.25)
        })
    }

    /// Half-size image by averaging 2×2 blocks (odd last rows/columns are averaged with fewer
    /// pixels). Pixel `i` of the result is centred at `2i + 0.5` of this one, matching
    /// [`crate::base::camera::Projection::downscaled`].
    pub fn downsample2(&self) -> RgbImage {
        let w2 = self.width.div_ceil(2).max(1);
        let h2 = self.height.div_ceil(2).max(1);
        RgbImage::from_fn(w2, h2, |x, y| {
            let mut acc = [0.0f32; 3];
            let mut n = 0.0f32;
            for yy in (2 * y)..(2 * y + 2).min(self.height) {
                for xx in (2 * x)..(2 * x + 2).min(self.width) {
                    let p = self.get(xx, yy);
                    acc[0] += p[0];
                    acc[1] += p[1];
                    acc[2] += p[2];
                    n += 1.0;
                }
            }
            [acc[0] / n, acc[1] / n, acc[2] / n]
        })
    }

    /// Separable Gaussian blur with standard deviation `sigma` pixels (clamped borders).
    ///
    /// Written as row operations on contiguous memory (the vertical pass adds whole rows), which
    /// the compiler vectorises; every output value is summed over the taps in the same order as a
    /// per-pixel loop would, so the result does not depend on this layout.
    pub fn blurred(&self, sigma: f64) -> RgbImage {
        if sigma <= 0.0 {
            return self.clone();
        }
        let radius = (3.0 * sigma).ceil() as isize;
        let mut kernel: Vec<f32> = (-radius..=radius)
            .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
            .collect();
        let sum: f32 = kernel.iter().sum();
        kernel.iter_mut().for_each(|k| *k /= sum);
        let (w, h) = (self.width, self.height);
        let clamp = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
        // Horizontal pass, one row at a time.
        let mut tmp = vec![[0.0f32; 3]; w * h];
        let r = radius as usize;
        for (src, dst) in self.data.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
            // Inside, each tap is one shifted run of the row added to the output's (the same
            // sums in the same order as per pixel, in a loop the compiler vectorises); the
            // border pixels clamp their taps. The first tap is assigned, not added: the buffer's
            // fresh pages are then first written, not read (a read maps the shared zero page,
            // and replacing it on the next write flushes the other cores' TLBs: 5 % of a run).
            if w > 2 * r {
                let n = 3 * (w - 2 * r);
                let (s, d) = (src.as_flattened(), dst.as_flattened_mut());
                for (k, &kv) in kernel.iter().enumerate() {
                    let run = d[3 * r..3 * r + n].iter_mut().zip(&s[3 * k..3 * k + n]);
                    if k == 0 {
                        run.for_each(|(o, p)| *o = kv * p);
                    } else {
                        run.for_each(|(o, p)| *o += kv * p);
                    }
                }
            }
            for (x, out) in dst.iter_mut().enumerate() {
                if x >= r && x + r < w {
                    continue;
                }
                let mut acc = [0.0f32; 3];
                for (k, &kv) in kernel.iter().enumerate() {
                    let p = src[clamp(x as isize + k as isize - radius, w)];
                    acc[0] += kv * p[0];
                    acc[1] += kv * p[1];
                    acc[2] += kv * p[2];
                }
                *out = acc;
            }
        }
        // Vertical pass: each output row accumulates whole source rows.
        let mut out = vec![[0.0f32; 3]; w * h];
        for (y, dst) in out.chunks_exact_mut(w).enumerate() {
            let dst = dst.as_flattened_mut();
            for (k, &kv) in kernel.iter().enumerate() {
                let sy = clamp(y as isize + k as isize - radius, h);
                let src = tmp[sy * w..(sy + 1) * w].as_flattened();
                // The first tap assigned (see the horizontal pass).
                if k == 0 {
                    for (d, s) in dst.iter_mut().zip(src) {
                        *d = kv * s;
                    }
                } else {
                    for (d, s) in dst.iter_mut().zip(src) {
                        *d += kv * s;
                    }
                }
            }
        }
        RgbImage {
            width: w,
            height: h,
            data: out,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> RgbImage {
        RgbImage::from_fn(8, 6, |x, y| [x as f32, y as f32, (x + 10 * y) as f32])
    }

    #[test]
    fn smoothing_the_chroma_keeps_every_pixels_luma_and_spreads_colour_by_1_2_1() {
        let y = |p: [f32; 3]| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
        // A grey ramp has no colour: nothing changes.
        let mut grey = RgbImage::from_fn(7, 5, |x, y| [(x + y) as f32 * 0.1; 3]);
        let before = grey.clone();
        grey.smooth_chroma(true, true);
        for (a, b) in grey.pixels().iter().zip(before.pixels()) {
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-6, "{a:?} vs {b:?}");
            }
        }
        // One red dot on grey: its colour (RGB minus luma) spreads as [1 2 1]/4 along each axis
        // asked for, the luma of every pixel stays.
        let dot = |x: usize, y: usize| {
            if (x, y) == (3, 2) {
                [0.9, 0.2, 0.2]
            } else {
                [0.5; 3]
            }
        };
        let chroma = |p: [f32; 3]| [p[0] - y(p), p[2] - y(p)];
        let c0 = chroma(dot(3, 2));
        for (axes, weight) in [
            ([true, true], [[0.0625, 0.125], [0.125, 0.25]]),
            ([true, false], [[0.0, 0.0], [0.25, 0.5]]),
        ] {
            let mut img = RgbImage::from_fn(7, 5, dot);
            img.smooth_chroma(axes[0], axes[1]);
            for j in 0..5 {
                for i in 0..7 {
                    let p = img.get(i, j);
                    assert!((y(p) - y(dot(i, j))).abs() < 1e-6, "luma at ({i}, {j})");
                    let (di, dj) = (i.abs_diff(3), j.abs_diff(2));
                    let w = if di <= 1 && dj <= 1 {
                        weight[1 - dj][1 - di]
                    } else {
                        0.0
                    };
                    let c = chroma(p);
                    for k in 0..2 {
                        assert!(
                            (c[k] - w * c0[k]).abs() < 1e-6,
                            "{axes:?} ({i}, {j}): {c:?} vs {w} x {c0:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn an_image_enlarged_twice_has_its_pixels_where_the_enlarged_camera_looks() {
        // Pixel (i, j) of the enlarged image is the original at (i/2 - 1/4, j/2 - 1/4)
        // (`Projection::upscaled`). Catmull–Rom reproduces a linear ramp exactly away from the
        // border, where the edge pixels are repeated.
        let img = ramp();
        let big = img.enlarged2();
        assert_eq!((big.width(), big.height()), (16, 12));
        for j in 3..9 {
            for i in 3..13 {
                let (u, v) = (i as f32 / 2.0 - 0.25, j as f32 / 2.0 - 0.25);
                let p = big.get(i, j);
                let want = [u, v, u + 10.0 * v];
                for k in 0..3 {
                    assert!(
                        (p[k] - want[k]).abs() < 1e-4,
                        "({i}, {j}): {p:?} vs {want:?}"
                    );
                }
            }
        }
        // At the border the edge is repeated: no value beyond the original's range.
        assert_eq!(big.get(0, 0), [0.0, 0.0, 0.0]);
        assert!(big.pixels().iter().all(|p| p[0] <= 7.0 && p[1] <= 5.0));
    }

    /// The bicubic sample as a plain scalar loop over the 4×4 block (the implementation before
    /// the vertical pass ran on 4-lane vectors): every lane must match it to the bit.
    fn cubic_scalar(img: &RgbImage, u: f64, v: f64) -> Option<[f32; 9]> {
        if !img.inside(u, v) {
            return None;
        }
        let (w, h) = (img.width, img.height);
        let x0 = (u as usize).min(w.saturating_sub(2));
        let y0 = (v as usize).min(h.saturating_sub(2));
        let (wx, dwx) = catmull_rom((u - x0 as f64) as f32);
        let (wy, dwy) = catmull_rom((v - y0 as f64) as f32);
        let mut block = [[0.0f32; 12]; 4];
        for (j, row) in block.iter_mut().enumerate() {
            let y = (y0 + j).saturating_sub(1).min(h - 1);
            for (i, px) in row.chunks_exact_mut(3).enumerate() {
                px.copy_from_slice(&img.data[y * w + (x0 + i).saturating_sub(1).min(w - 1)]);
            }
        }
        let mut col = [0.0f32; 12];
        let mut col_dv = [0.0f32; 12];
        for (j, row) in block.iter().enumerate() {
            for m in 0..12 {
                col[m] += wy[j] * row[m];
                col_dv[m] += dwy[j] * row[m];
            }
        }
        let mut out = [0.0f32; 9];
        for i in 0..4 {
            for k in 0..3 {
                out[k] += wx[i] * col[3 * i + k];
                out[3 + k] += dwx[i] * col[3 * i + k];
                out[6 + k] += wx[i] * col_dv[3 * i + k];
            }
        }
        Some(out)
    }

    #[test]
    fn texture_is_the_spread_of_8x8_block_means_and_a_blank_image_is_told_apart() {
        // One colour: nothing. Blocks of 8×8 alternately black and white: luminance 0 and 1
        // half each, a standard deviation of exactly 0.5; pixel noise inside a block is averaged.
        let flat = RgbImage::from_fn(64, 48, |_, _| [0.3, 0.6, 0.1]);
        assert_eq!(flat.texture(), 0.0);
        let blocks = RgbImage::from_fn(64, 48, |x, y| [((x / 8 + y / 8) % 2) as f32; 3]);
        assert!(
            (blocks.texture() - 0.5).abs() < 1e-6,
            "{}",
            blocks.texture()
        );
        let noise = RgbImage::from_fn(64, 48, |x, y| [0.02 * ((x + y) % 2) as f32; 3]);
        assert!(noise.texture() < 1e-6, "{}", noise.texture());
        // Blocks cut by the right edge are left out: a 70-pixel-wide frame measures 8 blocks.
        let cut = RgbImage::from_fn(70, 48, |x, y| [((x / 8 + y / 8) % 2) as f32; 3]);
        assert!((cut.texture() - 0.5).abs() < 1e-6);
        // Blank: below 2e-4 whatever the others show, or below 5 % of the most textured.
        assert_eq!(
            super::blank_of(&[0.0, 0.2, 0.009, 0.011, 1e-4]),
            [true, false, true, false, true]
        );
        assert_eq!(super::blank_of(&[1e-4]), [true]);
        assert_eq!(super::blank_of(&[3e-4]), [false]);
        // A black frame records no colour, but does not make a colour rig a mixed one.
        let black = RgbImage::new(64, 48);
        let colour = RgbImage::from_fn(64, 48, |x, y| [((x / 8 + y / 8) % 2) as f32, 0.2, 0.7]);
        assert!(black.is_grey() && !colour.is_grey());
        assert!(!super::mixes_grey_and_colour(&[
            black.clone(),
            colour.clone()
        ]));
        assert!(super::mixes_grey_and_colour(&[blocks, colour]));
        assert_eq!(super::blank_images(&[black, flat]), [true, true]);
    }

    #[test]
    fn a_frames_change_is_read_from_its_block_means_within_a_window() {
        // 32×24 pixels: 4×3 blocks. Grey pixels' luminance is their value (the weights sum to 1).
        let before = RgbImage::from_fn(32, 24, |_, _| [0.5; 3]).block_means();
        let after = RgbImage::from_fn(32, 24, |x, y| {
            // Block (1, 1) brighter by 0.4; one pixel of block (3, 2) brighter by 0.64 (its
            // block's mean by 0.01): pixel noise counts for a sixty-fourth.
            if (8..16).contains(&x) && (8..16).contains(&y) {
                [0.9; 3]
            } else if (x, y) == (30, 20) {
                [1.14; 3]
            } else {
                [0.5; 3]
            }
        })
        .block_means();
        let whole = after
            .change_within(&before, [0.0, 0.0, 31.0, 23.0])
            .unwrap();
        let expected = ((0.4f64.powi(2) + 0.01f64.powi(2)) / 12.0).sqrt();
        assert!(
            (whole - expected).abs() < 1e-6,
            "{whole} against {expected}"
        );
        // A window inside block (0, 0) sees no change; one reaching pixel 8 takes block (1, 1).
        assert_eq!(
            after.change_within(&before, [0.0, 0.0, 7.9, 7.9]),
            Some(0.0)
        );
        let reach = after.change_within(&before, [0.0, 0.0, 8.0, 8.0]).unwrap();
        assert!((reach - (0.16f64 / 4.0).sqrt()).abs() < 1e-6, "{reach}");
        // The same frame again: exactly nothing.
        assert_eq!(
            before.change_within(&before, [0.0, 0.0, 31.0, 23.0]),
            Some(0.0)
        );
        // Another size, or a window off the image: not measured.
        let other = RgbImage::from_fn(40, 24, |_, _| [0.5; 3]).block_means();
        assert_eq!(other.change_within(&before, [0.0, 0.0, 31.0, 23.0]), None);
        assert_eq!(after.change_within(&before, [40.0, 0.0, 50.0, 23.0]), None);
    }

    #[test]
    fn cubic_lanes_match_the_scalar_sample_to_the_bit() {
        // Irregular values (not a low-order polynomial, so no rounding hides a wrong tap), and
        // samples inside, on the border rows and columns, at pixel centres and outside.
        let img = RgbImage::from_fn(13, 9, |x, y| {
            let t = (x * 7 + y * 13) as f32;
            [
                (0.37 * t).sin(),
                (0.11 * t * t).cos(),
                0.01 * t - (0.5 * t).sin(),
            ]
        });
        let mut checked = 0;
        for j in 0..=80 {
            for i in 0..=120 {
                let (u, v) = (-0.3 + 0.1013 * i as f64, -0.2 + 0.1011 * j as f64);
                let (a, b) = (img.sample_cubic(u, v), cubic_scalar(&img, u, v));
                assert_eq!(a.is_some(), b.is_some(), "at ({u}, {v})");
                if let (Some(a), Some(b)) = (a, b) {
                    assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "at ({u}, {v})");
                    checked += 1;
                }
            }
        }
        assert!(checked > 8000, "{checked} samples inside");
        for (u, v) in [
            (0.0, 0.0),
            (12.0, 8.0),
            (0.0, 8.0),
            (6.0, 4.0),
            (11.999, 7.5),
        ] {
            assert_eq!(
                img.sample_cubic(u, v).map(|s| s.map(f32::to_bits)),
                cubic_scalar(&img, u, v).map(|s| s.map(f32::to_bits))
            );
        }
    }

    #[test]
    fn bilinear_is_exact_on_pixel_centres_and_linear_between() {
        let img = ramp();
        assert_eq!(img.sample(3.0, 2.0), Some([3.0, 2.0, 23.0]));
        let s = img.sample(2.25, 4.5).unwrap();
        assert!(
            (s[0] - 2.25).abs() < 1e-6 && (s[1] - 4.5).abs() < 1e-6 && (s[2] - 47.25).abs() < 1e-5
        );
        assert_eq!(img.sample(7.0, 5.0), Some([7.0, 5.0, 57.0]));
        assert!(img.sample(-0.01, 0.0).is_none() && img.sample(0.0, 5.01).is_none());
    }

    #[test]
    fn gradient_of_a_ramp_is_its_slope() {
        let (gx, gy) = ramp().gradients();
        assert_eq!(gx.get(3, 3), [1.0, 0.0, 1.0]);
        assert_eq!(gy.get(3, 3), [0.0, 1.0, 10.0]);
        assert_eq!(gx.get(0, 0), [1.0, 0.0, 1.0]);
    }

    #[test]
    fn downsample_centres_follow_the_convention() {
        // A linear ramp in u: averaging pixels 2i and 2i+1 gives the value at 2i + 0.5.
        let small = ramp().downsample2();
        assert_eq!((small.width(), small.height()), (4, 3));
        assert_eq!(small.get(1, 1)[0], 2.5);
        assert_eq!(small.get(1, 1)[1], 2.5);
    }

    #[test]
    fn blur_preserves_constant_and_mean() {
        let img = RgbImage::from_fn(9, 9, |_, _| [0.25, 0.5, 0.75]);
        let b = img.blurred(1.5);
        for p in b.pixels() {
            assert!((p[0] - 0.25).abs() < 1e-6 && (p[2] - 0.75).abs() < 1e-6);
        }
    }

    /// Checks a sampler's derivatives (entries 3..9) against central differences of its values.
    fn assert_derivatives_match(
        sample: impl Fn(f64, f64) -> Option<[f32; 9]>,
        u: f64,
        v: f64,
        tol: f32,
    ) {
        let h = 1e-3;
        let at = |u: f64, v: f64| sample(u, v).unwrap();
        let s = at(u, v);
        for k in 0..3 {
            let gu = (at(u + h, v)[k] - at(u - h, v)[k]) / (2.0 * h as f32);
            let gv = (at(u, v + h)[k] - at(u, v - h)[k]) / (2.0 * h as f32);
            assert!(
                (s[3 + k] - gu).abs() < tol,
                "du {k} at ({u}, {v}): {} vs {gu}",
                s[3 + k]
            );
            assert!(
                (s[6 + k] - gv).abs() < tol,
                "dv {k} at ({u}, {v}): {} vs {gv}",
                s[6 + k]
            );
        }
    }

    #[test]
    fn sample_exact_gives_the_bilinear_value_and_its_derivatives() {
        let img = RgbImage::from_fn(8, 6, |x, y| {
            [
                (x * x) as f32 * 0.1,
                (x * y) as f32,
                ((x + 2 * y) % 5) as f32,
            ]
        });
        for &(u, v) in &[(2.3, 1.6), (0.1, 4.7), (6.5, 0.2)] {
            let (s, c) = (img.sample_exact(u, v).unwrap(), img.sample(u, v).unwrap());
            assert!((0..3).all(|k| (s[k] - c[k]).abs() < 1e-6));
            // Bilinear is linear in u (and in v) inside a cell: central differences are exact.
            assert_derivatives_match(|u, v| img.sample_exact(u, v), u, v, 2e-3);
        }
        assert!(img.sample_exact(7.01, 1.0).is_none() && img.sample_exact(1.0, -0.01).is_none());
    }

    #[test]
    fn sample_cubic_passes_through_the_pixels_and_reproduces_quadratics() {
        // Quadratic in u and v per channel: Catmull–Rom is exact for it away from the border.
        let q = |u: f64, v: f64| [0.01 * u * u, 0.02 * u * v, 0.5 + 0.1 * u - 0.03 * v * v];
        let img = RgbImage::from_fn(12, 10, |x, y| q(x as f64, y as f64).map(|c| c as f32));
        for &(u, v) in &[(3.0, 4.0), (4.25, 5.5), (7.9, 3.1), (5.5, 6.75)] {
            let s = img.sample_cubic(u, v).unwrap();
            let want = q(u, v);
            let du = [0.02 * u, 0.02 * v, 0.1];
            let dv = [0.0, 0.02 * u, -0.06 * v];
            for k in 0..3 {
                assert!(
                    (s[k] as f64 - want[k]).abs() < 1e-5,
                    "value {k} at ({u}, {v})"
                );
                assert!(
                    (s[3 + k] as f64 - du[k]).abs() < 1e-5,
                    "du {k} at ({u}, {v})"
                );
                assert!(
                    (s[6 + k] as f64 - dv[k]).abs() < 1e-5,
                    "dv {k} at ({u}, {v})"
                );
            }
        }
        // Any image: the interpolant passes through every pixel value, border pixels included.
        let img = RgbImage::from_fn(7, 5, |x, y| {
            [((x * 5 + y * 3) % 7) as f32, (x * y) as f32, 1.0]
        });
        for y in 0..5 {
            for x in 0..7 {
                let s = img.sample_cubic(x as f64, y as f64).unwrap();
                assert_eq!([s[0], s[1], s[2]], img.get(x, y), "pixel ({x}, {y})");
            }
        }
        assert!(img.sample_cubic(6.01, 1.0).is_none() && img.sample_cubic(1.0, -0.01).is_none());
    }

    #[test]
    fn sample_cubic_derivatives_are_exact_and_continuous() {
        let img = RgbImage::from_fn(9, 8, |x, y| {
            [
                ((x * 7 + y * 3) % 5) as f32,
                ((x * x + y) % 4) as f32,
                (y % 3) as f32,
            ]
        });
        // Inside cells, at the border, and just either side of a pixel boundary (u = 4).
        for &(u, v) in &[
            (2.3, 1.6),
            (0.2, 6.8),
            (7.7, 3.4),
            (4.0 - 1e-4, 2.5),
            (4.0 + 1e-4, 2.5),
        ] {
            assert_derivatives_match(|u, v| img.sample_cubic(u, v), u, v, 1e-2);
        }
        let (a, b) = (
            img.sample_cubic(4.0 - 1e-6, 2.5).unwrap(),
            img.sample_cubic(4.0 + 1e-6, 2.5).unwrap(),
        );
        for k in 0..9 {
            assert!(
                (a[k] - b[k]).abs() < 1e-4,
                "component {k} jumps at a pixel boundary"
            );
        }
    }

    #[test]
    fn blur_is_the_clamped_convolution_to_the_bit_at_the_border_and_inside() {
        // Every tap clamped into the image, summed pixel by pixel in kernel order: what the
        // blur computes, however it arranges the loops.
        fn reference(img: &RgbImage, sigma: f64) -> RgbImage {
            let r = (3.0 * sigma).ceil() as isize;
            let mut k: Vec<f32> = (-r..=r)
                .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
                .collect();
            let sum: f32 = k.iter().sum();
            k.iter_mut().for_each(|v| *v /= sum);
            let (w, h) = (img.width() as isize, img.height() as isize);
            let pass = |src: &RgbImage, dx: isize, dy: isize| {
                RgbImage::from_fn(w as usize, h as usize, |x, y| {
                    let mut acc = [0.0f32; 3];
                    for (t, &kv) in k.iter().enumerate() {
                        let o = t as isize - r;
                        let sx = (x as isize + o * dx).clamp(0, w - 1) as usize;
                        let sy = (y as isize + o * dy).clamp(0, h - 1) as usize;
                        let p = src.get(sx, sy);
                        for c in 0..3 {
                            acc[c] += kv * p[c];
                        }
                    }
                    acc
                })
            };
            pass(&pass(img, 1, 0), 0, 1)
        }
        for (w, h, sigma) in [(23, 9, 1.0), (5, 7, 1.0), (40, 12, 2.2), (7, 7, 1.2)] {
            let img = RgbImage::from_fn(w, h, |x, y| {
                let t = (x * 31 + y * 17) as f32;
                [
                    (t * 0.37).sin(),
                    (t * 0.11).cos(),
                    (x as f32) / (1.0 + y as f32),
                ]
            });
            let (got, want) = (img.blurred(sigma), reference(&img, sigma));
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(
                        got.get(x, y),
                        want.get(x, y),
                        "{w}x{h}, sigma {sigma}: ({x}, {y})"
                    );
                }
            }
        }
    }

    #[test]
    fn blur_of_an_impulse_is_the_separable_gaussian() {
        let mut img = RgbImage::new(15, 11);
        img.set(7, 5, [1.0, 2.0, 0.0]);
        let b = img.blurred(1.0);
        let g = |d: f64| (-d * d / 2.0).exp();
        let norm: f64 = (-3..=3).map(|i| g(i as f64)).sum();
        for y in 0..11 {
            for x in 0..15 {
                let (dx, dy) = (x as f64 - 7.0, y as f64 - 5.0);
                let want = if dx.abs() <= 3.0 && dy.abs() <= 3.0 {
                    g(dx) * g(dy) / (norm * norm)
                } else {
                    0.0
                };
                let p = b.get(x, y);
                assert!((p[0] as f64 - want).abs() < 1e-7, "({x}, {y})");
                assert!((p[1] as f64 - 2.0 * want).abs() < 2e-7 && p[2] == 0.0);
            }
        }
    }
}

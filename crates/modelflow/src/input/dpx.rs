//! DPX (SMPTE 268M) image files: the plate format of film scans and of many VFX pipelines, which
//! the `image` crate does not read. Hand-written, as no maintained Rust crate decodes DPX; only
//! what footage for tracking needs: the first image element, uncompressed, top-left origin, RGB,
//! RGBA, ABGR or luma, 8, 10, 12 or 16 bits per sample, either byte order, and for 10 and 12 bits
//! the "filled, method A" packing (samples in the high bits of their 32- or 16-bit container)
//! that OpenImageIO, Nuke and ffmpeg write. Anything else is refused with the header field that
//! says it.
//!
//! Values are the code values over the largest code (`v / 1023` for 10 bits), as stored: a
//! log-encoded scan (transfer "printing density") stays log. The tracker compares frames with a
//! brightness gain per triangle and camera, so a transfer curve shared by all frames does not
//! move the mesh.

use crate::base::image::RgbImage;
use crate::error::{Error, Result};
use std::path::Path;

/// Whether `head` (the file's first bytes) starts like a DPX file, in either byte order.
pub(crate) fn is_dpx(head: &[u8]) -> bool {
    head.starts_with(b"SDPX") || head.starts_with(b"XPDS")
}

/// Bytes of the header that [`layout`] reads.
pub(crate) const HEADER_LEN: usize = ELEMENT + 72;

/// Offsets into the generic header (SMPTE 268M, section 3).
const IMAGE_OFFSET: usize = 4;
const ORIENTATION: usize = 768;
const ELEMENTS: usize = 770;
const WIDTH: usize = 772;
const HEIGHT: usize = 776;
/// The first image element's descriptor block, 72 bytes.
const ELEMENT: usize = 780;

struct Reader<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    big: bool,
}

impl Reader<'_> {
    fn u8(&self, at: usize) -> u8 {
        self.bytes[at]
    }
    fn u16(&self, at: usize) -> u16 {
        let b = [self.bytes[at], self.bytes[at + 1]];
        if self.big {
            u16::from_be_bytes(b)
        } else {
            u16::from_le_bytes(b)
        }
    }
    fn u32(&self, at: usize) -> u32 {
        let b: [u8; 4] = self.bytes[at..at + 4].try_into().expect("four bytes");
        if self.big {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        }
    }
    fn refuse(&self, field: &str, why: String) -> Error {
        Error::invalid(self.path, field, why)
    }
}

/// The header fields that decide how the pixels are laid out.
#[derive(Debug)]
pub(crate) struct Layout {
    pub width: usize,
    pub height: usize,
    /// Samples per pixel and where R, G and B are among them.
    channels: usize,
    rgb: [usize; 3],
    bits: u32,
    /// Bytes from the file's start to the first pixel.
    data: usize,
    /// Bytes per row (rows start on 32-bit boundaries).
    row: usize,
}

/// Reads and checks the header of a DPX file (named `path` in errors) of `file_len` bytes, whose
/// first bytes are `bytes` (at least its header).
pub(crate) fn layout(path: &Path, bytes: &[u8], file_len: usize) -> Result<Layout> {
    if bytes.len() < HEADER_LEN || !is_dpx(bytes) {
        return Err(Error::invalid(
            path,
            "header",
            format!(
                "not a DPX file: {} bytes, where a DPX header (starting \"SDPX\" or \"XPDS\") has {HEADER_LEN}",
                bytes.len()
            ),
        ));
    }
    let r = Reader {
        path,
        bytes,
        big: bytes.starts_with(b"SDPX"),
    };
    let orientation = r.u16(ORIENTATION);
    if orientation != 0 {
        return Err(r.refuse(
            "orientation",
            format!("{orientation}: only 0 (left to right, top to bottom) is read; re-save the plate with the default orientation"),
        ));
    }
    if r.u16(ELEMENTS) == 0 {
        return Err(r.refuse("number of image elements", "0".into()));
    }
    let (width, height) = (r.u32(WIDTH) as usize, r.u32(HEIGHT) as usize);
    if width == 0 || height == 0 || width > 1 << 16 || height > 1 << 16 {
        return Err(r.refuse(
            "size",
            format!("{width} × {height}: expected 1 to 65536 pixels each way"),
        ));
    }
    if r.u32(ELEMENT) != 0 {
        return Err(r.refuse(
            "data sign",
            "signed samples: only unsigned ones are read".into(),
        ));
    }
    let descriptor = r.u8(ELEMENT + 20);
    let (channels, rgb) = match descriptor {
        6 => (1, [0, 0, 0]),
        50 => (3, [0, 1, 2]),
        51 => (4, [0, 1, 2]),
        52 => (4, [3, 2, 1]),
        d => {
            return Err(r.refuse(
                "descriptor",
                format!("{d}: only luma (6), RGB (50), RGBA (51) and ABGR (52) are read"),
            ))
        }
    };
    let bits = u32::from(r.u8(ELEMENT + 23));
    let packing = r.u16(ELEMENT + 24);
    let encoding = r.u16(ELEMENT + 26);
    if encoding != 0 {
        return Err(r.refuse(
            "encoding",
            format!("{encoding} (run-length): only uncompressed data is read"),
        ));
    }
    let samples = width * channels;
    let row = match (bits, packing) {
        (8, _) => samples.div_ceil(4) * 4,
        (16, _) | (12, 1) => (2 * samples).div_ceil(4) * 4,
        (10, 1) => samples.div_ceil(3) * 4,
        (10 | 12, p) => {
            return Err(r.refuse(
                "packing",
                format!("{p} with {bits} bits: only filled method A (1) is read, as OpenImageIO, Nuke and ffmpeg write it; re-save the plate with it"),
            ))
        }
        (b, _) => {
            return Err(r.refuse(
                "bit size",
                format!("{b}: only 8, 10, 12 and 16 bits per sample are read"),
            ))
        }
    };
    let data = match r.u32(ELEMENT + 28) {
        0 => r.u32(IMAGE_OFFSET),
        o => o,
    } as usize;
    let need = data + row * height;
    if file_len < need {
        return Err(r.refuse(
            "image data",
            format!(
                "the file ends before its pixels do: {file_len} bytes, where {width} × {height} pixels from byte {data} need {need}; it is truncated or still being written"
            ),
        ));
    }
    Ok(Layout {
        width,
        height,
        channels,
        rgb,
        bits,
        data,
        row,
    })
}

/// Decodes the DPX file `bytes` (named `path` in errors) as RGB in [0, 1].
pub(crate) fn decode(path: &Path, bytes: &[u8]) -> Result<RgbImage> {
    let l = layout(path, bytes, bytes.len())?;
    let r = Reader {
        path,
        bytes,
        big: bytes.starts_with(b"SDPX"),
    };
    // Divided, not multiplied by the reciprocal: the same values to the bit as the PNG path.
    let max = ((1u32 << l.bits) - 1) as f32;
    let samples = l.width * l.channels;
    let mut row = vec![0u16; samples];
    let mut data = Vec::with_capacity(l.width * l.height);
    for y in 0..l.height {
        let start = l.data + y * l.row;
        match l.bits {
            8 => {
                for (k, v) in row.iter_mut().enumerate() {
                    *v = u16::from(r.u8(start + k));
                }
            }
            10 => {
                // Three samples per 32-bit word, the first in its top bits, two bits of padding
                // at the bottom.
                for (k, v) in row.iter_mut().enumerate() {
                    let word = r.u32(start + 4 * (k / 3));
                    *v = ((word >> (22 - 10 * (k % 3) as u32)) & 0x3ff) as u16;
                }
            }
            // 12 bits sit in the top of their 16.
            12 => {
                for (k, v) in row.iter_mut().enumerate() {
                    *v = r.u16(start + 2 * k) >> 4;
                }
            }
            _ => {
                for (k, v) in row.iter_mut().enumerate() {
                    *v = r.u16(start + 2 * k);
                }
            }
        }
        data.extend(
            row.chunks_exact(l.channels)
                .map(|px| l.rgb.map(|c| f32::from(px[c]) / max)),
        );
    }
    RgbImage::from_pixels(l.width, l.height, data)
        .ok_or_else(|| Error::invalid(path, "size", "decoded pixel count does not match its size"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::imageio::read_rgb;

    const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/dpx");

    fn fixture(name: &str) -> std::path::PathBuf {
        Path::new(DIR).join(name)
    }

    /// Largest difference between two images of the same size, over every sample.
    fn max_diff(a: &RgbImage, b: &RgbImage) -> f32 {
        assert_eq!((a.width(), a.height()), (b.width(), b.height()));
        a.pixels()
            .iter()
            .zip(b.pixels())
            .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
            .fold(0.0, f32::max)
    }

    #[test]
    fn files_ffmpeg_wrote_read_as_the_picture_they_were_written_from() {
        // fixtures/dpx/README.md: one 16-bit PNG (ffmpeg's testsrc2, 6 × 4) written by ffmpeg as
        // DPX in each layout; each must read back as that picture to within its quantisation
        // (ffmpeg truncates to the fewer bits: up to one step of the smaller depth).
        let src = read_rgb(&fixture("src.png")).unwrap();
        for (file, step) in [
            ("rgb48be.dpx", 0.0),
            ("rgb48le.dpx", 0.0),
            ("gbrp12be.dpx", 1.0 / 4095.0),
            ("gbrp10be.dpx", 1.0 / 1023.0),
            ("gbrp10le.dpx", 1.0 / 1023.0),
            ("rgb24.dpx", 1.0 / 255.0),
            ("rgba.dpx", 1.0 / 255.0),
        ] {
            let img = read_rgb(&fixture(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
            let d = max_diff(&img, &src);
            assert!(d <= step + 1e-6, "{file}: off by {d}, one step is {step}");
        }
        // Exact values: the first pixel is (64764, 0, 0) in the PNG, 64764 >> 6 = 1011 in 10 bits.
        let ten = read_rgb(&fixture("gbrp10be.dpx")).unwrap();
        assert_eq!(ten.get(0, 0), [1011.0 / 1023.0, 0.0, 0.0]);
        // Luma: ffmpeg's own grey PNG of the same picture, sample for sample.
        let grey = read_rgb(&fixture("gray.dpx")).unwrap();
        assert_eq!(
            grey.pixels(),
            read_rgb(&fixture("gray.png")).unwrap().pixels()
        );
        assert_eq!(
            crate::input::imageio::image_size(&fixture("gbrp10le.dpx")).unwrap(),
            (6, 4)
        );
    }

    #[test]
    fn what_is_not_read_is_refused_with_its_field() {
        let dir = tempfile::tempdir().unwrap();
        let good = std::fs::read(fixture("gbrp10be.dpx")).unwrap();
        let write = |name: &str, bytes: &[u8]| {
            let p = dir.path().join(name);
            std::fs::write(&p, bytes).unwrap();
            p
        };
        let err = |p: &Path| read_rgb(p).unwrap_err().to_string();
        // Truncated: the pixels run past the end.
        let cut = write("cut.dpx", &good[..good.len() - 10]);
        let e = err(&cut);
        assert!(
            e.contains("cut.dpx") && e.contains("image data") && e.contains("truncated"),
            "{e}"
        );
        // Flipped orientation, run-length encoding, method B packing, a YCbCr descriptor.
        let patched = |name: &str, at: usize, value: &[u8]| {
            let mut b = good.clone();
            b[at..at + value.len()].copy_from_slice(value);
            write(name, &b)
        };
        for (name, at, value, field) in [
            ("flip.dpx", ORIENTATION, &[0u8, 2][..], "orientation"),
            ("rle.dpx", ELEMENT + 26, &[0, 1][..], "encoding"),
            ("methodb.dpx", ELEMENT + 24, &[0, 2][..], "packing"),
            ("ycbcr.dpx", ELEMENT + 20, &[100][..], "descriptor"),
        ] {
            let e = err(&patched(name, at, value));
            assert!(e.contains(name) && e.contains(field), "{e}");
        }
    }
}

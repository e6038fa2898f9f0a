//! Reading and writing image files as [`RgbImage`]: PNG (8/16-bit, grey or colour, with or
//! without alpha), JPEG, TIFF (8/16-bit), OpenEXR and DPX (8/10/12/16-bit) in; PNG (8- or 16-bit)
//! out. Integer samples are scaled to [0, 1] (by 1/255, 1/1023, 1/4095, 1/65535); float samples
//! are kept as they are; alpha is dropped. Decoding is the `image` crate's but for DPX
//! (`input::dpx`); this module fixes the value convention and names the file in every error.

use crate::base::image::RgbImage;
use crate::error::{Error, Result};
use crate::fsutil::write_atomic;
use image::{DynamicImage, ImageReader};
use std::path::Path;

fn decode_error(path: &Path, e: image::ImageError) -> Error {
    match e {
        image::ImageError::IoError(e) => Error::io(path, e),
        other => Error::invalid(path, "image", format!("cannot decode: {other}")),
    }
}

/// JPEG decoders fill a file that ends early with grey and report no error; a frame like that
/// would pull the mesh towards nothing. A complete JPEG has an end-of-image marker (FF D9) after
/// its last start-of-scan marker (FF DA); inside entropy-coded data FF is only ever followed by
/// 00 or a restart marker, so the check cannot be fooled by the image data. (Hand-written: no
/// crate reports truncation.)
fn check_jpeg_complete(path: &Path, bytes: &[u8]) -> Result<()> {
    let last_scan = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    let complete = match last_scan {
        Some(s) => bytes[s..].windows(2).any(|w| w == [0xFF, 0xD9]),
        None => false,
    };
    if complete {
        Ok(())
    } else {
        Err(Error::invalid(
            path,
            "image",
            format!(
                "the JPEG ends before its end-of-image marker ({} bytes): the file is truncated or still being written",
                bytes.len()
            ),
        ))
    }
}

fn open(path: &Path) -> Result<ImageReader<std::io::BufReader<std::fs::File>>> {
    ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))
}

/// Which axes of a JPEG's colour (its second and third components) are stored at a lower
/// resolution than its luma: `[horizontal, vertical]`, both for 4:2:0, the first for 4:2:2;
/// `[false, false]` for 4:4:4, a grey JPEG or a header it cannot read (the decoder then reports
/// that). Read from the start-of-frame segment's sampling factors. (Hand-written: the decoder
/// does not report them, and the header is a few bytes.)
pub(crate) fn jpeg_chroma_subsampling(bytes: &[u8]) -> [bool; 2] {
    let mut i = 2; // after the start-of-image marker FF D8
    while i + 4 <= bytes.len() {
        if bytes[i] != 0xFF {
            return [false, false];
        }
        let marker = bytes[i + 1];
        if marker == 0xFF {
            i += 1; // fill byte
            continue;
        }
        let len = u16::from_be_bytes([bytes[i + 2], bytes[i + 3]]) as usize;
        let is_frame = (0xC0..=0xCF).contains(&marker) && ![0xC4, 0xC8, 0xCC].contains(&marker);
        if is_frame {
            // P, Y, X, Nf, then per component: id, H << 4 | V, table.
            let seg = &bytes[(i + 4).min(bytes.len())..(i + 2 + len).min(bytes.len())];
            let n = *seg.get(5).unwrap_or(&0) as usize;
            if n < 3 || seg.len() < 6 + 3 * n {
                return [false, false];
            }
            let hv = |c: usize| (seg[6 + 3 * c + 1] >> 4, seg[6 + 3 * c + 1] & 0x0F);
            let (hy, vy) = hv(0);
            let ((hb, vb), (hr, vr)) = (hv(1), hv(2));
            return [hb.max(hr) < hy, vb.max(vr) < vy];
        }
        if marker == 0xDA || len < 2 {
            return [false, false]; // image data before any frame header: not a JPEG we know
        }
        i += 2 + len;
    }
    [false, false]
}

/// The turn an image file's metadata (EXIF `Orientation`, as phones and cameras write it in JPEG
/// and TIFF) asks viewers to apply, in words (`"turned 90° clockwise"`), or `None` for none, a
/// format without it, or a file it cannot read (loading it names that). modelflow reads the
/// pixels as stored and does not apply it ([`read_rgb`]).
pub fn image_orientation(path: &Path) -> Option<&'static str> {
    use image::metadata::Orientation as O;
    use image::ImageDecoder;
    let mut decoder = open(path).ok()?.into_decoder().ok()?;
    match decoder.orientation().ok()? {
        O::NoTransforms => None,
        O::Rotate90 => Some("turned 90° clockwise"),
        O::Rotate180 => Some("turned 180°"),
        O::Rotate270 => Some("turned 90° anticlockwise"),
        O::FlipHorizontal => Some("mirrored left to right"),
        O::FlipVertical => Some("mirrored top to bottom"),
        O::Rotate90FlipH => Some("turned 90° clockwise and mirrored"),
        O::Rotate270FlipH => Some("turned 90° anticlockwise and mirrored"),
    }
}

/// Reads an image file as RGB `f32` (see the module doc for the value convention).
pub fn read_rgb(path: &Path) -> Result<RgbImage> {
    read_rgb_stored(path).map(|s| s.image)
}

/// An image file as [`read_rgb`] reads it, and what its format says about its values.
pub(crate) struct Stored {
    pub image: RgbImage,
    /// The file stored floating-point values (OpenEXR, float TIFF): those are scene-linear
    /// unless the scene says otherwise (`input::transfer`).
    pub float: bool,
    /// The colour was stored at half resolution along `[x, y]` (a JPEG's chroma subsampling,
    /// [`jpeg_chroma_subsampling`]).
    pub chroma_halved: [bool; 2],
}

/// [`read_rgb`], with what [`Stored`] says about the file.
pub(crate) fn read_rgb_stored(path: &Path) -> Result<Stored> {
    crate::fsutil::require_file(path, "image")?;
    let reader = open(path)?;
    if reader.format().is_none() {
        // Not a format `image` knows from its first bytes: DPX, or an error from `image`.
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        if super::dpx::is_dpx(&bytes) {
            return super::dpx::decode(path, &bytes).map(|image| Stored {
                image,
                float: false,
                chroma_halved: [false, false],
            });
        }
    }
    let exr = reader.format() == Some(image::ImageFormat::OpenExr);
    let mut chroma_halved = [false, false];
    let img = if reader.format() == Some(image::ImageFormat::Jpeg) {
        // Read once: checked for completeness, then decoded from memory.
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        check_jpeg_complete(path, &bytes)?;
        chroma_halved = jpeg_chroma_subsampling(&bytes);
        ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::Jpeg).decode()
    } else {
        reader.decode()
    };
    let img = match img {
        Ok(img) => img,
        // No plain R, G, B channels: a multi-layer EXR, whose beauty pass is taken.
        Err(e) if exr => match read_exr_beauty(path)? {
            Some(img) => img,
            None => return Err(decode_error(path, e)),
        },
        Err(e) => return Err(decode_error(path, e)),
    };
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w == 0 || h == 0 {
        return Err(Error::invalid(path, "size", "the image is empty"));
    }
    let float = matches!(
        img,
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_)
    );
    let grey = |v: f32| [v, v, v];
    let data: Vec<[f32; 3]> = match &img {
        DynamicImage::ImageLuma8(b) => b.pixels().map(|p| grey(p.0[0] as f32 / 255.0)).collect(),
        DynamicImage::ImageLumaA8(b) => b.pixels().map(|p| grey(p.0[0] as f32 / 255.0)).collect(),
        DynamicImage::ImageRgb8(b) => b.pixels().map(|p| p.0.map(|c| c as f32 / 255.0)).collect(),
        DynamicImage::ImageRgba8(b) => b
            .pixels()
            .map(|p| [p.0[0], p.0[1], p.0[2]].map(|c| c as f32 / 255.0))
            .collect(),
        DynamicImage::ImageLuma16(b) => b.pixels().map(|p| grey(p.0[0] as f32 / 65535.0)).collect(),
        DynamicImage::ImageLumaA16(b) => {
            b.pixels().map(|p| grey(p.0[0] as f32 / 65535.0)).collect()
        }
        DynamicImage::ImageRgb16(b) => b
            .pixels()
            .map(|p| p.0.map(|c| c as f32 / 65535.0))
            .collect(),
        DynamicImage::ImageRgba16(b) => b
            .pixels()
            .map(|p| [p.0[0], p.0[1], p.0[2]].map(|c| c as f32 / 65535.0))
            .collect(),
        DynamicImage::ImageRgb32F(b) => b.pixels().map(|p| p.0).collect(),
        DynamicImage::ImageRgba32F(b) => b.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect(),
        // Any layout added to `image` later: its own conversion (same scaling).
        other => other.to_rgb32f().pixels().map(|p| p.0).collect(),
    };
    // A NaN or infinite value (possible in EXR) would make every cost that samples it
    // non-finite, and the tracker could not lower it: refused here, with where it is.
    if let Some(i) = data.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(Error::invalid(
            path,
            format!("pixel ({}, {})", i % w, i / w),
            format!(
                "value {:?} is not a finite number (NaN or infinity); the tracker needs finite values in every pixel",
                data[i]
            ),
        ));
    }
    let img = RgbImage::from_pixels(w, h, data).ok_or_else(|| {
        Error::invalid(path, "size", "decoded pixel count does not match its size")
    })?;
    Ok(Stored {
        image: img,
        float,
        chroma_halved,
    })
}

/// The beauty pass of a multi-layer OpenEXR, as Blender's "OpenEXR MultiLayer" and compositing
/// packages write it: channels named `<layer>.<pass>.R`, `.G`, `.B` (and many other passes:
/// depth, normals, ...). The pass taken is the one named `Combined` (Blender's beauty), else
/// `beauty` or `rgba` (any case), else the first with all three of R, G and B in name order.
/// `None` when no pass has them. Written by hand on top of the `exr` crate: `image` reads only
/// channels named plainly `R`, `G`, `B`.
fn read_exr_beauty(path: &Path) -> Result<Option<DynamicImage>> {
    let file = exr::prelude::read_all_flat_layers_from_file(path).map_err(|e| {
        Error::invalid(
            path,
            "image",
            format!("cannot decode the OpenEXR file: {e}"),
        )
    })?;
    // Every pass with R, G and B, as (its full name, layer, channel indices).
    let mut passes: Vec<(String, usize, [usize; 3])> = Vec::new();
    for (l, layer) in file.layer_data.iter().enumerate() {
        let prefix = layer
            .attributes
            .layer_name
            .as_ref()
            .map(|n| format!("{n}."))
            .unwrap_or_default();
        let names: Vec<String> = layer
            .channel_data
            .list
            .iter()
            .map(|c| format!("{prefix}{}", c.name))
            .collect();
        for (i, name) in names.iter().enumerate() {
            let Some(pass) = name.strip_suffix(".R") else {
                continue;
            };
            let find = |suffix: &str| names.iter().position(|n| *n == format!("{pass}{suffix}"));
            if let (Some(g), Some(b)) = (find(".G"), find(".B")) {
                passes.push((pass.to_string(), l, [i, g, b]));
            }
        }
    }
    let is = |p: &str, what: &str| {
        p.rsplit('.')
            .next()
            .is_some_and(|last| last.eq_ignore_ascii_case(what))
    };
    let chosen = passes
        .iter()
        .find(|(p, _, _)| is(p, "combined"))
        .or_else(|| passes.iter().find(|(p, _, _)| is(p, "beauty")))
        .or_else(|| passes.iter().find(|(p, _, _)| is(p, "rgba")))
        .or_else(|| passes.first());
    let Some((_, l, ch)) = chosen else {
        return Ok(None);
    };
    let layer = &file.layer_data[*l];
    let (w, h) = (layer.size.width(), layer.size.height());
    let values: Vec<Vec<f32>> = ch
        .iter()
        .map(|&c| {
            layer.channel_data.list[c]
                .sample_data
                .values_as_f32()
                .collect()
        })
        .collect();
    if values.iter().any(|v| v.len() != w * h) {
        return Err(Error::invalid(
            path,
            "image",
            "a channel of the beauty pass is subsampled; expected one sample per pixel",
        ));
    }
    let buf = image::Rgb32FImage::from_fn(w as u32, h as u32, |x, y| {
        let i = y as usize * w + x as usize;
        image::Rgb([values[0][i], values[1][i], values[2][i]])
    });
    Ok(Some(DynamicImage::ImageRgb32F(buf)))
}

/// Width and height of an image file, from its header only (fast: no pixel is decoded).
pub fn image_size(path: &Path) -> Result<(u32, u32)> {
    let reader = open(path)?;
    if reader.format().is_none() {
        use std::io::Read;
        let mut head = Vec::with_capacity(super::dpx::HEADER_LEN);
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len() as usize;
        file.take(super::dpx::HEADER_LEN as u64)
            .read_to_end(&mut head)
            .map_err(|e| Error::io(path, e))?;
        if super::dpx::is_dpx(&head) {
            let l = super::dpx::layout(path, &head, len)?;
            return Ok((l.width as u32, l.height as u32));
        }
    }
    let exr = reader.format() == Some(image::ImageFormat::OpenExr);
    match reader.into_dimensions() {
        Ok(size) => Ok(size),
        // A multi-layer EXR (no plain R, G, B): the size of its layers, from the header.
        Err(e) if exr => match exr::meta::MetaData::read_from_file(path, false) {
            Ok(meta) => match meta.headers.first() {
                Some(h) => Ok((h.layer_size.width() as u32, h.layer_size.height() as u32)),
                None => Err(decode_error(path, e)),
            },
            Err(_) => Err(decode_error(path, e)),
        },
        Err(e) => Err(decode_error(path, e)),
    }
}

fn quantise<const MAX: u32>(v: f32) -> f32 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (v * MAX as f32).round()
}

/// Writes an 8-bit RGB PNG atomically; values are clamped to [0, 1] (NaN to 0) and rounded.
pub fn write_png(path: &Path, img: &RgbImage) -> Result<()> {
    let raw: Vec<u8> = img
        .pixels()
        .iter()
        .flat_map(|p| p.map(|c| quantise::<255>(c) as u8))
        .collect();
    let buf = image::RgbImage::from_raw(img.width() as u32, img.height() as u32, raw)
        .ok_or_else(|| Error::invalid(path, "size", "the image is too large to encode"))?;
    encode_png(path, DynamicImage::ImageRgb8(buf))
}

/// Writes an 8-bit RGB JPEG atomically at `quality` (1–100); values are clamped to [0, 1].
pub fn write_jpeg(path: &Path, img: &RgbImage, quality: u8) -> Result<()> {
    let raw: Vec<u8> = img
        .pixels()
        .iter()
        .flat_map(|p| p.map(|c| quantise::<255>(c) as u8))
        .collect();
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, quality.clamp(1, 100))
        .encode(
            &raw,
            img.width() as u32,
            img.height() as u32,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| Error::invalid(path, "image", format!("cannot encode JPEG: {e}")))?;
    write_atomic(path, &bytes)
}

/// Writes a 16-bit RGB PNG atomically; values are clamped to [0, 1] (NaN to 0) and rounded.
pub fn write_png16(path: &Path, img: &RgbImage) -> Result<()> {
    let raw: Vec<u16> = img
        .pixels()
        .iter()
        .flat_map(|p| p.map(|c| quantise::<65535>(c) as u16))
        .collect();
    let buf = image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(
        img.width() as u32,
        img.height() as u32,
        raw,
    )
    .ok_or_else(|| Error::invalid(path, "size", "the image is too large to encode"))?;
    encode_png(path, DynamicImage::ImageRgb16(buf))
}

fn encode_png(path: &Path, img: DynamicImage) -> Result<()> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::invalid(path, "image", format!("cannot encode PNG: {e}")))?;
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use exr::prelude::*;

    /// A multi-layer EXR as Blender writes one: passes named `ViewLayer.<pass>.<channel>`.
    fn write_layered(path: &Path, passes: &[(&str, f32)]) {
        let (w, h) = (8usize, 4usize);
        let list: Vec<AnyChannel<FlatSamples>> = passes
            .iter()
            .map(|&(name, v)| {
                let samples = (0..w * h).map(|i| v + i as f32 * 0.001).collect();
                AnyChannel::new(name, FlatSamples::F32(samples))
            })
            .collect();
        let layer = Layer::new(
            (w, h),
            LayerAttributes::default(),
            Encoding::FAST_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(list)),
        );
        Image::from_layer(layer).write().to_file(path).unwrap();
    }

    /// A JPEG's first bytes up to its frame header: start of image, an APP0 segment, then a
    /// start-of-frame `marker` with the components' sampling factors (`H << 4 | V`).
    fn jpeg_header(marker: u8, factors: &[u8]) -> Vec<u8> {
        let mut b = vec![0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x04, b'J', b'F'];
        let len = 8 + 3 * factors.len() as u16;
        b.extend([0xFF, marker]);
        b.extend(len.to_be_bytes());
        b.extend([8, 0, 16, 0, 16, factors.len() as u8]);
        for (id, f) in factors.iter().enumerate() {
            b.extend([id as u8 + 1, *f, 0]);
        }
        b
    }

    #[test]
    fn a_jpegs_chroma_subsampling_is_read_from_its_frame_header() {
        // The real webcams' JPEGs (OpenCV's encoder): 4:2:0.
        let board = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/caliscope-board-sample/images_undist/cam0/0000.jpg"
        );
        let bytes = std::fs::read(board).unwrap();
        assert_eq!(jpeg_chroma_subsampling(&bytes), [true, true]);
        let stored = read_rgb_stored(Path::new(board)).unwrap();
        assert_eq!(stored.chroma_halved, [true, true]);
        // Baseline and progressive; 4:4:4, 4:2:2, 4:4:0, 4:2:0; a grey JPEG; not a JPEG.
        assert_eq!(
            jpeg_chroma_subsampling(&jpeg_header(0xC0, &[0x11, 0x11, 0x11])),
            [false, false]
        );
        assert_eq!(
            jpeg_chroma_subsampling(&jpeg_header(0xC0, &[0x21, 0x11, 0x11])),
            [true, false]
        );
        assert_eq!(
            jpeg_chroma_subsampling(&jpeg_header(0xC1, &[0x12, 0x11, 0x11])),
            [false, true]
        );
        assert_eq!(
            jpeg_chroma_subsampling(&jpeg_header(0xC2, &[0x22, 0x11, 0x11])),
            [true, true]
        );
        assert_eq!(
            jpeg_chroma_subsampling(&jpeg_header(0xC0, &[0x22])),
            [false, false]
        );
        // A Huffman table segment (C4) is not a frame header; the frame after it is read.
        let mut b = vec![0xFF, 0xD8, 0xFF, 0xC4, 0x00, 0x03, 0x00];
        b.extend(&jpeg_header(0xC0, &[0x22, 0x11, 0x11])[2..]);
        assert_eq!(jpeg_chroma_subsampling(&b), [true, true]);
        assert_eq!(jpeg_chroma_subsampling(b"\x89PNG\r\n"), [false, false]);
        assert_eq!(jpeg_chroma_subsampling(&[0xFF, 0xD8, 0xFF]), [false, false]);
        // PNGs are not touched.
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("a.png");
        write_png(&png, &RgbImage::new(4, 4)).unwrap();
        assert_eq!(read_rgb_stored(&png).unwrap().chroma_halved, [false, false]);
    }

    #[test]
    fn a_multi_layer_exr_gives_its_beauty_pass() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("0001.exr");
        // Another pass with R, G, B that sorts first (AO), the beauty (Combined), and passes
        // without colour (depth, normals).
        write_layered(
            &path,
            &[
                ("ViewLayer.AO.R", 9.0),
                ("ViewLayer.AO.G", 9.0),
                ("ViewLayer.AO.B", 9.0),
                ("ViewLayer.Combined.R", 0.5),
                ("ViewLayer.Combined.G", 0.25),
                ("ViewLayer.Combined.B", 1.5),
                ("ViewLayer.Combined.A", 1.0),
                ("ViewLayer.Depth.Z", 3.0),
                ("ViewLayer.Normal.X", 0.0),
                ("ViewLayer.Normal.Y", 1.0),
                ("ViewLayer.Normal.Z", 0.0),
            ],
        );
        assert_eq!(image_size(&path).unwrap(), (8, 4));
        let Stored {
            image: img, float, ..
        } = read_rgb_stored(&path).unwrap();
        assert!(float, "scene-linear, like any float EXR");
        assert_eq!((img.width(), img.height()), (8, 4));
        // Pixel (3, 2) is sample 19.
        assert_eq!(img.get(3, 2), [0.519, 0.269, 1.519]);

        // No pass with colour: the decoder's own message, naming the file.
        let bare = dir.path().join("depth.exr");
        write_layered(&bare, &[("ViewLayer.Depth.Z", 3.0)]);
        let err = read_rgb(&bare).unwrap_err().to_string();
        assert!(
            err.contains("depth.exr") && err.contains("cannot decode"),
            "{err}"
        );
    }
}

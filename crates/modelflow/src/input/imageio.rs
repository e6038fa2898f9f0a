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

/// Reads an image file as RGB `f32` (see the module doc for the value convention).
pub fn read_rgb(path: &Path) -> Result<RgbImage> {
    read_rgb_stored(path).map(|(img, _)| img)
}

/// [`read_rgb`], and whether the file stored floating-point values (OpenEXR, float TIFF):
/// those are scene-linear unless the scene says otherwise (`input::transfer`).
pub(crate) fn read_rgb_stored(path: &Path) -> Result<(RgbImage, bool)> {
    crate::fsutil::require_file(path, "image")?;
    let reader = open(path)?;
    if reader.format().is_none() {
        // Not a format `image` knows from its first bytes: DPX, or an error from `image`.
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        if super::dpx::is_dpx(&bytes) {
            return super::dpx::decode(path, &bytes).map(|img| (img, false));
        }
    }
    let img = if reader.format() == Some(image::ImageFormat::Jpeg) {
        // Read once: checked for completeness, then decoded from memory.
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        check_jpeg_complete(path, &bytes)?;
        ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::Jpeg).decode()
    } else {
        reader.decode()
    }
    .map_err(|e| decode_error(path, e))?;
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
    Ok((img, float))
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
    reader.into_dimensions().map_err(|e| decode_error(path, e))
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

//! Image files: every supported layout reads back with the documented scaling (8-bit / 255,
//! 16-bit / 65535, float as is, alpha dropped), headers give the size, and the PNG writers clamp
//! and round.

use image::{DynamicImage, ImageBuffer, ImageFormat, Luma, LumaA, Rgb, Rgba};
use modelflow::base::RgbImage;
use modelflow::input::{image_size, read_rgb, write_png, write_png16};
use std::path::{Path, PathBuf};

const W: u32 = 7;
const H: u32 = 5;

fn save(dir: &Path, name: &str, img: DynamicImage, fmt: ImageFormat) -> PathBuf {
    let p = dir.join(name);
    img.save_with_format(&p, fmt).unwrap();
    p
}

fn v8(x: u32, y: u32, c: u32) -> u8 {
    ((x * 37 + y * 11 + c * 101) % 256) as u8
}

fn v16(x: u32, y: u32, c: u32) -> u16 {
    ((x * 9973 + y * 7919 + c * 30011) % 65536) as u16
}

fn check(path: &Path, expect: impl Fn(u32, u32) -> [f32; 3]) {
    assert_eq!(image_size(path).unwrap(), (W, H), "{}", path.display());
    let img = read_rgb(path).unwrap();
    assert_eq!((img.width(), img.height()), (W as usize, H as usize));
    for y in 0..H {
        for x in 0..W {
            assert_eq!(
                img.get(x as usize, y as usize),
                expect(x, y),
                "{} at ({x}, {y})",
                path.display()
            );
        }
    }
}

#[test]
fn png_8bit_layouts() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = |v: u8| v as f32 / 255.0;
    let p = save(
        d,
        "g.png",
        DynamicImage::ImageLuma8(ImageBuffer::from_fn(W, H, |x, y| Luma([v8(x, y, 0)]))),
        ImageFormat::Png,
    );
    check(&p, |x, y| [s(v8(x, y, 0)); 3]);
    let p = save(
        d,
        "ga.png",
        DynamicImage::ImageLumaA8(ImageBuffer::from_fn(W, H, |x, y| {
            LumaA([v8(x, y, 0), v8(x, y, 3)])
        })),
        ImageFormat::Png,
    );
    check(&p, |x, y| [s(v8(x, y, 0)); 3]);
    let p = save(
        d,
        "rgb.png",
        DynamicImage::ImageRgb8(ImageBuffer::from_fn(W, H, |x, y| {
            Rgb([0, 1, 2].map(|c| v8(x, y, c)))
        })),
        ImageFormat::Png,
    );
    check(&p, |x, y| [0, 1, 2].map(|c| s(v8(x, y, c))));
    let p = save(
        d,
        "rgba.png",
        DynamicImage::ImageRgba8(ImageBuffer::from_fn(W, H, |x, y| {
            Rgba([0, 1, 2, 3].map(|c| v8(x, y, c)))
        })),
        ImageFormat::Png,
    );
    check(&p, |x, y| [0, 1, 2].map(|c| s(v8(x, y, c))));
}

#[test]
fn png_and_tiff_16bit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = |v: u16| v as f32 / 65535.0;
    let rgb16 = || {
        DynamicImage::ImageRgb16(ImageBuffer::from_fn(W, H, |x, y| {
            Rgb([0, 1, 2].map(|c| v16(x, y, c)))
        }))
    };
    let p = save(d, "rgb16.png", rgb16(), ImageFormat::Png);
    check(&p, |x, y| [0, 1, 2].map(|c| s(v16(x, y, c))));
    let p = save(
        d,
        "rgba16.png",
        DynamicImage::ImageRgba16(ImageBuffer::from_fn(W, H, |x, y| {
            Rgba([0, 1, 2, 3].map(|c| v16(x, y, c)))
        })),
        ImageFormat::Png,
    );
    check(&p, |x, y| [0, 1, 2].map(|c| s(v16(x, y, c))));
    let p = save(
        d,
        "g16.png",
        DynamicImage::ImageLuma16(ImageBuffer::from_fn(W, H, |x, y| Luma([v16(x, y, 1)]))),
        ImageFormat::Png,
    );
    check(&p, |x, y| [s(v16(x, y, 1)); 3]);
    let p = save(d, "rgb16.tif", rgb16(), ImageFormat::Tiff);
    check(&p, |x, y| [0, 1, 2].map(|c| s(v16(x, y, c))));
    let p = save(
        d,
        "rgb8.tiff",
        DynamicImage::ImageRgb8(ImageBuffer::from_fn(W, H, |x, y| {
            Rgb([0, 1, 2].map(|c| v8(x, y, c)))
        })),
        ImageFormat::Tiff,
    );
    check(&p, |x, y| [0, 1, 2].map(|c| v8(x, y, c) as f32 / 255.0));
}

#[test]
fn exr_floats_are_kept_as_they_are() {
    let dir = tempfile::tempdir().unwrap();
    // Values outside [0, 1] (HDR) and fractions that no integer format holds.
    let f = |x: u32, y: u32, c: u32| (x as f32 - 2.0) * 0.37 + y as f32 * 1.7 + c as f32 / 3.0;
    let img = ImageBuffer::<Rgb<f32>, _>::from_fn(W, H, |x, y| Rgb([0, 1, 2].map(|c| f(x, y, c))));
    let p = save(
        dir.path(),
        "hdr.exr",
        DynamicImage::ImageRgb32F(img),
        ImageFormat::OpenExr,
    );
    check(&p, |x, y| [0, 1, 2].map(|c| f(x, y, c)));
    let img =
        ImageBuffer::<Rgba<f32>, _>::from_fn(W, H, |x, y| Rgba([0, 1, 2, 3].map(|c| f(x, y, c))));
    let p = save(
        dir.path(),
        "hdra.exr",
        DynamicImage::ImageRgba32F(img),
        ImageFormat::OpenExr,
    );
    check(&p, |x, y| [0, 1, 2].map(|c| f(x, y, c)));
}

#[test]
fn non_finite_pixels_are_refused_with_their_place() {
    let dir = tempfile::tempdir().unwrap();
    let img = ImageBuffer::<Rgb<f32>, _>::from_fn(W, H, |x, y| {
        Rgb(if (x, y) == (3, 2) {
            [0.5, f32::NAN, 0.5]
        } else {
            [0.5; 3]
        })
    });
    let p = save(
        dir.path(),
        "nan.exr",
        DynamicImage::ImageRgb32F(img),
        ImageFormat::OpenExr,
    );
    let msg = read_rgb(&p).unwrap_err().to_string();
    for part in ["nan.exr", "pixel (3, 2)", "not a finite number"] {
        assert!(msg.contains(part), "{msg:?} should contain {part:?}");
    }
}

#[test]
fn a_truncated_jpeg_is_refused() {
    // JPEG decoders fill the missing part with grey without an error; the reader must not.
    let dir = tempfile::tempdir().unwrap();
    let img = ImageBuffer::from_fn(64, 48, |x, y| Rgb([(x * 4) as u8, (y * 5) as u8, 90u8]));
    let p = save(
        dir.path(),
        "whole.jpg",
        DynamicImage::ImageRgb8(img),
        ImageFormat::Jpeg,
    );
    assert!(read_rgb(&p).is_ok());
    let bytes = std::fs::read(&p).unwrap();
    let cut = dir.path().join("cut.jpg");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let msg = read_rgb(&cut).unwrap_err().to_string();
    assert!(
        msg.contains("cut.jpg") && msg.contains("truncated"),
        "{msg:?}"
    );
}

#[test]
fn jpeg_reads_close_to_what_was_written() {
    let dir = tempfile::tempdir().unwrap();
    let img = ImageBuffer::from_fn(16, 16, |_, _| Rgb([200u8, 100, 50]));
    let p = save(
        dir.path(),
        "a.jpg",
        DynamicImage::ImageRgb8(img),
        ImageFormat::Jpeg,
    );
    assert_eq!(image_size(&p).unwrap(), (16, 16));
    let back = read_rgb(&p).unwrap();
    for px in back.pixels() {
        for (c, want) in px.iter().zip([200.0, 100.0, 50.0]) {
            assert!((c * 255.0 - want).abs() <= 3.0, "{px:?}");
        }
    }
}

#[test]
fn write_png_clamps_and_rounds() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("sub/dir/out.png");
    let vals = [
        -0.5,
        0.0,
        0.499 / 255.0,
        0.501 / 255.0,
        0.5,
        1.0,
        7.0,
        f32::NAN,
    ];
    let img = RgbImage::from_fn(vals.len(), 1, |x, _| {
        [vals[x], 1.0 - vals[x].clamp(0.0, 1.0), 0.25]
    });
    write_png(&p, &img).unwrap();
    let raw = image::open(&p).unwrap().into_rgb8();
    let got: Vec<u8> = raw.pixels().map(|p| p.0[0]).collect();
    assert_eq!(got, vec![0, 0, 0, 1, 128, 255, 255, 0]);
    assert!(raw.pixels().all(|p| p.0[2] == 64));
    // 8-bit values come back exactly.
    let q = RgbImage::from_fn(W as usize, H as usize, |x, y| {
        [0, 1, 2].map(|c| v8(x as u32, y as u32, c) as f32 / 255.0)
    });
    write_png(&p, &q).unwrap();
    assert_eq!(read_rgb(&p).unwrap(), q);
}

#[test]
fn write_png16_round_trips_16bit_values() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("out16.png");
    let q = RgbImage::from_fn(W as usize, H as usize, |x, y| {
        [0, 1, 2].map(|c| v16(x as u32, y as u32, c) as f32 / 65535.0)
    });
    write_png16(&p, &q).unwrap();
    assert!(matches!(
        image::open(&p).unwrap(),
        DynamicImage::ImageRgb16(_)
    ));
    assert_eq!(read_rgb(&p).unwrap(), q);
}

#[test]
fn errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.png");
    assert!(read_rgb(&missing)
        .unwrap_err()
        .to_string()
        .contains("missing.png"));
    assert!(image_size(&missing)
        .unwrap_err()
        .to_string()
        .contains("missing.png"));
    let junk = dir.path().join("junk.png");
    std::fs::write(&junk, b"\x89PNG\r\n\x1a\nthis is not a png").unwrap();
    let msg = read_rgb(&junk).unwrap_err().to_string();
    assert!(
        msg.contains("junk.png") && msg.contains("cannot decode"),
        "{msg}"
    );
    assert!(image_size(&junk)
        .unwrap_err()
        .to_string()
        .contains("junk.png"));
    let text = dir.path().join("notes.txt");
    std::fs::write(&text, b"hello").unwrap();
    assert!(read_rgb(&text)
        .unwrap_err()
        .to_string()
        .contains("notes.txt"));
}

#[test]
fn image_size_reads_only_the_header() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("big.png");
    let noise = RgbImage::from_fn(1000, 600, |x, y| [((x * 7 + y * 13) % 97) as f32 / 96.0; 3]);
    write_png(&p, &noise).unwrap();
    // Cut the file to its first 200 bytes: the header survives, the pixels do not.
    let bytes = std::fs::read(&p).unwrap();
    assert!(bytes.len() > 10_000);
    std::fs::write(&p, &bytes[..200]).unwrap();
    assert_eq!(image_size(&p).unwrap(), (1000, 600));
    let msg = read_rgb(&p).unwrap_err().to_string();
    assert!(msg.contains("big.png"), "{msg}");
}

//! The tracker's per-pixel samplers (`RgbImage::sample_exact`, bilinear, and
//! `RgbImage::sample_cubic`, Catmull–Rom), each with its derivatives, on a textured 640×480
//! image at 4 096 sub-pixel positions spread over it: what every template pixel costs in every
//! evaluation of the solve (docs/speed.md). `cargo bench -p modelflow --bench sampling`.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use modelflow::RgbImage;

fn image() -> RgbImage {
    RgbImage::from_fn(640, 480, |x, y| {
        let (x, y) = (x as f32, y as f32);
        [
            0.5 + 0.4 * (0.21 * x + 0.13 * y).sin(),
            0.5 + 0.4 * (0.07 * x - 0.19 * y).cos(),
            0.5 + 0.4 * (0.11 * x * 0.5 + 0.05 * y).sin(),
        ]
    })
}

/// Sub-pixel positions inside the image, from a fixed sequence (a low-discrepancy walk).
fn positions() -> Vec<(f64, f64)> {
    (0..4096)
        .map(|i| {
            let i = i as f64;
            (
                1.5 + (i * 0.618_033_988_7).fract() * 636.0,
                1.5 + (i * 0.754_877_666_2).fract() * 476.0,
            )
        })
        .collect()
}

fn samplers(c: &mut Criterion) {
    let img = image();
    let at = positions();
    let mut group = c.benchmark_group("sample");
    group.throughput(Throughput::Elements(at.len() as u64));
    group.bench_function("bilinear_with_derivatives", |b| {
        b.iter(|| {
            let mut sum = 0.0f32;
            for &(u, v) in &at {
                if let Some(s) = img.sample_exact(black_box(u), black_box(v)) {
                    sum += s.iter().sum::<f32>();
                }
            }
            sum
        })
    });
    group.bench_function("cubic_with_derivatives", |b| {
        b.iter(|| {
            let mut sum = 0.0f32;
            for &(u, v) in &at {
                if let Some(s) = img.sample_cubic(black_box(u), black_box(v)) {
                    sum += s.iter().sum::<f32>();
                }
            }
            sum
        })
    });
    group.finish();
}

criterion_group!(benches, samplers);
criterion_main!(benches);

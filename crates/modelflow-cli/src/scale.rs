//! `modelflow bench --scale`: the tracker's cost model. Over a grid of camera counts, image sizes
//! and mesh sizes, a synthetic cloth (the default clip's motion, its grid refined to the vertex
//! count asked for, its rig widened to the camera count) is rendered in memory and tracked with
//! the default options for a few frames; each point reports the median milliseconds per solved
//! frame (rendering excluded, the tracker's own image pyramids included) and the process's peak
//! resident memory while it ran. A least-squares fit of `log ms` on `log pixels` and
//! `log vertices` gives how time grows with each.

use crate::progress::Progress;
use modelflow::synth::{SynthOptions, Synthetic};
use modelflow::tracker::{median, TrackOptions, Tracker};
use serde::Serialize;

/// The grid measured.
pub struct ScaleOptions {
    pub cameras: Vec<usize>,
    pub sizes: Vec<(u32, u32)>,
    pub vertices: Vec<usize>,
    /// Frames per point (the first is the start, so `frames − 1` are solved).
    pub frames: u32,
    /// Where the solver's per-pixel work runs (`None`: the CPU).
    pub gpu: Option<std::sync::Arc<modelflow::tracker::Gpu>>,
}

/// One grid point.
#[derive(Serialize)]
pub struct ScaleRow {
    pub cameras: usize,
    pub width: u32,
    pub height: u32,
    /// Vertices of the mesh tracked (the grid side squared).
    pub vertices: usize,
    /// Pixels of all cameras, one frame.
    pub megapixels: f64,
    /// Median wall time per solved frame, ms (pyramids, templates, solve; no image I/O).
    pub ms_per_frame: f64,
    /// Median Gauss–Newton iterations per frame.
    pub iterations: f64,
    /// Of `ms_per_frame` (medians): the image pyramids, the template patches, the evaluations
    /// of the cost and its normal equations, and the linear solves.
    pub ms_pyramids: f64,
    pub ms_patches: f64,
    pub ms_evaluation: f64,
    pub ms_linear_solver: f64,
    /// With a GPU: of the evaluations, the kernels' time per frame (mean), ms.
    pub ms_gpu_kernels: Option<f64>,
    /// With a GPU: copying positions up, sums back and each level's inputs up, per frame, ms.
    pub ms_gpu_transfers: Option<f64>,
    /// With a GPU: of the linear solves, those that ran there, per frame (mean), ms.
    pub ms_gpu_linear: Option<f64>,
    /// Peak resident memory of the process while the point ran (its images included), MiB;
    /// `None` where the system does not say (not Linux).
    pub peak_mib: Option<f64>,
}

/// The fitted growth: `ms ≈ c · Mpx^pixels_exponent · V^vertices_exponent`.
#[derive(Serialize)]
pub struct Fit {
    pub pixels_exponent: f64,
    pub vertices_exponent: f64,
    pub ms_at_1_mpx_1000_vertices: f64,
}

#[derive(Serialize)]
pub struct ScaleReport {
    pub threads: usize,
    /// Where the solver's per-pixel work ran: `cpu`, or the GPU's name.
    pub device: String,
    pub frames_per_point: u32,
    pub rows: Vec<ScaleRow>,
    /// `None` with fewer than three points or without variation in both pixels and vertices.
    pub fit: Option<Fit>,
}

/// Parses `640x480`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("{s:?}: expected WIDTHxHEIGHT, e.g. 1920x1080"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| (16..=8192).contains(v))
            .ok_or_else(|| format!("{s:?}: each side must be a whole number from 16 to 8192"))
    };
    Ok((p(w)?, p(h)?))
}

/// Resets the kernel's peak-RSS mark of this process (Linux: `/proc/self/clear_refs`, "5").
fn reset_peak() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// The peak resident memory since the last reset, MiB (Linux: `VmHWM` of `/proc/self/status`).
fn peak_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

pub fn measure(o: &ScaleOptions) -> anyhow::Result<ScaleReport> {
    anyhow::ensure!(
        (2..=100).contains(&o.frames),
        "--frames {}: the cost model needs 2 to 100 frames per point",
        o.frames
    );
    let points: Vec<(usize, (u32, u32), usize)> = o
        .cameras
        .iter()
        .flat_map(|&c| {
            o.sizes
                .iter()
                .flat_map(move |&s| o.vertices.iter().map(move |&v| (c, s, v)))
        })
        .collect();
    let bar = Progress::new("scale", (points.len() as u64) * (o.frames as u64 - 1));
    let mut rows = Vec::new();
    for (cameras, (width, height), vertices) in points {
        let side = ((vertices as f64).sqrt().round() as usize).max(3);
        let syn = Synthetic::generate(&SynthOptions {
            cameras: Some(cameras),
            width,
            height,
            frames: o.frames,
            // One sample per pixel: the renderer is not what is timed.
            supersample: 1,
            cloth_grid: side,
            ..SynthOptions::default()
        })?;
        let render = |f: u32| -> Vec<_> { (0..cameras).map(|c| syn.render(c, f)).collect() };
        let first = render(0);
        let has_peak = reset_peak();
        let mut tracker = Tracker::new(
            &syn.mesh,
            syn.cameras.clone(),
            0,
            &first,
            TrackOptions::default(),
        )?;
        tracker.set_gpu(o.gpu.clone());
        drop(first);
        let (mut ms, mut its) = (Vec::new(), Vec::new());
        let mut parts: [Vec<f64>; 4] = Default::default();
        let gpu_before = o.gpu.as_ref().map(|g| g.stats());
        for f in 1..o.frames {
            let imgs = render(f);
            let t0 = std::time::Instant::now();
            let report = tracker.step(f, &imgs)?;
            ms.push(t0.elapsed().as_secs_f64() * 1e3);
            its.push(report.iterations as f64);
            let split = [
                report.timing.pyramids,
                report.timing.patches,
                report.levels.iter().map(|s| s.evaluation_seconds).sum(),
                report.levels.iter().map(|s| s.linear_solver_seconds).sum(),
            ];
            for (p, v) in parts.iter_mut().zip(split) {
                p.push(v * 1e3);
            }
            bar.tick(&format!(
                "{cameras} x {width}x{height}, {} vertices: frame {f} {:.0} ms",
                side * side,
                ms.last().unwrap()
            ));
        }
        let peak = if has_peak { peak_mib() } else { None };
        let solved = (o.frames - 1).max(1) as f64;
        let gpu_used = o
            .gpu
            .as_ref()
            .zip(gpu_before)
            .map(|(g, b)| g.stats().since(&b));
        rows.push(ScaleRow {
            cameras,
            width,
            height,
            vertices: side * side,
            megapixels: cameras as f64 * width as f64 * height as f64 / 1e6,
            ms_per_frame: median(&ms),
            iterations: median(&its),
            ms_pyramids: median(&parts[0]),
            ms_patches: median(&parts[1]),
            ms_evaluation: median(&parts[2]),
            ms_linear_solver: median(&parts[3]),
            ms_gpu_kernels: gpu_used.map(|g| g.kernel_seconds * 1e3 / solved),
            ms_gpu_transfers: gpu_used.map(|g| {
                (g.transfer_seconds + g.upload_copy_seconds + g.upload_host_seconds) * 1e3 / solved
            }),
            ms_gpu_linear: gpu_used.map(|g| g.linear_solve_seconds * 1e3 / solved),
            peak_mib: peak,
        });
    }
    bar.finish();
    let fit = fit(&rows);
    Ok(ScaleReport {
        threads: rayon::current_num_threads(),
        device: o
            .gpu
            .as_ref()
            .map_or_else(|| "cpu".to_string(), |g| g.name().to_string()),
        frames_per_point: o.frames,
        rows,
        fit,
    })
}

/// Least squares of `ln ms = a + b·ln Mpx + c·ln V` (normal equations, 3×3).
fn fit(rows: &[ScaleRow]) -> Option<Fit> {
    let distinct = |f: &dyn Fn(&ScaleRow) -> f64| {
        rows.iter()
            .any(|r| (f(r) - f(&rows[0])).abs() > 1e-9 * f(&rows[0]).abs())
    };
    if rows.len() < 3 || !distinct(&|r| r.megapixels) || !distinct(&|r| r.vertices as f64) {
        return None;
    }
    let mut a = nalgebra::Matrix3::<f64>::zeros();
    let mut b = nalgebra::Vector3::<f64>::zeros();
    for r in rows {
        let x = nalgebra::Vector3::new(1.0, r.megapixels.ln(), (r.vertices as f64 / 1e3).ln());
        a += x * x.transpose();
        b += x * r.ms_per_frame.max(1e-6).ln();
    }
    let s = a.lu().solve(&b)?;
    Some(Fit {
        pixels_exponent: s[1],
        vertices_exponent: s[2],
        ms_at_1_mpx_1000_vertices: s[0].exp(),
    })
}

pub fn print(r: &ScaleReport) {
    println!(
        "cost model: synthetic cloth, default options, {} frames per point ({} solved), {} threads, per-pixel work on {}",
        r.frames_per_point,
        r.frames_per_point - 1,
        r.threads,
        r.device
    );
    println!(
        "  cameras   image       vertices   Mpx/frame   ms/frame   iterations   peak MiB   | of which ms: pyramids  patches  evaluations  linear solves"
    );
    for row in &r.rows {
        println!(
            "  {:>7}   {:>9}   {:>8}   {:>9.2}   {:>8.0}   {:>10.0}   {:>8}   | {:>21.0}  {:>7.0}  {:>11.0}  {:>13.0}",
            row.cameras,
            format!("{}x{}", row.width, row.height),
            row.vertices,
            row.megapixels,
            row.ms_per_frame,
            row.iterations,
            row.peak_mib.map_or("-".into(), |m| format!("{m:.0}")),
            row.ms_pyramids,
            row.ms_patches,
            row.ms_evaluation,
            row.ms_linear_solver
        );
    }
    for row in r.rows.iter().filter(|r| r.ms_gpu_kernels.is_some()) {
        println!(
            "  on the GPU, {} x {}x{}, {} vertices: kernels {:.0} ms per frame, transfers and uploads {:.0} ms, linear solves there {:.0} ms",
            row.cameras,
            row.width,
            row.height,
            row.vertices,
            row.ms_gpu_kernels.unwrap_or(0.0),
            row.ms_gpu_transfers.unwrap_or(0.0),
            row.ms_gpu_linear.unwrap_or(0.0)
        );
    }
    match &r.fit {
        Some(f) => println!(
            "fit: ms/frame ~ {:.0} x (Mpx)^{:.2} x (vertices/1000)^{:.2}",
            f.ms_at_1_mpx_1000_vertices, f.pixels_exponent, f.vertices_exponent
        ),
        None => println!("fit: needs at least three points varying in both pixels and vertices"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(mpx: f64, v: usize, ms: f64) -> ScaleRow {
        ScaleRow {
            cameras: 2,
            width: 640,
            height: 480,
            vertices: v,
            megapixels: mpx,
            ms_per_frame: ms,
            iterations: 20.0,
            ms_pyramids: 0.0,
            ms_patches: 0.0,
            ms_evaluation: 0.0,
            ms_linear_solver: 0.0,
            ms_gpu_kernels: None,
            ms_gpu_transfers: None,
            ms_gpu_linear: None,
            peak_mib: None,
        }
    }

    #[test]
    fn the_fit_recovers_known_exponents() {
        // ms = 50 · Mpx^0.9 · (V/1000)^0.3, exactly.
        let law = |m: f64, v: usize| 50.0 * m.powf(0.9) * (v as f64 / 1e3).powf(0.3);
        let rows: Vec<ScaleRow> = [(0.6, 1681), (2.4, 1681), (0.6, 40000), (16.6, 10000)]
            .iter()
            .map(|&(m, v)| row(m, v, law(m, v)))
            .collect();
        let f = fit(&rows).unwrap();
        assert!((f.pixels_exponent - 0.9).abs() < 1e-9);
        assert!((f.vertices_exponent - 0.3).abs() < 1e-9);
        assert!((f.ms_at_1_mpx_1000_vertices - 50.0).abs() < 1e-6);
        assert!(fit(&rows[..2]).is_none());
    }

    #[test]
    fn sizes_parse_and_bad_ones_say_why() {
        assert_eq!(parse_size("1920x1080"), Ok((1920, 1080)));
        assert!(parse_size("1920").unwrap_err().contains("WIDTHxHEIGHT"));
        assert!(parse_size("9000x10").unwrap_err().contains("16 to 8192"));
    }
}

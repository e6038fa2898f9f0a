//! `modelflow bench --capture-range`: the largest per-frame motion the tracker follows. A
//! synthetic object (default: the blob, 4 cameras at 1280×720) is carried by hand-held motion
//! (`synth --shake`) of increasing speed; each speed is a short clip tracked with the default
//! options, in memory, and scored against its ground truth. A speed is *tracked* when every
//! frame's RMS vertex error stays within 1 % of the object's size and no frame stalls; the figure
//! is the largest speed tracked with every slower one tracked too.

use crate::progress::Progress;
use modelflow::base::rms_distance;
use modelflow::synth::{SynthOptions, Synthetic};
use modelflow::tracker::{TrackOptions, Tracker};
use serde::Serialize;

/// What is measured.
pub struct CaptureOptions {
    pub preset: String,
    pub width: u32,
    pub height: u32,
    /// Frames per clip (the first is the start).
    pub frames: u32,
    /// Hand-held speeds tried, pixels per frame in the first camera, ascending.
    pub speeds: Vec<f64>,
    pub track: TrackOptions,
}

/// One speed's result.
#[derive(Serialize)]
pub struct CaptureRow {
    /// Hand-held speed asked for (px per frame at the object's centre, first camera).
    pub shake_px: f64,
    /// Measured per-frame vertex motion over all cameras and frames, px (median and maximum).
    pub motion_median_px: f64,
    pub motion_max_px: f64,
    /// RMS vertex error, % of the bounding-box diagonal: mean and worst over the frames.
    pub error_mean_pct: f64,
    pub error_max_pct: f64,
    /// Frames whose solve could not lower the cost.
    pub stalled: usize,
    /// Frames the tracker's own checks flagged as suspect (`FrameReport::suspect`): a lost
    /// speed should be flagged, a tracked one not.
    pub suspect: usize,
    /// The largest change of velocity in one frame the tracker measured (`FrameReport::jump`),
    /// % of the size: how close the speed comes to the leap that flags a frame.
    pub jump_max_pct: f64,
    pub tracked: bool,
    pub seconds_per_frame: f64,
}

/// The benchmark's result.
#[derive(Serialize)]
pub struct CaptureReport {
    pub preset: String,
    pub width: u32,
    pub height: u32,
    pub cameras: usize,
    pub frames: u32,
    /// Error bound of "tracked", % of the object's size.
    pub bound_pct: f64,
    pub rows: Vec<CaptureRow>,
    /// Largest speed tracked with every slower one tracked (0 when the slowest fails).
    pub capture_range_px: f64,
    /// The largest measured per-frame vertex motion (px) among the speeds counted.
    pub capture_range_max_motion_px: f64,
}

const BOUND_PCT: f64 = 1.0;

pub fn measure(o: &CaptureOptions) -> anyhow::Result<CaptureReport> {
    let total = o.speeds.len() as u64 * (o.frames as u64 - 1);
    let bar = Progress::new("capture", total);
    let mut rows = Vec::new();
    let mut cameras = 0;
    for &shake in &o.speeds {
        let syn = Synthetic::generate(&SynthOptions {
            width: o.width,
            height: o.height,
            frames: o.frames,
            shake,
            ..SynthOptions::preset(&o.preset)?
        })?;
        cameras = syn.cameras.len();
        let motion = syn.motion_stats();
        let images =
            |f: u32| -> Vec<_> { (0..syn.cameras.len()).map(|c| syn.render(c, f)).collect() };
        let mut tracker = Tracker::new(&syn.mesh, syn.cameras.clone(), 0, &images(0), o.track)?;
        let diag = syn.mesh.bbox_diagonal();
        let (mut sum, mut worst, mut stalled, mut secs) = (0.0, 0.0f64, 0, 0.0);
        let (mut suspect, mut jump) = (0, 0.0f64);
        for f in 1..o.frames {
            let imgs = images(f);
            let t0 = std::time::Instant::now();
            let report = tracker.step(f, &imgs)?;
            secs += t0.elapsed().as_secs_f64();
            stalled += report.stalled as usize;
            suspect += report.suspect as usize;
            jump = jump.max(report.jump);
            let err = 100.0 * rms_distance(tracker.positions(), &syn.truth[f as usize]) / diag;
            sum += err;
            worst = worst.max(err);
            bar.tick(&format!("{shake} px, frame {f}: {err:.2} %"));
        }
        let n = (o.frames - 1) as f64;
        rows.push(CaptureRow {
            shake_px: shake,
            motion_median_px: motion.median,
            motion_max_px: motion.max,
            error_mean_pct: sum / n,
            error_max_pct: worst,
            stalled,
            suspect,
            jump_max_pct: 100.0 * jump,
            tracked: worst <= BOUND_PCT && stalled == 0,
            seconds_per_frame: secs / n,
        });
    }
    bar.finish();
    let counted: Vec<&CaptureRow> = rows.iter().take_while(|r| r.tracked).collect();
    Ok(CaptureReport {
        preset: o.preset.clone(),
        width: o.width,
        height: o.height,
        cameras,
        frames: o.frames,
        bound_pct: BOUND_PCT,
        capture_range_px: counted.last().map_or(0.0, |r| r.shake_px),
        capture_range_max_motion_px: counted.iter().map(|r| r.motion_max_px).fold(0.0, f64::max),
        rows,
    })
}

pub fn print(r: &CaptureReport) {
    println!(
        "capture range: {} preset, {} cameras at {}x{}, {} frames per speed, tracked = every frame within {} % of the size and none stalled",
        r.preset, r.cameras, r.width, r.height, r.frames, r.bound_pct
    );
    println!(
        "  shake px/frame   motion median/max px   error mean/max %   stalled   suspect   leap max %   s/frame   tracked"
    );
    for row in &r.rows {
        println!(
            "  {:>14.0}   {:>9.1} / {:<9.1}   {:>7.3} / {:<7.3}   {:>7}   {:>7}   {:>10.1}   {:>7.2}   {}",
            row.shake_px,
            row.motion_median_px,
            row.motion_max_px,
            row.error_mean_pct,
            row.error_max_pct,
            row.stalled,
            row.suspect,
            row.jump_max_pct,
            row.seconds_per_frame,
            if row.tracked { "yes" } else { "no" }
        );
    }
    println!(
        "largest speed tracked: {:.0} px per frame (vertex motion up to {:.1} px)",
        r.capture_range_px, r.capture_range_max_motion_px
    );
}

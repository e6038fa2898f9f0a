//! `modelflow synth`: writes a synthetic multi-view data set with ground truth (a scene file,
//! images, initial mesh and true mesh per frame) from a preset, with a progress bar.

use crate::progress::Progress;
use modelflow::synth::{SynthOptions, Synthetic};
use std::path::PathBuf;

#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Preset: cloth (a hanging, waving, folding sheet; 2 cameras), blob (a closed, turning,
    /// lobed surface; 4 cameras around it), irregular (the blob on an uneven triangulation with
    /// a hole), limb (a capsule that bends at an elbow while its forearm twists; 4 cameras) or
    /// crossing (a body and an arm that sweeps across in front of it: one mesh of two pieces,
    /// each hiding the other from some of its 4 cameras).
    #[arg(long, default_value = "cloth")]
    preset: String,
    /// Output folder (created; existing files with the same names are replaced).
    #[arg(long)]
    out: PathBuf,
    /// Number of cameras (default: the preset's).
    #[arg(long)]
    cameras: Option<usize>,
    /// Image width in pixels (16 to 8192).
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Image height in pixels (16 to 8192).
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Number of frames (1 to 10000).
    #[arg(long, default_value_t = 120)]
    frames: u32,
    /// Standard deviation of Gaussian image noise, intensities in [0, 1].
    #[arg(long, default_value_t = 0.0)]
    noise: f64,
    /// Seed of the texture and the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Flat albedo instead of diffuse lighting.
    #[arg(long)]
    no_light: bool,
    /// Anti-aliasing subsamples per pixel along each axis.
    #[arg(long, default_value_t = 3)]
    supersample: u32,
    /// Hand-held motion on top of the preset's: pixels per frame at the object's centre in the
    /// first camera (a circle of 12 frames with a roll), for large per-frame motion.
    #[arg(long, default_value_t = 0.0)]
    shake: f64,
    /// Render through lens distortion, given as MODEL:COEFFICIENTS in OpenCV's order, e.g.
    /// opencv:-0.3,0.1,0,0,0 (k1, k2, p1, p2, k3) or fisheye:0.05,-0.01,0,0; the scene file
    /// records it (docs/scene-format.md).
    #[arg(long, allow_hyphen_values = true)]
    distortion: Option<String>,
    /// Cloth only: vertices along each side of its grid (3 to 1000; 41 gives 1 681 vertices).
    #[arg(long, default_value_t = 41)]
    cloth_grid: usize,
    /// Cameras out of sync: the last camera records each frame this many frames late, the others
    /// in proportion (0 to 1; 0.1 is 3.3 ms at 30 fps). The ground truth stays at frame times.
    #[arg(long, default_value_t = 0.0)]
    sync_error: f64,
    /// Motion blur: the shutter's opening as a fraction of a frame (0 to 1), centred on the
    /// frame's time; each image is the mean of renders over it (at least 8, and as many as keep
    /// the fastest vertex within a pixel between two, up to 160: a streak). The scene file
    /// records it as each camera's `shutter`.
    #[arg(long, default_value_t = 0.0)]
    motion_blur: f64,
    /// A rolling shutter: the readout from the top row to the bottom row, in frames (0 to 1;
    /// 0, the default: a global shutter), centred on each camera's time. A moving object leans
    /// and stretches; the scene file records it as each camera's `rolling_shutter`.
    #[arg(long, default_value_t = 0.0)]
    rolling_shutter: f64,
    /// The object turned in the hand: degrees per frame about the first camera's image vertical
    /// through its centre (0 to 90), on top of the preset's motion and --shake.
    #[arg(long, default_value_t = 0.0)]
    turn: f64,
    /// A textured wall behind the object in every camera's view (instead of the flat grey), as
    /// a room stands behind a real rig's subject.
    #[arg(long)]
    backdrop: bool,
    /// A camera knocked off its calibration while filming, as CAMERA:FRAME:DEGREES (e.g.
    /// 0:5:0.2): its images are rendered turned by that much about its own centre from that
    /// frame on, while the scene file keeps its calibration.
    #[arg(long, allow_hyphen_values = true)]
    bump: Option<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = SynthOptions {
        cameras: args.cameras,
        width: args.width,
        height: args.height,
        frames: args.frames,
        noise: args.noise,
        light: !args.no_light,
        seed: args.seed,
        supersample: args.supersample,
        shake: args.shake,
        distortion: args
            .distortion
            .as_deref()
            .map(|d| {
                d.parse::<modelflow::base::Distortion>()
                    .map_err(|m| anyhow::anyhow!("--distortion: {m}"))
            })
            .transpose()?,
        cloth_grid: args.cloth_grid,
        sync_error: args.sync_error,
        motion_blur: args.motion_blur,
        rolling_shutter: args.rolling_shutter,
        turn: args.turn,
        backdrop: args.backdrop,
        bump: args
            .bump
            .as_deref()
            .map(|b| {
                b.parse::<modelflow::synth::Bump>()
                    .map_err(|m| anyhow::anyhow!("--bump: {m}"))
            })
            .transpose()?,
        ..SynthOptions::preset(&args.preset)?
    };
    let start = std::time::Instant::now();
    let synth = Synthetic::generate(&opts)?;
    let progress = Progress::new(&format!("synth {} (files written)", opts.preset), 0);
    let scene = synth.write(&args.out, &|done, total| {
        progress.set(done as u64, total as u64)
    })?;
    progress.finish();
    let motion = synth.motion_stats();
    eprintln!(
        "wrote {} ({} frames, {} cameras) in {:.1} s; per-frame vertex motion: max {:.2} px, median {:.2} px",
        scene.display(),
        opts.frames,
        opts.camera_count(),
        start.elapsed().as_secs_f64(),
        motion.max,
        motion.median
    );
    println!("{}", scene.display());
    Ok(())
}

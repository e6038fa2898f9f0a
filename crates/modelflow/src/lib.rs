//! modelflow: markerless capture of deforming geometry from calibrated, synchronised multi-view
//! footage, after "Model Flowing" (Reuterswärd, 2005). See `ARCHITECTURE.md` for the map.
//!
//! The modules follow the data's path: [`base`] (camera, image, mesh) → [`input`] (scene, mesh
//! and image files) → [`tracker`] (Model Flow) or [`baseline`] (optical flow) → [`run`] (the run
//! folder) → [`report`] (scores, plots, overlays); [`synth`] makes footage with ground truth.
//! What most programs need is re-exported here:
//!
//! ```no_run
//! use modelflow::{evaluate, read_run, track_scene, RunOptions, Scene, TrackOptions};
//! # fn main() -> modelflow::Result<()> {
//! let scene = Scene::load("shot/scene.json".as_ref())?;
//! let out = std::path::Path::new("runs/shot");
//! track_scene(&scene, &TrackOptions::default(), out, &RunOptions::default(), &mut |_| {})?;
//! let score = evaluate(&scene, &read_run(out)?)?;
//! println!("mean error {:.3} %", score.rms_mean_pct);
//! # Ok(())
//! # }
//! ```

pub mod base;
pub mod baseline;
mod error;
pub mod export;
pub(crate) mod fsutil;
pub mod input;
pub mod report;
pub mod run;
pub mod synth;
pub mod tracker;

pub use base::{Camera, Mesh, Projection, RgbImage};
pub use baseline::BaselineOptions;
pub use error::{Error, Result};
pub use input::Scene;
pub use report::{evaluate, write_report, EvalReport, ReportOptions};
pub use run::{
    frames_to_check, read_frame_log, read_run, FrameLog, Manifest, OpenMode, RunOptions,
};
pub use synth::{write_dataset, SynthOptions, Synthetic};
pub use tracker::{track_scene, TrackOptions, Tracker};

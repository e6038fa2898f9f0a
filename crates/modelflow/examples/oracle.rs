//! Measures how much of a run's error is accumulation: tracks a scene with ground truth twice —
//! normally, and restarting every frame from the true previous shape (`--oracle`) — and prints
//! the error per frame. Used to diagnose drift (see the closing notes of issue #3).
//!
//! `cargo run --release --example oracle -- SCENE.json [--oracle]`

use modelflow::input::Scene;
use modelflow::tracker::{TrackOptions, Tracker};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path: PathBuf = args
        .next()
        .ok_or("usage: oracle SCENE.json [--oracle]")?
        .into();
    let oracle = args.next().is_some_and(|a| a == "--oracle");
    let scene = Scene::load(&path)?;
    let truth = |f: u32| -> Result<_, Box<dyn std::error::Error>> {
        Ok(scene
            .ground_truth(f)
            .ok_or("the scene has no ground truth")??
            .positions)
    };
    let first = scene.load_images(scene.first)?;
    let mut tracker = Tracker::new(
        &scene.mesh,
        scene.cameras.clone(),
        scene.first,
        &first,
        TrackOptions::default(),
    )?;
    let diag = scene.mesh.bbox_diagonal();
    let mut sum = 0.0;
    for f in scene.first + 1..=scene.last {
        if oracle {
            tracker.set_positions(truth(f - 1)?)?;
        }
        tracker.step(f, &scene.load_images(f)?)?;
        let t = truth(f)?;
        let rms = (tracker
            .positions()
            .iter()
            .zip(&t)
            .map(|(a, b)| (a - b).norm_squared())
            .sum::<f64>()
            / t.len() as f64)
            .sqrt();
        sum += rms;
        println!(
            "frame {f}: {:.4} % ({:.2} mm)",
            100.0 * rms / diag,
            rms * 1e3
        );
    }
    println!(
        "mean over solved frames {:.4} %",
        100.0 * sum / (scene.last - scene.first).max(1) as f64 / diag
    );
    Ok(())
}

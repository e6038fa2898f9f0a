//! Lens distortion end to end: footage rendered through a lens loads as pinhole images that
//! match the pinhole render, is tracked as well as pinhole footage, and a scene's distortion
//! entry is checked with errors that name the field.

mod common;

use common::*;
use modelflow::base::Distortion;
use modelflow::input::{DistortionEntry, Scene};
use modelflow::synth::{SynthOptions, Synthetic};
use modelflow::RgbImage;

fn opts(distortion: Option<Distortion>) -> SynthOptions {
    SynthOptions {
        width: 320,
        height: 240,
        frames: 5,
        distortion,
        ..SynthOptions::default()
    }
}

/// Mean absolute difference over the central 80 % of two images (0..1 per channel).
fn mean_diff(a: &RgbImage, b: &RgbImage) -> f64 {
    let (w, h) = (a.width(), a.height());
    let (mut sum, mut n) = (0.0, 0);
    for y in h / 10..h - h / 10 {
        for x in w / 10..w - w / 10 {
            let (p, q) = (a.get(x, y), b.get(x, y));
            sum += (0..3).map(|k| (p[k] - q[k]).abs() as f64).sum::<f64>() / 3.0;
            n += 1;
        }
    }
    sum / n as f64
}

#[test]
fn footage_through_a_lens_is_undistorted_at_load_and_tracked_like_pinhole_footage() {
    // Barrel distortion as strong as a webcam's (the image corners move by ~20 px at 320×240).
    let lens: Distortion = "opencv:-0.3,0.1,0.001,-0.0005,0".parse().unwrap();
    let pinhole = Synthetic::generate(&opts(None)).unwrap();
    let distorted = Synthetic::generate(&opts(Some(lens.clone()))).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let scene_path = distorted
        .write(&dir.path().join("lens"), &|_, _| {})
        .unwrap();
    let pin_path = pinhole.write(&dir.path().join("pin"), &|_, _| {}).unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    assert_eq!(
        scene.cameras[0].lens.as_ref().map(|l| l.distortion()),
        Some(&lens),
        "the scene file records the lens"
    );
    // The raw frames really are distorted; undistorted at load they are the pinhole render up
    // to resampling and 8-bit rounding.
    let raw = &scene.load_raw_images(2).unwrap()[0];
    let loaded = &scene.load_images(2).unwrap()[0];
    let truth = pinhole.render(0, 2);
    let (before, after) = (mean_diff(raw, &truth), mean_diff(loaded, &truth));
    assert!(
        after < 0.006 && after < 0.4 * before,
        "mean difference to the pinhole render: raw {before:.4}, undistorted {after:.4}"
    );
    // Tracked through the lens, as well as the pinhole footage (within 10 %, or 0.02 % of the
    // size: both are a few hundredths of a percent).
    let through = track_errors(&scene);
    let plain = track_errors(&Scene::load(&pin_path).unwrap());
    eprintln!("error per frame (%): through the lens {through:.4?}, pinhole {plain:.4?}");
    for (f, (a, b)) in through.iter().zip(&plain).enumerate() {
        assert!(
            *a <= 1.1 * b + 0.02,
            "frame {}: {a:.4} % through the lens vs {b:.4} % pinhole",
            f + 1
        );
    }
    let mean = through.iter().sum::<f64>() / through.len() as f64;
    assert!(mean < 0.3, "mean error {mean:.3} %");
}

fn broken_lens(model: &str, coefficients: &[f64]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    file.cameras[1].distortion = Some(DistortionEntry {
        model: model.into(),
        coefficients: coefficients.to_vec(),
    });
    file.write(&path).unwrap();
    match Scene::load(&path) {
        Ok(_) => panic!("{model} {coefficients:?} should be refused"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_distortion_entries_name_the_field_and_the_reason() {
    let cases: [(&str, &[f64], &str); 4] = [
        ("opencv", &[0.1, 0.0, 0.0], "4, 5, 8, 12 or 14 coefficients"),
        (
            "fisheye",
            &[0.1, 0.0, 0.0, 0.0, 0.0],
            "takes 4 coefficients",
        ),
        ("kannala", &[0.0; 4], "unknown model \"kannala\""),
        // Millimetre-scale coefficients given as if normalised: folds over near the centre.
        ("opencv", &[-40.0, 0.0, 0.0, 0.0], "folds over"),
    ];
    for (model, c, why) in cases {
        let msg = broken_lens(model, c);
        assert!(
            msg.contains("scene.json")
                && msg.contains("cameras[1].distortion")
                && msg.contains(why),
            "{msg}"
        );
    }
    // A P-matrix camera has no K for the lens.
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    let c = &mut file.cameras[0];
    let (k, r, t) = (
        c.k.take().unwrap(),
        c.r.take().unwrap(),
        c.t.take().unwrap(),
    );
    let p = [0, 1, 2].map(|i| {
        let mut row = [0.0; 4];
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3)
                .map(|m| k[i][m] * if j < 3 { r[m][j] } else { t[m] })
                .sum();
        }
        row
    });
    c.p = Some(vec![p; FRAMES as usize]);
    c.distortion = Some(DistortionEntry {
        model: "opencv".into(),
        coefficients: vec![0.1, 0.0, 0.0, 0.0],
    });
    file.write(&path).unwrap();
    let msg = Scene::load(&path).err().unwrap().to_string();
    assert!(
        msg.contains("cameras[0].distortion") && msg.contains("P matrix"),
        "{msg}"
    );
}

#[test]
fn zero_coefficients_are_a_pinhole_camera() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = write_scene(dir.path());
    file.cameras[0].distortion = Some(DistortionEntry {
        model: "opencv".into(),
        coefficients: vec![0.0; 5],
    });
    file.write(&path).unwrap();
    let scene = Scene::load(&path).unwrap();
    assert!(scene.cameras[0].lens.is_none() && scene.undistort[0].is_none());
}

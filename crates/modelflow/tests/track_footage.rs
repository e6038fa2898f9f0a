//! The tracker on rendered footage: small synthetic cloth from our renderer (with ground truth),
//! and the Blender-rendered cloth sample in `fixtures/` (footage made by another renderer, which
//! checks the camera and pixel conventions end to end).

use modelflow::input::Scene;
use modelflow::synth::{write_dataset, SynthOptions, Synthetic};
use modelflow::tracker::{track_scene, TrackOptions, Tracker};
use modelflow::{OpenMode, RgbImage, RunOptions};
use nalgebra::Point3;

fn rms(a: &[Point3<f64>], b: &[Point3<f64>]) -> f64 {
    (a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm_squared())
        .sum::<f64>()
        / a.len() as f64)
        .sqrt()
}

/// Every camera's image of frame `f`.
fn images(syn: &Synthetic, f: u32) -> Vec<RgbImage> {
    (0..syn.cameras.len()).map(|c| syn.render(c, f)).collect()
}

/// A tracker with the default options, started on the first frame.
fn start(syn: &Synthetic) -> Tracker {
    Tracker::new(
        &syn.mesh,
        syn.cameras.clone(),
        0,
        &images(syn, 0),
        TrackOptions::default(),
    )
    .unwrap()
}

/// Tracks `syn` over `frames` frames with `options`, asserting that no frame stalls: the mean
/// error over frames 1.. (% of the first mesh's size) and the pixels compared at the finest
/// level solved, summed.
fn track_mean(syn: &Synthetic, frames: u32, options: TrackOptions) -> (f64, usize) {
    let diag = syn.mesh.bbox_diagonal();
    let mut tr = Tracker::new(&syn.mesh, syn.cameras.clone(), 0, &images(syn, 0), options).unwrap();
    let (mut sum, mut pixels) = (0.0, 0);
    for f in 1..frames {
        let report = tr.step(f, &images(syn, f)).unwrap();
        assert!(!report.stalled, "frame {f} stalled ({:?})", report.stop);
        sum += 100.0 * rms(tr.positions(), &syn.truth[f as usize]) / diag;
        pixels += report.pixels;
    }
    (sum / (frames - 1) as f64, pixels)
}

/// `preset` at 320×240 over `frames` frames, tracked with the default options to its last
/// frame (asserting that no frame stalls): the footage and the tracker there.
fn tracked_320x240(preset: &str, frames: u32) -> (Synthetic, Tracker) {
    let opts = SynthOptions {
        width: 320,
        height: 240,
        frames,
        ..SynthOptions::preset(preset).unwrap()
    };
    let syn = Synthetic::generate(&opts).unwrap();
    let mut tr = start(&syn);
    for f in 1..frames {
        let report = tr.step(f, &images(&syn, f)).unwrap();
        assert!(
            !report.stalled,
            "{preset} frame {f} stalled ({:?})",
            report.stop
        );
    }
    (syn, tr)
}

/// The default cloth at 320×240, `frames` frames.
fn cloth_320x240(frames: u32) -> (SynthOptions, Synthetic) {
    let opts = SynthOptions {
        width: 320,
        height: 240,
        frames,
        ..SynthOptions::default()
    };
    let syn = Synthetic::generate(&opts).unwrap();
    (opts, syn)
}

#[test]
fn first_frames_of_the_default_cloth_are_tracked_to_ground_truth() {
    // 320×240, 2 cameras with the default narrow baseline, the default cloth's first frames
    // (diffuse lighting on, so shading changes as it moves).
    let (opts, syn) = cloth_320x240(6);
    let images = |f: u32| images(&syn, f);
    let mut tr = start(&syn);
    let diag = syn.mesh.bbox_diagonal();
    let mut sum = 0.0;
    for f in 1..opts.frames {
        tr.step(f, &images(f)).unwrap();
        let truth = &syn.truth[f as usize];
        let err = 100.0 * rms(tr.positions(), truth) / diag;
        let still = 100.0 * rms(&syn.truth[0], truth) / diag;
        // The shot's accuracy bounds (mean 0.3 % of the cloth's size, about 4 mm, most of it depth
        // along the narrow baseline; no frame above 0.4 %), and far better than not moving.
        assert!(err < 0.4, "frame {f}: error {err:.3} % of the cloth's size");
        sum += err;
        assert!(
            f < 2 || err < 0.5 * still,
            "frame {f}: error {err:.3} % vs {still:.3} % standing still"
        );
    }
    let mean = sum / (opts.frames - 1) as f64;
    assert!(mean < 0.3, "mean error {mean:.3} % of the cloth's size");
}

#[test]
fn an_irregular_triangulation_with_a_hole_is_tracked_and_never_stalls() {
    // The blob's surface on an artist-like mesh (edges from about 1.5 to 30 cm, uneven
    // valences, a hole through which the inside shows), 4 cameras at 320×240, carried by a
    // hand-held motion of 6 px per frame on top of its own turning and swelling.
    let opts = SynthOptions {
        width: 320,
        height: 240,
        frames: 7,
        shake: 6.0,
        ..SynthOptions::preset("irregular").unwrap()
    };
    let syn = Synthetic::generate(&opts).unwrap();
    assert!(!syn.mesh.is_closed());
    let images = |f: u32| images(&syn, f);
    let mut tr = start(&syn);
    let diag = syn.mesh.bbox_diagonal();
    let mut sum = 0.0;
    for f in 1..opts.frames {
        let report = tr.step(f, &images(f)).unwrap();
        let moved = 100.0 * rms(&syn.truth[f as usize - 1], &syn.truth[f as usize]) / diag;
        let accepted = report
            .levels
            .iter()
            .flat_map(|l| &l.iterations)
            .filter(|i| i.accepted)
            .count();
        // The truth moved (about 1 % of the size per frame), so some step must have been taken.
        assert!(moved > 0.3, "frame {f}: truth moved only {moved:.3} %");
        assert!(
            !report.stalled && accepted > 0,
            "frame {f}: every step rejected ({:?})",
            report.stop
        );
        let err = 100.0 * rms(tr.positions(), &syn.truth[f as usize]) / diag;
        let still = 100.0 * rms(&syn.truth[0], &syn.truth[f as usize]) / diag;
        eprintln!("frame {f}: error {err:.3} %, standing still {still:.3} %");
        assert!(
            err < 0.1 * still && err < 0.5,
            "frame {f}: error {err:.3} % (standing still {still:.3} %)"
        );
        sum += err;
    }
    let mean = sum / (opts.frames - 1) as f64;
    assert!(mean < 0.3, "mean error {mean:.3} % of the blob's size");
}

#[test]
fn a_surface_that_swells_is_followed_not_pulled_back_to_its_first_shape() {
    // The irregular preset's lobes swell: by frame 30 one edge in twelve is 13 % or more
    // longer than at frame 0 and some 30 %. Springs that always pull toward the first frame's
    // lengths hold them back (0.69 % final error at this size with `--spring-yield 0`; 0.57 %
    // with the yield strain pulled back every frame, `--spring-stretch-share 0`; 0.42 % with
    // the defaults: once the surface shows that it stretches, the spring past its yield is
    // centred on the length the images held in the previous frame).
    let (syn, tr) = tracked_320x240("irregular", 31);
    let diag = syn.mesh.bbox_diagonal();
    let last = 31 - 1;
    let truth = &syn.truth[last as usize];
    let lengths = |x: &[Point3<f64>]| -> Vec<f64> {
        syn.mesh
            .edges()
            .iter()
            .map(|&[a, b]| (x[b as usize] - x[a as usize]).norm())
            .collect()
    };
    let (rest, now) = (lengths(&syn.mesh.positions), lengths(truth));
    let stretched = rest
        .iter()
        .zip(&now)
        .filter(|(r, n)| *n > &(1.13 * *r))
        .count();
    assert!(
        stretched * 12 >= rest.len(),
        "the footage must stretch: {stretched} of {} edges 13 % longer",
        rest.len()
    );
    let err = 100.0 * rms(tr.positions(), truth) / diag;
    eprintln!("frame {last}: error {err:.3} % of the size");
    assert!(err < 0.52, "final error {err:.3} % of the size");
}

#[test]
fn an_elbow_that_bends_is_followed_into_its_crook() {
    // The limb preset bends 52° at its elbow by frame 60: the skin along the inside of the bend
    // is compressed by up to 61 % (44 % on average over the edges checked here), and the
    // forearm hides that crook from some cameras. Springs that pulled a strain back by their
    // whole yield every frame held it near the yield (0.68 % final error at this size with
    // `--spring-stretch-share 0`). Once the surface shows that it stretches (the outside of the
    // elbow, which the cameras see, past twice the yield), they are centred on the previous
    // frame's length past the yield (the default) and follow it (tracked −46 %, 0.42 %).
    let (syn, tr) = tracked_320x240("limb", 61);
    let diag = syn.mesh.bbox_diagonal();
    let last = 61 - 1;
    // The edges along the limb within 6 cm of the elbow, on the inside of the bend (rest +y).
    let crook: Vec<[u32; 2]> = syn
        .mesh
        .edges()
        .into_iter()
        .filter(|&[a, b]| {
            let (ma, mb) = (syn.material[a as usize], syn.material[b as usize]);
            let along = (ma[0] - mb[0]).abs();
            let mid = [0.5 * (ma[0] + mb[0]), 0.5 * (ma[1] + mb[1])];
            along > 0.01 && mid[0].abs() < 0.06 && mid[1] > 0.11
        })
        .collect();
    let strain = |x: &[Point3<f64>]| {
        crook
            .iter()
            .map(|&[a, b]| {
                let rest = (syn.mesh.positions[b as usize] - syn.mesh.positions[a as usize]).norm();
                (x[b as usize] - x[a as usize]).norm() / rest - 1.0
            })
            .sum::<f64>()
            / crook.len() as f64
    };
    let truth = &syn.truth[last as usize];
    let (tracked, real) = (strain(tr.positions()), strain(truth));
    let err = 100.0 * rms(tr.positions(), truth) / diag;
    eprintln!(
        "{} crook edges: strain {tracked:.3} tracked, {real:.3} true; error {err:.3} %",
        crook.len()
    );
    assert!(real < -0.4, "the footage must fold the crook: {real:.3}");
    assert!(
        tracked < 0.7 * real,
        "crook compressed by {tracked:.3} of {real:.3}"
    );
    assert!(err < 0.55, "final error {err:.3} % of the size");
}

#[test]
fn a_cloth_that_folds_is_followed_not_pulled_back_to_its_first_shape() {
    // The default cloth ripples and folds: its local shape changes for good. The bending term
    // against the rest shape pulled every fold back toward the flat first frame; past its yield
    // (default 0.05 of the mean edge length) a fold the images held in the previous frame is
    // kept, less the yield. At this size, frames 1–40: mean error 0.239 % with the default,
    // 0.262 % with `--bending-yield 0` (0.131 against 0.143 % over the 640×480 bench clip).
    // The cloth never holds an edge at twice the springs' yield, so its springs pull drift
    // back past the yield too (0.264 % with `--spring-pull-back 0 --spring-stretch-share 0`).
    let (opts, syn) = cloth_320x240(41);
    let mut tr = start(&syn);
    let diag = syn.mesh.bbox_diagonal();
    let mut sum = 0.0;
    for f in 1..opts.frames {
        let report = tr.step(f, &images(&syn, f)).unwrap();
        assert!(!report.stalled, "frame {f} stalled ({:?})", report.stop);
        sum += 100.0 * rms(tr.positions(), &syn.truth[f as usize]) / diag;
    }
    let mean = sum / (opts.frames - 1) as f64;
    eprintln!("mean error {mean:.4} % of the size");
    assert!(mean < 0.245, "mean error {mean:.4} % of the size");
}

#[test]
fn a_draft_at_half_resolution_follows_the_cloth_from_a_fraction_of_the_pixels() {
    // `finest_level: 1` stops at the half-resolution level: a proxy track of large footage.
    // The mesh must still follow the cloth (at half resolution the images hold it less
    // closely), every frame solved there and none at full resolution.
    let (opts, syn) = cloth_320x240(13);
    let run = |finest_level: usize| {
        let options = TrackOptions {
            finest_level,
            ..TrackOptions::default()
        };
        track_mean(&syn, opts.frames, options)
    };
    let (full, full_pixels) = run(0);
    let (draft, draft_pixels) = run(1);
    eprintln!(
        "mean error {full:.4} % ({full_pixels} pixels), draft {draft:.4} % ({draft_pixels} pixels)"
    );
    assert!(draft < 0.35, "draft's mean error {draft:.4} % of the size");
    assert!(
        (draft_pixels as f64) < 0.45 * full_pixels as f64,
        "the draft compared {draft_pixels} pixels at its finest level, full resolution {full_pixels}"
    );
}

#[test]
fn comparing_the_cameras_with_each_other_stops_depth_drifting_on_a_narrow_baseline() {
    // Two cameras with the default cloth's narrow baseline: each camera compared with its own
    // previous frame fixes the motion across its rays well and along them poorly, and the depth
    // error accumulates. `stereo` (on by default) also compares the two cameras in the frame
    // being solved, which fixes where the surface is (320×240, frames 1–24: see the figures
    // printed; the 640×480 bench clip 0.122 → 0.106 % with the defaults, docs/tracker.md).
    let (opts, syn) = cloth_320x240(25);
    let run = |stereo: f64, stereo_stride: u32| {
        let options = TrackOptions {
            stereo,
            stereo_stride,
            ..TrackOptions::default()
        };
        track_mean(&syn, opts.frames, options).0
    };
    let d = TrackOptions::default();
    let without = run(0.0, d.stereo_stride);
    let with = run(d.stereo, d.stereo_stride);
    let every_pixel = run(d.stereo, 1);
    eprintln!(
        "mean error {without:.4} % without, {with:.4} % with the cameras compared (defaults), \
         {every_pixel:.4} % comparing every pixel"
    );
    assert!(
        with < 0.9 * without,
        "mean error {with:.4} % with the cameras compared, {without:.4} % without"
    );
    // Every `stereo_stride`-th pixel at that many times the weight holds the surface as well
    // as every pixel does.
    assert!(
        with < 1.1 * every_pixel,
        "mean error {with:.4} % with every {}th pixel compared, {every_pixel:.4} % with all",
        d.stereo_stride
    );
}

#[test]
fn motion_beyond_the_capture_range_is_reported_and_never_throws_the_mesh_far_away() {
    // The default cloth shaken by 140 px per frame at 640×480, past its 80 px capture range,
    // written as 8-bit PNGs and read back as a user's footage is.
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        frames: 5,
        shake: 140.0,
        ..SynthOptions::default()
    };
    let path = write_dataset(&opts, dir.path(), &|_, _| {}).unwrap();
    let scene = Scene::load(&path).unwrap();
    let diag = scene.mesh.bbox_diagonal();
    let mut tr = Tracker::new(
        &scene.mesh,
        scene.cameras.clone(),
        0,
        &scene.load_images(0).unwrap(),
        TrackOptions::default(),
    )
    .unwrap();
    let mut reported = Vec::new();
    for f in 1..5 {
        let r = tr.step(f, &scene.load_images(f).unwrap()).unwrap();
        if r.suspect || r.stalled {
            reported.push(f);
        }
        // Lost, but on the images: a rigid step once carried it 60 sizes away (88 m for a
        // 1.4 m cloth), where every template pixel, squeezed into a few, fitted as well.
        let truth = scene.ground_truth(f).unwrap().unwrap();
        let err = rms(tr.positions(), &truth.positions) / diag;
        assert!(err < 3.0, "frame {f}: {:.0} % of its size off", 100.0 * err);
    }
    assert!(
        !reported.is_empty(),
        "no frame was reported suspect or stalled"
    );
}

#[test]
fn a_finely_triangulated_mesh_is_compared_at_every_level() {
    // 10 000 vertices on 320×240 footage: at the coarsest level (160×120) a triangle covers about
    // a quarter of a pixel, and a pixel's neighbours belong to triangles rings away on the same
    // smooth sheet. Those pixels must still be compared there, or the coarse levels, which give
    // the tracker its capture range, solve the regularisers alone (they kept 19 pixels of about
    // 15 600, and 640×480 footage moving 32 px per frame was lost: 56 % error).
    let opts = SynthOptions {
        width: 320,
        height: 240,
        frames: 3,
        cloth_grid: 100,
        shake: 24.0,
        ..SynthOptions::default()
    };
    let syn = Synthetic::generate(&opts).unwrap();
    assert_eq!(syn.mesh.positions.len(), 10_000);
    let mut tr = start(&syn);
    let diag = syn.mesh.bbox_diagonal();
    for f in 1..opts.frames {
        let report = tr.step(f, &images(&syn, f)).unwrap();
        let coarsest = report.levels.first().unwrap().pixels as f64;
        let finest = report.levels.last().unwrap().pixels as f64;
        // A level has a quarter of the next finer one's pixels.
        assert!(
            coarsest > 0.15 * finest,
            "frame {f}: {coarsest} pixels at the coarsest level, {finest} at the finest"
        );
        let err = 100.0 * rms(tr.positions(), &syn.truth[f as usize]) / diag;
        assert!(err < 0.3, "frame {f}: error {err:.3} % of the cloth's size");
    }
}

/// Mean and worst per-frame RMS error (% of the size) of tracking `syn` with the defaults, and
/// the median of the frames' information shares (what flags a frame as showing next to no
/// texture below `INFORMATION_FLOOR`); with `told` false the tracker is not told when each camera records nor how
/// long its shutter stays open (as for a rig whose lags and shutters nobody wrote down).
fn track_errors(syn: &Synthetic, told: bool) -> (f64, f64, f64) {
    let mut cameras = syn.cameras.clone();
    if !told {
        cameras.iter_mut().for_each(|c| {
            c.time_offset = 0.0;
            c.shutter = 0.0;
            c.rolling_shutter = 0.0;
        });
    }
    let mut tr = Tracker::new(
        &syn.mesh,
        cameras,
        0,
        &images(syn, 0),
        TrackOptions::default(),
    )
    .unwrap();
    let diag = syn.mesh.bbox_diagonal();
    let mut information = Vec::new();
    let errs: Vec<f64> = (1..syn.frames())
        .map(|f| {
            let report = tr.step(f, &images(syn, f)).unwrap();
            assert!(!report.stalled, "frame {f} stalled");
            information.push(report.information_share);
            100.0 * rms(tr.positions(), &syn.truth[f as usize]) / diag
        })
        .collect();
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    information.sort_by(f64::total_cmp);
    let median = information[information.len() / 2];
    (mean, errs.iter().copied().fold(0.0, f64::max), median)
}

#[test]
fn cameras_out_of_sync_and_a_slow_shutter_are_tolerated_and_known_lags_compensated() {
    // The blob, four cameras at 320×240, carried 10 px per frame.
    let base = SynthOptions {
        width: 320,
        height: 240,
        frames: 7,
        shake: 10.0,
        ..SynthOptions::preset("blob").unwrap()
    };
    let rig = |sync_error, motion_blur| {
        Synthetic::generate(&SynthOptions {
            sync_error,
            motion_blur,
            ..base.clone()
        })
        .unwrap()
    };
    let clean = track_errors(&rig(0.0, 0.0), true);
    assert!(clean.0 < 0.3, "clean mean {:.3} %", clean.0);
    // Clocks spread over a tenth of a frame (3.3 ms at 30 fps: the views disagree by up to a
    // pixel), unknown to the tracker, and a shutter open for half a frame (5 px of smear) cost
    // accuracy in proportion, not the track. (Measured: clean 0.068 %, out of sync and blurred
    // 0.295 % mean; 0.088 % and 0.312 % before the membrane followed the mesh's turn,
    // 2026-12-01, which helps the clean clip most.)
    let hard = track_errors(&rig(0.1, 0.5), false);
    eprintln!("clean {clean:?}, out of sync and blurred {hard:?}");
    assert!(
        hard.0 < 0.5 && hard.1 < 0.8 && hard.0 < 5.0 * clean.0,
        "out of sync and blurred: mean {:.3} %, worst {:.3} % (clean {:.3} %)",
        hard.0,
        hard.1,
        clean.0
    );
    // Lags of up to half a frame: told the cameras' time offsets (as `synth` writes them into
    // the scene), the tracker sees the surface where each camera saw it, moved along its
    // velocity, and gets much of the accuracy back.
    let late = rig(0.5, 0.0);
    let (told, untold) = (track_errors(&late, true), track_errors(&late, false));
    eprintln!("half a frame out of sync: told {told:?}, not told {untold:?}");
    assert!(
        told.0 < 0.75 * untold.0,
        "told the lags: mean {:.3} %, not told: {:.3} %",
        told.0,
        untold.0
    );
}

#[test]
fn fast_motion_under_a_long_shutter_is_compared_under_the_common_smear() {
    // The blob, four cameras at 320×240, carried on a hand-held circle of 16 px per frame (its
    // velocity turns 30° a frame) with the shutter open the whole frame: each image is smeared
    // 16 px along that frame's motion, a different way each frame, and the first frame's
    // anchor is smeared along the first frame's. Told the shutter (as `synth` writes it into
    // the scene), the tracker compares each template and frame under their common smear and
    // leaves out the pixels whose smear reaches past the mesh's outline.
    let syn = Synthetic::generate(&SynthOptions {
        width: 320,
        height: 240,
        frames: 9,
        shake: 16.0,
        motion_blur: 1.0,
        ..SynthOptions::preset("blob").unwrap()
    })
    .unwrap();
    assert!(
        syn.cameras.iter().all(|c| c.shutter == 1.0),
        "synth records the shutter"
    );
    let (told, untold) = (track_errors(&syn, true), track_errors(&syn, false));
    eprintln!("shutter told {told:?}, not told {untold:?}");
    assert!(
        told.0 < 0.75 * untold.0 && told.1 < untold.1,
        "told the shutter: mean {:.3} %, worst {:.3} %; not told: {:.3} %, {:.3} %",
        told.0,
        told.1,
        untold.0,
        untold.1
    );
    // The smears leave less texture than the first frame showed; the frames' information is
    // measured against what the smeared images kept, so a frame is not flagged for it.
    assert!(
        told.2 > 0.5 * untold.2 && told.2 > modelflow::tracker::INFORMATION_FLOOR,
        "median information share {:.3} told the shutter, {:.3} not told",
        told.2,
        untold.2
    );
}

#[test]
fn a_rolling_shutter_is_compensated_when_its_readout_is_known() {
    // The blob, four cameras at 320×240, carried on a hand-held circle of 12 px per frame and
    // filmed by rolling shutters that read from the top row to the bottom one over 0.8 frame
    // (a webcam's 27 ms at 30 fps): its top is seen up to 0.4 frame before the frame's time and
    // its bottom as much after, so each image shows it leaning and stretched along its motion,
    // differently in each frame as the motion turns. Told the readout (as `synth` writes it
    // into the scene), the tracker sees each vertex where it was when its row was read.
    // (Measured 2026-12-08: told 0.264 % mean, 0.311 % worst; not told 0.898 %, 1.086 %; the
    // same motion under global shutters 0.098 %, 0.200 %.)
    let rig = |rolling_shutter| {
        Synthetic::generate(&SynthOptions {
            width: 320,
            height: 240,
            frames: 9,
            shake: 12.0,
            rolling_shutter,
            ..SynthOptions::preset("blob").unwrap()
        })
        .unwrap()
    };
    let syn = rig(0.8);
    assert!(
        syn.cameras.iter().all(|c| c.rolling_shutter == 0.8),
        "synth records the readout"
    );
    let (told, untold) = (track_errors(&syn, true), track_errors(&syn, false));
    let global = track_errors(&rig(0.0), true);
    eprintln!("rolling shutter told {told:?}, not told {untold:?}; global shutter {global:?}");
    assert!(
        told.0 < 0.5 * untold.0 && told.1 < untold.1 && told.0 < 0.4,
        "told the readout: mean {:.3} %, worst {:.3} %; not told: {:.3} %, {:.3} %",
        told.0,
        told.1,
        untold.0,
        untold.1
    );
}

fn blender_scene() -> Scene {
    let p = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/blender-cloth-sample/scene.json"
    );
    Scene::load(std::path::Path::new(p)).expect("the shared Blender sample loads")
}

#[test]
fn blender_cloth_is_tracked_with_default_settings() {
    let scene = blender_scene();
    let dir = tempfile::tempdir().unwrap();
    let mut frames = 0;
    let summary = track_scene(
        &scene,
        &TrackOptions::default(),
        dir.path(),
        &RunOptions::default(),
        &mut |_| frames += 1,
    )
    .unwrap();
    assert_eq!(frames, 11);
    assert_eq!(summary.frames, 12);
    let run = modelflow::read_run(dir.path()).unwrap();
    let report = modelflow::evaluate(&scene, &run).unwrap();
    // Standing still scores 0.30 % mean and 0.86 % final on this clip; OpenCV's pyramidal LK plus
    // triangulation 0.082 % and 0.113 % (tools/opencv_lk_reference.py). Issue #3 asks for at most
    // half of OpenCV's, mean and final.
    eprintln!(
        "Blender sample: mean {:.4} %, final {:.4} %",
        report.rms_mean_pct, report.rms_final_pct
    );
    assert!(
        report.rms_mean_pct <= 0.5 * 0.082,
        "mean {:.4} % is more than half of OpenCV's 0.082 %",
        report.rms_mean_pct
    );
    assert!(
        report.rms_final_pct <= 0.5 * 0.113,
        "final {:.4} % is more than half of OpenCV's 0.113 %",
        report.rms_final_pct
    );
    // Issue #11's no-regression bound, what the tracker scored when the issue was filed
    // (measured now: 0.0359 % and 0.0529 %).
    assert!(
        report.rms_mean_pct <= 0.036 && report.rms_final_pct <= 0.053,
        "mean {:.4} % / final {:.4} %: past issue #11's bound of 0.036 / 0.053 %",
        report.rms_mean_pct,
        report.rms_final_pct
    );
    // The log has one line per solved frame with the documented fields.
    let log = std::fs::read_to_string(dir.path().join("log.jsonl")).unwrap();
    let lines: Vec<serde_json::Value> = log
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 11);
    for (i, l) in lines.iter().enumerate() {
        assert_eq!(l["frame"], i as u64 + 1);
        for key in [
            "iterations",
            "cost_before",
            "cost_after",
            "pixels",
            "seconds",
            "load_seconds",
            "stop",
        ] {
            assert!(!l[key].is_null(), "log line {i} lacks {key}");
        }
        assert!(l["cost_after"].as_f64().unwrap() <= l["cost_before"].as_f64().unwrap());
    }
}

#[test]
fn a_used_folder_is_refused_and_force_replaces_only_run_files() {
    let scene = blender_scene();
    let dir = tempfile::tempdir().unwrap();
    // Left from an earlier, longer run: a frame past the scene's end; and a user's own file.
    std::fs::write(dir.path().join("0042.obj"), "v 0 0 0\n").unwrap();
    std::fs::write(dir.path().join("notes.obj"), "keep me").unwrap();
    let short = Scene { last: 2, ..scene };
    let err = track_scene(
        &short,
        &TrackOptions::default(),
        dir.path(),
        &RunOptions::default(),
        &mut |_| {},
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("not a modelflow run") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(dir.path().join("0042.obj")).unwrap(),
        b"v 0 0 0\n"
    );
    let force = RunOptions {
        mode: OpenMode::Force,
        ..RunOptions::default()
    };
    track_scene(
        &short,
        &TrackOptions::default(),
        dir.path(),
        &force,
        &mut |_| {},
    )
    .unwrap();
    assert!(!dir.path().join("0042.obj").exists());
    assert_eq!(
        std::fs::read(dir.path().join("notes.obj")).unwrap(),
        b"keep me"
    );
    let run = modelflow::read_run(dir.path()).unwrap();
    assert_eq!(
        run.iter().map(|(f, _)| *f).collect::<Vec<_>>(),
        vec![0, 1, 2]
    );
    modelflow::evaluate(&short, &run).unwrap();
}

/// The real webcam board (`fixtures/caliscope-board-sample`, a copy of the shared clip's
/// undistorted frames) with the named cameras (all of them when none are named), tracked with
/// the defaults into a fresh folder (returned), held to the bounds (% of the board's size):
/// every frame but 4 within `frame`, the mean within `mean`, the last frame within `last`.
/// The truth is a rigid pose fitted to corner detections, good to about 0.5 % of the board; at
/// frame 4 one camera saw the board about 10 px off the others' pose (its README), so that
/// frame is left out of the per-frame bound.
fn track_webcam_board(cameras: &[&str], frame: f64, mean: f64, last: f64) -> tempfile::TempDir {
    let p = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/caliscope-board-sample/scene.json"
    );
    let mut scene = Scene::load(std::path::Path::new(p)).expect("the webcam sample loads");
    if !cameras.is_empty() {
        let names: Vec<String> = cameras.iter().map(|c| c.to_string()).collect();
        scene = scene.with_cameras(&names).expect("the sample's cameras");
    }
    let dir = tempfile::tempdir().unwrap();
    track_scene(
        &scene,
        &TrackOptions::default(),
        dir.path(),
        &RunOptions::default(),
        &mut |_| {},
    )
    .unwrap();
    let run = modelflow::read_run(dir.path()).unwrap();
    let report = modelflow::evaluate(&scene, &run).unwrap();
    let per_frame: Vec<f64> = report.per_frame.iter().map(|f| f.rms_pct).collect();
    eprintln!("webcam board {cameras:?}: {per_frame:.2?} %");
    for (f, &e) in per_frame.iter().enumerate() {
        assert!(
            f == 4 || e <= frame,
            "frame {f}: {e:.2} % of the board's size"
        );
    }
    assert!(
        report.rms_mean_pct <= mean,
        "mean {:.2} %",
        report.rms_mean_pct
    );
    assert!(
        report.rms_final_pct <= last,
        "final {:.2} %",
        report.rms_final_pct
    );
    dir
}

/// Real webcam footage (`fixtures/caliscope-board-sample`, a copy of the shared clip's
/// undistorted frames): a glossy board held in both hands, four webcams, 4–18 px per frame.
#[test]
fn the_real_webcam_board_is_tracked_without_folding() {
    // With the first frame compared at the coarsest pyramid level too, a corner of the board
    // folded out of its plane at frames 11–15 (1.6–2.1 %, final 1.5 %); the defaults measure
    // 0.52 % mean, 0.70 % worst frame but 4, 0.30 % final.
    track_webcam_board(&[], 1.0, 0.8, 0.6);
}

/// The same real board seen by two of its four webcams (cam1 and cam2), as a stereo rig sees
/// it. At frame 12 the board moves about 8 px in cam1; the coarsest pyramid level (the board
/// 22–38 px across there) moved it 4 cm, into a valley the finer levels did not leave: every
/// frame from 12 on was 5–8 % of the board's size off, unflagged. The level after the coarsest
/// is now also solved from where the coarsest started when the coarsest level's move did not
/// clearly explain that level's images, and the start whose solution costs less is kept
/// (docs/tracker.md, "A second start after the coarsest level").
#[test]
fn two_webcams_of_the_real_board_follow_it_where_the_coarsest_level_leads_off() {
    // Frame 4's truth is the README's doubtful one; the defaults measure 0.58 % mean, 1.05 %
    // worst frame but 4, 0.48 % final.
    let dir = track_webcam_board(&["cam1", "cam2"], 1.3, 0.8, 0.8);
    // The log says where the second start was kept.
    let log = std::fs::read_to_string(dir.path().join("log.jsonl")).unwrap();
    let kept = log
        .lines()
        .filter(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            v["second_start"] == "kept"
        })
        .count();
    assert!(kept >= 1, "no frame kept its second start");
}

//! Tracker behaviour on exactly rendered planar footage (ray-traced analytically here, so the
//! test does not depend on the project's own renderer): zero motion stays put, a rigid motion is
//! recovered, a moving camera is handled.

use crate::base::camera::{look_at, Camera, Projection};
use crate::base::image::RgbImage;
use crate::base::mesh::{grid, rms_distance, Mesh};
use crate::tracker::patch::{PatchOptions, PatchSet};
use crate::tracker::pyramid::Pyramid;
use crate::tracker::regularise::{self, EdgeSet, FrameContext, Regularisation};
use crate::tracker::solve::{
    GainModel, Interpolation, Lag, Loss, Motion, Problem, SolveSummary, SolverOptions, StageRole,
};
use crate::tracker::{FrameReport, TrackOptions, Tracker};
use nalgebra::{Matrix3, Point3, Vector3};
use std::sync::Arc;

/// A smooth, colourful, non-periodic texture on the unit square.
fn texture(s: f64, t: f64) -> [f32; 3] {
    let f = |a: f64, b: f64, c: f64, d: f64| {
        (a * s * std::f64::consts::TAU + b * t * std::f64::consts::TAU + c).sin() * d
    };
    let r = 0.5 + f(7.3, 2.1, 0.3, 0.2) + f(3.1, 11.7, 1.1, 0.15) + f(17.0, 5.3, 2.0, 0.1);
    let g = 0.5 + f(2.9, 8.3, 0.7, 0.2) + f(13.1, 3.7, 2.1, 0.15) + f(6.0, 19.3, 0.4, 0.1);
    let b = 0.5 + f(9.7, 6.1, 1.7, 0.2) + f(4.3, 15.1, 0.2, 0.15) + f(21.0, 9.0, 1.3, 0.1);
    [r as f32, g as f32, b as f32]
}

struct Plane {
    origin: Point3<f64>,
    u: Vector3<f64>,
    v: Vector3<f64>,
}

impl Plane {
    fn at(&self, s: f64, t: f64) -> Point3<f64> {
        self.origin + self.u * s + self.v * t
    }

    /// Directions to move a 4×4 grid of `n` vertices on the plane along, for curvature tests:
    /// every vertex along the normal, vertex 5 alone, and a slide within the plane.
    fn directions(&self, n: usize) -> Vec<Vec<Vector3<f64>>> {
        let normal = self.u.cross(&self.v).normalize();
        vec![
            vec![normal; n],
            (0..n)
                .map(|i| {
                    if i == 5 {
                        Vector3::new(0.3, 0.2, -1.0)
                    } else {
                        Vector3::zeros()
                    }
                })
                .collect(),
            (0..n)
                .map(|i| self.u.normalize() * (0.5 + (i % 4) as f64 * 0.25))
                .collect(),
        ]
    }
}

/// Along `dir` from `x`: the Gauss–Newton model's curvature `2·δᵀAδ` and the cost's own, by
/// second differences of `Problem::cost`.
fn curvatures(
    problem: &Problem,
    a: &crate::tracker::sparse::BlockSparse,
    x: &[Point3<f64>],
    dir: &[Vector3<f64>],
    opts: &SolverOptions,
) -> (f64, f64) {
    let mut ad = vec![Vector3::zeros(); x.len()];
    a.mul(dir, &mut ad);
    let model = 2.0 * dir.iter().zip(&ad).map(|(u, v)| u.dot(v)).sum::<f64>();
    let h = 2e-4;
    let at = |e: f64| {
        let y: Vec<Point3<f64>> = x.iter().zip(dir).map(|(p, u)| p + u * e).collect();
        problem.cost(&y, opts)
    };
    (model, (at(h) - 2.0 * at(0.0) + at(-h)) / (h * h))
}

/// Ray-traces the plane with 3×3 supersampling (pixel centres at integer coordinates).
fn render(
    plane: &Plane,
    k: &Matrix3<f64>,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    w: usize,
    h: usize,
) -> RgbImage {
    let kinv = k.try_inverse().unwrap();
    let c = -(r.transpose() * t);
    let n = plane.u.cross(&plane.v);
    RgbImage::from_fn(w, h, |x, y| {
        let mut acc = [0.0f32; 3];
        for sy in 0..3 {
            for sx in 0..3 {
                let px = x as f64 + (sx as f64 - 1.0) / 3.0;
                let py = y as f64 + (sy as f64 - 1.0) / 3.0;
                let d = r.transpose() * (kinv * Vector3::new(px, py, 1.0));
                let lam = (plane.origin - Point3::from(c)).dot(&n) / d.dot(&n);
                let p = Point3::from(c) + d * lam - plane.origin;
                let s = p.dot(&plane.u) / plane.u.norm_squared();
                let tt = p.dot(&plane.v) / plane.v.norm_squared();
                let col = if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&tt) {
                    texture(s, tt)
                } else {
                    [0.1, 0.1, 0.1]
                };
                for ch in 0..3 {
                    acc[ch] += col[ch] / 9.0;
                }
            }
        }
        acc
    })
}

struct Rig {
    k: Matrix3<f64>,
    poses: Vec<(Matrix3<f64>, Vector3<f64>)>,
}

impl Rig {
    fn new(eyes: &[Point3<f64>]) -> Self {
        let k = Matrix3::new(300.0, 0.0, 79.5, 0.0, 300.0, 59.5, 0.0, 0.0, 1.0);
        let poses = eyes
            .iter()
            .map(|e| look_at(e, &Point3::new(0.0, 0.0, 0.0), &Vector3::z()))
            .collect();
        Rig { k, poses }
    }
    fn cameras(&self) -> Vec<Camera> {
        self.poses
            .iter()
            .enumerate()
            .map(|(i, (r, t))| {
                Camera::fixed(
                    format!("cam{i}"),
                    160,
                    120,
                    Projection::from_krt(&self.k, r, t).unwrap(),
                )
            })
            .collect()
    }
    fn images(&self, plane: &Plane) -> Vec<RgbImage> {
        self.poses
            .iter()
            .map(|(r, t)| render(plane, &self.k, r, t, 160, 120))
            .collect()
    }
}

fn plane_at(offset: Vector3<f64>) -> Plane {
    Plane {
        origin: Point3::new(-0.3, 0.0, -0.25) + offset,
        u: Vector3::new(0.6, 0.0, 0.0),
        v: Vector3::new(0.0, 0.1, 0.5),
    }
}

fn mesh_of(plane: &Plane) -> Mesh {
    grid(9, 9, |s, t| plane.at(s, t))
}

fn rig() -> Rig {
    Rig::new(&[Point3::new(-0.15, -1.5, 0.2), Point3::new(0.15, -1.5, 0.25)])
}

#[test]
fn zero_motion_stays_put() {
    let rig = rig();
    let plane = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane);
    let imgs = rig.images(&plane);
    let mut tr = Tracker::new(&mesh, rig.cameras(), 0, &imgs, TrackOptions::default()).unwrap();
    let mut settled = Vec::new();
    for f in 1..12 {
        let rep = tr.step(f, &imgs).unwrap();
        assert!(rep.pixels > 5000, "{}", rep.pixels);
        if f == 2 {
            settled = tr.positions().to_vec();
        }
    }
    // The cameras compared with each other (`stereo`) put the surface where the two renders
    // agree best, a few hundredths of a pixel from the given mesh (0.12 mm on this 0.6 m
    // plane, 0.02 %), within two frames; after that nothing moves: no drift.
    let err = rms_distance(tr.positions(), &mesh.positions);
    assert!(err < 2e-4, "{err} m from the given mesh with no motion");
    let since = rms_distance(tr.positions(), &settled);
    assert!(
        since < 1e-6,
        "drifted {since} m over frames 3 to 11 with no motion"
    );
    let still = TrackOptions {
        stereo: 0.0,
        ..TrackOptions::default()
    };
    let mut tr = Tracker::new(&mesh, rig.cameras(), 0, &imgs, still).unwrap();
    for f in 1..3 {
        tr.step(f, &imgs).unwrap();
    }
    let err = rms_distance(tr.positions(), &mesh.positions);
    assert!(
        err < 1e-4,
        "drifted {err} m with no motion (cameras not compared)"
    );
}

#[test]
fn a_camera_lag_beyond_a_frame_is_refused_by_name() {
    let rig = rig();
    let plane = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane);
    let imgs = rig.images(&plane);
    for bad in [f64::NAN, 1.5, -3.0] {
        let mut cams = rig.cameras();
        cams[1].time_offset = bad;
        let err = Tracker::new(&mesh, cams, 0, &imgs, TrackOptions::default())
            .err()
            .expect("refused")
            .to_string();
        assert!(err.contains("cameras[1].time_offset"), "{err}");
    }
}

#[test]
fn images_prepared_ahead_give_the_same_step_and_must_match_the_levels() {
    // `track_scene` builds the next frame's pyramids while the current one is solved; that must
    // not change the result.
    let rig = rig();
    let plane0 = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane0);
    let imgs0 = rig.images(&plane0);
    let imgs1 = rig.images(&plane_at(Vector3::new(0.004, 0.0, -0.003)));
    let opts = TrackOptions {
        levels: 2,
        ..TrackOptions::default()
    };
    let mut a = Tracker::new(&mesh, rig.cameras(), 0, &imgs0, opts).unwrap();
    let mut b = Tracker::new(&mesh, rig.cameras(), 0, &imgs0, opts).unwrap();
    a.step(1, &imgs1).unwrap();
    b.step_prepared(1, crate::tracker::prepare(&imgs1, &opts))
        .unwrap();
    assert_eq!(a.positions(), b.positions());
    let fewer = TrackOptions { levels: 1, ..opts };
    let err = b
        .step_prepared(2, crate::tracker::prepare(&imgs1, &fewer))
        .unwrap_err()
        .to_string();
    assert!(err.contains("pyramid levels"), "{err}");
    let blurrier = TrackOptions { blur: 2.0, ..opts };
    let err = b
        .step_prepared(2, crate::tracker::prepare(&imgs1, &blurrier))
        .unwrap_err()
        .to_string();
    assert!(err.contains("blur"), "{err}");
}

/// Tracks `mesh(plane)` from the plane at rest through frames `1..=frames` of it moving by
/// `motion` per frame, seen in `images(plane)`; asserts that no frame stalls and returns each
/// frame's RMS vertex error (m) against `mesh(plane)`.
fn track_plane(
    rig: &Rig,
    opts: TrackOptions,
    motion: Vector3<f64>,
    frames: u32,
    mesh: impl Fn(&Plane) -> Mesh,
    images: impl Fn(&Plane) -> Vec<RgbImage>,
) -> Vec<f64> {
    let plane0 = plane_at(Vector3::zeros());
    let mut tr = Tracker::new(&mesh(&plane0), rig.cameras(), 0, &images(&plane0), opts).unwrap();
    (1..=frames)
        .map(|f| {
            let plane = plane_at(motion * f as f64);
            let rep = tr.step(f, &images(&plane)).unwrap();
            assert!(!rep.stalled, "frame {f} stalled");
            rms_distance(tr.positions(), &mesh(&plane).positions)
        })
        .collect()
}

#[test]
fn rigid_motion_is_recovered() {
    let rig = rig();
    let motion = Vector3::new(0.006, -0.004, 0.005);
    let errors = track_plane(&rig, TrackOptions::default(), motion, 4, mesh_of, |p| {
        rig.images(p)
    });
    for (f, err) in (1..).zip(errors) {
        eprintln!("frame {f}: rms error {err:.2e} m");
        // 0.6 m plane; 1 pixel at 1.5 m is 5 mm. Ask for a small fraction of a pixel.
        assert!(err < 1.0e-3, "frame {f}: rms {err}");
    }
}

#[test]
fn a_large_motion_is_caught() {
    // 2 cm per frame along the image rows and 1 cm in depth: about 4 px per frame in 160×120
    // images whose automatic pyramid has one level; the rigid stage catches it, the free stage
    // refines it.
    let rig = rig();
    let motion = Vector3::new(0.02, 0.01, -0.008);
    let errors = track_plane(&rig, TrackOptions::default(), motion, 3, mesh_of, |p| {
        rig.images(p)
    });
    for (f, err) in (1..).zip(errors) {
        assert!(err < 1.5e-3, "frame {f}: rms {err} m for a 2.4 cm motion");
    }
}

/// The relative decreases of a stage's accepted steps, in order.
fn accepted_decreases(stage: &crate::tracker::solve::SolveSummary) -> Vec<f64> {
    stage
        .iterations
        .iter()
        .filter(|i| i.accepted)
        .map(|i| -i.cost_change / (i.cost - i.cost_change))
        .collect()
}

#[test]
fn approach_stages_stop_at_their_own_decrease_and_the_frames_stay_as_accurate() {
    // Two levels: the coarsest (rigid, then free) and full resolution (a Huber approach, then
    // the Tukey refine). Only the approach may stop at `approach_decrease`; every other stage
    // goes on while a step lowers its cost by `min_relative_decrease` or more.
    let rig = rig();
    let motion = Vector3::new(0.006, -0.004, 0.005);
    let track = |approach: f64| {
        let opts = TrackOptions {
            levels: 2,
            approach_decrease: approach,
            ..TrackOptions::default()
        };
        let min = opts.solver.min_relative_decrease;
        let plane0 = plane_at(Vector3::zeros());
        let mut tr = Tracker::new(
            &mesh_of(&plane0),
            rig.cameras(),
            0,
            &rig.images(&plane0),
            opts,
        )
        .unwrap();
        let mut reports = Vec::new();
        for f in 1..=3u32 {
            let plane = plane_at(motion * f as f64);
            let rep = tr.step(f, &rig.images(&plane)).unwrap();
            assert!(!rep.stalled, "frame {f} stalled");
            let err = rms_distance(tr.positions(), &mesh_of(&plane).positions);
            assert!(err < 1.0e-3, "approach {approach}, frame {f}: rms {err} m");
            assert_eq!(rep.levels.len(), 4, "stages: {:?}", rep.levels);
            for (k, stage) in rep.levels.iter().enumerate() {
                let threshold = if k == 2 { min.max(approach) } else { min };
                let d = accepted_decreases(stage);
                // Every accepted step but the last lowered the cost by the threshold or more
                // (else the stage would have stopped there).
                for (i, &dec) in d.iter().enumerate().take(d.len().saturating_sub(1)) {
                    assert!(
                        dec >= threshold,
                        "approach {approach}, frame {f}, stage {k}: step {i} lowered the cost by \
                         {dec:.2e} < {threshold:.0e} and the stage went on: {stage:?}"
                    );
                }
            }
            reports.push(rep);
        }
        reports
    };
    let strict = track(0.0);
    let loose = track(0.03);
    // The coarsest level is not an approach: the first frame's is the same either way.
    for k in 0..2 {
        assert_eq!(
            accepted_decreases(&strict[0].levels[k]),
            accepted_decreases(&loose[0].levels[k]),
            "stage {k}"
        );
    }
    let tries = |r: &[crate::tracker::FrameReport]| -> usize {
        r.iter().map(|r| r.levels[2].iterations.len()).sum()
    };
    eprintln!(
        "approach stages' tries over 3 frames: {} with the looser stop, {} without",
        tries(&loose),
        tries(&strict)
    );
    assert!(tries(&loose) < tries(&strict));
}

#[test]
fn a_frame_whose_images_show_no_texture_where_the_mesh_is_is_suspect() {
    // A tracked frame keeps about the information the first frame's own images give the mesh;
    // a mesh that slipped off onto a plain background sees none: every camera shows flat grey
    // in frame 2 here. Its information share falls under the floor and the frame is suspect.
    let rig = rig();
    let plane0 = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane0);
    let mut tr = Tracker::new(
        &mesh,
        rig.cameras(),
        0,
        &rig.images(&plane0),
        TrackOptions::default(),
    )
    .unwrap();
    let rep = tr
        .step(
            1,
            &rig.images(&plane_at(Vector3::new(0.004, -0.002, 0.003))),
        )
        .unwrap();
    assert!(
        rep.information_share > 0.5 && !rep.suspect,
        "frame 1: share {}, suspect {}",
        rep.information_share,
        rep.suspect
    );
    let grey: Vec<RgbImage> = rig
        .images(&plane0)
        .iter()
        .map(|i| RgbImage::from_fn(i.width(), i.height(), |_, _| [0.5; 3]))
        .collect();
    let rep = tr.step(2, &grey).unwrap();
    assert!(
        rep.information_share < crate::tracker::INFORMATION_FLOOR && rep.suspect,
        "frame 2: share {}, suspect {}",
        rep.information_share,
        rep.suspect
    );
}

#[test]
fn a_blank_image_is_left_out_of_its_frame_and_of_the_templates_taken_from_it() {
    // Camera 0's image is black at the first frame (a lens cap taken off late) and again at
    // frame 2 (a dropped frame written black). Compared, a black image matches nothing: before
    // it was left out, the first case moved a cloth 78 % of its size off and the second broke
    // a limb to 6.8 % once the camera's pictures came back.
    let rig = rig();
    let motion = Vector3::new(0.006, -0.004, 0.005);
    let plane0 = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane0);
    let black = |imgs: Vec<RgbImage>| -> Vec<RgbImage> {
        let mut imgs = imgs;
        imgs[0] = RgbImage::new(imgs[0].width(), imgs[0].height());
        imgs
    };
    let mut tr = Tracker::new(
        &mesh,
        rig.cameras(),
        0,
        &black(rig.images(&plane0)),
        TrackOptions::default(),
    )
    .unwrap();
    assert_eq!(tr.blank_at_first(), [0]);
    for f in 1..=5u32 {
        let plane = plane_at(motion * f as f64);
        let imgs = if f == 2 {
            black(rig.images(&plane))
        } else {
            rig.images(&plane)
        };
        let rep = tr.step(f, &imgs).unwrap();
        let err = rms_distance(tr.positions(), &mesh_of(&plane).positions);
        assert!(!rep.stalled, "frame {f} stalled");
        assert!(err < 1.0e-3, "frame {f}: rms {err} m");
        if f == 2 {
            assert_eq!(rep.blank_cameras, [0]);
            assert!(rep.suspect, "frame 2 is to be checked");
        } else {
            assert!(rep.blank_cameras.is_empty(), "frame {f}");
        }
    }
}

#[test]
fn a_frame_that_cannot_be_improved_is_reported_as_stalled() {
    // A NaN in the next image (the file readers refuse them; a library user might not) makes
    // every cost that samples it NaN: no step can lower it, and the report must say so.
    let rig = rig();
    let plane0 = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane0);
    let imgs0 = rig.images(&plane0);
    let mut tr = Tracker::new(&mesh, rig.cameras(), 0, &imgs0, TrackOptions::default()).unwrap();
    let mut imgs1 = rig.images(&plane_at(Vector3::new(0.004, 0.0, 0.0)));
    let w = imgs1[0].width();
    let h = imgs1[0].height();
    imgs1[0].pixels_mut()[(h / 2) * w + w / 2] = [f32::NAN; 3];
    let rep = tr.step(1, &imgs1).unwrap();
    assert!(rep.stalled, "{rep:?}");
    assert_eq!(tr.positions(), &mesh.positions[..]);
    // The next, clean frame is tracked again.
    let rep = tr
        .step(2, &rig.images(&plane_at(Vector3::new(0.004, 0.0, 0.0))))
        .unwrap();
    assert!(!rep.stalled);
}

#[test]
fn a_frame_in_which_no_camera_sees_the_mesh_is_reported_as_stalled() {
    // Moved out of every camera's view, the mesh has no pixel to compare: only the regularisers
    // would move it (a mesh left in that state flew off and reported "converged" for every later
    // frame), so the frame must count as stalled and keep its shape.
    let rig = rig();
    let plane0 = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane0);
    let imgs0 = rig.images(&plane0);
    let mut tr = Tracker::new(&mesh, rig.cameras(), 0, &imgs0, TrackOptions::default()).unwrap();
    let away: Vec<Point3<f64>> = mesh
        .positions
        .iter()
        .map(|p| p + Vector3::new(0.0, 0.0, -100.0))
        .collect();
    tr.set_positions(away.clone()).unwrap();
    let rep = tr.step(1, &rig.images(&plane0)).unwrap();
    assert_eq!(rep.pixels, 0, "{rep:?}");
    assert!(rep.stalled, "{rep:?}");
    assert_eq!(tr.positions(), &away[..]);
}

/// Checks the assembled gradient (`−2·b`, the cost's gradient with Huber off) against central
/// differences of the cost at `x`, every axis of `vertices`, to 1 % relative; returns how many
/// entries it compared.
fn check_gradient(
    problem: &Problem,
    x: &[Point3<f64>],
    opts: &SolverOptions,
    vertices: &[usize],
    what: &str,
) -> usize {
    let (_, _, b) = problem.linearize(x, opts);
    // Image values are f32: a step of 0.1 mm keeps the difference well above their rounding.
    let eps = 1e-4;
    let mut checked = 0;
    for &v in vertices {
        for k in 0..3 {
            let mut xp = x.to_vec();
            xp[v][k] += eps;
            let mut xm = x.to_vec();
            xm[v][k] -= eps;
            let fd = (problem.cost(&xp, opts) - problem.cost(&xm, opts)) / (2.0 * eps);
            let analytic = -2.0 * b[v][k];
            assert!(
                (fd - analytic).abs() <= 1e-2 * fd.abs().max(analytic.abs()) + 1e-9,
                "{what}: vertex {v} axis {k}: fd {fd} vs analytic {analytic}"
            );
            checked += 1;
        }
    }
    checked
}

/// Every camera's patches of `mesh` at frame 0 (full resolution, every pixel), from `src`.
fn frame0_patches(mesh: &Mesh, cams: &[Camera], src: &[Pyramid]) -> PatchSet {
    let popts = PatchOptions {
        margin: 1,
        min_cos: 0.1,
        two_sided: true,
        checkerboard: false,
        stride: 1,
    };
    let mut set = PatchSet::default();
    for (c, cam) in cams.iter().enumerate() {
        set.add_camera(
            &mesh.positions,
            &mesh.triangles,
            cam.at(0),
            &src[c].levels[0],
            c as u16,
            1.0,
            &popts,
            None,
        );
    }
    set
}

/// The photometric problem of frame-0 patches `set` against the full-resolution images `dst`
/// that `cams` saw at frame 1, with `regularisers` (the setup of the tests on one plane).
fn frame1_problem<'a>(
    mesh: &'a Mesh,
    set: &'a PatchSet,
    by_triangle: &'a [(u32, std::ops::Range<usize>)],
    dst: &'a [Pyramid],
    cams: &[Camera],
    pattern: &'a [[u32; 2]],
    regularisers: &'a [Box<dyn regularise::Regulariser>],
) -> Problem<'a> {
    Problem {
        regularisers,
        ..Problem::photometric(
            &mesh.triangles,
            set,
            by_triangle,
            dst.iter().map(|p| &p.levels[0]).collect(),
            cams.iter().map(|c| c.at(1).clone()).collect(),
            pattern,
        )
    }
}

/// The tests on one plane moved between two frames: the rig, the plane at frame 0 and moved
/// 5 mm at frame 1, and its 4×4 mesh at frame 0.
struct MovedPlane {
    rig: Rig,
    at0: Plane,
    at1: Plane,
    mesh: Mesh,
    cams: Vec<Camera>,
}

impl MovedPlane {
    fn new() -> Self {
        let rig = rig();
        let at0 = plane_at(Vector3::zeros());
        let at1 = plane_at(Vector3::new(0.004, 0.0, -0.003));
        let mesh = grid(4, 4, |s, t| at0.at(s, t));
        let cams = rig.cameras();
        MovedPlane {
            rig,
            at0,
            at1,
            mesh,
            cams,
        }
    }

    /// Each camera's one-level pyramid of `plane`, the light scaled by `light`.
    fn pyramids(&self, plane: &Plane, light: f32) -> Vec<Pyramid> {
        self.rig
            .images(plane)
            .into_iter()
            .map(|mut img| {
                if light != 1.0 {
                    img.pixels_mut()
                        .iter_mut()
                        .for_each(|px| *px = px.map(|c| light * c));
                }
                Pyramid::new(&img, 1, 1.0)
            })
            .collect()
    }
}

/// The regularisers of `mesh`, their frame begun with the mesh at rest (its own positions as the
/// previous and the predicted shape).
fn regularisers_at_rest(
    mesh: &Mesh,
    edges: &Arc<EdgeSet>,
    reg: &Regularisation,
) -> Vec<Box<dyn regularise::Regulariser>> {
    let mut regularisers = regularise::build(mesh, edges, reg);
    for r in &mut regularisers {
        r.begin_frame(&FrameContext {
            previous: &mesh.positions,
            predicted: &mesh.positions,
            information: None,
        });
    }
    regularisers
}

#[test]
fn assembled_gradient_matches_finite_differences_of_the_cost() {
    let moved = MovedPlane::new();
    let (mesh, cams) = (&moved.mesh, &moved.cams);
    let src = moved.pyramids(&moved.at0, 1.0);
    let dst = moved.pyramids(&moved.at1, 1.0);
    let mut set = frame0_patches(mesh, cams, &src);
    let by_triangle = set.by_triangle();
    let edges = Arc::new(EdgeSet::new(mesh));
    // A stretched spring (k = 5) and a membrane term are included too.
    let reg = Regularisation {
        spring_k: 5.0,
        bending: 0.0,
        ..Regularisation::default()
    };
    let regularisers = regularisers_at_rest(mesh, &edges, &reg);
    let problem = frame1_problem(
        mesh,
        &set,
        &by_triangle,
        &dst,
        cams,
        &edges.edges,
        &regularisers,
    );
    // Huber off (huge threshold) so the cost is the plain sum of squares whose gradient is 2·Jᵀr.
    // Both ways of sampling the next frame: the Jacobian is each interpolant's own derivative.
    let mut checked = 0;
    for interpolation in [Interpolation::Cubic, Interpolation::Linear] {
        let opts = SolverOptions {
            huber: 1e3,
            interpolation,
            ..SolverOptions::default()
        };
        let mut x = mesh.positions.clone();
        x[5].x += 0.02;
        x[6].z -= 0.01;
        checked += check_gradient(
            &problem,
            &x,
            &opts,
            &[5, 6, 9, 10],
            &format!("{interpolation:?}"),
        );
    }
    assert_eq!(checked, 24);

    // Tukey with a threshold the displaced pixels reach, and the patches' Cauchy loss on top
    // (its gradient is the pixels' scaled per patch; the threshold's gradient term is off, so
    // the thresholds do not move with the positions): the cost it adds is differentiated too.
    // Gains off: they are fitted by least squares, which is optimal for (and so needs no
    // derivative in) the plain squares only.
    let mut x = mesh.positions.clone();
    x[5].x += 0.02;
    x[6].z -= 0.01;
    let tukey = |patch_scale: f64| SolverOptions {
        loss: Loss::Tukey,
        huber: 0.3,
        tukey_px: 0.0,
        patch_scale,
        gain: GainModel::Off,
        ..SolverOptions::default()
    };
    assert!(
        problem.cost(&x, &tukey(0.5)) < 0.99 * problem.cost(&x, &tukey(0.0)),
        "the patches' loss changed nothing"
    );
    assert_eq!(
        check_gradient(&problem, &x, &tukey(0.5), &[5, 6, 9, 10], "patches"),
        12
    );

    // Cameras that record late or early see the surface moved on along its velocity (over one
    // frame, and over two after a stalled frame): the derivative carries the velocity's
    // dependence on the positions.
    let offsets = per_vertex(
        &(0..cams.len())
            .map(|c| 0.3 - 0.45 * c as f64)
            .collect::<Vec<_>>(),
        mesh.positions.len(),
    );
    let previous: Vec<Point3<f64>> = mesh
        .positions
        .iter()
        .map(|p| p - Vector3::new(0.003, -0.001, 0.002))
        .collect();
    let opts = SolverOptions {
        huber: 1e3,
        ..SolverOptions::default()
    };
    let mut x = mesh.positions.clone();
    x[5].x += 0.01;
    for gap in [1.0, 2.0] {
        let lagged = Problem {
            lag: Some(Lag {
                offsets: &offsets,
                previous: &previous,
                gap,
            }),
            targets: dst.iter().map(|p| &p.levels[0]).collect(),
            projections: cams.iter().map(|c| c.at(1).clone()).collect(),
            ..problem
        };
        let (c_on, c_late) = (problem.cost(&x, &opts), lagged.cost(&x, &opts));
        assert!(c_on != c_late, "the lag changed nothing");
        let n = check_gradient(
            &lagged,
            &x,
            &opts,
            &[5, 6, 9, 10],
            &format!("lagged cameras, gap {gap}"),
        );
        assert_eq!(n, 12);
    }

    // The confidence the tracker reads from a solve's last linearisation is the one a fresh
    // linearisation at the solve's result gives, exactly.
    let opts = SolverOptions::default();
    let mut start = mesh.positions.clone();
    start[5].x += 0.01;
    let (x, _, lin) = problem.solve_motion(&start, None, &opts, Motion::Free);
    let fresh = problem.vertex_confidence(&x, &problem.solve_options(&start, &opts));
    assert_eq!(problem.confidence(&lin), fresh);
    assert!(fresh.iter().any(|c| c.information > 0.0));
    // A Huber solve asked to collect the residuals' median carries, at its result, exactly the
    // median a pass of its own there gives; a Tukey solve started from that linearisation ends
    // where one that takes the median itself does.
    let huber = SolverOptions {
        loss: Loss::Huber,
        ..opts
    };
    // As an approach stage too (from this far off its steps are tried with the normal
    // equations, as any stage's): the median comes from the pass at its result.
    let role = StageRole {
        collect_median: true,
        approach: true,
    };
    let (xh, _, lin_h) = problem.solve_stage(&start, None, &huber, Motion::Free, role);
    assert!(lin_h.median().is_some());
    assert_eq!(lin_h.median(), problem.median_residual(&xh, &huber));
    let (carried, _, _) = problem.solve_motion(&xh, Some(lin_h), &opts, Motion::Free);
    let (own, _, _) = problem.solve_motion(&xh, None, &opts, Motion::Free);
    assert_eq!(carried, own);

    // An approach stage (a finer level or the refine follows) ends on a step that does what its
    // model promised, but only where the next step could not still promise its threshold: from
    // this far off (the first step takes 97 % of the cost, and what is left is so little that 5 %
    // of either step's decrease would still count) it goes on step for step as the same stage in
    // no role does, and ends where it does.
    let approach = SolverOptions {
        min_relative_decrease: 0.03,
        ..huber
    };
    let (xf, full, _) =
        problem.solve_stage(&start, None, &approach, Motion::Free, StageRole::default());
    let role = StageRole {
        collect_median: false,
        approach: true,
    };
    let (xa, on_approach, _) = problem.solve_stage(&start, None, &approach, Motion::Free, role);
    assert_eq!(xa, xf);
    assert_eq!(on_approach.iterations.len(), 3);
    for (a, f) in on_approach.iterations.iter().zip(&full.iterations) {
        assert_eq!(
            (a.accepted, a.cost, a.cg_iterations),
            (f.accepted, f.cost, f.cg_iterations)
        );
    }
}

/// A plane moved between two frames whose next images carry noise: a cost with a floor, as
/// footage has, so that a stage's relative decreases settle.
#[test]
fn an_approach_stage_ends_on_a_step_its_model_predicted() {
    let moved = MovedPlane::new();
    let (mesh, cams) = (&moved.mesh, &moved.cams);
    let src = moved.pyramids(&moved.at0, 1.0);
    // Deterministic noise of about 0.03 in every channel.
    let dst: Vec<Pyramid> = moved
        .rig
        .images(&moved.at1)
        .into_iter()
        .map(|mut img| {
            let mut h = 0x9e37_79b9_u32;
            for px in img.pixels_mut() {
                *px = px.map(|c| {
                    h ^= h << 13;
                    h ^= h >> 17;
                    h ^= h << 5;
                    c + 0.06 * ((h % 1000) as f32 / 1000.0 - 0.5)
                });
            }
            Pyramid::new(&img, 1, 1.0)
        })
        .collect();
    let mut set = frame0_patches(mesh, cams, &src);
    let by_triangle = set.by_triangle();
    let edges = Arc::new(EdgeSet::new(mesh));
    let regularisers = regularisers_at_rest(mesh, &edges, &Regularisation::default());
    let problem = frame1_problem(
        mesh,
        &set,
        &by_triangle,
        &dst,
        cams,
        &edges.edges,
        &regularisers,
    );
    let approach = SolverOptions {
        loss: Loss::Huber,
        min_relative_decrease: 0.03,
        ..SolverOptions::default()
    };
    // Near the solution, as a finer level starts from a coarser one's: the noise's floor is
    // most of the cost there.
    let (mut start, _) = problem.solve(&mesh.positions, &approach);
    start[5].x += 0.0005;
    start[10].y -= 0.0005;
    let (xf, full, _) =
        problem.solve_stage(&start, None, &approach, Motion::Free, StageRole::default());
    let role = StageRole {
        collect_median: true,
        approach: true,
    };
    let (xa, ends, lin) = problem.solve_stage(&start, None, &approach, Motion::Free, role);
    // The same stage in no role takes one step and then solves one more only to find that it
    // promises too little; the approach stage ends on the first, at the same mesh.
    let accepted = |s: &SolveSummary| s.iterations.iter().filter(|i| i.accepted).count();
    assert_eq!((accepted(&full), full.iterations.len()), (1, 2));
    assert_eq!((accepted(&ends), ends.iterations.len()), (1, 1));
    assert_eq!(xa, xf);
    assert_eq!(ends.final_cost, full.final_cost);
    // The median comes from the pass at its result; the normal equations it returns are the
    // start's, so a stage that goes on from its result linearises afresh.
    assert_eq!(lin.median(), problem.median_residual(&xa, &approach));
    let huber = SolverOptions {
        min_relative_decrease: 1e-3,
        ..approach
    };
    let (on, _, _) = problem.solve_motion(&xa, Some(lin), &huber, Motion::Free);
    let (fresh, _, _) = problem.solve_motion(&xa, None, &huber, Motion::Free);
    assert_eq!(on, fresh);
}

#[test]
fn springs_alone_relax_a_stretched_mesh() {
    let rest = grid(6, 6, |s, t| Point3::new(s, t, 0.0));
    let stretched: Vec<Point3<f64>> = rest
        .positions
        .iter()
        .map(|p| Point3::new(p.x * 1.3, p.y * 1.25, 0.0))
        .collect();
    let edges = Arc::new(EdgeSet::new(&rest));
    let reg = Regularisation {
        membrane: 0.0,
        bending: 0.0,
        ..Regularisation::default()
    };
    let regularisers = regularise::build(&rest, &edges, &reg);
    let problem = Problem {
        triangles: &rest.triangles,
        patches: &[],
        pixels: &[],
        by_triangle: &[],
        targets: vec![],
        projections: vec![],
        pattern: &edges.edges,
        regularisers: &regularisers,
        cancel: None,
        gpu: None,
        moving_source: None,
        gauge_floor: 0.0,
        lag: None,
        rims: None,
    };
    let opts = SolverOptions {
        max_iterations: 60,
        min_relative_decrease: 1e-6,
        ..SolverOptions::default()
    };
    let strain = |x: &[Point3<f64>]| {
        edges
            .edges
            .iter()
            .zip(&edges.rest)
            .map(|([a, b], r)| ((x[*b as usize] - x[*a as usize]).norm() / r - 1.0).abs())
            .fold(0.0, f64::max)
    };
    assert!(strain(&stretched) > 0.25);
    let (x, summary) = problem.solve(&stretched, &opts);
    assert!(
        summary.final_cost < 1e-3 * summary.initial_cost,
        "{summary:?}"
    );
    assert!(
        strain(&x) < 0.05,
        "largest strain after relaxing: {}",
        strain(&x)
    );
}

#[test]
fn moving_camera_is_handled() {
    // The plane moves and so does the first camera; each frame must use that frame's pose.
    let k = Matrix3::new(300.0, 0.0, 79.5, 0.0, 300.0, 59.5, 0.0, 0.0, 1.0);
    let eye0 = |f: u32| Point3::new(-0.15 + 0.03 * f as f64, -1.5 + 0.02 * f as f64, 0.2);
    let eye1 = Point3::new(0.15, -1.5, 0.25);
    let pose = |e: &Point3<f64>| look_at(e, &Point3::origin(), &Vector3::z());
    let frames = 4u32;
    let cam0 = Camera::moving(
        "cam0",
        160,
        120,
        0,
        (0..=frames)
            .map(|f| {
                let (r, t) = pose(&eye0(f));
                Projection::from_krt(&k, &r, &t).unwrap()
            })
            .collect(),
    );
    let (r1, t1) = pose(&eye1);
    let cam1 = Camera::fixed(
        "cam1",
        160,
        120,
        Projection::from_krt(&k, &r1, &t1).unwrap(),
    );
    let motion = Vector3::new(0.004, 0.0, 0.003);
    let images = |f: u32| {
        let plane = plane_at(motion * f as f64);
        let (r0, t0) = pose(&eye0(f));
        vec![
            render(&plane, &k, &r0, &t0, 160, 120),
            render(&plane, &k, &r1, &t1, 160, 120),
        ]
    };
    let mesh = mesh_of(&plane_at(Vector3::zeros()));
    let mut tr = Tracker::new(
        &mesh,
        vec![cam0, cam1],
        0,
        &images(0),
        TrackOptions::default(),
    )
    .unwrap();
    for f in 1..=frames {
        tr.step(f, &images(f)).unwrap();
    }
    let truth = mesh_of(&plane_at(motion * frames as f64)).positions;
    let err = rms_distance(tr.positions(), &truth);
    assert!(
        err < 1.5e-3,
        "rms {err} m after {frames} frames with a moving camera"
    );
}

#[test]
fn a_hidden_triangle_contributes_no_pixels() {
    // Two parallel squares, the front one hiding the back one's centre from camera 0.
    let k = Matrix3::new(300.0, 0.0, 79.5, 0.0, 300.0, 59.5, 0.0, 0.0, 1.0);
    let cam = Projection::from_krt(&k, &Matrix3::identity(), &Vector3::zeros()).unwrap();
    let quad = |z: f64, s: f64| {
        vec![
            Point3::new(-s, -s, z),
            Point3::new(s, -s, z),
            Point3::new(s, s, z),
            Point3::new(-s, s, z),
        ]
    };
    let mut positions = quad(2.0, 0.3); // back
    positions.extend(quad(1.0, 0.2)); // front, covering the back one entirely in this view
    let triangles = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
    let img = RgbImage::from_fn(160, 120, |x, y| texture(x as f64 / 160.0, y as f64 / 120.0));
    let popts = PatchOptions {
        margin: 1,
        min_cos: 0.1,
        two_sided: true,
        checkerboard: false,
        stride: 1,
    };
    let mut set = PatchSet::default();
    set.add_camera(&positions, &triangles, &cam, &img, 0, 1.0, &popts, None);
    let tris: Vec<u32> = set.patches.iter().map(|p| p.triangle).collect();
    assert!(
        tris.contains(&2) && tris.contains(&3),
        "front triangles have pixels"
    );
    assert!(
        !tris.contains(&0) && !tris.contains(&1),
        "hidden triangles have none: {tris:?}"
    );
    // Seen from the side where nothing hides it, the back square does contribute.
    let mut set = PatchSet::default();
    set.add_camera(
        &positions[..4],
        &triangles[..2],
        &cam,
        &img,
        0,
        1.0,
        &popts,
        None,
    );
    assert_eq!(set.patches.len(), 2);
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let rig = rig();
    let motion = Vector3::new(0.005, -0.003, 0.004);
    let plane0 = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane0);
    // A rod in one camera, so that the templates' cross-camera check drops pixels too.
    let frames: Vec<Vec<RgbImage>> = (0..3)
        .map(|f| {
            let mut im = rig.images(&plane_at(motion * f as f64));
            paint_rod(&mut im[0], 70, 86);
            im
        })
        .collect();
    // Two levels: the full-resolution templates are built on another thread while the coarser
    // level is solved (with three threads; in turn with one).
    let opts = TrackOptions {
        levels: 2,
        ..TrackOptions::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut tr = Tracker::new(&mesh, rig.cameras(), 0, &frames[0], opts).unwrap();
            for (f, images) in frames.iter().enumerate().skip(1) {
                tr.step(f as u32, images).unwrap();
            }
            tr.positions().to_vec()
        })
    };
    let one = run(1);
    let three = run(3);
    assert!(
        one.iter().zip(&three).all(|(a, b)| a == b),
        "bitwise identical results"
    );
}

/// Paints a static rod (a pale band with a shaded edge, columns `x0..x1`) over an image.
fn paint_rod(img: &mut RgbImage, x0: usize, x1: usize) {
    for y in 0..img.height() {
        for x in x0..x1 {
            let f = (x - x0) as f32 / (x1 - x0) as f32;
            let shade = 0.75 + 0.2 * (f * std::f32::consts::PI).sin();
            img.set(x, y, [0.95 * shade, 0.8 * shade, 0.75 * shade]);
        }
    }
}

/// The surface points (through `mesh`) of camera `source`'s template pixels in `set`.
fn source_points<'a>(
    set: &'a PatchSet,
    mesh: &'a Mesh,
    source: u16,
) -> impl Iterator<Item = Point3<f64>> + 'a {
    set.patches
        .iter()
        .filter(move |p| p.source == source)
        .flat_map(move |p| {
            let x = mesh.triangles[p.triangle as usize].map(|v| mesh.positions[v as usize]);
            set.pixels[p.start as usize..p.end as usize]
                .iter()
                .map(move |px| {
                    let l = px.lambda;
                    Point3::from(
                        x[0].coords * l[0] as f64
                            + x[1].coords * l[1] as f64
                            + x[2].coords * l[2] as f64,
                    )
                })
        })
}

/// Camera 0's template pixels in `set` that `proj` (camera 0's) puts under a rod painted over
/// columns 70..86 of its image, and those clear of it (beyond four columns either side).
fn under_and_clear_of_rod(set: &PatchSet, mesh: &Mesh, proj: &Projection) -> (usize, usize) {
    let (mut under, mut clear) = (0usize, 0usize);
    for pt in source_points(set, mesh, 0) {
        let u = proj.project(&pt).unwrap().x;
        if (70.0..86.0).contains(&u) {
            under += 1;
        } else if !(66.0..90.0).contains(&u) {
            clear += 1;
        }
    }
    (under, clear)
}

/// The plane moving 1 px per frame for 5 frames behind a static rod in camera 0: the RMS error
/// per frame.
fn track_behind_rod(opts: TrackOptions) -> Vec<f64> {
    let rig = rig();
    let motion = Vector3::new(0.004, -0.002, 0.003);
    let images = |plane: &Plane| {
        let mut im = rig.images(plane);
        paint_rod(&mut im[0], 70, 86);
        im
    };
    track_plane(&rig, opts, motion, 5, mesh_of, images)
}

#[test]
fn a_static_occluder_does_not_hold_the_surface_back() {
    // A rod stands still in front of the moving plane (1 px per frame) in one camera, covering
    // an eighth of it: its pixels match best if the surface does not move. Without the rod both
    // losses track to 0.2 mm. With it, Huber alone lets the rod hold the mesh back more every
    // frame (3.4 → 7.1 mm over 5 frames); the Tukey refinement rejects the rod's pixels once
    // they are misaligned by more than its tolerance, so the error stays under a pixel (5 mm)
    // instead of growing. (Within the tolerance, 1 px, the rod's edges still pull: a motion of
    // a pixel cannot tell a static edge from a slow one.)
    let run = |loss: Loss| {
        let mut opts = TrackOptions {
            // The rod is left in the templates: this is the loss's part alone (the test below
            // checks the templates' part).
            consensus: 0.0,
            ..TrackOptions::default()
        };
        opts.solver.loss = loss;
        track_behind_rod(opts)
    };
    let (huber, tukey) = (run(Loss::Huber), run(Loss::Tukey));
    eprintln!("rms error per frame (m): huber {huber:?}, tukey {tukey:?}");
    let worst = |e: &[f64]| e.iter().cloned().fold(0.0, f64::max);
    assert!(worst(&tukey) < 4.5e-3, "tukey: {tukey:?}");
    assert!(
        tukey[4] < 0.6 * huber[4],
        "huber {huber:?}, tukey {tukey:?}"
    );
}

#[test]
fn a_sliver_triangle_does_not_stall_the_tracker() {
    // One triangle of the plane's grid split in three around a point 1e-7 m off the middle of
    // an edge (a sliver of height 1e-7 on a 7.5 cm edge, as an artist's mesh may hold): the
    // motion is tracked as well as without it, and no frame stalls.
    let rig = rig();
    let motion = Vector3::new(0.006, -0.004, 0.005);
    let [a, b, c] = mesh_of(&plane_at(Vector3::zeros())).triangles[40];
    let with_sliver = |m: &Mesh| {
        let (pa, pb, pc) = (
            m.positions[a as usize],
            m.positions[b as usize],
            m.positions[c as usize],
        );
        let mid = Point3::from((pa.coords + pb.coords) * 0.5);
        let towards_c = (pc - mid).normalize();
        let mut positions = m.positions.clone();
        positions.push(mid + towards_c * 1e-7);
        let p = (positions.len() - 1) as u32;
        let mut triangles = m.triangles.clone();
        triangles[40] = [a, b, p];
        triangles.push([a, p, c]);
        triangles.push([p, b, c]);
        Mesh::new(positions, triangles)
    };
    let errors = track_plane(
        &rig,
        TrackOptions::default(),
        motion,
        4,
        |p| with_sliver(&mesh_of(p)),
        |p| rig.images(p),
    );
    for (f, err) in (1..).zip(errors) {
        assert!(err < 1.0e-3, "frame {f}: rms {err}");
    }
}

/// The test plane as `align` sees it: every camera's pixels of it, taken with the mesh at `x0`,
/// to be compared in the other cameras of the same frame, and what a [`Problem`] over them
/// borrows.
struct CrossPlane {
    plane: Plane,
    mesh: Mesh,
    pyramids: Vec<Pyramid>,
    projections: Vec<Projection>,
    x0: Vec<Point3<f64>>,
    set: PatchSet,
    by_triangle: Vec<(u32, std::ops::Range<usize>)>,
    edges: EdgeSet,
}

impl CrossPlane {
    /// `x0` is the plane's 4×4 grid changed by `displace`.
    fn new(displace: impl Fn(&mut [Point3<f64>])) -> Self {
        let rig = rig();
        let plane = plane_at(Vector3::zeros());
        let mesh = grid(4, 4, |s, t| plane.at(s, t));
        let pyramids: Vec<Pyramid> = rig
            .images(&plane)
            .iter()
            .map(|i| Pyramid::new(i, 1, 1.0))
            .collect();
        let projections: Vec<Projection> = rig.cameras().iter().map(|c| c.at(0).clone()).collect();
        let popts = PatchOptions {
            margin: 1,
            min_cos: 0.1,
            two_sided: true,
            checkerboard: false,
            stride: 1,
        };
        let mut x0 = mesh.positions.clone();
        displace(&mut x0);
        let targets: Vec<&RgbImage> = pyramids.iter().map(|p| &p.levels[0]).collect();
        let mut set = crate::tracker::align::cross_patches(
            &x0,
            &mesh.triangles,
            &projections,
            &targets,
            &popts,
            0,
        );
        assert!(set.patches.iter().all(|p| p.source != p.camera));
        let by_triangle = set.by_triangle();
        let edges = EdgeSet::new(&mesh);
        CrossPlane {
            plane,
            mesh,
            pyramids,
            projections,
            x0,
            set,
            by_triangle,
            edges,
        }
    }

    /// `x0` moved off in three vertices: where the gradient tests evaluate.
    fn moved(&self) -> Vec<Point3<f64>> {
        let mut x = self.x0.clone();
        x[5].x += 0.01;
        x[6].z -= 0.008;
        x[9].y += 0.005;
        x
    }

    /// Options under which the cost is a smooth least-squares sum (no robust cap, no gains):
    /// what finite differences can check.
    fn smooth_options() -> SolverOptions {
        SolverOptions {
            huber: 1e3,
            gain: GainModel::Off,
            ..SolverOptions::default()
        }
    }

    /// `align`'s problem (the source rays sliding as the mesh moves), or with `glued` the
    /// tracker's derivative over the same pixels (as if they were glued to the surface).
    fn problem(&self, glued: bool) -> Problem<'_> {
        Problem {
            moving_source: (!glued).then_some(&self.x0[..]),
            ..Problem::photometric(
                &self.mesh.triangles,
                &self.set,
                &self.by_triangle,
                self.pyramids.iter().map(|p| &p.levels[0]).collect(),
                self.projections.clone(),
                &self.edges.edges,
            )
        }
    }
}

#[test]
fn moving_source_gradient_matches_finite_differences_of_the_cost() {
    // `align`'s warp between two cameras of one frame: the pixels are taken from each camera
    // with the mesh at `x0`, and as the mesh moves, the surface point each pixel sees slides
    // along its own camera's ray. The assembled gradient must be that cost's exact derivative.
    let cross = CrossPlane::new(|x| x[5].z += 0.01);
    let problem = cross.problem(false);
    let (opts, x) = (CrossPlane::smooth_options(), cross.moved());
    let checked = check_gradient(&problem, &x, &opts, &[5, 6, 9, 10], "moving source");
    assert_eq!(checked, 12);
    let (_, _, b) = problem.linearize(&x, &opts);
    // Without the source's motion (the tracker's derivative, as if the pixels were glued to
    // the surface) the gradient is a different one: the test can tell them apart.
    let (_, _, b_fixed) = cross.problem(true).linearize(&x, &opts);
    let diff: f64 = b.iter().zip(&b_fixed).map(|(p, q)| (p - q).norm()).sum();
    let size: f64 = b.iter().map(|p| p.norm()).sum();
    assert!(diff > 0.1 * size, "{diff} vs {size}");
}

#[test]
fn moving_source_with_cameras_out_of_sync_matches_finite_differences_of_the_cost() {
    // The tracker's comparisons between cameras (`--stereo`) in a rig whose second camera
    // records 0.3 frame late (or the first 0.2 early): each camera sees the triangle at its own
    // instant, moved along the velocity from `previous`, so both ends of the warp move with
    // the unknowns at their own rates. The assembled gradient must be that cost's derivative.
    let cross = CrossPlane::new(|x| x[5].z += 0.01);
    let previous: Vec<Point3<f64>> = cross
        .x0
        .iter()
        .map(|p| p - Vector3::new(0.004, -0.002, 0.003))
        .collect();
    let (opts, x) = (CrossPlane::smooth_options(), cross.moved());
    let in_sync = cross.problem(false).cost(&x, &opts);
    for offsets in [[0.0, 0.3], [-0.2, 0.3]] {
        let lags = per_vertex(&offsets, previous.len());
        let lagged = Problem {
            lag: Some(Lag {
                offsets: &lags,
                previous: &previous,
                gap: 1.0,
            }),
            ..cross.problem(false)
        };
        assert!(lagged.cost(&x, &opts) != in_sync, "the lag changed nothing");
        let n = check_gradient(
            &lagged,
            &x,
            &opts,
            &[5, 6, 9, 10],
            &format!("moving source, cameras {offsets:?} frames late"),
        );
        assert_eq!(n, 12);
    }
}

/// `align`'s normal equations are the curvature of its cost: at the true surface, where the
/// cameras agree, Gauss–Newton is exact up to the residuals left by resampling, so along any
/// direction the cost's second derivative (finite differences of `Problem::cost`, the source
/// rays sliding and the gains re-fitted) is `2·δᵀAδ`. Without the source's motion in the
/// derivative, the matrix is another one, which the test tells apart.
#[test]
fn moving_source_normal_equations_are_the_curvature_of_the_cost() {
    let cross = CrossPlane::new(|_| {});
    let (problem, fixed) = (cross.problem(false), cross.problem(true));
    let (x, plane) = (cross.x0.clone(), &cross.plane);
    let n = x.len();
    let dirs = plane.directions(n);
    for gain in [GainModel::Off, GainModel::Linear] {
        let opts = SolverOptions {
            huber: 1e3,
            gain,
            ..SolverOptions::default()
        };
        let (_, a, _) = problem.linearize(&x, &opts);
        let (_, a_fixed, _) = fixed.linearize(&x, &opts);
        for (d, dir) in dirs.iter().enumerate() {
            let (model, fd) = curvatures(&problem, &a, &x, dir, &opts);
            let (model_fixed, _) = curvatures(&fixed, &a_fixed, &x, dir, &opts);
            // (A slide within the plane leaves every source ray on the same surface: no
            // curvature at all, which the derivative without the source's motion misses.)
            assert!(
                (fd - model).abs() <= 0.02 * fd.abs() + 1e-6,
                "{gain:?}, direction {d}: cost's curvature {fd:.6e}, model's {model:.6e}"
            );
            assert!(
                (fd - model_fixed).abs() > 0.15 * fd.abs().max(model_fixed.abs()),
                "{gain:?}, direction {d}: the glued pixels' matrix agrees ({model_fixed:.6e})"
            );
        }
    }
}

/// The brightness gains are re-fitted at every evaluation, so the cost the solver lowers is the
/// cost *profiled* over them, and its Gauss–Newton matrix is the Schur complement of the joint
/// one (variable projection). At a zero-residual point Gauss–Newton is exact: along any
/// direction, the profiled cost's second derivative (finite differences of `Problem::cost`, which
/// re-fits the gains) is `2·δᵀAδ`. The matrix without the complement overrates it along every
/// motion a gain change can mimic, which made the free stage creep.
#[test]
fn normal_equations_are_the_curvature_of_the_cost_with_its_gains_refitted() {
    let rig = rig();
    let plane = plane_at(Vector3::zeros());
    let mesh = grid(4, 4, |s, t| plane.at(s, t));
    let cams = rig.cameras();
    // A faint texture under strong shading across the images (a ramp): moving the mesh along it
    // changes a triangle's mean brightness, which a gain can mimic.
    let src: Vec<Pyramid> = rig
        .images(&plane)
        .iter()
        .map(|i| {
            let w = i.width() as f32;
            let shaded = RgbImage::from_fn(i.width(), i.height(), |x, y| {
                i.get(x, y)
                    .map(|c| (0.5 + 0.1 * (c - 0.5)) * (0.3 + 1.2 * x as f32 / w))
            });
            Pyramid::new(&shaded, 1, 1.0)
        })
        .collect();
    // The next frame: the surface has not moved, the light has dimmed by 15 %: a gain fits it
    // exactly, so the mesh's own positions are a zero-residual point.
    let dst: Vec<Pyramid> = src
        .iter()
        .map(|p| {
            let mut img = p.levels[0].clone();
            img.pixels_mut()
                .iter_mut()
                .for_each(|px| *px = px.map(|c| 0.85 * c));
            Pyramid {
                levels: vec![img],
                fine: Vec::new(),
            }
        })
        .collect();
    let mut set = frame0_patches(&mesh, &cams, &src);
    let by_triangle = set.by_triangle();
    let edges = EdgeSet::new(&mesh);
    let problem = frame1_problem(&mesh, &set, &by_triangle, &dst, &cams, &edges.edges, &[]);
    let x = mesh.positions.clone();
    let n = x.len();
    for gain in [GainModel::Constant, GainModel::Linear] {
        let opts = SolverOptions {
            huber: 1e3,
            gain,
            ..SolverOptions::default()
        };
        let (cost, a, _) = problem.linearize(&x, &opts);
        assert!(
            cost < 1e-12,
            "{gain:?}: not a zero-residual point ({cost:e})"
        );
        let dirs = plane.directions(n);
        for (d, dir) in dirs.iter().enumerate() {
            let (model, fd) = curvatures(&problem, &a, &x, dir, &opts);
            assert!(
                (fd - model).abs() <= 0.03 * fd.abs(),
                "{gain:?}, direction {d}: cost's curvature {fd:.6e}, model's {model:.6e}"
            );
        }
    }
}

/// A surface turned away from its light darkens by more than half (Lambertian: to 30 % from
/// facing the light to 73° off it). The gains take that up within `gain_range` (4 by default):
/// the moved plane seen under a light dimmed to 30 % fits exactly at its true position, and the
/// solve finds it there. Under the earlier bound (2) the gain is held at 0.5 and what is left
/// is the texture itself, a residual no position explains.
#[test]
fn a_patch_darkened_to_under_half_is_compared_up_to_its_gain() {
    let moved = MovedPlane::new();
    let (mesh, cams) = (&moved.mesh, &moved.cams);
    let truth = grid(4, 4, |s, t| moved.at1.at(s, t)).positions;
    let src = moved.pyramids(&moved.at0, 1.0);
    let mut set = frame0_patches(mesh, cams, &src);
    let by_triangle = set.by_triangle();
    let edges = EdgeSet::new(mesh);
    // The cost at the truth (every pixel kept) and where the solve from the first frame's
    // mesh ends (m from the truth), with the light at `light` and the gains within `range`.
    let solved = |light: f32, range: f64| {
        let dst = moved.pyramids(&moved.at1, light);
        let problem = frame1_problem(mesh, &set, &by_triangle, &dst, cams, &edges.edges, &[]);
        let opts = SolverOptions {
            gain_range: range,
            ..SolverOptions::default()
        };
        let every_pixel = SolverOptions {
            loss: Loss::Huber,
            huber: 1e3,
            ..opts
        };
        let at_truth = problem.cost(&truth, &every_pixel);
        let (x, _) = problem.solve(&mesh.positions, &opts);
        (at_truth, rms_distance(&x, &truth))
    };
    let range = SolverOptions::default().gain_range;
    let (_, err_lit) = solved(1.0, range);
    let (cost_now, err_now) = solved(0.3, range);
    let (cost_old, err_old) = solved(0.3, 2.0);
    eprintln!(
        "light at 30 %: cost at the truth {cost_now:.3e} (bound 2: {cost_old:.3e}); \
         solved {err_now:.2e} m from it (bound 2: {err_old:.2e} m; unchanged light {err_lit:.2e} m)"
    );
    assert!(
        cost_now < 1e-3 * cost_old,
        "{cost_now:e} against {cost_old:e}"
    );
    assert!(
        err_now < 1.2 * err_lit,
        "{err_now} m, unchanged light {err_lit} m"
    );
    assert!(
        err_old > 5.0 * err_now,
        "bound 2: {err_old} m, now {err_now} m"
    );
}

#[test]
fn an_occluder_in_one_camera_is_left_out_of_the_templates() {
    // The static rod of the test above, with the templates checked against the other camera
    // (`consensus`): the rod's pixels, which camera 1 contradicts, are left out, and the error
    // stays near what the plane gives without a rod (0.2 mm): 0.7–1.0 mm, against 3.2–4.4 mm
    // with the check off (what remains comes from the rod in the frame being solved, which
    // only the Tukey refinement handles).
    let run = |consensus: f64| {
        let opts = TrackOptions {
            consensus,
            ..TrackOptions::default()
        };
        track_behind_rod(opts)
    };
    let (on, off) = (run(TrackOptions::default().consensus), run(0.0));
    eprintln!("rms error per frame (m): consensus {on:?}, without {off:?}");
    let worst = |e: &[f64]| e.iter().cloned().fold(0.0, f64::max);
    assert!(worst(&on) < 1.5e-3, "consensus: {on:?}");
    assert!(worst(&on) < 0.4 * worst(&off), "on {on:?}, off {off:?}");
}

#[test]
fn asking_the_other_cameras_only_until_every_pixel_agreed_changes_no_verdict() {
    // Four cameras see the plane. A rod covers columns 70..86 of camera 0 (its pixels there
    // are contradicted by every other camera: dropped) and columns 20..40 of camera 1 (camera
    // 0's pixels that fall under it are contradicted by camera 1, which is asked first, and
    // kept on the word of camera 2). Stopping once every pixel of a patch has agreed with some
    // camera must leave the same pixels as asking every camera about every pixel.
    let rig = Rig::new(&[
        Point3::new(-0.15, -1.5, 0.2),
        Point3::new(0.15, -1.5, 0.25),
        Point3::new(-0.05, -1.5, 0.35),
        Point3::new(0.05, -1.5, 0.1),
    ]);
    let plane = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane);
    let cams = rig.cameras();
    let mut im = rig.images(&plane);
    paint_rod(&mut im[0], 70, 86);
    paint_rod(&mut im[1], 20, 40);
    let pyr: Vec<Pyramid> = im.iter().map(|i| Pyramid::new(i, 1, 1.0)).collect();
    let set = frame0_patches(&mesh, &cams, &pyr);
    let projections: Vec<Projection> = cams.iter().map(|c| c.at(0).clone()).collect();
    let images: Vec<&RgbImage> = pyr.iter().map(|p| &p.levels[0]).collect();
    let opts = crate::tracker::consensus::ConsensusOptions {
        k: TrackOptions::default().consensus,
        min: SolverOptions::default().tukey_min,
        px: SolverOptions::default().tukey_px,
    };
    let (mut early, mut all) = (set.clone(), set.clone());
    let args = (
        &mesh.positions,
        &mesh.triangles,
        &projections,
        &images,
        &opts,
    );
    let dropped_early = crate::tracker::consensus::drop_contradicted_ahead(
        &mut early, args.0, args.1, args.2, args.3, args.4, None,
    )
    .0
    .dropped;
    let dropped_all = crate::tracker::consensus::drop_contradicted_asking(
        &mut all, args.0, args.1, args.2, args.3, args.4, true, None,
    )
    .0
    .dropped;
    eprintln!("{dropped_early} of {} pixels dropped", set.pixels.len());
    assert!(dropped_early > 500, "{dropped_early} dropped");
    assert_eq!(dropped_early, dropped_all);
    assert_eq!(early.patches, all.patches);
    assert_eq!(early.pixels, all.pixels);
    // Camera 0's pixels under camera 1's rod: kept, though camera 1 contradicts them.
    let under_rod_1 = |s: &PatchSet| {
        source_points(s, &mesh, 0)
            .filter(|pt| (22.0..38.0).contains(&projections[1].project(pt).unwrap().x))
            .count()
    };
    let (before, after) = (under_rod_1(&set), under_rod_1(&early));
    eprintln!("camera 0's pixels under camera 1's rod: {after} of {before} kept");
    assert!(before > 500 && after as f64 > 0.9 * before as f64);
}

/// A rod painted over columns 70..86 of camera 0's image of the plane, checked against the
/// other cameras of `rig` (camera 1 exposed `exposure_1` times as bright): camera 0's template
/// loses what lies under the rod and keeps the rest; without the rod next to nothing is
/// dropped.
fn assert_the_rod_alone_is_dropped(rig: &Rig, exposure_1: f32) {
    let plane = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane);
    let cams = rig.cameras();
    let projections: Vec<Projection> = cams.iter().map(|c| c.at(0).clone()).collect();
    let opts = crate::tracker::consensus::ConsensusOptions {
        k: TrackOptions::default().consensus,
        min: SolverOptions::default().tukey_min,
        px: SolverOptions::default().tukey_px,
    };
    // Camera 0's template pixels, before and after, by column: under the rod or clear of it;
    // and all pixels, before and after.
    let check = |rod: bool| {
        let mut im = rig.images(&plane);
        for p in im[1].pixels_mut() {
            *p = p.map(|v| v * exposure_1);
        }
        if rod {
            paint_rod(&mut im[0], 70, 86);
        }
        let pyr: Vec<Pyramid> = im.iter().map(|i| Pyramid::new(i, 1, 1.0)).collect();
        let mut set = frame0_patches(&mesh, &cams, &pyr);
        let before = set.clone();
        let images: Vec<&RgbImage> = pyr.iter().map(|p| &p.levels[0]).collect();
        crate::tracker::consensus::drop_contradicted_ahead(
            &mut set,
            &mesh.positions,
            &mesh.triangles,
            &projections,
            &images,
            &opts,
            None,
        );
        let columns = |set: &PatchSet| under_and_clear_of_rod(set, &mesh, &projections[0]);
        (
            columns(&before),
            columns(&set),
            before.pixels.len(),
            set.pixels.len(),
        )
    };
    let ((u0, c0), (u1, c1), _, _) = check(true);
    eprintln!("rod: under it {u1} of {u0} kept, clear of it {c1} of {c0}");
    assert!(u0 > 1000 && u1 * 10 < u0, "under the rod {u1} of {u0} kept");
    assert!(
        c1 as f64 > 0.9 * c0 as f64,
        "clear of the rod {c1} of {c0} kept"
    );
    let (_, _, all0, all1) = check(false);
    eprintln!("no rod: {all1} of {all0} kept");
    assert!(all1 as f64 > 0.99 * all0 as f64, "{all1} of {all0} kept");
}

#[test]
fn with_eight_cameras_an_occluder_in_one_is_still_left_out() {
    // Eight cameras in a row see the plane (the statistics sample every 10th pixel instead of
    // every 4th).
    let rig = Rig::new(
        &(0..8)
            .map(|i| Point3::new(-0.2 + 0.057 * i as f64, -1.5, 0.2 + 0.02 * (i % 3) as f64))
            .collect::<Vec<_>>(),
    );
    assert_the_rod_alone_is_dropped(&rig, 1.0);
}

#[test]
fn the_pixels_an_occluder_covers_are_the_ones_dropped() {
    // Two cameras see the plane: camera 0's template is checked against camera 1 alone, which
    // is exposed darker (same texture, same gains up to 20 % exposure).
    assert_the_rod_alone_is_dropped(&rig(), 0.8);
}

/// The GPU kernels, run on the CPU as C (`gpu::Gpu::emulated`), give the CPU loop's sums to the
/// bit: cost, normal equations, gradient, median residual and per-vertex confidence, for every
/// loss, interpolation and gain model, with cameras that record late, and for `align`'s moving
/// source. (The kernels form every sum in the CPU's order with the CPU's operations; on a GPU
/// only its `log1p` differs, which the test below bounds on tracked meshes.)
#[test]
fn the_gpu_kernels_give_the_cpu_sums() {
    use crate::tracker::gpu::Gpu;
    use crate::tracker::sparse::BlockSparse;
    let gpu = Arc::new(Gpu::emulated());
    let close = |a: f64, b: f64, _scale: f64, what: &str| {
        assert!(a.to_bits() == b.to_bits(), "{what}: CPU {a:e}, GPU {b:e}");
    };
    let compare = |cpu: &Problem, x: &[Point3<f64>], opts: &SolverOptions, label: &str| {
        let uploaded = gpu.upload(cpu).unwrap();
        let mut on_gpu = cpu.clone();
        on_gpu.gpu = Some(&uploaded);
        let (c0, a0, b0): (f64, BlockSparse, Vec<Vector3<f64>>) = cpu.linearize(x, opts);
        let (c1, a1, b1) = on_gpu.linearize(x, opts);
        assert!(c0 > 0.0, "{label}: nothing compared");
        close(c0, c1, c0, &format!("{label}: cost"));
        close(
            cpu.cost(x, opts),
            on_gpu.cost(x, opts),
            c0,
            &format!("{label}: cost alone"),
        );
        let bmax = b0.iter().map(|v| v.amax()).fold(0.0, f64::max);
        assert!(bmax > 0.0, "{label}: no gradient");
        for (p, q) in b0.iter().zip(&b1) {
            for k in 0..3 {
                close(p[k], q[k], bmax, &format!("{label}: gradient"));
            }
        }
        let v: Vec<Vector3<f64>> = (0..x.len())
            .map(|i| Vector3::new((i as f64).sin(), (2.0 * i as f64).cos(), 0.3))
            .collect();
        let (mut y0, mut y1) = (
            vec![Vector3::zeros(); x.len()],
            vec![Vector3::zeros(); x.len()],
        );
        a0.mul(&v, &mut y0);
        a1.mul(&v, &mut y1);
        let ymax = y0.iter().map(|v| v.amax()).fold(0.0, f64::max);
        for (p, q) in y0.iter().zip(&y1) {
            for k in 0..3 {
                close(p[k], q[k], ymax, &format!("{label}: normal equations"));
            }
        }
        assert_eq!(
            cpu.median_residual(x, opts),
            on_gpu.median_residual(x, opts),
            "{label}: median residual"
        );
        let (k0, k1) = (
            cpu.vertex_confidence(x, opts),
            on_gpu.vertex_confidence(x, opts),
        );
        let imax = k0.iter().map(|k| k.information).fold(0.0, f64::max);
        for (p, q) in k0.iter().zip(&k1) {
            close(p.information, q.information, imax, label);
            assert_eq!(p.pixels, q.pixels, "{label}: pixels");
        }
        assert!(uploaded.failure().is_none());
    };

    let moved = MovedPlane::new();
    let (mesh, cams) = (&moved.mesh, &moved.cams);
    let (src, dst) = (
        moved.pyramids(&moved.at0, 1.0),
        moved.pyramids(&moved.at1, 1.0),
    );
    let mut set = frame0_patches(mesh, cams, &src);
    let by_triangle = set.by_triangle();
    let edges = Arc::new(EdgeSet::new(mesh));
    let problem = frame1_problem(mesh, &set, &by_triangle, &dst, cams, &edges.edges, &[]);
    let mut x = mesh.positions.clone();
    x[5].x += 0.02;
    x[6].z -= 0.01;
    let variants = [
        SolverOptions::default(),
        SolverOptions {
            loss: Loss::Huber,
            huber: 0.05,
            interpolation: Interpolation::Linear,
            gain: GainModel::Constant,
            ..SolverOptions::default()
        },
        SolverOptions {
            huber: 0.2,
            patch_scale: 0.0,
            gain: GainModel::Off,
            ..SolverOptions::default()
        },
        SolverOptions {
            huber: 0.02,
            tukey_px: 0.2,
            gain: GainModel::Linear,
            interpolation: Interpolation::Linear,
            ..SolverOptions::default()
        },
    ];
    for (i, opts) in variants.iter().enumerate() {
        compare(&problem, &x, opts, &format!("plane, options {i}"));
    }
    // Cameras that record late or early.
    let previous: Vec<Point3<f64>> = mesh
        .positions
        .iter()
        .map(|p| p - Vector3::new(0.003, 0.001, 0.0))
        .collect();
    let offsets = [0.4, -0.25];
    let lags = per_vertex(&offsets, previous.len());
    let lagged = Problem {
        lag: Some(Lag {
            offsets: &lags,
            previous: &previous,
            gap: 1.0,
        }),
        ..problem.clone()
    };
    compare(&lagged, &x, &SolverOptions::default(), "late cameras");
    // `align`'s moving source, and the same pixels glued to the surface.
    let cross = CrossPlane::new(|x| x[5].z += 0.01);
    let mut xc = cross.x0.clone();
    xc[5].x += 0.01;
    xc[9].y += 0.005;
    for gain in [GainModel::Off, GainModel::Constant, GainModel::Linear] {
        let opts = SolverOptions {
            gain,
            ..SolverOptions::default()
        };
        compare(
            &cross.problem(false),
            &xc,
            &opts,
            &format!("moving source, {gain:?}"),
        );
        compare(
            &cross.problem(true),
            &xc,
            &opts,
            &format!("glued source, {gain:?}"),
        );
        // The comparisons between cameras of a rig out of sync: each end at its own instant.
        let prev_c: Vec<Point3<f64>> = cross
            .x0
            .iter()
            .map(|p| p - Vector3::new(0.004, -0.002, 0.003))
            .collect();
        let lags_c = per_vertex(&offsets, prev_c.len());
        let lagged_cross = Problem {
            lag: Some(Lag {
                offsets: &lags_c,
                previous: &prev_c,
                gap: 1.0,
            }),
            ..cross.problem(false)
        };
        compare(
            &lagged_cross,
            &xc,
            &opts,
            &format!("moving source, late cameras, {gain:?}"),
        );
    }
}

/// A tracker whose evaluations and linear solves run through the GPU path (here its kernels
/// emulated on the CPU) tracks the CPU's meshes to the bit, through every level, the rigid stage
/// and the Tukey refine.
#[test]
fn a_tracker_on_the_gpu_path_tracks_what_the_cpu_tracks() {
    use crate::tracker::gpu::Gpu;
    let rig = rig();
    let motion = Vector3::new(0.005, -0.003, 0.004);
    let plane0 = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane0);
    let frames: Vec<Vec<RgbImage>> = (0..3)
        .map(|f| rig.images(&plane_at(motion * f as f64)))
        .collect();
    let run = |gpu: Option<Arc<Gpu>>| {
        let mut tr =
            Tracker::new(&mesh, rig.cameras(), 0, &frames[0], TrackOptions::default()).unwrap();
        tr.set_gpu(gpu);
        for (f, images) in frames.iter().enumerate().skip(1) {
            tr.step(f as u32, images).unwrap();
        }
        tr.positions().to_vec()
    };
    let cpu = run(None);
    let device = Arc::new(Gpu::emulated());
    let gpu = run(Some(Arc::clone(&device)));
    // The free stages' linear solves ran there too (the emulated GPU takes any size).
    assert!(device.stats().linear_solves > 0, "{:?}", device.stats());
    let moved = rms_distance(&cpu, &mesh.positions);
    let diff = rms_distance(&cpu, &gpu);
    assert!(moved > 0.005, "the plane moved {moved}");
    assert!(
        cpu.iter().zip(&gpu).all(|(a, b)| a == b),
        "GPU path off the CPU by {diff} m"
    );
}

/// On a machine with an NVIDIA GPU: the default cloth (640×480, two cameras, 1 681 vertices)
/// tracked with the per-pixel work on the GPU stays within 1e-5 of the mesh's size of the CPU's
/// track in every frame (the bound; the sums are ordered differently there). Without
/// a GPU (CI) it is skipped and says why.
#[test]
fn the_gpu_tracks_the_default_cloth_as_the_cpu_does() {
    use crate::synth::{SynthOptions, Synthetic};
    use crate::tracker::gpu::Gpu;
    let gpu = match Gpu::open() {
        Ok(g) => Arc::new(g),
        Err(e) => {
            eprintln!("SKIPPED (no GPU here): {e}");
            return;
        }
    };
    eprintln!("GPU: {}", gpu.name());
    let frames = 8;
    let syn = Synthetic::generate(&SynthOptions {
        frames,
        ..SynthOptions::default()
    })
    .unwrap();
    let images: Vec<Vec<RgbImage>> = (0..frames)
        .map(|f| (0..syn.cameras.len()).map(|c| syn.render(c, f)).collect())
        .collect();
    let size = syn.mesh.bbox_diagonal();
    let start = |gpu: Option<Arc<Gpu>>| {
        let mut t = Tracker::new(
            &syn.mesh,
            syn.cameras.clone(),
            0,
            &images[0],
            TrackOptions::default(),
        )
        .unwrap();
        t.set_gpu(gpu);
        t
    };
    let (mut cpu, mut on_gpu) = (start(None), start(Some(gpu)));
    let mut worst = 0.0f64;
    for f in 1..frames {
        let a = cpu.step(f, &images[f as usize]).unwrap();
        let b = on_gpu.step(f, &images[f as usize]).unwrap();
        let diff = cpu
            .positions()
            .iter()
            .zip(on_gpu.positions())
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max)
            / size;
        eprintln!(
            "frame {f}: largest vertex difference {diff:.2e} of the size; CPU {} its, GPU {} its",
            a.iterations, b.iterations
        );
        worst = worst.max(diff);
        assert!(
            diff <= 1e-5,
            "frame {f}: GPU off the CPU by {diff:e} of the size"
        );
    }
    eprintln!("worst frame: {worst:.2e} of the size");
}

/// `preset` at rest in the first frame and turned 10° per frame from then on, in front of its
/// four cameras (90° apart) at 320×240, tracked over `frames` frames with `opts`, each frame's
/// report handed to `check`: the last frame's RMS vertex error, % of the mesh's size.
fn turning_final_error(
    preset: crate::synth::Preset,
    frames: u32,
    opts: TrackOptions,
    check: &mut dyn FnMut(u32, &FrameReport),
) -> f64 {
    use crate::synth::{SynthOptions, Synthetic};
    let syn = Synthetic::generate(&SynthOptions {
        preset,
        width: 320,
        height: 240,
        frames,
        turn: 10.0,
        supersample: 2,
        ..SynthOptions::default()
    })
    .unwrap();
    let images = |f: u32| -> Vec<RgbImage> { (0..4).map(|c| syn.render(c, f)).collect() };
    let mut t = Tracker::new(&syn.mesh, syn.cameras.clone(), 0, &images(0), opts).unwrap();
    for f in 1..frames {
        check(f, &t.step(f, &images(f)).unwrap());
    }
    let truth = &syn.truth[frames as usize - 1];
    100.0 * rms_distance(t.positions(), truth) / syn.mesh.bbox_diagonal()
}

/// [`turning_final_error`] of the blob, every frame neither stalled nor suspect.
fn turning_blob_final_error(frames: u32, opts: TrackOptions) -> f64 {
    turning_final_error(crate::synth::Preset::Blob, frames, opts, &mut |f, r| {
        assert!(!r.stalled && !r.suspect, "frame {f}: {r:?}")
    })
}

/// [`turning_blob_final_error`] over ten frames with and without the first frame's view lent
/// to the cameras that see a triangle now but did not then.
fn turning_blob_with_lent_anchor(lent_anchor: f64) -> f64 {
    turning_blob_final_error(
        10,
        // The cameras compared with each other (`stereo`, on by default) hold the sides too
        // (without and with the lent view: 0.346 and 0.305 %): off here, the lent view alone.
        TrackOptions {
            lent_anchor,
            stereo: 0.0,
            ..TrackOptions::default()
        },
    )
}

#[test]
fn sides_turned_into_view_are_held_by_the_first_frames_view_from_another_camera() {
    // After 90° each camera sees what its neighbour saw at the first frame. Without that view
    // the sides coming into a camera's view are compared with the previous frame only and
    // drift with the turn.
    let (without, lent) = (
        turning_blob_with_lent_anchor(0.0),
        turning_blob_with_lent_anchor(1.0),
    );
    eprintln!("turning blob, final error: without {without:.3} %, lent {lent:.3} %");
    assert!(
        lent < 0.75 * without,
        "without {without:.3} %, lent {lent:.3} %"
    );
}

#[test]
fn an_open_surface_turned_half_round_reads_no_change_of_colour_balance_and_names_no_camera() {
    // The irregular preset has a hole, so no facing test leaves its back out: once the object
    // had turned far enough, the first frame's pixels of a side now at the back were read
    // through the front and taken for a change of white balance (one camera 70 % more blue
    // by frame 14 here, after which every comparison in it was made in wrong colours). Nothing
    // in this footage changes colour.
    //
    // Nor is any camera knocked: the cameras' own contradicted shares must not name one. A
    // camera that sees a triangle nearly edge-on, or from its other side (the hole shows the
    // inside), contradicted much of what another sees head-on, and as the object turned such
    // views came and went: one camera was named at frames 8–12 here before those checks
    // were left out of the share (2026-12-06).
    let mut reports = Vec::new();
    let e = turning_final_error(
        crate::synth::Preset::Irregular,
        16,
        TrackOptions::default(),
        &mut |f, r| {
            for (c, b) in r.colour_balance.iter().enumerate() {
                assert!(
                    b.iter().all(|v| (v - 1.0).abs() < 0.01),
                    "frame {f}, camera {c}: colour balance {b:?} read from footage whose colours never change"
                );
            }
            reports.push((f, r.clone()));
        },
    );
    eprintln!("irregular mesh turned 150°: final error {e:.3} %");
    assert!(e < 0.6, "final error {e:.3} %");
    let named: Vec<_> =
        crate::tracker::health::check_reports(0, reports.iter().map(|(f, r)| (*f, r)))
            .into_iter()
            .filter(|c| {
                c.concerns
                    .iter()
                    .any(|k| matches!(k, crate::tracker::Concern::Disagree { .. }))
            })
            .collect();
    assert!(named.is_empty(), "no camera moved: {named:?}");
}

/// [`turning_blob_final_error`] after the first frame of the turn, with the membrane's
/// reference turned with the mesh or not.
fn blob_starting_to_turn_error(membrane_turns: bool) -> f64 {
    turning_blob_final_error(
        2,
        TrackOptions {
            regularisation: Regularisation {
                membrane_turns,
                ..Regularisation::default()
            },
            ..TrackOptions::default()
        },
    )
}

#[test]
fn an_object_that_starts_to_turn_is_not_held_back_by_the_membrane() {
    // With no velocity known yet the membrane's reference is the previous shape: held in its
    // orientation it resists the turn (a hand-held object starting to move, or speeding up);
    // turned with the mesh it resists only a change of shape.
    let (fixed, turning) = (
        blob_starting_to_turn_error(false),
        blob_starting_to_turn_error(true),
    );
    eprintln!("blob starting to turn, frame 1: fixed {fixed:.4} %, turning {turning:.4} %");
    assert!(
        turning < 0.75 * fixed && turning < 0.1,
        "fixed {fixed:.4} %, turning {turning:.4} %"
    );
}

/// What stands 25 cm in front of the sheet in `sheet_behind_a_strip`.
#[derive(Clone, Copy)]
enum Strip {
    /// A strip of the same mesh sweeping across it (an arm across a body), tracked with it;
    /// the sheet drifts slowly.
    Sweeping,
    /// A rod `width` wide (m) that is not part of the mesh and stands still, while the sheet
    /// starts from rest and speeds up across the view; `third_camera` adds a camera below the
    /// two.
    Still { width: f64, third_camera: bool },
}

/// A sheet behind a strip (`Strip`), rendered by the project's renderer into two cameras (or
/// three) at 320×240 and tracked with `opts`: the sheet's RMS error after `frames` frames (m),
/// and the hidden pixels each frame reported.
fn sheet_behind_a_strip(
    strip_is: Strip,
    opts: TrackOptions,
    frames: u32,
) -> (f64, Vec<FrameReport>) {
    use crate::synth::{render, RenderOptions, Surface, Texture};
    let (w, h) = (320usize, 240usize);
    let k = Matrix3::new(600.0, 0.0, 159.5, 0.0, 600.0, 119.5, 0.0, 0.0, 1.0);
    let mut eyes = vec![Point3::new(-0.2, -1.6, 0.1), Point3::new(0.2, -1.6, 0.15)];
    if let Strip::Still {
        third_camera: true, ..
    } = strip_is
    {
        eyes.push(Point3::new(0.0, -1.6, -0.15));
    }
    let cameras: Vec<Camera> = eyes
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let (r, t) = look_at(e, &Point3::new(0.0, 0.0, 0.0), &Vector3::z());
            Camera::fixed(
                format!("cam{i}"),
                w as u32,
                h as u32,
                Projection::from_krt(&k, &r, &t).unwrap(),
            )
        })
        .collect();
    // The sheet (9×9 vertices, 60×50 cm) at y = 0.1, the strip (3×9, 10×60 cm, or the rod's
    // width) at y = −0.15, starting left of the middle: one mesh of two pieces.
    let sheet = grid(9, 9, |s, t| {
        Point3::new(-0.3 + 0.6 * s, 0.1, -0.25 + 0.5 * t)
    });
    let wide = match strip_is {
        Strip::Sweeping => 0.1,
        Strip::Still { width, .. } => width,
    };
    let strip = grid(3, 9, |s, t| {
        Point3::new(-0.2 + wide * s, -0.15, -0.3 + 0.6 * t)
    });
    let n_sheet = sheet.positions.len();
    let mut positions = sheet.positions.clone();
    positions.extend(&strip.positions);
    let mut triangles = sheet.triangles.clone();
    triangles.extend(
        strip
            .triangles
            .iter()
            .map(|t| t.map(|v| v + n_sheet as u32)),
    );
    let scene = Mesh::new(positions.clone(), triangles);
    let at = |f: u32| -> Vec<Point3<f64>> {
        let f = f as f64;
        positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let d = match (strip_is, i < n_sheet) {
                    // The sheet drifts 2 mm per frame (under a pixel), the strip sweeps 1.5 cm
                    // (about 5 px).
                    (Strip::Sweeping, true) => Vector3::new(-0.0015, 0.0, 0.0013) * f,
                    (Strip::Sweeping, false) => Vector3::new(0.015, 0.0, 0.0) * f,
                    // From rest, 1.6 mm more each frame (0.6 px, 3 px by frame 6).
                    (Strip::Still { .. }, true) => Vector3::new(0.0008, 0.0, 0.0002) * f * f,
                    (Strip::Still { .. }, false) => Vector3::zeros(),
                };
                p + d
            })
            .collect()
    };
    let texture = Texture::new(3, 0.006);
    let material = |m: &[f64; 3]| texture.eval(m);
    let rest: Vec<[f64; 3]> = positions.iter().map(|p| [p.x, p.y, p.z]).collect();
    let images = |f: u32| -> Vec<RgbImage> {
        let moved = Mesh::new(at(f), scene.triangles.clone());
        cameras
            .iter()
            .map(|c| {
                render(
                    &moved,
                    &rest,
                    &Surface::Material(&material),
                    c.at(f),
                    w,
                    h,
                    &RenderOptions::default(),
                )
                .unwrap()
            })
            .collect()
    };
    let tracked = match strip_is {
        Strip::Sweeping => scene.clone(),
        Strip::Still { .. } => Mesh::new(sheet.positions.clone(), sheet.triangles.clone()),
    };
    let mut t = Tracker::new(&tracked, cameras.clone(), 0, &images(0), opts).unwrap();
    let mut reports = Vec::new();
    for f in 1..=frames {
        let r = t.step(f, &images(f)).unwrap();
        assert!(!r.stalled, "frame {f}: {r:?}");
        reports.push(r);
    }
    let truth = at(frames);
    let err = rms_distance(&t.positions()[..n_sheet], &truth[..n_sheet]);
    (err, reports)
}

#[test]
fn a_still_rod_in_front_of_a_surface_that_starts_to_move_does_not_hold_it_back() {
    // Next to the rod's edges the sheet's template pixels land on the rod under the true motion
    // but beside it under none: kept, they hold the sheet back as it starts to move, the first
    // frame's (the anchor's) most, since their way is all the sheet went. The rod's own pixels
    // are contradicted by the other cameras and unchanged in the next frame, so the pixels
    // whose way crosses them are left out. Two cameras and a 10 cm rod (a band of the sheet
    // that neither sees), three cameras and a 3 cm one.
    let frames = 6;
    for (width, third_camera) in [(0.1, false), (0.03, true)] {
        let strip = Strip::Still {
            width,
            third_camera,
        };
        let (kept, _) = sheet_behind_a_strip(
            strip,
            TrackOptions {
                still_occluders: false,
                ..TrackOptions::default()
            },
            frames,
        );
        let (left_out, reports) = sheet_behind_a_strip(strip, TrackOptions::default(), frames);
        // Each frame's log says how many pixels it left out there (none in the first, which has
        // no velocity to predict the way with and leaves out only the pixels on the marks).
        let near: Vec<usize> = reports.iter().map(|r| r.near_still).collect();
        assert!(
            near[1..].iter().all(|&n| n > 0),
            "near a still rod per frame {near:?}"
        );
        eprintln!(
            "sheet rms after {frames} frames behind a {width} m rod, {} cameras: kept {:.3} mm, \
             left out {:.3} mm",
            2 + third_camera as usize,
            kept * 1e3,
            left_out * 1e3
        );
        assert!(
            left_out < 0.6 * kept,
            "{width} m rod: kept {kept:e}, left out {left_out:e}"
        );
    }
}

#[test]
fn a_strip_of_the_mesh_sweeping_in_front_of_it_does_not_drag_the_surface_behind() {
    // Each frame the strip covers a band of the sheet that the previous frame's template still
    // sees; compared there, those pixels match the strip's colours and pull the sheet along
    // with it. Left out (judged from the mesh where each level starts), they do not.
    let frames = 6;
    let with = |hidden_ahead| TrackOptions {
        hidden_ahead,
        ..TrackOptions::default()
    };
    let (kept, _) = sheet_behind_a_strip(Strip::Sweeping, with(false), frames);
    let (left_out, reports) = sheet_behind_a_strip(Strip::Sweeping, with(true), frames);
    let hidden: Vec<usize> = reports.iter().map(|r| r.hidden).collect();
    eprintln!(
        "sheet rms after {frames} frames: kept {:.2} mm, left out {:.2} mm; hidden per frame {hidden:?}",
        kept * 1e3,
        left_out * 1e3
    );
    assert!(hidden.iter().all(|&h| h > 0), "hidden per frame {hidden:?}");
    // Measured: 2.80 mm kept, 0.23 mm left out (the strip itself about 0.4 mm either way).
    assert!(
        left_out < 0.25 * kept,
        "kept {kept:e}, left out {left_out:e}"
    );
    assert!(left_out < 1e-3, "left out {left_out:e}");
}

#[test]
fn two_cameras_that_share_only_a_rim_over_a_plain_background_leave_a_true_mesh_where_it_is() {
    // The blob seen by two cameras that share about 1 % of its surface, its rim, over a plain
    // grey background; and the crossing's two cameras, which share 29 pixels. Moved outward,
    // the rim's pixels land on the background, which both cameras see alike, so the cost falls
    // to nothing there: the check once called the blob's true mesh 10 px inside the surface and
    // moved every vertex 59 mm out before tracking (the run 3.3 % off at every frame).
    use crate::synth::{Preset, SynthOptions, Synthetic};
    use crate::tracker::{moved_onto_surface, surface_offset};
    for preset in [Preset::Blob, Preset::Crossing] {
        let syn = Synthetic::generate(&SynthOptions {
            preset,
            cameras: Some(2),
            width: 480,
            height: 360,
            frames: 2,
            ..SynthOptions::default()
        })
        .unwrap();
        let images: Vec<RgbImage> = (0..2).map(|c| syn.render(c, 0)).collect();
        let found = surface_offset(&syn.mesh, &syn.cameras, 0, &images);
        assert!(found.is_none_or(|f| !f.is_off()), "{preset:?}: {found:?}");
        assert!(
            moved_onto_surface(&syn.mesh, &syn.cameras, 0, &images).is_none(),
            "{preset:?}"
        );
    }
}

/// One lag per camera as `Lag` takes them: each camera's for every one of `n` vertices (empty
/// for a camera on time).
fn per_vertex(offsets: &[f64], n: usize) -> Vec<Vec<f64>> {
    offsets
        .iter()
        .map(|&d| if d == 0.0 { Vec::new() } else { vec![d; n] })
        .collect()
}

//! The "Universal Capture" baseline (Borshukov et al. 2003; thesis §2.4, §3.1.2) that the Model
//! Flow tracker is measured against: 2D optical flow in each camera on its own, then
//! triangulation. Per frame `t → t+1` and per camera, every mesh vertex the camera sees at `t`
//! (`visibility`) is tracked by pyramidal Lucas–Kanade (`lk`); each vertex is then triangulated
//! (`triangulate`) from the cameras that tracked it, with the cameras' poses at `t+1`. A vertex
//! with fewer than two usable tracks keeps its previous position.
//!
//! Where a 2D track starts is [`Seeding`]: `Chained` carries each camera's 2D track from frame to
//! frame as Universal Capture did (re-seeding a camera's track from the reprojection of the 3D
//! vertex only when it was lost or the vertex just became visible); `Reprojected` restarts every
//! track each frame at the reprojection of the triangulated vertex. The default is `Reprojected`:
//! it feeds the multi-view consistency of the triangulation back into the 2D tracks (two cameras'
//! independent drifts are pulled onto one epipolar-consistent point every frame) and resumes
//! lost tracks for free; on the Blender sample the two give the same RMS error to 1e-6 scene
//! units (with two cameras the triangulated point reprojects almost onto the 2D tracks), see
//! `docs/baseline.md`.
//! The baseline is meant as the strongest form of the approach we know, so that the comparison
//! with Model Flow is fair: colour Lucas–Kanade with a forward–backward check, z-buffered
//! visibility, DLT refined on the reprojection error, outlier cameras dropped.

use crate::base::camera::Camera;
use crate::base::image::RgbImage;
use crate::base::mesh::Mesh;
use crate::baseline::gradient::GradientPyramid;
use crate::baseline::lk::{self, LkOptions};
use crate::baseline::triangulate::triangulate;
use crate::baseline::visibility::visible_vertices;
use crate::error::{Error, Result};
use crate::input::scene::Scene;
use crate::run::{write_run, FrameDetail, FrameLog, Method, OpenMode, RunFolder, RunOptions};
use nalgebra::{Point2, Point3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where each frame's 2D tracks start (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Seeding {
    /// Continue each camera's own 2D track (Universal Capture); re-seed lost tracks.
    Chained,
    /// Start every track at the reprojection of the current 3D vertex.
    Reprojected,
}

/// Options of the baseline.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BaselineOptions {
    pub lk: LkOptions,
    pub seeding: Seeding,
    /// Gauss–Newton steps refining each linear triangulation.
    pub refine_iterations: usize,
    /// Largest reprojection error (pixels) a triangulated vertex may have. With more than two
    /// cameras the worst track is dropped until the rest agree; a vertex whose tracks never agree
    /// keeps its previous position.
    pub max_reprojection_error: f64,
}

impl Default for BaselineOptions {
    fn default() -> Self {
        BaselineOptions {
            lk: LkOptions::default(),
            seeding: Seeding::Reprojected,
            refine_iterations: 5,
            max_reprojection_error: 2.0,
        }
    }
}

impl BaselineOptions {
    /// Checks every option against its range before any work, naming it as `modelflow
    /// baseline` spells it (a huge window or pyramid would allocate without bound).
    pub fn validate(&self) -> Result<()> {
        let lk = &self.lk;
        if !(1..=50).contains(&lk.window_radius) {
            return Err(Error::option(
                "--window",
                2 * lk.window_radius + 1,
                "an odd number of pixels from 3 to 101",
            ));
        }
        if !(1..=12).contains(&lk.levels) {
            return Err(Error::option("--levels", lk.levels, "1 to 12"));
        }
        if let Some(fb) = lk.forward_backward {
            if !(fb.is_finite() && fb > 0.0 && fb <= 1000.0) {
                return Err(Error::option(
                    "--fb",
                    fb,
                    "a number in (0, 1000] pixels (0 = off)",
                ));
            }
        }
        let r = self.max_reprojection_error;
        if !(r.is_finite() && r > 0.0 && r <= 1000.0) {
            return Err(Error::option(
                "--max-reprojection",
                r,
                "a number in (0, 1000] pixels",
            ));
        }
        let finite = |v: f64| v.is_finite() && v >= 0.0;
        if !(finite(lk.epsilon)
            && finite(lk.min_eigenvalue)
            && finite(lk.pyramid_sigma)
            && lk.pyramid_sigma <= 20.0)
            || lk.max_iterations == 0
            || lk.max_iterations > 10000
        {
            return Err(Error::option(
                "baseline options",
                format!("{lk:?}"),
                "finite, non-negative numbers, at least one iteration, a blur of at most 20 px",
            ));
        }
        Ok(())
    }
}

/// What one frame step did (the baseline's part of a run's log line).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct BaselineFrame {
    /// Successful 2D tracks, summed over cameras (a vertex seen by two cameras counts twice).
    pub tracked: usize,
    /// Vertices that got a new 3D position; the others kept their previous one.
    pub triangulated: usize,
}

/// The baseline's state between frames: current vertex positions, each camera's image pyramid
/// and 2D tracks at the current frame.
pub struct Baseline {
    opts: BaselineOptions,
    cameras: Vec<Camera>,
    triangles: Vec<[u32; 3]>,
    positions: Vec<Point3<f64>>,
    frame: u32,
    pyramids: Vec<GradientPyramid>,
    /// Per camera, per vertex: the 2D track position at `frame` (`None` if lost or not seen).
    tracks: Vec<Vec<Option<Point2<f64>>>>,
}

fn check_images(cameras: &[Camera], images: &[RgbImage], frame: u32) -> Result<()> {
    if images.len() != cameras.len() {
        return Err(Error::mismatch(
            format!("frame {frame}: images"),
            format!("{} (one per camera)", cameras.len()),
            images.len(),
        ));
    }
    for (c, img) in cameras.iter().zip(images) {
        if (img.width(), img.height()) != (c.width as usize, c.height as usize) {
            return Err(Error::mismatch(
                format!("frame {frame}: camera {}: image size", c.name),
                format!("{}x{}", c.width, c.height),
                format!("{}x{}", img.width(), img.height()),
            ));
        }
    }
    Ok(())
}

impl Baseline {
    /// Starts at `first_frame` with the mesh lined up with it and that frame's images (one per
    /// camera, in the order of `cameras`).
    pub fn new(
        mesh: &Mesh,
        cameras: &[Camera],
        first_frame: u32,
        images: &[RgbImage],
        opts: &BaselineOptions,
    ) -> Result<Baseline> {
        opts.validate()?;
        check_images(cameras, images, first_frame)?;
        let n = mesh.positions.len();
        Ok(Baseline {
            opts: opts.clone(),
            cameras: cameras.to_vec(),
            triangles: mesh.triangles.clone(),
            positions: mesh.positions.clone(),
            frame: first_frame,
            pyramids: images
                .par_iter()
                .map(|img| lk::pyramid(img, &opts.lk))
                .collect(),
            tracks: vec![vec![None; n]; cameras.len()],
        })
    }

    /// The current frame.
    pub fn frame(&self) -> u32 {
        self.frame
    }

    /// Vertex positions at the current frame.
    pub fn positions(&self) -> &[Point3<f64>] {
        &self.positions
    }

    /// Advances one frame given the next frame's images (one per camera).
    pub fn step(&mut self, images: &[RgbImage]) -> Result<BaselineFrame> {
        let next_frame = self.frame + 1;
        check_images(&self.cameras, images, next_frame)?;
        let next_pyramids: Vec<GradientPyramid> = images
            .par_iter()
            .map(|img| lk::pyramid(img, &self.opts.lk))
            .collect();
        let n = self.positions.len();
        // 2D tracking, camera by camera.
        let mut new_tracks: Vec<Vec<Option<Point2<f64>>>> = Vec::with_capacity(self.cameras.len());
        for (ci, cam) in self.cameras.iter().enumerate() {
            let proj = cam.at(self.frame);
            let visible = visible_vertices(
                &self.positions,
                &self.triangles,
                proj,
                cam.width,
                cam.height,
            );
            let mut ids = Vec::new();
            let mut starts = Vec::new();
            for (v, &vis) in visible.iter().enumerate() {
                if !vis {
                    continue;
                }
                let start = match (self.opts.seeding, self.tracks[ci][v]) {
                    (Seeding::Chained, Some(p)) if cam.contains(&p) => Some(p),
                    _ => proj.project(&self.positions[v]),
                };
                if let Some(p) = start {
                    ids.push(v);
                    starts.push(p);
                }
            }
            let moved = lk::track(
                &self.pyramids[ci],
                &next_pyramids[ci],
                &starts,
                &self.opts.lk,
            );
            let mut row = vec![None; n];
            for (&v, q) in ids.iter().zip(moved) {
                row[v] = q;
            }
            new_tracks.push(row);
        }
        let tracked = new_tracks.iter().flatten().filter(|t| t.is_some()).count();
        // Triangulation, vertex by vertex, with the cameras' poses at the new frame.
        let projections: Vec<_> = self.cameras.iter().map(|c| c.at(next_frame)).collect();
        let solved: Vec<(Option<Point3<f64>>, Vec<usize>)> = (0..n)
            .into_par_iter()
            .map(|v| {
                let mut used: Vec<usize> = (0..self.cameras.len())
                    .filter(|&c| new_tracks[c][v].is_some())
                    .collect();
                loop {
                    if used.len() < 2 {
                        return (None, used);
                    }
                    let obs: Vec<_> = used
                        .iter()
                        .map(|&c| (projections[c], new_tracks[c][v].unwrap()))
                        .collect();
                    match triangulate(&obs, self.opts.refine_iterations) {
                        Some(t) if t.worst.1 <= self.opts.max_reprojection_error => {
                            return (Some(t.point), used)
                        }
                        Some(t) if used.len() > 2 => {
                            used.remove(t.worst.0);
                        }
                        _ => return (None, Vec::new()),
                    }
                }
            })
            .collect();
        let mut triangulated = 0;
        for (v, (point, used)) in solved.into_iter().enumerate() {
            if let Some(x) = point {
                self.positions[v] = x;
                triangulated += 1;
            }
            // A camera's track that disagreed with the others is dropped (re-seeded next time).
            for (c, row) in new_tracks.iter_mut().enumerate() {
                if row[v].is_some() && point.is_some() && !used.contains(&c) {
                    row[v] = None;
                }
            }
        }
        self.tracks = new_tracks;
        self.pyramids = next_pyramids;
        self.frame = next_frame;
        Ok(BaselineFrame {
            tracked,
            triangulated,
        })
    }
}

/// What a whole run did.
#[derive(Clone, Debug, PartialEq)]
pub struct BaselineSummary {
    /// One entry per frame solved (all frames after the first).
    pub frames: Vec<BaselineFrame>,
    /// Wall-clock seconds per solved frame, image loading included.
    pub seconds: Vec<f64>,
    pub out_dir: PathBuf,
}

/// Runs the baseline over the whole scene into the run folder `out_dir` (see `run`: one mesh
/// per frame, the first being the input mesh, one log line per solved frame, the manifest),
/// calling `on_frame` after each solved frame. The baseline cannot resume a run (its 2D tracks
/// are not in the folder): `run.mode` must be `New` or `Force`.
pub fn run(
    scene: &Scene,
    opts: &BaselineOptions,
    out_dir: &Path,
    run: &RunOptions,
    on_frame: &(dyn Fn(&FrameLog) + Sync),
) -> Result<BaselineSummary> {
    opts.validate()?;
    if run.mode == OpenMode::Resume {
        return Err(Error::option(
            "resume",
            "requested",
            "a new run: the baseline cannot resume (its 2D tracks are not in the run folder)",
        ));
    }
    let mut summary = BaselineSummary {
        frames: Vec::new(),
        seconds: Vec::new(),
        out_dir: out_dir.to_path_buf(),
    };
    write_run(out_dir, Method::Baseline, scene, opts, run, |folder, _| {
        run_into(folder, &mut summary, scene, opts, run, on_frame)
    })?;
    Ok(summary)
}

fn run_into(
    folder: &mut RunFolder,
    summary: &mut BaselineSummary,
    scene: &Scene,
    opts: &BaselineOptions,
    run: &RunOptions,
    on_frame: &(dyn Fn(&FrameLog) + Sync),
) -> Result<()> {
    folder.write_first(&scene.mesh)?;
    let images = scene.load_images(scene.first)?;
    let mut tracker = Baseline::new(&scene.mesh, &scene.cameras, scene.first, &images, opts)?;
    drop(images);
    for frame in scene.first + 1..=scene.last {
        if run.cancelled() {
            return Err(Error::Interrupted {
                last_complete: frame - 1,
            });
        }
        let start = Instant::now();
        let images = scene.load_images(frame).map_err(|e| Error::AtFrame {
            frame,
            error: Box::new(e),
        })?;
        let load_seconds = start.elapsed().as_secs_f64();
        let step = Instant::now();
        let stats = tracker.step(&images)?;
        let seconds = step.elapsed().as_secs_f64();
        folder.write_mesh(
            frame,
            &scene.mesh.with_positions(tracker.positions().to_vec()),
        )?;
        let wall_seconds = start.elapsed().as_secs_f64();
        let line = FrameLog {
            frame,
            seconds,
            load_seconds,
            wall_seconds,
            detail: FrameDetail::Baseline(stats),
        };
        folder.append(&line)?;
        summary.frames.push(stats);
        summary.seconds.push(wall_seconds);
        on_frame(&line);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::camera::{look_at, Projection};
    use crate::base::mesh::grid;
    use nalgebra::{Matrix3, Vector3};

    /// Smooth value noise: random values on an integer lattice, smoothstep-interpolated.
    fn value_noise(x: f64, y: f64, seed: u64) -> f64 {
        let hash = |i: i64, j: i64| {
            let mut h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
                ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
                ^ seed.wrapping_mul(0x1656_67B1_9E37_79F9);
            h ^= h >> 31;
            h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
            h ^= h >> 29;
            (h >> 11) as f64 / (1u64 << 53) as f64
        };
        let (i, j) = (x.floor() as i64, y.floor() as i64);
        let (fx, fy) = (x - x.floor(), y - y.floor());
        let s = |t: f64| t * t * (3.0 - 2.0 * t);
        let (sx, sy) = (s(fx), s(fy));
        let top = hash(i, j) + (hash(i + 1, j) - hash(i, j)) * sx;
        let bottom = hash(i, j + 1) + (hash(i + 1, j + 1) - hash(i, j + 1)) * sx;
        top + (bottom - top) * sy
    }

    /// A non-repeating colour texture with detail at several scales (plane units; about 100
    /// pixels per unit in these cameras).
    fn texture(x: f64, y: f64) -> [f32; 3] {
        let octaves = |c: u64| {
            [(0.04, 0.5), (0.08, 0.3), (0.16, 0.2)]
                .iter()
                .map(|&(cell, amp)| {
                    amp * value_noise(x / cell, y / cell, 3 * c + (cell * 100.0) as u64)
                })
                .sum::<f64>() as f32
        };
        [octaves(0), octaves(1), octaves(2)]
    }

    const W: usize = 200;
    const H: usize = 150;

    fn k() -> Matrix3<f64> {
        Matrix3::new(300.0, 0.0, 99.5, 0.0, 300.0, 74.5, 0.0, 0.0, 1.0)
    }

    /// Pose (R, t) of a camera at `eye` looking at `target`, world y up in the image.
    fn pose(eye: Point3<f64>, target: Point3<f64>) -> (Matrix3<f64>, Vector3<f64>) {
        look_at(&eye, &target, &Vector3::new(0.0, -1.0, 0.0))
    }

    /// Renders the textured square `[-0.8, 0.8]²` of the plane `z = shift.z`, its texture moved
    /// by `shift.xy`, on a flat grey background (ray casting at pixel centres).
    fn render(r: &Matrix3<f64>, t: &Vector3<f64>, shift: Vector3<f64>) -> RgbImage {
        let kinv = k().try_inverse().unwrap();
        let c = -(r.transpose() * t);
        RgbImage::from_fn(W, H, |u, v| {
            let d = r.transpose() * (kinv * Vector3::new(u as f64, v as f64, 1.0));
            let s = (shift.z - c.z) / d.z;
            let x = c + d * s;
            let (px, py) = (x.x - shift.x, x.y - shift.y);
            if s > 0.0 && px.abs() <= 0.8 && py.abs() <= 0.8 {
                texture(px, py)
            } else {
                [0.3, 0.3, 0.3]
            }
        })
    }

    struct Rig {
        cameras: Vec<Camera>,
        /// Per camera, per frame: (R, t).
        poses: Vec<Vec<(Matrix3<f64>, Vector3<f64>)>>,
    }

    /// Two cameras 3 units from the plane, 0.8 apart; `cam1` looks at `target1` and moves up by
    /// `cam1_step` per frame (a moving camera, one pose per frame).
    fn rig(frames: usize, target1: Point3<f64>, cam1_step: f64) -> Rig {
        let p0 = pose(Point3::new(-0.4, 0.0, -3.0), Point3::origin());
        let p1: Vec<_> = (0..frames)
            .map(|f| {
                let dy = cam1_step * f as f64;
                pose(
                    Point3::new(0.4, dy, -3.0),
                    Point3::new(target1.x, target1.y + dy, target1.z),
                )
            })
            .collect();
        let proj =
            |(r, t): &(Matrix3<f64>, Vector3<f64>)| Projection::from_krt(&k(), r, t).unwrap();
        Rig {
            cameras: vec![
                Camera::fixed("cam0", W as u32, H as u32, proj(&p0)),
                Camera::moving("cam1", W as u32, H as u32, 0, p1.iter().map(proj).collect()),
            ],
            poses: vec![vec![p0; frames], p1],
        }
    }

    fn images(rig: &Rig, frame: usize, shift: Vector3<f64>) -> Vec<RgbImage> {
        rig.poses
            .iter()
            .map(|p| render(&p[frame].0, &p[frame].1, shift))
            .collect()
    }

    fn plate() -> Mesh {
        grid(9, 9, |u, v| Point3::new(u - 0.5, v - 0.5, 0.0))
    }

    #[test]
    fn recovers_a_rigid_translation_seen_by_two_cameras() {
        let step = Vector3::new(0.02, -0.015, 0.03);
        let frames = 4;
        let rig = rig(frames, Point3::origin(), 0.03);
        let mesh = plate();
        for seeding in [Seeding::Reprojected, Seeding::Chained] {
            let opts = BaselineOptions {
                seeding,
                ..BaselineOptions::default()
            };
            let mut b = Baseline::new(
                &mesh,
                &rig.cameras,
                0,
                &images(&rig, 0, Vector3::zeros()),
                &opts,
            )
            .unwrap();
            for f in 1..frames {
                let shift = step * f as f64;
                let stats = b.step(&images(&rig, f, shift)).unwrap();
                assert_eq!(b.frame(), f as u32);
                assert_eq!(
                    stats.triangulated,
                    mesh.vertex_count(),
                    "{seeding:?} frame {f}"
                );
                assert_eq!(stats.tracked, 2 * mesh.vertex_count());
                let err = b
                    .positions()
                    .iter()
                    .zip(&mesh.positions)
                    .map(|(p, p0)| (p - (p0 + shift)).norm())
                    .fold(0.0f64, f64::max);
                // The plate moved 4 cm per frame; a tenth of a pixel is about a millimetre.
                assert!(err < 4e-3, "{seeding:?} frame {f}: max error {err}");
            }
        }
    }

    #[test]
    fn vertices_seen_by_one_camera_keep_their_position() {
        let step = Vector3::new(0.02, -0.015, 0.03);
        // cam1 looks far to the right: the left columns of the plate are outside its image.
        let rig = rig(2, Point3::new(0.9, 0.0, 0.0), 0.0);
        let mesh = plate();
        let in_cam1 = visible_vertices(
            &mesh.positions,
            &mesh.triangles,
            rig.cameras[1].at(0),
            W as u32,
            H as u32,
        );
        let only_cam0 = in_cam1.iter().filter(|&&v| !v).count();
        assert!(
            (9..60).contains(&only_cam0),
            "{only_cam0} vertices outside cam1"
        );
        let opts = BaselineOptions::default();
        let mut b = Baseline::new(
            &mesh,
            &rig.cameras,
            0,
            &images(&rig, 0, Vector3::zeros()),
            &opts,
        )
        .unwrap();
        let stats = b.step(&images(&rig, 1, step)).unwrap();
        for (v, p) in b.positions().iter().enumerate() {
            if !in_cam1[v] {
                assert_eq!(*p, mesh.positions[v], "vertex {v} seen by cam0 only moved");
            }
        }
        // The others (bar a few at cam1's image border) followed the plate.
        let followed = (0..mesh.vertex_count())
            .filter(|&v| {
                in_cam1[v] && (b.positions()[v] - (mesh.positions[v] + step)).norm() < 4e-3
            })
            .count();
        assert!(
            followed + 5 >= mesh.vertex_count() - only_cam0,
            "{followed} followed"
        );
        assert!(stats.triangulated <= mesh.vertex_count() - only_cam0);
    }

    #[test]
    fn wrong_image_count_or_size_is_a_clear_error() {
        let rig = rig(2, Point3::origin(), 0.0);
        let imgs = images(&rig, 0, Vector3::zeros());
        let opts = BaselineOptions::default();
        let err = Baseline::new(&plate(), &rig.cameras, 0, &imgs[..1], &opts)
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("images: expected 2 (one per camera), found 1"),
            "{err}"
        );
        let mut b = Baseline::new(&plate(), &rig.cameras, 0, &imgs, &opts).unwrap();
        let small = vec![imgs[0].clone(), RgbImage::new(10, 10)];
        let err = b.step(&small).unwrap_err().to_string();
        assert!(
            err.contains("frame 1: camera cam1: image size: expected 200x150, found 10x10"),
            "{err}"
        );
    }
}

//! The tracker: runs the per-frame solver over a shot (thesis §6.6, "the next frame starts from
//! the solved one").
//!
//! For each new frame it builds image pyramids, compares the new frame against two templates —
//! the previous frame (the thesis' method) and the first frame of the shot (so that small errors
//! do not accumulate into drift; the thesis' Fig. 7.7 shows that they otherwise do) — and solves
//! coarse to fine. Each frame uses every camera's own projection at that frame. A constant-velocity
//! prediction is tried as the starting guess and kept only if it matches the images better than
//! the previous positions.
//!
//! [`Tracker`] works in memory (images in, positions out); [`track_scene`] drives it over a scene
//! on disk and writes one OBJ per frame and a JSON-lines log.

use crate::bending::Bending;
use crate::camera::{Camera, Projection};
use crate::error::{Error, Result};
use crate::image::RgbImage;
use crate::mesh::Mesh;
use crate::patch::{PatchOptions, PatchSet};
use crate::pyramid::Pyramid;
use crate::solve::{Interpolation, Problem, SolveSummary, SolverOptions, StopReason};
use crate::springs::EdgeSet;
use nalgebra::Point3;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// Tracker settings. `Default` is what `modelflow track` uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackOptions {
    pub solver: SolverOptions,
    /// Pyramid levels solved, coarse to fine (1 = full resolution only).
    pub levels: usize,
    /// Gaussian smoothing (pixels, at each level's own scale) before gradients are taken.
    pub blur: f64,
    /// Weight of the first-frame template relative to the previous-frame one (0 = thesis only).
    pub anchor_weight: f64,
    /// Silhouette margin in pixels.
    pub margin: usize,
    /// Grazing-angle cut-off (cosine between normal and view direction).
    pub min_cos: f64,
    /// Try a constant-velocity prediction as the starting guess.
    pub predict: bool,
    /// At full resolution, compare every other pixel of the previous frame (a checkerboard, at
    /// twice the weight) instead of all of them. Neighbouring pixels of a smoothed image carry
    /// nearly the same information, so this halves the finest level's work for no measurable
    /// loss of accuracy (the first-frame anchor is always a checkerboard).
    pub checkerboard: bool,
}

impl Default for TrackOptions {
    fn default() -> Self {
        TrackOptions {
            solver: SolverOptions::default(),
            levels: 2,
            blur: 1.0,
            anchor_weight: 2.0,
            margin: 1,
            min_cos: 0.1,
            predict: true,
            checkerboard: true,
        }
    }
}

/// What happened in one frame.
#[derive(Clone, Debug, Serialize)]
pub struct FrameReport {
    pub frame: u32,
    /// Gauss–Newton iterations over all levels.
    pub iterations: usize,
    /// Cost at the previous frame's positions (no deformation), finest level.
    pub cost_before: f64,
    /// Cost at the solution, finest level.
    pub cost_after: f64,
    /// Pixels compared at the solution, finest level.
    pub pixels: usize,
    /// Time of the step (pyramids, patches, solver), seconds.
    pub seconds: f64,
    /// Why the finest level stopped.
    pub stop: StopReason,
    /// Whether the constant-velocity prediction was used as the start.
    pub predicted: bool,
    /// Where the time went: building pyramids, building patches, solving (seconds).
    pub timing: StepTiming,
    /// Per-level solver summaries, coarse to fine.
    pub levels: Vec<SolveSummary>,
}

/// Time split of one frame's step, seconds.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct StepTiming {
    /// Building the frame's image pyramids ([`prepare`]); `track_scene` does this while the
    /// previous frame is solved, so it is not on the critical path there.
    pub pyramids: f64,
    /// Building the template patches.
    pub patches: f64,
    /// The Gauss–Newton solves.
    pub solve: f64,
}

struct Template {
    positions: Vec<Point3<f64>>,
    pyramids: Vec<Pyramid>,
    frame: u32,
}

/// Frame-by-frame tracker state, in memory.
pub struct Tracker {
    triangles: Vec<[u32; 3]>,
    cameras: Vec<Camera>,
    opts: TrackOptions,
    edges: EdgeSet,
    bending: Bending,
    two_sided: bool,
    /// Anchor patches per level (built once from the first frame).
    anchor: Vec<PatchSet>,
    prev: Template,
    before_prev: Option<Vec<Point3<f64>>>,
}

fn level_projection(p: &Projection, level: usize) -> Projection {
    if level == 0 {
        p.clone()
    } else {
        p.downscaled(1 << level)
    }
}

impl Tracker {
    /// A tracker whose mesh lines up with `images` (one per camera) at `frame`.
    pub fn new(
        mesh: &Mesh,
        cameras: Vec<Camera>,
        frame: u32,
        images: &[RgbImage],
        opts: TrackOptions,
    ) -> Result<Self> {
        if images.len() != cameras.len() {
            return Err(Error::Usage(format!(
                "{} images given for {} cameras",
                images.len(),
                cameras.len()
            )));
        }
        let levels = opts.levels.max(1);
        let pyramids = build_pyramids(images, levels, opts.blur);
        let edges = EdgeSet::new(mesh.edges(), &mesh.positions);
        let mut t = Tracker {
            triangles: mesh.triangles.clone(),
            cameras,
            opts,
            edges,
            bending: Bending::new(&mesh.triangles, &mesh.positions),
            two_sided: !mesh.is_closed(),
            anchor: Vec::new(),
            prev: Template {
                positions: mesh.positions.clone(),
                pyramids,
                frame,
            },
            before_prev: None,
        };
        // The anchor keeps every other pixel (checkerboard) at twice the weight: the same total
        // pull for half the work.
        if opts.anchor_weight > 0.0 {
            t.anchor = (0..levels)
                .map(|l| t.template_patches(&t.prev, l, 2.0 * opts.anchor_weight as f32, true))
                .collect();
        }
        Ok(t)
    }

    /// Replaces the current frame's vertex positions (e.g. a corrected shape from an artist, or
    /// ground truth in an experiment); the next step starts from them, with no velocity.
    pub fn set_positions(&mut self, positions: Vec<Point3<f64>>) -> Result<()> {
        if positions.len() != self.prev.positions.len() {
            return Err(Error::Usage(format!(
                "{} positions given for a mesh of {} vertices",
                positions.len(),
                self.prev.positions.len()
            )));
        }
        self.prev.positions = positions;
        self.before_prev = None;
        Ok(())
    }

    /// Current vertex positions (the last solved frame).
    pub fn positions(&self) -> &[Point3<f64>] {
        &self.prev.positions
    }

    fn patch_options(&self) -> PatchOptions {
        PatchOptions {
            margin: self.opts.margin,
            min_cos: self.opts.min_cos,
            two_sided: self.two_sided,
            checkerboard: false,
        }
    }

    fn template_patches(
        &self,
        tpl: &Template,
        level: usize,
        weight: f32,
        checkerboard: bool,
    ) -> PatchSet {
        let popts = PatchOptions {
            checkerboard,
            ..self.patch_options()
        };
        let per_cam: Vec<PatchSet> = self
            .cameras
            .par_iter()
            .enumerate()
            .map(|(c, cam)| {
                let mut set = PatchSet::default();
                let proj = level_projection(cam.at(tpl.frame), level);
                set.add_camera(
                    &tpl.positions,
                    &self.triangles,
                    &proj,
                    &tpl.pyramids[c].levels[level],
                    c as u16,
                    weight,
                    &popts,
                    None,
                );
                set
            })
            .collect();
        merge(per_cam)
    }

    /// Solves for `frame` given its images (one per camera) and makes it the new template.
    pub fn step(&mut self, frame: u32, images: &[RgbImage]) -> Result<FrameReport> {
        let prepared = prepare(images, &self.opts);
        self.step_prepared(frame, prepared)
    }

    /// [`Tracker::step`] with the frame's images already prepared by [`prepare`] (which needs
    /// no tracker, so it can run while the previous frame is being solved).
    pub fn step_prepared(&mut self, frame: u32, prepared: Prepared) -> Result<FrameReport> {
        if prepared.pyramids.len() != self.cameras.len() {
            return Err(Error::Usage(format!(
                "{} images given for {} cameras",
                prepared.pyramids.len(),
                self.cameras.len()
            )));
        }
        let levels = self.opts.levels.max(1);
        if prepared.pyramids.iter().any(|p| p.levels.len() < levels)
            || prepared.blur != self.opts.blur
        {
            return Err(Error::Usage(format!(
                "images prepared for other options than the tracker's ({levels} pyramid levels, \
                 blur {} px)",
                self.opts.blur
            )));
        }
        let t0 = Instant::now();
        let next = prepared.pyramids;
        let mut timing = StepTiming {
            pyramids: prepared.seconds,
            ..Default::default()
        };
        let ncam = self.cameras.len();
        let mut x = self.prev.positions.clone();
        let mut summaries = Vec::with_capacity(levels);
        let mut predicted = false;
        let mut cost_before = 0.0;
        let mut cost_after = 0.0;
        let mut pixels = 0;
        let mut stop = StopReason::NoData;
        // The membrane's reference shape is the constant-velocity prediction when there is one,
        // so that it penalises changes of the deformation's *rate* (a cloth that keeps folding is
        // not held back), and the previous shape otherwise.
        let reference: Vec<Point3<f64>> = match &self.before_prev {
            Some(pp) => self
                .prev
                .positions
                .iter()
                .zip(pp)
                .map(|(a, b)| a + (a - b))
                .collect(),
            None => self.prev.positions.clone(),
        };
        // The bending term's targets: the rest shape's Laplacian coordinates, turned by per-vertex
        // rotations taken from the previous shape (they change little in a frame; needed only
        // where the rest Laplacian is not zero).
        let bend_targets = if self.opts.solver.springs.bending > 0.0 {
            self.bending.targets_at(&self.prev.positions)
        } else {
            Vec::new()
        };
        for level in (0..levels).rev() {
            let tp = Instant::now();
            let cb = level == 0 && self.opts.checkerboard;
            let weight = if cb { 2.0 } else { 1.0 };
            let mut set = self.template_patches(&self.prev, level, weight, cb);
            if let Some(anchor) = self.anchor.get(level) {
                // Anchor patches only where the triangle is seen in the previous frame too
                // (otherwise it has turned away or been covered since the first frame).
                let cover = set.coverage(self.triangles.len(), ncam);
                for p in &anchor.patches {
                    if cover[p.triangle as usize * ncam + p.camera as usize] {
                        let start = set.pixels.len() as u32;
                        set.pixels
                            .extend_from_slice(&anchor.pixels[p.start as usize..p.end as usize]);
                        set.patches.push(crate::patch::Patch {
                            start,
                            end: set.pixels.len() as u32,
                            ..*p
                        });
                    }
                }
            }
            let by_triangle = set.by_triangle();
            timing.patches += tp.elapsed().as_secs_f64();
            let ts = Instant::now();
            // Coarse levels only bring the mesh near the solution and the finest level decides
            // it, so the (dearer) chosen interpolation is used there only.
            let sopts = SolverOptions {
                interpolation: if level == 0 {
                    self.opts.solver.interpolation
                } else {
                    Interpolation::Linear
                },
                ..self.opts.solver
            };
            let problem = Problem {
                triangles: &self.triangles,
                patches: &set.patches,
                pixels: &set.pixels,
                by_triangle: &by_triangle,
                targets: next.iter().map(|p| &p.levels[level]).collect(),
                projections: self
                    .cameras
                    .iter()
                    .map(|c| level_projection(c.at(frame), level))
                    .collect(),
                edges: &self.edges,
                previous: &reference,
                bending: Some((&self.bending, &bend_targets)),
            };
            if level == levels - 1 && self.opts.predict {
                if let Some(pp) = &self.before_prev {
                    let guess: Vec<Point3<f64>> =
                        x.iter().zip(pp).map(|(a, b)| a + (a - b)).collect();
                    if problem.cost(&guess, &sopts) < problem.cost(&x, &sopts) {
                        x = guess;
                        predicted = true;
                    }
                }
            }
            if level == 0 {
                cost_before = problem.cost(&self.prev.positions, &sopts);
            }
            let (sol, summary) = problem.solve(&x, &sopts);
            x = sol;
            if level == 0 {
                cost_after = summary.final_cost;
                pixels = summary.pixels;
                stop = summary.stop;
            }
            summaries.push(summary);
            timing.solve += ts.elapsed().as_secs_f64();
        }
        let iterations = summaries.iter().map(|s| s.iterations.len()).sum();
        let old = std::mem::replace(
            &mut self.prev,
            Template {
                positions: x,
                pyramids: next,
                frame,
            },
        );
        self.before_prev = Some(old.positions);
        Ok(FrameReport {
            frame,
            iterations,
            cost_before,
            cost_after,
            pixels,
            seconds: prepared.seconds + t0.elapsed().as_secs_f64(),
            stop,
            predicted,
            timing,
            levels: summaries,
        })
    }
}

/// One frame's images made ready for [`Tracker::step_prepared`]: each camera's smoothed pyramid.
pub struct Prepared {
    pyramids: Vec<Pyramid>,
    /// The smoothing they were built with (must be the tracker's).
    blur: f64,
    /// Time it took, seconds (reported as the step's `timing.pyramids`).
    seconds: f64,
}

/// Builds the pyramids the tracker with `opts` needs from one frame's images (one per camera).
pub fn prepare(images: &[RgbImage], opts: &TrackOptions) -> Prepared {
    let t = Instant::now();
    let pyramids = build_pyramids(images, opts.levels.max(1), opts.blur);
    Prepared {
        pyramids,
        blur: opts.blur,
        seconds: t.elapsed().as_secs_f64(),
    }
}

fn build_pyramids(images: &[RgbImage], levels: usize, blur: f64) -> Vec<Pyramid> {
    images
        .par_iter()
        .map(|img| Pyramid::new(img, levels, blur))
        .collect()
}

fn merge(sets: Vec<PatchSet>) -> PatchSet {
    let mut out = PatchSet::default();
    for s in sets {
        let off = out.pixels.len() as u32;
        out.pixels.extend(s.pixels);
        out.patches
            .extend(s.patches.into_iter().map(|p| crate::patch::Patch {
                start: p.start + off,
                end: p.end + off,
                ..p
            }));
    }
    out
}

/// One line of a run's `log.jsonl`.
#[derive(Clone, Debug, Serialize)]
pub struct FrameLog {
    #[serde(flatten)]
    pub report: FrameReport,
    /// Time spent reading this frame's images (overlapped with the previous frame's solve, as is
    /// building their pyramids, `timing.pyramids`).
    pub load_seconds: f64,
    /// Wall time from the end of the previous frame to the end of this one (what a user waits).
    pub wall_seconds: f64,
}

/// Summary of a tracked shot.
#[derive(Clone, Debug, Serialize)]
pub struct TrackSummary {
    pub frames: usize,
    pub total_seconds: f64,
    /// Median wall time per solved frame, image loading included.
    pub median_frame_seconds: f64,
    pub median_iterations: f64,
}

/// Tracks a whole scene: writes `out_dir/{frame:04}.obj` for every frame (the first one is the
/// input mesh) and `out_dir/log.jsonl`, calling `on_frame` after each solved frame. Every file is
/// written atomically; the log is rewritten after each frame so an interrupted run keeps a
/// consistent log of what it finished. The next frame's images are read, and their pyramids
/// built, while the current frame is solved.
pub fn track_scene(
    scene: &crate::scene::Scene,
    opts: &TrackOptions,
    out_dir: &std::path::Path,
    on_frame: &mut dyn FnMut(&FrameLog),
) -> Result<TrackSummary> {
    use crate::eval::frame_file;
    use crate::fsutil::write_atomic;
    use crate::meshio::write_obj;
    let t_start = Instant::now();
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    crate::eval::remove_stale_frames(out_dir, scene.first, scene.last)?;
    write_obj(&out_dir.join(frame_file(scene.first)), &scene.mesh)?;
    let first_images = scene.load_images(scene.first)?;
    let mut tracker = Tracker::new(
        &scene.mesh,
        scene.cameras.clone(),
        scene.first,
        &first_images,
        *opts,
    )?;
    drop(first_images);
    let log_path = out_dir.join("log.jsonl");
    let mut log = String::new();
    write_atomic(&log_path, log.as_bytes())?;
    let mut walls = Vec::new();
    let mut iters = Vec::new();
    if scene.first == scene.last {
        return Ok(TrackSummary {
            frames: 1,
            total_seconds: t_start.elapsed().as_secs_f64(),
            median_frame_seconds: 0.0,
            median_iterations: 0.0,
        });
    }
    // Reads a frame's images and builds their pyramids; runs while the previous frame is solved.
    let load = |frame: u32| {
        let t = Instant::now();
        scene.load_images(frame).map(|imgs| {
            let load_seconds = t.elapsed().as_secs_f64();
            (prepare(&imgs, opts), load_seconds)
        })
    };
    let mut pending = Some(load(scene.first + 1));
    let mut t_frame = Instant::now();
    for frame in scene.first + 1..=scene.last {
        let Some(loaded) = pending.take() else {
            break;
        };
        let (prepared, load_seconds) = loaded?;
        let has_next = frame < scene.last;
        let (report, next) = rayon::join(
            || tracker.step_prepared(frame, prepared),
            || has_next.then(|| load(frame + 1)),
        );
        let report = report?;
        let mesh = scene.mesh.with_positions(tracker.positions().to_vec());
        write_obj(&out_dir.join(frame_file(frame)), &mesh)?;
        let wall = t_frame.elapsed().as_secs_f64();
        t_frame = Instant::now();
        walls.push(wall);
        iters.push(report.iterations as f64);
        let entry = FrameLog {
            report,
            load_seconds,
            wall_seconds: wall,
        };
        log.push_str(
            &serde_json::to_string(&entry).map_err(|e| Error::Usage(format!("log: {e}")))?,
        );
        log.push('\n');
        write_atomic(&log_path, log.as_bytes())?;
        on_frame(&entry);
        pending = next;
    }
    Ok(TrackSummary {
        frames: (scene.last - scene.first + 1) as usize,
        total_seconds: t_start.elapsed().as_secs_f64(),
        median_frame_seconds: median(&walls),
        median_iterations: median(&iters),
    })
}

/// Median of a list (0 if empty).
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

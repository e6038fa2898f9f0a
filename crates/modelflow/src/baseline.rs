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
//! lost tracks for free, and it was also the more accurate of the two on the footage we measured
//! (see `docs/baseline.md`). This is the strongest form of the approach we know of, so that the
//! comparison with Model Flow is fair.

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::RgbImage;
use crate::lk::{self, LkOptions, Pyramid};
use crate::mesh::Mesh;
use crate::triangulate::triangulate;
use crate::visibility::visible_vertices;
use nalgebra::{Point2, Point3};
use rayon::prelude::*;

/// Where each frame's 2D tracks start (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Seeding {
    /// Continue each camera's own 2D track (Universal Capture); re-seed lost tracks.
    Chained,
    /// Start every track at the reprojection of the current 3D vertex.
    Reprojected,
}

/// Options of the baseline.
#[derive(Clone, Debug, PartialEq)]
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

/// What one frame step did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepStats {
    /// The frame just solved.
    pub frame: u32,
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
    pyramids: Vec<Pyramid>,
    /// Per camera, per vertex: the 2D track position at `frame` (`None` if lost or not seen).
    tracks: Vec<Vec<Option<Point2<f64>>>>,
}

fn check_images(cameras: &[Camera], images: &[RgbImage], frame: u32) -> Result<()> {
    if images.len() != cameras.len() {
        return Err(Error::Usage(format!(
            "frame {frame}: {} images for {} cameras",
            images.len(),
            cameras.len()
        )));
    }
    for (c, img) in cameras.iter().zip(images) {
        if (img.width(), img.height()) != (c.width as usize, c.height as usize) {
            return Err(Error::Usage(format!(
                "frame {frame}: camera {}: image is {}x{}, the camera is {}x{}",
                c.name,
                img.width(),
                img.height(),
                c.width,
                c.height
            )));
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
                .map(|img| Pyramid::for_tracking(img, &opts.lk))
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
    pub fn step(&mut self, images: &[RgbImage]) -> Result<StepStats> {
        let next_frame = self.frame + 1;
        check_images(&self.cameras, images, next_frame)?;
        let next_pyramids: Vec<Pyramid> = images
            .par_iter()
            .map(|img| Pyramid::for_tracking(img, &self.opts.lk))
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
        Ok(StepStats {
            frame: next_frame,
            tracked,
            triangulated,
        })
    }
}

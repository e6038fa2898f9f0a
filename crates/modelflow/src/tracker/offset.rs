//! Whether the first mesh lies on the surface the cameras agree on. A mesh off the surface (a
//! visual hull made from silhouettes lies outside it) is tracked with a lag: every turn of the
//! object is followed short (docs/tracker.md, "The first mesh must lie on the surface"), and
//! nothing in the frames' own checks shows it. Before tracking, the mesh is moved along its
//! vertex normals by whole pixels, −10 to +10, and at each offset the cameras are compared with
//! each other as `align` compares them (each camera's pixels warped into every other camera that
//! sees the triangle); where they agree best says how far off the surface the mesh is. Knows
//! patches, projections and images; not the tracker's solve.

use crate::base::{Camera, Mesh, Projection, RgbImage};
use crate::tracker::align::cross_patches;
use crate::tracker::patch::PatchOptions;
use crate::tracker::pyramid::Pyramid;
use crate::tracker::sequence::{level_projection, tracked_mesh};
use crate::tracker::solve::{Loss, Problem, SolverOptions};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// How far along its normals the mesh would have to move for the cameras to agree best.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceOffset {
    /// In pixels of the images at the mesh (positive: along the normals, which for a closed
    /// mesh point outward, so a mesh outside the surface has a negative offset).
    pub pixels: f64,
    /// The same in scene units.
    pub length: f64,
    /// The cameras' disagreement (mean robust cost per pixel) where the mesh is, over that at the
    /// best offset: 1 when the mesh is where they agree best.
    pub ratio: f64,
    /// Whether the best offset is at the end of the range searched (it may be further).
    pub at_limit: bool,
    /// Whether the mesh is closed (its normals point outward, `Mesh::facing_outward`).
    pub closed: bool,
}

impl SurfaceOffset {
    /// An offset worth a warning: at least `MIN_PX` pixels, where the cameras agree clearly
    /// better (`MIN_RATIO`) than where the mesh is.
    pub fn is_off(&self) -> bool {
        self.pixels.abs() >= MIN_PX && self.ratio >= MIN_RATIO
    }
}

/// Offsets below this many pixels are not reported.
pub const MIN_PX: f64 = 1.5;
/// Nor offsets where the cameras agree less than this much better than at the mesh.
pub const MIN_RATIO: f64 = 1.5;
/// The range searched, whole pixels either way.
const RANGE: i32 = 10;

/// The offset along the normals at which `cameras` agree best about `mesh` at `frame`
/// (`images`: one per camera, pinhole); `None` when no two cameras see a common triangle.
pub fn surface_offset(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
) -> Option<SurfaceOffset> {
    if cameras.len() < 2 || images.len() != cameras.len() {
        return None;
    }
    let (m, _) = tracked_mesh(mesh);
    let closed = m.is_closed();
    let mut normals = vec![Vector3::zeros(); m.positions.len()];
    for (i, t) in m.triangles.iter().enumerate() {
        let n = m.triangle_normal(i);
        for &v in t {
            normals[v as usize] += n;
        }
    }
    for n in &mut normals {
        let l = n.norm();
        if l > 0.0 {
            *n /= l;
        }
    }
    let per_unit = crate::tracker::outline::pixels_per_unit(cameras, frame, &m.positions);
    if !(per_unit.is_finite() && per_unit > 0.0) {
        return None;
    }
    let targets: Vec<RgbImage> = images
        .par_iter()
        .map(|i| Pyramid::new(i, 1, 1.0).levels.swap_remove(0))
        .collect();
    let targets: Vec<&RgbImage> = targets.iter().collect();
    let projections: Vec<Projection> = cameras
        .iter()
        .map(|c| level_projection(c.at(frame), 0))
        .collect();
    let popts = PatchOptions {
        margin: 1,
        min_cos: 0.1,
        two_sided: !closed,
        checkerboard: false,
    };
    let pattern = m.edges();
    // The convex loss: a highlight or an occluder differs between viewpoints at any offset.
    let opts = SolverOptions {
        loss: Loss::Huber,
        ..SolverOptions::default()
    };
    let cost = |k: i32| -> Option<f64> {
        let d = k as f64 / per_unit;
        let x: Vec<Point3<f64>> = m
            .positions
            .iter()
            .zip(&normals)
            .map(|(p, n)| p + n * d)
            .collect();
        let mut set = cross_patches(&x, &m.triangles, &projections, &targets, &popts);
        if set.patches.is_empty() {
            return None;
        }
        let by = set.by_triangle();
        let problem = Problem {
            moving_source: Some(&x),
            ..Problem::photometric(
                &m.triangles,
                &set,
                &by,
                targets.clone(),
                projections.clone(),
                &pattern,
            )
        };
        Some(problem.cost(&x, &opts))
    };
    let costs: Vec<f64> = (-RANGE..=RANGE)
        .map(|k| cost(k).unwrap_or(f64::INFINITY))
        .collect();
    let at_zero = costs[RANGE as usize];
    if !at_zero.is_finite() {
        return None;
    }
    let (best, &c) = costs.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    // Sub-pixel: the parabola through the best offset and its neighbours.
    let mut pixels = best as f64 - RANGE as f64;
    if best > 0 && best + 1 < costs.len() {
        let (l, r) = (costs[best - 1], costs[best + 1]);
        let curve = l - 2.0 * c + r;
        if curve > 0.0 && curve.is_finite() {
            pixels += 0.5 * (l - r) / curve;
        }
    }
    Some(SurfaceOffset {
        pixels,
        length: pixels / per_unit,
        ratio: if c > 0.0 { at_zero / c } else { 1.0 },
        at_limit: best == 0 || best + 1 == costs.len(),
        closed,
    })
}

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
use serde::{Deserialize, Serialize};

/// How far along its normals the mesh would have to move for the cameras to agree best.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
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
/// The range searched, whole pixels either way (of the level compared).
const RANGE: i32 = 10;
/// The widest image [`surface_offset`] compares at full size; wider ones at a coarser level.
const CHECK_WIDTH: u32 = 1280;

/// What the scans need of a frame: the cameras' images at one pyramid level and their
/// projections there, pixels per scene unit at the mesh, and the comparison's options.
struct Frame<'a> {
    targets: Vec<&'a RgbImage>,
    projections: Vec<Projection>,
    per_unit: f64,
    opts: SolverOptions,
}

/// One offset's comparison: the mean cost per pixel over every triangle, and per triangle its
/// cost and compared pixels (weighted).
type Scanned = Option<(f64, Vec<(u32, f64, f64)>)>;

impl Frame<'_> {
    /// For offsets −RANGE..=RANGE pixels of `x` along `normals`: what the cameras' comparison
    /// gives there (`None` where no two cameras see a common triangle).
    fn scan(
        &self,
        x: &[Point3<f64>],
        normals: &[Vector3<f64>],
        triangles: &[[u32; 3]],
        edges: &[[u32; 2]],
        closed: bool,
    ) -> Vec<Scanned> {
        let popts = PatchOptions {
            margin: 1,
            min_cos: 0.1,
            two_sided: !closed,
            checkerboard: false,
        };
        (-RANGE..=RANGE)
            .map(|k| {
                let d = k as f64 / self.per_unit;
                let xk: Vec<Point3<f64>> = x.iter().zip(normals).map(|(p, n)| p + n * d).collect();
                let mut set =
                    cross_patches(&xk, triangles, &self.projections, &self.targets, &popts);
                if set.patches.is_empty() {
                    return None;
                }
                let by = set.by_triangle();
                let problem = Problem {
                    moving_source: Some(&xk),
                    ..Problem::photometric(
                        triangles,
                        &set,
                        &by,
                        self.targets.clone(),
                        self.projections.clone(),
                        edges,
                    )
                };
                let (cost, _, parts) = problem.evaluate(&xk, &self.opts, None);
                let per_triangle = by
                    .iter()
                    .zip(&parts)
                    .map(|((t, _), a)| (*t, a.cost, a.weight))
                    .collect();
                Some((cost, per_triangle))
            })
            .collect()
    }
}

/// The minimum of `costs` (indexed from −RANGE), refined by the parabola through its
/// neighbours, in pixels; its cost; and whether it is at an end of the range.
fn best_offset(costs: &[f64]) -> Option<(f64, f64, bool)> {
    let (best, &c) = costs
        .iter()
        .enumerate()
        .filter(|(_, c)| c.is_finite())
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let mut pixels = best as f64 - RANGE as f64;
    if best > 0 && best + 1 < costs.len() {
        let (l, r) = (costs[best - 1], costs[best + 1]);
        let curve = l - 2.0 * c + r;
        if curve > 0.0 && curve.is_finite() {
            pixels += 0.5 * (l - r) / curve;
        }
    }
    Some((pixels, c, best == 0 || best + 1 == costs.len()))
}

/// The comparison at pyramid `level` (of `pyramids`, blurred as the tracker's).
fn frame_of<'a>(
    cameras: &[Camera],
    frame: u32,
    pyramids: &'a [Pyramid],
    level: usize,
    x: &[Point3<f64>],
) -> Option<Frame<'a>> {
    let per_unit =
        crate::tracker::outline::pixels_per_unit(cameras, frame, x) / (1u32 << level) as f64;
    if !(per_unit.is_finite() && per_unit > 0.0) {
        return None;
    }
    Some(Frame {
        targets: pyramids.iter().map(|p| &p.levels[level]).collect(),
        projections: cameras
            .iter()
            .map(|c| level_projection(c.at(frame), level))
            .collect(),
        per_unit,
        // The convex loss: a highlight or an occluder differs between viewpoints at any offset.
        opts: SolverOptions {
            loss: Loss::Huber,
            ..SolverOptions::default()
        },
    })
}

fn pyramids(images: &[RgbImage], levels: usize) -> Vec<Pyramid> {
    images
        .par_iter()
        .map(|i| Pyramid::new(i, levels, 1.0))
        .collect()
}

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
    let normals = m.vertex_normals();
    // Large frames are compared at a coarser level (at most 1280 px wide), so that a rig of 4K
    // cameras is checked in about the time a 720p one is; offsets are still given in pixels of
    // the frames themselves.
    let widest = cameras.iter().map(|c| c.width).max().unwrap_or(0);
    let level = (0..4).find(|&l| widest >> l <= CHECK_WIDTH).unwrap_or(4);
    let pyramids = pyramids(images, level + 1);
    let f = frame_of(cameras, frame, &pyramids, level, &m.positions)?;
    let scale = (1u32 << level) as f64;
    let costs: Vec<f64> = f
        .scan(&m.positions, &normals, &m.triangles, &m.edges(), closed)
        .into_iter()
        .map(|s| s.map_or(f64::INFINITY, |(c, _)| c))
        .collect();
    let at_zero = costs[RANGE as usize];
    if !at_zero.is_finite() {
        return None;
    }
    let (pixels, c, at_limit) = best_offset(&costs)?;
    Some(SurfaceOffset {
        pixels: pixels * scale,
        length: pixels / f.per_unit,
        ratio: if c > 0.0 { at_zero / c } else { 1.0 },
        at_limit,
        closed,
    })
}

/// How far (pixels of the level scanned) a vertex's own offset may lie on the other side of the
/// mesh's as a whole before [`onto_surface`] distrusts it.
const OTHER_SIDE_PX: f64 = 2.0;

/// The median of `v` (the upper one of an even count; 0 when empty).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// A first mesh found off the surface and moved onto it before tracking
/// (`TrackOptions::onto_surface`, [`Tracker::first_mesh_moved`](crate::tracker::Tracker::first_mesh_moved)).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SurfaceMove {
    /// What the check found where the mesh was given.
    pub found: SurfaceOffset,
    /// How far the vertices moved, in scene units: the median over the vertices.
    pub median: f64,
    /// The farthest any vertex moved, in scene units.
    pub max: f64,
}

/// Rounds of [`onto_surface`] for a mesh moved before tracking (as `align --surface` does first).
const ROUNDS: usize = 3;

/// When the cameras at `frame` agree clearly better with `mesh` moved along its normals
/// ([`SurfaceOffset::is_off`]), its vertices moved onto the surface ([`onto_surface`]) and what
/// was done; `None` when the mesh lies on the surface (or the check cannot tell: fewer than two
/// cameras see it).
pub fn moved_onto_surface(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
) -> Option<(Vec<Point3<f64>>, SurfaceMove)> {
    let found = surface_offset(mesh, cameras, frame, images)?;
    if !found.is_off() {
        return None;
    }
    let moved = onto_surface(mesh, cameras, frame, images, ROUNDS);
    let mut d: Vec<f64> = moved
        .iter()
        .zip(&mesh.positions)
        .map(|(a, b)| (a - b).norm())
        .collect();
    d.sort_by(f64::total_cmp);
    let median = d.get(d.len() / 2).copied().unwrap_or(0.0);
    let max = d.last().copied().unwrap_or(0.0);
    Some((moved, SurfaceMove { found, median, max }))
}

/// `mesh` with every vertex moved along its normal onto the surface `cameras` agree on at
/// `frame` (positions, one per vertex of `mesh`). Per vertex, the offset at which its
/// triangles' cross-camera comparisons agree best (−10 to +10 px, refined by a parabola), trusted
/// only with a clear minimum (the cost 3 px to either side at least 1.2 times it, not at the end
/// of the range, not more than `OTHER_SIDE_PX` on the other side of the trusted ones' median)
/// and replaced by the median of the trusted ones in its ring; then filled in and
/// smoothed over the mesh (vertices no two cameras see take their neighbours'), and applied;
/// `rounds` times from the moved mesh, the first at half resolution (twice the reach). For a
/// mesh made from silhouettes (a visual hull), outside the surface by different amounts in
/// different places. It keeps the triangulation and the vertices' tangential placement.
pub fn onto_surface(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
    rounds: usize,
) -> Vec<Point3<f64>> {
    let (m, of_vertex) = tracked_mesh(mesh);
    let closed = m.is_closed();
    let pyramids = pyramids(images, 2);
    let mut x = m.positions.clone();
    let nv = x.len();
    let edges = m.edges();
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); nv];
    for &[a, b] in &edges {
        neighbours[a as usize].push(b);
        neighbours[b as usize].push(a);
    }
    for round in 0..rounds {
        let level = usize::from(round == 0 && rounds > 1);
        let Some(f) = frame_of(cameras, frame, &pyramids, level, &x) else {
            break;
        };
        let normals = m.with_positions(x.clone()).vertex_normals();
        let scans = f.scan(&x, &normals, &m.triangles, &edges, closed);
        // Per vertex and offset: its triangles' cost and pixels.
        let n = scans.len();
        let mut cost = vec![0.0; nv * n];
        let mut weight = vec![0.0; nv * n];
        for (k, s) in scans.iter().enumerate() {
            let Some((_, tris)) = s else { continue };
            for &(t, c, w) in tris {
                for &v in &m.triangles[t as usize] {
                    cost[v as usize * n + k] += c;
                    weight[v as usize * n + k] += w;
                }
            }
        }
        let own: Vec<Option<f64>> = (0..nv)
            .map(|v| {
                let (c, w) = (&cost[v * n..(v + 1) * n], &weight[v * n..(v + 1) * n]);
                if w.iter().any(|&w| w <= 0.0) {
                    return None;
                }
                let mean: Vec<f64> = c.iter().zip(w).map(|(c, w)| c / w).collect();
                let (p, low, at_limit) = best_offset(&mean)?;
                let i = (p.round() as i32 + RANGE) as usize;
                let clear = [i.saturating_sub(3), (i + 3).min(n - 1)]
                    .iter()
                    .all(|&j| mean[j] >= 1.2 * low);
                (!at_limit && clear).then_some(p)
            })
            .collect();
        // The mesh lies off the surface to one side (a visual hull: outside everywhere): a
        // vertex whose clear minimum is well to the other side has found something else, most
        // often the background, which two cameras see alike where a silhouette triangle has
        // been moved off the object. Not trusted.
        let side = median(own.iter().flatten().copied().collect());
        let own: Vec<Option<f64>> = own
            .into_iter()
            .map(|o| o.filter(|&p| side.abs() < 1.0 || p * side.signum() > -OTHER_SIDE_PX))
            .collect();
        let own: Vec<Option<f64>> = (0..nv)
            .map(|v| {
                own[v]?;
                let mut ring: Vec<f64> = std::iter::once(v as u32)
                    .chain(neighbours[v].iter().copied())
                    .filter_map(|u| own[u as usize])
                    .collect();
                ring.sort_by(f64::total_cmp);
                Some(ring[ring.len() / 2])
            })
            .collect();
        // Vertices without a clear minimum of their own (no two cameras see them) start from
        // the median of the trusted offsets, not from where they are, so that the smoothing
        // below fills a large unseen region (the underside, the back) with what the seen
        // surface says about the mesh, rather than leaving its middle where it was.
        let prior = median(own.iter().flatten().copied().collect());
        let mut d: Vec<f64> = own.iter().map(|o| o.unwrap_or(prior)).collect();
        for _ in 0..200 {
            d = (0..nv)
                .map(|v| {
                    let nb = &neighbours[v];
                    let sum: f64 = nb.iter().map(|&u| d[u as usize]).sum();
                    let (w_own, own_d) = match own[v] {
                        Some(o) => (1.0, o),
                        None => (0.0, 0.0),
                    };
                    let den = w_own + nb.len() as f64;
                    if den > 0.0 {
                        (w_own * own_d + sum) / den
                    } else {
                        0.0
                    }
                })
                .collect();
        }
        let step = 1.0 / f.per_unit;
        for ((p, nrm), d) in x.iter_mut().zip(&normals).zip(&d) {
            *p += nrm * (d * step);
        }
    }
    match of_vertex {
        Some(of) => of.iter().map(|&v| x[v as usize]).collect(),
        None => x,
    }
}

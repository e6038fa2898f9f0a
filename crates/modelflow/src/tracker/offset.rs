//! Whether the first mesh lies on the surface the cameras agree on. A mesh off the surface (a
//! visual hull made from silhouettes lies outside it) is tracked with a lag: every turn of the
//! object is followed short (docs/tracker.md, "The first mesh must lie on the surface"), and
//! nothing in the frames' own checks shows it. Before tracking, the mesh is moved along its
//! vertex normals by whole pixels, −10 to +10, and at each offset the cameras are compared with
//! each other as `align` compares them (each camera's pixels warped into every other camera that
//! sees the triangle); where they agree best says how far off the surface the mesh is (farther
//! than that: the valley the surface makes in the cost, found at coarser levels). An offset
//! that shifts the cameras' views relative to each other by less than a calibration's error
//! ([`MIN_DISPARITY_PX`]) is not acted on: a camera slightly off reads the same. Knows
//! patches, projections and images; not the tracker's solve.

use crate::base::{Camera, Mesh, Projection, RgbImage};
use crate::tracker::align::cross_patches;
use crate::tracker::patch::PatchOptions;
use crate::tracker::pyramid::{camera_level, level_skips, Pyramid};
use crate::tracker::sequence::{level_projection, tracked_mesh};
use crate::tracker::solve::{Loss, Problem, SolverOptions};
use nalgebra::{Point2, Point3, Vector3};
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
    /// Pixels compared between cameras where the mesh is (at the level compared).
    #[serde(default)]
    pub compared: f64,
    /// The texture of the pixels compared at the best offset over that where the mesh is
    /// (`texture`'s measure): near 0 when moving the mesh there only moves its pixels onto a
    /// plain background, which every camera sees alike.
    #[serde(default)]
    pub texture_kept: f64,
    /// How far the offset moves where one camera's view of the surface lands in another's, in
    /// pixels of the frames (`disparity_per_unit`: the median over the vertices two cameras
    /// see): what the cameras' calibration must be good to for the offset to mean the mesh, not
    /// the calibration. A wide rig turns an offset into about as much disagreement between the
    /// cameras; two cameras 12° apart turn 5 px along the normals into 1 px between them.
    /// `None` where no two cameras see a vertex well (and in a file written before it was
    /// recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disparity: Option<f64>,
}

impl SurfaceOffset {
    /// An offset worth a warning: at least `MIN_PX` pixels, where the cameras agree clearly
    /// better (`MIN_RATIO`) than where the mesh is, found from at least `MIN_COMPARED` pixels,
    /// and where the pixels compared keep at least `MIN_TEXTURE_KEPT` of their texture.
    pub fn is_off(&self) -> bool {
        self.is_off_by_images() && !self.within_calibration()
    }

    /// The cameras agree clearly better with the mesh moved along its normals (as
    /// [`SurfaceOffset::is_off`] judges), whatever the move means for the cameras'
    /// disagreement with each other: what `align --surface`, asked to, acts on.
    pub fn is_off_by_images(&self) -> bool {
        self.pixels.abs() >= MIN_PX
            && self.ratio >= MIN_RATIO
            && self.compared >= MIN_COMPARED
            && self.texture_kept >= MIN_TEXTURE_KEPT
    }

    /// The offset moves where the cameras see the surface relative to each other by less than
    /// [`MIN_DISPARITY_PX`] ([`SurfaceOffset::disparity`]): a calibration that far off (a
    /// principal point half a pixel out, a lens model slightly wrong) draws the same verdict,
    /// so the mesh as given is the better guess. On the Blender cloth sample (two cameras 12°
    /// apart) one camera's principal point moved by 1 px read as 5 px along the normals, 65
    /// times better, and the mesh moved there ended 1.76 % of its size off instead of 0.03 %.
    fn within_calibration(&self) -> bool {
        self.disparity.is_some_and(|d| d < MIN_DISPARITY_PX)
    }

    /// An offset the cameras agree on clearly better, but which moves their views of the
    /// surface relative to each other by less than a calibration's error
    /// (`MIN_DISPARITY_PX`): not acted on, and worth a note.
    pub fn explained_by_calibration(&self) -> bool {
        self.is_off_by_images() && self.within_calibration()
    }

    /// Off the surface ([`SurfaceOffset::is_off`]) by at most `MAX_MOVE` of the size
    /// (bounding-box diagonal) of the mesh checked: what [`moved_onto_surface`] moves onto it.
    /// Farther off, the mesh is not a visual hull outside the surface but misplaced (a blob
    /// turned 5° and moved 3 % of its size read as 142 px outside it, a quarter of its size),
    /// which the placement check names.
    pub fn is_off_within(&self, size: f64) -> bool {
        self.is_off() && self.length.abs() <= MAX_MOVE * size
    }
}

/// Offsets below this many pixels are not reported.
pub const MIN_PX: f64 = 1.5;
/// Nor offsets that move where the cameras see the surface relative to each other by fewer
/// pixels of the frames than this ([`SurfaceOffset::disparity`]): what a calibration's own
/// error may be.
pub const MIN_DISPARITY_PX: f64 = 1.5;
/// Nor offsets where the cameras agree less than this much better than at the mesh.
pub const MIN_RATIO: f64 = 1.5;
/// Nor offsets found from fewer pixels compared than this: two cameras that share only a few
/// pixels of a rim (the crossing preset's two cameras share 29 at 480×360) tell nothing.
pub const MIN_COMPARED: f64 = 200.0;
/// Nor offsets at which the pixels compared keep less than this share of the texture they have
/// where the mesh is. Two cameras that share only the object's rim, over a plain background:
/// moved outward, the rim's pixels land on the background, which both see alike, and the cost
/// falls to nothing (the blob seen by two cameras at 480×360: from 1.4·10⁻³ to 2·10⁻¹⁶, 59 mm
/// out, the texture kept ~0); a mesh outside the surface moved onto it gains texture instead.
pub const MIN_TEXTURE_KEPT: f64 = 0.25;
/// The range searched, whole pixels either way (of the level compared).
const RANGE: i32 = 10;
/// `RANGE` as a number to print.
pub const RANGE_PX: i32 = RANGE;
/// The widest image [`surface_offset`] compares at full size; wider ones at a coarser level.
const CHECK_WIDTH: u32 = 1280;

/// What the scans need of a frame: the cameras' images at one pyramid level and their
/// projections there, pixels per scene unit at the mesh, and the comparison's options.
pub(crate) struct Frame<'a> {
    pub(crate) targets: Vec<&'a RgbImage>,
    pub(crate) projections: Vec<Projection>,
    pub(crate) per_unit: f64,
    pub(crate) opts: SolverOptions,
    /// Only the comparisons that involve this camera (index into `targets`); all without it.
    pub(crate) involving: Option<u16>,
    /// Of each patch's pixels, every `stride`-th (1 = all).
    pub(crate) stride: usize,
}

/// One offset's comparison (`None` where no two cameras see a common triangle).
pub(crate) type Scanned = Option<Scan>;

/// What the cameras' comparison gives at one offset.
pub(crate) struct Scan {
    /// The mean cost per pixel over every triangle.
    pub(crate) cost: f64,
    /// Per triangle: its index, cost and compared pixels (weighted).
    per_triangle: Vec<(u32, f64, f64)>,
    /// The pixels compared.
    pub(crate) pixels: f64,
    /// Their texture ([`texture`]).
    texture: f64,
}

/// The texture of a comparison's pixels: per patch, the mean squared deviation of its source
/// colours from their mean, averaged over the pixels. What a plain background lacks.
fn texture(set: &crate::tracker::patch::PatchSet) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for p in &set.patches {
        let px = &set.pixels[p.start as usize..p.end as usize];
        if px.is_empty() {
            continue;
        }
        let mut mean = [0.0f64; 3];
        for s in px {
            for (m, c) in mean.iter_mut().zip(s.color) {
                *m += c as f64;
            }
        }
        let k = px.len() as f64;
        let mean = mean.map(|m| m / k);
        for s in px {
            sum += s
                .color
                .iter()
                .zip(mean)
                .map(|(&c, m)| (c as f64 - m).powi(2))
                .sum::<f64>();
        }
        n += px.len();
    }
    if n > 0 {
        sum / n as f64
    } else {
        0.0
    }
}

impl Frame<'_> {
    /// For offsets `center`−RANGE..=`center`+RANGE pixels of `x` along `normals`: what the
    /// cameras' comparison gives there (`None` where no two cameras see a common triangle).
    pub(crate) fn scan(
        &self,
        x: &[Point3<f64>],
        normals: &[Vector3<f64>],
        triangles: &[[u32; 3]],
        edges: &[[u32; 2]],
        closed: bool,
        offsets: std::ops::RangeInclusive<i32>,
    ) -> Vec<Scanned> {
        let popts = PatchOptions {
            margin: 1,
            min_cos: 0.1,
            two_sided: !closed,
            checkerboard: false,
            stride: self.stride,
        };
        offsets
            .map(|k| {
                let d = k as f64 / self.per_unit;
                let xk: Vec<Point3<f64>> = x.iter().zip(normals).map(|(p, n)| p + n * d).collect();
                let mut set =
                    cross_patches(&xk, triangles, &self.projections, &self.targets, &popts, 0);
                if let Some(c) = self.involving {
                    set.patches.retain(|p| p.camera == c || p.source == c);
                }
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
                Some(Scan {
                    cost,
                    per_triangle,
                    pixels: set.compared_pixels() as f64,
                    texture: texture(&set),
                })
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

/// The clearest valley of `costs` (indexed from −RANGE): the interior local minimum whose
/// cost is lowest against the highest cost within 3 px on its lower side (the minimum of the
/// two sides' maxima), refined by the parabola through its neighbours, in pixels, and its cost;
/// `None` without one at least `VALLEY` times as deep.
fn clearest_valley(costs: &[f64]) -> Option<(f64, f64)> {
    let n = costs.len();
    let mut best: Option<(usize, f64)> = None;
    for i in 1..n.saturating_sub(1) {
        let c = costs[i];
        if !(c.is_finite() && c > 0.0 && c < costs[i - 1] && c < costs[i + 1]) {
            continue;
        }
        let side = |r: &[f64]| {
            r.iter()
                .copied()
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max)
        };
        let depth =
            side(&costs[i.saturating_sub(3)..i]).min(side(&costs[i + 1..(i + 4).min(n)])) / c;
        if depth >= VALLEY && best.is_none_or(|(_, d)| depth > d) {
            best = Some((i, depth));
        }
    }
    let (i, _) = best?;
    let (l, c, r) = (costs[i - 1], costs[i], costs[i + 1]);
    let curve = l - 2.0 * c + r;
    let refine = if curve > 0.0 {
        0.5 * (l - r) / curve
    } else {
        0.0
    };
    Some((i as f64 - RANGE as f64 + refine, c))
}

/// How much deeper than its sides a valley of the offset scan must be to be followed.
const VALLEY: f64 = 2.0;

/// The comparison at pyramid `level` (of `pyramids`, blurred as the tracker's), between the
/// cameras whose image is not `blank` (`image::blank_images`: a black frame or a lens cap
/// compares alike with nothing, so any offset that moves the mesh out of view would look better).
/// A camera smaller than the largest is taken at the level of its own pyramid that shows the
/// scene at the same scale (`pyramid::level_skips`, as the tracker's), down to its full
/// resolution.
pub(crate) fn frame_of<'a>(
    cameras: &[Camera],
    frame: u32,
    pyramids: &'a [Pyramid],
    level: usize,
    x: &[Point3<f64>],
    blank: &[bool],
) -> Option<Frame<'a>> {
    let per_unit =
        crate::tracker::outline::pixels_per_unit(cameras, frame, x) / (1u32 << level) as f64;
    if !(per_unit.is_finite() && per_unit > 0.0) {
        return None;
    }
    let seen = |c: &usize| !blank.get(*c).copied().unwrap_or(false);
    let skips = level_skips(cameras.iter().map(|c| (c.width, c.height)));
    let at = |c: usize| camera_level(level, skips[c]).min(pyramids[c].levels.len() - 1);
    Some(Frame {
        targets: (0..pyramids.len())
            .filter(seen)
            .map(|c| &pyramids[c].levels[at(c)])
            .collect(),
        projections: (0..cameras.len())
            .filter(seen)
            .map(|c| level_projection(cameras[c].at(frame), at(c)))
            .collect(),
        per_unit,
        // The convex loss: a highlight or an occluder differs between viewpoints at any offset.
        opts: SolverOptions {
            loss: Loss::Huber,
            ..SolverOptions::default()
        },
        involving: None,
        stride: 1,
    })
}

/// The cameras' comparison with each other (each camera's pixels of `x` warped into every other
/// camera that sees the triangle, up to the gains, the convex loss), each camera `c` at its
/// pyramid level `levels[c]`: its mean cost per pixel and, per triangle compared, its index,
/// cost and weight, each camera `c` seen through `projections[c]` (full resolution) in
/// `images[c]` (that level's image, from any frame); only the comparisons that involve camera
/// `involving` (its pixels warped into the others, theirs into it). `None` when it sees no
/// triangle another camera sees. What [`surface_offset`] scans along the normals, at the mesh as
/// it is.
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn cross_scan(
    x: &[Point3<f64>],
    triangles: &[[u32; 3]],
    edges: &[[u32; 2]],
    closed: bool,
    projections: &[&Projection],
    images: &[&RgbImage],
    levels: &[usize],
    involving: usize,
) -> Option<(f64, Vec<(u32, f64, f64)>)> {
    let f = Frame {
        targets: images.to_vec(),
        projections: projections
            .iter()
            .zip(levels)
            .map(|(p, &l)| level_projection(p, l))
            .collect(),
        per_unit: 1.0,
        opts: SolverOptions {
            loss: Loss::Huber,
            ..SolverOptions::default()
        },
        involving: Some(involving as u16),
        stride: 1,
    };
    let still = vec![Vector3::zeros(); x.len()];
    f.scan(x, &still, triangles, edges, closed, 0..=0)
        .pop()
        .flatten()
        .map(|s| (s.cost, s.per_triangle))
}

/// What the cameras' comparison with each other gives about `mesh` at `frame`
/// ([`Compared`]: full resolution, each camera's pixels warped into every other camera that
/// sees the triangle, the convex loss; the cameras with a blank image left out); `None` when
/// no two cameras see a common triangle. What a verdict about the mesh's placement rests on.
pub(crate) fn compared_texture(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
) -> Option<Compared> {
    let blank = crate::base::image::blank_images(images);
    let (m, _) = tracked_mesh(mesh);
    let seen = |c: &usize| !blank.get(*c).copied().unwrap_or(false);
    let f = Frame {
        targets: (0..images.len()).filter(seen).map(|c| &images[c]).collect(),
        projections: (0..cameras.len())
            .filter(seen)
            .map(|c| cameras[c].at(frame).clone())
            .collect(),
        per_unit: 1.0,
        opts: SolverOptions {
            loss: Loss::Huber,
            ..SolverOptions::default()
        },
        involving: None,
        stride: 1,
    };
    if f.targets.len() < 2 {
        return None;
    }
    let still = vec![Vector3::zeros(); m.positions.len()];
    let s = f
        .scan(
            &m.positions,
            &still,
            &m.triangles,
            &m.edges(),
            m.is_closed(),
            0..=0,
        )
        .pop()
        .flatten()?;
    Some(Compared {
        pixels: s.pixels,
        texture: s.texture,
        cost: s.cost,
    })
}

/// What [`compared_texture`] finds where a mesh is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Compared {
    /// The pixels the cameras compare with each other.
    pub pixels: f64,
    /// Their texture ([`texture`]).
    pub texture: f64,
    /// Their mean cost per pixel.
    pub cost: f64,
}

fn pyramids(images: &[RgbImage], levels: usize) -> Vec<Pyramid> {
    images
        .par_iter()
        .map(|i| Pyramid::new(i, levels, 1.0))
        .collect()
}

/// What [`surface_offset`] and [`view_agreement`] scan from: the mesh as the tracker works on
/// it, with its normals and edges; which cameras' images are blank; and the images' pyramids
/// down to the level compared. Large frames are compared at a coarser level (at most
/// `CHECK_WIDTH` wide), so that a rig of 4K cameras is checked in about the time a 720p one
/// is; offsets are still given in pixels of the frames themselves.
pub(crate) struct ScanStart {
    pub(crate) m: Mesh,
    pub(crate) closed: bool,
    pub(crate) normals: Vec<Vector3<f64>>,
    pub(crate) edges: Vec<[u32; 2]>,
    pub(crate) blank: Vec<bool>,
    pub(crate) level: usize,
    pub(crate) pyramids: Vec<Pyramid>,
}

pub(crate) fn scan_start(mesh: &Mesh, cameras: &[Camera], images: &[RgbImage]) -> ScanStart {
    let (m, _) = tracked_mesh(mesh);
    let widest = cameras.iter().map(|c| c.width).max().unwrap_or(0);
    let level = (0..4).find(|&l| widest >> l <= CHECK_WIDTH).unwrap_or(4);
    ScanStart {
        closed: m.is_closed(),
        normals: m.vertex_normals(),
        edges: m.edges(),
        m,
        blank: crate::base::image::blank_images(images),
        level,
        pyramids: pyramids(images, level + 1),
    }
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
    let ScanStart {
        m,
        closed,
        normals,
        edges,
        blank,
        level,
        pyramids: pyramids_here,
    } = scan_start(mesh, cameras, images);
    if blank.iter().filter(|b| !**b).count() < 2 {
        return None;
    }
    let f = frame_of(cameras, frame, &pyramids_here, level, &m.positions, &blank)?;
    let scale = (1u32 << level) as f64;
    let costs_of = |f: &Frame<'_>, center: i32| -> Vec<f64> {
        f.scan(
            &m.positions,
            &normals,
            &m.triangles,
            &edges,
            closed,
            center - RANGE..=center + RANGE,
        )
        .into_iter()
        .map(|s| s.map_or(f64::INFINITY, |s| s.cost))
        .collect()
    };
    // What is compared at offset `k` alone.
    let here = |f: &Frame<'_>, k: i32| {
        f.scan(&m.positions, &normals, &m.triangles, &edges, closed, k..=k)
            .pop()
            .flatten()
    };
    let mut first = f.scan(
        &m.positions,
        &normals,
        &m.triangles,
        &edges,
        closed,
        -RANGE..=RANGE,
    );
    let costs: Vec<f64> = first
        .iter()
        .map(|s| s.as_ref().map_or(f64::INFINITY, |s| s.cost))
        .collect();
    let at_mesh = first.swap_remove(RANGE as usize)?;
    let at_zero = at_mesh.cost;
    if !at_zero.is_finite() {
        return None;
    }
    let (mut pixels, mut c, mut at_limit) = best_offset(&costs)?;
    // A best offset at the end of the range may lie further, or be a slow drift (a mesh far
    // off the surface compares nothing alike at any offset near it, and moving it one way puts
    // more of it over a background the cameras see alike). The true surface is a narrow, deep
    // valley of the cost, a few pixels wide at the level compared and wider at coarser ones:
    // coarser levels, each reaching twice as far, are searched (centred where the mesh is) for
    // a clear valley; the first found is followed back level by level to this one.
    if at_limit {
        let pyramids = pyramids(images, MAX_LEVEL + 1);
        let valley = (level + 1..=MAX_LEVEL).find_map(|coarse| {
            let fc = frame_of(cameras, frame, &pyramids, coarse, &m.positions, &blank)?;
            let (p, _) = clearest_valley(&costs_of(&fc, 0))?;
            Some((coarse, p * (1u32 << coarse) as f64))
        });
        if let Some((coarse, mut found)) = valley {
            for l in (level..coarse).rev() {
                let Some(fl) = frame_of(cameras, frame, &pyramids, l, &m.positions, &blank) else {
                    continue;
                };
                let s = (1u32 << l) as f64;
                let center = (found / s).round() as i32;
                let costs = costs_of(&fl, center);
                let Some((p, cl, lim)) = clearest_valley(&costs)
                    .map(|(p, cl)| (p, cl, false))
                    .or_else(|| best_offset(&costs))
                else {
                    continue;
                };
                found = (center as f64 + p) * s;
                if l == level {
                    (pixels, c, at_limit) = (found / s, cl, lim);
                }
            }
        }
    }
    // The verdict's check: what is compared at the offset found still has the texture it has
    // where the mesh is (`MIN_TEXTURE_KEPT`). Checked only here, not along the scans: a mesh far
    // outside the surface compares mostly background where it is, and its way to the surface
    // would be lost if the scans were weighed by texture.
    let texture_kept = match here(&f, pixels.round() as i32) {
        Some(s) if at_mesh.texture > 0.0 => s.texture / at_mesh.texture,
        Some(_) => 1.0,
        None => 0.0,
    };
    let length = pixels / f.per_unit;
    let seen = not_blank(cameras, &blank);
    let per_unit: Vec<f64> = disparity_per_unit(&seen, frame, &m.positions, &normals, closed)
        .into_iter()
        .flatten()
        .collect();
    Some(SurfaceOffset {
        pixels: pixels * scale,
        length,
        ratio: if c > 0.0 { at_zero / c } else { 1.0 },
        at_limit,
        closed,
        compared: at_mesh.pixels,
        texture_kept,
        disparity: (!per_unit.is_empty()).then(|| length.abs() * median(per_unit)),
    })
}

/// How far moving `mesh`'s vertices to `moved` (one per vertex of `mesh`) shifts where one
/// camera's view of the surface lands in another's, pixels of the frames: the RMS over the
/// vertices two cameras see well of [`disparity_per_unit`] times the move's part along the
/// vertex normal (to first order a move along the surface changes nothing the cameras compare:
/// a flat sheet's slide). The cameras whose image at `frame` is blank left out. `None` where no
/// two cameras see a vertex so.
pub(crate) fn disparity_of_move(
    mesh: &Mesh,
    moved: &[Point3<f64>],
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
) -> Option<f64> {
    let seen = not_blank(cameras, &crate::base::image::blank_images(images));
    let (m, of_vertex) = tracked_mesh(mesh);
    let normals = m.vertex_normals();
    let per_unit = disparity_per_unit(&seen, frame, &m.positions, &normals, m.is_closed());
    let (mut sum, mut n) = (0.0, 0usize);
    for (i, (p, q)) in mesh.positions.iter().zip(moved).enumerate() {
        let j = of_vertex.as_ref().map_or(i, |o| o[i] as usize);
        if let Some(d) = per_unit.get(j).copied().flatten() {
            sum += (d * normals[j].dot(&(q - p))).powi(2);
            n += 1;
        }
    }
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// The most vertices [`disparity_per_unit`] looks at (evenly spread over the mesh's own order).
const DISPARITY_VERTICES: usize = 4096;
/// The least cosine between a vertex's normal and the way to a camera for that camera to count
/// as seeing it in [`disparity_per_unit`].
const DISPARITY_MIN_COS: f64 = 0.3;

/// Whether `cam` sees the vertex at `p` with unit normal `n` at `frame`: in view, in front, and
/// facing it within `acos 0.3` (either side of an open sheet); where it sees it in the image,
/// and from which side (the sign of the normal's cosine with the way to the camera).
fn sees_vertex(
    cam: &Camera,
    frame: u32,
    p: &Point3<f64>,
    n: &Vector3<f64>,
    closed: bool,
) -> Option<(Point2<f64>, f64)> {
    let proj = cam.at(frame);
    let at = proj.project(p).filter(|q| cam.contains(q))?;
    let cos = n.dot(&(proj.center() - p).normalize());
    let facing = if closed { cos } else { cos.abs() };
    (facing >= DISPARITY_MIN_COS).then_some((at, cos.signum()))
}

/// The cameras whose image is not `blank` (`image::blank_images`).
pub(crate) fn not_blank<'a>(cameras: &'a [Camera], blank: &[bool]) -> Vec<&'a Camera> {
    cameras
        .iter()
        .zip(blank)
        .filter(|(_, b)| !**b)
        .map(|(c, _)| c)
        .collect()
}

/// Per vertex of `x` (with unit `normals`; every `k`-th, at most [`DISPARITY_VERTICES`], the
/// others `None`): how many pixels of the frames where one camera's view of the surface lands
/// in another camera moves per scene unit that the surface moves along the vertex normal. A
/// camera `s` sees the point where its ray meets the surface: moved by `δ` along the normal, the
/// surface meets the ray `δ/cos α` further along it, and another camera `c` sees that step of
/// the ray as `|J_c·r_s|·δ/cos α` pixels (its projection's derivative along the ray). The median
/// over the ordered pairs of cameras that both see the vertex in view, in front, and facing
/// (within `acos 0.3` of its normal, on the same side for an open sheet); `None` for a vertex
/// fewer than two cameras see so. Geometry alone, the projection read by finite difference.
pub(crate) fn disparity_per_unit(
    cameras: &[&Camera],
    frame: u32,
    x: &[Point3<f64>],
    normals: &[Vector3<f64>],
    closed: bool,
) -> Vec<Option<f64>> {
    let step = x.len().div_ceil(DISPARITY_VERTICES).max(1);
    let eps = 1e-4 * crate::base::mesh::bbox_diagonal(x).max(1e-300);
    x.iter()
        .zip(normals)
        .enumerate()
        .map(|(i, (p, n))| {
            if i % step != 0 || !n.iter().all(|v| v.is_finite()) || n.norm() == 0.0 {
                return None;
            }
            // The cameras that see the vertex: their projection and which side they see.
            let seeing: Vec<(&Projection, Point2<f64>, f64)> = cameras
                .iter()
                .filter_map(|cam| {
                    let (at, side) = sees_vertex(cam, frame, p, n, closed)?;
                    Some((cam.at(frame), at, side))
                })
                .collect();
            let mut d = Vec::new();
            for (s, (ps, _, side_s)) in seeing.iter().enumerate() {
                let ray = (p - ps.center()).normalize();
                let along = eps / n.dot(&ray).abs();
                for (c, (pc, at_c, side_c)) in seeing.iter().enumerate() {
                    if c == s || side_c != side_s {
                        continue;
                    }
                    if let Some(q) = pc.project(&(p + ray * along)) {
                        d.push((q - at_c).norm() / eps);
                    }
                }
            }
            (!d.is_empty()).then(|| median(d))
        })
        .collect()
}

/// How clearly two cameras' views agree about the first mesh ([`view_agreement`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairAgreement {
    /// The two cameras (indices into the scene's cameras), `a < b`.
    pub a: usize,
    pub b: usize,
    /// Their comparison's highest mean cost over its lowest as the mesh is moved −10 to +10 px
    /// along its normals: a valley where the mesh (or the surface near it) is, deep where the
    /// surface has texture; about 1 when their pixels match no better anywhere.
    pub contrast: f64,
    /// Pixels they compare where the mesh is (at the level compared).
    pub compared: f64,
}

/// Whether each pair of cameras that see the same part of the first mesh agree about it: what
/// a camera whose images are another camera's (folders swapped), or whose calibration is far
/// off (a lens model that is not its own, a pose inverted), shows before anything is tracked.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ViewAgreement {
    /// The pairs of cameras compared ([`view_agreement`]) that compare at least
    /// `MIN_COMPARED` pixels where the mesh is.
    pub pairs: Vec<PairAgreement>,
}

/// The offsets along the normals (pixels of the level compared) at which [`view_agreement`]
/// compares a pair of cameras: dense near the mesh, where the valley is, sparse farther out,
/// where the cost only has to be high.
const VIEW_OFFSETS: [i32; 13] = [-10, -8, -6, -4, -2, -1, 0, 1, 2, 4, 6, 8, 10];
/// The most partners [`view_agreement`] compares each camera with: those that see the most of
/// the mesh with it (all pairs of a rig of four; a camera that agrees with none of its three
/// closest partners agrees with no other).
const VIEW_PARTNERS: usize = 3;
/// Of each patch's pixels [`view_agreement`] compares every this many: a ratio of mean costs
/// needs no more (the contrasts of the table in docs/tracker.md within a few per cent).
const VIEW_STRIDE: usize = 4;

/// The pairs of `cameras` (indices, `i < j`) [`view_agreement`] compares: for each camera, the
/// [`VIEW_PARTNERS`] others that see the most vertices of `x` with it (in view, in front,
/// facing within `acos 0.3`; every `k`-th vertex as [`disparity_per_unit`] takes them), and none
/// that see no vertex together.
pub(crate) fn view_pairs(
    cameras: &[&Camera],
    frame: u32,
    x: &[Point3<f64>],
    normals: &[Vector3<f64>],
    closed: bool,
) -> Vec<(usize, usize)> {
    let n = cameras.len();
    let step = x.len().div_ceil(DISPARITY_VERTICES).max(1);
    let mut shared = vec![0usize; n * n];
    for (p, nv) in x.iter().zip(normals).step_by(step) {
        let sides: Vec<Option<f64>> = cameras
            .iter()
            .map(|cam| sees_vertex(cam, frame, p, nv, closed).map(|(_, side)| side))
            .collect();
        for a in 0..n {
            for b in a + 1..n {
                if sides[a].is_some() && sides[a] == sides[b] {
                    shared[a * n + b] += 1;
                    shared[b * n + a] += 1;
                }
            }
        }
    }
    let mut pairs = Vec::new();
    for a in 0..n {
        let mut partners: Vec<usize> = (0..n)
            .filter(|&b| b != a && shared[a * n + b] > 0)
            .collect();
        // Most shared first; ties by index, so the choice does not depend on anything else.
        partners.sort_by_key(|&b| (std::cmp::Reverse(shared[a * n + b]), b));
        for &b in partners.iter().take(VIEW_PARTNERS) {
            pairs.push((a.min(b), a.max(b)));
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// The least [`PairAgreement::contrast`] of two cameras that agree. Measured pairs that agree:
/// the real board's six 2.5–5.5, the Blender hard sample's three (a glossy object, a rod in
/// front of it) 1.7–8.8, synthetic clips 1.6 (two cameras that share a rim) to hundreds;
/// cameras whose images were swapped or three frames late, or whose lens model was wildly
/// wrong, 1.01–1.15 (docs/tracker.md, "Cameras that do not agree about the first mesh").
pub const AGREE_CONTRAST: f64 = 1.4;

impl ViewAgreement {
    fn agree(p: &PairAgreement) -> bool {
        p.contrast >= AGREE_CONTRAST
    }

    /// The cameras (indices, ascending) that were compared with another camera and agree with
    /// none, in a rig where some pair does agree (so the mesh and its texture can show
    /// agreement).
    pub fn disagreeing(&self) -> Vec<usize> {
        if !self.pairs.iter().any(Self::agree) {
            return Vec::new();
        }
        let mut cams: Vec<usize> = self.pairs.iter().flat_map(|p| [p.a, p.b]).collect();
        cams.sort_unstable();
        cams.dedup();
        cams.retain(|&c| {
            !self
                .pairs
                .iter()
                .any(|p| (p.a == c || p.b == c) && Self::agree(p))
        });
        cams
    }

    /// Cameras were compared, and no two of them agree: the surface shows too little texture
    /// for them to, or the calibration or the images are wrong for all of them (a two-camera rig
    /// cannot tell which camera).
    pub fn none_agree(&self) -> bool {
        !self.pairs.is_empty() && !self.pairs.iter().any(Self::agree)
    }
}

/// Whether the cameras' views agree about `mesh` at `frame` ([`ViewAgreement`]): pairs of
/// cameras (blank images left out; each camera with its `VIEW_PARTNERS` partners,
/// `view_pairs`) compared as [`surface_offset`] compares all of them (each one's pixels, every
/// `VIEW_STRIDE`-th, warped into the other through the mesh, up to the gains, the convex
/// loss, at most 1280 px wide) with the mesh moved along its normals by `VIEW_OFFSETS`; pairs
/// that compare fewer than `MIN_COMPARED` pixels where the mesh is are left out.
pub fn view_agreement(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
) -> ViewAgreement {
    let mut out = ViewAgreement::default();
    if cameras.len() < 2 || images.len() != cameras.len() {
        return out;
    }
    let z = scan_start(mesh, cameras, images);
    let (m, normals, edges, closed) = (&z.m, &z.normals, &z.edges, z.closed);
    let Some(all) = frame_of(cameras, frame, &z.pyramids, z.level, &m.positions, &z.blank) else {
        return out;
    };
    let seen: Vec<usize> = (0..cameras.len()).filter(|&c| !z.blank[c]).collect();
    let pairs = view_pairs(
        &not_blank(cameras, &z.blank),
        frame,
        &m.positions,
        normals,
        closed,
    );
    for (i, j) in pairs {
        let (a, b) = (seen[i], seen[j]);
        let f = Frame {
            targets: vec![all.targets[i], all.targets[j]],
            projections: vec![all.projections[i].clone(), all.projections[j].clone()],
            per_unit: all.per_unit,
            opts: all.opts,
            involving: None,
            stride: VIEW_STRIDE,
        };
        let scan = |k: i32| {
            f.scan(&m.positions, normals, &m.triangles, edges, closed, k..=k)
                .pop()
                .flatten()
        };
        // Where the mesh is first: a pair that shares too little of it is not scanned on.
        let at_mesh = scan(0);
        let compared = at_mesh.as_ref().map_or(0.0, |s| s.pixels);
        if compared < MIN_COMPARED {
            continue;
        }
        let costs: Vec<f64> = VIEW_OFFSETS
            .iter()
            .filter(|&&k| k != 0)
            .map(|&k| scan(k))
            .chain([at_mesh])
            .flatten()
            .map(|s| s.cost)
            .filter(|c| c.is_finite())
            .collect();
        let lo = costs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = costs.iter().copied().fold(0.0, f64::max);
        if costs.len() > VIEW_OFFSETS.len() / 2 && lo > 0.0 {
            out.pairs.push(PairAgreement {
                a,
                b,
                contrast: hi / lo,
                compared,
            });
        }
    }
    out
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

/// The farthest [`moved_onto_surface`] moves a mesh, as a share of its bounding box's diagonal
/// (the test `track_cli::a_mesh_off_the_surface_is_moved_onto_it_before_tracking_and_named`
/// moves one 10 % of it out and back).
pub const MAX_MOVE: f64 = 0.25;

/// Rounds of [`onto_surface`] for a mesh moved before tracking (as `align --surface` does first).
const ROUNDS: usize = 3;
/// The offset (pixels of the level scanned) that [`onto_surface`]'s first round finds well
/// inside its range of ±`RANGE`; a mesh found farther off is moved by the offset first.
const REACH_PX: f64 = 8.0;
/// The coarsest level the offset searches go to.
const MAX_LEVEL: usize = 5;

/// The pyramid level of each round of [`onto_surface`]: with more than one round, the first at
/// half the finest's resolution (twice the reach), the rest at the finest. The finest is full
/// resolution up to twice `CHECK_WIDTH` wide (a 1080p rig) and coarser beyond (half resolution
/// for 4K: a 1920-pixel-wide comparison places a vertex as well as a 1080p rig does, at a
/// quarter of the full frames' cost).
fn round_levels(widest: u32, rounds: usize) -> Vec<usize> {
    let finest = (0..MAX_LEVEL)
        .find(|&l| widest >> l <= 2 * CHECK_WIDTH)
        .unwrap_or(MAX_LEVEL);
    (0..rounds)
        .map(|r| {
            if r == 0 && rounds > 1 {
                finest + 1
            } else {
                finest
            }
        })
        .collect()
}

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
    // Farther off than a quarter of its size, the mesh is not a visual hull outside the
    // surface: it is misplaced (`align`), or what the cameras agree on there is not the object
    // (a black card over half of one camera's first frame drew a limb 61 % of its size inward).
    if !found.is_off_within(mesh.bbox_diagonal()) {
        return None;
    }
    // Misplaced as a whole, it reads off along its normals too: left as it is, for the
    // placement check to name, rather than reshaped.
    if crate::tracker::align::misplaced_instead(&found, mesh, cameras, frame, images).is_some() {
        return None;
    }
    Some(moved_onto(mesh, cameras, frame, images, found))
}

/// [`moved_onto_surface`] from the first-mesh check already made on the same mesh, cameras,
/// frame and images ([`FirstMeshCheck`](crate::tracker::FirstMeshCheck), as `track` makes it to
/// warn before tracking): the same result without measuring the offset and the placement again.
pub(crate) fn moved_onto_surface_as_checked(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
    check: &crate::tracker::FirstMeshCheck,
) -> Option<(Vec<Point3<f64>>, SurfaceMove)> {
    let found = *check.off_surface(mesh.bbox_diagonal())?;
    Some(moved_onto(mesh, cameras, frame, images, found))
}

/// `mesh` moved onto the surface from `found`, the offset read off where it is given, and what
/// was done.
fn moved_onto(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
    found: SurfaceOffset,
) -> (Vec<Point3<f64>>, SurfaceMove) {
    let moved = onto_surface(mesh, cameras, frame, images, ROUNDS, Some(&found));
    let mut d: Vec<f64> = moved
        .iter()
        .zip(&mesh.positions)
        .map(|(a, b)| (a - b).norm())
        .collect();
    d.sort_by(f64::total_cmp);
    let median = d.get(d.len() / 2).copied().unwrap_or(0.0);
    let max = d.last().copied().unwrap_or(0.0);
    (moved, SurfaceMove { found, median, max })
}

/// `mesh` with every vertex moved along its normal onto the surface `cameras` agree on at
/// `frame` (positions, one per vertex of `mesh`). Per vertex, the offset at which its
/// triangles' cross-camera comparisons agree best (−10 to +10 px, refined by a parabola), trusted
/// only with a clear minimum (the cost 3 px to either side at least 1.2 times it, not at the end
/// of the range, not more than `OTHER_SIDE_PX` on the other side of the trusted ones' median)
/// and replaced by the median of the trusted ones in its ring; then filled in and
/// smoothed over the mesh (vertices no two cameras see take their neighbours'), and applied;
/// `rounds` times (at least; `round_levels`) from the moved mesh, coarse to fine. `found`
/// ([`surface_offset`]'s result for the mesh, when known): an offset beyond the first round's
/// reach (more than `REACH_PX` pixels there) is applied to every vertex first, so that the
/// rounds scan around the surface rather than around a mesh whose neighbourhood compares
/// nothing alike. For a mesh made from silhouettes (a visual hull), outside the surface by
/// different amounts in different places. It keeps the triangulation and the vertices'
/// tangential placement.
pub fn onto_surface(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
    rounds: usize,
    found: Option<&SurfaceOffset>,
) -> Vec<Point3<f64>> {
    let blank = crate::base::image::blank_images(images);
    let (m, of_vertex) = tracked_mesh(mesh);
    let closed = m.is_closed();
    let widest = cameras.iter().map(|c| c.width).max().unwrap_or(0);
    let levels = round_levels(widest, rounds);
    let pyramids = pyramids(images, levels.iter().max().map_or(1, |l| l + 1));
    let mut x = m.positions.clone();
    let first = levels.first().copied().unwrap_or(0);
    if let Some(f) = found.filter(|f| f.pixels.abs() / (1u32 << first) as f64 > REACH_PX) {
        let normals = m.vertex_normals();
        for (p, n) in x.iter_mut().zip(&normals) {
            *p += n * f.length;
        }
    }
    let nv = x.len();
    let edges = m.edges();
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); nv];
    for &[a, b] in &edges {
        neighbours[a as usize].push(b);
        neighbours[b as usize].push(a);
    }
    for &level in &levels {
        let Some(f) = frame_of(cameras, frame, &pyramids, level, &x, &blank) else {
            break;
        };
        let normals = m.with_positions(x.clone()).vertex_normals();
        let scans = f.scan(&x, &normals, &m.triangles, &edges, closed, -RANGE..=RANGE);
        // Per vertex and offset: its triangles' cost and pixels.
        let n = scans.len();
        let mut cost = vec![0.0; nv * n];
        let mut weight = vec![0.0; nv * n];
        for (k, s) in scans.iter().enumerate() {
            let Some(s) = s else { continue };
            for &(t, c, w) in &s.per_triangle {
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

#[cfg(test)]
mod tests {
    use super::{best_offset, clearest_valley, round_levels};

    #[test]
    fn a_camera_of_half_the_size_is_compared_at_its_level_of_the_same_scale() {
        // A 64×48 camera and one of 32×24 that sees exactly what it sees (its projection
        // downscaled by 2): at level 1 the large one is taken at its level 1 and the small one at
        // its full resolution, both 32×24, and every point lands on the same pixel in both.
        use super::frame_of;
        use crate::base::{Camera, Projection, RgbImage};
        use crate::tracker::pyramid::Pyramid;
        use nalgebra::{Matrix3, Point3, Vector3};
        let k = Matrix3::new(60.0, 0.0, 31.5, 0.0, 60.0, 23.5, 0.0, 0.0, 1.0);
        let pose =
            Projection::from_krt(&k, &Matrix3::identity(), &Vector3::new(0.0, 0.0, 2.0)).unwrap();
        let cams = [
            Camera::fixed("big", 64, 48, pose.clone()),
            Camera::fixed("small", 32, 24, pose.downscaled(2)),
        ];
        let texture = |w: usize, h: usize| {
            RgbImage::from_fn(w, h, |x, y| [((x * 7 + y * 3) % 5) as f32 / 5.0; 3])
        };
        let pyramids = [
            Pyramid::new(&texture(64, 48), 2, 1.0),
            Pyramid::new(&texture(32, 24), 2, 1.0),
        ];
        let x = [
            Point3::new(-0.2, -0.2, 0.0),
            Point3::new(0.2, -0.2, 0.0),
            Point3::new(0.0, 0.2, 0.0),
        ];
        for (level, small_level) in [(1, 0), (0, 0)] {
            let f = frame_of(&cams, 0, &pyramids, level, &x, &[false, false]).unwrap();
            assert!(std::ptr::eq(f.targets[0], &pyramids[0].levels[level]));
            assert!(std::ptr::eq(f.targets[1], &pyramids[1].levels[small_level]));
            if level == 1 {
                for p in &x {
                    let (a, b) = (f.projections[0].project(p), f.projections[1].project(p));
                    assert!((a.unwrap() - b.unwrap()).norm() < 1e-9, "{a:?} {b:?}");
                }
            }
        }
    }

    #[test]
    fn the_rounds_end_at_a_comparison_as_fine_as_a_1080p_rigs() {
        // 640 px and 1080p: half resolution, then full twice.
        assert_eq!(round_levels(640, 3), [1, 0, 0]);
        assert_eq!(round_levels(1920, 3), [1, 0, 0]);
        // 4K: a quarter, then half resolution; no full-size round.
        assert_eq!(round_levels(3840, 3), [2, 1, 1]);
        // One round (a refinement): the finest level only.
        assert_eq!(round_levels(640, 1), [0]);
        assert_eq!(round_levels(3840, 1), [1]);
        assert_eq!(round_levels(7680, 2), [3, 2]);
        assert!(round_levels(640, 0).is_empty());
    }

    #[test]
    fn a_clear_valley_is_found_beside_a_drift_and_a_shallow_one_is_not() {
        // A drift falling toward +10 (the best offset at the end of the range) with a narrow,
        // deep valley at −6.
        let mut costs: Vec<f64> = (0..21).map(|i| 0.02 - 0.0003 * i as f64).collect();
        costs[3] = 0.002;
        costs[4] = 0.008;
        costs[2] = 0.009;
        let (p, c) = clearest_valley(&costs).unwrap();
        assert!((p + 7.0).abs() < 0.5 && c == 0.002, "{p} {c}");
        // Here the valley is also the global minimum, inside the range.
        assert!(!best_offset(&costs).unwrap().2);
        // The drift alone has no valley.
        let drift: Vec<f64> = (0..21).map(|i| 0.02 - 0.0003 * i as f64).collect();
        assert_eq!(clearest_valley(&drift), None);
        // Nor has noise on it (a dip of 10 %).
        let mut noisy = drift.clone();
        noisy[8] *= 0.9;
        assert_eq!(clearest_valley(&noisy), None);
    }
}

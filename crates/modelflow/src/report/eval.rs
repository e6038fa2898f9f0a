//! Scoring a run (its frame meshes, as `run::read_run` reads them) against a scene's ground
//! truth: per frame, the RMS and maximum vertex distance to the ground-truth mesh, also as a
//! percentage of the scene mesh's size (its bounding-box diagonal); and the same over the
//! *seen* vertices only, those of a triangle that owns at least one pixel of some camera's
//! z-buffered view of the ground truth at that frame (what the images can tell; the rest is the
//! regularisers' guess). Where the error lies: per number of cameras that see a vertex (none,
//! one, two, ...), and split into the whole mesh's misplacement (the rigid motion that best maps
//! the run's mesh onto the truth) and its misshaping (what is left after it).

use crate::base::camera::Camera;
use crate::base::mesh::Mesh;
use crate::base::raster::{rasterize, NONE};
use crate::base::units::Units;
use crate::error::{Error, Result};
use crate::input::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;

/// Error of one frame, in world units (and percent of the scene mesh's bounding-box diagonal).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameError {
    pub frame: u32,
    /// sqrt(mean over vertices of the squared distance to the ground truth).
    pub rms: f64,
    pub rms_pct: f64,
    /// Largest vertex distance.
    pub max: f64,
    /// Median and 90th percentile of the vertex distances (how the error spreads over the mesh).
    pub median: f64,
    pub p90: f64,
    /// The RMS over the vertices seen by some camera in the ground truth (0 when none is).
    pub seen_rms: f64,
    pub seen_rms_pct: f64,
    /// How many vertices that is.
    pub seen: usize,
    /// How much of the truth's motion since the previous frame the run made, over those
    /// vertices: `Σ (run's step · truth's step) / Σ |truth's step|²`. 1: all of it; below 1 the
    /// run lags (and, frame after frame, drifts); above 1 it overshoots. `None` for the first
    /// frame, and where the truth did not move (its step under 10⁻⁹ of the scale).
    pub followed: Option<f64>,
    /// The RMS left after the rigid motion that best maps the run's mesh onto the truth (least
    /// squares over all vertices) is taken out: the error of the shape alone. 0 for a run that is
    /// the truth moved rigidly; equal to `rms` when the run's best placement is where it is.
    pub shape_rms: f64,
    pub shape_rms_pct: f64,
    /// That rigid motion: its rotation, degrees, and the distance between the run's and the
    /// truth's centroids (the misplacement of the whole mesh).
    pub pose_turn_deg: f64,
    pub pose_shift: f64,
    /// The RMS over the vertices seen by each number of cameras (in the truth; only the counts
    /// that occur, fewest cameras first).
    pub by_views: Vec<ViewsError>,
}

/// The error over the vertices that `cameras` cameras see (see [`FrameError::by_views`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ViewsError {
    /// How many cameras see them (0: none; their place is the regularisers' guess).
    pub cameras: usize,
    /// How many vertices that is.
    pub vertices: usize,
    pub rms: f64,
    pub rms_pct: f64,
}

/// [`ViewsError`] over a run: for each number of cameras, the mean over the frames where some
/// vertex is seen by that many of the per-frame RMS.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ViewsSummary {
    pub cameras: usize,
    /// The mean number of such vertices per frame (over all frames).
    pub vertices_mean: f64,
    pub rms_mean: f64,
    pub rms_mean_pct: f64,
}

/// The score of a run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EvalReport {
    pub frames: usize,
    pub per_frame: Vec<FrameError>,
    /// Mean of the per-frame RMS.
    pub rms_mean: f64,
    /// RMS of the last frame.
    pub rms_final: f64,
    pub rms_mean_pct: f64,
    pub rms_final_pct: f64,
    /// Mean of the per-frame RMS over the seen vertices, and its last value.
    pub seen_rms_mean: f64,
    pub seen_rms_final: f64,
    pub seen_rms_mean_pct: f64,
    pub seen_rms_final_pct: f64,
    /// The median over frames of [`FrameError::followed`] (`None` when no frame has one).
    pub followed_median: Option<f64>,
    /// Mean and last value of [`FrameError::shape_rms`].
    pub shape_rms_mean: f64,
    pub shape_rms_final: f64,
    pub shape_rms_mean_pct: f64,
    pub shape_rms_final_pct: f64,
    /// Means over the frames of [`FrameError::pose_turn_deg`] and [`FrameError::pose_shift`].
    pub pose_turn_deg_mean: f64,
    pub pose_shift_mean: f64,
    /// [`FrameError::by_views`] over the run.
    pub by_views: Vec<ViewsSummary>,
    /// The bounding-box diagonal of the scene mesh (frame `first`), the 100 % of the `_pct` values.
    pub scale: f64,
    /// The unit of every length above (the scene's `units`; `null`: scene units). Lengths here
    /// stay in the scene's unit; the table and the report show them in mm when it is known.
    pub units: Option<Units>,
}

/// Compares a run (as from `read_run`) with the scene's ground truth, frame by frame over all
/// the scene's frames. Every scene frame must be in the run and no other.
pub fn evaluate(scene: &Scene, run: &[(u32, Mesh)]) -> Result<EvalReport> {
    if scene.ground_truth.is_none() {
        return Err(Error::invalid(
            &scene.path,
            "ground_truth",
            "the scene has no ground truth to evaluate against",
        ));
    }
    if let Some((f, _)) = run.iter().find(|(f, _)| !scene.frames().contains(f)) {
        return Err(Error::mismatch(
            "the run's frames",
            format!("the scene's frames {}..={}", scene.first, scene.last),
            format!("a mesh for frame {f}"),
        ));
    }
    let have: std::collections::BTreeSet<u32> = run.iter().map(|(f, _)| *f).collect();
    let missing: Vec<u32> = scene.frames().filter(|f| !have.contains(f)).collect();
    if !missing.is_empty() {
        let mut shown: Vec<String> = missing.iter().take(10).map(|f| f.to_string()).collect();
        if missing.len() > 10 {
            shown.push(format!("... ({} frames in all)", missing.len()));
        }
        return Err(Error::mismatch(
            "the run's frames",
            format!(
                "a mesh for every scene frame {}..={}",
                scene.first, scene.last
            ),
            format!("no mesh for frame(s) {}", shown.join(", ")),
        ));
    }
    let scale = scene.mesh.bbox_diagonal();
    let by_frame: std::collections::BTreeMap<u32, &Mesh> =
        run.iter().map(|(f, m)| (*f, m)).collect();
    let frame_error = |frame: u32, truth: &Mesh, before: Option<&Mesh>| -> Result<FrameError> {
        let mesh = by_frame[&frame];
        if mesh.positions.len() != truth.positions.len() {
            return Err(Error::mismatch(
                format!("frame {frame}: the run's mesh"),
                format!("{} vertices (as the ground truth)", truth.positions.len()),
                format!("{} vertices", mesh.positions.len()),
            ));
        }
        let views = views_of_vertices(&scene.cameras, frame, truth);
        let seen: Vec<bool> = views.iter().map(|&v| v > 0).collect();
        let followed = match (frame.checked_sub(1), before) {
            (Some(p), Some(before)) => followed(
                &by_frame[&p].positions,
                mesh,
                &before.positions,
                truth,
                &seen,
                scale,
            ),
            _ => None,
        };
        let (mut sum, mut max, mut seen_sum, mut seen_count) = (0.0f64, 0.0f64, 0.0, 0);
        let mut d2s = Vec::with_capacity(mesh.positions.len());
        for ((a, b), &s) in mesh.positions.iter().zip(&truth.positions).zip(&seen) {
            let d2 = (a - b).norm_squared();
            d2s.push(d2);
            sum += d2;
            max = max.max(d2);
            if s {
                seen_sum += d2;
                seen_count += 1;
            }
        }
        let rms = (sum / mesh.positions.len() as f64).sqrt();
        let seen_rms = (seen_sum / seen_count.max(1) as f64).sqrt();
        let most = views.iter().copied().max().unwrap_or(0) as usize;
        let mut groups = vec![(0usize, 0.0f64); most + 1];
        for (&k, d2) in views.iter().zip(&d2s) {
            groups[k as usize].0 += 1;
            groups[k as usize].1 += d2;
        }
        let by_views = groups
            .iter()
            .enumerate()
            .filter(|(_, (n, _))| *n > 0)
            .map(|(cameras, &(n, sum))| {
                let rms = (sum / n as f64).sqrt();
                ViewsError {
                    cameras,
                    vertices: n,
                    rms,
                    rms_pct: pct(rms, scale),
                }
            })
            .collect();
        let fit = rigid_fit(&mesh.positions, &truth.positions);
        let shape_rms = fit.rms;
        d2s.sort_by(f64::total_cmp);
        let quantile = |q: f64| {
            d2s.get(((d2s.len().max(1) - 1) as f64 * q).round() as usize)
                .map_or(0.0, |d2| d2.sqrt())
        };
        Ok(FrameError {
            frame,
            rms,
            rms_pct: pct(rms, scale),
            max: max.sqrt(),
            median: quantile(0.5),
            p90: quantile(0.9),
            seen_rms,
            seen_rms_pct: pct(seen_rms, scale),
            seen: seen_count,
            followed,
            shape_rms,
            shape_rms_pct: pct(shape_rms, scale),
            pose_turn_deg: fit.turn_deg,
            pose_shift: fit.shift,
            by_views,
        })
    };
    // Runs of consecutive frames in parallel, each read in order: a frame's ground truth is the
    // next frame's "before" (for `followed`), so only a run's first frame reads one twice.
    let load = |f: u32| {
        scene
            .ground_truth(f)
            .unwrap_or_else(|| unreachable!("checked above"))
    };
    let frames: Vec<u32> = scene.frames().collect();
    let per_frame: Vec<FrameError> = frames
        .par_chunks(EVAL_CHUNK)
        .map(|chunk| {
            let mut before: Option<Mesh> = match chunk[0].checked_sub(1) {
                Some(p) if by_frame.contains_key(&p) => Some(load(p)?),
                _ => None,
            };
            let mut out = Vec::with_capacity(chunk.len());
            for &frame in chunk {
                let truth = load(frame)?;
                out.push(frame_error(frame, &truth, before.as_ref())?);
                before = Some(truth);
            }
            Ok(out)
        })
        .collect::<Result<Vec<Vec<FrameError>>>>()?
        .into_iter()
        .flatten()
        .collect();
    let rms_mean = per_frame.iter().map(|e| e.rms).sum::<f64>() / per_frame.len() as f64;
    let rms_final = per_frame.last().map_or(0.0, |e| e.rms);
    let seen_rms_mean = per_frame.iter().map(|e| e.seen_rms).sum::<f64>() / per_frame.len() as f64;
    let seen_rms_final = per_frame.last().map_or(0.0, |e| e.seen_rms);
    let mut f: Vec<f64> = per_frame.iter().filter_map(|e| e.followed).collect();
    f.sort_by(f64::total_cmp);
    let followed_median = (!f.is_empty()).then(|| {
        let m = f.len() / 2;
        if f.len() % 2 == 1 {
            f[m]
        } else {
            0.5 * (f[m - 1] + f[m])
        }
    });
    let frames_n = per_frame.len().max(1) as f64;
    let mean_of = |f: &dyn Fn(&FrameError) -> f64| per_frame.iter().map(f).sum::<f64>() / frames_n;
    let shape_rms_mean = mean_of(&|e| e.shape_rms);
    let shape_rms_final = per_frame.last().map_or(0.0, |e| e.shape_rms);
    let most = per_frame
        .iter()
        .flat_map(|e| e.by_views.iter().map(|v| v.cameras))
        .max();
    let by_views: Vec<ViewsSummary> = (0..most.map_or(0, |m| m + 1))
        .filter_map(|cameras| {
            let groups: Vec<&ViewsError> = per_frame
                .iter()
                .filter_map(|e| e.by_views.iter().find(|v| v.cameras == cameras))
                .collect();
            if groups.is_empty() {
                return None;
            }
            let rms_mean = groups.iter().map(|v| v.rms).sum::<f64>() / groups.len() as f64;
            Some(ViewsSummary {
                cameras,
                vertices_mean: groups.iter().map(|v| v.vertices as f64).sum::<f64>() / frames_n,
                rms_mean,
                rms_mean_pct: pct(rms_mean, scale),
            })
        })
        .collect();
    Ok(EvalReport {
        shape_rms_mean,
        shape_rms_final,
        shape_rms_mean_pct: pct(shape_rms_mean, scale),
        shape_rms_final_pct: pct(shape_rms_final, scale),
        pose_turn_deg_mean: mean_of(&|e| e.pose_turn_deg),
        pose_shift_mean: mean_of(&|e| e.pose_shift),
        by_views,
        frames: per_frame.len(),
        per_frame,
        rms_mean,
        rms_final,
        rms_mean_pct: pct(rms_mean, scale),
        rms_final_pct: pct(rms_final, scale),
        seen_rms_mean,
        seen_rms_final,
        seen_rms_mean_pct: pct(seen_rms_mean, scale),
        seen_rms_final_pct: pct(seen_rms_final, scale),
        followed_median,
        scale,
        units: scene.units,
    })
}

/// [`FrameError::followed`] from the run's and the truth's positions at the previous frame and
/// this one, over the vertices `seen` (all of them when none is); `None` when the truth's step is
/// under 10⁻⁹ of `scale` (RMS) or a vertex count differs.
fn followed(
    run_before: &[nalgebra::Point3<f64>],
    run: &Mesh,
    truth_before: &[nalgebra::Point3<f64>],
    truth: &Mesh,
    seen: &[bool],
    scale: f64,
) -> Option<f64> {
    let n = truth.positions.len();
    if [
        run_before.len(),
        run.positions.len(),
        truth_before.len(),
        seen.len(),
    ]
    .iter()
    .any(|&m| m != n)
    {
        return None;
    }
    let any = seen.iter().any(|&s| s);
    let (mut dot, mut norm, mut count) = (0.0f64, 0.0f64, 0usize);
    for i in (0..n).filter(|&i| !any || seen[i]) {
        let dt = truth.positions[i] - truth_before[i];
        let dk = run.positions[i] - run_before[i];
        dot += dk.dot(&dt);
        norm += dt.norm_squared();
        count += 1;
    }
    let floor = 1e-9 * scale;
    (count > 0 && norm > floor * floor * count as f64).then(|| dot / norm)
}

/// Frames per task of [`evaluate`] (each task reads its frames' ground truth in order).
const EVAL_CHUNK: usize = 8;

/// How many cameras see each vertex of `truth` (the mesh at `frame`): a camera sees the vertices
/// of a triangle that owns at least one pixel of its z-buffered index buffer.
fn views_of_vertices(cameras: &[Camera], frame: u32, truth: &Mesh) -> Vec<u16> {
    let mut views = vec![0u16; truth.positions.len()];
    for cam in cameras {
        let mut seen = vec![false; truth.positions.len()];
        let ib = rasterize(
            &truth.positions,
            &truth.triangles,
            cam.at(frame),
            cam.width as usize,
            cam.height as usize,
        );
        let mut owns = vec![false; truth.triangles.len()];
        for &t in ib.owners().iter().filter(|&&t| t != NONE) {
            owns[t as usize] = true;
        }
        for (tri, _) in truth.triangles.iter().zip(&owns).filter(|(_, &o)| o) {
            for &v in tri {
                seen[v as usize] = true;
            }
        }
        for (n, s) in views.iter_mut().zip(seen) {
            *n += s as u16;
        }
    }
    views
}

/// The rigid motion that best maps `run` onto `truth` (`base::mesh::best_motion`, no scale)
/// and what it leaves.
struct RigidFit {
    /// RMS distance from the moved run to the truth.
    rms: f64,
    /// The motion's rotation angle, degrees.
    turn_deg: f64,
    /// The distance between the two centroids.
    shift: f64,
}

fn rigid_fit(run: &[nalgebra::Point3<f64>], truth: &[nalgebra::Point3<f64>]) -> RigidFit {
    let n = run.len().min(truth.len());
    if n == 0 {
        return RigidFit {
            rms: 0.0,
            turn_deg: 0.0,
            shift: 0.0,
        };
    }
    let (run, truth) = (&run[..n], &truth[..n]);
    let (rotation, t, _) = crate::base::mesh::best_motion(run, truth, false);
    let sum: f64 = run
        .iter()
        .zip(truth)
        .map(|(a, b)| (rotation * a.coords + t - b.coords).norm_squared())
        .sum();
    let cos = ((rotation.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    let shift = crate::base::mesh::centroid(truth) - crate::base::mesh::centroid(run);
    RigidFit {
        rms: (sum / n as f64).sqrt(),
        turn_deg: cos.acos().to_degrees(),
        shift: shift.norm(),
    }
}

fn pct(v: f64, scale: f64) -> f64 {
    if scale > 0.0 {
        100.0 * v / scale
    } else {
        0.0
    }
}

/// RMS distance from `points` to the surface of `truth` (the closest point on any of its
/// triangles), over the points that lie *over* it: a point whose closest point is on the
/// truth's border (an open mesh's outline) hangs past its edge, and is counted apart. How far a
/// mesh is from the true surface, whichever point of it is which: `align` is scored with it
/// beside the vertex error, since the images fix where a surface is but not how it slides along
/// itself. A point counts as over the surface unless its closest point is on the border *and*
/// it is further from it sideways (in that triangle's plane) than along its normal. Returns
/// `(rms, points over the surface)`, `None` when no point is over it. Brute force over the
/// triangles, in parallel over the points (written by hand: a check, run on one frame).
pub fn surface_rms(points: &[nalgebra::Point3<f64>], truth: &Mesh) -> Option<(f64, usize)> {
    let tris: Vec<[nalgebra::Point3<f64>; 3]> = truth
        .triangles
        .iter()
        .map(|t| t.map(|v| truth.positions[v as usize]))
        .collect();
    // Border edges (one triangle) and their vertices.
    let border_edges: std::collections::HashSet<[u32; 2]> =
        truth.border_edges().into_iter().map(|(e, _)| e).collect();
    let mut border = vec![false; truth.positions.len()];
    for [a, b] in &border_edges {
        border[*a as usize] = true;
        border[*b as usize] = true;
    }
    // Per point in parallel, summed in order (the same result whatever the thread count).
    let per_point: Vec<Option<f64>> = points
        .par_iter()
        .map(|p| {
            let mut best = (f64::INFINITY, false);
            for (t, tri) in truth.triangles.iter().zip(&tris) {
                let (q, feature) = closest_on_triangle(p, tri);
                let d = (q - p).norm_squared();
                if d < best.0 {
                    // On a border edge or vertex, and more beside the surface than above it:
                    // past the surface's outline.
                    let on_border = match feature {
                        Feature::Inside => false,
                        Feature::Vertex(i) => border[t[i] as usize],
                        Feature::Edge(i, j) => {
                            let (a, b) = (t[i], t[j]);
                            border_edges.contains(&[a.min(b), a.max(b)])
                        }
                    };
                    let past = on_border && {
                        let n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
                        let off = p - q;
                        match n.try_normalize(1e-300) {
                            Some(n) => {
                                let along = off.dot(&n).abs();
                                (off - n * off.dot(&n)).norm() > along
                            }
                            None => true,
                        }
                    };
                    best = (d, past);
                }
            }
            (!best.1 && best.0.is_finite()).then_some(best.0)
        })
        .collect();
    let over: Vec<f64> = per_point.into_iter().flatten().collect();
    let (sum, n) = (over.iter().sum::<f64>(), over.len());
    (n > 0).then(|| ((sum / n as f64).sqrt(), n))
}

/// Where on a triangle its closest point to a query lies.
#[derive(Clone, Copy)]
enum Feature {
    Inside,
    Vertex(usize),
    Edge(usize, usize),
}

/// The point of triangle `t` closest to `p` (Ericson, Real-Time Collision Detection, §5.1.5).
fn closest_on_triangle(
    p: &nalgebra::Point3<f64>,
    t: &[nalgebra::Point3<f64>; 3],
) -> (nalgebra::Point3<f64>, Feature) {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Feature::Vertex(0));
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (a + ab * (d1 / (d1 - d3)), Feature::Edge(0, 1));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (a + ac * (d2 / (d2 - d6)), Feature::Edge(0, 2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Feature::Edge(1, 2));
    }
    let denom = va + vb + vc;
    if denom.abs() < 1e-300 {
        return (a, Feature::Vertex(0));
    }
    (a + ab * (vb / denom) + ac * (vc / denom), Feature::Inside)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::camera::{look_at, Projection};
    use crate::base::mesh::grid;
    use nalgebra::{Matrix3, Point3, Vector3};

    #[test]
    fn surface_distance_counts_points_over_the_surface_only() {
        // A unit square sheet in z = 0.
        let sheet = grid(5, 5, |s, t| Point3::new(s, t, 0.0));
        let points = [
            Point3::new(0.5, 0.5, 0.03),   // over the middle
            Point3::new(0.1, 0.9, -0.04),  // over it, below
            Point3::new(0.7, 0.2, 0.0),    // on it
            Point3::new(1.5, 0.5, 0.0),    // past its edge: not counted
            Point3::new(-0.2, -0.3, 0.01), // past its corner: not counted
        ];
        let (rms, n) = surface_rms(&points, &sheet).unwrap();
        assert_eq!(n, 3);
        let want = ((0.03f64.powi(2) + 0.04f64.powi(2)) / 3.0).sqrt();
        assert!((rms - want).abs() < 1e-12, "{rms} vs {want}");
        // A closed surface has no border: every point counts.
        let (_, n) = surface_rms(&points, &crate::synth::icosphere(2)).unwrap();
        assert_eq!(n, 5);
        // Right above a border vertex counts; nothing over the sheet gives no figure.
        assert_eq!(
            surface_rms(&[Point3::new(1.0, 1.0, 0.02)], &sheet).map(|r| r.1),
            Some(1)
        );
        assert_eq!(surface_rms(&[Point3::new(3.0, 3.0, 0.0)], &sheet), None);
    }

    #[test]
    fn hidden_and_out_of_view_vertices_are_not_seen() {
        // One camera 3 m in front of a 1 m sheet; a smaller sheet 1 m behind it (hidden) and
        // another 5 m to the side (out of view).
        let sheet = |size: f64, c: Vector3<f64>| {
            grid(4, 4, move |u, v| {
                Point3::new((u - 0.5) * size, (v - 0.5) * size, 0.0) + c
            })
        };
        let parts = [
            sheet(1.0, Vector3::zeros()),
            sheet(0.5, Vector3::new(0.0, 0.0, -1.0)),
            sheet(0.5, Vector3::new(5.0, 0.0, 0.0)),
        ];
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for p in &parts {
            let base = positions.len() as u32;
            positions.extend_from_slice(&p.positions);
            triangles.extend(p.triangles.iter().map(|t| t.map(|v| v + base)));
        }
        let mesh = Mesh::new(positions, triangles);
        let (r, t) = look_at(
            &Point3::new(0.0, 0.0, 3.0),
            &Point3::origin(),
            &Vector3::y(),
        );
        let k = Matrix3::new(200.0, 0.0, 99.5, 0.0, 200.0, 74.5, 0.0, 0.0, 1.0);
        let cam = Camera::fixed("c", 200, 150, Projection::from_krt(&k, &r, &t).unwrap());
        let views = views_of_vertices(std::slice::from_ref(&cam), 0, &mesh);
        assert_eq!(views[..16], [1; 16]);
        assert_eq!(views[16..], [0; 32]);
        // A second camera in front of the side sheet, and the first one again: the front sheet
        // is seen twice, the side sheet once, the hidden one never.
        let (r2, t2) = look_at(
            &Point3::new(5.0, 0.0, 3.0),
            &Point3::new(5.0, 0.0, 0.0),
            &Vector3::y(),
        );
        let side = Camera::fixed("s", 200, 150, Projection::from_krt(&k, &r2, &t2).unwrap());
        let views = views_of_vertices(&[cam.clone(), side, cam], 0, &mesh);
        assert_eq!(views[..16], [2; 16]);
        assert_eq!(views[16..32], [0; 16]);
        assert_eq!(views[32..], [1; 16]);
    }

    #[test]
    fn the_rigid_fit_takes_out_a_turn_and_a_shift_and_leaves_the_shape() {
        use nalgebra::Rotation3;
        let truth: Vec<Point3<f64>> = grid(5, 4, |u, v| Point3::new(u, 0.3 * v, u * v))
            .positions
            .to_vec();
        let centre = truth.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / truth.len() as f64;
        // Turned 10° about a tilted axis through the centroid and shifted by (0.3, 0, -0.4).
        let turn = Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(Vector3::new(1.0, 2.0, 0.5)),
            10f64.to_radians(),
        );
        let shift = Vector3::new(0.3, 0.0, -0.4);
        let moved: Vec<Point3<f64>> = truth
            .iter()
            .map(|p| Point3::from(turn * (p.coords - centre) + centre + shift))
            .collect();
        let fit = rigid_fit(&moved, &truth);
        assert!(fit.rms < 1e-12, "{}", fit.rms);
        assert!((fit.turn_deg - 10.0).abs() < 1e-9, "{}", fit.turn_deg);
        assert!((fit.shift - 0.5).abs() < 1e-12, "{}", fit.shift);
        // Scaled about the centroid: no rigid motion does better than none, so the shape's
        // error is the whole error.
        let scaled: Vec<Point3<f64>> = truth
            .iter()
            .map(|p| Point3::from((p.coords - centre) * 1.1 + centre))
            .collect();
        let fit = rigid_fit(&scaled, &truth);
        let whole = crate::base::mesh::rms_distance(&scaled, &truth);
        assert!((fit.rms - whole).abs() < 1e-12 && fit.turn_deg < 1e-6 && fit.shift < 1e-12);
        // Nothing to fit.
        assert_eq!(rigid_fit(&[], &[]).rms, 0.0);
    }
}

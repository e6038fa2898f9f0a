//! Bending regulariser: keeps the mesh's local shape close to its rest shape (the scene's mesh,
//! which lines up with the first frame), up to a rotation per vertex — the rotation-invariant
//! Laplacian coordinates of Sorkine et al., "Laplacian Surface Editing" (2004).
//!
//! For every vertex `i` whose one-ring is closed (not on an open boundary) the uniform Laplacian
//! `δ_i(X) = X_i − mean_{j∈N(i)} X_j` is compared with the rest shape's `δ⁰_i`, turned by the
//! rotation `R_i` that best aligns the rest one-ring with the current one (Procrustes). A vertex
//! on an open boundary with exactly two boundary neighbours gets a stencil *along the border*:
//! `N(i)` is those two, so `δ_i` is the border curve's second difference (its own bending), and
//! `R_i` still comes from the vertex's whole one-ring. The
//! residual `√β·(δ_i(X) − R_i·δ⁰_i)/L̄` (L̄: mean rest edge length, so β has no units) is linear in
//! the positions once `R_i` is fixed, and `R_i` is re-estimated from the starting guess of each
//! solve. A flat sheet's rest Laplacians are zero (but at its corners) and the term is plain
//! bending energy; a rigid motion costs nothing.
//!
//! Why the tracker needs it: the images pin each vertex's *projection* well, but depth along a
//! narrow baseline and vertices on the mesh's border (few pixels, one-sided) are weakly seen.
//! The frame-to-frame membrane only refers to the tracker's own previous output, so what it gets
//! wrong it keeps; this term refers to the given rest shape, so such errors do not accumulate.
//! Border vertices also enter their inner neighbours' residuals, which extrapolate the border
//! from the inside; the border stencils add smoothness along it. Without them a border seen by
//! few pixels zig-zags in depth (on the Blender sample, ±4 mm from one border vertex to the
//! next at the last frame), while a border that curls as a whole is not penalised by them.

use super::{procrustes, FrameContext, Regulariser, System};
use crate::base::mesh::EdgeSides;
use crate::tracker::sparse::{BlockSparse, ScalarSparse};
use nalgebra::{Matrix3, Point3, Vector3};
use std::sync::Arc;

/// The Laplacian stencils of a mesh and its rest shape's Laplacian coordinates.
#[derive(Clone, Debug)]
pub struct Bending {
    /// Centre vertex of each stencil.
    centre: Vec<u32>,
    /// `ring[start[k]..start[k + 1]]` are the neighbours of stencil `k`.
    start: Vec<usize>,
    ring: Vec<u32>,
    /// `δ⁰` of each stencil.
    rest_delta: Vec<Vector3<f64>>,
    /// `frame[frame_start[k]..frame_start[k + 1]]` is the whole one-ring of stencil `k`'s centre,
    /// from which its rotation is estimated (the same as its `ring` inside the mesh).
    frame_start: Vec<usize>,
    frame: Vec<u32>,
    /// Rest positions (for the per-vertex rotations).
    rest: Vec<Point3<f64>>,
    mean_length: f64,
    /// `LᵀL` of the stencils' Laplacian `L` (rows: `1` at the centre, `−1/n` at each
    /// neighbour): the term's constant normal-equation matrix, up to its weight.
    gram: Arc<ScalarSparse>,
}

impl Bending {
    /// Stencils for every vertex with a closed one-ring of `triangles`, and along the border for
    /// every border vertex with two border neighbours; rest shape `rest`.
    pub fn new(triangles: &[[u32; 3]], rest: &[Point3<f64>]) -> Self {
        let n = rest.len();
        let mut nb: Vec<Vec<u32>> = vec![Vec::new(); n];
        for t in triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                nb[a as usize].push(b);
                nb[b as usize].push(a);
            }
        }
        // An edge used by one triangle only lies on an open boundary.
        let sides = EdgeSides::new(triangles);
        let mut on_boundary = vec![false; n];
        for e in sides.edges() {
            if let [only] = e {
                let [a, b] = only.edge;
                on_boundary[a as usize] = true;
                on_boundary[b as usize] = true;
            }
        }
        let mut centre = Vec::new();
        let mut start = vec![0];
        let mut ring = Vec::new();
        let mut frame_start = vec![0];
        let mut frame = Vec::new();
        let mut rest_delta = Vec::new();
        let mut length_sum = 0.0;
        let mut length_count = 0usize;
        for (i, mut r) in nb.into_iter().enumerate() {
            r.sort_unstable();
            r.dedup();
            for &j in &r {
                length_sum += (rest[j as usize] - rest[i]).norm();
                length_count += 1;
            }
            let stencil: Vec<u32> = if on_boundary[i] {
                let key = |j: u32| [j.min(i as u32), j.max(i as u32)];
                r.iter()
                    .copied()
                    .filter(|&j| sides.of(key(j)).len() == 1)
                    .collect()
            } else {
                r.clone()
            };
            // A border vertex needs exactly two border neighbours (a simple border curve).
            let usable = if on_boundary[i] {
                stencil.len() == 2
            } else {
                stencil.len() >= 3
            };
            if !usable {
                continue;
            }
            let mean = stencil
                .iter()
                .fold(Vector3::zeros(), |s, &j| s + rest[j as usize].coords)
                / stencil.len() as f64;
            centre.push(i as u32);
            rest_delta.push(rest[i].coords - mean);
            ring.extend(stencil);
            start.push(ring.len());
            frame.extend(r);
            frame_start.push(frame.len());
        }
        let mut b = Bending {
            centre,
            start,
            ring,
            frame_start,
            frame,
            rest_delta,
            rest: rest.to_vec(),
            mean_length: if length_count > 0 {
                length_sum / length_count as f64
            } else {
                1.0
            },
            gram: Arc::new(ScalarSparse::gram(n, [])),
        };
        let rows: Vec<Vec<(u32, f64)>> = (0..b.len())
            .map(|k| {
                let (c, r) = b.stencil(k);
                let inv = 1.0 / r.len() as f64;
                std::iter::once((c as u32, 1.0))
                    .chain(r.iter().map(|&j| (j, -inv)))
                    .collect()
            })
            .collect();
        b.gram = Arc::new(ScalarSparse::gram(n, rows.iter().map(|r| &r[..])));
        b
    }

    /// Number of stencils (inner vertices, and border vertices with two border neighbours).
    pub fn len(&self) -> usize {
        self.centre.len()
    }

    fn stencil(&self, k: usize) -> (usize, &[u32]) {
        (
            self.centre[k] as usize,
            &self.ring[self.start[k]..self.start[k + 1]],
        )
    }

    /// Stencil `k`'s Laplacian coordinates at `x`: its centre less the mean of its ring.
    fn delta(&self, k: usize, x: &[Point3<f64>]) -> Vector3<f64> {
        let (c, r) = self.stencil(k);
        let sum = r
            .iter()
            .fold(Vector3::zeros(), |acc, &j| acc + x[j as usize].coords);
        x[c].coords - sum * (1.0 / r.len() as f64)
    }

    /// The rotation that best turns stencil `k`'s rest one-ring into the one at `x` (orthogonal
    /// Procrustes on the centred ring, reflections excluded).
    fn rotation(&self, k: usize, x: &[Point3<f64>]) -> Matrix3<f64> {
        let c = self.centre[k] as usize;
        let mut m = Matrix3::zeros();
        for &j in &self.frame[self.frame_start[k]..self.frame_start[k + 1]] {
            let j = j as usize;
            m += (x[j] - x[c]) * (self.rest[j] - self.rest[c]).transpose();
        }
        procrustes(&m)
    }

    /// The rest Laplacian coordinates turned into the shape `x`: `R_k·δ⁰_k` with `R_k` the
    /// rotation of stencil `k` at `x`, computed only where `δ⁰_k` is not zero (a flat sheet's inner
    /// and straight-border stencils need no rotation; its corners do).
    pub fn targets_at(&self, x: &[Point3<f64>]) -> Vec<Vector3<f64>> {
        let tol = 1e-9 * self.mean_length;
        (0..self.len())
            .map(|k| {
                let d = self.rest_delta[k];
                if d.norm() <= tol {
                    Vector3::zeros()
                } else {
                    self.rotation(k, x) * d
                }
            })
            .collect()
    }

    /// Adds the term's cost (returned) and, with `system`, its normal-equation matrix (as the
    /// shared scalar part `s·LᵀL ⊗ I₃`, see `sparse`) and right-hand side `−Jᵀr` at `x`, for
    /// target Laplacian coordinates `targets` (one per stencil); `weight` is β divided by
    /// whatever the caller normalises by.
    pub fn accumulate(
        &self,
        x: &[Point3<f64>],
        targets: &[Vector3<f64>],
        weight: f64,
        mut system: Option<(&mut BlockSparse, &mut [Vector3<f64>])>,
    ) -> f64 {
        debug_assert_eq!(targets.len(), self.len(), "one target per stencil");
        let s = weight / (self.mean_length * self.mean_length);
        if let Some((a, _)) = system.as_mut() {
            a.add_scalar(&self.gram, s);
        }
        let mut cost = 0.0;
        for (k, target) in targets.iter().enumerate().take(self.len()) {
            let (c, r) = self.stencil(k);
            let res = self.delta(k, x) - target;
            cost += s * res.norm_squared();
            if let Some((_, b)) = system.as_mut() {
                // J = s^½·[1 at c, −1/n at each neighbour] ⊗ I₃.
                let inv = 1.0 / r.len() as f64;
                b[c] -= res * s;
                for &j in r {
                    b[j as usize] += res * (s * inv);
                }
            }
        }
        cost
    }
}

/// Where the bending term pulls a stencil in this frame: `rest` (the rest shape's Laplacian
/// coordinates turned into the previous frame), or, when the previous frame's own coordinates
/// `previous` lay further than `band` from it, the point on the way from `rest` to `previous`
/// that is `band` short of `previous`. So a deviation the images held for a frame (a fold, a
/// dent) is kept, less the band, and a further change is resisted from there, as a change from
/// rest is; within the band (small drift) the rest shape pulls as before.
pub(crate) fn yielded_target(
    rest: Vector3<f64>,
    previous: Vector3<f64>,
    band: f64,
) -> Vector3<f64> {
    let dev = previous - rest;
    let n = dev.norm();
    if n > band && n.is_finite() {
        rest + dev * (1.0 - band / n)
    } else {
        rest
    }
}

/// Where the bending term yields, as fractions of the mean rest edge length (0 = never).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Yield {
    /// The yield of every stencil, or of those the images saw little of when `seen` is set.
    pub fraction: f64,
    /// A yield of its own for the stencils whose centre the previous frame's images pinned well.
    pub seen: Option<SeenYield>,
}

/// The yield of the stencils the images saw well (`Regularisation::bending_yield_seen`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SeenYield {
    pub fraction: f64,
    /// A centre is seen well when its information in the previous frame was at least this share
    /// of the median over the vertices with any.
    pub share: f64,
}

/// The median of the positive values of `v` (the upper one of an even count); `None` when there
/// is none. Whatever the order of `v`, the same value (a total order on f64).
fn positive_median(v: &[f64]) -> Option<f64> {
    let mut p: Vec<f64> = v
        .iter()
        .copied()
        .filter(|x| *x > 0.0 && x.is_finite())
        .collect();
    if p.is_empty() {
        return None;
    }
    let mid = p.len() / 2;
    Some(*p.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// The bending term as the solver sees it: [`Bending`]'s stencils with the weight `β` (divided
/// by the number of stencils) and the frame's target Laplacian coordinates, turned by rotations
/// taken from the previous frame's shape (they change little in a frame), and past the yield
/// moved toward the previous frame's own ([`yielded_target`]), with a yield per stencil that
/// depends on how well the previous frame's images saw its centre ([`Yield`]).
pub(crate) struct BendingTerm {
    bending: Bending,
    weight: f64,
    /// The yield as fractions of the mean rest edge length.
    yielding: Yield,
    targets: Vec<Vector3<f64>>,
}

impl BendingTerm {
    pub fn new(bending: Bending, beta: f64, yielding: Yield) -> Self {
        let weight = beta / bending.len().max(1) as f64;
        let targets = bending.rest_delta.clone();
        BendingTerm {
            bending,
            weight,
            yielding,
            targets,
        }
    }

    /// Each stencil's yield as a length this frame (0: none), given the previous frame's
    /// per-vertex `information` when known.
    fn bands(&self, information: Option<&[f64]>) -> Vec<f64> {
        let l = self.bending.mean_length;
        let plain = self.yielding.fraction * l;
        let gate = self.yielding.seen.and_then(|seen| {
            let info = information.filter(|i| i.len() == self.bending.rest.len())?;
            let median = positive_median(info)?;
            Some((info, seen.share * median, seen.fraction * l))
        });
        (0..self.bending.len())
            .map(|k| match gate {
                Some((info, threshold, band))
                    if info[self.bending.centre[k] as usize] >= threshold =>
                {
                    band
                }
                _ => plain,
            })
            .collect()
    }
}

impl Regulariser for BendingTerm {
    fn name(&self) -> &'static str {
        "bending"
    }

    fn begin_frame(&mut self, frame: &FrameContext<'_>) {
        self.targets = self.bending.targets_at(frame.previous);
        if self.yielding.fraction <= 0.0 && self.yielding.seen.is_none_or(|s| s.fraction <= 0.0) {
            return;
        }
        let bands = self.bands(frame.information);
        for (k, (t, band)) in self.targets.iter_mut().zip(bands).enumerate() {
            if band > 0.0 {
                *t = yielded_target(*t, self.bending.delta(k, frame.previous), band);
            }
        }
    }

    fn accumulate(&self, x: &[Point3<f64>], system: Option<System<'_>>) -> f64 {
        self.bending
            .accumulate(x, &self.targets, self.weight, system)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::mesh::grid;
    use nalgebra::{Rotation3, Vector3};

    /// One yield for every stencil.
    fn plain(fraction: f64) -> Yield {
        Yield {
            fraction,
            seen: None,
        }
    }

    /// A 5×5 grid bent into a bump (a curved rest shape).
    fn bumpy() -> crate::base::mesh::Mesh {
        grid(5, 5, |u, v| {
            Point3::new(u, v, 0.3 * (u * 2.0).sin() * (v * 3.0).cos())
        })
    }

    fn system_of(
        b: &Bending,
        x: &[Point3<f64>],
        targets: &[Vector3<f64>],
    ) -> (f64, BlockSparse, Vec<Vector3<f64>>) {
        let mut a = BlockSparse::new(x.len(), &[]);
        let mut rhs = vec![Vector3::zeros(); x.len()];
        let cost = b.accumulate(x, targets, 0.7, Some((&mut a, &mut rhs[..])));
        (cost, a, rhs)
    }

    #[test]
    fn inner_vertices_get_their_ring_and_border_vertices_their_border_neighbours() {
        let m = bumpy();
        let b = Bending::new(&m.triangles, &m.positions);
        // The 3×3 inner vertices of a 5×5 grid, and all 16 border vertices (corners included).
        assert_eq!(b.len(), 25);
        for k in 0..b.len() {
            let (c, r) = b.stencil(k);
            let (x, y) = (c % 5, c / 5);
            if (1..4).contains(&x) && (1..4).contains(&y) {
                // Its whole ring (4 to 8 neighbours, as the grid's diagonals alternate).
                assert!(r.len() >= 4, "inner vertex {c}: {r:?}");
            } else {
                // Its two neighbours along the border, each one grid step away on the border.
                assert_eq!(r.len(), 2, "border vertex {c}");
                for &j in r {
                    let (jx, jy) = (j as usize % 5, j as usize / 5);
                    assert_eq!(jx.abs_diff(x) + jy.abs_diff(y), 1, "{c} -> {j}");
                    assert!(
                        jx == 0 || jx == 4 || jy == 0 || jy == 4,
                        "{j} is on the border"
                    );
                }
            }
        }
        // A flat sheet: zero Laplacians inside and along straight borders, but not at corners.
        let flat = grid(4, 3, |u, v| Point3::new(u, v, 0.0));
        let fb = Bending::new(&flat.triangles, &flat.positions);
        assert_eq!(fb.len(), 12);
        let zero = fb.rest_delta.iter().filter(|d| d.norm() < 1e-12).count();
        assert_eq!(zero, 8, "all but the four corners");
    }

    #[test]
    fn a_border_that_zig_zags_costs_and_one_that_curls_as_a_whole_does_not() {
        // Flat 6×6 sheet; move its top border row (y = 5) out of the plane.
        let m = grid(6, 6, |u, v| Point3::new(u * 5.0, v * 5.0, 0.0));
        let b = Bending::new(&m.triangles, &m.positions);
        let border_cost = |x: &[Point3<f64>]| {
            let t = b.targets_at(x);
            // Only the stencils centred on the moved row, away from the corners.
            (1..5)
                .map(|i| {
                    let k = b.centre.iter().position(|&c| c as usize == 30 + i).unwrap();
                    let (c, r) = b.stencil(k);
                    let mean = (x[r[0] as usize].coords + x[r[1] as usize].coords) / 2.0;
                    (x[c].coords - mean - t[k]).norm_squared()
                })
                .sum::<f64>()
        };
        let mut curl = m.positions.clone();
        let mut zig = m.positions.clone();
        for i in 0..6 {
            curl[30 + i].z += 0.3;
            zig[30 + i].z += if i % 2 == 0 { 0.3 } else { -0.3 };
        }
        assert!(border_cost(&curl) < 1e-12, "{}", border_cost(&curl));
        assert!(border_cost(&zig) > 0.1, "{}", border_cost(&zig));
    }

    #[test]
    fn rigid_motion_costs_nothing_and_bending_does() {
        let m = bumpy();
        let b = Bending::new(&m.triangles, &m.positions);
        let r = Rotation3::from_euler_angles(0.4, -0.7, 1.1);
        let t = Vector3::new(3.0, -2.0, 0.5);
        let moved: Vec<Point3<f64>> = m.positions.iter().map(|p| r * p + t).collect();
        for k in 0..b.len() {
            assert!(
                (b.rotation(k, &moved) - r.matrix()).norm() < 1e-9,
                "Procrustes recovers the rotation"
            );
        }
        let targets = b.targets_at(&moved);
        assert!(b.accumulate(&moved, &targets, 1.0, None) < 1e-20);
        // Skipping the zero rest Laplacians gives the same targets as turning every one.
        for (k, t) in targets.iter().enumerate() {
            assert!((b.rotation(k, &moved) * b.rest_delta[k] - t).norm() < 1e-12);
        }
        // Without the rotations the turned rest shape is penalised...
        assert!(b.accumulate(&moved, &b.rest_delta, 1.0, None) > 1e-3);
        // ...and so is a real change of shape, even with them.
        let mut dented = moved.clone();
        dented[12] += r * Vector3::new(0.0, 0.0, 0.05);
        assert!(b.accumulate(&dented, &b.targets_at(&dented), 1.0, None) > 1e-6);
    }

    #[test]
    fn normal_equations_are_exact_for_the_quadratic_term() {
        // The residuals are linear in the positions, so cost(x + d) = cost(x) − 2·bᵀd + dᵀ·A·d
        // holds exactly for any step d: this checks the blocks and the right-hand side at once.
        let m = bumpy();
        let b = Bending::new(&m.triangles, &m.positions);
        let x: Vec<Point3<f64>> = m
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                p + Vector3::new(
                    0.01 * (i as f64).sin(),
                    0.02 * (i as f64 * 1.3).cos(),
                    0.015,
                )
            })
            .collect();
        let targets = b.rest_delta.clone();
        let (c0, a, rhs) = system_of(&b, &x, &targets);
        let d: Vec<Vector3<f64>> = (0..x.len())
            .map(|i| Vector3::new((i as f64 * 0.7).cos(), (i as f64 * 1.9).sin(), 0.3) * 0.05)
            .collect();
        let moved: Vec<Point3<f64>> = x.iter().zip(&d).map(|(p, d)| p + d).collect();
        let c1 = b.accumulate(&moved, &targets, 0.7, None);
        let mut ad = vec![Vector3::zeros(); x.len()];
        a.mul(&d, &mut ad);
        let predicted = c0 - 2.0 * rhs.iter().zip(&d).map(|(b, d)| b.dot(d)).sum::<f64>()
            + d.iter().zip(&ad).map(|(d, ad)| d.dot(ad)).sum::<f64>();
        assert!(
            (c1 - predicted).abs() < 1e-12 * (1.0 + c1.abs()),
            "{c1} vs {predicted}"
        );
        assert!(c1 > 0.0 && c0 > 0.0);
    }

    #[test]
    fn the_yield_keeps_a_held_deviation_less_the_band_and_pulls_drift_back_to_rest() {
        let rest = Vector3::new(0.0, 0.0, 0.1);
        // Within the band (0.05): drift, pulled back to the rest shape.
        let small = Vector3::new(0.03, 0.0, 0.13);
        assert_eq!(yielded_target(rest, small, 0.05), rest);
        // Beyond it: the deviation (0.3, 0.4, 0) of length 0.5 is kept less 0.05, i.e. 0.9 of it.
        let fold = Vector3::new(0.3, 0.4, 0.1);
        let t = yielded_target(rest, fold, 0.05);
        assert!((t - Vector3::new(0.27, 0.36, 0.1)).norm() < 1e-15, "{t}");
        // A non-finite shape (a degenerate previous frame) falls back to the rest shape.
        let nan = Vector3::new(f64::NAN, 0.0, 0.0);
        assert_eq!(yielded_target(rest, nan, 0.05), rest);
    }

    #[test]
    fn past_the_yield_a_fold_held_in_the_previous_frame_costs_only_its_further_change() {
        // A dent of the bumpy sheet held by the previous frame: without the yield the term pulls
        // it all the way back to the rest shape; with it, the dent as it was costs only the band
        // (here 4 % of it), and a dent growing further costs as a dent from rest would.
        let m = bumpy();
        let b = Bending::new(&m.triangles, &m.positions);
        let mut dented = m.positions.clone();
        dented[12].z += 0.2;
        let frame = FrameContext {
            previous: &dented,
            predicted: &dented,
            information: None,
        };
        let mut stiff = BendingTerm::new(b.clone(), 1.0, plain(0.0));
        let mut yielding = BendingTerm::new(b.clone(), 1.0, plain(0.05));
        stiff.begin_frame(&frame);
        yielding.begin_frame(&frame);
        let (held_stiff, held_yield) = (
            stiff.accumulate(&dented, None),
            yielding.accumulate(&dented, None),
        );
        assert!(
            held_yield < 0.1 * held_stiff,
            "{held_yield} vs {held_stiff}"
        );
        // The rest shape is what the yielding term now resists, by about as much as the stiff
        // one resists the dent: going back is a change too, until the images allow it.
        let back = yielding.accumulate(&m.positions, None);
        assert!(back > 0.5 * held_stiff, "{back} vs {held_stiff}");
        // A further 0.2 costs at least what the first 0.2 did (less the band).
        let mut deeper = dented.clone();
        deeper[12].z += 0.2;
        let further = yielding.accumulate(&deeper, None);
        assert!(further > 0.7 * held_stiff, "{further} vs {held_stiff}");
    }

    #[test]
    fn the_images_decide_where_the_yield_is_small() {
        // The same held dent under a gated yield: where the previous frame's images pinned the
        // dented vertex (information at or above half the median) it keeps its dent less the
        // small band, so costs little; where they saw it little the large band applies, and the
        // dent costs what it does with that band alone.
        let m = bumpy();
        let b = Bending::new(&m.triangles, &m.positions);
        let mut dented = m.positions.clone();
        dented[12].z += 0.2;
        let gated = Yield {
            fraction: 0.5,
            seen: Some(SeenYield {
                fraction: 0.01,
                share: 0.5,
            }),
        };
        let cost = |yielding: Yield, information: Option<&[f64]>| {
            let mut t = BendingTerm::new(b.clone(), 1.0, yielding);
            t.begin_frame(&FrameContext {
                previous: &dented,
                predicted: &dented,
                information,
            });
            t.accumulate(&dented, None)
        };
        let mut info = vec![1.0; m.positions.len()];
        let well_seen = cost(gated, Some(&info));
        assert_eq!(well_seen, cost(plain(0.01), None));
        // Half the median exactly is still seen; below it is not. Vertices the images did not
        // see at all (information 0) do not lower the median.
        info[0] = 0.0;
        info[12] = 0.5;
        assert_eq!(cost(gated, Some(&info)), well_seen);
        info[12] = 0.49;
        let little_seen = cost(gated, Some(&info));
        assert!(
            little_seen > 10.0 * well_seen,
            "{little_seen} vs {well_seen}"
        );
        // Before any frame was solved, and when the term is not gated, the large band holds.
        assert_eq!(cost(gated, None), cost(plain(0.5), None));
        assert!(cost(plain(0.5), None) > 10.0 * well_seen);
    }

    #[test]
    fn the_median_of_the_information_ignores_vertices_the_images_did_not_see() {
        assert_eq!(positive_median(&[0.0, 3.0, 1.0, 0.0, 2.0]), Some(2.0));
        assert_eq!(positive_median(&[4.0, 1.0, 3.0, 2.0]), Some(3.0));
        assert_eq!(positive_median(&[0.0, f64::NAN]), None);
    }
}

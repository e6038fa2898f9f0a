//! Where the tracked mesh has folded over itself: pairs of neighbouring triangles that faced
//! nearly the same way in the first frame's mesh and face opposite ways now. A fold of that
//! kind is not a deformation any smooth surface makes between two triangles that share an
//! edge; it is what the tracker leaves where part of the surface turned out of every view and
//! came back, or where a tight crease collapsed past what the regularisers hold. The frame is
//! then reported (`health::Concern::Folded`), where before it passed silently: on a blob turned
//! through 360° the folds grew from frame 40 while the frames' own checks saw nothing
//! (docs/tracker.md, "Suspect frames").
//!
//! An edge is watched when its two triangles' normals are within [`WATCH_BELOW_DEGREES`] of
//! each other in the first frame's mesh (a crease modelled that sharp, a box's edge, is not
//! watched); it counts as folded when they are more than [`FOLDED_DEGREES`] apart. Knows
//! triangles and positions only.

use crate::base::mesh::EdgeSides;
use nalgebra::{Point3, Vector3};

/// Neighbouring triangles whose normals differ by more than this (degrees) in the first
/// frame's mesh are not watched.
pub const WATCH_BELOW_DEGREES: f64 = 60.0;
/// A watched edge is folded when its triangles' normals differ by more than this (degrees).
/// No ground truth of our clips comes near it (the bending elbow of `synth --preset limb` is
/// the sharpest, 107°), nor any track of them that follows the truth (docs/tracker.md).
pub const FOLDED_DEGREES: f64 = 120.0;

/// The watched edges of a mesh, as pairs of triangle indices.
#[derive(Clone, Debug, Default)]
pub(crate) struct FoldWatch {
    pairs: Vec<[u32; 2]>,
    /// The cosine below which a watched pair counts as folded.
    cos_folded: f64,
}

impl FoldWatch {
    /// The edges of `triangles` shared by exactly two triangles whose normals at `positions`
    /// (the first frame's mesh) are within [`WATCH_BELOW_DEGREES`]. A degenerate triangle (no
    /// normal) is not watched.
    pub(crate) fn new(positions: &[Point3<f64>], triangles: &[[u32; 3]]) -> Self {
        let normals: Vec<Option<Vector3<f64>>> =
            triangles.iter().map(|t| normal(positions, t)).collect();
        let cos_watch = WATCH_BELOW_DEGREES.to_radians().cos();
        let pairs: Vec<[u32; 2]> = EdgeSides::new(triangles)
            .edges()
            .filter_map(|e| match e {
                [s, t] => Some([s.triangle, t.triangle]),
                _ => None,
            })
            .filter(
                |ts| match (normals[ts[0] as usize], normals[ts[1] as usize]) {
                    (Some(a), Some(b)) => a.dot(&b) > cos_watch,
                    _ => false,
                },
            )
            .collect();
        FoldWatch {
            pairs,
            cos_folded: FOLDED_DEGREES.to_radians().cos(),
        }
    }

    /// How many watched edges are folded with the mesh at `positions`. A triangle that has
    /// collapsed to no area has no facing and does not count.
    pub(crate) fn folded(&self, positions: &[Point3<f64>], triangles: &[[u32; 3]]) -> usize {
        if self.pairs.is_empty() {
            return 0;
        }
        // Each triangle's normal once (a triangle is in up to three pairs).
        let normals: Vec<Option<Vector3<f64>>> =
            triangles.iter().map(|t| normal(positions, t)).collect();
        self.pairs
            .iter()
            .filter(
                |[a, b]| match (normals[*a as usize], normals[*b as usize]) {
                    (Some(na), Some(nb)) => na.dot(&nb) < self.cos_folded,
                    _ => false,
                },
            )
            .count()
    }

    /// How many edges are watched.
    #[cfg(test)]
    pub(crate) fn watched(&self) -> usize {
        self.pairs.len()
    }
}

/// The unit normal of triangle `t` (by its winding), or `None` when it has no area.
fn normal(positions: &[Point3<f64>], t: &[u32; 3]) -> Option<Vector3<f64>> {
    let [a, b, c] = t.map(|v| positions[v as usize]);
    let n = (b - a).cross(&(c - a));
    let len = n.norm();
    (len > 0.0 && len.is_finite()).then(|| n / len)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strip of two triangles sharing the edge from (0,0,0) to (0,1,0): the first in the
    /// plane z = 0 on the side x < 0, the second turned about the shared edge by `degrees`
    /// away from flat.
    fn hinge(degrees: f64) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let a = degrees.to_radians();
        let positions = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(-1.0, 0.5, 0.0),
            Point3::new(a.cos(), 0.5, a.sin()),
        ];
        // Both wound so that, flat, their normals agree.
        (positions, vec![[0, 1, 2], [1, 0, 3]])
    }

    #[test]
    fn a_hinge_counts_as_folded_only_past_the_threshold() {
        let (flat, triangles) = hinge(0.0);
        let watch = FoldWatch::new(&flat, &triangles);
        assert_eq!(watch.watched(), 1);
        assert_eq!(watch.folded(&flat, &triangles), 0);
        for (degrees, folded) in [(30.0, 0), (90.0, 0), (115.0, 0), (125.0, 1), (179.0, 1)] {
            let (bent, _) = hinge(degrees);
            assert_eq!(
                watch.folded(&bent, &triangles),
                folded,
                "turned by {degrees}°"
            );
        }
        // Turned the other way round the edge: the same.
        let (bent, _) = hinge(-150.0);
        assert_eq!(watch.folded(&bent, &triangles), 1);
    }

    #[test]
    fn a_crease_modelled_sharp_and_a_collapsed_triangle_are_not_counted() {
        // Modelled at 80° (a box's edge would be 90°): not watched, whatever it does later.
        let (creased, triangles) = hinge(80.0);
        let watch = FoldWatch::new(&creased, &triangles);
        assert_eq!(watch.watched(), 0);
        assert_eq!(watch.folded(&hinge(170.0).0, &triangles), 0);
        // Watched, then one triangle collapsed onto a line: no facing, not folded.
        let (flat, triangles) = hinge(0.0);
        let watch = FoldWatch::new(&flat, &triangles);
        let mut collapsed = flat.clone();
        collapsed[3] = Point3::new(0.0, 0.5, 0.0);
        assert_eq!(watch.folded(&collapsed, &triangles), 0);
    }

    #[test]
    fn a_sheet_folded_over_along_a_row_of_edges_counts_each_edge() {
        // A 5×5 grid in the plane z = 0, its columns x >= 2 folded over onto the rest (turned
        // by 170° about the line x = 2): the fold runs along the 4 edges of that line.
        let n = 5;
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = (j * n + i) as u32;
                triangles.push([v, v + 1, v + n as u32]);
                triangles.push([v + 1, v + n as u32 + 1, v + n as u32]);
            }
        }
        let grid = |turn: f64| -> Vec<Point3<f64>> {
            let a = turn.to_radians();
            (0..n * n)
                .map(|k| {
                    let (i, j) = ((k % n) as f64, (k / n) as f64);
                    if i <= 2.0 {
                        Point3::new(i, j, 0.0)
                    } else {
                        let d = i - 2.0;
                        Point3::new(2.0 + d * a.cos(), j, d * a.sin())
                    }
                })
                .collect()
        };
        let watch = FoldWatch::new(&grid(0.0), &triangles);
        assert_eq!(watch.folded(&grid(0.0), &triangles), 0);
        assert_eq!(watch.folded(&grid(100.0), &triangles), 0);
        assert_eq!(watch.folded(&grid(170.0), &triangles), 4);
    }
}

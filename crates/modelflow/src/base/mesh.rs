//! Triangle meshes: vertex positions, triangles as index triples, optional per-vertex texture
//! coordinates, the input file's face-varying texture coordinates and normals (carried through
//! tracking to the outputs), and the topology queries the tracker needs (edges, closedness,
//! neighbours).
//! Reading and writing files lives in `meshio`; this module does no I/O.

use nalgebra::{Point3, UnitQuaternion, Vector3};
use std::collections::HashMap;
use std::sync::Arc;

/// A face-varying attribute as OBJ stores it: a table of values (`vt` or `vn` lines) and, per
/// triangle, the table index of each of its three corners. A vertex on a UV seam or a hard edge
/// has several.
#[derive(Clone, Debug, PartialEq)]
pub struct CornerTable<const N: usize> {
    pub values: Vec<[f64; N]>,
    /// One triple per triangle of the mesh, in the order of `Mesh::triangles`.
    pub index: Vec<[u32; 3]>,
}

/// The input mesh's normals, carried with the surface as it deforms: each normal `n` of the
/// table is turned, at every frame, by the smallest rotation that takes the area-weighted normal
/// of the triangles sharing `n` in the input mesh (`rest`) to the same normal now. At the first
/// frame every normal is exactly the input's; custom and split normals stay what the artist made.
#[derive(Clone, Debug, PartialEq)]
pub struct CornerNormals {
    pub table: CornerTable<3>,
    /// Per entry of `table.values`: the area-weighted normal of its triangles in the input mesh.
    pub rest: Vec<Vector3<f64>>,
}

/// A triangle mesh. Every tracked frame shares the topology of the input mesh; only positions change.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Point3<f64>>,
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex texture coordinates, if the file had them (synthetic footage uses them).
    pub uvs: Option<Vec<[f64; 2]>>,
    /// The input file's texture coordinates per triangle corner (`f v/vt`), when every corner
    /// has one; shared by every frame's mesh.
    pub corner_uvs: Option<Arc<CornerTable<2>>>,
    /// The input file's normals per triangle corner (`f v//vn`), when every corner has one.
    pub corner_normals: Option<Arc<CornerNormals>>,
    /// The input file's faces, when some had more than three corners (an artist's quads): each
    /// face's corner count, in the file's order. Face `f`'s triangles are the next `n − 2` of
    /// `triangles`, a fan from its first corner (as the readers triangulate), so the faces are
    /// rebuilt from the triangles ([`Mesh::face_corners`]) and the meshes written keep them.
    pub polygons: Option<Arc<Vec<u32>>>,
}

impl Mesh {
    pub fn new(positions: Vec<Point3<f64>>, triangles: Vec<[u32; 3]>) -> Self {
        Mesh {
            positions,
            triangles,
            uvs: None,
            corner_uvs: None,
            corner_normals: None,
            polygons: None,
        }
    }

    /// Per-vertex texture coordinates (for renderers): the given ones, with no face-varying
    /// attributes.
    pub fn with_vertex_uvs(
        positions: Vec<Point3<f64>>,
        triangles: Vec<[u32; 3]>,
        uvs: Vec<[f64; 2]>,
    ) -> Self {
        Mesh {
            uvs: Some(uvs),
            ..Mesh::new(positions, triangles)
        }
    }

    /// The same topology with other positions.
    pub fn with_positions(&self, positions: Vec<Point3<f64>>) -> Self {
        assert_eq!(positions.len(), self.positions.len());
        Mesh {
            positions,
            triangles: self.triangles.clone(),
            uvs: self.uvs.clone(),
            corner_uvs: self.corner_uvs.clone(),
            corner_normals: self.corner_normals.clone(),
            polygons: self.polygons.clone(),
        }
    }

    /// The input face (counted from 0, in the file's order) that triangle `t` was cut from: `t`
    /// itself unless the mesh keeps its input polygons ([`Mesh::polygons`]).
    pub fn face_of_triangle(&self, t: usize) -> usize {
        let (counts, _) = self.face_corners();
        let mut first = 0;
        for (f, n) in counts.iter().enumerate() {
            first += *n as usize - 2;
            if t < first {
                return f;
            }
        }
        t
    }

    /// The faces to write: each face's corner count, and per corner (face by face, in order)
    /// the triangle and the corner of it (0 to 2) that carries its vertex and face-varying
    /// indices. The input's polygons ([`Mesh::polygons`]) where they match the triangles,
    /// otherwise the triangles themselves.
    pub fn face_corners(&self) -> (Vec<u32>, Vec<(u32, u8)>) {
        let fits = |p: &Vec<u32>| {
            p.iter().all(|&n| n >= 3)
                && p.iter().map(|&n| n as usize - 2).sum::<usize>() == self.triangles.len()
        };
        match self.polygons.as_deref().filter(|p| fits(p)) {
            Some(p) => {
                let mut corners = Vec::with_capacity(self.triangles.len() + 2 * p.len());
                let mut t = 0u32;
                for &n in p {
                    // The fan (c0, c1, c2), (c0, c2, c3), ...: its first triangle's three
                    // corners, then each next triangle's last.
                    corners.extend([(t, 0), (t, 1), (t, 2)]);
                    for k in 1..n - 2 {
                        corners.push((t + k, 2));
                    }
                    t += n - 2;
                }
                (p.clone(), corners)
            }
            None => (
                vec![3; self.triangles.len()],
                (0..self.triangles.len() as u32)
                    .flat_map(|t| [(t, 0), (t, 1), (t, 2)])
                    .collect(),
            ),
        }
    }

    /// The same mesh with other triangles over the same vertices (the face-varying tables,
    /// which follow the triangles, are dropped).
    pub fn with_triangles(&self, triangles: Vec<[u32; 3]>) -> Self {
        Mesh {
            positions: self.positions.clone(),
            triangles,
            uvs: self.uvs.clone(),
            corner_uvs: None,
            corner_normals: None,
            polygons: None,
        }
    }

    /// The area-weighted normal (unnormalised: twice the area) of every triangle.
    fn face_areas(&self) -> Vec<Vector3<f64>> {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| self.positions[v as usize]);
                (b - a).cross(&(c - a))
            })
            .collect()
    }

    /// Per entry of a corner table: the unit area-weighted normal of the triangles whose corners
    /// use it (zero when they have no area).
    pub fn corner_group_normals(&self, index: &[[u32; 3]], entries: usize) -> Vec<Vector3<f64>> {
        let mut sum = vec![Vector3::zeros(); entries];
        for (t, n) in index.iter().zip(self.face_areas()) {
            for &e in t {
                sum[e as usize] += n;
            }
        }
        sum.into_iter()
            .map(|n| n.try_normalize(0.0).unwrap_or_else(Vector3::zeros))
            .collect()
    }

    /// The unit area-weighted normal of every vertex (zero where its triangles have no area).
    pub fn vertex_normals(&self) -> Vec<Vector3<f64>> {
        self.corner_group_normals(&self.triangles, self.positions.len())
    }

    /// The input normals as they are at this mesh's positions (see [`CornerNormals`]); `None`
    /// when the input had no normals on every corner.
    pub fn current_normals(&self) -> Option<Vec<[f64; 3]>> {
        let cn = self.corner_normals.as_ref()?;
        let now = self.corner_group_normals(&cn.table.index, cn.table.values.len());
        Some(
            cn.table
                .values
                .iter()
                .zip(cn.rest.iter().zip(&now))
                .map(|(v, (rest, now))| {
                    if rest == now {
                        return *v;
                    }
                    match UnitQuaternion::rotation_between(rest, now) {
                        Some(q) => {
                            let n = q * Vector3::from(*v);
                            [n.x, n.y, n.z]
                        }
                        None => *v,
                    }
                })
                .collect(),
        )
    }

    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Unique undirected edges `(a, b)` with `a < b`, sorted.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        let mut e: Vec<[u32; 2]> = self
            .triangles
            .iter()
            .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
            .map(|[a, b]| if a < b { [a, b] } else { [b, a] })
            .collect();
        e.sort_unstable();
        e.dedup();
        e
    }

    /// The mesh with vertices at exactly the same position merged, and for every vertex its
    /// merged index; `None` when no two vertices coincide. Exporters split a surface's vertices
    /// along UV seams and hard edges (PLY, and every format without separate texture indices)
    /// or write a triangle soup (one copy per triangle, as STL holds): the copies are not joined
    /// by any edge, so the regularisers cannot hold the seams shut and a soup has no edges to
    /// hold at all. Only bit-identical positions are merged (the copies an exporter writes are);
    /// a triangle whose corners merge into one another (none in a loaded mesh, which refuses
    /// zero-area triangles) is left out; the texture and normal tables are dropped.
    pub fn welded(&self) -> Option<(Mesh, Vec<u32>)> {
        let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(self.positions.len());
        let mut positions = Vec::with_capacity(self.positions.len());
        let of_vertex: Vec<u32> = self
            .positions
            .iter()
            .map(|p| {
                // +0.0 and −0.0 are the same position.
                let key = [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits());
                *first.entry(key).or_insert_with(|| {
                    positions.push(*p);
                    (positions.len() - 1) as u32
                })
            })
            .collect();
        if positions.len() == self.positions.len() {
            return None;
        }
        let triangles = self
            .triangles
            .iter()
            .map(|t| t.map(|v| of_vertex[v as usize]))
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
        let mesh = Mesh {
            positions,
            triangles,
            uvs: None,
            corner_uvs: None,
            corner_normals: None,
            polygons: None,
        };
        Some((mesh, of_vertex))
    }

    /// The triangles wound as the tracker needs them: consistently across every edge two
    /// triangles share (each such edge run one way by one and the other way by the other), and
    /// each closed piece facing outward (its triangles' normals, by the right-hand rule, point
    /// out of the volume it encloses: a positive signed volume). Returns them and how many were
    /// turned. Artists' meshes are often wound inconsistently (after booleans, mirroring,
    /// merges) or inward as a whole (another package's convention); the tracker's facing test
    /// would then take the turned triangles for back faces and never compare their pixels, and
    /// a closed mesh wound inward would show no camera anything. Pieces meet only through shared
    /// edges; an edge with three or more triangles joins nothing, and where a non-orientable
    /// surface (a Möbius strip) cannot agree, the first winding found stays. Open pieces keep
    /// the winding of their first triangle (the tracker treats open surfaces as two-sided).
    pub fn facing_outward(&self) -> (Vec<[u32; 3]>, usize) {
        let n = self.triangles.len();
        // Every undirected edge with the triangles that run it, and which way.
        let by_edge = EdgeSides::new(&self.triangles);
        let mut flip = vec![false; n];
        let mut seen = vec![false; n];
        let mut out = self.triangles.clone();
        for root in 0..n {
            if seen[root] {
                continue;
            }
            seen[root] = true;
            let mut piece = vec![root];
            let mut closed = true;
            let mut k = 0;
            while k < piece.len() {
                let t = piece[k];
                k += 1;
                let tri = self.triangles[t];
                for e in 0..3 {
                    let (a, b) = (tri[e], tri[(e + 1) % 3]);
                    let key = if a < b { [a, b] } else { [b, a] };
                    let runs = by_edge.of(key);
                    if runs.len() != 2 {
                        closed = false;
                        continue;
                    }
                    let here = (a < b) != flip[t];
                    for side in runs {
                        let (o, forward) = (side.triangle as usize, side.forward);
                        if o == t || seen[o] {
                            continue;
                        }
                        // The neighbour must run the shared edge the other way.
                        flip[o] = forward == here;
                        seen[o] = true;
                        piece.push(o);
                    }
                }
            }
            let wound = |t: usize, flip: &[bool]| {
                let tri = self.triangles[t];
                if flip[t] {
                    [tri[0], tri[2], tri[1]]
                } else {
                    tri
                }
            };
            if closed {
                let volume: f64 = piece
                    .iter()
                    .map(|&t| {
                        let [a, b, c] = wound(t, &flip).map(|v| self.positions[v as usize].coords);
                        a.dot(&b.cross(&c))
                    })
                    .sum();
                if volume < 0.0 {
                    for &t in &piece {
                        flip[t] = !flip[t];
                    }
                }
            }
            for &t in &piece {
                out[t] = wound(t, &flip);
            }
        }
        let turned = flip.iter().filter(|&&f| f).count();
        (out, turned)
    }

    /// Whether every edge is shared by exactly two triangles (a closed, manifold surface).
    pub fn is_closed(&self) -> bool {
        let sides = EdgeSides::new(&self.triangles);
        !self.triangles.is_empty() && sides.edges().all(|e| e.len() == 2)
    }

    /// The border: edges with exactly one triangle, as `([a, b], c)` with `a < b` and `c` that
    /// triangle's third vertex, sorted. Empty for a closed mesh.
    pub fn border_edges(&self) -> Vec<([u32; 2], u32)> {
        EdgeSides::new(&self.triangles)
            .edges()
            .filter_map(|e| match e {
                [only] => Some((only.edge, only.third)),
                _ => None,
            })
            .collect()
    }

    /// Triangles thinner than `ratio` of their longest edge (height over the longest edge over
    /// the longest edge), as (triangle index, that ratio). Such a sliver owns almost no pixels:
    /// the tracker handles it (its edges weigh by area), but it usually means a modelling slip.
    pub fn slivers(&self, ratio: f64) -> Vec<(usize, f64)> {
        self.triangles
            .iter()
            .enumerate()
            .filter_map(|(i, t)| {
                let [a, b, c] = t.map(|v| self.positions[v as usize]);
                let longest = (b - a).norm().max((c - a).norm()).max((c - b).norm());
                if longest == 0.0 {
                    return Some((i, 0.0));
                }
                let height = (b - a).cross(&(c - a)).norm() / longest;
                let r = height / longest;
                (r < ratio).then_some((i, r))
            })
            .collect()
    }

    /// Unnormalised normal of triangle `i` (right-handed: counter-clockwise seen from its front).
    pub fn triangle_normal(&self, i: usize) -> Vector3<f64> {
        let [a, b, c] = self.triangles[i].map(|v| self.positions[v as usize]);
        (b - a).cross(&(c - a))
    }

    /// Length of the diagonal of the axis-aligned bounding box of the surface: of the vertices
    /// some triangle uses (a loose vertex, [`Mesh::loose_vertices`], is no part of the surface
    /// and does not make it larger).
    pub fn bbox_diagonal(&self) -> f64 {
        let used = self.used_vertices();
        if used.iter().all(|&u| u) {
            return bbox_diagonal(&self.positions);
        }
        let on_surface: Vec<Point3<f64>> = self
            .positions
            .iter()
            .zip(&used)
            .filter_map(|(p, &u)| u.then_some(*p))
            .collect();
        bbox_diagonal(&on_surface)
    }

    /// Whether some triangle uses each vertex.
    fn used_vertices(&self) -> Vec<bool> {
        let mut used = vec![false; self.positions.len()];
        for t in &self.triangles {
            for &v in t {
                if let Some(u) = used.get_mut(v as usize) {
                    *u = true;
                }
            }
        }
        used
    }

    /// The vertices no triangle uses (a file's leftover points: an artist's deleted faces, a
    /// pivot): they carry no surface, so no pixel moves them; the tracker's rigid stage carries
    /// them with the mesh as a whole.
    pub fn loose_vertices(&self) -> Vec<usize> {
        self.used_vertices()
            .iter()
            .enumerate()
            .filter_map(|(i, &u)| (!u).then_some(i))
            .collect()
    }
}

/// The mean of `points` (the origin for none).
pub fn centroid(points: &[Point3<f64>]) -> Point3<f64> {
    let n = points.len().max(1) as f64;
    Point3::from(points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n)
}

/// The motion `X' = s·R·X + t` that maps `a` onto `b` (corresponding points) in the least-squares
/// sense: rotation, translation and, when `scaled`, one uniform scale (Umeyama 1991; `s` is 1
/// otherwise, the rigid fit of Kabsch). Reflections are excluded. Degenerate input (no spread)
/// gives the identity rotation and the shift between the centroids.
pub fn best_motion(
    a: &[Point3<f64>],
    b: &[Point3<f64>],
    scaled: bool,
) -> (nalgebra::Matrix3<f64>, Vector3<f64>, f64) {
    use nalgebra::Matrix3;
    let (ca, cb) = (centroid(a).coords, centroid(b).coords);
    let mut cov = Matrix3::zeros();
    let mut var_a = 0.0;
    for (p, q) in a.iter().zip(b) {
        let (da, db) = (p.coords - ca, q.coords - cb);
        cov += db * da.transpose();
        var_a += da.norm_squared();
    }
    let svd = cov.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return (Matrix3::identity(), cb - ca, 1.0);
    };
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * vt;
    let s = if scaled && var_a > 0.0 {
        (svd.singular_values.component_mul(&d.diagonal())).sum() / var_a
    } else {
        1.0
    };
    (r, cb - r * ca * s, s)
}

/// The RMS distance of `points` from `c` (their spread about it).
pub fn rms_radius(points: &[Point3<f64>], c: &Point3<f64>) -> f64 {
    let n = points.len().max(1) as f64;
    (points.iter().map(|p| (p - c).norm_squared()).sum::<f64>() / n).sqrt()
}

/// The RMS distance between corresponding points of `a` and `b` (the vertex error of a mesh
/// against another of the same topology).
pub fn rms_distance(a: &[Point3<f64>], b: &[Point3<f64>]) -> f64 {
    let n = a.len().min(b.len()).max(1) as f64;
    (a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt()
}

/// Length of the diagonal of the axis-aligned bounding box of some points (0 if empty).
pub fn bbox_diagonal(points: &[Point3<f64>]) -> f64 {
    let Some(first) = points.first() else {
        return 0.0;
    };
    let (mut lo, mut hi) = (first.coords, first.coords);
    for p in points {
        lo = lo.inf(&p.coords);
        hi = hi.sup(&p.coords);
    }
    (hi - lo).norm()
}

/// One side of a triangle: the undirected edge it runs (`[a, b]`, `a < b` unless the side is
/// degenerate), the triangle, whether it runs the edge from `a` to `b`, and its third vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Side {
    pub edge: [u32; 2],
    pub triangle: u32,
    pub forward: bool,
    pub third: u32,
}

/// Every side of a triangle list grouped by undirected edge, in edge order and, within an edge,
/// in triangle order: the adjacency every topology query needs (closedness, the border, which
/// triangles meet at an edge). A sorted list rather than a hash map, so that whatever iterates
/// it does so in one fixed order. Hand-written: a few lines, and no crate does exactly this.
pub(crate) struct EdgeSides {
    sides: Vec<Side>,
}

impl EdgeSides {
    pub fn new(triangles: &[[u32; 3]]) -> Self {
        let mut sides = Vec::with_capacity(3 * triangles.len());
        for (i, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                sides.push(Side {
                    edge: if a < b { [a, b] } else { [b, a] },
                    triangle: i as u32,
                    forward: a < b,
                    third: t[(k + 2) % 3],
                });
            }
        }
        // Stable: within an edge the sides stay in triangle order.
        sides.sort_by_key(|s| s.edge);
        EdgeSides { sides }
    }

    /// Each edge with the sides that run it, in edge order.
    pub fn edges(&self) -> impl Iterator<Item = &[Side]> {
        self.sides.chunk_by(|a, b| a.edge == b.edge)
    }

    /// The sides that run `edge` (`[a, b]` with `a < b`); empty when none does.
    pub fn of(&self, edge: [u32; 2]) -> &[Side] {
        let lo = self.sides.partition_point(|s| s.edge < edge);
        let hi = lo + self.sides[lo..].partition_point(|s| s.edge == edge);
        &self.sides[lo..hi]
    }
}

/// A regular grid of `nx × ny` vertices spanning `[0,1]²` in uv, triangulated with alternating
/// diagonals; `place(u, v)` gives each vertex's position. Used by synthetic footage and tests.
pub fn grid(nx: usize, ny: usize, place: impl Fn(f64, f64) -> Point3<f64>) -> Mesh {
    assert!(nx >= 2 && ny >= 2);
    let mut positions = Vec::with_capacity(nx * ny);
    let mut uvs = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let (u, v) = (i as f64 / (nx - 1) as f64, j as f64 / (ny - 1) as f64);
            positions.push(place(u, v));
            uvs.push([u, v]);
        }
    }
    let mut triangles = Vec::with_capacity(2 * (nx - 1) * (ny - 1));
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = (j * nx + i) as u32;
            let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
            if (i + j) % 2 == 0 {
                triangles.push([a, b, d]);
                triangles.push([a, d, c]);
            } else {
                triangles.push([a, b, c]);
                triangles.push([b, d, c]);
            }
        }
    }
    Mesh::with_vertex_uvs(positions, triangles, uvs)
}

#[cfg(test)]
mod tests {
    #[test]
    fn edge_sides_group_each_edge_s_triangles_in_order_and_say_which_way_they_run() {
        // Two triangles sharing the edge 1-2 (run 1→2 by the first, 2→1 by the second).
        let s = super::EdgeSides::new(&[[0, 1, 2], [2, 1, 3]]);
        let shared = s.of([1, 2]);
        assert_eq!(
            shared
                .iter()
                .map(|x| (x.triangle, x.forward, x.third))
                .collect::<Vec<_>>(),
            vec![(0, true, 0), (1, false, 3)]
        );
        assert_eq!(s.of([0, 3]), &[]);
        assert_eq!(s.of([9, 10]), &[]);
        let edges: Vec<[u32; 2]> = s.edges().map(|e| e[0].edge).collect();
        assert_eq!(edges, vec![[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]);
        assert_eq!(s.edges().filter(|e| e.len() == 1).count(), 4);
    }

    #[test]
    fn slivers_are_found_by_their_height() {
        let m = Mesh::new(
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(0.025, 0.0, 0.0),
                Point3::new(0.0125, 1e-7, 0.0),
                Point3::new(0.0125, 0.02, 0.0),
            ],
            vec![[0, 1, 2], [0, 1, 3]],
        );
        let s = m.slivers(1e-3);
        assert_eq!(s.len(), 1);
        assert_eq!(s[0].0, 0);
        assert!((s[0].1 - 4e-6).abs() < 1e-12, "{}", s[0].1);
    }

    use super::*;

    #[test]
    fn grid_topology() {
        let m = grid(3, 3, |u, v| Point3::new(u, v, 0.0));
        assert_eq!(m.positions.len(), 9);
        assert_eq!(m.triangles.len(), 8);
        // 12 outer/inner grid edges + 4 diagonals.
        assert_eq!(m.edges().len(), 16);
        assert!(!m.is_closed());
        // All triangles face +z.
        for i in 0..m.triangles.len() {
            assert!(m.triangle_normal(i).z > 0.0);
        }
        assert!((m.bbox_diagonal() - 2f64.sqrt()).abs() < 1e-12);
        assert!(m.loose_vertices().is_empty());
    }

    #[test]
    fn a_loose_vertex_is_found_and_not_counted_in_the_surfaces_size() {
        let mut m = grid(3, 3, |u, v| Point3::new(u, v, 0.0));
        // A leftover point far away, as a deleted face leaves one in an artist's file.
        m.positions.push(Point3::new(100.0, 0.0, 0.0));
        assert_eq!(m.loose_vertices(), [9]);
        assert!((m.bbox_diagonal() - 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn windings_are_made_consistent_and_closed_surfaces_face_outward() {
        // A tetrahedron wound outward, then with one face turned, then all turned.
        let positions = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let outward = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        let m = |t: Vec<[u32; 3]>| Mesh {
            positions: positions.clone(),
            triangles: t,
            uvs: None,
            corner_uvs: None,
            corner_normals: None,
            polygons: None,
        };
        let (t, turned) = m(outward.clone()).facing_outward();
        assert_eq!((t, turned), (outward.clone(), 0));
        let mut one = outward.clone();
        one[2] = [1, 3, 2];
        let (t, turned) = m(one).facing_outward();
        assert_eq!((t, turned), (outward.clone(), 1));
        let inward: Vec<[u32; 3]> = outward.iter().map(|t| [t[0], t[2], t[1]]).collect();
        let (t, turned) = m(inward).facing_outward();
        assert_eq!((t.clone(), turned), (outward.clone(), 4));
        // Every normal points away from the centroid.
        let c = Point3::new(0.25, 0.25, 0.25);
        let mm = m(t);
        for i in 0..4 {
            let tri = mm.triangles[i].map(|v| mm.positions[v as usize]);
            let centre = (tri[0].coords + tri[1].coords + tri[2].coords) / 3.0;
            assert!(mm.triangle_normal(i).dot(&(centre - c.coords)) > 0.0);
        }
        // An open sheet: made consistent with its first triangle, not turned as a whole.
        let sheet = grid(3, 3, |u, v| Point3::new(u, v, 0.0));
        let mut t = sheet.triangles.clone();
        t[3] = [t[3][0], t[3][2], t[3][1]];
        let (fixed, turned) = sheet.with_triangles(t).facing_outward();
        assert_eq!((fixed, turned), (sheet.triangles.clone(), 1));
    }

    #[test]
    fn a_polygon_meshs_triangles_know_their_faces_and_corners() {
        // A quad, a triangle and a pentagon, fan-triangulated as the readers do.
        let p = |x: f64, y: f64| Point3::new(x, y, 0.0);
        let positions = (0..9).map(|i| p(i as f64, (i % 3) as f64)).collect();
        let triangles = vec![
            [0, 1, 2],
            [0, 2, 3],
            [3, 2, 4],
            [4, 5, 6],
            [4, 6, 7],
            [4, 7, 8],
        ];
        let m = Mesh {
            polygons: Some(Arc::new(vec![4, 3, 5])),
            ..Mesh::new(positions, triangles)
        };
        let faces: Vec<usize> = (0..6).map(|t| m.face_of_triangle(t)).collect();
        assert_eq!(faces, [0, 0, 1, 2, 2, 2]);
        let (counts, corners) = m.face_corners();
        assert_eq!(counts, [4, 3, 5]);
        let vertices: Vec<u32> = corners
            .iter()
            .map(|&(t, k)| m.triangles[t as usize][k as usize])
            .collect();
        assert_eq!(vertices, [0, 1, 2, 3, 3, 2, 4, 4, 5, 6, 7, 8]);
        // Triangles that no longer match the faces are their own faces.
        let other = m.with_triangles(vec![[0, 1, 2]]);
        assert_eq!(other.face_corners().0, [3]);
        let stale = Mesh {
            polygons: Some(Arc::new(vec![4, 4])),
            ..m.clone()
        };
        assert_eq!(stale.face_corners().0, [3; 6]);
        assert_eq!(stale.face_of_triangle(5), 5);
    }

    #[test]
    fn vertices_at_the_same_place_are_welded() {
        // Two triangles of a square, each with its own copies of the diagonal's ends.
        let p = |x: f64, y: f64| Point3::new(x, y, 0.0);
        let m = Mesh {
            positions: vec![
                p(0.0, 0.0),
                p(1.0, 0.0),
                p(1.0, 1.0),
                p(0.0, 0.0),
                p(1.0, 1.0),
                p(0.0, 1.0),
            ],
            triangles: vec![[0, 1, 2], [3, 4, 5]],
            uvs: None,
            corner_uvs: None,
            corner_normals: None,
            polygons: None,
        };
        let (w, of) = m.welded().unwrap();
        assert_eq!(
            w.positions,
            vec![p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]
        );
        assert_eq!(w.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(of, vec![0, 1, 2, 0, 2, 3]);
        assert_eq!(w.edges().len(), 5);
        // Nothing to weld: None. A position a hair apart is another vertex.
        assert!(w.welded().is_none());
        let mut apart = m.clone();
        apart.positions[3].x = 1e-300;
        assert_eq!(apart.welded().unwrap().0.positions.len(), 5);
    }

    #[test]
    fn tetrahedron_is_closed() {
        let p = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let m = Mesh::new(p.clone(), vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]);
        assert!(m.is_closed());
        assert!(m.border_edges().is_empty());
        // Without its base the border is the base's three edges, each with its apex opposite.
        let open = Mesh::new(p, vec![[0, 1, 3], [1, 2, 3], [0, 3, 2]]);
        assert!(!open.is_closed());
        assert_eq!(
            open.border_edges(),
            vec![([0, 1], 3), ([0, 2], 3), ([1, 2], 3)]
        );
    }
}

/// A change of axes between the conventions 3D packages write meshes in: what a mesh looks like
/// when it was written with one up axis and the cameras were calibrated with the other (Blender's
/// world and most photogrammetry are Z-up; Maya, glTF and Blender's OBJ export by default are
/// Y-up). Turns about the world's origin, as the exporters do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisSwap {
    /// A mesh written Y-up read into a Z-up world: `(x, y, z) → (x, −z, y)`.
    YUpToZUp,
    /// A mesh written Z-up read into a Y-up world: `(x, y, z) → (x, z, −y)`.
    ZUpToYUp,
}

impl AxisSwap {
    /// Both swaps, in a fixed order.
    pub const ALL: [AxisSwap; 2] = [AxisSwap::YUpToZUp, AxisSwap::ZUpToYUp];

    /// The point `p` with its axes swapped.
    pub fn apply(self, p: &Point3<f64>) -> Point3<f64> {
        match self {
            AxisSwap::YUpToZUp => Point3::new(p.x, -p.z, p.y),
            AxisSwap::ZUpToYUp => Point3::new(p.x, p.z, -p.y),
        }
    }

    /// `mesh` with its axes swapped (same triangles).
    pub fn mesh(self, mesh: &Mesh) -> Mesh {
        mesh.with_positions(mesh.positions.iter().map(|p| self.apply(p)).collect())
    }

    /// What the swap does, in words a user can act on.
    pub fn describe(self) -> &'static str {
        match self {
            AxisSwap::YUpToZUp => {
                "turned from Y-up to Z-up, (x, y, z) → (x, −z, y): a mesh written Y-up (Blender's OBJ export by default, Maya, glTF) for cameras in a Z-up world"
            }
            AxisSwap::ZUpToYUp => {
                "turned from Z-up to Y-up, (x, y, z) → (x, z, −y): a mesh written Z-up (Blender's world, most scans) for cameras in a Y-up world"
            }
        }
    }
}

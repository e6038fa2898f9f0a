//! An artist-like irregular triangulation of the unit sphere, for the `irregular` preset: the
//! icosphere's even triangulation is coarsened by edge collapses towards a target edge length
//! that varies over the sphere (fine on one side, about four times coarser on the other), its
//! vertices are jittered along the sphere (uneven valences, slivers, short and long edges side by
//! side), and a cap is cut out to leave a hole with a border. Vertices stay on the unit sphere, so
//! they remain material coordinates of the blob's motion.
//!
//! Hand-written: it is a test-data generator, not a mesh-processing library; the crates that
//! decimate meshes (e.g. meshopt) aim at a uniform vertex budget and keep the triangulation
//! regular, which is the opposite of what this is for.

use crate::base::mesh::Mesh;
use crate::synth::texture::mix64;
use nalgebra::{Point3, Vector3};

/// How the triangulation of [`irregular_sphere`] is made.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Irregularity {
    /// Target edge length on the coarse side, as a multiple of the icosphere's edge length.
    pub coarsening: f64,
    /// Direction of the finely triangulated side.
    pub fine_side: Vector3<f64>,
    /// Tangential jitter of each vertex, as a fraction of its shortest edge.
    pub jitter: f64,
    /// Centre direction and angular radius (radians) of the cap cut out as a hole; `None`: closed.
    pub hole: Option<(Vector3<f64>, f64)>,
    pub seed: u64,
}

/// A uniform number in [0, 1) from a hash of `seed` and `i`.
fn unit(seed: u64, i: u64) -> f64 {
    (mix64(seed ^ mix64(i.wrapping_add(0x5EED))) >> 11) as f64 / (1u64 << 53) as f64
}

fn normal(p: &[Vector3<f64>], t: [u32; 3]) -> Vector3<f64> {
    let [a, b, c] = t.map(|v| p[v as usize]);
    (b - a).cross(&(c - a))
}

/// Whether triangle `t` faces outwards with a non-negligible area (on the unit sphere, its
/// normal points along its centroid).
fn outward(p: &[Vector3<f64>], t: [u32; 3]) -> bool {
    let [a, b, c] = t.map(|v| p[v as usize]);
    let n = (b - a).cross(&(c - a));
    let longest = (b - a).norm().max((c - a).norm()).max((c - b).norm());
    n.dot(&(a + b + c)) > 0.0 && n.norm() > 1e-3 * longest * longest
}

/// The irregular sphere (unit radius, counter-clockwise triangles seen from outside).
pub(crate) fn irregular_sphere(icosphere: &Mesh, how: &Irregularity) -> Mesh {
    let mut pos: Vec<Vector3<f64>> = icosphere.positions.iter().map(|p| p.coords).collect();
    let mut tris: Vec<Option<[u32; 3]>> = icosphere.triangles.iter().copied().map(Some).collect();
    let mut alive = vec![true; pos.len()];
    let mut around: Vec<Vec<usize>> = vec![Vec::new(); pos.len()];
    for (i, t) in icosphere.triangles.iter().enumerate() {
        for v in t {
            around[*v as usize].push(i);
        }
    }
    let base = {
        let t = icosphere.triangles[0];
        (pos[t[0] as usize] - pos[t[1] as usize]).norm()
    };
    let fine = how.fine_side.normalize();
    // Target edge length: the icosphere's on the fine side, `coarsening` times it on the other.
    let target = |d: &Vector3<f64>| {
        let s = ((0.6 - d.normalize().dot(&fine)) / 1.2).clamp(0.0, 1.0);
        base * (1.0 + (how.coarsening - 1.0) * s * s * (3.0 - 2.0 * s))
    };

    // Edge collapses, shortest relative to the target first, until none is short enough.
    loop {
        let mut edges: Vec<(f64, u32, u32)> = Vec::new();
        for t in tris.iter().flatten() {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                if a < b {
                    let (pa, pb) = (pos[a as usize], pos[b as usize]);
                    let ratio = (pa - pb).norm() / target(&(pa + pb));
                    if ratio < 0.75 {
                        edges.push((ratio, a, b));
                    }
                }
            }
        }
        edges.sort_by(|x, y| x.0.total_cmp(&y.0).then((x.1, x.2).cmp(&(y.1, y.2))));
        let mut collapsed = 0;
        for (_, a, b) in edges {
            if alive[a as usize]
                && alive[b as usize]
                && collapse(&mut pos, &mut tris, &mut around, &mut alive, a, b, &target)
            {
                collapsed += 1;
            }
        }
        if collapsed == 0 {
            break;
        }
    }

    // Tangential jitter, kept only where every triangle around the vertex stays outward.
    for v in 0..pos.len() {
        if !alive[v] {
            continue;
        }
        let p = pos[v];
        let shortest = around[v]
            .iter()
            .filter_map(|&t| tris[t])
            .flat_map(|t| t.into_iter())
            .filter(|&w| w as usize != v)
            .map(|w| (pos[w as usize] - p).norm())
            .fold(f64::INFINITY, f64::min);
        let helper = if p.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let (e1, e2) = {
            let e1 = p.cross(&helper).normalize();
            (e1, p.cross(&e1))
        };
        let ang = 2.0 * std::f64::consts::PI * unit(how.seed, 2 * v as u64);
        let r = how.jitter * shortest * unit(how.seed, 2 * v as u64 + 1).sqrt();
        pos[v] = (p + (e1 * ang.cos() + e2 * ang.sin()) * r).normalize();
        if !around[v]
            .iter()
            .filter_map(|&t| tris[t])
            .all(|t| outward(&pos, t))
        {
            pos[v] = p;
        }
    }

    // The hole: every triangle whose centroid lies inside the cap.
    if let Some((dir, radius)) = how.hole {
        let dir = dir.normalize();
        for t in tris.iter_mut() {
            if let Some(tri) = t {
                let c = tri.iter().map(|&v| pos[v as usize]).sum::<Vector3<f64>>();
                if c.normalize().dot(&dir) > radius.cos() {
                    *t = None;
                }
            }
        }
    }

    // Compact: drop dead and unused vertices, renumber.
    let mut used = vec![false; pos.len()];
    for t in tris.iter().flatten() {
        for v in t {
            used[*v as usize] = true;
        }
    }
    let mut index = vec![u32::MAX; pos.len()];
    let mut out = Vec::new();
    for (v, p) in pos.iter().enumerate() {
        if used[v] {
            index[v] = out.len() as u32;
            out.push(Point3::from(*p));
        }
    }
    let triangles = tris
        .iter()
        .flatten()
        .map(|t| t.map(|v| index[v as usize]))
        .collect();
    Mesh::new(out, triangles)
}

/// Collapses edge (a, b) into a vertex at its midpoint (kept as `a`) if the surface stays a
/// manifold (the link condition: a and b share exactly the two opposite vertices), every
/// remaining triangle around it stays outward, and no new edge grows past 1.3× its target length.
#[allow(clippy::too_many_arguments)]
fn collapse(
    pos: &mut [Vector3<f64>],
    tris: &mut [Option<[u32; 3]>],
    around: &mut [Vec<usize>],
    alive: &mut [bool],
    a: u32,
    b: u32,
    target: &dyn Fn(&Vector3<f64>) -> f64,
) -> bool {
    let ring = |v: u32, tris: &[Option<[u32; 3]>]| -> Vec<u32> {
        let mut r: Vec<u32> = around[v as usize]
            .iter()
            .filter_map(|&t| tris[t])
            .flat_map(|t| t.into_iter())
            .filter(|&w| w != v)
            .collect();
        r.sort_unstable();
        r.dedup();
        r
    };
    let (ra, rb) = (ring(a, tris), ring(b, tris));
    let shared: Vec<u32> = ra.iter().copied().filter(|w| rb.contains(w)).collect();
    let faces: Vec<usize> = around[a as usize]
        .iter()
        .copied()
        .filter(|&t| tris[t].is_some_and(|tri| tri.contains(&b)))
        .collect();
    if shared.len() != 2 || faces.len() != 2 || ra.len() + rb.len() < 9 {
        return false;
    }
    let m = ((pos[a as usize] + pos[b as usize]) * 0.5).normalize();
    if rb.iter().chain(&ra).any(|&w| {
        w != a && w != b && (pos[w as usize] - m).norm() > 1.3 * target(&(pos[w as usize] + m))
    }) {
        return false;
    }
    let (old_a, old_b) = (pos[a as usize], pos[b as usize]);
    pos[a as usize] = m;
    pos[b as usize] = m;
    let moved: Vec<usize> = around[a as usize]
        .iter()
        .chain(&around[b as usize])
        .copied()
        .filter(|&t| tris[t].is_some() && !faces.contains(&t))
        .collect();
    let ok = moved.iter().all(|&t| {
        let tri = tris[t]
            .expect("live triangle")
            .map(|v| if v == b { a } else { v });
        outward(pos, tri) && normal(pos, tri).norm() > 0.0
    });
    if !ok {
        pos[a as usize] = old_a;
        pos[b as usize] = old_b;
        return false;
    }
    for &t in &faces {
        tris[t] = None;
    }
    for &t in &moved {
        if let Some(tri) = tris[t].as_mut() {
            for v in tri.iter_mut() {
                if *v == b {
                    *v = a;
                }
            }
        }
    }
    let mut list: Vec<usize> = moved;
    list.sort_unstable();
    list.dedup();
    around[a as usize] = list;
    around[b as usize].clear();
    alive[b as usize] = false;
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::icosphere;

    fn make(hole: bool) -> Mesh {
        irregular_sphere(
            &icosphere(4),
            &Irregularity {
                coarsening: 4.0,
                fine_side: Vector3::new(0.3, -0.9, 0.3),
                jitter: 0.3,
                hole: hole.then_some((Vector3::new(-0.6, -0.6, 0.2), 0.2)),
                seed: 7,
            },
        )
    }

    #[test]
    fn the_sphere_stays_a_closed_outward_manifold_with_uneven_edges() {
        let m = make(false);
        assert!(m.is_closed());
        // Euler characteristic of a sphere.
        let (v, e, f) = (m.vertex_count(), m.edges().len(), m.triangles.len());
        assert_eq!(v as i64 - e as i64 + f as i64, 2, "V {v} E {e} F {f}");
        let p: Vec<Vector3<f64>> = m.positions.iter().map(|p| p.coords).collect();
        assert!(p.iter().all(|x| (x.norm() - 1.0).abs() < 1e-12));
        assert!(m.triangles.iter().all(|t| outward(&p, *t)));
        let lengths: Vec<f64> = m
            .edges()
            .iter()
            .map(|[a, b]| (p[*a as usize] - p[*b as usize]).norm())
            .collect();
        let (lo, hi) = lengths
            .iter()
            .fold((f64::MAX, 0f64), |(l, h), &x| (l.min(x), h.max(x)));
        // The icosphere's edges are all within ±20 % of each other; these span a factor > 5.
        assert!(hi / lo > 5.0, "edge lengths {lo}..{hi}");
        assert!(v < 2562 * 3 / 4 && v > 2562 / 5, "{v} vertices");
        // Uneven valences.
        let mut valence = vec![0usize; v];
        for [a, b] in m.edges() {
            valence[a as usize] += 1;
            valence[b as usize] += 1;
        }
        let (vmin, vmax) = (valence.iter().min().unwrap(), valence.iter().max().unwrap());
        assert!(*vmin <= 4 && *vmax >= 8, "valences {vmin}..{vmax}");
    }

    #[test]
    fn the_hole_leaves_one_border_and_the_same_seed_the_same_mesh() {
        let m = make(true);
        assert!(!m.is_closed());
        let mut count = std::collections::HashMap::<[u32; 2], u32>::new();
        for t in &m.triangles {
            for [a, b] in [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]] {
                *count.entry([a.min(b), a.max(b)]).or_default() += 1;
            }
        }
        assert!(count.values().all(|&c| c <= 2), "non-manifold edge");
        let border = count.values().filter(|&&c| c == 1).count();
        assert!(border >= 8, "{border} border edges");
        assert_eq!(make(true), m);
    }
}

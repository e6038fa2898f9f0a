//! Which mesh vertices a camera sees: in front of it, inside its image and not hidden by another
//! part of the mesh. The last point is decided by the z-buffered index buffer of `raster` (the
//! one the Model Flow tracker uses), looked up at the pixel centre nearest to each vertex. The
//! optical-flow baseline (`baseline`) uses it to choose which vertices each camera tracks.

use crate::base::camera::Projection;
use crate::base::raster::{rasterize, NONE};
use nalgebra::Point3;

/// Relative depth tolerance of the vertex test: a vertex counts as visible if it is no more than
/// this fraction of its depth behind the nearest surface at its pixel.
const DEPTH_TOLERANCE: f64 = 1e-3;

/// For each vertex, whether the camera `proj` with an image of `width`×`height` sees it.
///
/// A vertex is visible when it projects in front of the camera and inside the image, and at its
/// nearest pixel centre either nothing is drawn, the nearest surface is one of its own triangles,
/// or the nearest surface is not in front of it by more than [`DEPTH_TOLERANCE`].
pub fn visible_vertices(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    proj: &Projection,
    width: u32,
    height: u32,
) -> Vec<bool> {
    let (w, h) = (width as usize, height as usize);
    // Projected vertices: (u, v, depth); depth <= 0 marks a vertex behind the camera.
    let projected: Vec<[f64; 3]> = positions
        .iter()
        .map(|x| {
            let p = proj.project_h(x);
            if p.z > 0.0 {
                [p.x / p.z, p.y / p.z, p.z]
            } else {
                [f64::NAN, f64::NAN, p.z]
            }
        })
        .collect();
    let ib = rasterize(positions, triangles, proj, w, h);
    projected
        .iter()
        .enumerate()
        .map(|(vi, &[u, v, z])| {
            if z <= 0.0 || !(u >= -0.5 && v >= -0.5 && u < w as f64 - 0.5 && v < h as f64 - 0.5) {
                return false;
            }
            let x = (u.round().max(0.0) as usize).min(w - 1);
            let y = (v.round().max(0.0) as usize).min(h - 1);
            let owner = ib.owner_at(x, y);
            owner == NONE
                || triangles[owner as usize].contains(&(vi as u32))
                || z <= ib.depth_at(x, y) as f64 * (1.0 + DEPTH_TOLERANCE)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::mesh::grid;
    use nalgebra::{Matrix3, Vector3};

    fn camera() -> Projection {
        let k = Matrix3::new(200.0, 0.0, 49.5, 0.0, 200.0, 49.5, 0.0, 0.0, 1.0);
        Projection::from_krt(&k, &Matrix3::identity(), &Vector3::new(0.0, 0.0, 4.0)).unwrap()
    }

    #[test]
    fn a_front_plate_hides_the_back_plate() {
        // Back plate at z = 1 spanning [-0.5, 0.5]², front plate at z = 0 covering x < 0.
        let back = grid(5, 5, |u, v| Point3::new(u - 0.5, v - 0.5, 1.0));
        let front = grid(3, 3, |u, v| {
            Point3::new(-0.8 + 0.78 * u, v - 0.5 + 0.0, 0.0)
        });
        let mut positions = back.positions.clone();
        let mut triangles = back.triangles.clone();
        let off = positions.len() as u32;
        positions.extend(front.positions.iter().copied());
        triangles.extend(front.triangles.iter().map(|t| t.map(|i| i + off)));
        // Stretch the front plate vertically so that it covers the back plate's rows.
        for p in &mut positions[off as usize..] {
            p.y *= 1.6;
        }
        let vis = visible_vertices(&positions, &triangles, &camera(), 100, 100);
        for (i, p) in back.positions.iter().enumerate() {
            let hidden = p.x < -0.1;
            assert_eq!(vis[i], !hidden, "back vertex {i} at {p:?}");
        }
        assert!(
            vis[off as usize..].iter().all(|&v| v),
            "front plate is fully visible"
        );
    }

    #[test]
    fn vertices_outside_the_image_or_behind_are_not_visible() {
        let positions = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(5.0, 0.0, 0.0),
            Point3::new(0.0, 0.0, -6.0),
        ];
        let vis = visible_vertices(&positions, &[[0, 1, 2]], &camera(), 100, 100);
        assert_eq!(vis, vec![true, false, false]);
    }
}

//! How much of the mesh's surface the cameras see at a frame, and by how many of them. The
//! tracker fixes a surface point's depth from the images only where two or more cameras see it;
//! where one camera alone sees it, its motion along that camera's rays is held by the
//! regularisers alone and drifts over a shot (docs/tracker.md, "Where depth comes from"). A rig
//! whose views barely overlap is worth knowing about before a long shot is tracked.
//!
//! A triangle counts as seen by a camera when it owns a pixel the tracker could compare there:
//! the same z-buffered index buffer, facing test and margin as the tracker's templates
//! (`patch::trackable_pixels`), from geometry alone (no images are read).

use crate::base::camera::Camera;
use crate::base::mesh::Mesh;
use crate::tracker::patch::{trackable_pixels, PatchOptions};
use crate::tracker::TrackOptions;
use rayon::prelude::*;
use serde::Serialize;

/// Fractions of the mesh's surface area (at the frame's positions) by how many cameras see it.
/// They sum to 1 (all 0 for a mesh without area).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Coverage {
    /// Seen by two or more cameras: depth from the images.
    pub two_or_more: f64,
    /// Seen by exactly one camera: depth from the regularisers alone.
    pub one: f64,
    /// Seen by no camera (facing away, hidden, outside every image).
    pub none: f64,
}

impl Coverage {
    /// The share of the *seen* surface that only one camera sees (0 when nothing is seen).
    pub fn one_camera_share(&self) -> f64 {
        let seen = self.two_or_more + self.one;
        if seen > 0.0 {
            self.one / seen
        } else {
            0.0
        }
    }
}

/// The coverage of `mesh` (its positions as they are at `frame`) by `cameras` at `frame`, with
/// the tracker's facing test and margin from `opts` (`min_cos`, `margin`).
pub fn coverage(mesh: &Mesh, cameras: &[Camera], frame: u32, opts: &TrackOptions) -> Coverage {
    // The mesh as the tracker works on it (vertices merged, triangles wound outward).
    let (mesh, _) = crate::tracker::sequence::tracked_mesh(mesh);
    let mesh = &mesh;
    let triangles = &mesh.triangles;
    let popts = PatchOptions {
        margin: opts.margin,
        min_cos: opts.min_cos,
        two_sided: !mesh.is_closed(),
        checkerboard: false,
        stride: 1,
    };
    // Per camera (in parallel), which triangles own a comparable pixel; then how many cameras.
    let seen: Vec<Vec<bool>> = cameras
        .par_iter()
        .map(|cam| {
            let size = (cam.width as usize, cam.height as usize);
            let (ib, mask) =
                trackable_pixels(&mesh.positions, triangles, cam.at(frame), size, &popts);
            let mut seen = vec![false; triangles.len()];
            for (&owner, _) in ib.owners().iter().zip(&mask).filter(|(_, m)| **m) {
                seen[owner as usize] = true;
            }
            seen
        })
        .collect();
    let mut count = vec![0usize; triangles.len()];
    for s in &seen {
        for (c, &v) in count.iter_mut().zip(s) {
            *c += usize::from(v);
        }
    }
    let mut area = [0.0f64; 3];
    for (i, &c) in count.iter().enumerate() {
        area[c.min(2)] += 0.5 * mesh.triangle_normal(i).norm();
    }
    let total: f64 = area.iter().sum();
    if total <= 0.0 || !total.is_finite() {
        return Coverage::default();
    }
    Coverage {
        two_or_more: area[2] / total,
        one: area[1] / total,
        none: area[0] / total,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{Preset, SynthOptions, Synthetic};

    fn rig(preset: Preset, cameras: usize) -> Coverage {
        let syn = Synthetic::generate(&SynthOptions {
            preset,
            cameras: Some(cameras),
            width: 320,
            height: 240,
            frames: 1,
            supersample: 1,
            ..SynthOptions::default()
        })
        .unwrap();
        coverage(&syn.mesh, &syn.cameras, 0, &TrackOptions::default())
    }

    #[test]
    fn a_rig_whose_cameras_face_each_other_across_a_closed_surface_shares_no_view_of_it() {
        // The blob with two cameras on opposite sides: each sees its own half.
        let c = rig(Preset::Blob, 2);
        assert!(c.two_or_more < 0.02, "{c:?}");
        assert!(c.one > 0.5, "{c:?}");
        assert!(c.one_camera_share() > 0.95, "{c:?}");
        assert!((c.two_or_more + c.one + c.none - 1.0).abs() < 1e-12);
    }

    #[test]
    fn two_cameras_in_front_of_a_sheet_both_see_nearly_all_of_it() {
        let c = rig(Preset::Cloth, 2);
        assert!(c.two_or_more > 0.9, "{c:?}");
        assert!(c.one_camera_share() < 0.1, "{c:?}");
        // Four cameras around the blob: most of what is seen is seen twice.
        let b = rig(Preset::Blob, 4);
        assert!(b.two_or_more > b.one, "{b:?}");
    }
}

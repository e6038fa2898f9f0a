//! The cameras' images shifted by the fraction of a pixel at which they agree best about the
//! first mesh. A calibration is good to some tenths of a pixel (a principal point a pixel off,
//! another renderer's pixel-centre convention half a pixel from ours, a rotation a hundredth of
//! a degree off). A camera compared with its own earlier frames does not see that, but the
//! comparisons between cameras in the frame being solved (`TrackOptions::stereo`) do, and hold
//! the mesh where the miscalibrated views agree instead of where the surface is: two cameras
//! 12° apart with one principal point a pixel off moved the tracked cloth by 0.3 % of its size
//! in every frame (docs/tracker.md, "Cameras that disagree by a fraction of a pixel"). The
//! first mesh is lined up with the first frame, so it is taken as the truth: each camera's image
//! shift (two unknowns per camera) at which every pair of cameras that sees the mesh together
//! agrees best about it is fitted, from each pair's cost modelled as a quadratic in its two
//! cameras' shifts (by finite differences), the pairs' models summed and solved within the
//! shifts the cost holds firmly. Those it holds loosely (every camera shifted alike, which
//! moving the mesh would also do) stay as calibrated. Knows patches, projections and images;
//! not the tracker's solve.

use crate::base::{Camera, Mesh, RgbImage};
use crate::tracker::offset::{frame_of, not_blank, scan_start, view_pairs, Frame, MIN_COMPARED};
use crate::tracker::pyramid::{camera_level, level_skips};
use nalgebra::{DMatrix, DVector, Matrix4, Vector4};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The image shifts at which the cameras agree best about the first mesh ([`camera_shifts`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraShifts {
    /// Per camera, in the scene's order: how far its images are shifted (pixels of its frames,
    /// x right, y down) from where its calibration puts them, as the tracker sees them; `[0, 0]`
    /// for a camera compared with no other.
    pub shifts: Vec<[f64; 2]>,
    /// The pairs of cameras compared.
    pub pairs: usize,
    /// The pairs' mean cost per pixel, summed, as calibrated and with the shifts (not measured
    /// with a shift over [`MAX_SHIFT_PX`]: `cost_after` is then `cost_before`).
    pub cost_before: f64,
    pub cost_after: f64,
    /// Whether the shifts were applied: not when they lower the cost by less than
    /// [`MIN_GAIN`] (what the images' noise, a glossy surface's highlights and the pixels
    /// compared changing with the shift make of an exact calibration), nor when one is larger
    /// than [`MAX_SHIFT_PX`] (not a calibration's fraction of a pixel; the first-mesh checks
    /// name what is wrong then).
    pub applied: bool,
}

impl CameraShifts {
    /// The largest disagreement between two cameras that the shifts take out, in pixels: the
    /// largest difference between two cameras' shifts.
    pub fn largest(&self) -> f64 {
        let mut m = 0.0f64;
        for a in &self.shifts {
            for b in &self.shifts {
                m = m.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt());
            }
        }
        m
    }
}

/// The largest shift of one camera that is applied, in pixels of its frames.
pub const MAX_SHIFT_PX: f64 = 3.0;
/// The least share by which the shifts must lower the cameras' cost to be applied. Measured
/// (`camera_shifts` at the first frame): principal points moved by half a pixel and by one on
/// the Blender cloth sample 95 and 99 %, the real board's calibration 19 %; the Blender hard
/// sample's exact calibration (a glossy object), PNG and JPEG, 0.8 %, with shifts of 0.3–0.5
/// px that are not there.
pub const MIN_GAIN: f64 = 0.05;
/// Of each patch's pixels, every this many are compared.
const STRIDE: usize = 4;
/// The finite differences' steps, one round each, in pixels of the level compared. A round
/// after the first only when the one before moved a camera by more than `REFINE`: one Newton
/// step from a 1 px stencil overshoots a shift of a pixel by a quarter.
const STEPS: [f64; 2] = [1.0, 0.5];
/// The least step of a round (pixels of the level compared) that asks for the next round.
const REFINE: f64 = 0.25;
/// Shifts whose curvature is under this share of the firmest's are left as they are.
const FIRM: f64 = 0.2;

/// The 15 points at which a pair's cost is evaluated to fit its quadratic in the pair's four
/// shifts (`[dx_a, dy_a, dx_b, dy_b]`): the centre, `±h` along each, `h` along two at once.
fn stencil(h: f64) -> Vec<Vector4<f64>> {
    let e = |k: usize| {
        let mut v = Vector4::zeros();
        v[k] = h;
        v
    };
    let mut p = vec![Vector4::zeros()];
    for k in 0..4 {
        p.push(e(k));
        p.push(-e(k));
    }
    for a in 0..4 {
        for b in a + 1..4 {
            p.push(e(a) + e(b));
        }
    }
    p
}

/// The gradient and curvature of the cost at the stencil's centre from its values `f` at
/// [`stencil`]`(h)`'s points (central differences; the mixed terms one-sided).
fn quadratic(f: &[f64], h: f64) -> (Vector4<f64>, Matrix4<f64>) {
    let mut g = Vector4::zeros();
    let mut c = Matrix4::zeros();
    let plus = |k: usize| f[1 + 2 * k];
    let minus = |k: usize| f[2 + 2 * k];
    for k in 0..4 {
        g[k] = (plus(k) - minus(k)) / (2.0 * h);
        c[(k, k)] = (plus(k) - 2.0 * f[0] + minus(k)) / (h * h);
    }
    let mut i = 9;
    for a in 0..4 {
        for b in a + 1..4 {
            let v = (f[i] - plus(a) - plus(b) + f[0]) / (h * h);
            c[(a, b)] = v;
            c[(b, a)] = v;
            i += 1;
        }
    }
    (g, c)
}

/// The shifts of `cameras`' images at which they agree best about `mesh` at `frame` (`images`:
/// one per camera, pinhole) ([`CameraShifts`]): the pairs of cameras `view_agreement` compares
/// (blank images left out; each camera with the three that see most of the mesh with it), each
/// one's pixels (every `STRIDE`-th) warped into the other through the mesh, up to the gains,
/// the convex loss, at most 1280 px wide. `None` when no two cameras compare `MIN_COMPARED`
/// pixels.
pub fn camera_shifts(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
) -> Option<CameraShifts> {
    if cameras.len() < 2 || images.len() != cameras.len() {
        return None;
    }
    let z = scan_start(mesh, cameras, images);
    let m = &z.m;
    let all = frame_of(cameras, frame, &z.pyramids, z.level, &m.positions, &z.blank)?;
    let seen: Vec<usize> = (0..cameras.len()).filter(|&c| !z.blank[c]).collect();
    let n = seen.len();
    // A pair's mean cost per pixel and the pixels compared, its cameras shifted by `da` and
    // `db` (pixels of the level compared).
    let cost = |a: usize, b: usize, da: [f64; 2], db: [f64; 2]| {
        let f = Frame {
            targets: vec![all.targets[a], all.targets[b]],
            projections: vec![
                all.projections[a].shifted(da),
                all.projections[b].shifted(db),
            ],
            per_unit: all.per_unit,
            opts: all.opts,
            involving: None,
            stride: STRIDE,
        };
        f.scan(
            &m.positions,
            &z.normals,
            &m.triangles,
            &z.edges,
            z.closed,
            0..=0,
        )
        .pop()
        .flatten()
        .filter(|s| s.cost.is_finite())
        .map(|s| (s.cost, s.pixels))
    };
    let pairs: Vec<(usize, usize)> = view_pairs(
        &not_blank(cameras, &z.blank),
        frame,
        &m.positions,
        &z.normals,
        z.closed,
    )
    .into_par_iter()
    .filter(|&(a, b)| cost(a, b, [0.0; 2], [0.0; 2]).is_some_and(|(_, px)| px >= MIN_COMPARED))
    .collect();
    if pairs.is_empty() {
        return None;
    }
    // The pairs' costs summed in their order (whatever the threads).
    let total = |d: &[[f64; 2]]| -> Option<f64> {
        let each: Option<Vec<f64>> = pairs
            .par_iter()
            .map(|&(a, b)| cost(a, b, d[a], d[b]).map(|c| c.0))
            .collect();
        each.map(|v| v.iter().sum())
    };
    let mut before = None;
    let mut d = vec![[0.0f64; 2]; n];
    for &h in &STEPS {
        let points = stencil(h);
        let fits: Vec<Option<Vec<f64>>> = pairs
            .par_iter()
            .map(|&(a, b)| {
                points
                    .iter()
                    .map(|p| {
                        let da = [d[a][0] + p[0], d[a][1] + p[1]];
                        let db = [d[b][0] + p[2], d[b][1] + p[3]];
                        cost(a, b, da, db).map(|c| c.0)
                    })
                    .collect()
            })
            .collect();
        // The first round's centres: the pairs as calibrated.
        if before.is_none() {
            let centres: Option<Vec<f64>> = fits.iter().map(|f| f.as_ref().map(|f| f[0])).collect();
            before = Some(centres?.iter().sum::<f64>());
        }
        let mut curve = DMatrix::<f64>::zeros(2 * n, 2 * n);
        let mut grad = DVector::<f64>::zeros(2 * n);
        for (&(a, b), f) in pairs.iter().zip(fits) {
            let Some((g, c)) = f.map(|f| quadratic(&f, h)) else {
                continue;
            };
            let at = [2 * a, 2 * a + 1, 2 * b, 2 * b + 1];
            for r in 0..4 {
                grad[at[r]] += g[r];
                for k in 0..4 {
                    curve[(at[r], at[k])] += c[(r, k)];
                }
            }
        }
        // Newton's step within the shifts the cost holds firmly.
        let eig = curve.symmetric_eigen();
        let firmest = eig.eigenvalues.max();
        if !(firmest.is_finite() && firmest > 0.0) {
            break;
        }
        let mut step = DVector::<f64>::zeros(2 * n);
        for (k, &l) in eig.eigenvalues.iter().enumerate() {
            if l > FIRM * firmest {
                let v = eig.eigenvectors.column(k);
                step -= v * (v.dot(&grad) / l);
            }
        }
        let mut largest = 0.0f64;
        for (c, dc) in d.iter_mut().enumerate() {
            dc[0] += step[2 * c];
            dc[1] += step[2 * c + 1];
            largest = largest.max(step[2 * c].hypot(step[2 * c + 1]));
        }
        if largest <= REFINE {
            break;
        }
    }
    let before = before?;
    // Each camera's shift in pixels of its own level (`offset::frame_of`: a smaller camera's
    // level is finer by its skip), then of its own images.
    let skips = level_skips(cameras.iter().map(|c| (c.width, c.height)));
    let mut shifts = vec![[0.0; 2]; cameras.len()];
    for (i, &c) in seen.iter().enumerate() {
        let scale = f64::from(1u32 << camera_level(z.level, skips[c]));
        shifts[c] = [d[i][0] * scale, d[i][1] * scale];
    }
    let within = shifts
        .iter()
        .all(|s| s.iter().all(|v| v.is_finite()) && s[0].hypot(s[1]) <= MAX_SHIFT_PX);
    let after = if within { total(&d) } else { None };
    // (A rig whose pairs compare only flat colour, cost 0, has nothing to gain.)
    let applied = before > 0.0 && after.is_some_and(|a| a <= (1.0 - MIN_GAIN) * before);
    Some(CameraShifts {
        shifts,
        pairs: pairs.len(),
        cost_before: before,
        cost_after: after.unwrap_or(before),
        applied,
    })
}

#[cfg(test)]
mod tests {
    use super::camera_shifts;
    use crate::base::RgbImage;
    use crate::synth::{Preset, SynthOptions, Synthetic};

    fn footage(preset: Preset, cameras: usize) -> (Synthetic, Vec<RgbImage>) {
        let syn = Synthetic::generate(&SynthOptions {
            preset,
            cameras: Some(cameras),
            width: 320,
            height: 240,
            frames: 2,
            ..SynthOptions::default()
        })
        .unwrap();
        let images = (0..cameras).map(|c| syn.render(c, 0)).collect();
        (syn, images)
    }

    #[test]
    fn a_principal_point_a_fraction_of_a_pixel_off_is_found_and_an_exact_one_left() {
        // The cloth seen by two cameras 12° apart. Camera 0's calibration puts the surface
        // (0.7, −0.4) px from where its image shows it: the shifts that make the two agree
        // move camera 0 by (−0.7, +0.4) against camera 1, whichever way they share it.
        let (syn, images) = footage(Preset::Cloth, 2);
        let exact = camera_shifts(&syn.mesh, &syn.cameras, 0, &images).unwrap();
        assert!(!exact.applied && exact.pairs == 1, "{exact:?}");
        let mut off = syn.cameras.clone();
        off[0] = off[0].shifted([0.7, -0.4]);
        let found = camera_shifts(&syn.mesh, &off, 0, &images).unwrap();
        let (a, b) = (found.shifts[0], found.shifts[1]);
        let rel = [a[0] - b[0], a[1] - b[1]];
        assert!(
            found.applied && (rel[0] + 0.7).abs() < 0.1 && (rel[1] - 0.4).abs() < 0.1,
            "{found:?}"
        );
        assert!(found.cost_after < 0.5 * found.cost_before, "{found:?}");
        assert!(
            (found.largest() - 0.7f64.hypot(0.4)).abs() < 0.1,
            "{found:?}"
        );
    }

    #[test]
    fn one_camera_of_a_row_off_by_half_a_pixel_is_the_one_shifted() {
        // Four cameras in a row in front of the cloth; camera 2's calibration half a pixel off
        // in both axes. Its shift against each other camera is the half pixel back; the
        // others' against each other stay within a tenth of a pixel.
        let (syn, images) = footage(Preset::Cloth, 4);
        let mut off = syn.cameras.clone();
        off[2] = off[2].shifted([0.5, 0.5]);
        let found = camera_shifts(&syn.mesh, &off, 0, &images).unwrap();
        assert!(found.applied, "{found:?}");
        let s = &found.shifts;
        let rel = |a: usize, b: usize| [s[a][0] - s[b][0], s[a][1] - s[b][1]];
        for other in [0, 1, 3] {
            let r = rel(2, other);
            assert!(
                (r[0] + 0.5).abs() < 0.1 && (r[1] + 0.5).abs() < 0.1,
                "{other}: {r:?} {found:?}"
            );
        }
        for (a, b) in [(0, 1), (0, 3), (1, 3)] {
            let r = rel(a, b);
            assert!(r[0].hypot(r[1]) < 0.1, "{a} {b}: {r:?} {found:?}");
        }
    }
}

//! `align`: a mesh placed 5 % of its size and 10° off is brought back onto the surface the
//! cameras see; what the images cannot fix (a flat sheet's position within its plane) is kept
//! as placed and named.

use modelflow::base::{centroid, rms_distance};
use modelflow::input::Scene;
use modelflow::synth::{Preset, SynthOptions, Synthetic};
use modelflow::tracker::{align, perturb, placement, AlignOptions, MotionKind};
use nalgebra::{Point3, Vector3};
use std::path::Path;

fn rms_pct(a: &[Point3<f64>], b: &[Point3<f64>], size: f64) -> f64 {
    100.0 * rms_distance(a, b) / size
}

/// The Blender cloth sample's scene (from fixtures/), its frame-0 images and true positions.
fn blender_cloth() -> (Scene, Vec<modelflow::RgbImage>, Vec<Point3<f64>>) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/blender-cloth-sample");
    let scene = Scene::load(&dir.join("scene.json")).unwrap();
    let images = scene.load_images(0).unwrap();
    let truth = scene.ground_truth(0).unwrap().unwrap().positions;
    (scene, images, truth)
}

/// The unit normal of the (flat) sheet `p`: from its grid's first row and its last vertex.
fn sheet_normal(p: &[Point3<f64>]) -> Vector3<f64> {
    (p[40] - p[0]).cross(&(p[p.len() - 1] - p[0])).normalize()
}

fn footage(preset: Preset) -> (Synthetic, Vec<modelflow::RgbImage>) {
    footage_with(preset, None)
}

/// `preset`'s first frame at 320×240, with `cameras` cameras (the preset's own without).
fn footage_with(preset: Preset, cameras: Option<usize>) -> (Synthetic, Vec<modelflow::RgbImage>) {
    let syn = Synthetic::generate(&SynthOptions {
        preset,
        cameras,
        width: 320,
        height: 240,
        frames: 1,
        ..SynthOptions::default()
    })
    .unwrap();
    let images = (0..syn.cameras.len()).map(|c| syn.render(c, 0)).collect();
    (syn, images)
}

#[test]
fn misplaced_meshes_are_brought_back_within_a_tenth_of_a_percent() {
    // A closed surface on an artist-like triangulation, and the waving cloth (open, two-sided).
    for (preset, seed) in [(Preset::Irregular, 1), (Preset::Cloth, 2)] {
        let (syn, images) = footage(preset);
        let size = syn.mesh.bbox_diagonal();
        let start = syn
            .mesh
            .with_positions(perturb(&syn.mesh, 0.05, 10.0, seed));
        let before = rms_pct(&start.positions, &syn.mesh.positions, size);
        assert!(
            before > 4.0,
            "{preset:?}: the misplacement is real: {before} %"
        );
        let a = align(&start, &syn.cameras, 0, &images, &AlignOptions::default()).unwrap();
        let after = rms_pct(&a.positions, &syn.mesh.positions, size);
        assert!(after < 0.1, "{preset:?}: {before:.2} % → {after:.3} %");
        assert!(
            (a.angle_deg() - 10.0).abs() < 0.5,
            "{preset:?}: turned back by {}°",
            a.angle_deg()
        );
        assert!((a.scale - 1.0).abs() < 1e-12);
    }
}

/// `preset` seen by three cameras 120° apart at 320×240 (a fifth of the surface they see is
/// seen by two of them, in bands near the silhouettes), its mesh misplaced 5 % of its size and
/// 10° (`perturb`, `seed`).
fn three_cameras(
    preset: Preset,
    seed: u64,
) -> (Synthetic, Vec<modelflow::RgbImage>, modelflow::Mesh, f64) {
    let (syn, images) = footage_with(preset, Some(3));
    let size = syn.mesh.bbox_diagonal();
    let start = syn
        .mesh
        .with_positions(perturb(&syn.mesh, 0.05, 10.0, seed));
    (syn, images, start, size)
}

#[test]
fn three_cameras_around_a_mesh_misplaced_bring_it_back_where_the_plain_pass_is_drawn_off() {
    // From this misplacement the plain coarse-to-fine pass is drawn partly over the plain
    // background (there the bands compare background with background) and ends 21 % of the
    // size off; the pass that weighs each patch by its texture comes back, and the cameras
    // agree there many times better per unit of texture, so it is kept.
    let (syn, images, start, size) = three_cameras(Preset::Irregular, 2);
    let plain = AlignOptions {
        texture_pass: false,
        search: false,
        ..AlignOptions::default()
    };
    let lost = align(&start, &syn.cameras, 0, &images, &plain).unwrap();
    let lost_pct = rms_pct(&lost.positions, &syn.mesh.positions, size);
    assert!(
        lost_pct > 2.0,
        "the plain pass alone is drawn off here: {lost_pct:.3} %"
    );
    assert_eq!((lost.passes.len(), lost.kept_pass), (1, 0));
    let a = align(&start, &syn.cameras, 0, &images, &AlignOptions::default()).unwrap();
    let after = rms_pct(&a.positions, &syn.mesh.positions, size);
    assert!(
        after < 0.1,
        "5 % and 10° off → {after:.3} % (plain pass {lost_pct:.2} %)"
    );
    assert_eq!(a.passes.len(), 2 + modelflow::tracker::SEARCH_STARTS);
    let (kept, first) = (a.passes[a.kept_pass], a.passes[0]);
    assert!(kept.weighed && a.kept_pass > 0, "{:?}", a.passes);
    assert!(
        kept.per_texture * modelflow::tracker::TEXTURE_PASS_GAIN <= first.per_texture,
        "{:?}",
        a.passes
    );
}

#[test]
fn a_misplacement_beyond_both_passes_reach_is_found_by_the_search_around_it() {
    // The blob seen by three cameras, from a misplacement that draws both passes from the
    // placement given over the background (14 % off); one of the starts around it comes back.
    let (syn, images, start, size) = three_cameras(Preset::Blob, 1);
    let no_search = AlignOptions {
        search: false,
        ..AlignOptions::default()
    };
    let lost = align(&start, &syn.cameras, 0, &images, &no_search).unwrap();
    let lost_pct = rms_pct(&lost.positions, &syn.mesh.positions, size);
    assert!(
        lost_pct > 2.0,
        "both passes are drawn off here: {lost_pct:.3} %"
    );
    let a = align(&start, &syn.cameras, 0, &images, &AlignOptions::default()).unwrap();
    let after = rms_pct(&a.positions, &syn.mesh.positions, size);
    assert!(
        after < 0.1,
        "5 % and 10° off → {after:.3} % (without the search {lost_pct:.2} %)"
    );
    let kept = a.passes[a.kept_pass];
    assert!(
        a.kept_pass >= 2 && kept.shift.iter().chain(&kept.turn).any(|v| *v != 0.0),
        "kept a start around the placement given: {kept:?}"
    );
}

#[test]
fn a_nearly_round_surface_in_noisy_footage_is_kept_where_it_is_and_not_called_misplaced() {
    // The limb (a capsule) in footage with 2 % noise: `align` from the true placement spins it
    // about its axis, which the images hold loosely, to where the noise puts it (1.3 % of its
    // size here), and there the cameras agree *worse* with each other than where it was (1 %;
    // 10 of 12 noise levels and seeds tried end worse). So `align` keeps the placement given,
    // and `track`'s placement check does not call it misplaced. Moved 3 % of its size across
    // the axis, the mesh is misplaced, and named.
    let syn = Synthetic::generate(&SynthOptions {
        preset: Preset::Limb,
        width: 320,
        height: 240,
        frames: 2,
        noise: 0.02,
        seed: 2,
        ..SynthOptions::default()
    })
    .unwrap();
    let images: Vec<_> = (0..syn.cameras.len()).map(|c| syn.render(c, 0)).collect();
    let size = syn.mesh.bbox_diagonal();
    let a = align(
        &syn.mesh,
        &syn.cameras,
        0,
        &images,
        &AlignOptions::default(),
    )
    .unwrap();
    let g = a.agreement.expect("the cameras compare the mesh");
    assert!(g.kept_given && g.after > g.before, "{g:?}");
    assert_eq!(a.positions, syn.mesh.positions);
    assert!(
        a.loose.iter().any(|m| m.kind == MotionKind::Rotation),
        "{:?}",
        a.loose
    );
    let p = placement(&syn.mesh, &syn.cameras, 0, &images).unwrap();
    assert!(!p.is_off() && p.fraction < 1e-9, "{p:?}");
    let axis = Vector3::from(a.loose[0].axis);
    let across = axis.cross(&Vector3::z()).normalize();
    let moved = syn.mesh.with_positions(
        syn.mesh
            .positions
            .iter()
            .map(|q| q + across * (0.03 * size))
            .collect(),
    );
    let p = placement(&moved, &syn.cameras, 0, &images).unwrap();
    assert!(p.is_off() && (p.fraction - 0.03).abs() < 0.006, "{p:?}");
    assert!(p.agreement_gain > 1.3, "{p:?}");
}

#[test]
fn two_noisy_cameras_that_share_a_rim_do_not_call_a_true_mesh_misplaced() {
    // The irregular blob seen by two cameras that share 4 % of its surface, in 10 % noise:
    // `align` from the true placement moves it 2.2 % of its size to where the cameras agree
    // only 2.6 % better, within what the changing set of pixels compared gives by itself.
    // The check wanted the user to line up a true mesh (and `align` would have moved it off).
    let syn = Synthetic::generate(&SynthOptions {
        preset: Preset::Irregular,
        cameras: Some(2),
        width: 480,
        height: 360,
        frames: 15,
        noise: 0.1,
        ..SynthOptions::default()
    })
    .unwrap();
    // As `synth` writes them: 8-bit PNGs.
    let images: Vec<_> = (0..syn.cameras.len())
        .map(|c| {
            let mut img = syn.render(c, 0);
            for px in img.pixels_mut() {
                *px = px.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() / 255.0);
            }
            img
        })
        .collect();
    let p = placement(&syn.mesh, &syn.cameras, 0, &images).unwrap();
    assert!(
        p.fraction > 0.01 && p.agreement_gain < modelflow::tracker::PLACEMENT_MIN_GAIN,
        "the case this guards: {p:?}"
    );
    assert!(!p.is_off(), "{p:?}");
}

#[test]
fn the_scale_is_found_when_asked() {
    let (syn, images) = footage(Preset::Blob);
    let size = syn.mesh.bbox_diagonal();
    let moved = perturb(&syn.mesh, 0.04, 8.0, 3);
    let n = moved.len() as f64;
    let c: Vector3<f64> = moved.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n;
    let grown: Vec<Point3<f64>> = moved
        .iter()
        .map(|p| Point3::from(c + (p.coords - c) * 1.06))
        .collect();
    let start = syn.mesh.with_positions(grown);
    let opts = AlignOptions {
        scale: true,
        ..AlignOptions::default()
    };
    let a = align(&start, &syn.cameras, 0, &images, &opts).unwrap();
    let after = rms_pct(&a.positions, &syn.mesh.positions, size);
    assert!(after < 0.1, "{after:.3} %");
    assert!((a.scale - 1.0 / 1.06).abs() < 2e-3, "scale {}", a.scale);
    // Without --scale the pose alone cannot undo it.
    let rigid = align(&start, &syn.cameras, 0, &images, &AlignOptions::default()).unwrap();
    assert!(rms_pct(&rigid.positions, &syn.mesh.positions, size) > 0.5);
}

#[test]
fn a_flat_sheet_gets_its_plane_back_and_keeps_its_place_in_it() {
    // The Blender cloth sample's first frame is exactly flat: photo-consistency fixes the plane
    // (depth and tilt) but not where the sheet lies in it. Those three motions are named, and
    // left as the user placed them.
    let (scene, images, truth) = blender_cloth();
    let p = &truth;
    let normal = sheet_normal(p);
    let size = scene.mesh.bbox_diagonal();
    let off_plane = |x: &[Point3<f64>]| {
        let ss: f64 = x.iter().map(|q| (q - p[0]).dot(&normal).powi(2)).sum();
        100.0 * (ss / x.len() as f64).sqrt() / size
    };
    let start = scene
        .mesh
        .with_positions(perturb(&scene.mesh, 0.05, 10.0, 1));
    assert!(off_plane(&start.positions) > 1.0);
    let a = align(&start, &scene.cameras, 0, &images, &AlignOptions::default()).unwrap();
    assert!(
        off_plane(&a.positions) < 0.1,
        "{} %",
        off_plane(&a.positions)
    );
    let free: Vec<_> = a.loose.iter().filter(|m| m.stiffness < 1e-6).collect();
    assert_eq!(free.len(), 3, "{:?}", a.loose);
    for m in free {
        let axis = Vector3::from(m.axis);
        match m.kind {
            MotionKind::Rotation => assert!(axis.dot(&normal).abs() > 0.99, "{m:?}"),
            MotionKind::Translation => assert!(axis.dot(&normal).abs() < 0.05, "{m:?}"),
            MotionKind::Scale => panic!("{m:?}"),
        }
    }
    // The in-plane placement is the user's: the sheet is as far from the true one within the
    // plane as it was placed (the sliding a tilted sheet does on its way in is undone).
    let ct = centroid(p);
    let in_plane = |x: &[Point3<f64>]| {
        let e = centroid(x) - ct;
        (e - normal * e.dot(&normal)).norm()
    };
    let (before, after) = (in_plane(&start.positions), in_plane(&a.positions));
    assert!(before > 0.02 * size, "{before}");
    assert!((after - before).abs() < 1e-3 * size, "{before} → {after}");
}

#[test]
fn a_flat_sheet_at_any_orientation_keeps_its_place_in_its_plane() {
    // The same footage with the whole world turned and shifted (cameras and mesh together, so
    // the images stay valid): the sheet's plane is no longer along a world axis, so each free
    // motion mixes axes. Those must still be found and kept, whatever the damping.
    let (scene, images, truth) = blender_cloth();
    let q = nalgebra::Rotation3::from_euler_angles(0.4, -0.7, 1.1);
    let shift = Vector3::new(0.3, -1.2, 0.5);
    let to_new = |p: &Point3<f64>| Point3::from(q * p.coords + shift);
    // P' = P·[Qᵀ | −Qᵀs] so that P'·X' = P·X.
    let mut back = nalgebra::Matrix4::<f64>::identity();
    back.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&q.inverse().into_inner());
    back.fixed_view_mut::<3, 1>(0, 3)
        .copy_from(&(q.inverse() * -shift));
    let cameras: Vec<modelflow::Camera> = scene
        .cameras
        .iter()
        .map(|c| {
            let p = modelflow::Projection::from_matrix(&(c.at(0).matrix() * back)).unwrap();
            modelflow::Camera::fixed(c.name.clone(), c.width, c.height, p)
        })
        .collect();
    let truth: Vec<Point3<f64>> = truth.iter().map(to_new).collect();
    let placed_mesh = scene
        .mesh
        .with_positions(scene.mesh.positions.iter().map(to_new).collect());
    let start = placed_mesh.with_positions(perturb(&placed_mesh, 0.05, 10.0, 2));
    let a = align(&start, &cameras, 0, &images, &AlignOptions::default()).unwrap();
    let normal = sheet_normal(&truth);
    let size = placed_mesh.bbox_diagonal();
    let off_plane = |x: &[Point3<f64>]| {
        let ss: f64 = x.iter().map(|p| (p - truth[0]).dot(&normal).powi(2)).sum();
        100.0 * (ss / x.len() as f64).sqrt() / size
    };
    assert!(
        off_plane(&a.positions) < 0.1,
        "{} %",
        off_plane(&a.positions)
    );
    assert_eq!(a.loose.iter().filter(|m| m.stiffness < 1e-6).count(), 3);
    let in_plane = |x: &[Point3<f64>]| {
        let e = centroid(x) - centroid(&truth);
        (e - normal * e.dot(&normal)).norm()
    };
    let (before, after) = (in_plane(&start.positions), in_plane(&a.positions));
    assert!((after - before).abs() < 1e-3 * size, "{before} → {after}");
}

#[test]
fn a_flat_sheet_whose_border_is_its_outline_is_placed_by_it() {
    // With `outline`, the motions photo-consistency leaves free are set by the contrast across
    // the sheet's border: the Blender cloth (textured, against a plain background) comes back
    // from 5 % and 10° off to within 0.1 % per vertex, in-plane placement included.
    let (scene, images, truth) = blender_cloth();
    let size = scene.mesh.bbox_diagonal();
    let opts = AlignOptions {
        outline: true,
        ..AlignOptions::default()
    };
    for seed in [1, 3] {
        let start = scene
            .mesh
            .with_positions(perturb(&scene.mesh, 0.05, 10.0, seed));
        let a = align(&start, &scene.cameras, 0, &images, &opts).unwrap();
        let after = rms_pct(&a.positions, &truth, size);
        assert!(after < 0.1, "seed {seed}: {after:.3} %");
        let o = a.outline.expect("the sheet has a border and free motions");
        assert!(o.contrast_after > o.contrast_before, "{o:?}");
    }
    // The irregular mesh has a border (its hole) but the images fix its whole pose: the outline
    // has nothing left to set, and is not used.
    let (syn, imgs) = footage(Preset::Irregular);
    let a = align(&syn.mesh, &syn.cameras, 0, &imgs, &opts).unwrap();
    assert!(a.outline.is_none());
}

#[test]
fn a_glossy_near_sphere_rendered_by_blender_comes_back_within_about_a_tenth_of_a_percent() {
    // The hard sample's first frame (fixtures/blender-hard-sample-frame0: Blender's render, a
    // glossy squashed sphere on an irregular mesh, three cameras at 480×360): three rotations
    // are held loosely and the highlights, which differ between viewpoints, pull them. Weighing
    // each (triangle, camera) patch as a whole (`SolverOptions::patch_scale`, as the tracker
    // does) brought it back to 0.14-0.15 % per vertex (the pixels alone 0.22-0.29 %);
    // comparing the cameras at twice the images' resolution (`AlignOptions::enlarge`, chosen
    // for images this size) to 0.08-0.11 %.
    let dir =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/blender-hard-sample-frame0");
    let scene = Scene::load(&dir.join("scene.json")).unwrap();
    let images = scene.load_images(0).unwrap();
    let truth = scene.ground_truth(0).unwrap().unwrap().positions;
    let size = scene.mesh.bbox_diagonal();
    let as_they_are = AlignOptions {
        enlarge: 1,
        ..AlignOptions::default()
    };
    let (mut sum, mut sum_as_they_are) = (0.0, 0.0);
    for seed in [1, 2, 3] {
        let start = scene
            .mesh
            .with_positions(perturb(&scene.mesh, 0.05, 10.0, seed));
        let before = rms_pct(&start.positions, &truth, size);
        assert!(
            before > 4.0,
            "seed {seed}: the misplacement is real: {before} %"
        );
        let a = align(&start, &scene.cameras, 0, &images, &AlignOptions::default()).unwrap();
        assert_eq!(a.enlarged, 2, "480×360 images are compared enlarged");
        let after = rms_pct(&a.positions, &truth, size);
        assert!(after < 0.12, "seed {seed}: {before:.2} % → {after:.3} %");
        let plain = align(&start, &scene.cameras, 0, &images, &as_they_are).unwrap();
        assert_eq!(plain.enlarged, 1);
        let after_plain = rms_pct(&plain.positions, &truth, size);
        assert!(
            after_plain < 0.2,
            "seed {seed}: {before:.2} % → {after_plain:.3} %"
        );
        sum += after;
        sum_as_they_are += after_plain;
    }
    assert!(
        sum < 0.8 * sum_as_they_are,
        "enlarged {:.3} % against {:.3} % as they are (means)",
        sum / 3.0,
        sum_as_they_are / 3.0
    );
}

#[test]
fn every_level_count_it_accepts_is_solved_enlarged_or_not() {
    // The Blender cloth sample (two 320×240 cameras) is compared enlarged twice, one level
    // deeper; the deepest count `validate` accepts must still run (it asked for 9 levels once).
    let (scene, images, truth) = blender_cloth();
    let size = scene.mesh.bbox_diagonal();
    for enlarge in [0, 1] {
        let opts = AlignOptions {
            levels: 8,
            search: false,
            enlarge,
            ..AlignOptions::default()
        };
        let a = align(&scene.mesh, &scene.cameras, 0, &images, &opts).unwrap();
        assert_eq!(a.enlarged, if enlarge == 0 { 2 } else { 1 });
        assert_eq!(a.levels.len(), 8);
        let off = rms_pct(&a.positions, &truth, size);
        assert!(
            off < 0.05,
            "enlarge {enlarge}: {off:.3} % from the truth it started at"
        );
    }
}

#[test]
fn align_refuses_what_it_cannot_do() {
    let (syn, images) = footage(Preset::Irregular);
    // One camera cannot be compared with anything.
    let err = align(
        &syn.mesh,
        &syn.cameras[..1],
        0,
        &images[..1],
        &AlignOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("at least 2"), "{err}");
    // A mesh nobody sees.
    let far = syn.mesh.with_positions(
        syn.mesh
            .positions
            .iter()
            .map(|p| p + Vector3::new(100.0, 0.0, 0.0))
            .collect(),
    );
    let err = align(&far, &syn.cameras, 0, &images, &AlignOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("outside the images"), "{err}");
    // A vertex that is not a number is named, not carried into a NaN pose.
    let mut bad = syn.mesh.positions.clone();
    bad[7].y = f64::NAN;
    let err = align(
        &syn.mesh.with_positions(bad),
        &syn.cameras,
        0,
        &images,
        &AlignOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("vertex 7"), "{err}");
    // Images that are not the cameras' size.
    let small: Vec<modelflow::RgbImage> = images.iter().map(|i| i.downsample2()).collect();
    let err = align(&syn.mesh, &syn.cameras, 0, &small, &AlignOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("the camera's size"), "{err}");
}

/// The default blob (640×480, four cameras) at its first frame: the scene, its images and the
/// mesh's size (bounding-box diagonal).
fn blob_first_frame() -> (Synthetic, Vec<modelflow::RgbImage>, f64) {
    blob_first_frame_at(640, 480)
}

/// [`blob_first_frame`] at `width × height`.
fn blob_first_frame_at(width: u32, height: u32) -> (Synthetic, Vec<modelflow::RgbImage>, f64) {
    let syn = Synthetic::generate(&SynthOptions {
        preset: Preset::Blob,
        frames: 1,
        width,
        height,
        ..SynthOptions::default()
    })
    .unwrap();
    let images: Vec<_> = (0..syn.cameras.len()).map(|c| syn.render(c, 0)).collect();
    let size = syn.mesh.bbox_diagonal();
    (syn, images, size)
}

/// `mesh` with every vertex moved `d` along its normal (a visual hull, for `d > 0` on a closed
/// mesh).
fn along_normals(mesh: &modelflow::Mesh, d: f64) -> modelflow::Mesh {
    let normals = mesh.vertex_normals();
    mesh.with_positions(
        mesh.positions
            .iter()
            .zip(&normals)
            .map(|(p, n)| p + n * d)
            .collect(),
    )
}

#[test]
fn a_mesh_misplaced_so_far_that_it_reads_far_off_the_surface_is_named() {
    // The blob turned 5° and moved 3 % of its size (640×480, four cameras): the surface check
    // reads it 29 % of its size off along its normals, farther than `track` moves a mesh onto
    // the surface, so it was neither moved nor checked for its placement: no warning at all.
    let (syn, images, size) = blob_first_frame();
    let moved = syn.mesh.with_positions(perturb(&syn.mesh, 0.03, 5.0, 8));
    let c = modelflow::tracker::first_mesh_check(&moved, &syn.cameras, 0, &images);
    let s = c.surface.expect("the cameras compare the mesh");
    assert!(
        s.is_off() && !s.is_off_within(size),
        "the case this guards: {s:?}"
    );
    let p = c.placement.expect("its placement is checked");
    assert!(p.is_off() && (p.fraction - 0.034).abs() < 0.005, "{p:?}");
}

#[test]
fn a_misplaced_mesh_that_also_reads_off_along_its_normals_is_named_not_reshaped() {
    // The blob turned 5° and moved 3 % of its size in the direction of seed 4 reads 11 px off
    // the surface along its normals, the cameras agreeing 1.5 times better there: within the
    // reach `track` moves a mesh onto the surface, so it was reshaped along its normals (and
    // said so) instead of named as misplaced. `align`'s rigid move makes them agree 26 times
    // better: that is what it is. A mesh moved along its normals by 2 % of its size (a visual
    // hull) still reads as off the surface, and is moved onto it.
    use modelflow::tracker::moved_onto_surface;
    let (syn, images, size) = blob_first_frame();
    let moved = syn.mesh.with_positions(perturb(&syn.mesh, 0.03, 5.0, 4));
    let c = modelflow::tracker::first_mesh_check(&moved, &syn.cameras, 0, &images);
    let s = c.surface.expect("the cameras compare the mesh");
    assert!(s.is_off_within(size), "the case this guards: {s:?}");
    let p = c.placement.expect("its placement is checked");
    assert!(p.is_off() && (p.fraction - 0.035).abs() < 0.005, "{p:?}");
    assert!(p.agreement_gain > 10.0 * s.ratio, "{p:?} {s:?}");
    assert!(c.off_surface(size).is_none());
    assert!(moved_onto_surface(&moved, &syn.cameras, 0, &images).is_none());
    // Off along its normals: moved onto the surface, not called misplaced.
    let hull = along_normals(&syn.mesh, 0.02 * size);
    let c = modelflow::tracker::first_mesh_check(&hull, &syn.cameras, 0, &images);
    let s = c.off_surface(size).expect("read off the surface");
    assert!(s.pixels < -5.0, "{s:?}");
    assert!(c.placement.is_none(), "{:?}", c.placement);
}

#[test]
fn a_tracker_given_tracks_first_mesh_check_starts_where_one_that_measures_it_does() {
    // `track` checks the first mesh to warn before tracking and hands the check to the tracker
    // (`RunOptions::first_mesh_check`), which moves a mesh off the surface onto it from there
    // instead of measuring again: the same start to the bit, for a visual hull (moved) and for
    // a misplaced mesh (left as given, for the warning to name).
    use modelflow::tracker::{TrackOptions, Tracker};
    let (syn, images, size) = blob_first_frame_at(320, 240);
    let hull = along_normals(&syn.mesh, 0.02 * size);
    let misplaced = syn.mesh.with_positions(perturb(&syn.mesh, 0.03, 5.0, 4));
    for (mesh, moved) in [(&hull, true), (&misplaced, false)] {
        let check = modelflow::tracker::first_mesh_check(mesh, &syn.cameras, 0, &images);
        let start = |check| {
            let t = Tracker::new_checked(
                mesh,
                syn.cameras.clone(),
                0,
                &images,
                TrackOptions::default(),
                check,
            )
            .unwrap();
            (t.positions().to_vec(), t.first_mesh_moved().copied())
        };
        let (given, measured) = (start(Some(&check)), start(None));
        assert_eq!(given, measured);
        assert_eq!(given.1.is_some(), moved, "{:?}", given.1);
        assert_eq!(given.0 != mesh.positions, moved);
    }
}

#[test]
fn a_rig_with_two_cameras_of_half_the_size_lines_up_as_well_as_one_of_a_size() {
    // The blob's four cameras at 320×240, and the same with two of them halved (160×120
    // witnesses: 2×2 means, the projection halved about the pixel-centre convention). Until
    // 2026-12-07 every camera was compared at the same pyramid index, the witnesses at half
    // the others' scale at every level: 0.040 % off against 0.027 % (seeds 1–3, `align
    // --perturb 5,10`). Each camera now enters the levels by its size (`pyramid::level_skips`).
    use modelflow::base::Camera;
    let (syn, images) = footage(Preset::Blob);
    let size = syn.mesh.bbox_diagonal();
    let start = syn.mesh.with_positions(perturb(&syn.mesh, 0.05, 10.0, 1));
    let opts = AlignOptions::default();
    let full = align(&start, &syn.cameras, 0, &images, &opts).unwrap();
    let full = rms_pct(&full.positions, &syn.mesh.positions, size);
    let halved = |c: usize| c < 2;
    let cameras: Vec<Camera> = syn
        .cameras
        .iter()
        .enumerate()
        .map(|(c, cam)| {
            if !halved(c) {
                return cam.clone();
            }
            let (w, h) = (cam.width / 2, cam.height / 2);
            Camera::fixed(cam.name.clone(), w, h, cam.at(0).downscaled(2))
        })
        .collect();
    let small: Vec<modelflow::RgbImage> = images
        .iter()
        .enumerate()
        .map(|(c, i)| {
            if halved(c) {
                i.downsample2()
            } else {
                i.clone()
            }
        })
        .collect();
    let mixed = align(&start, &cameras, 0, &small, &opts).unwrap();
    let mixed = rms_pct(&mixed.positions, &syn.mesh.positions, size);
    assert!(full < 0.05, "{full}");
    assert!(
        mixed < 1.15 * full,
        "{mixed} % against {full} % with every camera at 320×240"
    );
}

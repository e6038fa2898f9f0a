//! Unit tests of the exporters: exact bytes of the point caches' headers, and the glTF read back
//! by the `gltf` crate.

use super::*;
use crate::base::mesh::grid;
use nalgebra::Point3;

fn frames(n: u32) -> Vec<(u32, Mesh)> {
    let m = grid(3, 2, |u, v| Point3::new(u, v, 0.0));
    (0..n)
        .map(|f| {
            let moved = m
                .positions
                .iter()
                .map(|p| Point3::new(p.x + 0.25 * f as f64, p.y, p.z - 0.5 * f as f64))
                .collect();
            (10 + f, m.with_positions(moved))
        })
        .collect()
}

#[test]
fn pc2_and_mdd_headers_are_exact() {
    let fr = frames(3);
    let b = cache::pc2(&fr).unwrap();
    assert_eq!(&b[..12], b"POINTCACHE2\0");
    assert_eq!(&b[12..16], &1i32.to_le_bytes());
    assert_eq!(&b[16..20], &6i32.to_le_bytes());
    assert_eq!(&b[20..24], &10f32.to_le_bytes());
    assert_eq!(&b[24..28], &1f32.to_le_bytes());
    assert_eq!(&b[28..32], &3i32.to_le_bytes());
    assert_eq!(b.len(), 32 + 3 * 6 * 12);
    // Frame 12 (third sample), vertex 0: x = 0.5, z = -1.
    let at = 32 + 2 * 6 * 12;
    assert_eq!(&b[at..at + 4], &0.5f32.to_le_bytes());
    assert_eq!(&b[at + 8..at + 12], &(-1f32).to_le_bytes());

    let b = cache::mdd(&fr, 24.0);
    assert_eq!(&b[..8], &[0, 0, 0, 3, 0, 0, 0, 6]);
    assert_eq!(&b[8..12], &0f32.to_be_bytes());
    assert_eq!(&b[16..20], &(2.0f32 / 24.0).to_be_bytes());
    let at = 20 + 2 * 6 * 12;
    assert_eq!(&b[at..at + 4], &0.5f32.to_be_bytes());
    assert_eq!(b.len(), 20 + 3 * 6 * 12);

    // Uneven frames are refused for PC2, taken by MDD.
    let uneven = vec![fr[0].clone(), fr[2].clone(), (13, fr[1].1.clone())];
    assert!(cache::pc2(&uneven)
        .unwrap_err()
        .to_string()
        .contains("evenly spaced"));
}

#[test]
fn mismatched_topology_and_bad_fps_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut fr = frames(2);
    fr[1].1.triangles.pop();
    let e = export(
        &fr,
        &[],
        ExportFormat::Usda,
        &dir.path().join("a.usda"),
        &ExportOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("frame 11's mesh"), "{e}");
    let e = export(
        &frames(2),
        &[],
        ExportFormat::Usda,
        &dir.path().join("a.usda"),
        &ExportOptions {
            fps: f64::NAN,
            units: None,
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("--fps"), "{e}");
    let short = vec![(10, vec![VertexConfidence::default(); 5])];
    let e = export(
        &frames(2),
        &short,
        ExportFormat::Usda,
        &dir.path().join("a.usda"),
        &ExportOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("frame 10's confidence"), "{e}");
    assert!(!dir.path().join("a.usda").exists());
}

#[test]
fn glb_reads_back_with_the_gltf_crate() {
    let dir = tempfile::tempdir().unwrap();
    let fr = frames(4);
    let out = dir.path().join("t.glb");
    let s = export(&fr, &[], ExportFormat::Glb, &out, &ExportOptions::default()).unwrap();
    assert_eq!((s.frames, s.vertices, s.triangles), (4, 6, 4));
    let (doc, buffers, _) = ::gltf::import(&out).unwrap();
    let mesh = doc.meshes().next().unwrap();
    let prim = mesh.primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let base: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let uv: Vec<[f32; 2]> = reader.read_tex_coords(0).unwrap().into_f32().collect();
    assert_eq!(base.len(), 6);
    // grid's uvs are (u, v); glTF's v runs down.
    let m0 = &fr[0].1;
    for (p, t) in base.iter().zip(&uv) {
        let i = m0
            .positions
            .iter()
            .position(|q| q.x as f32 == p[0] && q.y as f32 == p[1])
            .unwrap();
        let want = m0.uvs.as_ref().unwrap()[i];
        assert_eq!(*t, [want[0] as f32, 1.0 - want[1] as f32]);
    }
    let targets: Vec<_> = reader.read_morph_targets().collect();
    assert_eq!(targets.len(), 4);
    let d: Vec<[f32; 3]> = targets[3].0.clone().unwrap().collect();
    assert!(d.iter().all(|v| *v == [0.75, 0.0, -1.5]), "{d:?}");
    let anim = doc.animations().next().unwrap();
    let ch = anim.channels().next().unwrap();
    let times: Vec<f32> = match ch.reader(|b| Some(&buffers[b.index()])).read_inputs() {
        Some(t) => t.collect(),
        None => panic!("no inputs"),
    };
    assert_eq!(times, vec![0.0, 1.0 / 24.0, 2.0 / 24.0, 3.0 / 24.0]);
}

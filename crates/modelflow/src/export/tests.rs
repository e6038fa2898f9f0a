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
    // Confidence out of order (the Alembic export samples it in time).
    let swapped = vec![
        (11, vec![VertexConfidence::default(); 6]),
        (10, vec![VertexConfidence::default(); 6]),
    ];
    let e = export(
        &frames(2),
        &swapped,
        ExportFormat::Abc,
        &dir.path().join("a.abc"),
        &ExportOptions::default(),
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("confidence") && e.to_string().contains("ascending"),
        "{e}"
    );
    assert!(!dir.path().join("a.abc").exists());
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

/// The Alembic subset the exporter writes, read back by the Alembic library's own rules (its
/// `Ogawa` groups and data, `AbcCoreOgawa`'s archive layout, object headers ending in 32 bytes of
/// hashes, property headers' bit fields): what a reader needs the file to hold. Blender's importer
/// reads the same files in `tools/check_blender.sh` (docs/export.md).
mod abc_reader {
    pub const DATA: u64 = 1 << 63;

    pub struct File<'a>(pub &'a [u8]);

    #[derive(Debug)]
    pub struct Prop {
        pub name: String,
        pub metadata: String,
        /// 0 compound, 1 scalar, 2 array (3: an array whose samples hold one value each).
        pub kind: u32,
        pub pod: u32,
        pub extent: u32,
        pub samples: u32,
        pub sampling: u32,
        pub group: u64,
    }

    impl<'a> File<'a> {
        fn u64_at(&self, at: usize) -> u64 {
            u64::from_le_bytes(self.0[at..at + 8].try_into().unwrap())
        }
        pub fn root(&self) -> u64 {
            assert_eq!(&self.0[..5], b"Ogawa");
            assert_eq!(self.0[5], 0xff, "not frozen");
            assert_eq!(&self.0[6..8], &[0, 1]);
            self.u64_at(8)
        }
        pub fn children(&self, group: u64) -> Vec<u64> {
            assert_eq!(group & DATA, 0, "a data child where a group belongs");
            if group == 0 {
                return Vec::new();
            }
            let n = self.u64_at(group as usize) as usize;
            (0..n)
                .map(|i| self.u64_at(group as usize + 8 * (i + 1)))
                .collect()
        }
        pub fn data(&self, child: u64) -> &'a [u8] {
            assert_ne!(child & DATA, 0, "a group where data belongs");
            let pos = (child & !DATA) as usize;
            if pos == 0 {
                return &[];
            }
            let n = self.u64_at(pos) as usize;
            &self.0[pos + 8..pos + 8 + n]
        }
        /// An object's children: (name, metadata, group).
        pub fn objects(&self, object: u64) -> Vec<(String, String, u64)> {
            let ch = self.children(object);
            let headers = self.data(*ch.last().unwrap());
            assert!(headers.len() >= 32, "no hashes after the object headers");
            let h = &headers[..headers.len() - 32];
            let (mut at, mut out) = (0, Vec::new());
            while at < h.len() {
                let n = u32::from_le_bytes(h[at..at + 4].try_into().unwrap()) as usize;
                let name = String::from_utf8(h[at + 4..at + 4 + n].to_vec()).unwrap();
                at += 4 + n;
                assert_eq!(h[at], 0xff, "metadata inline");
                let m = u32::from_le_bytes(h[at + 1..at + 5].try_into().unwrap()) as usize;
                let meta = String::from_utf8(h[at + 5..at + 5 + m].to_vec()).unwrap();
                at += 5 + m;
                out.push((name, meta, ch[out.len() + 1]));
            }
            assert_eq!(out.len() + 2, ch.len());
            out
        }
        /// An object's own two hashes (of its properties, of its children), after its
        /// children's headers.
        pub fn hashes(&self, object: u64) -> ([u8; 16], [u8; 16]) {
            let ch = self.children(object);
            let h = self.data(*ch.last().unwrap());
            let at = h.len() - 32;
            (
                h[at..at + 16].try_into().unwrap(),
                h[at + 16..].try_into().unwrap(),
            )
        }
        /// A compound's properties.
        pub fn props(&self, compound: u64) -> Vec<Prop> {
            let ch = self.children(compound);
            let Some(last) = ch.last() else {
                return Vec::new();
            };
            let h = self.data(*last);
            let (mut at, mut out) = (0, Vec::new());
            while at < h.len() {
                let info = u32::from_le_bytes(h[at..at + 4].try_into().unwrap());
                at += 4;
                let hint = (info >> 2) & 3;
                // A count in 1, 2 or 4 bytes, as the header's size hint says.
                let get = |at: &mut usize| {
                    let (v, n) = match hint {
                        0 => (h[*at] as u32, 1),
                        1 => (u16::from_le_bytes([h[*at], h[*at + 1]]) as u32, 2),
                        _ => (u32::from_le_bytes(h[*at..*at + 4].try_into().unwrap()), 4),
                    };
                    *at += n;
                    v
                };
                let kind = info & 3;
                let (mut samples, mut sampling) = (0, 0);
                if kind != 0 {
                    samples = get(&mut at);
                    if info & 0x200 != 0 {
                        let (_first, _last) = (get(&mut at), get(&mut at));
                    }
                    if info & 0x100 != 0 {
                        sampling = get(&mut at);
                    }
                }
                let n = get(&mut at) as usize;
                let name = String::from_utf8(h[at..at + n].to_vec()).unwrap();
                at += n;
                let meta_index = (info >> 20) & 0xff;
                let metadata = if meta_index == 0xff {
                    let m = get(&mut at) as usize;
                    let s = String::from_utf8(h[at..at + m].to_vec()).unwrap();
                    at += m;
                    s
                } else {
                    assert_eq!(meta_index, 0, "no indexed metadata but the empty one");
                    String::new()
                };
                out.push(Prop {
                    name,
                    metadata,
                    kind,
                    pod: (info >> 4) & 0xf,
                    extent: (info >> 12) & 0xff,
                    samples,
                    sampling,
                    group: ch[out.len()],
                });
            }
            assert_eq!(out.len() + 1, ch.len());
            out
        }
        /// Sample `i` of an array or scalar property: its values, after the 16-byte key.
        pub fn sample(&self, p: &Prop, i: usize) -> &'a [u8] {
            let ch = self.children(p.group);
            let step = if p.kind >= 2 { 2 } else { 1 };
            if p.kind >= 2 {
                assert_eq!(ch[step * i + 1], DATA, "rank-1 dimensions are empty");
            }
            let d = self.data(ch[step * i]);
            use sha2::Digest;
            assert_eq!(&d[..16], &sha2::Sha256::digest(&d[16..])[..16]);
            &d[16..]
        }
    }
}

/// `frames` exported as Alembic to `out`, and the file's bytes.
fn abc_bytes(frames: &[(u32, Mesh)], out: &std::path::Path) -> Vec<u8> {
    abc_bytes_with(frames, &[], out)
}

/// [`abc_bytes`] with the per-vertex `confidence` of some frames.
fn abc_bytes_with(
    frames: &[(u32, Mesh)],
    confidence: &[(u32, Vec<VertexConfidence>)],
    out: &std::path::Path,
) -> Vec<u8> {
    export(
        frames,
        confidence,
        ExportFormat::Abc,
        out,
        &ExportOptions::default(),
    )
    .unwrap();
    std::fs::read(out).unwrap()
}

fn f32s(b: &[u8]) -> Vec<f32> {
    b.chunks(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

fn f64s(b: &[u8]) -> Vec<f64> {
    b.chunks(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

#[test]
fn alembic_holds_the_meshes_topology_uvs_and_times_where_readers_look() {
    use abc_reader::File;
    let dir = tempfile::tempdir().unwrap();
    let fr = frames(3);
    let out = dir.path().join("t.abc");
    assert_eq!(ExportFormat::from_path(&out), Some(ExportFormat::Abc));
    let s = export(&fr, &[], ExportFormat::Abc, &out, &ExportOptions::default()).unwrap();
    assert_eq!((s.frames, s.vertices, s.triangles), (3, 6, 4));
    let bytes = std::fs::read(&out).unwrap();
    let f = File(&bytes);
    let root = f.children(f.root());
    assert_eq!(root.len(), 6);
    assert_eq!(f.data(root[0]), &0i32.to_le_bytes());
    assert!(i32::from_le_bytes(f.data(root[1]).try_into().unwrap()) >= 9999);
    assert!(String::from_utf8_lossy(f.data(root[3])).contains("_ai_AlembicVersion="));
    assert!(f.data(root[5]).is_empty());
    // Sampling 0 (the identity: one sample a second from 0), then the frames' (3 samples,
    // uniform, 1/24 s apart from frame 10): each its most samples, time per cycle, stored times.
    let ts = f.data(root[4]);
    assert_eq!(ts.len(), 24 + 24);
    assert_eq!(f64s(&ts[4..12]), vec![1.0]);
    assert_eq!(&ts[24..28], &3u32.to_le_bytes());
    assert_eq!(f64s(&ts[28..36]), vec![1.0 / 24.0]);
    assert_eq!(&ts[36..40], &1u32.to_le_bytes());
    assert_eq!(f64s(&ts[40..48]), vec![10.0 / 24.0]);

    let top = f.objects(root[2]);
    assert_eq!(top.len(), 1);
    assert_eq!(top[0].0, "tracked");
    assert!(top[0].1.contains("schemaObjTitle=AbcGeom_Xform_v3:.xform"));
    let mesh = f.objects(top[0].2);
    assert_eq!(mesh[0].0, "mesh");
    assert!(mesh[0]
        .1
        .contains("schemaObjTitle=AbcGeom_PolyMesh_v1:.geom"));
    let props = f.props(f.children(mesh[0].2)[0]);
    assert_eq!(props.len(), 1);
    assert_eq!((props[0].name.as_str(), props[0].kind), (".geom", 0));
    assert!(props[0].metadata.contains("schema=AbcGeom_PolyMesh_v1"));
    let geom = f.props(props[0].group);
    let by = |n: &str| geom.iter().find(|p| p.name == n).unwrap();

    // Points: every frame, float32 × 3, at sampling 1.
    let p = by("P");
    assert_eq!(
        (p.kind, p.pod, p.extent, p.samples, p.sampling),
        (2, 10, 3, 3, 1)
    );
    assert!(p.metadata.contains("interpretation=point"));
    for (i, (_, m)) in fr.iter().enumerate() {
        let want: Vec<f32> = m
            .positions
            .iter()
            .flat_map(|q| [q.x as f32, q.y as f32, q.z as f32])
            .collect();
        assert_eq!(f32s(f.sample(p, i)), want, "frame {i}");
    }
    // Faces: each triangle's corners reversed (Alembic winds clockwise), once.
    let idx = by(".faceIndices");
    assert_eq!((idx.kind, idx.pod, idx.samples), (2, 6, 1));
    let got: Vec<i32> = f
        .sample(idx, 0)
        .chunks(4)
        .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let want: Vec<i32> = fr[0]
        .1
        .triangles
        .iter()
        .flat_map(|t| [t[2] as i32, t[1] as i32, t[0] as i32])
        .collect();
    assert_eq!(got, want);
    let counts = by(".faceCounts");
    assert_eq!(f.sample(counts, 0), &[3, 0, 0, 0].repeat(4)[..]);
    // UVs per corner, in the same reversed order.
    let uv = by("uv");
    assert!(uv.metadata.contains("geoScope=fvr"));
    let uvs = fr[0].1.uvs.as_ref().unwrap();
    let want: Vec<f32> = fr[0]
        .1
        .triangles
        .iter()
        .flat_map(|t| [t[2], t[1], t[0]])
        .flat_map(|v| [uvs[v as usize][0] as f32, uvs[v as usize][1] as f32])
        .collect();
    assert_eq!(f32s(f.sample(uv, 0)), want);
    // Bounds per frame, as float64.
    let b = by(".selfBnds");
    assert_eq!((b.kind, b.pod, b.extent, b.samples), (1, 11, 6, 3));
    assert_eq!(f64s(f.sample(b, 2)), vec![0.5, 0.0, -1.0, 1.5, 1.0, -1.0]);

    // Uneven frames: each sampled at its own time (acyclic).
    let uneven = vec![fr[0].clone(), fr[2].clone(), (15, fr[1].1.clone())];
    let bytes = abc_bytes(&uneven, &out);
    let f = File(&bytes);
    let ts = f.data(f.children(f.root())[4]);
    assert_eq!(f64s(&ts[28..36]), vec![f64::MAX / 32.0]);
    assert_eq!(&ts[36..40], &3u32.to_le_bytes());
    assert_eq!(
        f64s(&ts[40..64]),
        vec![10.0 / 24.0, 12.0 / 24.0, 15.0 / 24.0]
    );
}

#[test]
fn alembic_cameras_project_as_the_scenes_through_alembics_screen_window() {
    // Two cameras: one still, with its principal point off centre and fx ≠ fy (a webcam's K);
    // one that moves, given at frames 10 and 12 only. Read back by Alembic's rules, each
    // camera's `Xform` (one matrix op) and `Camera` film back must put a point where K·[R | t]
    // does, through the screen window of `CameraSample::getScreenWindow` (offsets over half the
    // horizontal aperture, the vertical extent aperture over horizontal); the moving camera at
    // frame 11 and 13 holds its view of frame 10 and 12. A third camera, the first's copy,
    // gets the first's hashes.
    use crate::base::{look_at, Projection};
    use abc_reader::File;
    use nalgebra::{Matrix3, Vector3};
    let fr = frames(4);
    let k = Matrix3::new(903.5, 0.0, 618.3, 0.0, 907.9, 394.2, 0.0, 0.0, 1.0);
    let pose = |eye: [f64; 3]| {
        let (r, t) = look_at(
            &Point3::from(eye),
            &Point3::new(1.0, 0.5, -0.5),
            &Vector3::new(0.0, 1.0, 0.0),
        );
        Projection::from_krt(&k, &r, &t).unwrap()
    };
    let cameras = [
        ExportCamera {
            name: "web cam".into(),
            width: 1280,
            height: 720,
            views: vec![(10, pose([0.3, -2.0, 4.0]))],
        },
        ExportCamera {
            name: "web cam".into(),
            width: 1280,
            height: 720,
            views: vec![(10, pose([3.0, 1.0, 3.0])), (12, pose([2.0, 2.5, 3.5]))],
        },
        ExportCamera {
            name: "copy".into(),
            width: 1280,
            height: 720,
            views: vec![(10, pose([0.3, -2.0, 4.0]))],
        },
    ];
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("c.abc");
    let s = export_with_cameras(
        &fr,
        &[],
        &cameras,
        ExportFormat::Abc,
        &out,
        &ExportOptions::default(),
    )
    .unwrap();
    assert_eq!(s.cameras, 3);
    let bytes = std::fs::read(&out).unwrap();
    let f = File(&bytes);
    let root = f.children(f.root());
    let top = f.objects(root[2]);
    let names: Vec<&str> = top.iter().map(|o| o.0.as_str()).collect();
    assert_eq!(names, ["tracked", "cameras"]);
    let cams = f.objects(top[1].2);
    let names: Vec<&str> = cams.iter().map(|o| o.0.as_str()).collect();
    assert_eq!(names, ["web_cam", "web_cam_1", "copy"], "USD's names");
    // The objects' hashes, which instancing readers compare: the same camera twice hashes
    // alike, different ones do not, an object with no children has a zero children hash.
    let h: Vec<_> = cams.iter().map(|c| f.hashes(c.2)).collect();
    assert_eq!(h[0], h[2]);
    assert_ne!(h[0].0, h[1].0);
    assert_ne!(h[0].1, h[1].1);
    assert_ne!(h[0].0, [0; 16]);
    let shape = f.objects(cams[1].2)[0].2;
    assert_eq!(f.hashes(shape).1, [0; 16]);
    assert_ne!(f.hashes(shape).0, [0; 16]);
    assert_ne!(f.hashes(top[0].2), f.hashes(top[1].2));
    let point = Point3::new(0.7, 0.2, -0.9);
    for (c, (name, meta, group)) in cams.iter().enumerate().take(2) {
        assert!(meta.contains("schema=AbcGeom_Xform_v3"));
        let shape = f.objects(*group);
        assert_eq!(shape.len(), 1);
        assert_eq!(shape[0].0, format!("{name}Shape"));
        assert!(shape[0].1.contains("schema=AbcGeom_Camera_v1"));
        let xform = f.props(f.children(*group)[0]);
        assert_eq!(xform[0].name, ".xform");
        let xp = f.props(xform[0].group);
        let by = |n: &str| xp.iter().find(|p| p.name == n).unwrap();
        assert_eq!(f.sample(by(".ops"), 0), &[0x30]);
        assert_eq!(
            (by(".vals").kind, by(".vals").pod, by(".vals").extent),
            (1, 11, 16)
        );
        assert_eq!(f.sample(by("isNotConstantIdentity"), 0), &[1]);
        let geom = f.props(f.children(shape[0].2)[0]);
        assert_eq!(geom[0].name, ".geom");
        let core = &f.props(geom[0].group)[0];
        assert_eq!(
            (core.name.as_str(), core.kind, core.extent),
            (".core", 1, 16)
        );
        let n = if c == 0 { 1 } else { 4 };
        assert_eq!(
            (by(".vals").samples, core.samples, by(".inherits").samples),
            (n, n, n)
        );
        for i in 0..n as usize {
            let frame = 10 + i as u32;
            let view = if c == 0 {
                &cameras[0].views[0].1
            } else if frame < 12 {
                &cameras[1].views[0].1
            } else {
                &cameras[1].views[1].1
            };
            let m = f64s(f.sample(by(".vals"), i));
            let v = f64s(f.sample(core, i));
            // World to camera: the matrix is camera-to-world with the translation in its last
            // row, the camera looking down −Z with +Y up.
            let d = [point.x - m[12], point.y - m[13], point.z - m[14]];
            let axis = |r: usize| d[0] * m[4 * r] + d[1] * m[4 * r + 1] + d[2] * m[4 * r + 2];
            let (x, y, z) = (axis(0), axis(1), axis(2));
            let (focal, hap, hoff, vap, voff) = (v[0], v[1], v[2], v[3], v[4]);
            assert_eq!(v[5], 1.0, "no squeeze");
            // The screen window (Alembic's), then pixels: its edges are the image's.
            let sx = 2.0 * focal * (x / -z) / (hap * 10.0);
            let sy = 2.0 * focal * (y / -z) / (hap * 10.0);
            let (off_x, off_y, aper_y) = (2.0 * hoff / hap, 2.0 * voff / hap, vap / hap);
            let u = (sx - (off_x - 1.0)) / 2.0 * 1280.0 - 0.5;
            let w = (aper_y + off_y - sy) / (2.0 * aper_y) * 720.0 - 0.5;
            let want = view.project(&point).unwrap();
            assert!(
                (u - want.x).abs() < 1e-9 && (w - want.y).abs() < 1e-9,
                "camera {c} frame {frame}: ({u}, {w}) against ({}, {})",
                want.x,
                want.y
            );
            assert!(v[14] > 0.0 && v[15] > v[14], "a clipping range");
        }
    }
}

#[test]
fn alembic_carries_the_confidence_as_vertex_parameters_at_the_solved_frames() {
    // `track` writes a confidence file beside every solved frame, not beside the first: the
    // three numbers go into the mesh's `.arbGeomParams` as float vertex parameters on their own
    // time sampling (2: frames 11 and 12 of 10..=12); sigma is infinite where nothing holds the
    // vertex. When every frame has one, they share the points' sampling and no other is added.
    use abc_reader::File;
    let fr = frames(3);
    let conf = |f: u32| -> Vec<VertexConfidence> {
        (0..6)
            .map(|v| VertexConfidence {
                information: if v == 5 {
                    0.0
                } else {
                    f as f64 * 100.0 + v as f64
                },
                residual: 0.01 * (v + 1) as f64,
                pixels: 50.0,
            })
            .collect()
    };
    let confidence = vec![(11, conf(11)), (12, conf(12))];
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("c.abc");
    let bytes = abc_bytes_with(&fr, &confidence, &out);
    let f = File(&bytes);
    let root = f.children(f.root());
    let ts = f.data(root[4]);
    // Samplings 0 and 1 as before (24 bytes each), then 2: two samples, 1/24 s from 11/24 s.
    assert_eq!(ts.len(), 3 * 24);
    assert_eq!(&ts[48..52], &2u32.to_le_bytes());
    assert_eq!(f64s(&ts[52..60]), vec![1.0 / 24.0]);
    assert_eq!(f64s(&ts[64..72]), vec![11.0 / 24.0]);
    let top = f.objects(root[2]);
    let mesh = f.objects(top[0].2);
    let props = f.props(f.children(mesh[0].2)[0]);
    let geom = f.props(props[0].group);
    let arb = geom.iter().find(|p| p.name == ".arbGeomParams").unwrap();
    assert_eq!(arb.kind, 0);
    let params = f.props(arb.group);
    let names: Vec<&str> = params.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["information", "residual", "sigma"]);
    for p in &params {
        assert_eq!(
            (p.kind, p.pod, p.extent, p.samples, p.sampling),
            (2, 10, 1, 2, 2)
        );
        assert!(p.metadata.contains("geoScope=vtx") && p.metadata.contains("isGeomParam=true"));
    }
    for (i, (frame, c)) in confidence.iter().enumerate() {
        let info = f32s(f.sample(&params[0], i));
        let want: Vec<f32> = c.iter().map(|v| v.information as f32).collect();
        assert_eq!(info, want, "frame {frame}");
        let sigma = f32s(f.sample(&params[2], i));
        assert_eq!(sigma[0], c[0].sigma() as f32);
        assert!(sigma[5].is_infinite(), "nothing holds vertex 5");
    }
    // Every frame with its confidence: the points' sampling, no third.
    let all: Vec<_> = fr.iter().map(|(f, _)| (*f, conf(*f))).collect();
    let bytes = abc_bytes_with(&fr, &all, &out);
    let f = File(&bytes);
    let root = f.children(f.root());
    assert_eq!(f.data(root[4]).len(), 2 * 24);
    let mesh = f.objects(f.objects(root[2])[0].2);
    let geom = f.props(f.props(f.children(mesh[0].2)[0])[0].group);
    let arb = geom.iter().find(|p| p.name == ".arbGeomParams").unwrap();
    assert!(f
        .props(arb.group)
        .iter()
        .all(|p| (p.samples, p.sampling) == (3, 1)));
}

#[test]
fn alembic_keeps_an_artists_quads_and_uv_seams() {
    use abc_reader::File;
    // Two quads folded along x = 1, with a UV seam and a hard edge between them (as in
    // tests/export.rs).
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("folded.obj");
    std::fs::write(
        &src,
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 1 0 0\nv 1 1 0\nv 2 0 1\nv 2 1 1\n\
         vt 0 0\nvt 0.5 0\nvt 0.5 1\nvt 0 1\nvt 0.6 0\nvt 1 0\nvt 1 1\nvt 0.6 1\n\
         vn 0 0 1\nvn -0.6 0 0.8\n\
         f 1/1/1 2/2/1 3/3/1 4/4/1\nf 2/5/2 7/6/2 8/7/2 3/8/2\n",
    )
    .unwrap();
    let m = crate::input::read_mesh(&src).unwrap();
    let bytes = abc_bytes(&[(0, m.clone()), (1, m)], &dir.path().join("f.abc"));
    let f = File(&bytes);
    let top = f.objects(f.children(f.root())[2]);
    let mesh = f.objects(top[0].2);
    let geom = f.props(f.props(f.children(mesh[0].2)[0])[0].group);
    let by = |n: &str| geom.iter().find(|p| p.name == n).unwrap();
    let ints = |b: &[u8]| -> Vec<i32> {
        b.chunks(4)
            .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    };
    assert_eq!(ints(f.sample(by(".faceCounts"), 0)), vec![4, 4]);
    assert_eq!(
        ints(f.sample(by(".faceIndices"), 0)),
        vec![3, 2, 1, 0, 2, 7, 6, 1]
    );
    assert_eq!(
        f32s(f.sample(by("uv"), 0)),
        vec![0.0, 1.0, 0.5, 1.0, 0.5, 0.0, 0.0, 0.0, 0.6, 1.0, 1.0, 1.0, 1.0, 0.0, 0.6, 0.0]
    );
    // The normals per corner at both frames: the first quad's, then the second's.
    let n = by("N");
    assert_eq!((n.samples, n.extent), (2, 3));
    assert!(n.metadata.contains("interpretation=normal"));
    let mut want = [0.0, 0.0, 1.0].repeat(4);
    want.extend([-0.6, 0.0, 0.8].repeat(4));
    assert_eq!(f32s(f.sample(n, 1)), want);
}

//! Mesh files: OBJ and PLY (ascii and both binary byte orders) read back exactly what was
//! written, polygons are triangulated, a glTF file from Blender is read as the surface it holds,
//! and bad files give errors naming the file and line or element.

use modelflow::base::{grid, Mesh};
use modelflow::input::{read_mesh, write_obj};
use nalgebra::Point3;
use std::path::Path;

fn err(path: &Path) -> String {
    match read_mesh(path) {
        Ok(m) => panic!("{} read as {m:?}", path.display()),
        Err(e) => e.to_string(),
    }
}

fn assert_names(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "{msg:?} should mention {p:?}");
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn obj_round_trip_is_exact_with_and_without_uvs() {
    let dir = tempfile::tempdir().unwrap();
    // Awkward values: thirds, tiny and huge magnitudes, negative zero.
    let m = grid(4, 3, |u, v| {
        Point3::new(u / 3.0 + 1e-17, -v * 1e9 / 7.0, (u * v).sin() * 1e-300)
    });
    let p = dir.path().join("a.obj");
    write_obj(&p, &m).unwrap();
    assert_eq!(read_mesh(&p).unwrap(), m);
    let plain = Mesh::new(m.positions.clone(), m.triangles.clone());
    write_obj(&p, &plain).unwrap();
    let back = read_mesh(&p).unwrap();
    assert_eq!(back, plain);
    assert!(back.uvs.is_none());
}

/// Two quads folded along x = 1 as an artist's file has them: a UV seam (vertex 2 and 5 have
/// two texture coordinates each), a hard edge (the fold's normals are split) and quads.
const FOLDED: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 1 0 0\nv 1 1 0\nv 2 0 1\nv 2 1 1\n\
    vt 0 0\nvt 0.5 0\nvt 0.5 1\nvt 0 1\nvt 0.6 0\nvt 1 0\nvt 1 1\nvt 0.6 1\n\
    vn 0 0 1\nvn -0.7071067811865475 0 0.7071067811865475\n\
    f 1/1/1 2/2/1 3/3/1 4/4/1\nf 2/5/2 7/6/2 8/7/2 3/8/2\n";

#[test]
fn obj_keeps_seams_and_normals_through_writing_and_moving() {
    let dir = tempfile::tempdir().unwrap();
    let m = read_mesh(&write(dir.path(), "folded.obj", FOLDED.as_bytes())).unwrap();
    assert!(m.uvs.is_none(), "vertex 2 has two texture coordinates");
    let uv = m.corner_uvs.as_ref().expect("face-varying uvs kept");
    assert_eq!(uv.values.len(), 8);
    assert_eq!(uv.index, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]);
    let n = m.corner_normals.as_ref().expect("normals kept");
    assert_eq!(
        n.table.index,
        vec![[0, 0, 0], [0, 0, 0], [1, 1, 1], [1, 1, 1]]
    );
    // Written and read back: the same tables, the same indices, the same normals.
    let p = dir.path().join("out.obj");
    write_obj(&p, &m).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    // The quads are written as quads, as the input had them.
    assert!(text.contains("\nf 2/5/2 7/6/2 8/7/2 3/8/2\n"), "{text}");
    let back = read_mesh(&p).unwrap();
    assert_eq!(back.corner_uvs, m.corner_uvs);
    assert_eq!(back.corner_normals, m.corner_normals);
    // Turned 90 degrees about z, the normals turn with the surface; the uvs stay.
    let turned: Vec<Point3<f64>> = m
        .positions
        .iter()
        .map(|p| Point3::new(-p.y, p.x, p.z))
        .collect();
    let moved = m.with_positions(turned);
    let normals = moved.current_normals().unwrap();
    let want = [
        [0.0, 0.0, 1.0],
        [
            0.0,
            -std::f64::consts::FRAC_1_SQRT_2,
            std::f64::consts::FRAC_1_SQRT_2,
        ],
    ];
    for (got, want) in normals.iter().zip(want) {
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 1e-12, "{normals:?}");
        }
    }
    write_obj(&p, &moved).unwrap();
    let back = read_mesh(&p).unwrap();
    assert_eq!(back.corner_uvs, m.corner_uvs);
    assert_eq!(back.corner_normals.unwrap().table.index, n.table.index);
}

#[test]
fn obj_face_forms_quads_and_negative_indices() {
    let dir = tempfile::tempdir().unwrap();
    let text = "# a unit square as one quad, then a triangle with relative indices\n\
                mtllib x.mtl\no square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\ns off\nusemtl m\n\
                f 1/1/1 2/2/1 3/3/1 4/4/1\n\
                v 2 0 0.5 # comment after data\n\
                f 2//1 -1//1 3//1\n";
    let m = read_mesh(&write(dir.path(), "q.OBJ", text.as_bytes())).unwrap();
    assert_eq!(m.positions.len(), 5);
    assert_eq!(m.positions[4], Point3::new(2.0, 0.0, 0.5));
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]]);
    assert_eq!(m.polygons.as_deref(), Some(&vec![4, 3]));
    // The last face has no vt: per-vertex uvs are not defined.
    assert!(m.uvs.is_none());

    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0.5 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
                f -4/-4 -3/-3 -2/-2 -1/-1\n";
    let m = read_mesh(&write(dir.path(), "n.obj", text.as_bytes())).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.uvs.unwrap()[0], [0.5, 0.0]);

    // vt not 1:1 onto v (a seam: vertex 1 has two texture coordinates).
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0.2 0\n\
                f 1/1 2/2 3/3\nf 1/4 3/3 4/2\n";
    let m = read_mesh(&write(dir.path(), "s.obj", text.as_bytes())).unwrap();
    assert!(m.uvs.is_none());
}

#[test]
fn obj_polygons_are_written_back_as_the_input_had_them() {
    // An artist's mesh of quads, a pentagon and a triangle, with seams in its UVs and split
    // normals: tracked as triangles, written back with the same faces and the same vt/vn
    // indices at every corner, at the first frame and after the vertices moved.
    let dir = tempfile::tempdir().unwrap();
    let text = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\nv 3 0.5 0\nv 1 2 0\n\
                vt 0 0\nvt 0.5 0\nvt 1 0\nvt 0 0.5\nvt 0.5 0.5\nvt 1 0.5\nvt 0.9 0.2\nvt 0.5 1\nvt 0.6 0\n\
                vn 0 0 1\nvn 0 0.6 0.8\n\
                f 1/1/1 2/2/1 5/5/1 4/4/1\n\
                f 2/9/2 3/3/2 7/7/2 6/6/2 5/5/2\n\
                f 4/4/1 5/5/1 8/8/1\n\
                f 5/5/1 6/6/1 8/8/1\n";
    let src = write(dir.path(), "artist.obj", text.as_bytes());
    let m = read_mesh(&src).unwrap();
    assert_eq!(m.polygons.as_deref(), Some(&vec![4, 5, 3, 3]));
    assert_eq!(m.triangles.len(), 2 + 3 + 1 + 1);
    let faces = |path: &Path| -> Vec<String> {
        std::fs::read_to_string(path)
            .unwrap()
            .lines()
            .filter(|l| l.starts_with("f "))
            .map(str::to_string)
            .collect()
    };
    let out = dir.path().join("out.obj");
    write_obj(&out, &m).unwrap();
    let input: Vec<String> = text
        .lines()
        .filter(|l| l.starts_with("f "))
        .map(str::to_string)
        .collect();
    assert_eq!(faces(&out), input);
    assert_eq!(read_mesh(&out).unwrap(), m);
    let moved = m.with_positions(
        m.positions
            .iter()
            .map(|p| Point3::new(p.x, p.y, 0.1 * p.x * p.y))
            .collect(),
    );
    write_obj(&out, &moved).unwrap();
    assert_eq!(faces(&out), input);
    // A mesh whose triangles no longer match the faces (another topology) is written as
    // triangles, not as faces that would be wrong.
    write_obj(&out, &m.with_triangles(vec![[0, 1, 4], [0, 4, 3]])).unwrap();
    assert_eq!(faces(&out), vec!["f 1 2 5", "f 1 5 4"]);
}

#[test]
fn obj_errors_name_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n";
    let cases: &[(&str, &[&str])] = &[
        ("f 1 2 5\n", &["line 5", "\"5\" out of range"]),
        ("f 1 2 -5\n", &["line 5", "out of range"]),
        ("f 1 0 2\n", &["line 5", "out of range"]),
        ("f 1 2 x\n", &["line 5", "not a number"]),
        ("f 1 2\n", &["line 5", "at least 3"]),
        ("f 1 2 2\n", &["line 5", "degenerate", "repeated vertex"]),
        (
            "f 1 2 3\nf 2 4 3\nf 3 2 1\n",
            &["line 7", "duplicate triangle", "at line 5"],
        ),
        ("v 2 0 0\nf 1 2 5\n", &["line 6", "degenerate", "zero area"]),
        ("v nan 0 0\nf 1 2 3\n", &["line 5", "non-finite"]),
        ("v 1 2\n", &["line 5", "expected `v x y z`"]),
        ("f 1/9 2 3\n", &["line 5", "texture index"]),
        ("", &["faces", "no triangles"]),
    ];
    for (i, (tail, parts)) in cases.iter().enumerate() {
        let name = format!("bad{i}.obj");
        let p = write(d, &name, format!("{base}{tail}").as_bytes());
        let msg = err(&p);
        assert!(msg.contains(&name), "{msg:?} should name the file");
        assert_names(&msg, parts);
    }
    let msg = err(&d.join("missing.obj"));
    assert_names(&msg, &["missing.obj"]);
    let msg = err(&write(d, "m.stl", b"solid"));
    assert_names(&msg, &["m.stl", "extension", ".obj, .ply, .glb or .gltf"]);
}

// ---- PLY -------------------------------------------------------------------------------------

/// The test mesh: a unit square (one quad) and a triangle beside it.
fn square() -> (Vec<[f64; 3]>, Vec<Vec<u32>>) {
    (
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 1.0 / 3.0],
        ],
        vec![vec![0, 1, 2, 3], vec![1, 4, 2]],
    )
}

fn expected() -> Mesh {
    let (v, _) = square();
    Mesh {
        // The quad and the triangle, kept as faces for writing.
        polygons: Some(std::sync::Arc::new(vec![4, 3])),
        ..Mesh::new(
            v.iter().map(|p| Point3::new(p[0], p[1], p[2])).collect(),
            vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]],
        )
    }
}

const HEADER_BODY: &str = "comment written by a test\n\
    element vertex 5\n\
    property double x\nproperty uchar red\nproperty double y\nproperty double z\n\
    property list uchar float normals\n\
    element face 2\n\
    property short flags\nproperty list uchar int vertex_indices\nproperty list ushort uint extra\n\
    element material 1\nproperty float shininess\nproperty list int int ids\n\
    end_header\n";

/// A PLY with properties and elements the reader must skip: a `uchar red` between the
/// coordinates, a float list per vertex, a scalar and a list around the face indices, and a
/// trailing `material` element.
fn ply(format: &str) -> Vec<u8> {
    let (v, f) = square();
    let mut out = format!("ply\nformat {format} 1.0\n{HEADER_BODY}").into_bytes();
    if format == "ascii" {
        for p in &v {
            out.extend(format!("{} 200 {} {} 2 0.5 -0.5\n", p[0], p[1], p[2]).bytes());
        }
        for face in &f {
            let idx: Vec<String> = face.iter().map(|i| i.to_string()).collect();
            out.extend(format!("7 {} {} 1 9\n", face.len(), idx.join(" ")).bytes());
        }
        out.extend(b"0.25 3 1 2 3\n");
        return out;
    }
    let be = format == "binary_big_endian";
    macro_rules! put {
        ($v:expr) => {
            if be {
                out.extend_from_slice(&$v.to_be_bytes())
            } else {
                out.extend_from_slice(&$v.to_le_bytes())
            }
        };
    }
    for p in &v {
        put!(p[0]);
        put!(200u8);
        put!(p[1]);
        put!(p[2]);
        put!(2u8);
        put!(0.5f32);
        put!(-0.5f32);
    }
    for face in &f {
        put!(7i16);
        put!(face.len() as u8);
        for &i in face {
            put!(i as i32);
        }
        put!(1u16);
        put!(9u32);
    }
    put!(0.25f32);
    put!(3i32);
    for i in 1..=3i32 {
        put!(i);
    }
    out
}

#[test]
fn ply_ascii_and_binary_read_the_same_mesh() {
    let dir = tempfile::tempdir().unwrap();
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let p = write(dir.path(), &format!("{format}.ply"), &ply(format));
        let m = read_mesh(&p).unwrap_or_else(|e| panic!("{format}: {e}"));
        assert_eq!(m, expected(), "{format}");
    }
}

#[test]
fn ply_float_vertices_short_counts_and_vertex_index_name() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = b"ply\r\nformat binary_little_endian 1.0\r\nelement vertex 3\r\n\
        property float32 x\r\nproperty float32 y\r\nproperty float32 z\r\nproperty float32 u\r\nproperty float32 v\r\n\
        element face 1\r\nproperty list uint16 uint8 vertex_index\r\nend_header\r\n"
        .to_vec();
    for (x, y, u) in [(0.5f32, 0.0f32, 0.0f32), (1.5, 0.0, 1.0), (0.5, 1.25, 0.5)] {
        for v in [x, y, 0.0, u, 1.0 - u] {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b.extend_from_slice(&3u16.to_le_bytes());
    b.extend_from_slice(&[0, 1, 2]);
    let m = read_mesh(&write(dir.path(), "f.ply", &b)).unwrap();
    assert_eq!(m.positions[2], Point3::new(0.5, 1.25, 0.0));
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    assert_eq!(m.uvs.unwrap()[1], [1.0, 0.0]);
}

#[test]
fn ply_errors_name_file_and_element() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ascii = String::from_utf8(ply("ascii")).unwrap();
    let cases: Vec<(String, &[&str])> = vec![
        (
            ascii.replace("7 3 1 4 2", "7 3 1 5 2"),
            &["face[1]", "vertex index 5 out of range"],
        ),
        (
            ascii.replace("7 3 1 4 2", "7 3 1 1 2"),
            &["face[1]", "degenerate", "in 1 1 2"],
        ),
        (
            ascii.replace("2 200 0 0.3333333333333333", "1 200 0.5 0"),
            &["face[1]", "zero area"],
        ),
        (
            ascii.replace("1 200 1 0 2", "1 200 nan 0 2"),
            &["vertex[2]", "non-finite"],
        ),
        (
            ascii.replace("7 4 0 1 2 3", "7 4 0 1 2.5 3"),
            &["face[0]", "not an integer"],
        ),
        (
            ascii.replace("7 4 0 1 2 3 1 9", "7 4 0 1 2 3 1 9 9"),
            &["face[0]", "values on the line"],
        ),
        (
            ascii.replace("0.25 3 1 2 3\n", ""),
            &["material[0]", "ends early"],
        ),
        (
            ascii.replace("format ascii", "format utf16"),
            &["header line 2", "unknown format"],
        ),
        (
            ascii.replace("property double z", "property quad z"),
            &["header line", "unknown type"],
        ),
        (
            ascii.replace("end_header", "end_head"),
            &["header", "end_header"],
        ),
        (
            ascii.replacen("property double x", "property double w", 1),
            &["header", "x, y or z"],
        ),
    ];
    for (i, (text, parts)) in cases.iter().enumerate() {
        let name = format!("bad{i}.ply");
        let msg = err(&write(d, &name, text.as_bytes()));
        assert!(msg.contains(&name), "{msg:?} should name the file");
        assert_names(&msg, parts);
    }
    // An element without properties and an absurd count is skipped at once.
    let empty = ascii.replace(
        "element material 1",
        "element nothing 18446744073709551615\nelement material 1",
    );
    assert_eq!(
        read_mesh(&write(d, "empty.ply", empty.as_bytes())).unwrap(),
        expected()
    );
    let bin = ply("binary_big_endian");
    let msg = err(&write(d, "cut.ply", &bin[..bin.len() - 30]));
    assert_names(&msg, &["cut.ply", "face[1]", "truncated"]);
}

mod junk {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 200, .. ProptestConfig::default() })]

        /// Truncated or corrupted PLY/OBJ files give errors, never panics.
        #[test]
        fn damaged_mesh_files_never_panic(which in 0usize..4, cut in 0usize..2000, pos in 0usize..2000, byte in any::<u8>()) {
            let dir = tempfile::tempdir().unwrap();
            let (name, mut bytes) = match which {
                0 => ("a.ply", ply("ascii")),
                1 => ("b.ply", ply("binary_little_endian")),
                2 => ("c.ply", ply("binary_big_endian")),
                _ => {
                    let p = dir.path().join("x.obj");
                    write_obj(&p, &grid(3, 3, |u, v| Point3::new(u, v, u * v))).unwrap();
                    ("d.obj", std::fs::read(&p).unwrap())
                }
            };
            let p = pos % bytes.len();
            bytes[p] = byte;
            bytes.truncate(cut.min(bytes.len()));
            let _ = read_mesh(&write(dir.path(), name, &bytes));
        }
    }
}

#[test]
fn obj_with_a_byte_order_mark_or_carriage_returns_alone_reads_every_vertex() {
    let dir = tempfile::tempdir().unwrap();
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";
    let plain = read_mesh(&write(dir.path(), "plain.obj", text.as_bytes())).unwrap();
    assert_eq!(plain.positions.len(), 4);
    // A byte-order mark (Windows editors) before the first `v` line: that vertex is kept.
    let bom = format!("\u{feff}{text}");
    let m = read_mesh(&write(dir.path(), "bom.obj", bom.as_bytes())).unwrap();
    assert_eq!(m, plain);
    // Lines ended by a carriage return alone (classic Mac OS).
    let cr = text.replace('\n', "\r");
    let m = read_mesh(&write(dir.path(), "cr.obj", cr.as_bytes())).unwrap();
    assert_eq!(m, plain);
}

#[test]
fn a_polygon_with_three_corners_in_a_row_is_triangulated_without_a_flat_triangle() {
    let dir = tempfile::tempdir().unwrap();
    // A hexagon whose corners 1, 2, 3 lie on one straight edge (as CAD and Blender export a
    // face split along an edge); listed so that a fan from its first corner has a flat triangle.
    let text = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5 6\n";
    let m = read_mesh(&write(dir.path(), "hex.obj", text.as_bytes())).unwrap();
    assert_eq!(m.triangles.len(), 4);
    let area: f64 = m
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| m.positions[v as usize]);
            0.5 * (b - a).cross(&(c - a)).norm()
        })
        .collect::<Vec<_>>()
        .iter()
        .inspect(|&&a| assert!(a > 1e-9, "a flat triangle: {:?}", m.triangles))
        .sum();
    assert!((area - 3.0).abs() < 1e-12, "the hexagon's area, {area}");
    // Written back as one hexagon (its corners turned, the same face).
    let out = dir.path().join("back.obj");
    write_obj(&out, &m).unwrap();
    let back = std::fs::read_to_string(&out).unwrap();
    assert_eq!(
        back.lines().filter(|l| l.starts_with("f ")).count(),
        1,
        "{back}"
    );
    // The same face in a PLY file: the same triangles.
    let ply = "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n\
               property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
               end_header\n0 0 0\n1 0 0\n2 0 0\n2 1 0\n1 2 0\n0 1 0\n6 0 1 2 3 4 5\n";
    let p = read_mesh(&write(dir.path(), "hex.ply", ply.as_bytes())).unwrap();
    assert_eq!(p.triangles, m.triangles);
}

#[test]
fn gltf_from_blender_is_read_as_one_welded_surface_in_world_coordinates() {
    // fixtures/gltf (tools/make_gltf_fixture.py): the hard sample's irregular 565-vertex mesh as
    // Blender's glTF exporter writes it, split at every UV seam and hard edge, placed by a parent
    // node (turned, scaled unevenly, mirrored) and its own; beside it the same mesh as Blender's
    // OBJ exporter writes it in world coordinates. Read, the glTF must be that mesh: one vertex
    // per point (the splits welded), every triangle with the OBJ's corners in the OBJ's turning
    // order (the mirror's winding turned back), the UVs per corner, and the normals facing the
    // way the winding does.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/gltf");
    let glb = read_mesh(&dir.join("surface.glb")).unwrap();
    let obj = read_mesh(&dir.join("expected.obj")).unwrap();
    let stored: usize = gltf::Gltf::open(dir.join("surface.glb"))
        .unwrap()
        .document
        .meshes()
        .flat_map(|m| m.primitives().collect::<Vec<_>>())
        .map(|p| p.get(&gltf::Semantic::Positions).unwrap().count())
        .sum();
    assert!(stored > 700, "the file splits the vertices ({stored})");
    assert_eq!(glb.positions.len(), 565);
    assert_eq!(obj.positions.len(), 565);
    assert_eq!(glb.triangles.len(), obj.triangles.len());
    // The OBJ's vertex at each glTF vertex's point (6 decimals in the OBJ).
    let to_obj: Vec<usize> = glb
        .positions
        .iter()
        .map(|p| {
            let (i, d) = obj
                .positions
                .iter()
                .enumerate()
                .map(|(i, q)| (i, (p - q).norm()))
                .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
            assert!(d < 2e-6, "vertex at {p:?} is {d} from the OBJ's nearest");
            i
        })
        .collect();
    let mut seen = to_obj.clone();
    seen.sort_unstable();
    seen.dedup();
    assert_eq!(seen.len(), 565, "one glTF vertex per OBJ vertex");
    // Triangles: the same corners in the same turning order, and their UVs.
    let key = |t: [usize; 3]| {
        let r = (0..3).min_by_key(|&k| t[k]).unwrap();
        [t[r], t[(r + 1) % 3], t[(r + 2) % 3]]
    };
    let obj_tris: std::collections::HashMap<[usize; 3], usize> = obj
        .triangles
        .iter()
        .enumerate()
        .map(|(i, t)| (key(t.map(|v| v as usize)), i))
        .collect();
    let (guv, ouv) = (
        glb.corner_uvs.as_ref().unwrap(),
        obj.corner_uvs.as_ref().unwrap(),
    );
    for (i, t) in glb.triangles.iter().enumerate() {
        let mapped = t.map(|v| to_obj[v as usize]);
        let j = *obj_tris.get(&key(mapped)).unwrap_or_else(|| {
            panic!("triangle {i} {mapped:?} is not the OBJ's, or turns the other way")
        });
        for (k, &v) in mapped.iter().enumerate() {
            let m = (0..3).find(|&m| obj.triangles[j][m] as usize == v).unwrap();
            let a = guv.values[guv.index[i][k] as usize];
            let b = ouv.values[ouv.index[j][m] as usize];
            assert!(
                (a[0] - b[0]).abs() < 2e-6 && (a[1] - b[1]).abs() < 2e-6,
                "triangle {i} corner {k}: uv {a:?} against the OBJ's {b:?}"
            );
        }
    }
    // The normals (Blender's, turned by the nodes' inverse transpose) face as the winding does.
    let normals = glb.corner_normals.as_ref().unwrap();
    for (i, t) in glb.triangles.iter().enumerate() {
        let p = t.map(|v| glb.positions[v as usize]);
        let face = (p[1] - p[0]).cross(&(p[2] - p[0])).normalize();
        for k in 0..3 {
            let n = normals.table.values[normals.table.index[i][k] as usize];
            let d = face.dot(&nalgebra::Vector3::from(n));
            assert!(
                d > 0.3,
                "triangle {i} corner {k}: normal against the face {d}"
            );
        }
    }
}

#[test]
fn gltf_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "broken.glb", b"glTF\x02\x00\x00\x00garbage");
    assert_names(&err(&p), &["broken.glb"]);
    let p = write(
        dir.path(),
        "mesh.gltf",
        b"{\"asset\": {\"version\": \"2.0\"}}",
    );
    assert_names(&err(&p), &["mesh.gltf", "no triangles"]);
}

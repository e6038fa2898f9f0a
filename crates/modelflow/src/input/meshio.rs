//! Reading and writing triangle meshes: Wavefront OBJ and PLY (ascii and both binary byte
//! orders) in, OBJ out, with validation that names the file and the line (OBJ) or element (PLY)
//! at fault.
//!
//! Both readers are written by hand: `tobj` reports no line numbers (which our errors must give)
//! and, to give per-vertex texture coordinates, splits vertices, changing the vertex identity
//! the tracker and the ground truth depend on; `ply-rs` is no longer maintained. The subset we
//! need (positions, optional texture coordinates, polygon faces) is small.

use crate::base::mesh::{CornerNormals, CornerTable, Mesh};
use crate::error::{Error, Result};
use crate::fsutil::write_atomic_with;
use nalgebra::Point3;
use std::io::Write;
use std::path::Path;
use std::sync::Arc;

/// How much of [`validate`] a reader applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Checks {
    /// Everything, including degenerate triangles: for input meshes.
    Full,
    /// Structure only (triangles present, indices in range, finite positions), degenerate
    /// triangles allowed: for meshes a run produced, which may have collapsed triangles.
    Structure,
}

/// Reads a mesh, dispatching on the file extension (`.obj`, `.ply`, or glTF's `.glb` and `.gltf`,
/// whose meshes are read as one in world coordinates, the vertices split at seams welded:
/// docs/scene-format.md; any case), and validates
/// it fully (see [`validate`]).
pub fn read_mesh(path: &Path) -> Result<Mesh> {
    read_mesh_with(path, Checks::Full)
}

/// [`read_mesh`] with a choice of checks.
pub fn read_mesh_with(path: &Path, checks: Checks) -> Result<Mesh> {
    crate::fsutil::require_file(path, "mesh")?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "obj" => {
            let text = std::fs::read(path).map_err(|e| Error::io(path, e))?;
            parse_obj(path, &String::from_utf8_lossy(&text), checks)
        }
        "ply" => {
            let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
            parse_ply(path, &bytes, checks)
        }
        "glb" | "gltf" => super::gltfmesh::read_gltf(path, checks),
        _ => Err(Error::invalid(
            path,
            "extension",
            format!("unknown mesh format {ext:?}: expected .obj, .ply, .glb or .gltf"),
        )),
    }
}

/// The corner of polygon `poly` (vertex indices, in order) from which its fan triangulation has
/// no flat triangle (the test [`validate`] applies), the first such; 0 when every corner gives one
/// (a truly degenerate polygon, then refused with its line) or an index is not yet known.
fn fan_start(poly: &[u32], positions: &[Point3<f64>]) -> usize {
    let n = poly.len();
    if n <= 3 || poly.iter().any(|&v| v as usize >= positions.len()) {
        return 0;
    }
    let flat = |a: u32, b: u32, c: u32| {
        let [a, b, c] = [a, b, c].map(|v| positions[v as usize]);
        let (e1, e2) = (b - a, c - a);
        let longest = e1.norm().max(e2.norm()).max((c - b).norm());
        e1.cross(&e2).norm() <= 1e-12 * longest * longest
    };
    (0..n)
        .find(|&r| (1..n - 1).all(|k| !flat(poly[r], poly[(r + k) % n], poly[(r + k + 1) % n])))
        .unwrap_or(0)
}

/// Checks a mesh read from `path`: at least one triangle, finite positions, indices in range,
/// and with [`Checks::Full`] no degenerate triangle (repeated index or zero area). `locate(i)`
/// names triangle `i`'s place in the file (e.g. `line 12`); vertex numbers in messages start at
/// `index_base` (1 for OBJ, 0 for PLY), as in the file.
pub fn validate(
    path: &Path,
    mesh: &Mesh,
    checks: Checks,
    index_base: u32,
    locate: impl Fn(usize) -> String,
) -> Result<()> {
    let base = index_base as u64;
    let n = mesh.positions.len();
    if let Some(i) = mesh
        .positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(Error::invalid(
            path,
            format!("vertex {}", i as u64 + base),
            format!(
                "non-finite coordinate {:?}",
                mesh.positions[i].coords.as_slice()
            ),
        ));
    }
    if mesh.triangles.is_empty() {
        return Err(Error::invalid(
            path,
            "faces",
            "the mesh has no triangles (a mesh needs at least one face)",
        ));
    }
    // Each triangle's sorted vertices, to find one given twice (the same pixels would be
    // compared twice, and the two copies fight over the warp where their windings differ).
    let mut seen: std::collections::HashMap<[u32; 3], usize> = std::collections::HashMap::new();
    for (i, t) in mesh.triangles.iter().enumerate() {
        if let Some(&bad) = t.iter().find(|&&v| v as usize >= n) {
            return Err(Error::invalid(
                path,
                locate(i),
                format!(
                    "vertex index {} out of range (the mesh has {n} vertices)",
                    bad as u64 + base
                ),
            ));
        }
        if checks == Checks::Structure {
            continue;
        }
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            return Err(Error::invalid(
                path,
                locate(i),
                format!(
                    "degenerate triangle: repeated vertex in {} {} {}",
                    t[0] as u64 + base,
                    t[1] as u64 + base,
                    t[2] as u64 + base
                ),
            ));
        }
        let mut key = *t;
        key.sort_unstable();
        if let Some(&first) = seen.get(&key) {
            return Err(Error::invalid(
                path,
                locate(i),
                format!(
                    "duplicate triangle: vertices {} {} {} already form the triangle at {}",
                    t[0] as u64 + base,
                    t[1] as u64 + base,
                    t[2] as u64 + base,
                    locate(first)
                ),
            ));
        }
        seen.insert(key, i);
        let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
        let (e1, e2) = (b - a, c - a);
        let longest = e1.norm().max(e2.norm()).max((c - b).norm());
        let area2 = e1.cross(&e2).norm();
        if area2 <= 1e-12 * longest * longest {
            return Err(Error::invalid(
                path,
                locate(i),
                format!(
                    "degenerate triangle: vertices {} {} {} have zero area",
                    t[0] as u64 + base,
                    t[1] as u64 + base,
                    t[2] as u64 + base
                ),
            ));
        }
    }
    if let Some(uvs) = &mesh.uvs {
        if uvs.len() != n {
            return Err(Error::invalid(
                path,
                "vt",
                format!("{} texture coordinates for {n} vertices", uvs.len()),
            ));
        }
    }
    Ok(())
}

/// Parses OBJ text. Reads `v`, `vt`, `vn` and `f` (forms `v`, `v/vt`, `v//vn`, `v/vt/vn`,
/// negative indices relative to the end); polygons are fan-triangulated; every other statement
/// is ignored. The faces' `vt` and `vn` indices are kept per triangle corner
/// ([`Mesh::corner_uvs`], [`Mesh::corner_normals`]) when every corner has one; per-vertex
/// texture coordinates ([`Mesh::uvs`]) only when the faces map each vertex to one `vt`
/// consistently.
pub fn parse_obj(path: &Path, text: &str, checks: Checks) -> Result<Mesh> {
    // A byte-order mark is not part of the first line (it would hide a `v` line), and a file
    // whose lines end in a carriage return alone (classic Mac OS) has lines all the same.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let cr_only;
    let text = if !text.contains('\n') && text.contains('\r') {
        cr_only = text.replace('\r', "\n");
        cr_only.as_str()
    } else {
        text
    };
    let mut positions: Vec<Point3<f64>> = Vec::new();
    let mut tex: Vec<[f64; 2]> = Vec::new();
    let mut normals: Vec<[f64; 3]> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    // Per triangle corner: the vt and vn indices (kept while every corner has one).
    let mut corner_vt: Option<Vec<[u32; 3]>> = Some(Vec::new());
    let mut corner_vn: Option<Vec<[u32; 3]>> = Some(Vec::new());
    let mut tri_lines: Vec<usize> = Vec::new();
    // Each face's corner count (kept as the mesh's polygons when one has more than three).
    let mut face_sizes: Vec<u32> = Vec::new();
    // Vertex -> vt index seen in faces; `uv_ok` turns false on any inconsistency.
    let mut uv_of: Vec<Option<usize>> = Vec::new();
    let mut uv_ok = true;
    let mut corners: Vec<(u32, Option<usize>, Option<u32>)> = Vec::new();

    for (lineno, raw) in text.lines().enumerate() {
        let line_no = lineno + 1;
        let field = || format!("line {line_no}");
        let line = raw.split('#').next().unwrap_or("");
        let mut it = line.split_whitespace();
        let Some(tag) = it.next() else { continue };
        match tag {
            "v" => {
                let c = parse_floats::<3>(&mut it).ok_or_else(|| {
                    Error::invalid(path, field(), format!("expected `v x y z`, got {raw:?}"))
                })?;
                if !c.iter().all(|v| v.is_finite()) {
                    return Err(Error::invalid(
                        path,
                        field(),
                        format!("non-finite vertex coordinate in {raw:?}"),
                    ));
                }
                positions.push(Point3::new(c[0], c[1], c[2]));
            }
            "vt" => {
                let c = parse_floats::<2>(&mut it).ok_or_else(|| {
                    Error::invalid(path, field(), format!("expected `vt u v`, got {raw:?}"))
                })?;
                tex.push(c);
            }
            "vn" => {
                let c = parse_floats::<3>(&mut it)
                    .filter(|c| c.iter().all(|v| v.is_finite()))
                    .ok_or_else(|| {
                        Error::invalid(
                            path,
                            field(),
                            format!("expected `vn x y z` with finite numbers, got {raw:?}"),
                        )
                    })?;
                normals.push(c);
            }
            "f" => {
                corners.clear();
                for tok in it {
                    let mut parts = tok.split('/');
                    let vi = parts.next().unwrap_or("");
                    let v = resolve_index(vi, positions.len()).ok_or_else(|| {
                        Error::invalid(
                            path,
                            field(),
                            format!(
                                "vertex index {vi:?} out of range or not a number (there are {} vertices so far)",
                                positions.len()
                            ),
                        )
                    })?;
                    let vt = match parts.next() {
                        Some(s) if !s.is_empty() => {
                            Some(resolve_index(s, tex.len()).ok_or_else(|| {
                                Error::invalid(
                                    path,
                                    field(),
                                    format!(
                                        "texture index {s:?} out of range or not a number (there are {} vt so far)",
                                        tex.len()
                                    ),
                                )
                            })? as usize)
                        }
                        _ => None,
                    };
                    let vn = match parts.next() {
                        Some(s) if !s.is_empty() => {
                            Some(resolve_index(s, normals.len()).ok_or_else(|| {
                                Error::invalid(
                                    path,
                                    field(),
                                    format!(
                                        "normal index {s:?} out of range or not a number (there are {} vn so far)",
                                        normals.len()
                                    ),
                                )
                            })?)
                        }
                        _ => None,
                    };
                    corners.push((v, vt, vn));
                }
                if corners.len() < 3 {
                    return Err(Error::invalid(
                        path,
                        field(),
                        format!("a face needs at least 3 vertices, got {raw:?}"),
                    ));
                }
                for &(v, vt, _) in corners.iter() {
                    let v = v as usize;
                    if uv_of.len() <= v {
                        uv_of.resize(v + 1, None);
                    }
                    match (vt, uv_of[v]) {
                        (None, _) => uv_ok = false,
                        (Some(t), None) => uv_of[v] = Some(t),
                        (Some(t), Some(prev)) if prev != t => uv_ok = false,
                        _ => {}
                    }
                }
                if corners.iter().any(|c| c.1.is_none()) {
                    corner_vt = None;
                }
                if corners.iter().any(|c| c.2.is_none()) {
                    corner_vn = None;
                }
                face_sizes.push(corners.len() as u32);
                // The fan starts at a corner from which no triangle is flat (a polygon with
                // three corners in a row, as CAD and Blender export them); the polygon is the
                // same with its corners turned, and is written back so.
                let r = fan_start(&corners.iter().map(|c| c.0).collect::<Vec<_>>(), &positions);
                corners.rotate_left(r);
                for k in 1..corners.len() - 1 {
                    let tri = [corners[0], corners[k], corners[k + 1]];
                    triangles.push(tri.map(|c| c.0));
                    tri_lines.push(line_no);
                    if let Some(t) = corner_vt.as_mut() {
                        t.push(tri.map(|c| c.1.unwrap_or(0) as u32));
                    }
                    if let Some(n) = corner_vn.as_mut() {
                        n.push(tri.map(|c| c.2.unwrap_or(0)));
                    }
                }
            }
            _ => {}
        }
    }
    let uvs = if uv_ok && !tex.is_empty() && !triangles.is_empty() {
        uv_of.resize(positions.len(), None);
        let mapped: Option<Vec<[f64; 2]>> = uv_of.iter().map(|t| t.map(|t| tex[t])).collect();
        match mapped {
            Some(u) => Some(u),
            // Vertices used by no face: fall back to vt[i] when the counts agree.
            None if tex.len() == positions.len() => Some(
                uv_of
                    .iter()
                    .enumerate()
                    .map(|(i, t)| tex[t.unwrap_or(i)])
                    .collect(),
            ),
            None => None,
        }
    } else {
        None
    };
    let mut mesh = Mesh {
        uvs,
        polygons: face_sizes
            .iter()
            .any(|&n| n > 3)
            .then(|| Arc::new(face_sizes)),
        ..Mesh::new(positions, triangles)
    };
    validate(path, &mesh, checks, 1, |i| format!("line {}", tri_lines[i]))?;
    let faces = !mesh.triangles.is_empty();
    // A table that maps each vertex to the vt of the same number says no more than the
    // per-vertex uvs (and is written back the same way).
    let same_as_vertices = |index: &Vec<[u32; 3]>| {
        tex.len() == mesh.positions.len() && mesh.uvs.is_some() && *index == mesh.triangles
    };
    mesh.corner_uvs = corner_vt
        .filter(|index| faces && !tex.is_empty() && !same_as_vertices(index))
        .map(|index| Arc::new(CornerTable { values: tex, index }));
    if let Some(index) = corner_vn.filter(|_| faces && !normals.is_empty()) {
        let rest = mesh.corner_group_normals(&index, normals.len());
        mesh.corner_normals = Some(Arc::new(CornerNormals {
            table: CornerTable {
                values: normals,
                index,
            },
            rest,
        }));
    }
    Ok(mesh)
}

fn parse_floats<'a, const N: usize>(it: &mut impl Iterator<Item = &'a str>) -> Option<[f64; N]> {
    let mut out = [0.0; N];
    for o in out.iter_mut() {
        *o = it.next()?.parse().ok()?;
    }
    Some(out)
}

/// A 1-based (or negative, relative) OBJ index to a 0-based index below `count`.
fn resolve_index(s: &str, count: usize) -> Option<u32> {
    let i: i64 = s.parse().ok()?;
    let idx = if i > 0 {
        i - 1
    } else if i < 0 {
        count as i64 + i
    } else {
        return None;
    };
    (idx >= 0 && (idx as usize) < count && idx <= u32::MAX as i64).then_some(idx as u32)
}

/// Writes a mesh as OBJ atomically: positions in the shortest text that reads back to the same
/// `f64`; the input file's texture coordinates and normals with their face-varying indices as
/// the input had them (normals turned with the surface, [`Mesh::current_normals`]), or per-vertex
/// texture coordinates; then one `f` per triangle (1-based).
pub fn write_obj(path: &Path, mesh: &Mesh) -> Result<()> {
    write_atomic_with(path, |w| write_obj_to(w, mesh))
}

/// [`write_obj`]'s text, into `w`.
pub(crate) fn write_obj_to(w: &mut impl Write, mesh: &Mesh) -> std::io::Result<()> {
    let vertex_uvs = mesh
        .uvs
        .as_ref()
        .filter(|u| u.len() == mesh.positions.len() && mesh.corner_uvs.is_none());
    let normals = mesh.current_normals();
    {
        writeln!(
            w,
            "# modelflow mesh: {} vertices, {} triangles",
            mesh.positions.len(),
            mesh.triangles.len()
        )?;
        for p in &mesh.positions {
            writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
        }
        if let Some(t) = &mesh.corner_uvs {
            for uv in &t.values {
                writeln!(w, "vt {} {}", uv[0], uv[1])?;
            }
        } else if let Some(uvs) = vertex_uvs {
            for uv in uvs {
                writeln!(w, "vt {} {}", uv[0], uv[1])?;
            }
        }
        if let Some(ns) = &normals {
            for n in ns {
                writeln!(w, "vn {} {} {}", n[0], n[1], n[2])?;
            }
        }
        let vn_index = mesh.corner_normals.as_ref().map(|n| &n.table.index);
        // The input's polygons where it had them (a quad stays a quad), else the triangles.
        let (counts, corners) = mesh.face_corners();
        let mut corners = corners.into_iter();
        for n in counts {
            w.write_all(b"f")?;
            for (i, k) in corners.by_ref().take(n as usize) {
                let (i, k) = (i as usize, k as usize);
                let v = mesh.triangles[i][k] as u64 + 1;
                let vt = match (&mesh.corner_uvs, vertex_uvs) {
                    (Some(c), _) => Some(c.index[i][k] as u64 + 1),
                    (None, Some(_)) => Some(v),
                    _ => None,
                };
                match (vt, vn_index.map(|n| n[i][k] as u64 + 1)) {
                    (None, None) => write!(w, " {v}")?,
                    (Some(vt), None) => write!(w, " {v}/{vt}")?,
                    (None, Some(vn)) => write!(w, " {v}//{vn}")?,
                    (Some(vt), Some(vn)) => write!(w, " {v}/{vt}/{vn}")?,
                }
            }
            w.write_all(b"\n")?;
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// PLY

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Debug)]
enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: PropKind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Clone, Copy, PartialEq)]
enum PlyFormat {
    Ascii,
    Le,
    Be,
}

/// A source of property values: ascii tokens or binary bytes.
trait ValueSource {
    fn value(&mut self, ty: Scalar) -> std::result::Result<f64, String>;
    /// Called after each element (ascii: one element per line).
    fn end_element(&mut self) -> std::result::Result<(), String> {
        Ok(())
    }
}

struct Binary<'a> {
    bytes: &'a [u8],
    pos: usize,
    big: bool,
}

impl ValueSource for Binary<'_> {
    fn value(&mut self, ty: Scalar) -> std::result::Result<f64, String> {
        let n = ty.size();
        let Some(b) = self.bytes.get(self.pos..self.pos + n) else {
            return Err("file ends early (truncated binary data)".into());
        };
        self.pos += n;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        if self.big {
            a[..n].reverse();
        }
        Ok(match ty {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        })
    }
}

struct Ascii<'a> {
    lines: std::str::Lines<'a>,
    current: Vec<&'a str>,
    next_tok: usize,
}

impl ValueSource for Ascii<'_> {
    fn value(&mut self, ty: Scalar) -> std::result::Result<f64, String> {
        if self.current.is_empty() {
            // Start of an element: its values are on the next non-blank line.
            loop {
                let line = self.lines.next().ok_or("file ends early")?;
                self.current = line.split_whitespace().collect();
                if !self.current.is_empty() {
                    break;
                }
            }
            self.next_tok = 0;
        }
        if self.next_tok >= self.current.len() {
            return Err(format!(
                "too few values on the line (got {})",
                self.current.len()
            ));
        }
        let tok = self.current[self.next_tok];
        self.next_tok += 1;
        let v: f64 = tok
            .parse()
            .map_err(|_| format!("{tok:?} is not a number"))?;
        if ty.is_integer() && v.fract() != 0.0 {
            return Err(format!("{tok:?} is not an integer"));
        }
        Ok(v)
    }

    fn end_element(&mut self) -> std::result::Result<(), String> {
        if self.next_tok < self.current.len() {
            return Err(format!(
                "{} values on the line, expected {}",
                self.current.len(),
                self.next_tok
            ));
        }
        self.current.clear();
        self.next_tok = 0;
        Ok(())
    }
}

/// Parses a PLY file (ascii, binary_little_endian or binary_big_endian). Reads `x y z` of the
/// `vertex` element (any numeric type), optional texture coordinates (`u v`, `s t` or
/// `texture_u texture_v`) and the `vertex_indices`/`vertex_index` list of the `face` element
/// (any integer types; polygons fan-triangulated). Every other property and element is skipped.
pub fn parse_ply(path: &Path, bytes: &[u8], checks: Checks) -> Result<Mesh> {
    let header_err = |msg: String| Error::invalid(path, "header", msg);
    // Header: ascii lines up to `end_header`.
    let mut pos = 0usize;
    let mut lines: Vec<String> = Vec::new();
    loop {
        let Some(nl) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(header_err("no `end_header` line".into()));
        };
        let line = String::from_utf8_lossy(&bytes[pos..pos + nl])
            .trim_end_matches('\r')
            .to_string();
        pos += nl + 1;
        let done = line.trim() == "end_header";
        lines.push(line);
        if done {
            break;
        }
        if lines.len() > 100_000 {
            return Err(header_err("header too long".into()));
        }
    }
    if lines.first().map(|l| l.trim()) != Some("ply") {
        return Err(header_err("the file does not start with `ply`".into()));
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for (i, line) in lines.iter().enumerate().skip(1) {
        let at = |msg: String| Error::invalid(path, format!("header line {}", i + 1), msg);
        let toks: Vec<&str> = line.split_whitespace().collect();
        match toks.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] | ["end_header"] => {}
            ["format", f, _version] => {
                format = Some(match *f {
                    "ascii" => PlyFormat::Ascii,
                    "binary_little_endian" => PlyFormat::Le,
                    "binary_big_endian" => PlyFormat::Be,
                    other => return Err(at(format!("unknown format {other:?}"))),
                })
            }
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count
                    .parse()
                    .map_err(|_| at(format!("bad element count {count:?}")))?,
                props: Vec::new(),
            }),
            ["property", "list", ct, it, name] => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| at("property before any element".into()))?;
                let count = Scalar::parse(ct)
                    .filter(|s| s.is_integer())
                    .ok_or_else(|| at(format!("bad list count type {ct:?}")))?;
                let item = Scalar::parse(it).ok_or_else(|| at(format!("unknown type {it:?}")))?;
                e.props.push(Property {
                    name: name.to_string(),
                    kind: PropKind::List { count, item },
                });
            }
            ["property", ty, name] => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| at("property before any element".into()))?;
                let ty = Scalar::parse(ty).ok_or_else(|| at(format!("unknown type {ty:?}")))?;
                e.props.push(Property {
                    name: name.to_string(),
                    kind: PropKind::Scalar(ty),
                });
            }
            _ => return Err(at(format!("cannot read {line:?}"))),
        }
    }
    let format = format.ok_or_else(|| header_err("no `format` line".into()))?;
    let body = &bytes[pos..];
    match format {
        PlyFormat::Ascii => {
            let text = std::str::from_utf8(body)
                .map_err(|_| Error::invalid(path, "body", "ascii PLY body is not valid text"))?;
            let mut src = Ascii {
                lines: text.lines(),
                current: Vec::new(),
                next_tok: 0,
            };
            read_ply_body(path, &elements, &mut src, checks)
        }
        PlyFormat::Le | PlyFormat::Be => {
            let mut src = Binary {
                bytes: body,
                pos: 0,
                big: format == PlyFormat::Be,
            };
            read_ply_body(path, &elements, &mut src, checks)
        }
    }
}

fn read_ply_body(
    path: &Path,
    elements: &[Element],
    src: &mut impl ValueSource,
    checks: Checks,
) -> Result<Mesh> {
    let mut positions = Vec::new();
    let mut uvs: Vec<[f64; 2]> = Vec::new();
    let mut triangles = Vec::new();
    let mut tri_faces: Vec<usize> = Vec::new();
    let mut face_sizes: Vec<u32> = Vec::new();
    let mut saw_vertex = false;
    let mut poly: Vec<u32> = Vec::new();
    for el in elements {
        let at = |i: usize, msg: String| Error::invalid(path, format!("{}[{i}]", el.name), msg);
        let find = |n: &str| {
            el.props
                .iter()
                .position(|p| p.name == n && matches!(p.kind, PropKind::Scalar(_)))
        };
        let is_vertex = el.name == "vertex" && !saw_vertex;
        let (xyz, uv) = if is_vertex {
            saw_vertex = true;
            let xyz = match (find("x"), find("y"), find("z")) {
                (Some(x), Some(y), Some(z)) => [x, y, z],
                _ => {
                    return Err(Error::invalid(
                        path,
                        "header",
                        "element `vertex` lacks x, y or z",
                    ))
                }
            };
            let uv = [("u", "v"), ("s", "t"), ("texture_u", "texture_v")]
                .iter()
                .find_map(|(a, b)| Some([find(a)?, find(b)?]));
            positions.reserve(el.count.min(1 << 16));
            (Some(xyz), uv)
        } else {
            (None, None)
        };
        let face_list = if el.name == "face" {
            el.props.iter().position(|p| {
                (p.name == "vertex_indices" || p.name == "vertex_index")
                    && matches!(p.kind, PropKind::List { item, .. } if item.is_integer())
            })
        } else {
            None
        };
        let mut vals = [0.0f64; 5];
        if el.props.is_empty() && !is_vertex {
            // Nothing stored per element: nothing to read (and no loop over a junk count).
            continue;
        }
        for i in 0..el.count {
            for (pi, p) in el.props.iter().enumerate() {
                match p.kind {
                    PropKind::Scalar(ty) => {
                        let v = src.value(ty).map_err(|m| at(i, m))?;
                        if let Some(xyz) = xyz {
                            if let Some(k) = xyz.iter().position(|&q| q == pi) {
                                vals[k] = v;
                            }
                            if let Some(k) = uv.and_then(|uv| uv.iter().position(|&q| q == pi)) {
                                vals[3 + k] = v;
                            }
                        }
                    }
                    PropKind::List { count, item } => {
                        let n = src.value(count).map_err(|m| at(i, m))?;
                        if !(0.0..=1e6).contains(&n) {
                            return Err(at(i, format!("bad list length {n}")));
                        }
                        let keep = face_list == Some(pi);
                        poly.clear();
                        for _ in 0..n as usize {
                            let v = src.value(item).map_err(|m| at(i, m))?;
                            if keep {
                                if !(0.0..=u32::MAX as f64).contains(&v) {
                                    return Err(at(i, format!("vertex index {v} out of range")));
                                }
                                poly.push(v as u32);
                            }
                        }
                        if keep {
                            if poly.len() < 3 {
                                return Err(at(
                                    i,
                                    format!("a face needs at least 3 vertices, got {}", poly.len()),
                                ));
                            }
                            face_sizes.push(poly.len() as u32);
                            // As for OBJ: the fan from a corner that gives no flat triangle.
                            let r = fan_start(&poly, &positions);
                            poly.rotate_left(r);
                            for k in 1..poly.len() - 1 {
                                triangles.push([poly[0], poly[k], poly[k + 1]]);
                                tri_faces.push(i);
                            }
                        }
                    }
                }
            }
            src.end_element().map_err(|m| at(i, m))?;
            if xyz.is_some() {
                let p = Point3::new(vals[0], vals[1], vals[2]);
                if !p.iter().all(|c| c.is_finite()) {
                    return Err(at(i, format!("non-finite coordinate {:?}", &vals[..3])));
                }
                positions.push(p);
                if uv.is_some() {
                    uvs.push([vals[3], vals[4]]);
                }
            }
        }
    }
    if !saw_vertex {
        return Err(Error::invalid(path, "header", "no `vertex` element"));
    }
    let has_uv = !uvs.is_empty();
    let mesh = Mesh {
        uvs: has_uv.then_some(uvs),
        polygons: face_sizes
            .iter()
            .any(|&n| n > 3)
            .then(|| Arc::new(face_sizes)),
        ..Mesh::new(positions, triangles)
    };
    validate(path, &mesh, checks, 0, |i| {
        format!("face[{}]", tri_faces[i])
    })?;
    Ok(mesh)
}

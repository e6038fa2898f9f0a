//! Reading the first mesh from glTF 2.0 (`.glb`, or `.gltf` with its buffers beside it), as
//! Blender, Maya and most 3D packages write it. The file is parsed by the `gltf` crate; what is
//! ours is turning the scene into one tracked mesh: every triangle primitive of every mesh the
//! default scene's nodes place, in world coordinates (each node's transform applied, a mirroring
//! one turning the triangles' winding back), and the vertices a glTF file splits at UV seams and
//! hard edges (it stores attributes per vertex) welded back into one surface where they lie at the
//! same point, so that the tracker sees the surface the artist made, not one piece per seam. The
//! texture coordinates and normals stay per corner, as an OBJ's `vt`/`vn` indices keep them, with
//! glTF's top-left UV origin turned into the OBJ's bottom-left. Coordinates are taken as they are
//! (no axis swapped: glTF's +Y up is the scene's axes, as the glTF export writes them).

use super::meshio::{validate, Checks};
use crate::base::mesh::{CornerNormals, CornerTable, Mesh};
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Matrix4, Point3, Vector3};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

/// The vertices and corners gathered from the primitives, before welding.
#[derive(Default)]
struct Gathered {
    /// Per glTF vertex (all primitives, one after another): world position, UV, normal.
    positions: Vec<Point3<f64>>,
    uvs: Vec<[f64; 2]>,
    normals: Vec<[f64; 3]>,
    /// Every primitive had texture coordinates, and normals.
    all_uvs: bool,
    all_normals: bool,
    /// Triangles over the glTF vertices, and where each came from (for messages).
    triangles: Vec<[u32; 3]>,
    places: Vec<(usize, usize, usize)>,
}

/// Reads a glTF file's meshes as one mesh (see the module's doc) and checks it as
/// [`super::meshio::read_mesh_with`] checks any mesh.
pub(crate) fn read_gltf(path: &Path, checks: Checks) -> Result<Mesh> {
    let bad = |field: &str, e: String| Error::invalid(path, field, e);
    let file = gltf::Gltf::open(path).map_err(|e| bad("glTF", e.to_string()))?;
    let buffers = gltf::import_buffers(&file.document, path.parent(), file.blob.clone())
        .map_err(|e| bad("buffers", e.to_string()))?;
    let mut g = Gathered {
        all_uvs: true,
        all_normals: true,
        ..Default::default()
    };
    let doc = &file.document;
    match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => {
            for node in scene.nodes() {
                gather_node(path, &node, &Matrix4::identity(), &buffers, &mut g)?;
            }
        }
        // No scene: the meshes as they are stored.
        None => {
            for mesh in doc.meshes() {
                gather_mesh(path, &mesh, &Matrix4::identity(), &buffers, &mut g)?;
            }
        }
    }
    if g.triangles.is_empty() {
        return Err(bad(
            "meshes",
            "no triangles: the file's scene places no mesh with a triangle primitive".into(),
        ));
    }
    // Weld: one vertex per distinct world position (the same f64 bits), in order of first use.
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let welded: Vec<u32> = g
        .positions
        .iter()
        .map(|p| {
            let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
            *index.entry(key).or_insert_with(|| {
                positions.push(*p);
                (positions.len() - 1) as u32
            })
        })
        .collect();
    let triangles: Vec<[u32; 3]> = g
        .triangles
        .iter()
        .map(|t| t.map(|v| welded[v as usize]))
        .collect();
    let mut mesh = Mesh::new(positions, triangles);
    validate(path, &mesh, checks, 0, |i| {
        let (m, p, t) = g.places[i];
        format!("mesh {m}, primitive {p}, triangle {t}")
    })?;
    if g.all_uvs {
        mesh.corner_uvs = Some(Arc::new(CornerTable {
            values: g.uvs,
            index: g.triangles.clone(),
        }));
    }
    if g.all_normals {
        let rest = mesh.corner_group_normals(&g.triangles, g.normals.len());
        mesh.corner_normals = Some(Arc::new(CornerNormals {
            table: CornerTable {
                values: g.normals,
                index: g.triangles,
            },
            rest,
        }));
    }
    Ok(mesh)
}

/// `node` and its children, placed by `parent` (node to world).
fn gather_node(
    path: &Path,
    node: &gltf::Node,
    parent: &Matrix4<f64>,
    buffers: &[gltf::buffer::Data],
    g: &mut Gathered,
) -> Result<()> {
    let m = node.transform().matrix();
    // glTF's matrices are column-major: m[column][row].
    let local = Matrix4::from_fn(|r, c| m[c][r] as f64);
    let world = parent * local;
    if let Some(mesh) = node.mesh() {
        gather_mesh(path, &mesh, &world, buffers, g)?;
    }
    for child in node.children() {
        gather_node(path, &child, &world, buffers, g)?;
    }
    Ok(())
}

/// The triangle primitives of `mesh`, placed by `world`.
fn gather_mesh(
    path: &Path,
    mesh: &gltf::Mesh,
    world: &Matrix4<f64>,
    buffers: &[gltf::buffer::Data],
    g: &mut Gathered,
) -> Result<()> {
    let linear: Matrix3<f64> = world.fixed_view::<3, 3>(0, 0).into_owned();
    let normal_matrix = linear.try_inverse().map(|m| m.transpose()).ok_or_else(|| {
        Error::invalid(
            path,
            format!("mesh {}", mesh.index()),
            "placed by a singular node transform (a scale of 0)",
        )
    })?;
    // A mirroring transform turns the triangles' winding over; glTF asks readers to turn it back.
    let mirrored = linear.determinant() < 0.0;
    for prim in mesh.primitives() {
        if prim.mode() != gltf::mesh::Mode::Triangles {
            continue;
        }
        let field = format!("mesh {}, primitive {}", mesh.index(), prim.index());
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let Some(read) = reader.read_positions() else {
            return Err(Error::invalid(path, field, "no POSITION attribute"));
        };
        let base = g.positions.len() as u32;
        let n = read.len();
        g.positions.extend(read.map(|p| {
            let v = world * nalgebra::Vector4::new(p[0] as f64, p[1] as f64, p[2] as f64, 1.0);
            Point3::new(v.x, v.y, v.z)
        }));
        match reader.read_tex_coords(0) {
            Some(t) if g.all_uvs => g
                .uvs
                .extend(t.into_f32().map(|t| [t[0] as f64, 1.0 - t[1] as f64])),
            _ => g.all_uvs = false,
        }
        match reader.read_normals() {
            Some(ns) if g.all_normals => g.normals.extend(ns.map(|v| {
                let w = normal_matrix * Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64);
                let w = w.try_normalize(0.0).unwrap_or(w);
                [w.x, w.y, w.z]
            })),
            _ => g.all_normals = false,
        }
        // Attributes of another count than the positions (a malformed file) are left out.
        g.all_uvs &= g.uvs.len() == g.positions.len();
        g.all_normals &= g.normals.len() == g.positions.len();
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..n as u32).collect(),
        };
        if indices.len() % 3 != 0 {
            return Err(Error::invalid(
                path,
                field,
                format!(
                    "{} indices: a triangle list needs a multiple of 3",
                    indices.len()
                ),
            ));
        }
        if let Some(&i) = indices.iter().find(|&&i| i as usize >= n) {
            return Err(Error::invalid(
                path,
                field,
                format!("index {i} past its {n} vertices"),
            ));
        }
        for (k, t) in indices.chunks_exact(3).enumerate() {
            let t = if mirrored {
                [t[0], t[2], t[1]]
            } else {
                [t[0], t[1], t[2]]
            };
            g.triangles.push(t.map(|v| base + v));
            g.places.push((mesh.index(), prim.index(), k));
        }
    }
    Ok(())
}

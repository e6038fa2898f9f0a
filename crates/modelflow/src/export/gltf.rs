//! Binary glTF 2.0 (`.glb`): the first frame's mesh as one primitive (vertices split where a
//! corner's texture coordinate or normal differs, as glTF needs, in the mesh's vertex order, so
//! that the file read back as a first mesh numbers its vertices as the run; texture coordinates with v
//! flipped to glTF's top-left origin), one morph target per frame holding that frame's
//! displacement from the first (and its normals' change), and one animation whose weights
//! channel switches the targets on in turn, linearly between frames, `(f - first) / fps` seconds
//! apart. Coordinates are the scene's as they are (glTF viewers take +Y as up).

use super::ExportOptions;
use crate::base::mesh::Mesh;
use crate::error::{Error, Result};
use serde_json::{json, Value};
use std::collections::HashMap;

/// The glTF vertices of a mesh: per glTF vertex its mesh vertex, texture coordinate and normal
/// (table entries), and per triangle corner its glTF vertex.
struct Split {
    vertex: Vec<u32>,
    uv: Vec<u32>,
    normal: Vec<u32>,
    corners: Vec<u32>,
}

fn split(m: &Mesh) -> Split {
    const NONE: u32 = u32::MAX;
    let mut seen: HashMap<(u32, u32, u32), u32> = HashMap::new();
    let mut s = Split {
        vertex: Vec::new(),
        uv: Vec::new(),
        normal: Vec::new(),
        corners: Vec::with_capacity(3 * m.triangles.len()),
    };
    for (i, t) in m.triangles.iter().enumerate() {
        for (k, &v) in t.iter().enumerate() {
            let key = (
                v,
                m.corner_uvs.as_ref().map_or(NONE, |c| c.index[i][k]),
                m.corner_normals
                    .as_ref()
                    .map_or(NONE, |c| c.table.index[i][k]),
            );
            let next = s.vertex.len() as u32;
            let id = *seen.entry(key).or_insert_with(|| {
                s.vertex.push(key.0);
                s.uv.push(key.1);
                s.normal.push(key.2);
                next
            });
            s.corners.push(id);
        }
    }
    // The glTF vertices in the mesh's vertex order (each vertex's copies in order of first
    // use), so that a reader welding the copies back (as `input::gltfmesh` does) numbers the
    // vertices as the mesh does.
    let mut order: Vec<u32> = (0..s.vertex.len() as u32).collect();
    order.sort_by_key(|&g| (s.vertex[g as usize], g));
    let mut new_id = vec![0u32; order.len()];
    for (n, &g) in order.iter().enumerate() {
        new_id[g as usize] = n as u32;
    }
    let pick = |v: &[u32]| order.iter().map(|&g| v[g as usize]).collect::<Vec<_>>();
    Split {
        vertex: pick(&s.vertex),
        uv: pick(&s.uv),
        normal: pick(&s.normal),
        corners: s.corners.iter().map(|&c| new_id[c as usize]).collect(),
    }
}

/// Builds the binary chunk and the JSON's buffer views and accessors.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    /// Adds `data` (f32 or u32 values, `width` per element) and returns its accessor index.
    fn add(
        &mut self,
        data: &[u8],
        count: usize,
        kind: &str,
        component: u32,
        minmax: Option<(Vec<f32>, Vec<f32>)>,
        target: Option<u32>,
    ) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let mut view = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": data.len()});
        if let Some(t) = target {
            view["target"] = t.into();
        }
        self.bin.extend_from_slice(data);
        self.views.push(view);
        let mut acc = json!({
            "bufferView": self.views.len() - 1,
            "componentType": component,
            "count": count,
            "type": kind,
        });
        if let Some((lo, hi)) = minmax {
            acc["min"] = lo.into();
            acc["max"] = hi.into();
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }

    fn vec3(&mut self, v: &[[f32; 3]]) -> usize {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in v {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let bytes: Vec<u8> = v.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        self.add(
            &bytes,
            v.len(),
            "VEC3",
            FLOAT,
            Some((lo.to_vec(), hi.to_vec())),
            Some(ARRAY_BUFFER),
        )
    }
}

const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The `.glb` bytes of `frames`.
pub(crate) fn glb(frames: &[(u32, Mesh)], opts: &ExportOptions) -> Result<Vec<u8>> {
    let first = &frames[0].1;
    let s = split(first);
    let mut b = Builder::default();
    let pos = |m: &Mesh| -> Vec<[f32; 3]> {
        s.vertex
            .iter()
            .map(|&v| {
                let p = m.positions[v as usize];
                [p.x as f32, p.y as f32, p.z as f32]
            })
            .collect()
    };
    let nor = |m: &Mesh| -> Option<Vec<[f32; 3]>> {
        let ns = m.current_normals()?;
        Some(
            s.normal
                .iter()
                .map(|&n| ns[n as usize].map(|c| c as f32))
                .collect(),
        )
    };
    let base = pos(first);
    let base_n = nor(first);
    let mut attributes = json!({"POSITION": b.vec3(&base)});
    if let Some(n) = &base_n {
        attributes["NORMAL"] = b.vec3(n).into();
    }
    let uvs: Option<Vec<[f32; 2]>> = match (&first.corner_uvs, &first.uvs) {
        (Some(t), _) => Some(
            s.uv.iter()
                .map(|&u| t.values[u as usize])
                .map(|uv| [uv[0] as f32, 1.0 - uv[1] as f32])
                .collect(),
        ),
        (None, Some(u)) if u.len() == first.positions.len() => Some(
            s.vertex
                .iter()
                .map(|&v| u[v as usize])
                .map(|uv| [uv[0] as f32, 1.0 - uv[1] as f32])
                .collect(),
        ),
        _ => None,
    };
    if let Some(uv) = &uvs {
        let bytes: Vec<u8> = uv.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        attributes["TEXCOORD_0"] = b
            .add(&bytes, uv.len(), "VEC2", FLOAT, None, Some(ARRAY_BUFFER))
            .into();
    }
    let idx: Vec<u8> = s.corners.iter().flat_map(|c| c.to_le_bytes()).collect();
    let indices = b.add(
        &idx,
        s.corners.len(),
        "SCALAR",
        UNSIGNED_INT,
        None,
        Some(ELEMENT_ARRAY_BUFFER),
    );
    let mut targets = Vec::with_capacity(frames.len());
    for (_, m) in frames {
        let d: Vec<[f32; 3]> = pos(m)
            .iter()
            .zip(&base)
            .map(|(p, q)| [p[0] - q[0], p[1] - q[1], p[2] - q[2]])
            .collect();
        let mut t = json!({"POSITION": b.vec3(&d)});
        if let (Some(n), Some(n0)) = (nor(m), &base_n) {
            let d: Vec<[f32; 3]> = n
                .iter()
                .zip(n0)
                .map(|(p, q)| [p[0] - q[0], p[1] - q[1], p[2] - q[2]])
                .collect();
            t["NORMAL"] = b.vec3(&d).into();
        }
        targets.push(t);
    }
    let f0 = frames[0].0;
    let times: Vec<f32> = frames
        .iter()
        .map(|(f, _)| super::seconds(*f, f0, opts.fps) as f32)
        .collect();
    let n = frames.len();
    let tbytes: Vec<u8> = times.iter().flat_map(|t| t.to_le_bytes()).collect();
    let input = b.add(
        &tbytes,
        n,
        "SCALAR",
        FLOAT,
        Some((vec![times[0]], vec![times[n - 1]])),
        None,
    );
    let mut weights = vec![0f32; n * n];
    for k in 0..n {
        weights[k * n + k] = 1.0;
    }
    let wbytes: Vec<u8> = weights.iter().flat_map(|t| t.to_le_bytes()).collect();
    let output = b.add(&wbytes, n * n, "SCALAR", FLOAT, None, None);
    let mut initial = vec![0f32; n];
    initial[0] = 1.0;
    let target_names: Vec<String> = frames.iter().map(|(f, _)| format!("frame {f}")).collect();
    while b.bin.len() % 4 != 0 {
        b.bin.push(0);
    }
    let doc = json!({
        "asset": {"version": "2.0", "generator": format!("modelflow {}", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"name": "modelflow", "nodes": [0]}],
        "nodes": [{"name": "tracked", "mesh": 0}],
        "meshes": [{
            "name": "tracked",
            "primitives": [{"attributes": attributes, "indices": indices, "mode": 4, "targets": targets}],
            "weights": initial,
            "extras": {"targetNames": target_names},
        }],
        "animations": [{
            "name": "tracked",
            "samplers": [{"input": input, "output": output, "interpolation": "LINEAR"}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
        }],
        "buffers": [{"byteLength": b.bin.len()}],
        "bufferViews": b.views,
        "accessors": b.accessors,
    });
    let mut text =
        serde_json::to_vec(&doc).map_err(|e| Error::option("glTF", e, "serialisable JSON"))?;
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + b.bin.len();
    if total > u32::MAX as usize {
        return Err(Error::option(
            "frames",
            frames.len(),
            format!("fewer frames or vertices: the .glb would be {total} bytes, more than glTF's 4 GiB; export USD or a point cache instead"),
        ));
    }
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(&(b.bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b.bin);
    Ok(out)
}

//! Alembic (`.abc`) in its Ogawa container, the animated-geometry file of visual effects
//! pipelines (Maya, Houdini, Nuke, Katana, Blender, Unreal's geometry caches): one `Xform`
//! `tracked` holding one `PolyMesh` `mesh`, its face counts and indices once, its points and
//! bounds sampled at every frame, texture coordinates (when the mesh has them) as the `uv`
//! face-varying parameter, the input's normals (when it had them) as `N`, face-varying, at every
//! frame, the per-vertex confidence (when the run has it) as vertex parameters at the solved
//! frames; and the scene's cameras (when known) as an `Xform` `cameras` holding, per camera, an
//! `Xform` (camera-to-world) over a `Camera` (film back: the USD export's numbers). Written by
//! hand: no maintained Rust crate writes Alembic (the `alembic` crates are placeholders,
//! `ogawa-rs` only reads), and the subset a deforming mesh needs is small.
//!
//! **Ogawa**: a 16-byte header (`Ogawa`, the frozen byte `0xff`, format version 1, the root
//! group's position), then *data* (a `u64` size and the bytes) and *groups* (a `u64` count and
//! that many `u64` child positions, a data child's with its top bit set; position 0 is an empty
//! group, `1 << 63` empty data), each written after its children. **Alembic on Ogawa**: the root
//! group holds the archive's version (`i32` 0), the library version it claims (`i32`), the top
//! object, the archive's metadata, its time samplings and its indexed metadata (none here). An
//! object is a group of its properties (a compound), its child objects, then their headers; a
//! compound is a group of its properties, then their headers; an array property, per sample, the
//! sample's data (a 16-byte key, then the values) and its dimensions (empty: the count follows
//! from the size); a scalar property, the data per sample. Headers pack a property's kind, value
//! type, extent, sample count and time sampling into bit fields (`property_header`).
//!
//! Conventions: Alembic's faces wind clockwise seen from the side their normal points to (Maya's
//! and Blender's exporters reverse each face, their importers reverse it back), so every face's
//! corners are written in reverse. Coordinates are the scene's as they are (Alembic has no up
//! axis in the file; its users take +Y as up, and Blender's importer turns Y-up into its Z-up).
//! Frame `f` is sampled at `f / fps` seconds (a 3D package at the same rate shows it at frame
//! `f`, as the USD export's time codes): uniformly when the frames are evenly spaced, at each
//! frame's own time otherwise.
//! The samples' keys are the first 16 bytes of their data's SHA-256, and each object's two
//! hashes (of its properties, of its children) are made the same way from the digests of what
//! they hold, where Alembic's writer uses SpookyHash: readers only compare them (a sample seen
//! before; two objects alike, which instancing readers draw once), so equal content gets equal
//! hashes and different content different ones.

use super::ExportCamera;
use crate::base::mesh::Mesh;
use crate::tracker::VertexConfidence;
use sha2::{Digest, Sha256};
use std::collections::HashMap;

/// Ogawa's marker of a data child in a group's list of positions.
const DATA: u64 = 1 << 63;
/// The Alembic library version the file says wrote it (1.8.5, the layout written here).
const LIBRARY_VERSION: i32 = 10805;
/// Alembic's plain data types (`Alembic::Util::PlainOldDataType`) used here.
const POD_BOOL: u32 = 0;
const POD_UINT8: u32 = 1;
const POD_INT32: u32 = 6;
const POD_FLOAT32: u32 = 10;
const POD_FLOAT64: u32 = 11;
/// An `Xform` object's metadata, as its parent lists it.
const XFORM: &str = "schema=AbcGeom_Xform_v3;schemaObjTitle=AbcGeom_Xform_v3:.xform";
/// Alembic's time per cycle that marks an acyclic sampling (each sample at its own time).
const ACYCLIC: f64 = f64::MAX / 32.0;

/// The Ogawa container being written, in memory (the export writes it atomically), with a
/// digest of every data and group written: of a data's bytes, of a group's children's digests
/// (so equal content has equal digests wherever it lies; the objects' hashes are made of them).
struct Ogawa {
    bytes: Vec<u8>,
    digests: HashMap<u64, [u8; 16]>,
}

impl Ogawa {
    fn new() -> Self {
        let mut bytes = Vec::new();
        bytes.extend_from_slice(b"Ogawa");
        // Frozen (the archive is complete when the file is), format version 1, and the root
        // group's position, filled in by `finish`.
        bytes.extend_from_slice(&[0xff, 0, 1]);
        bytes.extend_from_slice(&[0; 8]);
        Ogawa {
            bytes,
            digests: HashMap::new(),
        }
    }

    /// The digest of what was written at `child` (zeros for the empty group and data).
    fn digest(&self, child: u64) -> [u8; 16] {
        self.digests.get(&child).copied().unwrap_or_default()
    }

    /// Writes one data child made of `parts` one after another; its position for a group.
    fn data(&mut self, parts: &[&[u8]]) -> u64 {
        let size: usize = parts.iter().map(|p| p.len()).sum();
        if size == 0 {
            return DATA;
        }
        let pos = self.bytes.len() as u64;
        self.bytes.extend_from_slice(&(size as u64).to_le_bytes());
        let mut hash = Sha256::new();
        for p in parts {
            self.bytes.extend_from_slice(p);
            hash.update(p);
        }
        self.digests.insert(pos | DATA, first16(&hash.finalize()));
        pos | DATA
    }

    /// Writes a group of `children` (positions from `data` and `group`); its position.
    fn group(&mut self, children: &[u64]) -> u64 {
        if children.is_empty() {
            return 0;
        }
        let pos = self.bytes.len() as u64;
        self.bytes
            .extend_from_slice(&(children.len() as u64).to_le_bytes());
        let mut hash = Sha256::new();
        for c in children {
            self.bytes.extend_from_slice(&c.to_le_bytes());
            hash.update(self.digest(*c));
        }
        self.digests.insert(pos, first16(&hash.finalize()));
        pos
    }

    /// The file, with `root` as its root group.
    fn finish(mut self, root: u64) -> Vec<u8> {
        self.bytes[8..16].copy_from_slice(&root.to_le_bytes());
        self.bytes
    }
}

/// A property as its parent compound lists it: the header fields of `property_header`.
struct Header {
    name: &'static str,
    metadata: &'static str,
    kind: Kind,
}

enum Kind {
    Compound,
    /// An array or scalar property of `pod` values `extent` at a time, `samples` samples on time
    /// sampling `sampling`, every one written (one sample: the same at every time, which the
    /// header marks constant); `homogenous`: every sample holds as many values.
    Values {
        array: bool,
        pod: u32,
        extent: u32,
        samples: u32,
        sampling: u32,
        homogenous: bool,
    },
}

/// The bytes a compound's header list holds for `h` (Alembic's property header: its fields
/// packed into a `u32`, then the sample count, time sampling, name and metadata in 1, 2 or 4
/// bytes each as the largest of them needs).
fn property_header(out: &mut Vec<u8>, h: &Header) {
    let (samples, sampling) = match h.kind {
        Kind::Values {
            samples, sampling, ..
        } => (samples, sampling),
        Kind::Compound => (0, 0),
    };
    let largest = [
        h.name.len() as u32,
        h.metadata.len() as u32,
        samples,
        sampling,
    ]
    .into_iter()
    .max()
    .unwrap_or(0);
    let hint: u32 = if largest < 256 {
        0
    } else if largest < 65536 {
        1
    } else {
        2
    };
    let put = |out: &mut Vec<u8>, v: u32| match hint {
        0 => out.push(v as u8),
        1 => out.extend_from_slice(&(v as u16).to_le_bytes()),
        _ => out.extend_from_slice(&v.to_le_bytes()),
    };
    // Metadata index 0 is the empty metadata, 0xff metadata written inline.
    let inline = !h.metadata.is_empty();
    let mut info: u32 = (hint << 2) | if inline { 0xff << 20 } else { 0 };
    match h.kind {
        Kind::Compound => out.extend_from_slice(&info.to_le_bytes()),
        Kind::Values {
            array,
            pod,
            extent,
            samples,
            sampling,
            homogenous,
        } => {
            info |= if array { 2 } else { 1 };
            info |= pod << 4;
            info |= extent << 12;
            if sampling != 0 {
                info |= 0x100;
            }
            if homogenous {
                info |= 0x400;
            }
            // Every sample differs from the one before (first changed at 1, last at n − 1,
            // which the header leaves implicit), or there is one: the same at every time.
            if samples <= 1 {
                info |= 0x800;
            }
            out.extend_from_slice(&info.to_le_bytes());
            put(out, samples);
            if sampling != 0 {
                put(out, sampling);
            }
        }
    }
    put(out, h.name.len() as u32);
    out.extend_from_slice(h.name.as_bytes());
    if inline {
        put(out, h.metadata.len() as u32);
        out.extend_from_slice(h.metadata.as_bytes());
    }
}

/// A sample's data child: its key (the first 16 bytes of the values' SHA-256), then the values.
fn sample(o: &mut Ogawa, values: &[u8]) -> u64 {
    let key = Sha256::digest(values);
    o.data(&[&key[..16], values])
}

/// An array property's group: each sample's data, then its (empty: rank 1) dimensions.
fn array_property<'a>(o: &mut Ogawa, samples: impl IntoIterator<Item = &'a [u8]>) -> u64 {
    let mut children = Vec::new();
    for s in samples {
        children.push(sample(o, s));
        children.push(DATA);
    }
    o.group(&children)
}

/// A scalar property's group: each sample's data.
fn scalar_property<'a>(o: &mut Ogawa, samples: impl IntoIterator<Item = &'a [u8]>) -> u64 {
    let children: Vec<u64> = samples.into_iter().map(|s| sample(o, s)).collect();
    o.group(&children)
}

/// An object's properties: one compound `name` (its schema's, `.geom` or `.xform`) with
/// `metadata` naming the schema, holding the compound `inner`.
fn schema_compound(o: &mut Ogawa, name: &'static str, metadata: &'static str, inner: u64) -> u64 {
    compound(
        o,
        &[(
            inner,
            Header {
                name,
                metadata,
                kind: Kind::Compound,
            },
        )],
    )
}

/// A compound property's group: its properties' groups, then their headers.
fn compound(o: &mut Ogawa, props: &[(u64, Header)]) -> u64 {
    let mut headers = Vec::new();
    for (_, h) in props {
        property_header(&mut headers, h);
    }
    let mut children: Vec<u64> = props.iter().map(|(g, _)| *g).collect();
    children.push(o.data(&[&headers]));
    o.group(&children)
}

/// An object's group: its properties, its children (name, metadata, group), then their headers
/// and the (zero) hashes of its properties and children.
fn object(o: &mut Ogawa, props: u64, children: &[(&str, &str, u64)]) -> u64 {
    let mut headers = Vec::new();
    for (name, metadata, _) in children {
        headers.extend_from_slice(&(name.len() as u32).to_le_bytes());
        headers.extend_from_slice(name.as_bytes());
        headers.push(0xff);
        headers.extend_from_slice(&(metadata.len() as u32).to_le_bytes());
        headers.extend_from_slice(metadata.as_bytes());
    }
    // The hash of the object's properties, then of its children (zeros when it has none), as
    // Alembic's writer places them; readers only compare them (whether two objects are alike).
    headers.extend_from_slice(&o.digest(props));
    if children.is_empty() {
        headers.extend_from_slice(&[0; 16]);
    } else {
        let mut hash = Sha256::new();
        for c in children {
            hash.update(o.digest(c.2));
        }
        headers.extend_from_slice(&first16(&hash.finalize()));
    }
    let mut list = vec![props];
    list.extend(children.iter().map(|c| c.2));
    list.push(o.data(&[&headers]));
    o.group(&list)
}

/// Appends the time sampling of `frames` (ascending), frame `f` at `f / fps` seconds, as the
/// archive's list holds it: its most samples, time per cycle, then its stored times (uniform when
/// the frames are evenly spaced: one; acyclic otherwise: each frame's).
fn time_sampling(out: &mut Vec<u8>, frames: &[u32], fps: f64) {
    let n = frames.len() as u32;
    let step = frames.get(1).map_or(1, |f| f - frames[0]);
    out.extend_from_slice(&n.to_le_bytes());
    if frames.windows(2).all(|w| w[1] - w[0] == step) {
        out.extend_from_slice(&(step as f64 / fps).to_le_bytes());
        out.extend_from_slice(&1u32.to_le_bytes());
        out.extend_from_slice(&(frames[0] as f64 / fps).to_le_bytes());
    } else {
        out.extend_from_slice(&ACYCLIC.to_le_bytes());
        out.extend_from_slice(&n.to_le_bytes());
        for f in frames {
            out.extend_from_slice(&(*f as f64 / fps).to_le_bytes());
        }
    }
}

fn first16(digest: &[u8]) -> [u8; 16] {
    let mut out = [0; 16];
    out.copy_from_slice(&digest[..16]);
    out
}

fn f32_bytes(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}

fn i32_bytes(values: impl IntoIterator<Item = i32>) -> Vec<u8> {
    values.into_iter().flat_map(i32::to_le_bytes).collect()
}

/// The Alembic file of `frames` (frame number and mesh, ascending, one topology), frame `f` at
/// `f / fps` seconds, with the per-vertex `confidence` of the frames that have it (may be
/// empty) as parameters of the mesh and `cameras` (when there are any) under `/cameras`.
pub(crate) fn abc(
    frames: &[(u32, Mesh)],
    confidence: &[(u32, Vec<VertexConfidence>)],
    cameras: &[ExportCamera],
    fps: f64,
) -> Vec<u8> {
    let first = &frames[0].1;
    let n = frames.len() as u32;
    // The input's polygons where it had them, else the triangles; each face's corners reversed
    // (Alembic winds clockwise).
    let (counts, corners) = first.face_corners();
    let mut reversed = Vec::with_capacity(corners.len());
    let mut at = 0usize;
    for &c in &counts {
        let face = &corners[at..at + c as usize];
        reversed.extend(face.iter().rev().copied());
        at += c as usize;
    }
    let vertex = |&(t, k): &(u32, u8)| first.triangles[t as usize][k as usize];

    let mut o = Ogawa::new();
    // The mesh's properties, in the `.geom` compound.
    let points: Vec<Vec<u8>> = frames
        .iter()
        .map(|(_, m)| {
            f32_bytes(
                m.positions
                    .iter()
                    .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32]),
            )
        })
        .collect();
    let p = array_property(&mut o, points.iter().map(Vec::as_slice));
    let indices = i32_bytes(reversed.iter().map(|c| vertex(c) as i32));
    let face_indices = array_property(&mut o, [indices.as_slice()]);
    let face_counts_bytes = i32_bytes(counts.iter().map(|&c| c as i32));
    let face_counts = array_property(&mut o, [face_counts_bytes.as_slice()]);
    let bounds: Vec<Vec<u8>> = frames
        .iter()
        .map(|(_, m)| {
            let (lo, hi) = super::usd::bounds(m);
            lo.iter()
                .chain(&hi)
                .flat_map(|&v| (v as f64).to_le_bytes())
                .collect()
        })
        .collect();
    let self_bounds = scalar_property(&mut o, bounds.iter().map(Vec::as_slice));
    let values = |array, pod, extent, samples, homogenous| Kind::Values {
        array,
        pod,
        extent,
        samples,
        sampling: 1,
        homogenous,
    };
    let mut geom = vec![
        (
            self_bounds,
            Header {
                name: ".selfBnds",
                metadata: "interpretation=box",
                kind: values(false, POD_FLOAT64, 6, n, true),
            },
        ),
        (
            p,
            Header {
                name: "P",
                metadata: "geoScope=vtx;interpretation=point",
                kind: values(true, POD_FLOAT32, 3, n, true),
            },
        ),
        (
            face_indices,
            Header {
                name: ".faceIndices",
                metadata: "",
                kind: values(true, POD_INT32, 1, 1, true),
            },
        ),
        (
            face_counts,
            Header {
                name: ".faceCounts",
                metadata: "",
                kind: values(true, POD_INT32, 1, 1, true),
            },
        ),
    ];
    // Texture coordinates, one per face corner (in the reversed order).
    let uv: Option<Vec<f32>> = if let Some(t) = &first.corner_uvs {
        Some(
            reversed
                .iter()
                .flat_map(|&(tri, k)| {
                    let uv = t.values[t.index[tri as usize][k as usize] as usize];
                    [uv[0] as f32, uv[1] as f32]
                })
                .collect(),
        )
    } else {
        first
            .uvs
            .as_ref()
            .filter(|u| u.len() == first.positions.len())
            .map(|uvs| {
                reversed
                    .iter()
                    .flat_map(|c| {
                        let uv = uvs[vertex(c) as usize];
                        [uv[0] as f32, uv[1] as f32]
                    })
                    .collect()
            })
    };
    if let Some(uv) = uv {
        let bytes = f32_bytes(uv);
        let g = array_property(&mut o, [bytes.as_slice()]);
        geom.push((
            g,
            Header {
                name: "uv",
                metadata: "geoScope=fvr;interpretation=vector;isGeomParam=true;podExtent=2;\
                           podName=float32_t",
                kind: values(true, POD_FLOAT32, 2, 1, true),
            },
        ));
    }
    // The input's normals (an artist's hard edges and custom normals), per face corner, turned
    // with the surface at every frame (`Mesh::current_normals`).
    if let Some(cn) = &first.corner_normals {
        let per_frame: Vec<Vec<u8>> = frames
            .iter()
            .map(|(_, m)| {
                let ns = m.current_normals().unwrap_or_default();
                f32_bytes(reversed.iter().flat_map(|&(tri, k)| {
                    let n = ns
                        .get(cn.table.index[tri as usize][k as usize] as usize)
                        .copied()
                        .unwrap_or_default();
                    [n[0] as f32, n[1] as f32, n[2] as f32]
                }))
            })
            .collect();
        let g = array_property(&mut o, per_frame.iter().map(Vec::as_slice));
        geom.push((
            g,
            Header {
                name: "N",
                metadata: "geoScope=fvr;interpretation=normal;isGeomParam=true;podExtent=3;\
                           podName=float32_t",
                kind: values(true, POD_FLOAT32, 3, n, true),
            },
        ));
    }
    // The confidence, per vertex at the frames that have it (the solved ones: sampling 1 when
    // they are the mesh's frames, else sampling 2, theirs), in `.arbGeomParams`, where readers
    // find a mesh's other attributes (Houdini's point attributes, Blender's attributes).
    let conf_frames: Vec<u32> = confidence.iter().map(|(f, _)| *f).collect();
    let mesh_frames: Vec<u32> = frames.iter().map(|(f, _)| *f).collect();
    let conf_sampling = if conf_frames == mesh_frames { 1 } else { 2 };
    if !confidence.is_empty() {
        let fields: [(&'static str, super::usd::ConfidenceField); 3] = [
            ("information", |c| c.information),
            ("residual", |c| c.residual),
            ("sigma", |c| c.sigma()),
        ];
        let mut params = Vec::new();
        for (name, value) in fields {
            let per_frame: Vec<Vec<u8>> = confidence
                .iter()
                .map(|(_, c)| f32_bytes(c.iter().map(|v| value(v) as f32)))
                .collect();
            let g = array_property(&mut o, per_frame.iter().map(Vec::as_slice));
            params.push((
                g,
                Header {
                    name,
                    metadata: "geoScope=vtx;isGeomParam=true;podExtent=1;podName=float32_t",
                    kind: Kind::Values {
                        array: true,
                        pod: POD_FLOAT32,
                        extent: 1,
                        samples: confidence.len() as u32,
                        sampling: conf_sampling,
                        homogenous: true,
                    },
                },
            ));
        }
        let g = compound(&mut o, &params);
        geom.push((
            g,
            Header {
                name: ".arbGeomParams",
                metadata: "",
                kind: Kind::Compound,
            },
        ));
    }
    let geom = compound(&mut o, &geom);
    let mesh_props = schema_compound(
        &mut o,
        ".geom",
        "schema=AbcGeom_PolyMesh_v1;schemaBaseType=AbcGeom_GeomBase_v1",
        geom,
    );
    let mesh = object(&mut o, mesh_props, &[]);
    // The transform above it: the identity, constant (its `.xform` compound holds no samples).
    let xform = compound(&mut o, &[]);
    let xform_props = schema_compound(&mut o, ".xform", "schema=AbcGeom_Xform_v3", xform);
    let tracked = object(
        &mut o,
        xform_props,
        &[(
            "mesh",
            "schema=AbcGeom_PolyMesh_v1;schemaBaseType=AbcGeom_GeomBase_v1;\
             schemaObjTitle=AbcGeom_PolyMesh_v1:.geom",
            mesh,
        )],
    );
    let mut top_children = vec![("tracked", XFORM, tracked)];
    if !cameras.is_empty() {
        let group = camera_objects(&mut o, frames, cameras);
        top_children.push(("cameras", XFORM, group));
    }
    let top_props = compound(&mut o, &[]);
    let top = object(&mut o, top_props, &top_children);

    // The archive: versions, top object, metadata, time samplings, indexed metadata (none).
    let version = o.data(&[&0i32.to_le_bytes()]);
    let library = o.data(&[&LIBRARY_VERSION.to_le_bytes()]);
    let metadata = format!(
        "_ai_AlembicVersion=Alembic 1.8.5 (written by modelflow {});_ai_Application=modelflow {};\
         _ai_Description=a tracked mesh, {} frames at {} per second",
        env!("CARGO_PKG_VERSION"),
        env!("CARGO_PKG_VERSION"),
        n,
        fps
    );
    let metadata = o.data(&[metadata.as_bytes()]);
    let mut samplings = Vec::new();
    // Sampling 0, the identity every archive has (one sample a second from 0; unused here).
    samplings.extend_from_slice(&0u32.to_le_bytes());
    samplings.extend_from_slice(&1.0f64.to_le_bytes());
    samplings.extend_from_slice(&1u32.to_le_bytes());
    samplings.extend_from_slice(&0.0f64.to_le_bytes());
    // Sampling 1, the frames'; sampling 2, the confidence's where its frames are others.
    time_sampling(&mut samplings, &mesh_frames, fps);
    if conf_sampling == 2 && !conf_frames.is_empty() {
        time_sampling(&mut samplings, &conf_frames, fps);
    }
    let samplings = o.data(&[&samplings]);
    let indexed = o.data(&[]);
    let root = o.group(&[version, library, top, metadata, samplings, indexed]);
    o.finish(root)
}

/// The `cameras` object: an identity `Xform` holding, for each camera, an `Xform` named as the USD
/// export names it (its camera-to-world matrix, one matrix operation) and under it a `Camera`
/// `<name>Shape` (its film back). Both are sampled at every frame for a camera that moves (its
/// view at each frame: the last at or before it), once for one that does not.
fn camera_objects(o: &mut Ogawa, frames: &[(u32, Mesh)], cameras: &[ExportCamera]) -> u64 {
    let first = &frames[0].1;
    let mut names: Vec<String> = Vec::new();
    let mut built = Vec::new();
    for cam in cameras {
        let name = super::usd::usd_name(&cam.name, &names);
        names.push(name.clone());
        let views: Vec<&crate::base::Projection> = if cam.views.len() <= 1 {
            cam.views.iter().map(|(_, p)| p).collect()
        } else {
            frames
                .iter()
                .map(|(f, _)| {
                    let at = cam.views.partition_point(|(g, _)| g <= f).max(1) - 1;
                    &cam.views[at].1
                })
                .collect()
        };
        let values: Vec<super::usd::CameraValues> = views
            .iter()
            .map(|p| super::usd::CameraValues::of(p, cam.width, cam.height, first))
            .collect();
        let n = values.len() as u32;
        // The film back (`Alembic::AbcGeom::CameraSample`'s 16 core values): focal length in
        // mm, apertures and their offsets in cm, no squeeze or overscan, Alembic's defaults for
        // the f-stop (5.6), focus distance (5) and shutter (open 0, close 1/48 s), the clipping
        // range.
        let core: Vec<Vec<u8>> = values
            .iter()
            .map(|v| {
                [
                    v.focal,
                    v.aperture[0] / 10.0,
                    v.offset[0] / 10.0,
                    v.aperture[1] / 10.0,
                    v.offset[1] / 10.0,
                    1.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    5.6,
                    5.0,
                    0.0,
                    1.0 / 48.0,
                    v.clipping[0],
                    v.clipping[1],
                ]
                .iter()
                .flat_map(|x| x.to_le_bytes())
                .collect()
            })
            .collect();
        let core = scalar_property(o, core.iter().map(Vec::as_slice));
        let geom = compound(
            o,
            &[(
                core,
                Header {
                    name: ".core",
                    metadata: "",
                    kind: Kind::Values {
                        array: false,
                        pod: POD_FLOAT64,
                        extent: 16,
                        samples: n,
                        sampling: 1,
                        homogenous: true,
                    },
                },
            )],
        );
        let shape_props = schema_compound(o, ".geom", "schema=AbcGeom_Camera_v1", geom);
        let shape = object(o, shape_props, &[]);
        // The transform: `.inherits` (whose samples give the schema its sample count), one
        // matrix operation (`.ops`: type 3 in the high nibble), its 16 channels (`.vals`, the
        // matrix row by row), and `isNotConstantIdentity`, whose presence says what it says.
        let inherits: Vec<&[u8]> = vec![&[1u8][..]; n as usize];
        let inherits = scalar_property(o, inherits);
        let ops = scalar_property(o, [&[0x30u8][..]]);
        let vals: Vec<Vec<u8>> = values
            .iter()
            .map(|v| {
                v.transform
                    .iter()
                    .flatten()
                    .flat_map(|x| x.to_le_bytes())
                    .collect()
            })
            .collect();
        let vals = scalar_property(o, vals.iter().map(Vec::as_slice));
        let not_identity = scalar_property(o, [&[1u8][..]]);
        let scalar = |pod, extent, samples, sampling| Kind::Values {
            array: false,
            pod,
            extent,
            samples,
            sampling,
            homogenous: true,
        };
        let xform = compound(
            o,
            &[
                (
                    inherits,
                    Header {
                        name: ".inherits",
                        metadata: "",
                        kind: scalar(POD_BOOL, 1, n, 1),
                    },
                ),
                (
                    ops,
                    Header {
                        name: ".ops",
                        metadata: "",
                        kind: scalar(POD_UINT8, 1, 1, 1),
                    },
                ),
                (
                    vals,
                    Header {
                        name: ".vals",
                        metadata: "",
                        kind: scalar(POD_FLOAT64, 16, n, 1),
                    },
                ),
                (
                    not_identity,
                    Header {
                        name: "isNotConstantIdentity",
                        metadata: "",
                        kind: scalar(POD_BOOL, 1, 1, 0),
                    },
                ),
            ],
        );
        let xform_props = schema_compound(o, ".xform", "schema=AbcGeom_Xform_v3", xform);
        built.push((name, xform_props, shape));
    }
    let mut objects = Vec::new();
    for (name, xform_props, shape) in &built {
        let shape_name = format!("{name}Shape");
        let g = object(
            o,
            *xform_props,
            &[(
                shape_name.as_str(),
                "schema=AbcGeom_Camera_v1;schemaObjTitle=AbcGeom_Camera_v1:.geom",
                *shape,
            )],
        );
        objects.push((name.as_str(), XFORM, g));
    }
    let identity = compound(o, &[]);
    let props = schema_compound(o, ".xform", "schema=AbcGeom_Xform_v3", identity);
    object(o, props, &objects)
}

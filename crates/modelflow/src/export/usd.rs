//! USD text (`.usda`): a stage whose default prim `tracked` holds one `Mesh` prim `mesh` with the
//! topology once (`faceVertexCounts`, `faceVertexIndices`, right-handed), `points` and `extent`
//! as time samples at the frame numbers, texture coordinates as the `st` primvar (face-varying
//! with indices, or per vertex) and normals as the `normals` primvar (face-varying, time
//! samples). The stage's time codes are the frame numbers at `fps` per second. A tracked run's
//! per-vertex confidence becomes the `information`, `residual` and `sigma` primvars (per vertex,
//! time samples at the solved frames; `sigma` is `inf` where nothing constrains the vertex).

use super::{ExportCamera, ExportOptions};
use crate::base::mesh::Mesh;
use crate::base::Projection;
use crate::tracker::VertexConfidence;
use std::fmt::Write;

/// The `.usda` text of `frames`.
pub(crate) fn usda(
    frames: &[(u32, Mesh)],
    confidence: &[(u32, Vec<VertexConfidence>)],
    cameras: &[ExportCamera],
    opts: &ExportOptions,
) -> String {
    let (f0, first) = (&frames[0].0, &frames[0].1);
    // The input's polygons where it had them (a quad stays a quad), else the triangles; every
    // face-varying table below follows the same corners.
    let (counts, corners) = first.face_corners();
    let last = frames[frames.len() - 1].0;
    let mut o = String::new();
    let _ = writeln!(o, "#usda 1.0\n(");
    let _ = writeln!(
        o,
        "    doc = \"modelflow {}: {} frames of a tracked mesh ({} vertices, {} faces)\"",
        env!("CARGO_PKG_VERSION"),
        frames.len(),
        first.positions.len(),
        counts.len()
    );
    let _ = writeln!(o, "    defaultPrim = \"tracked\"");
    let _ = writeln!(o, "    startTimeCode = {f0}\n    endTimeCode = {last}");
    let _ = writeln!(
        o,
        "    timeCodesPerSecond = {}\n    framesPerSecond = {}",
        opts.fps, opts.fps
    );
    if let Some(u) = opts.units {
        let _ = writeln!(o, "    metersPerUnit = {}", u.millimetres() / 1000.0);
    }
    let _ = writeln!(
        o,
        ")\n\ndef Xform \"tracked\"\n{{\n    def Mesh \"mesh\"\n    {{"
    );
    let _ = writeln!(o, "        uniform token subdivisionScheme = \"none\"");
    let _ = writeln!(o, "        uniform token orientation = \"rightHanded\"");
    let at = |index: &[[u32; 3]]| -> Vec<u32> {
        corners
            .iter()
            .map(|&(t, k)| index[t as usize][k as usize])
            .collect()
    };
    let _ = write!(o, "        int[] faceVertexCounts = [");
    list(&mut o, counts.iter(), |o, n| {
        let _ = write!(o, "{n}");
    });
    let _ = write!(o, "]\n        int[] faceVertexIndices = [");
    list(&mut o, at(&first.triangles).iter(), |o, v| {
        let _ = write!(o, "{v}");
    });
    o.push_str("]\n");

    samples(&mut o, "point3f[] points", frames, |o, m| {
        list(o, m.positions.iter(), |o, p| {
            let _ = write!(o, "({:?}, {:?}, {:?})", p.x as f32, p.y as f32, p.z as f32);
        });
    });
    samples(&mut o, "float3[] extent", frames, |o, m| {
        let (lo, hi) = bounds(m);
        let _ = write!(
            o,
            "({:?}, {:?}, {:?}), ({:?}, {:?}, {:?})",
            lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
        );
    });

    if let Some(t) = &first.corner_uvs {
        primvar(&mut o, "texCoord2f[] primvars:st", "faceVarying", |o| {
            list(o, t.values.iter(), |o, uv| {
                let _ = write!(o, "({:?}, {:?})", uv[0] as f32, uv[1] as f32);
            });
        });
        indices(&mut o, "primvars:st:indices", &at(&t.index));
    } else if let Some(uvs) = first
        .uvs
        .as_ref()
        .filter(|u| u.len() == first.positions.len())
    {
        primvar(&mut o, "texCoord2f[] primvars:st", "vertex", |o| {
            list(o, uvs.iter(), |o, uv| {
                let _ = write!(o, "({:?}, {:?})", uv[0] as f32, uv[1] as f32);
            });
        });
    }
    if let Some(n) = &first.corner_normals {
        let _ = writeln!(
            o,
            "        normal3f[] primvars:normals (\n            interpolation = \"faceVarying\"\n        )"
        );
        samples(&mut o, "normal3f[] primvars:normals", frames, |o, m| {
            let ns = m.current_normals().unwrap_or_default();
            list(o, ns.iter(), |o, n| {
                let _ = write!(
                    o,
                    "({:?}, {:?}, {:?})",
                    n[0] as f32, n[1] as f32, n[2] as f32
                );
            });
        });
        indices(&mut o, "primvars:normals:indices", &at(&n.table.index));
    }
    if !confidence.is_empty() {
        let fields: [(&str, ConfidenceField); 3] = [
            ("information", |c| c.information),
            ("residual", |c| c.residual),
            ("sigma", |c| c.sigma()),
        ];
        for (name, value) in fields {
            let _ = writeln!(
                o,
                "        float[] primvars:{name} (\n            interpolation = \"vertex\"\n        )"
            );
            let _ = writeln!(o, "        float[] primvars:{name}.timeSamples = {{");
            for (f, c) in confidence {
                let _ = write!(o, "            {f}: [");
                list(&mut o, c.iter(), |o, c| {
                    let _ = write!(o, "{:?}", value(c) as f32);
                });
                o.push_str("],\n");
            }
            o.push_str("        }\n");
        }
    }
    o.push_str("    }\n");
    if !cameras.is_empty() {
        cameras_usda(&mut o, cameras, first);
    }
    o.push_str("}\n");
    o
}

/// The horizontal aperture every camera is written with: only the ratios of focal length and
/// apertures to it matter for the projection, and at 36 (a full-frame sensor's width in mm)
/// the focal length reads as a 35 mm-equivalent one.
const APERTURE: f64 = 36.0;

/// The cameras as `UsdGeomCamera` prims under `/tracked/cameras`: USD's camera looks down its
/// −Z with +Y up, ours (OpenCV's) down +Z with +Y down, so its transform is
/// camera-to-world with the Y and Z axes turned over; `K` becomes focal length, apertures and
/// aperture offsets in the same units (`APERTURE` across the width), such that the image's
/// edges (pixel −0.5 and width − 0.5, pixel centres at integer coordinates) are the aperture's
/// edges. Non-square pixels make the vertical aperture `height·fx/fy` of the same scale. Skew
/// and lens distortion have no USD equivalent (the frames the tracker compares are pinhole ones).
/// The clipping range brackets the first frame's mesh (a tenth of its nearest depth to ten times
/// its farthest).
fn cameras_usda(o: &mut String, cameras: &[ExportCamera], first: &Mesh) {
    let _ = writeln!(o, "\n    def Scope \"cameras\"\n    {{");
    let mut names: Vec<String> = Vec::new();
    for cam in cameras {
        let name = usd_name(&cam.name, &names);
        names.push(name.clone());
        let _ = writeln!(o, "        def Camera \"{name}\"\n        {{");
        let _ = writeln!(o, "            token projection = \"perspective\"");
        let _ = writeln!(
            o,
            "            custom int2 modelflow:imageSize = ({}, {})",
            cam.width, cam.height
        );
        let _ = writeln!(
            o,
            "            custom string modelflow:name = \"{}\"",
            cam.name.replace('\\', "\\\\").replace('"', "\\\"")
        );
        let views: Vec<(u32, CameraValues)> = cam
            .views
            .iter()
            .map(|(f, p)| (*f, CameraValues::of(p, cam.width, cam.height, first)))
            .collect();
        let fields: [CameraField; 7] = [
            ("float", "focalLength", |v| format!("{:?}", v.focal as f32)),
            ("float", "horizontalAperture", |v| {
                format!("{:?}", v.aperture[0] as f32)
            }),
            ("float", "verticalAperture", |v| {
                format!("{:?}", v.aperture[1] as f32)
            }),
            ("float", "horizontalApertureOffset", |v| {
                format!("{:?}", v.offset[0] as f32)
            }),
            ("float", "verticalApertureOffset", |v| {
                format!("{:?}", v.offset[1] as f32)
            }),
            ("float2", "clippingRange", |v| {
                format!("({:?}, {:?})", v.clipping[0] as f32, v.clipping[1] as f32)
            }),
            ("matrix4d", "xformOp:transform", |v| {
                let rows: Vec<String> = v
                    .transform
                    .iter()
                    .map(|r| format!("({:?}, {:?}, {:?}, {:?})", r[0], r[1], r[2], r[3]))
                    .collect();
                format!("( {} )", rows.join(", "))
            }),
        ];
        for (ty, attr, value) in fields {
            match views.as_slice() {
                [(_, v)] => {
                    let _ = writeln!(o, "            {ty} {attr} = {}", value(v));
                }
                _ => {
                    let _ = writeln!(o, "            {ty} {attr}.timeSamples = {{");
                    for (f, v) in &views {
                        let _ = writeln!(o, "                {f}: {},", value(v));
                    }
                    let _ = writeln!(o, "            }}");
                }
            }
        }
        let _ = writeln!(
            o,
            "            uniform token[] xformOpOrder = [\"xformOp:transform\"]\n        }}"
        );
    }
    let _ = writeln!(o, "    }}");
}

/// A camera attribute: its USD type, name, and value at one frame.
type CameraField = (&'static str, &'static str, fn(&CameraValues) -> String);

/// A camera's USD numbers at one frame (also the Alembic export's: the same film back in
/// centimetres, the same matrix).
pub(super) struct CameraValues {
    /// Focal length, horizontal and vertical aperture, and their offsets, in mm (`APERTURE`
    /// across the image's width).
    pub(super) focal: f64,
    pub(super) aperture: [f64; 2],
    pub(super) offset: [f64; 2],
    /// Near and far clipping distances, in the scene's units.
    pub(super) clipping: [f64; 2],
    /// Camera-to-world, USD's (and Alembic's) row-vector convention (translation in the last
    /// row), the camera looking down its −Z with +Y up.
    pub(super) transform: [[f64; 4]; 4],
}

impl CameraValues {
    pub(super) fn of(p: &Projection, width: u32, height: u32, first: &Mesh) -> Self {
        let (k, r, _) = p.krt();
        let (w, h) = (width as f64, height as f64);
        let (fx, fy, cx, cy) = (k[(0, 0)], k[(1, 1)], k[(0, 2)], k[(1, 2)]);
        let s = APERTURE / w;
        // Pixel u at ndc (2u + 1 − w)/w across the aperture; u = fx·x/z + cx (docs/export.md).
        let focal = fx * s;
        let aperture = [w * s, h * s * fx / fy];
        let offset = [
            s * ((w - 1.0) / 2.0 - cx),
            s * fx / fy * (cy - (h - 1.0) / 2.0),
        ];
        // Rows 0–2: the camera's X, −Y, −Z axes in world coordinates (R's rows, the last two
        // turned over); row 3: its centre.
        let c = p.center();
        let mut transform = [[0.0; 4]; 4];
        for (i, sign) in [1.0, -1.0, -1.0].into_iter().enumerate() {
            for j in 0..3 {
                transform[i][j] = sign * r[(i, j)];
            }
        }
        transform[3] = [c.x, c.y, c.z, 1.0];
        // Depths of the mesh's bounding box corners.
        let (lo, hi) = (
            first.positions.iter().fold([f64::INFINITY; 3], |a, q| {
                [a[0].min(q.x), a[1].min(q.y), a[2].min(q.z)]
            }),
            first.positions.iter().fold([f64::NEG_INFINITY; 3], |a, q| {
                [a[0].max(q.x), a[1].max(q.y), a[2].max(q.z)]
            }),
        );
        let depths: Vec<f64> = (0..8)
            .map(|b| {
                let q = nalgebra::Point3::new(
                    if b & 1 == 0 { lo[0] } else { hi[0] },
                    if b & 2 == 0 { lo[1] } else { hi[1] },
                    if b & 4 == 0 { lo[2] } else { hi[2] },
                );
                p.depth(&q)
            })
            .collect();
        let far = depths.iter().fold(0.0f64, |a, &d| a.max(d));
        let near = depths
            .iter()
            .filter(|&&d| d > 0.0)
            .fold(f64::INFINITY, |a, &d| a.min(d));
        let clipping = if far > 0.0 && near.is_finite() {
            [0.1 * near, 10.0 * far]
        } else {
            [1e-3, 1e6]
        };
        CameraValues {
            focal,
            aperture,
            offset,
            clipping,
            transform,
        }
    }
}

/// A valid USD prim name for `name` (letters, digits and `_`, not starting with a digit), not
/// among `taken` (the Alembic export names its cameras' objects the same way).
pub(super) fn usd_name(name: &str, taken: &[String]) -> String {
    let mut n: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if n.is_empty() || n.starts_with(|c: char| c.is_ascii_digit()) {
        n.insert(0, '_');
    }
    let mut out = n.clone();
    let mut i = 1;
    while taken.contains(&out) {
        out = format!("{n}_{i}");
        i += 1;
    }
    out
}

/// One number of a vertex's confidence (also the Alembic export's).
pub(super) type ConfidenceField = fn(&VertexConfidence) -> f64;

/// Writes the items separated by ", ".
fn list<T>(o: &mut String, items: impl Iterator<Item = T>, mut item: impl FnMut(&mut String, T)) {
    for (i, x) in items.enumerate() {
        if i > 0 {
            o.push_str(", ");
        }
        item(o, x);
    }
}

/// `decl.timeSamples = { frame: [values], ... }`.
fn samples(
    o: &mut String,
    decl: &str,
    frames: &[(u32, Mesh)],
    mut values: impl FnMut(&mut String, &Mesh),
) {
    let _ = writeln!(o, "        {decl}.timeSamples = {{");
    for (f, m) in frames {
        let _ = write!(o, "            {f}: [");
        values(o, m);
        o.push_str("],\n");
    }
    o.push_str("        }\n");
}

fn primvar(o: &mut String, decl: &str, interpolation: &str, values: impl FnOnce(&mut String)) {
    let _ = write!(o, "        {decl} = [");
    values(o);
    let _ = writeln!(
        o,
        "] (\n            interpolation = \"{interpolation}\"\n        )"
    );
}

fn indices(o: &mut String, name: &str, index: &[u32]) {
    let _ = write!(o, "        int[] {name} = [");
    list(o, index.iter(), |o, v| {
        let _ = write!(o, "{v}");
    });
    o.push_str("]\n");
}

/// The bounding box of a mesh's positions, in `f32`.
pub(crate) fn bounds(m: &Mesh) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &m.positions {
        for (k, c) in [p.x, p.y, p.z].into_iter().enumerate() {
            lo[k] = lo[k].min(c as f32);
            hi[k] = hi[k].max(c as f32);
        }
    }
    (lo, hi)
}

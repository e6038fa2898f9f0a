//! USD text (`.usda`): a stage whose default prim `tracked` holds one `Mesh` prim `mesh` with the
//! topology once (`faceVertexCounts`, `faceVertexIndices`, right-handed), `points` and `extent`
//! as time samples at the frame numbers, texture coordinates as the `st` primvar (face-varying
//! with indices, or per vertex) and normals as the `normals` primvar (face-varying, time
//! samples). The stage's time codes are the frame numbers at `fps` per second. A tracked run's
//! per-vertex confidence becomes the `information`, `residual` and `sigma` primvars (per vertex,
//! time samples at the solved frames; `sigma` is `inf` where nothing constrains the vertex).

use super::ExportOptions;
use crate::base::mesh::Mesh;
use crate::tracker::VertexConfidence;
use std::fmt::Write;

/// The `.usda` text of `frames`.
pub(crate) fn usda(
    frames: &[(u32, Mesh)],
    confidence: &[(u32, Vec<VertexConfidence>)],
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
    o.push_str("    }\n}\n");
    o
}

/// One number of a vertex's confidence.
type ConfidenceField = fn(&VertexConfidence) -> f64;

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

//! Agisoft Metashape camera XML (File → Export → Cameras, "Agisoft XML"): every aligned camera
//! (one with a `<transform>`) becomes a camera named by its `label`; cameras not aligned are
//! left out, and aligned cameras disabled in Metashape (`enabled="false"`) are kept with a note
//! saying so. Labels must be unique.
//!
//! Chunks: the one chunk with aligned cameras that is not disabled is read; a file with several
//! such chunks is refused with their list unless one is chosen (by label or id).
//!
//! Metashape's conventions converted here (its manual, appendix "Camera models", frame
//! cameras): the principal point `cx`, `cy` is an offset from the image centre and its pixel
//! centres sit at half-integers, so ours is `(w/2 + cx − 0.5, h/2 + cy − 0.5)`; `f` is the focal
//! length and `b1`, `b2` the affinity and skew, so `K = [[f + b1, b2, ·], [0, f, ·], [0, 0, 1]]`;
//! its tangential `P1` multiplies `r² + 2x²` where OpenCV's `p2` does, so OpenCV gets
//! `(k1, k2, P2, P1, k3)`; `k4`, `p3`, `p4` have no OpenCV equivalent and must be zero. Camera
//! transforms are camera-to-chunk, or, in Metashape 2.x, camera-to-component for a camera with a
//! `component_id`: its component's `<transform>` (rotation, translation, scale) maps the
//! component to the chunk, `X_chunk = s·R·X_component + T`; the chunk's `<transform>` maps the
//! chunk to the world the same way: `X_world = s·R_c·X_chunk + T_c`.

use super::{check_rotation, CalibratedCamera};
use crate::base::lens::Distortion;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use std::collections::BTreeMap;
use std::path::Path;

/// The first child element of `n` named `tag`.
fn child<'a, 'i>(n: roxmltree::Node<'a, 'i>, tag: &str) -> Option<roxmltree::Node<'a, 'i>> {
    n.children().find(|c| c.has_tag_name(tag))
}

/// `X ↦ s·R·X + t`.
#[derive(Clone, Copy)]
struct Similarity {
    s: f64,
    r: Matrix3<f64>,
    t: Vector3<f64>,
}

impl Similarity {
    const IDENTITY: Similarity = Similarity {
        s: 1.0,
        r: Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        t: Vector3::new(0.0, 0.0, 0.0),
    };

    /// `outer` after `self`.
    fn then(&self, outer: &Similarity) -> Similarity {
        Similarity {
            s: outer.s * self.s,
            r: outer.r * self.r,
            t: outer.s * (outer.r * self.t) + outer.t,
        }
    }
}

/// Whether a chunk or camera is disabled in Metashape.
fn disabled(n: roxmltree::Node) -> bool {
    matches!(n.attribute("enabled"), Some("false" | "0"))
}

/// The cameras of a chunk (not those of its other elements).
fn cameras<'a, 'i>(
    chunk: roxmltree::Node<'a, 'i>,
) -> impl Iterator<Item = roxmltree::Node<'a, 'i>> {
    chunk.descendants().filter(|n| {
        n.has_tag_name("camera")
            && n.parent()
                .is_some_and(|p| p.has_tag_name("cameras") || p.has_tag_name("group"))
    })
}

struct Sensor {
    width: u32,
    height: u32,
    k: Matrix3<f64>,
    distortion: Option<Distortion>,
}

/// The aligned cameras of a Metashape camera XML file (of its one chunk with aligned cameras
/// that is not disabled).
pub fn read_metashape(path: &Path) -> Result<Vec<CalibratedCamera>> {
    read_metashape_chunk(path, None)
}

/// The aligned cameras of a Metashape camera XML file, of the chunk whose label or id is
/// `chunk` (a chunk without an `id` attribute has its position from 0), or, with `None`, of its
/// one chunk with aligned cameras that is not disabled.
pub fn read_metashape_chunk(path: &Path, chunk: Option<&str>) -> Result<Vec<CalibratedCamera>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let doc = roxmltree::Document::parse(&text).map_err(|e| {
        let p = e.pos();
        Error::invalid(
            path,
            format!("line {} column {}", p.row, p.col),
            format!("invalid XML: {e}"),
        )
    })?;
    let at = |n: roxmltree::Node, field: &str| {
        let line = doc.text_pos_at(n.range().start).row;
        format!("line {line}: {field}")
    };
    let bad =
        |n: roxmltree::Node, field: &str, msg: String| Error::invalid(path, at(n, field), msg);
    let chunks: Vec<roxmltree::Node> = doc
        .descendants()
        .filter(|n| n.has_tag_name("chunk"))
        .collect();
    if chunks.is_empty() {
        return Err(Error::invalid(
            path,
            "(document)",
            "no <chunk> element: not a Metashape camera file",
        ));
    }
    let id = |i: usize, c: roxmltree::Node| c.attribute("id").map_or(i.to_string(), String::from);
    let aligned = |c: roxmltree::Node| {
        cameras(c)
            .filter(|n| child(*n, "transform").is_some())
            .count()
    };
    let list = |picked: &[usize]| {
        picked
            .iter()
            .map(|&i| {
                let c = chunks[i];
                format!(
                    "{:?} (id {}, line {}{}, {} aligned cameras)",
                    c.attribute("label").unwrap_or(""),
                    id(i, c),
                    doc.text_pos_at(c.range().start).row,
                    if disabled(c) { ", disabled" } else { "" },
                    aligned(c)
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let all: Vec<usize> = (0..chunks.len()).collect();
    // Every refusal of the chunk choice names the chunks there are.
    let refuse = |msg: String| Error::invalid(path, "chunk", msg);
    let chunk = match chunk {
        Some(want) => {
            let found: Vec<usize> = all
                .iter()
                .copied()
                .filter(|&i| chunks[i].attribute("label") == Some(want) || id(i, chunks[i]) == want)
                .collect();
            match found[..] {
                [i] => chunks[i],
                [] => {
                    return Err(refuse(format!(
                        "no chunk has the label or id {want:?}; the chunks: {}",
                        list(&all)
                    )))
                }
                _ => {
                    return Err(refuse(format!(
                        "{want:?} names several chunks: {}; choose by id",
                        list(&found)
                    )))
                }
            }
        }
        None => {
            let enabled: Vec<usize> = all
                .iter()
                .copied()
                .filter(|&i| !disabled(chunks[i]))
                .collect();
            let with: Vec<usize> = enabled
                .iter()
                .copied()
                .filter(|&i| aligned(chunks[i]) > 0)
                .collect();
            match (&with[..], &enabled[..]) {
                ([i], _) => chunks[*i],
                ([], [i, ..]) => chunks[*i],
                ([], []) => {
                    return Err(refuse(format!(
                            "every chunk is disabled in Metashape: {}; choose one with --chunk LABEL_OR_ID",
                            list(&all)
                        )))
                }
                _ => {
                    return Err(refuse(format!(
                            "{} chunks have aligned cameras: {}; choose one with --chunk LABEL_OR_ID (or export one chunk from Metashape)",
                            with.len(),
                            list(&with)
                        )))
                }
            }
        }
    };
    let number = |n: roxmltree::Node, field: &str| -> Result<f64> {
        let s = n.text().unwrap_or("").trim();
        s.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| bad(n, field, format!("{s:?} is not a finite number")))
    };
    let numbers = |n: roxmltree::Node, field: &str, count: usize| -> Result<Vec<f64>> {
        let v = n
            .text()
            .unwrap_or("")
            .split_whitespace()
            .map(|s| s.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| bad(n, field, "expected finite numbers".into()))?;
        if v.len() != count {
            return Err(bad(
                n,
                field,
                format!("expected {count} numbers, found {}", v.len()),
            ));
        }
        Ok(v)
    };
    // Sensors.
    let mut sensors: BTreeMap<String, Sensor> = BTreeMap::new();
    for s in chunk.descendants().filter(|n| n.has_tag_name("sensor")) {
        let id = s.attribute("id").unwrap_or("").to_string();
        let field = |f: &str| format!("sensor {id}: {f}");
        let calib = s
            .children()
            .filter(|c| c.has_tag_name("calibration"))
            .max_by_key(|c| c.attribute("class") == Some("adjusted"))
            .ok_or_else(|| bad(s, &field("calibration"), "missing".into()))?;
        if let Some(t) = calib.attribute("type").filter(|t| *t != "frame") {
            return Err(bad(
                calib,
                &field("calibration type"),
                format!("{t:?}: only frame cameras are supported"),
            ));
        }
        let res = child(calib, "resolution")
            .or_else(|| child(s, "resolution"))
            .ok_or_else(|| bad(s, &field("resolution"), "missing".into()))?;
        let dim = |a: &str| {
            res.attribute(a)
                .and_then(|v| v.parse::<u32>().ok())
                .filter(|&v| v > 0)
                .ok_or_else(|| {
                    bad(
                        res,
                        &field(&format!("resolution {a}")),
                        "expected a positive integer".into(),
                    )
                })
        };
        let (w, h) = (dim("width")?, dim("height")?);
        let get = |tag: &str| -> Result<f64> {
            match child(calib, tag) {
                Some(n) => number(n, &field(tag)),
                None => Ok(0.0),
            }
        };
        let f = match child(calib, "f") {
            Some(n) => number(n, &field("f"))?,
            None => return Err(bad(calib, &field("f"), "missing".into())),
        };
        if f <= 0.0 {
            return Err(bad(calib, &field("f"), format!("{f} must be positive")));
        }
        for tag in ["k4", "p3", "p4"] {
            if get(tag)? != 0.0 {
                return Err(bad(
                    child(calib, tag).unwrap_or(calib),
                    &field(tag),
                    "has no equivalent in OpenCV's model (only k1-k3, p1, p2, b1, b2 can be imported)".into(),
                ));
            }
        }
        let (cx, cy, b1, b2) = (get("cx")?, get("cy")?, get("b1")?, get("b2")?);
        let k = Matrix3::new(
            f + b1,
            b2,
            w as f64 / 2.0 + cx - 0.5,
            0.0,
            f,
            h as f64 / 2.0 + cy - 0.5,
            0.0,
            0.0,
            1.0,
        );
        let c = [get("k1")?, get("k2")?, get("p2")?, get("p1")?, get("k3")?];
        let distortion =
            Distortion::new("opencv", &c).map_err(|m| bad(calib, &field("distortion"), m))?;
        sensors.insert(
            id,
            Sensor {
                width: w,
                height: h,
                k,
                distortion: Some(distortion).filter(|d| !d.is_identity()),
            },
        );
    }
    // A <transform> of rotation, translation and scale (each optional).
    let similarity = |t: roxmltree::Node, what: &str| -> Result<Similarity> {
        let r = match child(t, "rotation") {
            Some(n) => {
                let field = format!("{what} rotation");
                let r = Matrix3::from_row_slice(&numbers(n, &field, 9)?);
                if !check_rotation(&r) {
                    return Err(bad(n, &field, "not a rotation matrix".into()));
                }
                r
            }
            None => Matrix3::identity(),
        };
        let tr = match child(t, "translation") {
            Some(n) => Vector3::from_row_slice(&numbers(n, &format!("{what} translation"), 3)?),
            None => Vector3::zeros(),
        };
        let s = match child(t, "scale") {
            Some(n) => number(n, &format!("{what} scale"))?,
            None => 1.0,
        };
        if s <= 0.0 {
            return Err(bad(
                t,
                &format!("{what} scale"),
                format!("{s} must be positive"),
            ));
        }
        Ok(Similarity { s, r, t: tr })
    };
    // The chunk's transform to the world, if any.
    let world = match child(chunk, "transform") {
        None => Similarity::IDENTITY,
        Some(t) => similarity(t, "chunk transform")?,
    };
    // Metashape 2.x: each component's transform to the chunk.
    let mut components: BTreeMap<String, Similarity> = BTreeMap::new();
    for c in chunk.descendants().filter(|n| {
        n.has_tag_name("component") && n.parent().is_some_and(|p| p.has_tag_name("components"))
    }) {
        let cid = c.attribute("id").unwrap_or("").to_string();
        let sim = match child(c, "transform") {
            None => Similarity::IDENTITY,
            Some(t) => similarity(t, &format!("component {cid}: transform"))?,
        };
        components.insert(cid, sim);
    }
    let mut labels: BTreeMap<String, u32> = BTreeMap::new();
    let mut out = Vec::new();
    for cam in cameras(chunk) {
        let label = cam
            .attribute("label")
            .or(cam.attribute("id"))
            .unwrap_or("camera")
            .to_string();
        let Some(tn) = child(cam, "transform") else {
            continue; // not aligned
        };
        let field = |f: &str| format!("camera {label:?}: {f}");
        let sensor_id = cam.attribute("sensor_id").unwrap_or("");
        let sensor = sensors.get(sensor_id).ok_or_else(|| {
            bad(
                cam,
                &field("sensor_id"),
                format!("sensor {sensor_id:?} is not in the file"),
            )
        })?;
        let m = numbers(tn, &field("transform"), 16)?;
        let r_cam = Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
        let t_cam = Vector3::new(m[3], m[7], m[11]);
        if !check_rotation(&r_cam) || m[12..] != [0.0, 0.0, 0.0, 1.0] {
            return Err(bad(
                tn,
                &field("transform"),
                "expected a rigid 4x4 camera-to-chunk transform (rotation, translation, last row 0 0 0 1)".into(),
            ));
        }
        let to_chunk = match cam.attribute("component_id") {
            None => Similarity::IDENTITY,
            Some(cid) => *components.get(cid).ok_or_else(|| {
                bad(
                    cam,
                    &field("component_id"),
                    format!("component {cid:?} is not in the chunk's <components>"),
                )
            })?,
        };
        let line = doc.text_pos_at(cam.range().start).row;
        if let Some(first) = labels.insert(label.clone(), line) {
            return Err(bad(
                cam,
                &field("label"),
                format!("the camera on line {first} has this label too: camera names must be unique (rename one in Metashape)"),
            ));
        }
        // Camera to world: X = S·R·x_cam + T; so R x_cam·S = Rᵀ·(X − T): the same pixels.
        let pose = Similarity {
            s: 1.0,
            r: r_cam,
            t: t_cam,
        }
        .then(&to_chunk)
        .then(&world);
        let r = pose.r.transpose();
        let t = -(r * pose.t);
        out.push(CalibratedCamera {
            name: label,
            width: sensor.width,
            height: sensor.height,
            k: sensor.k,
            r,
            t,
            distortion: sensor.distortion.clone(),
            note: disabled(cam).then(|| "disabled in Metashape".to_string()),
        });
    }
    if out.is_empty() {
        return Err(Error::invalid(
            path,
            "cameras",
            "no aligned camera (none has a <transform>)",
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::calib::testing::{err, has};
    use nalgebra::Rotation3;

    /// A chunk with one 640x480 sensor (f 500) and the given cameras; `extra` goes before the
    /// cameras (components, the chunk transform).
    fn chunk(attrs: &str, extra: &str, cameras: &str) -> String {
        format!(
            r#"
  <chunk {attrs}>
    <sensors>
      <sensor id="0" label="s" type="frame">
        <resolution width="640" height="480"/>
        <calibration type="frame" class="adjusted">
          <resolution width="640" height="480"/>
          <f>500</f>
        </calibration>
      </sensor>
    </sensors>{extra}
    <cameras>{cameras}
    </cameras>
  </chunk>"#
        )
    }

    /// A camera whose camera-to-chunk (or -component) transform is `r`, `t`.
    fn camera(attrs: &str, r: &Matrix3<f64>, t: &Vector3<f64>) -> String {
        let mut m = Vec::new();
        for i in 0..3 {
            m.extend([r[(i, 0)], r[(i, 1)], r[(i, 2)], t[i]]);
        }
        m.extend([0.0, 0.0, 0.0, 1.0]);
        let m: Vec<String> = m.iter().map(|v| v.to_string()).collect();
        format!(
            "\n      <camera sensor_id=\"0\" {attrs}><transform>{}</transform></camera>",
            m.join(" ")
        )
    }

    fn transform(r: &Matrix3<f64>, t: &Vector3<f64>, s: f64) -> String {
        let r: Vec<String> = r.transpose().iter().map(|v| v.to_string()).collect();
        format!(
            "<transform><rotation>{}</rotation><translation>{} {} {}</translation><scale>{s}</scale></transform>",
            r.join(" "),
            t.x,
            t.y,
            t.z
        )
    }

    fn write(dir: &tempfile::TempDir, chunks: &[String]) -> std::path::PathBuf {
        let p = dir.path().join("cameras.xml");
        let doc = format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<document version=\"2.0.0\">{}\n</document>\n",
            chunks.concat()
        );
        std::fs::write(&p, doc).unwrap();
        p
    }

    fn identity() -> (Matrix3<f64>, Vector3<f64>) {
        (Matrix3::identity(), Vector3::zeros())
    }

    /// Metashape 2.x: a camera's transform is relative to its component, whose transform
    /// (scale, rotation, translation) maps it into the chunk. A point known in the camera's
    /// coordinates, carried to the world by hand through the three transforms, must be seen by
    /// the imported camera in the same direction.
    #[test]
    fn a_cameras_component_transform_is_applied_before_the_chunks() {
        let r_cam = Rotation3::from_euler_angles(0.1, 0.5, -0.2).into_inner();
        let t_cam = Vector3::new(0.5, -0.2, 1.0);
        // The component: 90 degrees about x, scale 2, then (1, 2, 3).
        let r_k = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        let (t_k, s_k) = (Vector3::new(1.0, 2.0, 3.0), 2.0);
        // The chunk: 30 degrees about z, scale 1.7, then (10, -4, 2.5).
        let r_c = Rotation3::from_axis_angle(&Vector3::z_axis(), 30f64.to_radians()).into_inner();
        let (t_c, s_c) = (Vector3::new(10.0, -4.0, 2.5), 1.7);
        let components = format!(
            "\n    <components active_id=\"0\"><component id=\"0\" label=\"Component 1\">{}</component></components>",
            transform(&r_k, &t_k, s_k)
        );
        let extra = format!("{components}\n    {}", transform(&r_c, &t_c, s_c));
        let cams = camera("id=\"0\" label=\"cam0\" component_id=\"0\"", &r_cam, &t_cam);
        let dir = tempfile::tempdir().unwrap();
        let p = write(&dir, &[chunk("label=\"Chunk 1\"", &extra, &cams)]);
        let c = &read_metashape(&p).unwrap()[0];

        let x_cam = Vector3::new(0.1, -0.2, 3.0);
        let x_component = r_cam * x_cam + t_cam;
        let x_chunk = s_k * (r_k * x_component) + t_k;
        let x_world = s_c * (r_c * x_chunk) + t_c;
        let seen = c.r * x_world + c.t;
        let (got, want) = (seen / seen.z, x_cam / x_cam.z);
        assert!(
            (got - want).norm() < 1e-9,
            "the camera sees the point at {got:?}, it is at {want:?}"
        );
        // And the distance is scaled by both scales.
        assert!((seen.norm() / x_cam.norm() - s_k * s_c).abs() < 1e-9);

        // A component the chunk does not have is named.
        let cams = camera("id=\"0\" label=\"cam0\" component_id=\"7\"", &r_cam, &t_cam);
        let p = write(&dir, &[chunk("label=\"Chunk 1\"", &extra, &cams)]);
        has(
            &err(read_metashape(&p)),
            &["cameras.xml", "camera \"cam0\": component_id", "\"7\""],
        );
    }

    #[test]
    fn disabled_chunks_are_skipped_and_several_enabled_ones_must_be_chosen() {
        let (r, t) = identity();
        let one = chunk(
            "label=\"Chunk 1\" enabled=\"false\"",
            "",
            &camera("id=\"0\" label=\"a\"", &r, &t),
        );
        let two = chunk(
            "label=\"Chunk 2\" enabled=\"true\"",
            "",
            &(camera("id=\"0\" label=\"b\"", &r, &t) + &camera("id=\"1\" label=\"c\"", &r, &t)),
        );
        let names = |c: Vec<CalibratedCamera>| c.into_iter().map(|c| c.name).collect::<Vec<_>>();
        let dir = tempfile::tempdir().unwrap();
        // The first chunk is disabled: the second is read.
        let p = write(&dir, &[one.clone(), two.clone()]);
        assert_eq!(names(read_metashape(&p).unwrap()), ["b", "c"]);
        // Chosen by label or by id (the position, without an id attribute), disabled or not.
        assert_eq!(
            names(read_metashape_chunk(&p, Some("Chunk 1")).unwrap()),
            ["a"]
        );
        assert_eq!(
            names(read_metashape_chunk(&p, Some("1")).unwrap()),
            ["b", "c"]
        );
        has(
            &err(read_metashape_chunk(&p, Some("Chunk 3"))),
            &[
                "cameras.xml",
                "\"Chunk 3\"",
                "\"Chunk 1\" (id 0",
                "\"Chunk 2\" (id 1",
            ],
        );
        // Two enabled chunks with aligned cameras: refused, with the list and how to choose.
        let p = write(&dir, &[one.replace("\"false\"", "\"true\""), two]);
        has(
            &err(read_metashape(&p)),
            &[
                "cameras.xml",
                "2 chunks have aligned cameras",
                "\"Chunk 1\" (id 0, line 3, 1 aligned cameras)",
                "\"Chunk 2\" (id 1",
                "--chunk",
                "export one chunk",
            ],
        );
    }

    #[test]
    fn disabled_cameras_are_kept_with_a_note_and_labels_must_be_unique() {
        let (r, t) = identity();
        let cams = camera("id=\"0\" label=\"a\"", &r, &t)
            + &camera("id=\"1\" label=\"b\" enabled=\"false\"", &r, &t);
        let dir = tempfile::tempdir().unwrap();
        let p = write(&dir, &[chunk("label=\"Chunk 1\"", "", &cams)]);
        let c = read_metashape(&p).unwrap();
        assert_eq!((c[0].note.as_deref(), c[1].name.as_str()), (None, "b"));
        assert_eq!(c[1].note.as_deref(), Some("disabled in Metashape"));

        let cams = camera("id=\"0\" label=\"a\"", &r, &t) + &camera("id=\"1\" label=\"a\"", &r, &t);
        let p = write(&dir, &[chunk("label=\"Chunk 1\"", "", &cams)]);
        let e = err(read_metashape(&p));
        let second = 1 + std::fs::read_to_string(&p)
            .unwrap()
            .lines()
            .position(|l| l.contains("id=\"1\""))
            .unwrap();
        has(
            &e,
            &[
                "cameras.xml",
                &format!("line {second}: camera \"a\": label"),
                &format!("line {}", second - 1),
                "unique",
            ],
        );
    }
}

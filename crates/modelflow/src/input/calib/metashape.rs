//! Agisoft Metashape camera XML (File → Export → Cameras, "Agisoft XML"): every aligned camera
//! (one with a `<transform>`) becomes a camera named by its `label`; cameras not aligned are
//! left out.
//!
//! Metashape's conventions converted here (its manual, appendix "Camera models", frame
//! cameras): the principal point `cx`, `cy` is an offset from the image centre and its pixel
//! centres sit at half-integers, so ours is `(w/2 + cx − 0.5, h/2 + cy − 0.5)`; `f` is the focal
//! length and `b1`, `b2` the affinity and skew, so `K = [[f + b1, b2, ·], [0, f, ·], [0, 0, 1]]`;
//! its tangential `P1` multiplies `r² + 2x²` where OpenCV's `p2` does, so OpenCV gets
//! `(k1, k2, P2, P1, k3)`; `k4`, `p3`, `p4` have no OpenCV equivalent and must be zero. Camera
//! transforms are camera-to-chunk, and the chunk's `<transform>` (rotation, translation, scale)
//! maps the chunk to the world: `X_world = s·R_c·X_chunk + T_c`.

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

struct Sensor {
    width: u32,
    height: u32,
    k: Matrix3<f64>,
    distortion: Option<Distortion>,
}

/// The aligned cameras of a Metashape camera XML file.
pub fn read_metashape(path: &Path) -> Result<Vec<CalibratedCamera>> {
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
    let chunk = doc
        .descendants()
        .find(|n| n.has_tag_name("chunk"))
        .ok_or_else(|| {
            Error::invalid(
                path,
                "(document)",
                "no <chunk> element: not a Metashape camera file",
            )
        })?;
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
    // The chunk's transform to the world, if any.
    let (rc, tc, sc) = match child(chunk, "transform") {
        None => (Matrix3::identity(), Vector3::zeros(), 1.0),
        Some(t) => {
            let r = match child(t, "rotation") {
                Some(n) => {
                    let r = Matrix3::from_row_slice(&numbers(n, "chunk transform rotation", 9)?);
                    if !check_rotation(&r) {
                        return Err(bad(
                            n,
                            "chunk transform rotation",
                            "not a rotation matrix".into(),
                        ));
                    }
                    r
                }
                None => Matrix3::identity(),
            };
            let tr = match child(t, "translation") {
                Some(n) => Vector3::from_row_slice(&numbers(n, "chunk transform translation", 3)?),
                None => Vector3::zeros(),
            };
            let s = match child(t, "scale") {
                Some(n) => number(n, "chunk transform scale")?,
                None => 1.0,
            };
            if s <= 0.0 {
                return Err(bad(
                    t,
                    "chunk transform scale",
                    format!("{s} must be positive"),
                ));
            }
            (r, tr, s)
        }
    };
    let mut out = Vec::new();
    for cam in chunk.descendants().filter(|n| {
        n.has_tag_name("camera")
            && n.parent()
                .is_some_and(|p| p.has_tag_name("cameras") || p.has_tag_name("group"))
    }) {
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
        // x_cam·s = R_camᵀ·R_cᵀ·(X − T_c) − s·R_camᵀ·t_cam: the same pixels as x_cam.
        let r = r_cam.transpose() * rc.transpose();
        let t = -(r * tc) - sc * (r_cam.transpose() * t_cam);
        out.push(CalibratedCamera {
            name: label,
            width: sensor.width,
            height: sensor.height,
            k: sensor.k,
            r,
            t,
            distortion: sensor.distortion.clone(),
            note: None,
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

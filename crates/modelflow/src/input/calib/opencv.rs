//! OpenCV `FileStorage` files (YAML or JSON, as `cv::FileStorage` writes them) from camera or
//! stereo calibration. Two layouts are read:
//!
//! - **stereo** (`stereoCalibrate`'s results): `K1`/`M1`, `D1`, `K2`/`M2`, `D2`, `R`, `T`: the
//!   first camera is the world (`R = I`, `t = 0`), the second is at `R`, `T`;
//! - **per camera**: a camera's fields at the top level (one camera, named after the file) or in
//!   one map per camera (named by the map's key): a camera matrix (`camera_matrix`, `K`,
//!   `cameraMatrix`, `M`), distortion (`distortion_coefficients`, `dist_coeffs`, `D`,
//!   `distCoeffs`; optional), a pose (`R` or `rvec` as `cv::Rodrigues` takes it, and `T`/`tvec`;
//!   absent: the world), and `distortion_model: fisheye` for `cv::fisheye` coefficients.
//!
//! The image size comes from `image_width`/`image_height` (or `width`/`height`, or
//! `image_size: [w, h]`), or else from the caller. OpenCV's pixel-centre convention is ours, so
//! `K` is taken as it is.

use super::{check_rotation, CalibratedCamera};
use crate::base::lens::Distortion;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use serde_json::{Map, Value};
use std::path::Path;

/// The cameras in an OpenCV `FileStorage` file (`.yml`, `.yaml` or `.json`); `size` is the image
/// size of cameras whose file gives none.
pub fn read_opencv(path: &Path, size: Option<(u32, u32)>) -> Result<Vec<CalibratedCamera>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let root = if text.trim_start().starts_with('{') {
        serde_json::from_str::<Value>(&text).map_err(|e| {
            Error::invalid(
                path,
                format!("line {} column {}", e.line(), e.column()),
                format!("invalid JSON: {e}"),
            )
        })?
    } else {
        parse_yaml(path, &text)?
    };
    let top = root
        .as_object()
        .ok_or_else(|| Error::invalid(path, "(top level)", "expected a map of named nodes"))?;
    let file = File { path, text: &text };
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "cam0".into());
    let top_size = file.size(top, "")?;
    if let (Some(_), Some(_)) = (pick(top, K1), pick(top, K2)) {
        let size = top_size.or(size);
        let first = file.camera(top, "cam0", "", K1, D1, false, size)?;
        let second = file.camera(top, "cam1", "", K2, D2, true, size)?;
        return Ok(vec![first, second]);
    }
    if pick(top, K).is_some() {
        return Ok(vec![file.camera(
            top,
            &stem,
            "",
            K,
            D,
            true,
            top_size.or(size),
        )?]);
    }
    let mut out = Vec::new();
    for (key, node) in top {
        if let Some(map) = node.as_object().filter(|m| pick(m, K).is_some()) {
            let size = file.size(map, &format!("{key}."))?.or(top_size).or(size);
            out.push(file.camera(map, key, &format!("{key}."), K, D, true, size)?);
        }
    }
    if out.is_empty() {
        return Err(Error::invalid(
            path,
            "(top level)",
            "no camera found: expected K1, D1, K2, D2, R, T (stereo), or a camera_matrix (or K) at the top level or in one map per camera",
        ));
    }
    Ok(out)
}

const K: &[&str] = &[
    "camera_matrix",
    "K",
    "cameraMatrix",
    "M",
    "intrinsic_matrix",
];
const D: &[&str] = &[
    "distortion_coefficients",
    "dist_coeffs",
    "D",
    "distCoeffs",
    "dist",
];
const K1: &[&str] = &["K1", "M1"];
const D1: &[&str] = &["D1"];
const K2: &[&str] = &["K2", "M2"];
const D2: &[&str] = &["D2"];

fn pick<'a>(
    m: &'a Map<String, Value>,
    names: &[&'static str],
) -> Option<(&'static str, &'a Value)> {
    names.iter().find_map(|n| m.get(*n).map(|v| (*n, v)))
}

struct File<'a> {
    path: &'a Path,
    text: &'a str,
}

impl File<'_> {
    /// "line N: FIELD" for the first line where `key` is written as a key, else just the field.
    fn at(&self, field: &str) -> String {
        let key = field.rsplit('.').next().unwrap_or(field);
        let pats = [format!("{key}:"), format!("\"{key}\":")];
        match self
            .text
            .lines()
            .position(|l| pats.iter().any(|p| l.trim_start().starts_with(p.as_str())))
        {
            Some(i) => format!("line {}: {field}", i + 1),
            None => field.to_string(),
        }
    }

    fn bad(&self, field: &str, msg: impl Into<String>) -> Error {
        Error::invalid(self.path, self.at(field), msg)
    }

    /// The numbers of a matrix node (`{rows, cols, data}`, OpenCV's `!!opencv-matrix`), or of a
    /// plain list, checked to hold `want` finite numbers.
    fn numbers(&self, v: &Value, field: &str, want: &[usize]) -> Result<Vec<f64>> {
        let data = match v {
            Value::Object(m) => {
                let d = m
                    .get("data")
                    .ok_or_else(|| self.bad(field, "a matrix node without `data`"))?;
                if let (Some(r), Some(c)) = (m.get("rows"), m.get("cols")) {
                    let (r, c) = (r.as_u64().unwrap_or(0), c.as_u64().unwrap_or(0));
                    let n = d.as_array().map_or(0, |a| a.len()) as u64;
                    if r * c != n {
                        return Err(self.bad(
                            field,
                            format!("rows {r} x cols {c} but {n} numbers in data"),
                        ));
                    }
                }
                d
            }
            other => other,
        };
        let list = data
            .as_array()
            .ok_or_else(|| self.bad(field, "expected a matrix or a list of numbers"))?;
        let nums = list
            .iter()
            .map(|x| x.as_f64().filter(|v| v.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| self.bad(field, "expected finite numbers only"))?;
        if !want.contains(&nums.len()) {
            return Err(self.bad(
                field,
                format!(
                    "expected {} numbers, found {}",
                    want.iter()
                        .map(|n| n.to_string())
                        .collect::<Vec<_>>()
                        .join(" or "),
                    nums.len()
                ),
            ));
        }
        Ok(nums)
    }

    /// The image size a map gives, if any.
    fn size(&self, m: &Map<String, Value>, prefix: &str) -> Result<Option<(u32, u32)>> {
        let dim = |v: &Value, f: &str| {
            v.as_u64()
                .and_then(|n| u32::try_from(n).ok())
                .filter(|&n| n > 0)
                .ok_or_else(|| {
                    self.bad(&format!("{prefix}{f}"), format!("{v} is not an image size"))
                })
        };
        for (w, h) in [("image_width", "image_height"), ("width", "height")] {
            if let (Some(a), Some(b)) = (m.get(w), m.get(h)) {
                return Ok(Some((dim(a, w)?, dim(b, h)?)));
            }
        }
        for key in ["image_size", "imageSize"] {
            if let Some(v) = m.get(key) {
                let s = self.numbers(v, &format!("{prefix}{key}"), &[2])?;
                let ok = |x: f64| x >= 1.0 && x <= u32::MAX as f64 && x.fract() == 0.0;
                if !(ok(s[0]) && ok(s[1])) {
                    return Err(
                        self.bad(&format!("{prefix}{key}"), "expected two positive integers")
                    );
                }
                return Ok(Some((s[0] as u32, s[1] as u32)));
            }
        }
        Ok(None)
    }

    #[allow(clippy::too_many_arguments)]
    fn camera(
        &self,
        m: &Map<String, Value>,
        name: &str,
        prefix: &str,
        k_names: &[&'static str],
        d_names: &[&'static str],
        posed: bool,
        size: Option<(u32, u32)>,
    ) -> Result<CalibratedCamera> {
        let (kn, kv) = pick(m, k_names)
            .ok_or_else(|| self.bad(&format!("{prefix}{}", k_names[0]), "missing camera matrix"))?;
        let kf = format!("{prefix}{kn}");
        let k = self.numbers(kv, &kf, &[9])?;
        let k = Matrix3::from_row_slice(&k);
        if k[(2, 0)] != 0.0 || k[(2, 1)] != 0.0 || k[(2, 2)] != 1.0 || k[(1, 0)] != 0.0 {
            return Err(self.bad(&kf, "expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]]"));
        }
        if k[(0, 0)] <= 0.0 || k[(1, 1)] <= 0.0 {
            return Err(self.bad(&kf, "focal lengths must be positive"));
        }
        let fisheye = m
            .get("distortion_model")
            .and_then(|v| v.as_str())
            .is_some_and(|s| s.eq_ignore_ascii_case("fisheye"));
        let distortion = match pick(m, d_names) {
            None => None,
            Some((dn, dv)) => {
                let df = format!("{prefix}{dn}");
                let c = self.numbers(dv, &df, if fisheye { &[4] } else { &[4, 5, 8, 12, 14] })?;
                let d = Distortion::new(if fisheye { "fisheye" } else { "opencv" }, &c)
                    .map_err(|msg| self.bad(&df, msg))?;
                Some(d).filter(|d| !d.is_identity())
            }
        };
        let (r, t) = if !posed {
            (Matrix3::identity(), Vector3::zeros())
        } else {
            let r = if let Some((rn, rv)) = pick(m, &["R", "rotation_matrix"]) {
                let rf = format!("{prefix}{rn}");
                let r = Matrix3::from_row_slice(&self.numbers(rv, &rf, &[9])?);
                if !check_rotation(&r) {
                    return Err(self.bad(&rf, "not a rotation matrix"));
                }
                r
            } else if let Some((rn, rv)) = pick(m, &["rvec", "rotation_vector", "r"]) {
                let v = self.numbers(rv, &format!("{prefix}{rn}"), &[3])?;
                // cv::Rodrigues: the axis times the angle.
                nalgebra::Rotation3::new(Vector3::new(v[0], v[1], v[2])).into_inner()
            } else {
                Matrix3::identity()
            };
            let t = match pick(m, &["T", "tvec", "translation", "t"]) {
                Some((tn, tv)) => {
                    let v = self.numbers(tv, &format!("{prefix}{tn}"), &[3])?;
                    Vector3::new(v[0], v[1], v[2])
                }
                None => Vector3::zeros(),
            };
            (r, t)
        };
        let (width, height) = size.ok_or_else(|| {
            self.bad(
                &format!("{prefix}image_width"),
                format!("camera {name}: no image size (image_width and image_height, or image_size); give it with --size WxH"),
            )
        })?;
        Ok(CalibratedCamera {
            name: name.to_string(),
            width,
            height,
            k,
            r,
            t,
            distortion,
            note: None,
        })
    }
}

/// OpenCV's YAML (its `%YAML:1.0` or `%YAML 1.2` directive dropped, `!!opencv-matrix` tags
/// ignored) as a JSON value.
fn parse_yaml(path: &Path, text: &str) -> Result<Value> {
    let body: String = text
        .lines()
        .map(|l| if l.starts_with("%YAML") { "" } else { l })
        .collect::<Vec<_>>()
        .join("\n");
    let docs = yaml_rust2::YamlLoader::load_from_str(&body).map_err(|e| {
        Error::invalid(
            path,
            format!("line {} column {}", e.marker().line(), e.marker().col() + 1),
            format!("invalid YAML: {}", e.info()),
        )
    })?;
    let doc = docs
        .into_iter()
        .next()
        .ok_or_else(|| Error::invalid(path, "(file)", "empty YAML document"))?;
    Ok(to_json(&doc))
}

fn to_json(y: &yaml_rust2::Yaml) -> Value {
    use yaml_rust2::Yaml;
    match y {
        Yaml::Real(s) => y
            .as_f64()
            .or_else(|| s.parse::<f64>().ok())
            .and_then(serde_json::Number::from_f64)
            .map_or(Value::Null, Value::Number),
        Yaml::Integer(i) => Value::from(*i),
        Yaml::String(s) => Value::String(s.clone()),
        Yaml::Boolean(b) => Value::Bool(*b),
        Yaml::Array(a) => Value::Array(a.iter().map(to_json).collect()),
        Yaml::Hash(h) => Value::Object(
            h.iter()
                .filter_map(|(k, v)| {
                    let key = match k {
                        Yaml::String(s) => s.clone(),
                        Yaml::Integer(i) => i.to_string(),
                        _ => return None,
                    };
                    Some((key, to_json(v)))
                })
                .collect(),
        ),
        _ => Value::Null,
    }
}

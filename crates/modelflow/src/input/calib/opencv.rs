//! OpenCV `FileStorage` files (YAML or JSON, as `cv::FileStorage` writes them) from camera or
//! stereo calibration. Two layouts are read:
//!
//! - **stereo** (`stereoCalibrate`'s results): `K1`/`M1`, `D1`, `K2`/`M2`, `D2`, `R`, `T`: the
//!   first camera is the world (`R = I`, `t = 0`), the second is at `R`, `T`;
//! - **per camera**: a camera's fields at the top level (one camera, named after the file) or in
//!   one map per camera (named by the map's key): a camera matrix (`camera_matrix`, `K`,
//!   `cameraMatrix`, `M`), distortion (`distortion_coefficients`, `dist_coeffs`, `D`,
//!   `distCoeffs`; optional), a pose (`R` or `rvec` as `cv::Rodrigues` takes it, and `T`/`tvec`),
//!   and `distortion_model: fisheye` for `cv::fisheye` coefficients (`opencv`, the default, and
//!   ROS's names `plumb_bob`, `rational_polynomial`, `equidistant` are read too; any other model
//!   is refused). A file of several cameras needs every camera's pose; a lone camera without one
//!   is the world (`calibrateCamera`'s intrinsics only). `R` and `rvec` together must agree.
//!
//! The image size comes from `image_width`/`image_height` (or `width`/`height`, or
//! `image_size: [w, h]`), or else from the caller. OpenCV's pixel-centre convention is ours, so
//! `K` is taken as it is. A byte-order mark at the start is skipped; XML `FileStorage` files are
//! refused with how to convert them.

use super::{check_rotation, strip_bom, CalibratedCamera};
use crate::base::lens::Distortion;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use serde_json::{Map, Value};
use std::path::Path;

/// The cameras in an OpenCV `FileStorage` file (`.yml`, `.yaml` or `.json`); `size` is the image
/// size of cameras whose file gives none.
pub fn read_opencv(path: &Path, size: Option<(u32, u32)>) -> Result<Vec<CalibratedCamera>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let text = strip_bom(&text);
    if text.trim_start().starts_with('<') {
        return Err(Error::invalid(
            path,
            "(file)",
            "an XML FileStorage file, which is not read: save the calibration with a .yml or .json file name instead (cv::FileStorage picks the format from the file name), or read this file with cv::FileStorage and write its nodes to a .yml file",
        ));
    }
    let root = if text.trim_start().starts_with('{') {
        super::parse_json(path, text)?
    } else {
        parse_yaml(path, text)?
    };
    let top = root
        .as_object()
        .ok_or_else(|| Error::invalid(path, "(top level)", "expected a map of named nodes"))?;
    let file = File { path, text };
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "cam0".into());
    let top_size = file.size(top, "")?;
    if let (Some(_), Some(_)) = (pick(top, K1), pick(top, K2)) {
        let size = top_size.or(size);
        let first = file.camera(top, "cam0", "", K1, D1, Pose::World, size)?;
        let second = file.camera(top, "cam1", "", K2, D2, Pose::Required, size)?;
        return Ok(vec![first, second]);
    }
    if pick(top, K).is_some() {
        return Ok(vec![file.camera(
            top,
            &stem,
            "",
            K,
            D,
            Pose::Optional,
            top_size.or(size),
        )?]);
    }
    let maps: Vec<(&String, &Map<String, Value>)> = top
        .iter()
        .filter_map(|(key, node)| Some((key, node.as_object()?)))
        .filter(|(_, m)| pick(m, K).is_some())
        .collect();
    // Several cameras need every pose: a missing one is not the world's origin.
    let pose = if maps.len() > 1 {
        Pose::Required
    } else {
        Pose::Optional
    };
    let mut out = Vec::new();
    for (key, map) in maps {
        let size = file.size(map, &format!("{key}."))?.or(top_size).or(size);
        out.push(file.camera(map, key, &format!("{key}."), K, D, pose, size)?);
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
const R: &[&str] = &["R", "rotation_matrix"];
const RVEC: &[&str] = &["rvec", "rotation_vector", "r"];
const T: &[&str] = &["T", "tvec", "translation", "t"];

/// How a camera's missing pose is taken.
#[derive(Clone, Copy, PartialEq)]
enum Pose {
    /// The world itself (stereo's first camera): no pose is read.
    World,
    /// A camera among several: its pose must be given.
    Required,
    /// The file's only camera: no pose means the world.
    Optional,
}

/// The distortion models read (`distortion_model`, case aside), and ours for each: ROS's
/// `camera_info` names OpenCV's model `plumb_bob` (5 coefficients) or `rational_polynomial` (8),
/// and `cv::fisheye`'s `equidistant`.
const MODELS: [(&str, &str); 5] = [
    ("opencv", "opencv"),
    ("plumb_bob", "opencv"),
    ("rational_polynomial", "opencv"),
    ("fisheye", "fisheye"),
    ("equidistant", "fisheye"),
];
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
    /// "line N: FIELD" for the line where the field's key is written (`cam1.D`: the first `D`
    /// key after the `cam1` key), else just the field.
    fn at(&self, field: &str) -> String {
        let lines: Vec<&str> = self.text.lines().collect();
        let mut from = 0;
        let mut found = None;
        for key in field.split('.') {
            let pats = [format!("{key}:"), format!("\"{key}\":")];
            match lines[from..]
                .iter()
                .position(|l| pats.iter().any(|p| l.trim_start().starts_with(p.as_str())))
            {
                Some(i) => {
                    found = Some(from + i);
                    from += i + 1;
                }
                None => {
                    found = None;
                    break;
                }
            }
        }
        match found {
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
            return Err(self.bad(field, super::expected_count(want, nums.len())));
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
                return super::whole_size(s[0], s[1]).map(Some).ok_or_else(|| {
                    self.bad(&format!("{prefix}{key}"), "expected two positive integers")
                });
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
        pose: Pose,
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
        let fisheye = match m.get("distortion_model") {
            None => false,
            Some(v) => {
                let model = v.as_str().and_then(|s| {
                    MODELS
                        .iter()
                        .find(|(name, _)| s.trim().eq_ignore_ascii_case(name))
                });
                match model {
                    Some((_, ours)) => *ours == "fisheye",
                    None => {
                        return Err(self.bad(
                            &format!("{prefix}distortion_model"),
                            format!(
                                "camera {name}: {v} is not a model that is read (opencv, also written plumb_bob or rational_polynomial; fisheye, also written equidistant)"
                            ),
                        ))
                    }
                }
            }
        };
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
        let (r, t) = if pose == Pose::World {
            (Matrix3::identity(), Vector3::zeros())
        } else {
            let matrix = match pick(m, R) {
                Some((rn, rv)) => {
                    let rf = format!("{prefix}{rn}");
                    let r = Matrix3::from_row_slice(&self.numbers(rv, &rf, &[9])?);
                    if !check_rotation(&r) {
                        return Err(self.bad(&rf, "not a rotation matrix"));
                    }
                    Some((rf, r))
                }
                None => None,
            };
            let vector = match pick(m, RVEC) {
                Some((rn, rv)) => {
                    let rf = format!("{prefix}{rn}");
                    let v = self.numbers(rv, &rf, &[3])?;
                    // cv::Rodrigues: the axis times the angle.
                    let v = Vector3::new(v[0], v[1], v[2]);
                    Some((rf, v, nalgebra::Rotation3::new(v).into_inner()))
                }
                None => None,
            };
            let t = match pick(m, T) {
                Some((tn, tv)) => {
                    let v = self.numbers(tv, &format!("{prefix}{tn}"), &[3])?;
                    Some(Vector3::new(v[0], v[1], v[2]))
                }
                None => None,
            };
            let r = match (matrix, vector) {
                (Some((rf, r)), Some((vf, v, rv))) => {
                    // Rotations by θ apart: |R1 - R2| (Frobenius) = 2·sqrt(2)·sin(θ/2).
                    let angle = 2.0
                        * ((r - rv).norm() / (2.0 * std::f64::consts::SQRT_2))
                            .min(1.0)
                            .asin();
                    if angle > 1e-6 {
                        return Err(self.bad(
                            &vf,
                            format!(
                                "camera {name}: {rf} {:?} and {vf} {:?} are different rotations (by {angle:.2e} rad): give one of them",
                                [0, 1, 2].map(|i| [0, 1, 2].map(|j| r[(i, j)])),
                                [v.x, v.y, v.z]
                            ),
                        ));
                    }
                    Some(r)
                }
                (Some((_, r)), None) | (None, Some((_, _, r))) => Some(r),
                (None, None) => None,
            };
            // Where the pose would be: the camera's map, or the top level's R and T.
            let here = if prefix.is_empty() {
                "R".to_string()
            } else {
                prefix.trim_end_matches('.').to_string()
            };
            match (r, t) {
                (Some(r), Some(t)) => (r, t),
                (None, None) if pose == Pose::Optional => (Matrix3::identity(), Vector3::zeros()),
                (None, None) => {
                    return Err(self.bad(
                        &here,
                        format!(
                            "camera {name} has no pose (R or rvec, and T or tvec): in a file of several cameras each needs one (the reference camera's is R = identity, T = 0)"
                        ),
                    ))
                }
                (Some(_), None) => {
                    return Err(self.bad(
                        &here,
                        format!("camera {name} has a rotation but no translation (T or tvec)"),
                    ))
                }
                (None, Some(_)) => {
                    return Err(self.bad(
                        &here,
                        format!("camera {name} has a translation but no rotation (R or rvec)"),
                    ))
                }
            }
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
pub(crate) fn parse_yaml(path: &Path, text: &str) -> Result<Value> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::calib::testing::{err, has};

    fn fixture(file: &str) -> String {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/opencv");
        std::fs::read_to_string(p.join(file)).unwrap()
    }

    fn read(name: &str, text: &str) -> Result<Vec<CalibratedCamera>> {
        super::super::testing::read_text(name, text, |p| read_opencv(p, None))
    }

    /// The line (from 1) of the `nth` (from 0) line holding `s`.
    fn line_of(text: &str, s: &str, nth: usize) -> usize {
        1 + text
            .lines()
            .enumerate()
            .filter(|(_, l)| l.contains(s))
            .nth(nth)
            .unwrap()
            .0
    }

    /// A camera map of a rig file: 640x480, K of f 800, and `pose` (YAML lines).
    fn camera(name: &str, pose: &str) -> String {
        format!(
            "{name}:\n   image_width: 640\n   image_height: 480\n   camera_matrix: [ 800., 0., 319.5, 0., 800., 239.5, 0., 0., 1. ]\n{pose}"
        )
    }

    const ORIGIN: &str = "   rvec: [ 0., 0., 0. ]\n   tvec: [ 0., 0., 0. ]\n";

    #[test]
    fn an_unknown_distortion_model_is_refused_with_the_models_read() {
        let rig = fixture("rig.yml");
        // cam2 is the third camera: its model's line is the third distortion_model line.
        let omnidir = rig.replace("distortion_model: fisheye", "distortion_model: omnidir");
        has(
            &err(read("rig.yml", &omnidir)),
            &[
                "rig.yml",
                &format!(
                    "line {}: cam2.distortion_model",
                    line_of(&rig, "distortion_model", 2)
                ),
                "\"omnidir\" is not a model that is read",
                "opencv",
                "fisheye",
            ],
        );
        // ROS's names for OpenCV's models are read as them.
        let ros = rig
            .replacen("distortion_model: opencv", "distortion_model: plumb_bob", 1)
            .replace("distortion_model: fisheye", "distortion_model: equidistant");
        assert_eq!(
            read("rig.yml", &ros).unwrap(),
            read("rig.yml", &rig).unwrap()
        );
    }

    #[test]
    fn every_camera_of_several_needs_a_pose_but_a_lone_one_is_the_world() {
        let rig = format!(
            "%YAML:1.0\n---\n{}{}",
            camera("cam0", ORIGIN),
            camera("cam1", "")
        );
        has(
            &err(read("rig.yml", &rig)),
            &[
                "rig.yml",
                &format!("line {}: cam1", line_of(&rig, "cam1:", 0)),
                "camera cam1 has no pose (R or rvec, and T or tvec)",
            ],
        );
        let half = format!(
            "%YAML:1.0\n---\n{}{}",
            camera("cam0", ORIGIN),
            camera("cam1", "   rvec: [ 0., 0.1, 0. ]\n")
        );
        has(
            &err(read("rig.yml", &half)),
            &["rig.yml", "cam1", "no translation (T or tvec)"],
        );
        // calibrateCamera's intrinsics alone: the camera is the world.
        let lone = format!("%YAML:1.0\n---\n{}", camera("cam0", ""));
        let c = read("cam.yml", &lone).unwrap();
        assert_eq!((c[0].r, c[0].t), (Matrix3::identity(), Vector3::zeros()));
    }

    #[test]
    fn r_and_rvec_must_be_the_same_rotation() {
        // A quarter turn about z, as a matrix and as cv::Rodrigues's vector.
        let quarter = "   R: [ 0., -1., 0., 1., 0., 0., 0., 0., 1. ]\n   tvec: [ 0.5, 0., 0. ]\n";
        let rvec = |z: f64| format!("   rvec: [ 0., 0., {z} ]\n");
        let rig = |z: f64| {
            format!(
                "%YAML:1.0\n---\n{}{}",
                camera("cam0", ORIGIN),
                camera("cam1", &format!("{quarter}{}", rvec(z)))
            )
        };
        let c = read("rig.yml", &rig(std::f64::consts::FRAC_PI_2)).unwrap();
        assert!((c[1].r - Matrix3::new(0., -1., 0., 1., 0., 0., 0., 0., 1.)).norm() < 1e-12);
        let text = rig(std::f64::consts::FRAC_PI_2 + 1e-4);
        has(
            &err(read("rig.yml", &text)),
            &[
                "rig.yml",
                &format!("line {}: cam1.rvec", line_of(&text, "rvec:", 1)),
                "cam1.R [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]",
                "cam1.rvec [0.0, 0.0, 1.5708",
                "different rotations (by 1.00e-4 rad)",
            ],
        );
    }

    #[test]
    fn a_byte_order_mark_is_skipped_and_xml_is_refused_with_how_to_convert() {
        for f in ["stereo.yml", "stereo.json"] {
            let text = fixture(f);
            assert_eq!(
                read(f, &format!("\u{feff}{text}")).unwrap(),
                read(f, &text).unwrap()
            );
        }
        let xml = "<?xml version=\"1.0\"?>\n<opencv_storage>\n<image_width>640</image_width>\n</opencv_storage>\n";
        has(
            &err(read("calib.xml", xml)),
            &[
                "calib.xml",
                "XML FileStorage",
                "not read",
                "with a .yml or .json file name",
            ],
        );
    }
}

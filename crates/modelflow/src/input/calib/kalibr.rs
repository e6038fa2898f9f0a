//! Kalibr's camera-chain files (`camchain.yaml` from `kalibr_calibrate_cameras`, and
//! `camchain-imucam.yaml` from `kalibr_calibrate_imu_camera`, whose IMU fields are not used): the
//! multi-camera rig calibration of the robotics and vision labs. One map per camera, `cam0`,
//! `cam1`, ..., each with `camera_model`, `intrinsics`, `distortion_model`, `distortion_coeffs`
//! and `resolution`, and from `cam1` on `T_cn_cnm1`.
//!
//! Conventions converted:
//! - the world is `cam0`'s frame; `T_cn_cnm1` (4×4) takes camera n−1's coordinates to camera
//!   n's, so camera n's world-to-camera transform is `T_cn_cnm1 · T_cnm1_w` along the chain (the
//!   cameras are taken in the order of their numbers, which must run from 0 without a gap);
//! - `camera_model: pinhole` with `intrinsics: [fu, fv, pu, pv]`, pixel centres at integers as
//!   OpenCV's (Kalibr finds the target's corners with OpenCV): `K` as it is; Kalibr's other
//!   projections (`omni`, `ds`, `eucm`) have no counterpart in OpenCV's models and are refused
//!   by name;
//! - `distortion_model: radtan` (`k1 k2 p1 p2`, OpenCV's first four), `equidistant` (OpenCV's
//!   fisheye `k1..k4`), `none`; `fov` is refused by name.

use super::{check_rotation, expected_count, pinhole_k, strip_bom, whole_size, CalibratedCamera};
use crate::base::lens::Distortion;
use crate::error::{Error, Result};
use nalgebra::{Matrix4, Vector3};
use serde_json::{Map, Value};
use std::path::Path;

/// The cameras of a Kalibr camera-chain file, named `cam0`, `cam1`, ... as Kalibr names them,
/// in the world of `cam0`.
pub fn read_kalibr(path: &Path) -> Result<Vec<CalibratedCamera>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let text = strip_bom(&text);
    let root = super::opencv::parse_yaml(path, text)?;
    let file = File { path, text };
    let top = root.as_object().ok_or_else(|| {
        Error::invalid(
            path,
            "(top level)",
            "expected a map of cameras (cam0:, cam1:, ...), as Kalibr writes camchain.yaml",
        )
    })?;
    // The cameras by number: cam0, cam1, ... without a gap (the chain runs through them).
    let mut numbered: Vec<(usize, &str, &Map<String, Value>)> = Vec::new();
    for (key, v) in top {
        let Some(n) = key
            .strip_prefix("cam")
            .and_then(|d| d.parse::<usize>().ok())
        else {
            continue;
        };
        let m = v
            .as_object()
            .ok_or_else(|| file.bad(key, "", "expected a map of the camera's values"))?;
        numbered.push((n, key, m));
    }
    numbered.sort_by_key(|c| c.0);
    if numbered.is_empty() {
        return Err(Error::invalid(
            path,
            "(top level)",
            "no camera: a Kalibr camera chain lists cam0, cam1, ...",
        ));
    }
    if let Some((i, (n, key, _))) = numbered.iter().enumerate().find(|(i, c)| c.0 != *i) {
        return Err(file.bad(
            key,
            "",
            format!(
                "camera numbers must run from cam0 without a gap (cam{i} is missing before cam{n}): each camera's T_cn_cnm1 is relative to the one before it"
            ),
        ));
    }
    // World (cam0) to the camera read last: T_cn_w = T_cn_cnm1 · T_cnm1_w.
    let mut from_world = Matrix4::<f64>::identity();
    let mut cameras = Vec::new();
    for (n, key, m) in numbered {
        let model = file.name_of(m, key, "camera_model", "pinhole")?;
        if model != "pinhole" {
            return Err(file.bad(
                key,
                "camera_model",
                format!(
                    "{model:?} is not read: only \"pinhole\" (with radtan or equidistant distortion) has a counterpart in OpenCV's models; calibrate with --models pinhole-radtan or pinhole-equi"
                ),
            ));
        }
        let i = file.numbers(m, key, "intrinsics", &[4])?;
        let k = pinhole_k(i[0], i[1], i[2], i[3])
            .ok_or_else(|| file.bad(key, "intrinsics", "focal lengths must be positive"))?;
        let dmodel = file.name_of(m, key, "distortion_model", "none")?;
        let distortion = match dmodel {
            "none" => None,
            "radtan" | "equidistant" => {
                let c = file.numbers(m, key, "distortion_coeffs", &[4])?;
                let ours = if dmodel == "radtan" { "opencv" } else { "fisheye" };
                let d = Distortion::new(ours, &c)
                    .map_err(|msg| file.bad(key, "distortion_coeffs", msg))?;
                Some(d).filter(|d| !d.is_identity())
            }
            other => {
                return Err(file.bad(
                    key,
                    "distortion_model",
                    format!(
                        "{other:?} is not read: radtan (OpenCV's k1 k2 p1 p2), equidistant (OpenCV's fisheye) or none"
                    ),
                ))
            }
        };
        let size = file.numbers(m, key, "resolution", &[2])?;
        let (width, height) = whole_size(size[0], size[1]).ok_or_else(|| {
            file.bad(
                key,
                "resolution",
                "expected [width, height] in whole pixels",
            )
        })?;
        if n > 0 {
            let t = file.numbers(m, key, "T_cn_cnm1", &[16])?;
            let t = Matrix4::from_row_slice(&t);
            let r = t.fixed_view::<3, 3>(0, 0).into_owned();
            if !check_rotation(&r) || t.row(3).iter().ne([0.0, 0.0, 0.0, 1.0].iter()) {
                return Err(file.bad(
                    key,
                    "T_cn_cnm1",
                    "not a rigid transform (a rotation, and a last row 0 0 0 1)",
                ));
            }
            from_world = t * from_world;
        }
        cameras.push(CalibratedCamera {
            name: key.to_string(),
            width,
            height,
            k,
            r: from_world.fixed_view::<3, 3>(0, 0).into_owned(),
            t: Vector3::new(from_world[(0, 3)], from_world[(1, 3)], from_world[(2, 3)]),
            distortion,
            note: m
                .get("rostopic")
                .and_then(Value::as_str)
                .map(|t| format!("rostopic {t}")),
        });
    }
    Ok(cameras)
}

struct File<'a> {
    path: &'a Path,
    text: &'a str,
}

impl File<'_> {
    /// "line N: CAM.KEY" for the line where `key` is written under the camera's map (the
    /// camera's own line when `key` is empty or not found), else "CAM.KEY".
    fn at(&self, cam: &str, key: &str) -> String {
        let field = if key.is_empty() {
            cam.to_string()
        } else {
            format!("{cam}.{key}")
        };
        let lines: Vec<&str> = self.text.lines().collect();
        let header = format!("{cam}:");
        let Some(start) = lines.iter().position(|l| l.starts_with(&header)) else {
            return field;
        };
        let mut line = start;
        if !key.is_empty() {
            for (i, l) in lines.iter().enumerate().skip(start + 1) {
                // The next camera's (or any top-level) key ends this one's map.
                if !l.starts_with([' ', '\t', '-']) && !l.trim().is_empty() {
                    break;
                }
                if l.trim_start().starts_with(&format!("{key}:")) {
                    line = i;
                    break;
                }
            }
        }
        format!("line {}: {field}", line + 1)
    }

    fn bad(&self, cam: &str, key: &str, msg: impl Into<String>) -> Error {
        Error::invalid(self.path, self.at(cam, key), msg)
    }

    /// The name `key` gives (a model's), `default` when the key is absent.
    fn name_of<'m>(
        &self,
        m: &'m Map<String, Value>,
        cam: &str,
        key: &str,
        default: &'static str,
    ) -> Result<&'m str> {
        match m.get(key) {
            None => Ok(default),
            Some(Value::String(s)) => Ok(s.as_str()),
            Some(v) => Err(self.bad(cam, key, format!("expected a name, found {v}"))),
        }
    }

    /// The numbers of `key` (a list, or a list of lists, flattened), finite and as many as one
    /// of `want`.
    fn numbers(
        &self,
        m: &Map<String, Value>,
        cam: &str,
        key: &str,
        want: &[usize],
    ) -> Result<Vec<f64>> {
        let v = m
            .get(key)
            .ok_or_else(|| self.bad(cam, key, format!("missing ({cam} has no {key})")))?;
        let mut out = Vec::new();
        let mut push = |x: &Value| match x.as_f64().filter(|f| f.is_finite()) {
            Some(f) => {
                out.push(f);
                true
            }
            None => false,
        };
        let ok = v.as_array().is_some_and(|a| {
            a.iter().all(|x| match x {
                Value::Array(row) => row.iter().all(&mut push),
                other => push(other),
            })
        });
        if !ok {
            return Err(self.bad(
                cam,
                key,
                format!("expected a list of finite numbers, found {v}"),
            ));
        }
        if !want.contains(&out.len()) {
            return Err(self.bad(cam, key, expected_count(want, out.len())));
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::calib::testing::has;
    use nalgebra::Matrix3;

    fn read(text: &str) -> Result<Vec<CalibratedCamera>> {
        super::super::testing::read_text("camchain.yaml", text, read_kalibr)
    }

    fn err(text: &str) -> String {
        match read(text) {
            Ok(c) => panic!("should be refused, read {} cameras", c.len()),
            Err(e) => e.to_string(),
        }
    }

    const CAM0: &str = "cam0:\n  cam_overlaps: [1]\n  camera_model: pinhole\n  distortion_coeffs: [-0.28, 0.07, 0.0002, 1.7e-05]\n  distortion_model: radtan\n  intrinsics: [458.6, 457.3, 367.2, 248.4]\n  resolution: [752, 480]\n  rostopic: /cam0/image_raw\n";

    fn cam(n: usize, t: &str) -> String {
        format!(
            "cam{n}:\n  T_cn_cnm1:\n{t}  camera_model: pinhole\n  distortion_coeffs: [0.01, -0.002, 0.003, -0.0004]\n  distortion_model: equidistant\n  intrinsics: [460.0, 461.0, 330.0, 250.0]\n  resolution: [640, 480]\n"
        )
    }

    /// A quarter turn about y, then 0.1 along x: as Kalibr writes a 4×4 (one row per line).
    const QUARTER: &str = "  - [0.0, 0.0, 1.0, 0.1]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [-1.0, 0.0, 0.0, 0.0]\n  - [0.0, 0.0, 0.0, 1.0]\n";

    #[test]
    fn the_chain_is_composed_camera_after_camera_in_the_world_of_cam0() {
        let text = format!("{CAM0}{}{}", cam(1, QUARTER), cam(2, QUARTER));
        let c = read(&text).unwrap();
        let names: Vec<&str> = c.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["cam0", "cam1", "cam2"]);
        assert_eq!((c[0].r, c[0].t), (Matrix3::identity(), Vector3::zeros()));
        // Two quarter turns about y make a half turn; the second shift is turned by the first
        // transform: t2 = R·t1 + t1 = (0, 0, −0.1) + (0.1, 0, 0).
        let half = Matrix3::new(-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
        assert!((c[2].r - half).norm() < 1e-15, "{}", c[2].r);
        assert!(
            (c[2].t - Vector3::new(0.1, 0.0, -0.1)).norm() < 1e-15,
            "{}",
            c[2].t
        );
        assert_eq!(c[0].k[(0, 2)], 367.2);
        assert_eq!(c[0].distortion.as_ref().unwrap().model(), "opencv");
        assert_eq!(c[1].distortion.as_ref().unwrap().model(), "fisheye");
        assert_eq!((c[1].width, c[1].height), (640, 480));
    }

    #[test]
    fn models_without_a_counterpart_and_broken_chains_are_refused_at_their_line() {
        let omni = format!(
            "{CAM0}{}",
            cam(1, QUARTER).replace("camera_model: pinhole", "camera_model: omni")
        );
        has(
            &err(&omni),
            &[
                "camchain.yaml",
                "line 15: cam1.camera_model",
                "\"omni\" is not read",
            ],
        );
        let fov = CAM0.replace("distortion_model: radtan", "distortion_model: fov");
        has(&err(&fov), &["line 5: cam0.distortion_model", "\"fov\""]);
        let gap = format!("{CAM0}{}", cam(2, QUARTER));
        has(&err(&gap), &["cam2", "cam1 is missing"]);
        let skew = format!(
            "{CAM0}{}",
            cam(
                1,
                &QUARTER.replace("[0.0, 1.0, 0.0, 0.0]", "[0.0, 2.0, 0.0, 0.0]")
            )
        );
        has(
            &err(&skew),
            &["line 10: cam1.T_cn_cnm1", "not a rigid transform"],
        );
        let short = CAM0.replace("[752, 480]", "[752]");
        has(
            &err(&short),
            &["line 7: cam0.resolution", "expected 2 numbers, found 1"],
        );
        let no_t = format!(
            "{CAM0}{}",
            cam(1, QUARTER).replace("T_cn_cnm1", "T_cam_imu")
        );
        has(&err(&no_t), &["cam1.T_cn_cnm1", "missing"]);
    }
}

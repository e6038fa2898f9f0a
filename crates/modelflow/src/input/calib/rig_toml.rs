//! TOML calibration files of the markerless-capture tools: anipose's `calibration.toml` (also
//! what Pose2Sim and FreeMoCap write and read) and caliscope's `camera_array.toml` (or the
//! cameras of its older `config.toml`). All of them are OpenCV's camera model written out as
//! TOML, so nothing is converted but the layout:
//!
//! - anipose, Pose2Sim, FreeMoCap, an older caliscope: one table per camera (`[cam_0]`,
//!   `[cam_1]`, ... or the camera's own name), each with `matrix` (3×3), `distortions`,
//!   `rotation`, `translation` and `size` (`[width, height]`), optionally `name` and `fisheye`;
//!   tables without `matrix` (`[metadata]`, `[charuco]`, ...) are not cameras. A camera is named
//!   by its `name`, else by its table;
//! - caliscope's `camera_array.toml`: the cameras under `[cameras.N]`, named `cam_N` as caliscope
//!   names their recordings (`cam_N.mp4`; `port_N` in its versions that keyed cameras by `port`).
//!   A camera marked `ignore = true` is left out, and said so, in either layout.
//!
//! Conventions, all OpenCV's, which are ours: `matrix` with pixel centres at integers;
//! `rotation` world-to-camera, as `cv::Rodrigues`'s vector (anipose, Pose2Sim, caliscope's recent
//! versions) or as the 3×3 matrix (caliscope's earlier ones); `translation` world-to-camera (`x = R·X + t`); `distortions` OpenCV's
//! radial–tangential coefficients (4, 5, 8, 12 or 14), or with `fisheye = true` OpenCV's fisheye
//! model's four. Refused with the file, line and field: a camera without a pose (a rig not
//! calibrated yet), a caliscope camera whose frames it turns (`rotation_count`, which modelflow
//! does not do), numbers of the wrong count or kind.

use super::{check_rotation, expected_count, strip_bom, whole_size, CalibratedCamera};
use crate::base::lens::Distortion;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use std::path::Path;
use toml::{Table, Value};

/// The cameras of a TOML rig calibration, and what the user should know about the file as a
/// whole (cameras left out, the world's unit).
#[derive(Clone, Debug, PartialEq)]
pub struct TomlCalibration {
    pub cameras: Vec<CalibratedCamera>,
    pub notes: Vec<String>,
}

/// Reads an anipose / Pose2Sim / FreeMoCap `calibration.toml` or a caliscope
/// `camera_array.toml`; `size` is the image size of cameras whose table gives none.
pub fn read_rig_toml(path: &Path, size: Option<(u32, u32)>) -> Result<TomlCalibration> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let text = strip_bom(&text);
    let root: Table = text.parse().map_err(|e: toml::de::Error| {
        let at = e
            .span()
            .map(|s| format!("line {}", super::line_at(text.as_bytes(), s.start)))
            .unwrap_or_else(|| "(file)".into());
        Error::invalid(
            path,
            at,
            format!("invalid TOML: {}", e.message().trim_end()),
        )
    })?;
    let file = File { path, text };
    let mut notes = Vec::new();
    let mut cameras = Vec::new();
    match root.get("cameras") {
        // caliscope: [cameras.N].
        Some(Value::Table(list)) => {
            notes.push(
                "a caliscope camera array: its world is in metres (--units m shows errors in mm)"
                    .into(),
            );
            for (key, v) in list {
                let section = format!("cameras.{key}");
                let Value::Table(m) = v else {
                    return Err(file.bad(&section, "", "expected a table of the camera's values"));
                };
                // As caliscope names the recordings: cam_N, or port_N in its versions that
                // keyed cameras by port.
                let name = if m.contains_key("port") && !m.contains_key("cam_id") {
                    format!("port_{key}")
                } else {
                    format!("cam_{key}")
                };
                if !file.caliscope_usable(m, &name, &section, &mut notes)? {
                    continue;
                }
                if !m.contains_key("matrix") {
                    return Err(file.bad(
                        &section,
                        "matrix",
                        format!("{name} has no camera matrix: calibrate its intrinsics in caliscope first"),
                    ));
                }
                cameras.push(file.camera(m, &name, &section, size)?);
            }
        }
        Some(_) => {
            return Err(file.bad(
                "cameras",
                "",
                "expected a table of cameras ([cameras.0], [cameras.1], ...)",
            ))
        }
        // anipose, Pose2Sim, FreeMoCap, older caliscope: a table per camera.
        None => {
            for (key, v) in &root {
                let Value::Table(m) = v else { continue };
                if !m.contains_key("matrix") {
                    continue;
                }
                let name = match m.get("name") {
                    Some(Value::String(s)) => s.clone(),
                    Some(other) => other.to_string(),
                    None => key.clone(),
                };
                // An older caliscope's config.toml: the same marks as its camera_array.toml.
                if !file.caliscope_usable(m, &name, key, &mut notes)? {
                    continue;
                }
                cameras.push(file.camera(m, &name, key, size)?);
            }
        }
    }
    if cameras.is_empty() {
        return Err(Error::invalid(
            path,
            "(cameras)",
            "no camera: expected tables with a `matrix` (anipose, Pose2Sim, FreeMoCap: [cam_0], ...; caliscope: [cameras.0], ...)",
        ));
    }
    Ok(TomlCalibration { cameras, notes })
}

struct File<'a> {
    path: &'a Path,
    text: &'a str,
}

impl File<'_> {
    /// "line N: SECTION.KEY" for the line where `key` is written in table `section` (its header
    /// line when `key` is empty or not found), else "SECTION.KEY".
    fn at(&self, section: &str, key: &str) -> String {
        let field = if key.is_empty() {
            section.to_string()
        } else {
            format!("{section}.{key}")
        };
        // A header's name, spaces and quotes left out: `[ cameras."0" ]` is `cameras.0`.
        let header = |l: &str| {
            let l = l.trim();
            (l.starts_with('[') && !l.starts_with("[[")).then(|| {
                l.trim_start_matches('[')
                    .split(']')
                    .next()
                    .unwrap_or("")
                    .chars()
                    .filter(|c| !c.is_whitespace() && *c != '"' && *c != '\'')
                    .collect::<String>()
            })
        };
        let lines: Vec<&str> = self.text.lines().collect();
        let Some(start) = lines
            .iter()
            .position(|l| header(l).as_deref() == Some(section))
        else {
            return field;
        };
        let mut line = start;
        if !key.is_empty() {
            for (i, l) in lines.iter().enumerate().skip(start + 1) {
                if header(l).is_some() {
                    break;
                }
                let t = l.trim_start();
                if t.strip_prefix(key)
                    .is_some_and(|rest| rest.trim_start().starts_with('='))
                {
                    line = i;
                    break;
                }
            }
        }
        format!("line {}: {field}", line + 1)
    }

    fn bad(&self, section: &str, key: &str, msg: impl Into<String>) -> Error {
        Error::invalid(self.path, self.at(section, key), msg)
    }

    /// Whether a camera caliscope marks is to be read: one with `ignore = true` is left out
    /// (and said so in `notes`); one whose frames caliscope turns (`rotation_count`) is refused.
    fn caliscope_usable(
        &self,
        m: &Table,
        name: &str,
        section: &str,
        notes: &mut Vec<String>,
    ) -> Result<bool> {
        if m.get("ignore").and_then(Value::as_bool) == Some(true) {
            notes.push(format!("{name} left out: caliscope marks it ignore = true"));
            return Ok(false);
        }
        match m.get("rotation_count") {
            None | Some(Value::Integer(0)) => Ok(true),
            Some(v) => Err(self.bad(
                section,
                "rotation_count",
                format!(
                    "{name}: {v}: caliscope turns this camera's frames by quarter turns before using them, and its calibration is of the turned frames; modelflow reads frames as filmed: set the camera's rotation to 0 in caliscope and calibrate it again"
                ),
            )),
        }
    }

    /// The numbers of `key` (a list, or a list of lists, flattened), checked to be finite and
    /// as many as one of `want`.
    fn numbers(&self, m: &Table, section: &str, key: &str, want: &[usize]) -> Result<Vec<f64>> {
        let v = m
            .get(key)
            .ok_or_else(|| self.bad(section, key, "missing"))?;
        let mut out = Vec::new();
        let mut flat = |v: &Value| -> bool {
            match v {
                Value::Integer(i) => out.push(*i as f64),
                Value::Float(f) if f.is_finite() => out.push(*f),
                _ => return false,
            }
            true
        };
        let ok = match v {
            Value::Array(a) => a.iter().all(|x| match x {
                Value::Array(row) => row.iter().all(&mut flat),
                other => flat(other),
            }),
            _ => false,
        };
        if !ok {
            return Err(self.bad(
                section,
                key,
                format!("expected a list of finite numbers, found {v}"),
            ));
        }
        if !want.contains(&out.len()) {
            return Err(self.bad(section, key, expected_count(want, out.len())));
        }
        Ok(out)
    }

    fn camera(
        &self,
        m: &Table,
        name: &str,
        section: &str,
        size: Option<(u32, u32)>,
    ) -> Result<CalibratedCamera> {
        let k = Matrix3::from_row_slice(&self.numbers(m, section, "matrix", &[9])?);
        if k[(2, 0)] != 0.0 || k[(2, 1)] != 0.0 || k[(2, 2)] != 1.0 || k[(1, 0)] != 0.0 {
            return Err(self.bad(
                section,
                "matrix",
                "expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]]",
            ));
        }
        if k[(0, 0)] <= 0.0 || k[(1, 1)] <= 0.0 {
            return Err(self.bad(section, "matrix", "focal lengths must be positive"));
        }
        let fisheye = match m.get("fisheye") {
            None => false,
            Some(Value::Boolean(b)) => *b,
            Some(v) => {
                return Err(self.bad(
                    section,
                    "fisheye",
                    format!("expected true or false, found {v}"),
                ))
            }
        };
        let distortion = if m.contains_key("distortions") {
            let (model, want): (&str, &[usize]) = if fisheye {
                ("fisheye", &[4])
            } else {
                ("opencv", &[4, 5, 8, 12, 14])
            };
            let c = self.numbers(m, section, "distortions", want)?;
            let d =
                Distortion::new(model, &c).map_err(|msg| self.bad(section, "distortions", msg))?;
            Some(d).filter(|d| !d.is_identity())
        } else {
            None
        };
        for key in ["rotation", "translation"] {
            if !m.contains_key(key) {
                return Err(self.bad(
                    section,
                    key,
                    format!(
                        "camera {name} has no {key}: the rig's cameras are not placed yet (run the tool's extrinsic calibration)"
                    ),
                ));
            }
        }
        let rv = self.numbers(m, section, "rotation", &[3, 9])?;
        let r = if rv.len() == 3 {
            // cv::Rodrigues: the axis times the angle.
            nalgebra::Rotation3::new(Vector3::new(rv[0], rv[1], rv[2])).into_inner()
        } else {
            let r = Matrix3::from_row_slice(&rv);
            if !check_rotation(&r) {
                return Err(self.bad(section, "rotation", "not a rotation matrix"));
            }
            r
        };
        let tv = self.numbers(m, section, "translation", &[3])?;
        let t = Vector3::new(tv[0], tv[1], tv[2]);
        let (width, height) = if m.contains_key("size") {
            let s = self.numbers(m, section, "size", &[2])?;
            whole_size(s[0], s[1]).ok_or_else(|| {
                self.bad(
                    section,
                    "size",
                    format!(
                        "expected [width, height] in whole pixels, found [{}, {}]",
                        s[0], s[1]
                    ),
                )
            })?
        } else {
            size.ok_or_else(|| {
                self.bad(
                    section,
                    "size",
                    format!("camera {name}: no image size; give it with --size WxH"),
                )
            })?
        };
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::calib::testing::has;

    fn read(text: &str) -> Result<TomlCalibration> {
        super::super::testing::read_text("calibration.toml", text, |p| read_rig_toml(p, None))
    }

    fn err(text: &str) -> String {
        match read(text) {
            Ok(c) => panic!("should be refused, read {} cameras", c.cameras.len()),
            Err(e) => e.to_string(),
        }
    }

    const CAM: &str = "[cam_0]\nname = \"A\"\nsize = [ 640, 480,]\nmatrix = [ [ 500.0, 0.0, 320.0,], [ 0.0, 500.0, 240.0,], [ 0.0, 0.0, 1.0,],]\ndistortions = [ -0.1, 0.01, 0.0, 0.0, 0.0,]\nrotation = [ 0.0, 0.0, 1.5707963267948966,]\ntranslation = [ 1.0, 2.0, 3.0,]\n";

    #[test]
    fn a_rodrigues_vector_and_a_float_size_are_read_as_anipose_and_pose2sim_write_them() {
        let text = format!(
            "{CAM}\n[cam_1]\nname = \"B\"\nsize = [ 1920.0, 1080.0]\nmatrix = [ [ 1000.0, 0.0, 960.0], [ 0.0, 1000.0, 540.0], [ 0.0, 0.0, 1.0]]\ndistortions = [ 0.1, -0.2, 0.3, 0.4]\nrotation = [ 0.0, 0.0, 0.0]\ntranslation = [ 0.0, 0.0, 0.0]\nfisheye = true\n\n[metadata]\nadjusted = false\nerror = 0.4\n"
        );
        let c = read(&text).unwrap().cameras;
        assert_eq!(c.len(), 2);
        assert_eq!(
            (c[0].name.as_str(), c[0].width, c[0].height),
            ("A", 640, 480)
        );
        // A quarter turn about z.
        let want = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        assert!((c[0].r - want).norm() < 1e-15, "{}", c[0].r);
        assert_eq!(c[0].t, Vector3::new(1.0, 2.0, 3.0));
        assert_eq!(c[0].distortion.as_ref().unwrap().model(), "opencv");
        assert_eq!(
            (c[1].name.as_str(), c[1].width, c[1].height),
            ("B", 1920, 1080)
        );
        let d = c[1].distortion.as_ref().unwrap();
        assert_eq!(
            (d.model(), d.coefficients()),
            ("fisheye", vec![0.1, -0.2, 0.3, 0.4])
        );
    }

    #[test]
    fn a_camera_without_a_pose_or_with_a_bad_field_is_refused_at_its_line() {
        let no_pose = CAM.replace("rotation = [ 0.0, 0.0, 1.5707963267948966,]\n", "");
        has(
            &err(&no_pose),
            &[
                "calibration.toml",
                "line 1: cam_0.rotation",
                "camera A has no rotation",
            ],
        );
        let short = CAM.replace(
            "translation = [ 1.0, 2.0, 3.0,]",
            "translation = [ 1.0, 2.0]",
        );
        has(
            &err(&short),
            &["line 7: cam_0.translation", "expected 3 numbers, found 2"],
        );
        let text = CAM.replace("[ 640, 480,]", "[ 640.5, 480]");
        has(&err(&text), &["line 3: cam_0.size", "whole pixels"]);
        let text = CAM.replace("\"A\"", "\"A\"\nfisheye = true");
        has(
            &err(&text),
            &["cam_0.distortions", "expected 4 numbers, found 5"],
        );
        let text = CAM.replace(
            "rotation = [ 0.0, 0.0, 1.5707963267948966,]",
            "rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 2]]",
        );
        has(&err(&text), &["cam_0.rotation", "not a rotation matrix"]);
        has(
            &err("[cam_0]\nmatrix = [1, 2\n"),
            &["line 2", "invalid TOML"],
        );
        has(&err("[metadata]\nerror = 1\n"), &["no camera"]);
    }

    #[test]
    fn caliscope_cameras_are_named_as_its_recordings_and_its_ignored_and_turned_ones_are_handled() {
        let cam = |n: usize, extra: &str| {
            format!(
                "[cameras.{n}]\ncam_id = {n}\n{extra}size = [1280, 720]\nmatrix = [[900.0, 0.0, 640.0], [0.0, 900.0, 360.0], [0.0, 0.0, 1.0]]\ndistortions = [-0.3, 0.05, 0.0, 0.0, 0.06]\ntranslation = [0.1, 0.2, 1.2]\nrotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n\n"
            )
        };
        let text = format!(
            "{}{}{}",
            cam(0, "rotation_count = 0\n"),
            cam(1, "ignore = true\n"),
            cam(2, "")
        );
        let got = read(&text).unwrap();
        let names: Vec<&str> = got.cameras.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["cam_0", "cam_2"]);
        assert!(
            got.notes.iter().any(|n| n.contains("cam_1 left out")),
            "{:?}",
            got.notes
        );
        let text = format!("{}{}", cam(0, ""), cam(1, "rotation_count = 1\n"));
        has(
            &err(&text),
            &[
                "line 11: cameras.1.rotation_count",
                "cam_1",
                "quarter turns",
            ],
        );
        let text = "[cameras.0]\ncam_id = 0\nsize = [1280, 720]\n";
        has(&err(text), &["cameras.0", "cam_0 has no camera matrix"]);
        // Versions that keyed cameras by port name their recordings port_N.
        let ported = cam(0, "").replace("cam_id = 0", "port = 0");
        assert_eq!(read(&ported).unwrap().cameras[0].name, "port_0");
        // An older caliscope's config.toml ([cam_N] tables): the same marks are honoured.
        let old = |n: usize, extra: &str| {
            cam(n, extra).replace(&format!("[cameras.{n}]"), &format!("[cam_{n}]"))
        };
        let text = format!("{}{}", old(0, ""), old(1, "ignore = true\n"));
        let got = read(&text).unwrap();
        assert_eq!(got.cameras.len(), 1);
        assert!(
            got.notes.iter().any(|n| n.contains("cam_1 left out")),
            "{:?}",
            got.notes
        );
        has(
            &err(&format!("{}{}", old(0, ""), old(1, "rotation_count = 2\n"))),
            &["cam_1.rotation_count", "quarter turns"],
        );
    }
}

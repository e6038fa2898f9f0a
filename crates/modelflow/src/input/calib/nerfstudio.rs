//! `transforms.json` files: nerfstudio's (`ns-process-data`), instant-ngp's and the original
//! NeRF synthetic datasets' (`transforms_train.json`), the camera files vision researchers pass
//! around. One JSON object: intrinsics at the top level (shared) or in each entry of `frames`
//! (per camera; a frame's own value wins), each frame one image with its `file_path` and its
//! `transform_matrix`.
//!
//! Conventions converted:
//! - `transform_matrix` is camera-to-world (4×4, or its top 3×4) with OpenGL's camera axes (x
//!   right, y up, looking down −z, as Blender's); ours is world-to-camera with OpenCV's (y down,
//!   looking down +z): `R = diag(1, −1, −1)·R_c2wᵀ`, `t = −R·C`;
//! - `fl_x`, `fl_y`, `cx`, `cy` in pixels with pixel centres at half-integers (nerfstudio casts
//!   rays through `pixel + 0.5`, as COLMAP, whose numbers it copies): our `cx`, `cy` are 0.5 less;
//! - without `fl_x`: `camera_angle_x` (and `camera_angle_y`, else square pixels), the principal
//!   point at the image's centre (what Blender renders; the original NeRF code's rays are half a
//!   pixel off it);
//! - `camera_model`: `OPENCV` (the default; `k1`, `k2`, `k3`, `p1`, `p2` as OpenCV's; nerfstudio's
//!   `k4` is a fourth radial power, which OpenCV's model lacks, so a non-zero one is refused),
//!   `PINHOLE`, `SIMPLE_PINHOLE`, `OPENCV_FISHEYE` (Kannala–Brandt `k1`..`k4`, as OpenCV's
//!   fisheye); others (equirectangular, ...) are refused by name;
//! - the image size from `w`, `h`, or the caller (the NeRF synthetic files give none: 800×800);
//! - `applied_transform` (nerfstudio: the turn it gave COLMAP's world, z up): the cameras are in
//!   the file's world, after it, unless the caller asks for the world before it, where a mesh
//!   made from the same reconstruction lies.
//!
//! Cameras are named after the folder holding each frame's image when those differ
//! (`images/cam0/0000.png` → `cam0`), else after its file stem (`./train/r_0` → `r_0`). Frames
//! of different `time` (D-NeRF's dynamic scenes: one camera's moments) are refused.

use super::{check_rotation, names_from_paths, parse_json, CalibratedCamera};
use crate::base::lens::Distortion;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use serde_json::{Map, Value};
use std::path::Path;

/// Which world a `transforms.json` file's cameras are placed in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NerfWorld {
    /// The file's own: where its `transform_matrix` entries are.
    #[default]
    File,
    /// The world before the file's `applied_transform` (nerfstudio's turn of COLMAP's world):
    /// where a mesh made from the same COLMAP reconstruction lies.
    BeforeApplied,
}

/// The cameras of a `transforms.json` file, and what the user should know about the file as a
/// whole (its `applied_transform`, fields that were ignored).
#[derive(Clone, Debug, PartialEq)]
pub struct NerfCalibration {
    pub cameras: Vec<CalibratedCamera>,
    pub notes: Vec<String>,
}

/// Reads a `transforms.json` file (nerfstudio, instant-ngp, NeRF synthetic); `size` is the image
/// size of cameras whose file gives none.
pub fn read_nerfstudio(
    path: &Path,
    size: Option<(u32, u32)>,
    world: NerfWorld,
) -> Result<NerfCalibration> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let root = parse_json(path, &text)?;
    let top = root.as_object().ok_or_else(|| {
        Error::invalid(
            path,
            "(top level)",
            "expected an object with \"frames\" (a transforms.json file)",
        )
    })?;
    let frames = top.get("frames").and_then(Value::as_array).ok_or_else(|| {
        Error::invalid(
            path,
            "frames",
            "missing or not a list: a transforms.json file lists its images in \"frames\"",
        )
    })?;
    if frames.is_empty() {
        return Err(Error::invalid(path, "frames", "the list is empty"));
    }
    let mut notes = Vec::new();
    let applied = match top.get("applied_transform") {
        None | Some(Value::Null) => None,
        Some(v) => Some(rigid_rows(path, "applied_transform", v)?),
    };
    let before_applied = match (world, applied) {
        (NerfWorld::BeforeApplied, Some((a, _))) if !check_rotation(&a) => {
            return Err(Error::invalid(
                path,
                "applied_transform",
                "its 3×3 part is not a rotation, so the world before it cannot be given to the cameras (a scale or a mirror in it)",
            ));
        }
        (NerfWorld::BeforeApplied, Some(at)) => {
            notes.push(
                "cameras placed in the world before the file's applied_transform (the original reconstruction's)"
                    .into(),
            );
            Some(at)
        }
        (NerfWorld::BeforeApplied, None) => {
            return Err(Error::invalid(
                path,
                "applied_transform",
                "missing: the file's world is the only one it gives (import without --before-applied-transform)",
            ));
        }
        (NerfWorld::File, Some(_)) => {
            notes.push(
                "cameras placed in the file's world, after its applied_transform (nerfstudio's turn of the reconstruction's world); a mesh in the original reconstruction's world needs --before-applied-transform"
                    .into(),
            );
            None
        }
        (NerfWorld::File, None) => None,
    };
    for key in ["scale", "offset", "aabb_scale"] {
        if top.contains_key(key) {
            notes.push(format!(
                "{key:?} ignored: it is how instant-ngp places the scene in its unit cube, not part of the cameras"
            ));
        }
    }
    let file = File { path, top };
    // Names: the folders holding the images when they differ, else the file stems.
    let paths: Vec<String> = frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            f.get("file_path")
                .and_then(Value::as_str)
                .map(str::to_owned)
                .ok_or_else(|| {
                    Error::invalid(
                        path,
                        format!("frames[{i}].file_path"),
                        "missing or not a string",
                    )
                })
        })
        .collect::<Result<_>>()?;
    // A dynamic scene's file (D-NeRF's) gives each frame its `time`: frames of different times
    // are moments of one moving camera, not the cameras of a rig.
    let times: Vec<Option<f64>> = frames
        .iter()
        .map(|f| f.get("time").and_then(Value::as_f64))
        .collect();
    if let Some(i) = times.iter().position(|t| *t != times[0]) {
        return Err(Error::invalid(
            path,
            format!("frames[{i}].time"),
            format!(
                "{:?} where frames[0] has {:?}: the frames are moments of a capture, not the cameras of one moment; import a file of one moment's frames (one image per camera)",
                times[i], times[0]
            ),
        ));
    }
    let names = camera_names(path, &paths)?;
    let mut out = Vec::with_capacity(frames.len());
    for (i, (frame, name)) in frames.iter().zip(names).enumerate() {
        let at = format!("frames[{i}]");
        let frame = frame
            .as_object()
            .ok_or_else(|| Error::invalid(path, &at, "expected an object"))?;
        let (width, height) = file.size(frame, &at, size)?;
        let (k, distortion) = file.intrinsics(frame, &at, width, height)?;
        let (rot, centre) = rigid_rows(
            path,
            &format!("{at}.transform_matrix"),
            frame
                .get("transform_matrix")
                .ok_or_else(|| Error::invalid(path, format!("{at}.transform_matrix"), "missing"))?,
        )?;
        if !check_rotation(&rot) {
            return Err(Error::invalid(
                path,
                format!("{at}.transform_matrix"),
                "its 3×3 part is not a rotation (camera-to-world, without scale)",
            ));
        }
        // OpenGL camera axes to OpenCV's, camera-to-world to world-to-camera.
        let flip = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
        let mut r = flip * rot.transpose();
        let mut t = -(r * centre);
        if let Some((a, b)) = before_applied {
            // A point X of the world before the file's `applied_transform` [A | b] is A·X + b in
            // the file's: x_cam = R·(A·X + b) + t.
            t += r * b;
            r *= a;
        }
        out.push(CalibratedCamera {
            name,
            width,
            height,
            k,
            r,
            t,
            distortion,
            note: None,
        });
    }
    Ok(NerfCalibration {
        cameras: out,
        notes,
    })
}

/// One name per frame (see [`names_from_paths`]); two frames of one name are two moments of one
/// camera, which a scene cannot hold.
fn camera_names(path: &Path, files: &[String]) -> Result<Vec<String>> {
    names_from_paths(files).map_err(|(j, i)| {
        Error::invalid(
            path,
            format!("frames[{i}].file_path"),
            format!(
                "{:?} and {:?} (frames[{j}]) name the same camera, by folder and by file name: import the frames of one moment of the rig (one image per camera)",
                files[i], files[j]
            ),
        )
    })
}

/// A 3×3 rotation part and translation from a 4×4 or 3×4 matrix given as rows.
fn rigid_rows(path: &Path, at: &str, v: &Value) -> Result<(Matrix3<f64>, Vector3<f64>)> {
    let bad = |m: &str| Error::invalid(path, at, m.to_owned());
    let rows = v
        .as_array()
        .filter(|r| r.len() == 3 || r.len() == 4)
        .ok_or_else(|| bad("expected a 4×4 (or 3×4) matrix as a list of rows"))?;
    let mut m = [[0.0f64; 4]; 4];
    for (i, row) in rows.iter().enumerate() {
        let row = row
            .as_array()
            .filter(|r| r.len() == 4)
            .ok_or_else(|| bad(&format!("row {i}: expected 4 numbers")))?;
        for (j, x) in row.iter().enumerate() {
            m[i][j] = x
                .as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(&format!("row {i}, column {j}: {x} is not a finite number")))?;
        }
    }
    if rows.len() == 4 {
        let last = m[3];
        if (last[0].abs() + last[1].abs() + last[2].abs() + (last[3] - 1.0).abs()) > 1e-9 {
            return Err(bad(&format!(
                "last row {last:?}: expected [0, 0, 0, 1] (a rigid transform)"
            )));
        }
    }
    let r = Matrix3::from_fn(|i, j| m[i][j]);
    Ok((r, Vector3::new(m[0][3], m[1][3], m[2][3])))
}

struct File<'a> {
    path: &'a Path,
    top: &'a Map<String, Value>,
}

/// Where `key`'s value comes from, as an error names it: the frame's own (`frames[i].key`) when
/// it gives one, else the file's (`key`).
fn field(frame: &Map<String, Value>, at: &str, key: &str) -> String {
    if frame.contains_key(key) {
        format!("{at}.{key}")
    } else {
        key.to_owned()
    }
}

impl File<'_> {
    /// A frame's value for `key`, else the file's; `Ok(None)` when neither gives it.
    fn number(&self, frame: &Map<String, Value>, at: &str, key: &str) -> Result<Option<f64>> {
        let Some(v) = frame.get(key).or(self.top.get(key)) else {
            return Ok(None);
        };
        if v.is_null() {
            return Ok(None);
        }
        v.as_f64()
            .filter(|x| x.is_finite())
            .map(Some)
            .ok_or_else(|| {
                Error::invalid(
                    self.path,
                    field(frame, at, key),
                    format!("{v} is not a finite number"),
                )
            })
    }

    fn size(
        &self,
        frame: &Map<String, Value>,
        at: &str,
        given: Option<(u32, u32)>,
    ) -> Result<(u32, u32)> {
        let dim = |key: &str| -> Result<Option<u32>> {
            match self.number(frame, at, key)? {
                None => Ok(None),
                Some(v) if v >= 1.0 && v.fract() == 0.0 && v <= u32::MAX as f64 => {
                    Ok(Some(v as u32))
                }
                Some(v) => Err(Error::invalid(
                    self.path,
                    field(frame, at, key),
                    format!("{v} is not an image size in pixels"),
                )),
            }
        };
        match (dim("w")?, dim("h")?) {
            (Some(w), Some(h)) => Ok((w, h)),
            (None, None) => given.ok_or_else(|| {
                Error::invalid(
                    self.path,
                    format!("{at}: w, h"),
                    "the image size is not in the file (the NeRF synthetic files give none; theirs is 800×800): give it with --size WxH",
                )
            }),
            _ => Err(Error::invalid(
                self.path,
                format!("{at}: w, h"),
                "only one of the image's width and height is given",
            )),
        }
    }

    fn intrinsics(
        &self,
        frame: &Map<String, Value>,
        at: &str,
        width: u32,
        height: u32,
    ) -> Result<(Matrix3<f64>, Option<Distortion>)> {
        let num = |key: &str| self.number(frame, at, key);
        let field = |key: &str| field(frame, at, key);
        let model = match frame.get("camera_model").or(self.top.get("camera_model")) {
            None | Some(Value::Null) => "OPENCV".to_owned(),
            Some(Value::String(s)) => s.clone(),
            Some(v) => {
                return Err(Error::invalid(
                    self.path,
                    field("camera_model"),
                    format!("{v} is not a camera model name"),
                ))
            }
        };
        let (w, h) = (width as f64, height as f64);
        let (fx, fy, cx, cy) = match num("fl_x")? {
            Some(fx) => {
                let fy = num("fl_y")?.unwrap_or(fx);
                let cx = num("cx")?.unwrap_or(w / 2.0);
                let cy = num("cy")?.unwrap_or(h / 2.0);
                (fx, fy, cx, cy)
            }
            None => {
                let ax = num("camera_angle_x")?.ok_or_else(|| {
                    Error::invalid(
                        self.path,
                        format!("{at}: fl_x"),
                        "no focal length: expected fl_x (pixels) or camera_angle_x (radians)",
                    )
                })?;
                let from_angle = |a: f64, side: f64, key: &str| {
                    if a > 0.0 && a < std::f64::consts::PI {
                        Ok(0.5 * side / (0.5 * a).tan())
                    } else {
                        Err(Error::invalid(
                            self.path,
                            field(key),
                            format!("{a} is not a field of view in radians (between 0 and π)"),
                        ))
                    }
                };
                let fx = from_angle(ax, w, "camera_angle_x")?;
                let fy = match num("camera_angle_y")? {
                    Some(ay) => from_angle(ay, h, "camera_angle_y")?,
                    None => fx,
                };
                (fx, fy, w / 2.0, h / 2.0)
            }
        };
        if !(fx > 0.0 && fy > 0.0) {
            return Err(Error::invalid(
                self.path,
                field("fl_x"),
                format!("focal lengths {fx}, {fy} must be positive"),
            ));
        }
        let k = Matrix3::new(fx, 0.0, cx - 0.5, 0.0, fy, cy - 0.5, 0.0, 0.0, 1.0);
        let c = |key: &str| Ok::<f64, Error>(num(key)?.unwrap_or(0.0));
        let distortion = match model.as_str() {
            "PINHOLE" | "SIMPLE_PINHOLE" => None,
            "OPENCV" | "PERSPECTIVE" => {
                if c("k4")? != 0.0 {
                    return Err(Error::invalid(
                        self.path,
                        field("k4"),
                        "nerfstudio's k4 (a fourth radial power) has no equivalent in OpenCV's model, whose k4 is a divisor's: recalibrate with k1, k2, k3, or undistort the images",
                    ));
                }
                let d = [c("k1")?, c("k2")?, c("p1")?, c("p2")?, c("k3")?];
                Some(Distortion::new("opencv", &d).map_err(|m| {
                    Error::invalid(self.path, format!("{at}: k1 k2 p1 p2 k3"), m)
                })?)
            }
            "OPENCV_FISHEYE" | "FISHEYE" => {
                let d = [c("k1")?, c("k2")?, c("k3")?, c("k4")?];
                Some(Distortion::new("fisheye", &d).map_err(|m| {
                    Error::invalid(self.path, format!("{at}: k1 k2 k3 k4"), m)
                })?)
            }
            other => {
                return Err(Error::invalid(
                    self.path,
                    field("camera_model"),
                    format!(
                        "{other} has no equivalent here (supported: OPENCV, PINHOLE, SIMPLE_PINHOLE, OPENCV_FISHEYE)"
                    ),
                ))
            }
        };
        Ok((k, distortion.filter(|d| !d.is_identity())))
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::has;
    use super::*;

    fn read(json: &str, size: Option<(u32, u32)>) -> Result<NerfCalibration> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("transforms.json");
        std::fs::write(&p, json).unwrap();
        read_nerfstudio(&p, size, NerfWorld::File)
    }

    fn err(json: &str) -> String {
        match read(json, None) {
            Ok(c) => panic!("should be refused, read {} cameras", c.cameras.len()),
            Err(e) => e.to_string(),
        }
    }

    const EYE: &str = "[[1,0,0,0],[0,1,0,0],[0,0,1,2],[0,0,0,1]]";

    #[test]
    fn an_opengl_camera_behind_the_origin_looks_at_it_down_our_z() {
        // Camera at z = 2 looking down its −z (OpenGL): the origin is 2 in front of it.
        let c = read(
            &format!(
                r#"{{"fl_x": 100, "fl_y": 100, "cx": 50, "cy": 40, "w": 100, "h": 80,
                "frames": [{{"file_path": "a/x.png", "transform_matrix": {EYE}}}]}}"#
            ),
            None,
        )
        .unwrap();
        let cam = &c.cameras[0];
        assert_eq!(cam.name, "a");
        let x = cam.r * Vector3::new(0.0, 0.1, 0.0) + cam.t;
        assert_eq!(x, Vector3::new(0.0, -0.1, 2.0), "world up is image up");
        assert_eq!((cam.k[(0, 2)], cam.k[(1, 2)]), (49.5, 39.5));
        assert!(
            cam.distortion.is_none(),
            "all-zero coefficients are no lens"
        );
    }

    #[test]
    fn broken_files_are_named_with_the_field() {
        let one = |extra: &str, m: &str| {
            format!(
                r#"{{"w": 10, "h": 10, {extra} "frames": [{{"file_path": "a.png", "transform_matrix": {m}}}]}}"#
            )
        };
        has(&err("[1]"), &["transforms.json", "(top level)"]);
        has(&err("{\"frames\": 3}"), &["frames", "not a list"]);
        has(&err(&one("", EYE)), &["frames[0]: fl_x", "camera_angle_x"]);
        has(
            &err(&one(
                "\"fl_x\": 5, \"camera_model\": \"EQUIRECTANGULAR\",",
                EYE,
            )),
            &["camera_model", "EQUIRECTANGULAR", "no equivalent"],
        );
        has(
            &err(&one("\"fl_x\": 5, \"k4\": 0.1,", EYE)),
            &["k4", "fourth radial power"],
        );
        has(
            &err(&one(
                "\"fl_x\": 5,",
                "[[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]",
            )),
            &["frames[0].transform_matrix", "not a rotation"],
        );
        has(
            &err(&one(
                "\"fl_x\": 5,",
                "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,1]]",
            )),
            &["transform_matrix", "last row"],
        );
        has(
            &err(&one("\"fl_x\": 5,", "[[1,0,0],[0,1,0]]")),
            &["transform_matrix", "4×4"],
        );
        has(
            &err(
                r#"{"fl_x": 5, "frames": [{"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}]}"#,
            ),
            &["w, h", "--size"],
        );
        has(
            &err(&format!(
                r#"{{"w": 10, "h": 10, "fl_x": 5, "frames": [{{"file_path": "i/a.png", "transform_matrix": {EYE}}}, {{"file_path": "j/b.png", "transform_matrix": {EYE}}}, {{"file_path": "i/b.jpg", "transform_matrix": {EYE}}}]}}"#
            )),
            &["frames[2].file_path", "one moment of the rig"],
        );
        has(&err("{\"frames\": [1, 2,"), &["line 1", "invalid JSON"]);
        // D-NeRF: one camera's frames at several times.
        has(
            &err(&format!(
                r#"{{"w": 10, "h": 10, "fl_x": 5, "frames": [{{"file_path": "a/r_0.png", "time": 0.0, "transform_matrix": {EYE}}}, {{"file_path": "a/r_1.png", "time": 0.05, "transform_matrix": {EYE}}}]}}"#
            )),
            &["frames[1].time", "moments of a capture"],
        );
    }
}

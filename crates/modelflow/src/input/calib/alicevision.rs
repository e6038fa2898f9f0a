//! AliceVision's SfM files (`.sfm`, `.json`): what Meshroom's `StructureFromMotion`,
//! `SfMTransform` and `ConvertSfMFormat` nodes write (`cameras.sfm`, `sfm.json`), the
//! reconstruction a vision researcher or a photogrammetry artist has. One JSON object: `views`
//! (one image each, with its `poseId` and `intrinsicId`), `intrinsics`, `poses`, `rigs`.
//!
//! Conventions converted (AliceVision's `sfmDataIO/jsonIO.cpp`, `camera/`, `geometry/Pose3`):
//! - every value is a string (`"1920"`; numbers are taken too), matrices flattened column by
//!   column (Eigen's order): `rotation` is the world-to-camera `R` (OpenCV's camera axes: x right,
//!   y down, looking down +z) and `center` the camera centre `C`, so `t = −R·C`;
//! - a view of a rig with `"isPoseIndependant": "false"`: its pose is the rig's sub-pose after the
//!   rig's pose (`R = R_sub·R_rig`, `C = C_rig + R_rigᵀ·C_sub`); any other view has its own pose;
//! - pixel centres at integers, as ours (AliceVision samples images at integer coordinates);
//! - the file `version`: from 1.2.1 on the `principalPoint` is an offset from the image's centre
//!   (`cx = w/2 + offset`), before it from the top-left corner; from 1.2.2 on the focal length is
//!   `focalLength` in millimetres on a `sensorWidth` with a `pixelRatio` (`p`), before it
//!   `pxFocalLength` in pixels (one number before 1.2.0, `fx`, `fy` after). The millimetres are
//!   `fx`'s up to 1.2.8 (`fx = f·w/sensorWidth`; `fy = fx/p` before 1.2.5, where the field held
//!   `fx/fy`, `fy = fx·p` from it) and `fy`'s from 1.2.11 (`fy = f·w/sensorWidth`, `fx = fy/p`:
//!   AliceVision's compatibility files of the same camera say so); 1.2.9 and 1.2.10 are refused
//!   unless `p` is 1, where both agree;
//! - the distortion (`distortionType`, or before it the `type`'s name: `radial1`, `radial3`,
//!   `brown`, `fisheye4`) in the normalised coordinates, as OpenCV's: `radialk1` (k1),
//!   `radialk3` (k1, k2, k3), `brown` (k1, k2, k3, t1, t2 = OpenCV's k1, k2, k3, p1, p2),
//!   `fisheye`/`fisheye4` (Kannala–Brandt, OpenCV's fisheye), `radialk3pt` (radialk3 divided by
//!   `1 + k1 + k2 + k3`: the same model with the focal lengths divided by it). `fisheye1` (the FOV
//!   model), the 3DEqualizer models, an `undistortionType` and `equidistant` cameras have no
//!   equivalent in our camera model and are refused by name.
//!
//! Views without a pose or an intrinsic (not reconstructed; AliceVision's undefined id is −1 or
//! 4294967295), and rotation-only (panorama) poses, are left out and said. Cameras are named
//! after the folder holding each view's image when those differ (`images/cam0/0000.png` →
//! `cam0`), else after its file stem. The file's own landmarks check the conversion: where a
//! camera's observations lie a median of more than 3 px from its landmarks' projections, the
//! import says so (AliceVision's solve leaves about 1 px; a convention read wrongly, hundreds).

use super::{check_rotation, expected_count, names_from_paths, parse_json, CalibratedCamera};
use crate::base::lens::Distortion;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use serde_json::{Map, Value};
use std::collections::BTreeMap;
use std::path::Path;

/// The cameras of an AliceVision SfM file, and what the user should know about it (views left
/// out).
#[derive(Clone, Debug, PartialEq)]
pub struct AliceVisionCalibration {
    pub cameras: Vec<CalibratedCamera>,
    pub notes: Vec<String>,
}

/// A file version, `[major, minor, revision]`.
type Version = (u64, u64, u64);

/// A pose: world-to-camera rotation and camera centre.
type Pose = (Matrix3<f64>, Vector3<f64>);

/// One intrinsic, read: its size, camera matrix and distortion.
type Intrinsic = (u32, u32, Matrix3<f64>, Option<Distortion>);

/// Reads an AliceVision (Meshroom) SfM file in its JSON form (`.sfm` or `.json`).
pub fn read_alicevision(path: &Path) -> Result<AliceVisionCalibration> {
    // Image metadata copied into the views may hold bytes that are not UTF-8 (Meshroom reads the
    // file ignoring them, and so does this).
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8_lossy(&bytes);
    let root = parse_json(path, &text)?;
    let file = File { path };
    let top = root.as_object().ok_or_else(|| {
        Error::invalid(
            path,
            "(top level)",
            "expected an object with \"views\" and \"intrinsics\" (an AliceVision SfM file)",
        )
    })?;
    if !top.contains_key("version") && top.contains_key("landmarks") {
        return Err(Error::invalid(
            path,
            "version",
            "missing, with \"landmarks\": the serialised layout of AliceVision's newest builds, not read; write the SfM as JSON with aliceVision_convertSfMFormat from a release that writes \"version\"",
        ));
    }
    let version = file.version(top)?;
    let list = |key: &str| -> Result<&[Value]> {
        match top.get(key) {
            None => Ok(&[]),
            Some(v) => v
                .as_array()
                .map(Vec::as_slice)
                .ok_or_else(|| Error::invalid(path, key, format!("expected a list, found {v}"))),
        }
    };
    let views = list("views")?;
    if views.is_empty() {
        return Err(Error::invalid(
            path,
            "views",
            "missing or empty: the file has no images (write the SfM with its views)",
        ));
    }
    // Intrinsics are read when a posed view uses them: one that cannot be read but is used by
    // no camera (an unreconstructed view's) does not stop the import.
    let mut intrinsics = BTreeMap::new();
    for (i, e) in list("intrinsics")?.iter().enumerate() {
        let at = format!("intrinsics[{i}]");
        let o = file.object(e, &at)?;
        if let Some(id) = file.id(o, &at, "intrinsicId")? {
            intrinsics.insert(id, (at, o));
        }
    }
    let mut poses: BTreeMap<u64, Pose> = BTreeMap::new();
    let mut rotation_only = Vec::new();
    for (i, e) in list("poses")?.iter().enumerate() {
        let at = format!("poses[{i}]");
        let o = file.object(e, &at)?;
        let Some(id) = file.id(o, &at, "poseId")? else {
            continue;
        };
        let pose = file.object(o.get("pose").unwrap_or(&Value::Null), &format!("{at}.pose"))?;
        // A pose marked invalid ("valid": "0") is one the reconstruction gave up.
        if pose.get("valid").is_some_and(is_false) {
            continue;
        }
        // A rotation-only pose (a panorama's) has no centre worth the name.
        if pose.get("rotationOnly").is_some_and(|v| !is_false(v)) {
            rotation_only.push(id);
            continue;
        }
        let transform = file.object(
            pose.get("transform").unwrap_or(&Value::Null),
            &format!("{at}.pose.transform"),
        )?;
        poses.insert(id, file.pose(transform, &format!("{at}.pose.transform"))?);
    }
    let mut rigs: BTreeMap<u64, Vec<Option<Pose>>> = BTreeMap::new();
    for (i, e) in list("rigs")?.iter().enumerate() {
        let at = format!("rigs[{i}]");
        let o = file.object(e, &at)?;
        let Some(id) = file.id(o, &at, "rigId")? else {
            continue;
        };
        let subs = o.get("subPoses").and_then(Value::as_array).ok_or_else(|| {
            Error::invalid(path, format!("{at}.subPoses"), "missing or not a list")
        })?;
        let mut out = Vec::with_capacity(subs.len());
        for (j, s) in subs.iter().enumerate() {
            let at = format!("{at}.subPoses[{j}]");
            let s = file.object(s, &at)?;
            let status = s.get("status").and_then(string).unwrap_or_default();
            out.push(if status.eq_ignore_ascii_case("uninitialized") {
                None
            } else {
                let p =
                    file.object(s.get("pose").unwrap_or(&Value::Null), &format!("{at}.pose"))?;
                Some(file.pose(p, &format!("{at}.pose"))?)
            });
        }
        rigs.insert(id, out);
    }
    let mut notes = Vec::new();
    let mut posed = Vec::new();
    let mut view_ids = Vec::new();
    for (i, v) in views.iter().enumerate() {
        let at = format!("views[{i}]");
        let o = file.object(v, &at)?;
        let mut image = o
            .get("path")
            .and_then(Value::as_str)
            .ok_or_else(|| Error::invalid(path, format!("{at}.path"), "missing or not a string"))?
            .to_owned();
        let view_id = file.id(o, &at, "viewId")?;
        if image.is_empty() {
            // A view without an image path is named by its id.
            image = format!("view{}", view_id.unwrap_or(i as u64));
        }
        let left_out = |why: &str| format!("views[{i}] ({image:?}) left out: {why}");
        let pose_id = file.id(o, &at, "poseId")?;
        let rig = file.id(o, &at, "rigId")?;
        let dependent = o.get("isPoseIndependant").is_some_and(is_false);
        let pose = match (rig, dependent) {
            (Some(rig), true) => {
                let sub = file.id(o, &at, "subPoseId")?;
                let rig_pose = pose_id.and_then(|p| poses.get(&p));
                let sub_pose = rigs
                    .get(&rig)
                    .zip(sub)
                    .and_then(|(s, sub)| s.get(usize::try_from(sub).ok()?))
                    .and_then(Option::as_ref);
                match (rig_pose, sub_pose) {
                    (Some((rr, cr)), Some((rs, cs))) => Some((rs * rr, cr + rr.transpose() * cs)),
                    _ => None,
                }
            }
            _ => pose_id.and_then(|p| poses.get(&p)).copied(),
        };
        let Some((r, centre)) = pose else {
            notes.push(left_out(
                if pose_id.is_some_and(|p| rotation_only.contains(&p)) {
                    "a rotation-only pose (a panorama's: no camera centre)"
                } else {
                    "no pose (not reconstructed)"
                },
            ));
            continue;
        };
        let intrinsic = file
            .id(o, &at, "intrinsicId")?
            .and_then(|id| intrinsics.get(&id));
        let Some((iat, intrinsic)) = intrinsic else {
            notes.push(left_out("no intrinsic"));
            continue;
        };
        let (width, height, k, distortion) = file.intrinsic(intrinsic, iat, version)?;
        posed.push((image, r, centre, width, height, k, distortion));
        view_ids.push(view_id);
    }
    if posed.is_empty() {
        return Err(Error::invalid(
            path,
            "poses",
            format!(
                "none of the {} views has a pose: import the SfM after StructureFromMotion (its cameras.sfm), not CameraInit's",
                views.len()
            ),
        ));
    }
    // Meshroom on Windows writes `C:\\shoot\\cam0\\0000.jpg`.
    let images: Vec<String> = posed.iter().map(|p| p.0.replace('\\', "/")).collect();
    let names = names_from_paths(&images).map_err(|(j, i)| {
        Error::invalid(
            path,
            "views",
            format!(
                "{:?} and {:?} name the same camera, by folder and by file name: import the SfM of one moment of the rig (one image per camera)",
                images[i], images[j]
            ),
        )
    })?;
    let cameras: Vec<CalibratedCamera> = posed
        .into_iter()
        .zip(names)
        .map(
            |((_, r, centre, width, height, k, distortion), name)| CalibratedCamera {
                name,
                width,
                height,
                k,
                r,
                t: -(r * centre),
                distortion,
                note: None,
            },
        )
        .collect();
    notes.extend(reprojection_notes(
        &cameras,
        &view_ids,
        top.get("structure").and_then(Value::as_array),
    ));
    Ok(AliceVisionCalibration { cameras, notes })
}

/// Where the file's landmarks project through the cameras read, against where AliceVision
/// observed them: a note for each camera whose observations lie a median of more than 3 px off.
fn reprojection_notes(
    cameras: &[CalibratedCamera],
    view_ids: &[Option<u64>],
    structure: Option<&Vec<Value>>,
) -> Vec<String> {
    use crate::base::{Camera, Lens, Projection};
    let Some(structure) = structure else {
        return Vec::new();
    };
    let projectors: Vec<Option<Camera>> = cameras
        .iter()
        .map(|c| {
            let p = Projection::from_krt(&c.k, &c.r, &c.t).ok()?;
            Some(
                Camera::fixed(&c.name, c.width, c.height, p)
                    .with_lens(c.distortion.clone().map(|d| Lens::new(c.k, d))),
            )
        })
        .collect();
    let mut misses: Vec<Vec<f64>> = vec![Vec::new(); cameras.len()];
    let vec_of =
        |v: Option<&Value>| -> Option<Vec<f64>> { v?.as_array()?.iter().map(number).collect() };
    for landmark in structure {
        let Some(x) = vec_of(landmark.get("X")).filter(|x| x.len() == 3) else {
            continue;
        };
        let x = nalgebra::Point3::new(x[0], x[1], x[2]);
        let Some(observations) = landmark.get("observations").and_then(Value::as_array) else {
            continue;
        };
        for obs in observations {
            let Some(id) = obs.get("observationId").and_then(number) else {
                continue;
            };
            let Some(i) = view_ids
                .iter()
                .position(|v| v.is_some_and(|v| v as f64 == id))
            else {
                continue;
            };
            let (Some(seen), Some(Some(camera))) = (
                vec_of(obs.get("x")).filter(|x| x.len() == 2),
                projectors.get(i),
            ) else {
                continue;
            };
            let miss = camera
                .project_raw(0, &x)
                .map_or(f64::INFINITY, |q| (q.x - seen[0]).hypot(q.y - seen[1]));
            misses[i].push(miss);
        }
    }
    let mut notes = Vec::new();
    for (c, mut m) in cameras.iter().zip(misses) {
        if m.is_empty() {
            continue;
        }
        m.sort_by(f64::total_cmp);
        let median = m[m.len() / 2];
        if median > 3.0 {
            notes.push(format!(
                "camera {:?}: the file's landmarks project a median of {median:.1} px from where AliceVision observed them ({} observations; its solve leaves about 1 px): this file may use a convention the importer does not know; check the scene's overlay before tracking",
                c.name,
                m.len()
            ));
        }
    }
    notes
}

/// A number written as AliceVision writes it (a string) or as a JSON number.
fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Number(n) => n.as_f64(),
        Value::String(s) => s.trim().parse().ok(),
        _ => None,
    }
    .filter(|x: &f64| x.is_finite())
}

/// A string, or a boolean or number as its text (`"false"`, `"0"`).
fn string(v: &Value) -> Option<String> {
    match v {
        Value::String(s) => Some(s.trim().to_ascii_lowercase()),
        Value::Bool(b) => Some(b.to_string()),
        Value::Number(n) => Some(n.to_string()),
        _ => None,
    }
}

/// Whether a flag is false as AliceVision or Meshroom write it (`"false"`, `"0"`, `false`, `0`).
fn is_false(v: &Value) -> bool {
    match v {
        Value::Bool(b) => !b,
        Value::String(s) => {
            let s = s.trim();
            s.eq_ignore_ascii_case("false") || s.parse::<f64>().is_ok_and(|x| x == 0.0)
        }
        Value::Number(n) => n.as_f64() == Some(0.0),
        _ => false,
    }
}

struct File<'a> {
    path: &'a Path,
}

impl File<'_> {
    fn object<'v>(&self, v: &'v Value, at: &str) -> Result<&'v Map<String, Value>> {
        v.as_object()
            .ok_or_else(|| Error::invalid(self.path, at, "missing or not an object"))
    }

    fn number(&self, o: &Map<String, Value>, at: &str, key: &str) -> Result<f64> {
        let v = o
            .get(key)
            .ok_or_else(|| Error::invalid(self.path, format!("{at}.{key}"), "missing"))?;
        number(v).ok_or_else(|| {
            Error::invalid(
                self.path,
                format!("{at}.{key}"),
                format!("{v} is not a finite number"),
            )
        })
    }

    /// An id, or `None` when the field is missing or AliceVision's undefined one (−1, or
    /// 4294967295 as it writes its unsigned index).
    fn id(&self, o: &Map<String, Value>, at: &str, key: &str) -> Result<Option<u64>> {
        if !o.contains_key(key) {
            return Ok(None);
        }
        let x = self.number(o, at, key)?;
        if x == -1.0 || x == u32::MAX as f64 {
            return Ok(None);
        }
        if x < 0.0 || x.fract() != 0.0 || x > u64::MAX as f64 {
            return Err(Error::invalid(
                self.path,
                format!("{at}.{key}"),
                format!("{x} is not an id (a whole number, at least 0)"),
            ));
        }
        Ok(Some(x as u64))
    }

    /// The numbers of a list (`""` is AliceVision's empty list).
    fn numbers(&self, o: &Map<String, Value>, at: &str, key: &str) -> Result<Vec<f64>> {
        let field = format!("{at}.{key}");
        match o.get(key) {
            None => Err(Error::invalid(self.path, field, "missing")),
            Some(Value::String(s)) if s.is_empty() => Ok(Vec::new()),
            Some(Value::Array(a)) => a
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    number(v).ok_or_else(|| {
                        Error::invalid(
                            self.path,
                            format!("{field}[{i}]"),
                            format!("{v} is not a finite number"),
                        )
                    })
                })
                .collect(),
            Some(v) => Err(Error::invalid(
                self.path,
                field,
                format!("expected a list of numbers, found {v}"),
            )),
        }
    }

    fn fixed<const N: usize>(
        &self,
        o: &Map<String, Value>,
        at: &str,
        key: &str,
    ) -> Result<[f64; N]> {
        let v = self.numbers(o, at, key)?;
        v.as_slice().try_into().map_err(|_| {
            Error::invalid(
                self.path,
                format!("{at}.{key}"),
                expected_count(&[N], v.len()),
            )
        })
    }

    fn version(&self, top: &Map<String, Value>) -> Result<Version> {
        let v = self.fixed::<3>(top, "(file)", "version").map_err(|_| {
            Error::invalid(
                self.path,
                "version",
                "missing or not three numbers: AliceVision writes its file version as [major, minor, revision]",
            )
        })?;
        Ok((v[0] as u64, v[1] as u64, v[2] as u64))
    }

    /// A `Pose3`: `rotation` (world to camera, column by column) and `center`.
    fn pose(&self, o: &Map<String, Value>, at: &str) -> Result<Pose> {
        let m = self.fixed::<9>(o, at, "rotation")?;
        let r = Matrix3::from_column_slice(&m);
        if !check_rotation(&r) {
            return Err(Error::invalid(
                self.path,
                format!("{at}.rotation"),
                "not a rotation (world to camera, nine numbers column by column)",
            ));
        }
        let c = self.fixed::<3>(o, at, "center")?;
        Ok((r, Vector3::from(c)))
    }

    fn intrinsic(&self, o: &Map<String, Value>, at: &str, version: Version) -> Result<Intrinsic> {
        let bad = |key: &str, m: String| Error::invalid(self.path, format!("{at}.{key}"), m);
        let (w, h) = (self.number(o, at, "width")?, self.number(o, at, "height")?);
        let (width, height) = super::whole_size(w, h)
            .ok_or_else(|| bad("width", format!("{w}×{h} is not an image size in pixels")))?;
        let kind = o.get("type").and_then(string).unwrap_or_default();
        // From file version 1.2.11 the distortion has its own field; before it, the type's name.
        let distortion = match o.get("distortionType").and_then(string) {
            // Meshroom's CameraInit writes `fisheye4` where AliceVision writes `fisheye`.
            Some(d) if d == "fisheye4" => "fisheye".into(),
            Some(d) => d,
            None => match kind.as_str() {
                "pinhole" => "none".into(),
                "radial1" => "radialk1".into(),
                "radial3" => "radialk3".into(),
                "fisheye4" => "fisheye".into(),
                "equidistant_r3" => "radialk3pt".into(),
                other => other.into(),
            },
        };
        let kind = match kind.as_str() {
            // The 3DEqualizer models' legacy types are pinhole cameras too, refused below by
            // their distortion's name.
            "pinhole" | "radial1" | "radial3" | "brown" | "fisheye4" | "fisheye1"
            | "3deradial4" | "3deanamorphic4" | "3declassicld" => "pinhole",
            other => other,
        };
        if kind != "pinhole" {
            return Err(bad(
                "type",
                format!(
                    "{kind:?}: only pinhole cameras (with OpenCV's distortion models) are read; an equidistant or spherical camera has no equivalent"
                ),
            ));
        }
        if let Some(u) = o.get("undistortionType").and_then(string) {
            if u != "none" {
                return Err(bad(
                    "undistortionType",
                    format!(
                        "{u:?}: an undistortion model (AliceVision's 3DEqualizer anamorphic or radial inverse), which OpenCV's models cannot hold"
                    ),
                ));
            }
        }
        let (mut fx, mut fy) = if version < (1, 2, 0) {
            let f = self.number(o, at, "pxFocalLength")?;
            (f, f)
        } else if version < (1, 2, 2) {
            let f = self.fixed::<2>(o, at, "pxFocalLength")?;
            (f[0], f[1])
        } else {
            let mm = self.number(o, at, "focalLength")?;
            let sensor = match o.get("sensorWidth") {
                Some(_) => self.number(o, at, "sensorWidth")?,
                None => 36.0,
            };
            let ratio = match o.get("pixelRatio") {
                Some(_) => self.number(o, at, "pixelRatio")?,
                None => 1.0,
            };
            if !(sensor > 0.0 && ratio > 0.0) {
                return Err(bad(
                    "sensorWidth",
                    format!(
                        "sensor width {sensor} mm and pixel ratio {ratio}: both must be positive"
                    ),
                ));
            }
            let f = mm / sensor * w;
            if version < (1, 2, 5) {
                // `pixelRatio` held fx/fy.
                (f, f / ratio)
            } else if version < (1, 2, 9) {
                (f, f * ratio)
            } else if version < (1, 2, 11) && ratio != 1.0 {
                return Err(bad(
                    "pixelRatio",
                    format!(
                        "{ratio} in file version {}.{}.{}: the millimetres were fx's before and fy's after these versions, and which this one uses is not known; write the SfM again with a newer Meshroom",
                        version.0, version.1, version.2
                    ),
                ));
            } else {
                // The millimetres are fy's.
                (f / ratio, f)
            }
        };
        let pp = self.fixed::<2>(o, at, "principalPoint")?;
        let (cx, cy) = if version < (1, 2, 1) {
            (pp[0], pp[1])
        } else {
            (pp[0] + w / 2.0, pp[1] + h / 2.0)
        };
        let k = self.numbers(o, at, "distortionParams").or_else(|e| {
            // A camera without distortion may leave the field out.
            if distortion == "none" && !o.contains_key("distortionParams") {
                Ok(Vec::new())
            } else {
                Err(e)
            }
        })?;
        let want = match distortion.as_str() {
            "none" => 0,
            "radialk1" => 1,
            "radialk3" | "radialk3pt" => 3,
            "brown" => 5,
            "fisheye" => 4,
            other => {
                return Err(bad(
                    "distortionType",
                    format!(
                        "{other:?}: no equivalent in OpenCV's models (read: none, radialk1, radialk3, radialk3pt, brown, fisheye)"
                    ),
                ))
            }
        };
        if k.len() != want {
            // AliceVision itself would use zeros in their place, silently.
            return Err(bad(
                "distortionParams",
                format!("{} for {distortion:?}", expected_count(&[want], k.len())),
            ));
        }
        let coefficients: Vec<f64> = match distortion.as_str() {
            "none" => Vec::new(),
            "radialk1" => vec![k[0], 0.0, 0.0, 0.0],
            "radialk3" => vec![k[0], k[1], 0.0, 0.0, k[2]],
            "radialk3pt" => {
                let d = 1.0 + k[0] + k[1] + k[2];
                if d <= 0.0 {
                    return Err(bad(
                        "distortionParams",
                        format!("1 + k1 + k2 + k3 = {d}: radialk3pt divides by it, so it must be positive"),
                    ));
                }
                fx /= d;
                fy /= d;
                vec![k[0], k[1], 0.0, 0.0, k[2]]
            }
            "brown" => vec![k[0], k[1], k[3], k[4], k[2]],
            _ => k.clone(),
        };
        let model = if distortion == "fisheye" {
            "fisheye"
        } else {
            "opencv"
        };
        let distortion = if coefficients.iter().all(|&c| c == 0.0) {
            None
        } else {
            Some(Distortion::new(model, &coefficients).map_err(|m| bad("distortionParams", m))?)
        };
        let k = super::pinhole_k(fx, fy, cx, cy).ok_or_else(|| {
            bad(
                if version < (1, 2, 2) {
                    "pxFocalLength"
                } else {
                    "focalLength"
                },
                format!("focal lengths {fx}, {fy} px: expected positive ones"),
            )
        })?;
        Ok((width, height, k, distortion))
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::has;
    use super::*;

    fn read(text: &str) -> Result<AliceVisionCalibration> {
        super::super::testing::read_text("cameras.sfm", text, read_alicevision)
    }

    fn fixture() -> String {
        std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/alicevision/cameras.sfm"),
        )
        .unwrap()
    }

    fn err(r: Result<AliceVisionCalibration>) -> String {
        match r {
            Ok(c) => panic!("should be refused, read {} cameras", c.cameras.len()),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn what_has_no_equivalent_is_refused_by_name_and_field() {
        let text = fixture();
        has(
            &err(read(&text.replacen(
                "\"distortionType\": \"brown\"",
                "\"distortionType\": \"fisheye1\"",
                1,
            ))),
            &[
                "cameras.sfm",
                "intrinsics[2].distortionType",
                "fisheye1",
                "no equivalent",
            ],
        );
        has(
            &err(read(&text.replacen(
                "\"type\": \"pinhole\"",
                "\"type\": \"equidistant\"",
                1,
            ))),
            &["intrinsics[0].type", "equidistant"],
        );
        has(
            &err(read(&text.replacen(
                "\"undistortionType\": \"none\"",
                "\"undistortionType\": \"3deanamorphic4\"",
                1,
            ))),
            &["intrinsics[0].undistortionType", "3DEqualizer"],
        );
        // A coefficient missing: AliceVision would use zeros; refused here.
        has(
            &err(read(&text.replacen("\"-0.21\",", "", 1))),
            &[
                "intrinsics[1].distortionParams",
                "expected 3 numbers, found 2",
                "radialk3",
            ],
        );
        has(
            &err(read(&text.replacen("\"version\": [", "\"versio\": [", 1))),
            &["version", "major, minor, revision"],
        );
        has(
            &err(read(&text[..text.len() / 2])),
            &["cameras.sfm", "invalid JSON", "line"],
        );
        // A rotation that is not one.
        let broken = text.replacen(
            "\"rotation\": [\n",
            "\"rotation\": [\n                        \"2\",\n",
            1,
        );
        has(
            &err(read(&broken)),
            &[
                "poses[0].pose.transform.rotation",
                "expected 9 numbers, found 10",
            ],
        );
    }

    /// The file's landmarks catch a camera read wrongly: observations moved 12 px in one camera
    /// are said, the others not.
    #[test]
    fn landmarks_that_do_not_reproject_are_said() {
        let mut doc: Value = serde_json::from_str(&fixture()).unwrap();
        for landmark in doc["structure"].as_array_mut().unwrap() {
            for obs in landmark["observations"].as_array_mut().unwrap() {
                if obs["observationId"] == "103" {
                    let u: f64 = obs["x"][0].as_str().unwrap().parse().unwrap();
                    obs["x"][0] = Value::String((u + 12.0).to_string());
                }
            }
        }
        let notes = read(&doc.to_string()).unwrap().notes;
        assert_eq!(notes.len(), 2, "{notes:?}");
        has(
            &notes[1],
            &["camera \"cam2\"", "median of 12.0 px", "3 observations"],
        );
    }

    /// What Meshroom writes besides AliceVision's strings: numbers, booleans, −1 for an undefined
    /// id, `fisheye4`; a rotation-only pose left out; the versions whose focal length is
    /// ambiguous refused when the pixels are not square.
    #[test]
    fn meshrooms_own_spellings_are_read() {
        let mut doc: Value = serde_json::from_str(&fixture()).unwrap();
        doc["views"][0]["poseId"] = Value::from(-1);
        doc["views"][1]["intrinsicId"] = Value::from(2);
        doc["views"][3]["isPoseIndependant"] = Value::Bool(true);
        doc["views"][4]["isPoseIndependant"] = Value::Bool(false);
        doc["intrinsics"][3]["distortionType"] = Value::from("fisheye4");
        doc["poses"][1]["pose"]["rotationOnly"] = Value::from("true");
        let read = read(&doc.to_string()).unwrap();
        let names: Vec<&str> = read.cameras.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["cam2", "cam3", "cam4", "cam5"]);
        has(&read.notes[0], &["views[0]", "no pose"]);
        has(&read.notes[1], &["views[1]", "rotation-only"]);
        assert!(matches!(
            read.cameras[1].distortion,
            Some(Distortion::Fisheye { .. })
        ));
        for version in ["9", "10"] {
            let mut doc: Value = serde_json::from_str(&fixture()).unwrap();
            doc["version"][2] = Value::from(version);
            has(
                &err(super::tests::read(&doc.to_string())),
                &[
                    "intrinsics[2].pixelRatio",
                    "1.02",
                    &format!("1.2.{version}"),
                ],
            );
        }
    }

    #[test]
    fn unreconstructed_views_are_left_out_and_said_and_a_file_without_poses_is_refused() {
        let read = read(&fixture()).unwrap();
        assert_eq!(read.cameras.len(), 6);
        assert_eq!(read.notes.len(), 1);
        has(&read.notes[0], &["views[6]", "cam6", "no pose"]);
        let mut doc: Value = serde_json::from_str(&fixture()).unwrap();
        doc["poses"] = Value::Array(Vec::new());
        doc["rigs"] = Value::Array(Vec::new());
        has(
            &err(super::tests::read(&doc.to_string())),
            &[
                "poses",
                "none of the 7 views has a pose",
                "StructureFromMotion",
            ],
        );
    }
}

//! Calibration importers: the camera files users already have (COLMAP sparse models, OpenCV
//! `FileStorage` files, Agisoft Metashape camera XML, nerfstudio / instant-ngp / NeRF
//! `transforms.json`, the TOML files of anipose, Pose2Sim, FreeMoCap and caliscope, Kalibr's
//! `camchain.yaml`, mrcal's `.cameramodel`, AliceVision's (Meshroom's) SfM files, the cameras of
//! an Alembic or USD file) turned into the cameras of a `modelflow-scene/1` file, in our
//! conventions (OpenCV pinhole, pixel centres at integers, world-to-camera `R`, `t`; see
//! `docs/scene-format.md`, "Importing a calibration"). Each reader converts its tool's own
//! conventions and names the file, line and field of anything it cannot use.

mod alembic;
mod alicevision;
mod colmap;
mod import;
mod kalibr;
mod metashape;
mod mrcal;
mod nerfstudio;
mod opencv;
mod rig_toml;
mod scene3d;
mod usd;

pub use alembic::read_alembic;
pub use alicevision::{read_alicevision, AliceVisionCalibration};
pub use colmap::read_colmap;
pub use import::{import_calibration, CalibrationFormat, ImportOptions, Imported};
pub use kalibr::read_kalibr;
pub use metashape::{read_metashape, read_metashape_chunk};
pub use mrcal::read_mrcal;
pub use nerfstudio::{read_nerfstudio, NerfCalibration, NerfWorld};
pub use opencv::read_opencv;
pub use rig_toml::{read_rig_toml, TomlCalibration};
pub use scene3d::{FramePose, SceneCameras};
pub use usd::read_usd;

use crate::base::camera::is_rotation;
use crate::base::lens::Distortion;
use crate::input::scene::{CameraEntry, DistortionEntry, FrameRange, SceneFile, FORMAT};
use nalgebra::{Matrix3, Vector3};

/// One calibrated camera of a rig, as an importer read it.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibratedCamera {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Camera matrix with pixel centres at integer coordinates.
    pub k: Matrix3<f64>,
    /// World to camera: `x = R·X + t`.
    pub r: Matrix3<f64>,
    pub t: Vector3<f64>,
    pub distortion: Option<Distortion>,
    /// Something the user should know about this camera (e.g. "disabled in Metashape"), shown
    /// next to it when it is imported.
    pub note: Option<String>,
}

/// A scene file for `cameras`: the mesh file and frames as given, and each camera's images at
/// `images` with `{camera}` replaced by its name (paths relative to the scene file's folder).
pub fn scene_file(
    cameras: &[CalibratedCamera],
    mesh: &str,
    images: &str,
    first: u32,
    last: u32,
) -> SceneFile {
    let rows = |m: &Matrix3<f64>| [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[(i, j)]));
    SceneFile {
        format: FORMAT.into(),
        frames: FrameRange { first, last },
        mesh: mesh.into(),
        cameras: cameras
            .iter()
            .map(|c| CameraEntry {
                name: c.name.clone(),
                width: c.width,
                height: c.height,
                k: Some(rows(&c.k)),
                r: Some(rows(&c.r)),
                t: Some([c.t.x, c.t.y, c.t.z]),
                poses: None,
                p: None,
                distortion: c.distortion.as_ref().map(|d| DistortionEntry {
                    model: d.model().into(),
                    coefficients: d.coefficients(),
                }),
                frame_offset: 0,
                time_offset: 0.0,
                shutter: 0.0,
                rolling_shutter: 0.0,
                images: images.replace("{camera}", &c.name),
                transfer: Default::default(),
            })
            .collect(),
        ground_truth: None,
        units: None,
    }
}

/// One camera name per image path: the folders holding the images when those all differ
/// (`images/cam0/0000.png` → `cam0`), else the file stems (`cam0_0000.png` → `cam0_0000`); the
/// indices `(first, second)` of two images that name the same camera both ways.
pub(crate) fn names_from_paths(
    files: &[String],
) -> std::result::Result<Vec<String>, (usize, usize)> {
    let part = |f: &String, folder: bool| {
        let p = std::path::Path::new(f.as_str());
        let s = if folder {
            p.parent().and_then(|d| d.file_name())
        } else {
            p.file_stem()
        };
        s.map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    let distinct = |names: &[String]| {
        let mut seen = std::collections::BTreeMap::new();
        for (i, n) in names.iter().enumerate() {
            if n.is_empty() {
                return Err((i, i));
            }
            if let Some(j) = seen.insert(n.as_str(), i) {
                return Err((j, i));
            }
        }
        Ok(())
    };
    let folders: Vec<String> = files.iter().map(|f| part(f, true)).collect();
    if distinct(&folders).is_ok() {
        return Ok(folders);
    }
    let stems: Vec<String> = files.iter().map(|f| part(f, false)).collect();
    distinct(&stems).map(|()| stems)
}

/// The rotation of a quaternion `(w, x, y, z)` (normalised first), or `None` for a zero or
/// non-finite one.
pub(crate) fn quaternion_rotation(w: f64, x: f64, y: f64, z: f64) -> Option<Matrix3<f64>> {
    let q = nalgebra::Quaternion::new(w, x, y, z);
    let n = q.norm();
    (n.is_finite() && n > 1e-12).then(|| {
        nalgebra::UnitQuaternion::from_quaternion(q)
            .to_rotation_matrix()
            .into_inner()
    })
}

/// `text` without a UTF-8 byte-order mark at its start (Windows editors write one).
pub(crate) fn strip_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// `text`, the content of `path`, as JSON (a byte-order mark skipped), or an error naming its
/// line and column.
pub(crate) fn parse_json(
    path: &std::path::Path,
    text: &str,
) -> crate::error::Result<serde_json::Value> {
    serde_json::from_str(strip_bom(text)).map_err(|e| {
        crate::error::Error::invalid(
            path,
            format!("line {} column {}", e.line(), e.column()),
            format!("invalid JSON: {e}"),
        )
    })
}

/// "expected 4 or 5 numbers, found 3": a list of the wrong length, as every reader says it.
pub(crate) fn expected_count(want: &[usize], found: usize) -> String {
    let want: Vec<String> = want.iter().map(|n| n.to_string()).collect();
    format!("expected {} numbers, found {found}", want.join(" or "))
}

/// An image size given as two numbers, if both are whole pixels (at least 1).
pub(crate) fn whole_size(w: f64, h: f64) -> Option<(u32, u32)> {
    let whole = |x: f64| x >= 1.0 && x <= u32::MAX as f64 && x.fract() == 0.0;
    (whole(w) && whole(h)).then_some((w as u32, h as u32))
}

/// The 1-based line of byte `offset` in `text`.
pub(crate) fn line_at(text: &[u8], offset: usize) -> usize {
    text[..offset.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// The camera matrix of focal lengths `fx`, `fy` and principal point `cx`, `cy`, or `None`
/// when a focal length is not positive.
pub(crate) fn pinhole_k(fx: f64, fy: f64, cx: f64, cy: f64) -> Option<Matrix3<f64>> {
    (fx > 0.0 && fy > 0.0).then(|| Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0))
}

/// Whether `r` is a rotation within the scene format's tolerance.
pub(crate) fn check_rotation(r: &Matrix3<f64>) -> bool {
    is_rotation(r, crate::input::scene::ROTATION_TOLERANCE)
}

/// What the importers' tests share: the error of a file that must be refused, and a check that
/// it names every part it should.
#[cfg(test)]
pub(crate) mod testing {
    use super::CalibratedCamera;
    use crate::error::Result;

    pub fn err(r: Result<Vec<CalibratedCamera>>) -> String {
        match r {
            Ok(c) => panic!("should be refused, read {} cameras", c.len()),
            Err(e) => e.to_string(),
        }
    }

    /// `read` on a file named `name` holding `text`, in a folder removed afterwards.
    pub fn read_text<T>(name: &str, text: &str, read: impl FnOnce(&std::path::Path) -> T) -> T {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        read(&p)
    }

    pub fn has(msg: &str, parts: &[&str]) {
        for p in parts {
            assert!(msg.contains(p), "{msg:?} should mention {p:?}");
        }
    }
}

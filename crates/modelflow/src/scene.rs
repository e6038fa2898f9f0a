//! The scene format `modelflow-scene/1` (see `docs/scene-format.md`): reading and validating a
//! scene file, resolving per-frame image and ground-truth paths, loading a frame's images, and
//! writing a scene file (for synthetic footage).

use crate::camera::Camera;
use crate::mesh::Mesh;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The format tag of this version of the scene format.
pub const FORMAT: &str = "modelflow-scene/1";

/// The scene file as it is on disk (serde mirror of the JSON). `Scene::load` turns it into a
/// validated [`Scene`]; synthetic footage builds one and writes it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    pub format: String,
    pub frames: FrameRange,
    pub mesh: String,
    pub cameras: Vec<CameraEntry>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground_truth: Option<String>,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameRange {
    pub first: u32,
    pub last: u32,
}

/// One camera entry: either `K` with `R`,`t` (static) or `poses` (moving), or `P` per frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraEntry {
    pub name: String,
    pub width: u32,
    pub height: u32,
    #[serde(rename = "K", default, skip_serializing_if = "Option::is_none")]
    pub k: Option<[[f64; 3]; 3]>,
    #[serde(rename = "R", default, skip_serializing_if = "Option::is_none")]
    pub r: Option<[[f64; 3]; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poses: Option<Vec<PoseEntry>>,
    #[serde(rename = "P", default, skip_serializing_if = "Option::is_none")]
    pub p: Option<Vec<[[f64; 4]; 3]>>,
    pub images: String,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseEntry {
    pub frame: u32,
    #[serde(rename = "R")]
    pub r: [[f64; 3]; 3],
    pub t: [f64; 3],
}

/// A path pattern in which `{frame}` or `{frame:0N}` stands for the frame number, resolved
/// relative to the scene file's folder.
#[derive(Clone, Debug, PartialEq)]
pub struct FramePattern {
    pub base: PathBuf,
    pub pattern: String,
}

/// A loaded, validated scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The scene file it was read from.
    pub path: PathBuf,
    pub first: u32,
    pub last: u32,
    /// The mesh lined up with frame `first`.
    pub mesh: Mesh,
    pub cameras: Vec<Camera>,
    /// Image pattern of each camera, in the order of `cameras`.
    pub images: Vec<FramePattern>,
    pub ground_truth: Option<FramePattern>,
}

impl Scene {
    pub fn frames(&self) -> std::ops::RangeInclusive<u32> {
        self.first..=self.last
    }

    pub fn dir(&self) -> &Path {
        self.path.parent().unwrap_or(Path::new("."))
    }
}

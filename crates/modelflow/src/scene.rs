//! The scene format `modelflow-scene/1` (see `docs/scene-format.md`): reading and validating a
//! scene file, resolving per-frame image and ground-truth paths, loading a frame's images, and
//! writing a scene file (for synthetic footage).

use crate::camera::Camera;
use crate::mesh::Mesh;
use std::path::{Path, PathBuf};

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

//! The run manifest `run.json`: what made the run (tool version, command, every option as given
//! and as used), on what (the scene's path and a checksum of the inputs), when (start and end,
//! each resumption), and how far it got. It is written when a run starts and when it ends or
//! stops; while it runs, the log is the record of progress.

use crate::error::{Error, Result};
use crate::input::scene::Scene;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The format tag of this version of the manifest.
pub const RUN_FORMAT: &str = "modelflow-run/1";

/// Which method wrote a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The Model Flow tracker (`modelflow track`).
    ModelFlow,
    /// The optical-flow baseline (`modelflow baseline`).
    Baseline,
}

/// Where a run stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Started and not ended (also what a killed run leaves).
    Running,
    /// Every frame is written.
    Complete,
    /// Stopped on request (Ctrl-C); resumable.
    Interrupted,
    /// Stopped by an error; resumable once the cause is fixed, if the inputs did not change.
    Failed,
}

/// The options of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Options {
    /// The options the user set explicitly, as written (e.g. `{"--spring-k": "2"}`).
    pub given: BTreeMap<String, String>,
    /// Every option the method used, defaults and derived values included.
    pub used: serde_json::Value,
}

/// The scene a run tracks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneRecord {
    /// The scene file, as an absolute path when it could be resolved.
    pub path: PathBuf,
    pub first: u32,
    pub last: u32,
    /// `sha256:` of everything tracking depends on (see [`inputs_checksum`]).
    pub checksum: String,
    /// The same over the image files of the frames up to `last_complete` only, as of `ended`
    /// ([`inputs_checksum_upto`]): a run stopped by an image that did not read can be resumed
    /// once that image is repaired, since the frames tracked came from files unchanged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracked_checksum: Option<String>,
}

/// A resumption of the run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Resumption {
    /// When (RFC 3339, UTC).
    pub at: String,
    /// The last frame that was complete then.
    pub from_frame: u32,
    pub command: Vec<String>,
}

/// The manifest `run.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// `modelflow-run/1`.
    pub format: String,
    /// `modelflow <version>`.
    pub tool: String,
    pub method: Method,
    /// The command line that started the run (empty when a program called the library).
    pub command: Vec<String>,
    pub options: Options,
    pub scene: SceneRecord,
    /// When the run started (RFC 3339, UTC).
    pub started: String,
    /// When it last ended or stopped (`None` while running, or after a kill).
    pub ended: Option<String>,
    pub status: Status,
    /// The last frame whose mesh and log line are both written (as of `ended`).
    pub last_complete: Option<u32>,
    /// Frames written, the first (the input mesh) included (as of `ended`).
    pub frames_completed: u32,
    /// Each time the run was continued with `--resume`.
    #[serde(default)]
    pub resumed: Vec<Resumption>,
    /// The tracker's cross-camera check on the last frame's solution, which no next frame's log
    /// line judges (`tracker::health`); `None` for the baseline, a run that did not end
    /// complete, or one written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_frame_check: Option<LastFrameCheck>,
    /// When the scene's mesh lay off the surface the cameras agree on and the tracker moved it
    /// onto it before tracking (`TrackOptions::onto_surface`): what the check found and how far
    /// the vertices moved. The run's first mesh is the moved one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_mesh_moved: Option<crate::tracker::SurfaceMove>,
    /// The shifts of the cameras' images at which they agreed best about the first mesh
    /// (`TrackOptions::shift_cameras`), measured before tracking; the tracker saw every camera
    /// shifted by them when `applied`. `None` for the baseline, with the option off, where no
    /// two cameras compare the mesh, or in a run written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_shifts: Option<crate::tracker::CameraShifts>,
}

/// The cross-camera check on a run's last frame (kept in `last_frame_check`): the verdict the
/// frames-to-check rules read, defined with them.
pub use crate::tracker::health::LastFrameCheck;

impl Manifest {
    /// A manifest for a run of `method` on `scene` starting now.
    pub fn new(
        method: Method,
        scene: &Scene,
        command: Vec<String>,
        options: Options,
    ) -> Result<Self> {
        let path = std::path::absolute(&scene.path).unwrap_or_else(|_| scene.path.clone());
        Ok(Manifest {
            format: RUN_FORMAT.into(),
            tool: format!("modelflow {}", env!("CARGO_PKG_VERSION")),
            method,
            command,
            options,
            scene: SceneRecord {
                path,
                first: scene.first,
                last: scene.last,
                checksum: inputs_checksum(scene)?,
                tracked_checksum: None,
            },
            started: now(),
            ended: None,
            status: Status::Running,
            last_complete: None,
            frames_completed: 0,
            resumed: Vec::new(),
            last_frame_check: None,
            first_mesh_moved: None,
            camera_shifts: None,
        })
    }

    /// Reads a manifest, naming the file and the field at fault.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let m: Manifest = serde_json::from_str(&text).map_err(|e| {
            Error::invalid(
                path,
                format!("line {} column {}", e.line(), e.column()),
                e.to_string(),
            )
        })?;
        if m.format != RUN_FORMAT {
            return Err(Error::invalid(
                path,
                "format",
                format!("expected \"{RUN_FORMAT}\", found {:?}", m.format),
            ));
        }
        Ok(m)
    }

    /// Writes the manifest atomically.
    pub(crate) fn write(&self, path: &Path) -> Result<()> {
        let mut text = serde_json::to_string_pretty(self)
            .map_err(|e| Error::invalid(path, "manifest", e.to_string()))?;
        text.push('\n');
        crate::fsutil::write_atomic(path, text.as_bytes())
    }
}

/// The current time as RFC 3339 in UTC, to the second.
pub(crate) fn now() -> String {
    humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()
}

/// The scene file a run folder's `run.json` names, when it names another file than `scene`
/// (`None` when they are the same file, or the folder has no readable manifest): scoring or
/// reporting a run against a scene it was not made from is allowed (a copy of the shot moved
/// elsewhere), but should be said.
pub fn made_from_another_scene(run: &Path, scene: &Path) -> Option<PathBuf> {
    let m = Manifest::read(&run.join(crate::run::MANIFEST)).ok()?;
    let recorded = m.scene.path;
    let same = crate::fsutil::same_file(&recorded, scene);
    (!same).then_some(recorded)
}

/// A checksum of everything tracking depends on, so that a run is resumed only on the inputs it
/// began with: the frame range, the mesh (positions and triangles), every camera (name, size and
/// projection at every frame) and, for every camera and frame, the image's path relative to the
/// scene and its size in bytes. Image contents are not read (that would cost as much as a run);
/// an image replaced by one of exactly the same size goes unnoticed.
pub fn inputs_checksum(scene: &Scene) -> Result<String> {
    inputs_checksum_upto(scene, scene.last)
}

/// [`inputs_checksum`] with the image files of frames `scene.first..=upto` only (the frame
/// range, the mesh and the cameras in full): what a run that got that far depended on.
pub fn inputs_checksum_upto(scene: &Scene, upto: u32) -> Result<String> {
    let mut h = Sha256::new();
    h.update(b"modelflow-inputs/1\0");
    h.update(scene.first.to_le_bytes());
    h.update(scene.last.to_le_bytes());
    let m = &scene.mesh;
    h.update((m.positions.len() as u64).to_le_bytes());
    for p in &m.positions {
        for c in [p.x, p.y, p.z] {
            h.update(c.to_bits().to_le_bytes());
        }
    }
    h.update((m.triangles.len() as u64).to_le_bytes());
    for t in &m.triangles {
        for v in t {
            h.update(v.to_le_bytes());
        }
    }
    for (cam, pattern) in scene.cameras.iter().zip(&scene.images) {
        h.update(cam.name.as_bytes());
        h.update([0]);
        h.update(cam.width.to_le_bytes());
        h.update(cam.height.to_le_bytes());
        for frame in scene.frames() {
            for v in cam.at(frame).matrix().iter() {
                h.update(v.to_bits().to_le_bytes());
            }
            if frame > upto {
                continue;
            }
            let path = pattern.path(frame);
            let size = std::fs::metadata(&path)
                .map_err(|e| Error::io(&path, e))?
                .len();
            let rel = path.strip_prefix(scene.dir()).unwrap_or(&path);
            h.update(rel.to_string_lossy().as_bytes());
            h.update([0]);
            h.update(size.to_le_bytes());
        }
    }
    let digest = h.finalize();
    let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    Ok(format!("sha256:{hex}"))
}

//! Opening a run folder for writing, by the rules that keep users' files safe:
//!
//! * a folder that does not exist, or is empty, gets a new run;
//! * a folder holding a run of the same scene is refused unless the run is resumed (`Resume`)
//!   or replaced (`Force`), so two runs are never mixed in one folder;
//! * a folder holding anything else (another scene's run, a ground truth, a user's files) is
//!   refused unless `Force`, and `Force` removes only files of the run-folder layout
//!   (`layout::is_layout_file`): everything else in the folder stays as it was.
//!
//! A frame is *complete* when its mesh and its log line are both written (mesh first). Resuming
//! drops what lies past the last complete frame (a torn log line, a mesh without its line) and
//! any temporary file a crash left.

use super::layout::{self, confidence_file, frame_file, LOG, MANIFEST};
use super::log::{read_log, FrameLog, LogWriter};
use super::manifest::{
    inputs_checksum_upto, now, LastFrameCheck, Manifest, Method, Options, Resumption, SceneRecord,
    Status,
};
use crate::base::mesh::Mesh;
use crate::error::{Error, Result};
use crate::input::meshio::{read_mesh_with, Checks};
use crate::input::scene::Scene;
use crate::tracker::VertexConfidence;
use nalgebra::Point3;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// How to treat a folder that already holds files.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OpenMode {
    /// Only an empty or new folder (the default).
    #[default]
    New,
    /// Continue the run of the same scene and options in the folder from its last complete
    /// frame (a new run if the folder is empty).
    Resume,
    /// Replace the run-folder files in the folder (frame meshes, log, manifest); leave every
    /// other file alone.
    Force,
}

/// How a run is written, besides the method's own options.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// What to do with a folder that already holds files.
    pub mode: OpenMode,
    /// The command line, for the manifest (empty when a program calls the library).
    pub command: Vec<String>,
    /// The options the user set explicitly, as written, for the manifest.
    pub given: BTreeMap<String, String>,
    /// When set (e.g. by a Ctrl-C handler), the run stops within one solver iteration; the
    /// frame being solved is abandoned and the folder stays resumable.
    pub cancel: Option<Arc<AtomicBool>>,
    /// When set, the tracker's per-pixel work runs on this GPU (`--device gpu`).
    pub gpu: Option<Arc<crate::tracker::Gpu>>,
    /// The first-mesh check (`tracker::first_mesh_check`) the caller already made on the
    /// scene's mesh, cameras and first frame (`track` makes it to warn before tracking): the
    /// tracker moves a mesh off the surface onto it from this instead of measuring again. It
    /// must be of the same scene (mesh, cameras, first frame's images); `None`: measured.
    pub first_mesh_check: Option<crate::tracker::FirstMeshCheck>,
}

impl RunOptions {
    /// Whether the run was asked to stop.
    pub fn cancelled(&self) -> bool {
        self.cancel
            .as_ref()
            .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
    }
}

/// Refuses a run folder the scene reads its own frames from: its ground truth's folder (whose
/// `NNNN.obj` files a run would replace, even with `--force`, which replaces frame meshes) or a
/// camera's image folder. Compared as resolved paths, so `truth/` and `./x/../truth` match.
fn refuse_scene_inputs(dir: &Path, scene: &Scene) -> Result<()> {
    let Ok(out) = std::fs::canonicalize(dir) else {
        return Ok(()); // not there yet: a new folder holds nothing of the scene
    };
    let folder_of = |p: PathBuf| {
        p.parent()
            .map(|d| {
                if d.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    d
                }
            })
            .and_then(|d| std::fs::canonicalize(d).ok())
    };
    if let Some(g) = &scene.ground_truth {
        if folder_of(g.path(scene.first)).is_some_and(|d| d == out) {
            return Err(Error::run_folder(
                dir,
                "is the scene's ground-truth folder: a run there would replace the truth's \
                 frame meshes; choose another folder",
            ));
        }
    }
    for (cam, pattern) in scene.cameras.iter().zip(&scene.images) {
        if !pattern.is_video() && folder_of(pattern.path(scene.first)).is_some_and(|d| d == out) {
            return Err(Error::run_folder(
                dir,
                format!(
                    "is camera {}'s image folder: the run's files would mix with its frames; \
                     choose another folder",
                    cam.name
                ),
            ));
        }
    }
    Ok(())
}

/// A run folder open for writing.
pub struct RunFolder {
    dir: PathBuf,
    manifest: Manifest,
    log: LogWriter,
    last_complete: Option<u32>,
}

/// Writes a run of `method` on `scene` into `dir`: opens the folder by the rules of `run.mode`
/// with a manifest of the options `used`, runs `body` on it (given the last complete frame when
/// resuming), and records in the manifest how it ended: complete, interrupted (the body returned
/// `Error::Interrupted`, which then names the folder's last complete frame) or failed.
pub fn write_run<T>(
    dir: &Path,
    method: Method,
    scene: &Scene,
    used: &impl serde::Serialize,
    run: &RunOptions,
    body: impl FnOnce(&mut RunFolder, Option<u32>) -> Result<T>,
) -> Result<T> {
    let used =
        serde_json::to_value(used).map_err(|e| Error::invalid(dir, "options", e.to_string()))?;
    let options = Options {
        given: run.given.clone(),
        used,
    };
    refuse_scene_inputs(dir, scene)?;
    let manifest = Manifest::new(method, scene, run.command.clone(), options)?;
    let Opened {
        mut folder,
        resumed,
    } = RunFolder::open(dir, manifest, run.mode, scene)?;
    let result = body(&mut folder, resumed);
    let status = match &result {
        Ok(_) => Status::Complete,
        Err(Error::Interrupted { .. }) => Status::Interrupted,
        Err(_) => Status::Failed,
    };
    // What the frames written were made from (an image that cannot be read now is not among
    // them: the run stops before the frame that needs it). Only a run that can be resumed
    // needs it; a complete one's is its `checksum`.
    if status != Status::Complete {
        folder.manifest.scene.tracked_checksum = folder
            .last_complete
            .and_then(|l| inputs_checksum_upto(scene, l).ok());
    }
    let finished = folder.finish(status);
    match result {
        Ok(value) => finished.map(|()| value),
        Err(Error::Interrupted { .. }) => Err(Error::Interrupted {
            last_complete: folder.last_complete.unwrap_or(scene.first),
        }),
        Err(e) => Err(e),
    }
}

/// What an opened folder already holds.
pub struct Opened {
    pub folder: RunFolder,
    /// When resuming: the last complete frame.
    pub resumed: Option<u32>,
}

impl RunFolder {
    /// Opens `dir` for the run `manifest` describes, by the rules of `mode` (see the module
    /// documentation). Refusals are `Error::RunFolder` with the reason and what to do.
    pub fn open(dir: &Path, manifest: Manifest, mode: OpenMode, scene: &Scene) -> Result<Opened> {
        let mut manifest = manifest;
        if dir.exists() && !dir.is_dir() {
            return Err(Error::run_folder(dir, "exists and is not a folder"));
        }
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let listing = Listing::read(dir)?;
        let existing = if listing.has_manifest {
            Some(Manifest::read(&dir.join(MANIFEST))?)
        } else {
            None
        };
        // The same inputs, or (a run that stopped part-way) the same inputs for the frames it
        // tracked: an image of a later frame repaired or replaced since is what it needs.
        let same_scene = existing.as_ref().is_some_and(|m| {
            m.method == manifest.method
                && (m.scene.checksum == manifest.scene.checksum
                    || (m.scene.first, m.scene.last) == (scene.first, scene.last)
                        && m.status != Status::Complete
                        && m.scene
                            .tracked_checksum
                            .as_ref()
                            .zip(m.last_complete)
                            .is_some_and(|(c, l)| {
                                inputs_checksum_upto(scene, l).is_ok_and(|now| &now == c)
                            }))
        });
        let mut resumed = None;
        match mode {
            OpenMode::Force => listing.remove_layout(dir)?,
            OpenMode::New | OpenMode::Resume if listing.is_empty() => listing.remove_layout(dir)?,
            OpenMode::New => {
                return Err(Error::run_folder(
                    dir,
                    refusal(&listing, &existing, same_scene, &manifest),
                ))
            }
            OpenMode::Resume => {
                let Some(old) = existing.clone().filter(|_| same_scene) else {
                    return Err(Error::run_folder(
                        dir,
                        format!(
                            "{}, so there is nothing to resume; choose another folder, or add \
                             --force to replace the run files in this one",
                            refusal_reason(&listing, &existing, &manifest)
                        ),
                    ));
                };
                if old.options.used != manifest.options.used {
                    return Err(Error::run_folder(
                        dir,
                        format!(
                            "the run was made with other options ({}; it was started with: {}); \
                             resume it with the same options, or add --force to start it again",
                            differences(&old.options.used, &manifest.options.used),
                            old.options
                                .given
                                .iter()
                                .map(|(k, v)| match v.as_str() {
                                    "true" => k.clone(),
                                    _ => format!("{k} {v}"),
                                })
                                .collect::<Vec<_>>()
                                .join(" ")
                        ),
                    ));
                }
                let last = truncate_to_complete(dir, &old)?;
                listing.remove_temporaries(dir)?;
                let command = std::mem::take(&mut manifest.command);
                // From here on the run is made from the inputs as they are now.
                let scene_record = SceneRecord {
                    checksum: manifest.scene.checksum.clone(),
                    tracked_checksum: None,
                    ..old.scene.clone()
                };
                manifest = Manifest {
                    status: Status::Running,
                    ended: None,
                    scene: scene_record,
                    ..old
                };
                manifest.resumed.push(Resumption {
                    at: now(),
                    from_frame: last.unwrap_or(manifest.scene.first),
                    command,
                });
                resumed = last;
            }
        }
        manifest.write(&dir.join(MANIFEST))?;
        let log = LogWriter::append_to(&dir.join(LOG))?;
        let last_complete = resumed;
        Ok(Opened {
            folder: RunFolder {
                dir: dir.to_path_buf(),
                manifest,
                log,
                last_complete,
            },
            resumed,
        })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// The last frame whose mesh and log line are both written.
    pub fn last_complete(&self) -> Option<u32> {
        self.last_complete
    }

    /// Writes the first frame: the input mesh, with no log line (nothing was solved).
    pub fn write_first(&mut self, mesh: &Mesh) -> Result<()> {
        let first = self.manifest.scene.first;
        crate::input::meshio::write_obj(&self.dir.join(frame_file(first)), mesh)?;
        self.last_complete = Some(first);
        Ok(())
    }

    /// Writes a solved frame's mesh (atomically). The frame is complete once its log line is
    /// appended too ([`RunFolder::append`]).
    pub fn write_mesh(&mut self, frame: u32, mesh: &Mesh) -> Result<()> {
        crate::input::meshio::write_obj(&self.dir.join(frame_file(frame)), mesh)
    }

    /// Writes a solved frame's per-vertex confidence (atomically), before its mesh.
    pub fn write_confidence(&mut self, frame: u32, confidence: &[VertexConfidence]) -> Result<()> {
        layout::write_confidence(&self.dir.join(confidence_file(frame)), confidence)
    }

    /// Appends a solved frame's log line, after its mesh: the frame is complete.
    pub fn append(&mut self, line: &FrameLog) -> Result<()> {
        self.log.append(line)?;
        self.last_complete = Some(line.frame);
        Ok(())
    }

    /// A complete frame's per-vertex confidence as written (exactly: its numbers are written in
    /// their shortest round-trip form); `None` when the frame has no confidence file (a frame in
    /// which no pixel was compared).
    pub fn read_confidence(&self, frame: u32) -> Result<Option<Vec<VertexConfidence>>> {
        let path = self.dir.join(confidence_file(frame));
        if !path.exists() {
            return Ok(None);
        }
        layout::read_confidence(&path).map(Some)
    }

    /// The positions of a complete frame's mesh, as written (exactly: OBJ numbers are written
    /// in their shortest round-trip form).
    pub fn read_positions(&self, frame: u32) -> Result<Vec<Point3<f64>>> {
        let path = self.dir.join(frame_file(frame));
        Ok(read_mesh_with(&path, Checks::Structure)?.positions)
    }

    /// Records the tracker's check on the last frame, written into the manifest when the run
    /// finishes.
    pub fn record_last_frame_check(&mut self, check: LastFrameCheck) {
        self.manifest.last_frame_check = Some(check);
    }

    /// Records in the manifest that the tracker moved the first mesh onto the surface, and
    /// writes the manifest now (a run killed before it ends still says so).
    pub fn record_first_mesh_moved(&mut self, moved: crate::tracker::SurfaceMove) -> Result<()> {
        self.manifest.first_mesh_moved = Some(moved);
        self.manifest.write(&self.dir.join(MANIFEST))
    }

    /// Records in the manifest the shifts of the cameras' images at which they agreed best
    /// about the first mesh (`TrackOptions::shift_cameras`), and writes the manifest now.
    pub fn record_camera_shifts(&mut self, shifts: crate::tracker::CameraShifts) -> Result<()> {
        self.manifest.camera_shifts = Some(shifts);
        self.manifest.write(&self.dir.join(MANIFEST))
    }

    /// Records how the run ended in the manifest.
    pub fn finish(&mut self, status: Status) -> Result<()> {
        self.manifest.status = status;
        self.manifest.ended = Some(now());
        self.manifest.last_complete = self.last_complete;
        self.manifest.frames_completed = self
            .last_complete
            .map_or(0, |l| l - self.manifest.scene.first + 1);
        self.manifest.write(&self.dir.join(MANIFEST))
    }
}

/// What a folder holds, sorted into the layout's files and the others.
struct Listing {
    layout: Vec<String>,
    other: Vec<String>,
    has_manifest: bool,
}

impl Listing {
    fn read(dir: &Path) -> Result<Self> {
        let mut l = Listing {
            layout: Vec::new(),
            other: Vec::new(),
            has_manifest: false,
        };
        for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
            let entry = entry.map_err(|e| Error::io(dir, e))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let is_file = entry.file_type().map_err(|e| Error::io(dir, e))?.is_file();
            if is_file && layout::is_layout_file(&name) {
                l.has_manifest |= name == MANIFEST;
                l.layout.push(name);
            } else {
                l.other.push(name);
            }
        }
        l.layout.sort();
        l.other.sort();
        Ok(l)
    }

    /// Nothing but temporaries a crash left.
    fn is_empty(&self) -> bool {
        self.other.is_empty() && self.layout.iter().all(|n| layout::layout_temporary(n))
    }

    fn remove_layout(&self, dir: &Path) -> Result<()> {
        for name in &self.layout {
            let p = dir.join(name);
            std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
        }
        Ok(())
    }

    fn remove_temporaries(&self, dir: &Path) -> Result<()> {
        for name in self.layout.iter().filter(|n| layout::layout_temporary(n)) {
            let p = dir.join(name);
            std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
        }
        Ok(())
    }
}

/// Why a folder is refused for a new run, and what to do.
fn refusal(
    listing: &Listing,
    existing: &Option<Manifest>,
    same_scene: bool,
    new: &Manifest,
) -> String {
    if same_scene {
        let m = existing.as_ref().expect("same scene implies a manifest");
        let done = match m.status {
            Status::Complete => "complete".to_string(),
            _ => "not complete".to_string(),
        };
        return format!(
            "holds a run of this scene ({done}, started {}); add --resume to continue it or \
             --force to replace it",
            m.started
        );
    }
    format!(
        "{}; choose an empty folder, or add --force to replace the run files in it (frame \
         meshes NNNN.obj, {LOG}, {MANIFEST}; other files are kept)",
        refusal_reason(listing, existing, new)
    )
}

fn refusal_reason(listing: &Listing, existing: &Option<Manifest>, new: &Manifest) -> String {
    if let Some(m) = existing.as_ref().filter(|m| m.method == new.method) {
        // The same scene file: say what differs, rather than call it another scene.
        if crate::fsutil::same_file(&m.scene.path, &new.scene.path) {
            return if (m.scene.first, m.scene.last) != (new.scene.first, new.scene.last) {
                format!(
                    "holds a run of this scene for frames {}..{}, not {}..{} (repeat the run's --frames to continue it)",
                    m.scene.first, m.scene.last, new.scene.first, new.scene.last
                )
            } else {
                "holds a run of this scene made from other inputs: the mesh, a camera, or the size of an image file of a frame it tracked has changed since it started, so its frames would not match a continuation"
                    .to_string()
            };
        }
    }
    if let Some(m) = existing {
        return format!(
            "holds a {} run of another scene ({})",
            match m.method {
                super::Method::ModelFlow => "Model Flow",
                super::Method::Baseline => "baseline",
            },
            m.scene.path.display()
        );
    }
    let names: Vec<&String> = listing.layout.iter().chain(&listing.other).collect();
    let shown: Vec<&str> = names.iter().take(3).map(|s| s.as_str()).collect();
    format!(
        "holds {} file(s) that are not a modelflow run ({}{})",
        names.len(),
        shown.join(", "),
        if names.len() > 3 { ", ..." } else { "" }
    )
}

/// Where two option sets differ, as `path: old -> new` (dotted paths to the leaves).
fn differences(old: &serde_json::Value, new: &serde_json::Value) -> String {
    fn walk(
        path: &str,
        a: Option<&serde_json::Value>,
        b: Option<&serde_json::Value>,
        out: &mut Vec<String>,
    ) {
        match (a, b) {
            (Some(serde_json::Value::Object(x)), Some(serde_json::Value::Object(y))) => {
                let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
                keys.sort();
                keys.dedup();
                for k in keys {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    walk(&p, x.get(k), y.get(k), out);
                }
            }
            (a, b) if a != b => {
                let show =
                    |v: Option<&serde_json::Value>| v.map_or("none".into(), |v| v.to_string());
                out.push(format!("{path}: {} -> {}", show(a), show(b)));
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk("", Some(old), Some(new), &mut out);
    out.join("; ")
}

/// Finds the last complete frame of the run in `dir` (mesh and log line written, every frame
/// before it too), cuts the log to it and removes the meshes past it. Returns it (`None` if not
/// even the first frame was written).
fn truncate_to_complete(dir: &Path, m: &Manifest) -> Result<Option<u32>> {
    let log_path = dir.join(LOG);
    let read = read_log(&log_path)?;
    let first = m.scene.first;
    let has_mesh = |f: u32| dir.join(frame_file(f)).is_file();
    let mut last = has_mesh(first).then_some(first);
    let mut kept = 0;
    if last.is_some() {
        for (i, line) in read.lines.iter().enumerate() {
            // (Frame numbers are checked, not wrapped: the last one may be u32::MAX.)
            let Some(expected) = u32::try_from(i)
                .ok()
                .and_then(|i| first.checked_add(1)?.checked_add(i))
            else {
                break;
            };
            if line.frame != expected || expected > m.scene.last || !has_mesh(expected) {
                break;
            }
            last = Some(expected);
            kept = i + 1;
        }
    }
    // The byte length of the first `kept` lines.
    let text = std::fs::read(&log_path).unwrap_or_default();
    let keep_len = if kept == 0 {
        0
    } else {
        text.iter()
            .enumerate()
            .filter(|(_, &c)| c == b'\n')
            .nth(kept - 1)
            .map_or(read.valid_len, |(i, _)| i as u64 + 1)
    };
    if (text.len() as u64) != keep_len {
        let f = std::fs::OpenOptions::new()
            .write(true)
            .open(&log_path)
            .map_err(|e| Error::io(&log_path, e))?;
        f.set_len(keep_len).map_err(|e| Error::io(&log_path, e))?;
    }
    // Meshes past the last complete frame belong to the interrupted frame(s).
    let from = match last {
        None => Some(first),
        Some(l) => l.checked_add(1),
    };
    for f in from.into_iter().flat_map(|from| from..=m.scene.last) {
        for p in [dir.join(frame_file(f)), dir.join(confidence_file(f))] {
            if p.is_file() {
                std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
            }
        }
    }
    Ok(last)
}

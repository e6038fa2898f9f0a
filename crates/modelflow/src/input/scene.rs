//! The scene format `modelflow-scene/1` (see `docs/scene-format.md`): reading and validating a
//! scene file, resolving per-frame image and ground-truth paths, loading a frame's images, and
//! writing a scene file (for synthetic footage).

use crate::base::camera::{is_rotation, Camera, Projection, ProjectionError};
use crate::base::image::RgbImage;
use crate::base::lens::{Distortion, Lens, UndistortMap};
use crate::base::mesh::Mesh;
use crate::base::units::Units;
use crate::error::{Error, Result};
use crate::fsutil::{not_a_file, require_file, write_atomic};
use crate::input::imageio::{image_size, read_rgb_stored};
use crate::input::meshio::read_mesh;
use crate::input::transfer::{encode_linear, Transfer};
use crate::input::video::{is_video, VideoReader, VIDEO_EXTENSIONS};
use nalgebra::{Matrix3, Matrix3x4, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

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
    /// The unit of the world coordinates (`m`, `cm` or `mm`); lengths are then shown in mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units: Option<Units>,
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
    /// Lens distortion of the frames (with `K`; see `docs/scene-format.md`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion: Option<DistortionEntry>,
    /// This camera's image of scene frame `f` is its file number `f + frame_offset` (for rigs
    /// whose cameras were not started together).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub frame_offset: i64,
    /// When this camera records each frame, in frames after the frame's time (−1 to 1; for
    /// rigs that are not genlocked: a camera 5 ms late at 30 fps has 0.15). The tracker
    /// compensates it along the surface's velocity.
    #[serde(default, skip_serializing_if = "is_zero_f64")]
    pub time_offset: f64,
    /// How long this camera's shutter stays open, as a fraction of a frame (0 to 1; 0.5 is a
    /// 180° shutter; 0, the default: sharp images). The tracker compares templates and frames
    /// under the smear their motion gives both.
    #[serde(default, skip_serializing_if = "is_zero_f64")]
    pub shutter: f64,
    /// A rolling shutter's readout, in frames from the top row to the bottom row (0 to 1; 0,
    /// the default: a global shutter). Row `y` is recorded at `time_offset +
    /// rolling_shutter·((y + 0.5)/height − 1/2)`; the tracker sees each vertex at its row's
    /// instant.
    #[serde(default, skip_serializing_if = "is_zero_f64")]
    pub rolling_shutter: f64,
    pub images: String,
    /// What the stored values are: `"auto"` (floating-point images scene-linear, integer ones
    /// encoded), `"linear"` or `"encoded"` (`input::transfer`).
    #[serde(default, skip_serializing_if = "Transfer::is_auto")]
    pub transfer: Transfer,
}

fn is_zero(v: &i64) -> bool {
    *v == 0
}

fn is_zero_f64(v: &f64) -> bool {
    *v == 0.0
}

/// A camera's lens distortion as written in the scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistortionEntry {
    /// `"opencv"` or `"fisheye"`.
    pub model: String,
    /// As OpenCV orders them.
    pub coefficients: Vec<f64>,
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
    /// Added to the frame number before it is put into the pattern (or, for a video, before
    /// the frame is read from it).
    pub offset: i64,
    /// The pattern is one video file holding every frame (see `input::video`).
    pub video: bool,
    /// What the stored values are (scene-linear ones are encoded at load).
    pub transfer: Transfer,
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
    /// The unit of the world coordinates, when the scene file gives it.
    pub units: Option<Units>,
    /// Per camera, the resampling from its raw (distorted) frames to pinhole ones; `None` for a
    /// camera without distortion.
    pub undistort: Vec<Option<std::sync::Arc<UndistortMap>>>,
    /// Per camera, the reader of its video file (`None`: image files).
    pub videos: Vec<Option<Arc<Mutex<VideoReader>>>>,
}

impl Scene {
    pub fn frames(&self) -> std::ops::RangeInclusive<u32> {
        self.first..=self.last
    }

    pub fn dir(&self) -> &Path {
        self.path.parent().unwrap_or(Path::new("."))
    }

    /// Bytes of memory tracking this scene needs, about: [`BYTES_PER_PIXEL`] per pixel of every
    /// camera (the images, their pyramids, the templates, the next frame read ahead), plus
    /// [`LENS_BYTES_PER_PIXEL`] for a camera with a lens, plus the mesh.
    pub fn memory_estimate(&self) -> u64 {
        let pixels: u64 = self
            .cameras
            .iter()
            .map(|c| {
                let px = c.width as u64 * c.height as u64;
                px * (BYTES_PER_PIXEL
                    + if c.lens.is_some() {
                        LENS_BYTES_PER_PIXEL
                    } else {
                        0
                    })
            })
            .sum();
        pixels + self.mesh.positions.len() as u64 * 4096 + 32 * 1024 * 1024
    }

    /// The cameras that see none of the mesh at the first frame, each with why
    /// ([`blind_cameras`]).
    pub fn blind_cameras(&self) -> Vec<BlindCamera> {
        blind_cameras(&self.cameras, self.first, &self.mesh)
    }

    /// The cameras whose principal point at the first frame lies far from the image's centre
    /// ([`off_centre_principal_points`]): a `K` made at another resolution than the footage's.
    pub fn off_centre_principal_points(&self) -> Vec<OffCentre> {
        off_centre_principal_points(&self.cameras, self.first)
    }

    /// The cameras whose image file at the first frame asks viewers to turn or mirror it (its
    /// EXIF orientation: a phone's or a camera's JPEG shot upright). modelflow reads the pixels as
    /// stored, as PIL's `Image.open` does; OpenCV's `imread` and photo viewers turn them, and a
    /// calibration made on those does not fit the stored pixels (turned 180°, even the size
    /// agrees).
    pub fn turned_images(&self) -> Vec<TurnedImages> {
        self.cameras
            .iter()
            .zip(&self.images)
            .enumerate()
            .filter(|(_, (_, pat))| !pat.video)
            .filter_map(|(index, (cam, pat))| {
                let file = pat.path(self.first);
                crate::input::imageio::image_orientation(&file).map(|turn| TurnedImages {
                    index,
                    name: cam.name.clone(),
                    file,
                    turn,
                })
            })
            .collect()
    }

    /// The mesh's size in the images at the first frame when it is too small to track or many
    /// times the images ([`mesh_out_of_scale`]): a mesh in another unit than the calibration.
    pub fn mesh_out_of_scale(&self) -> Option<MeshOutOfScale> {
        mesh_out_of_scale(&self.cameras, self.first, &self.mesh)
    }

    /// Refuses a scene whose [`Scene::memory_estimate`] exceeds `limit` bytes, before anything
    /// is allocated, saying how much it would need (`option` names the setting that raises the
    /// limit).
    pub fn check_memory(&self, limit: u64, option: &str) -> Result<()> {
        let need = self.memory_estimate();
        if need <= limit {
            return Ok(());
        }
        let size = |b: u64| {
            if b < 1 << 30 {
                format!("{:.0} MiB", b as f64 / (1u64 << 20) as f64)
            } else {
                format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64)
            }
        };
        let sizes: Vec<String> = self
            .cameras
            .iter()
            .map(|c| format!("{}x{}", c.width, c.height))
            .collect();
        Err(Error::option(
            option,
            size(limit),
            format!(
                "at least {}: tracking {} camera(s) of {} needs about that much ({BYTES_PER_PIXEL} bytes per pixel); raise {option} if the machine has the memory, or use smaller images or fewer cameras",
                size(need),
                self.cameras.len(),
                sizes.join(", "),
            ),
        ))
    }

    /// The same scene over frames `first..=last` only (within the scene's frames), with its mesh
    /// taken as lined up with frame `first`: what `track --frames A..B` runs on. At least two
    /// cameras must see the mesh at `first`.
    pub fn with_frames(&self, first: u32, last: u32) -> Result<Scene> {
        if first > last || first < self.first || last > self.last {
            return Err(Error::option(
                "--frames",
                format!("{first}..{last}"),
                format!(
                    "A..B with {} <= A <= B <= {} (the frames of {})",
                    self.first,
                    self.last,
                    self.path.display()
                ),
            ));
        }
        check_seen(&self.path, &self.cameras, first, &self.mesh)?;
        Ok(Scene {
            first,
            last,
            ..self.clone()
        })
    }

    /// The same scene with another mesh file as the mesh lined up with frame `first` (e.g. the
    /// last mesh of an earlier run, to go on from there). The ground truth, if any, must have its
    /// vertex count.
    pub fn with_mesh(&self, mesh: &Path) -> Result<Scene> {
        let m = read_mesh(mesh)?;
        if self.ground_truth.is_some() && m.positions.len() != self.mesh.positions.len() {
            return Err(Error::invalid(
                mesh,
                "vertices",
                format!(
                    "{} vertices, but the scene's mesh and ground truth have {}",
                    m.positions.len(),
                    self.mesh.positions.len()
                ),
            ));
        }
        check_seen(&self.path, &self.cameras, self.first, &m)?;
        Ok(Scene {
            mesh: m,
            ..self.clone()
        })
    }

    /// The same scene with only the named cameras, in the order named: what `track --cameras`
    /// runs on. Every name must be a camera of the scene, none twice, and at least two of them
    /// must see the mesh at the first frame.
    pub fn with_cameras(&self, names: &[String]) -> Result<Scene> {
        let picked = pick_cameras(&self.cameras, names)?;
        let cameras: Vec<Camera> = picked.iter().map(|&i| self.cameras[i].clone()).collect();
        check_seen(&self.path, &cameras, self.first, &self.mesh)?;
        Ok(Scene {
            cameras,
            images: picked.iter().map(|&i| self.images[i].clone()).collect(),
            undistort: picked.iter().map(|&i| self.undistort[i].clone()).collect(),
            videos: picked.iter().map(|&i| self.videos[i].clone()).collect(),
            ..self.clone()
        })
    }
}

/// What part of a scene file to load ([`Scene::load_selected`]): `None` is all of it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Selection {
    /// Only these cameras, by name, in this order (`--cameras`).
    pub cameras: Option<Vec<String>>,
    /// Only frames `A..=B`, within the scene's; the mesh is taken as lined up with `A`
    /// (`--frames`).
    pub frames: Option<(u32, u32)>,
}

/// The places in `cameras` of the `names` (`--cameras`), in the order named: each must be a
/// camera's name, and named once.
fn pick_cameras(cameras: &[Camera], names: &[String]) -> Result<Vec<usize>> {
    let all: Vec<&str> = cameras.iter().map(|c| c.name.as_str()).collect();
    let mut picked: Vec<usize> = Vec::with_capacity(names.len());
    for n in names {
        let i = all.iter().position(|c| c == n).ok_or_else(|| {
            Error::option(
                "--cameras",
                n,
                format!("names of the scene's cameras: {}", all.join(", ")),
            )
        })?;
        if picked.contains(&i) {
            return Err(Error::option("--cameras", n, "each camera named once"));
        }
        picked.push(i);
    }
    Ok(picked)
}

impl FramePattern {
    /// A pattern relative to `base`; fails (with the reason) unless it holds at least one
    /// `{frame}` or `{frame:0N}` placeholder and no other `{`/`}`.
    pub fn new(base: impl Into<PathBuf>, pattern: impl Into<String>) -> Result<Self, String> {
        let pattern = pattern.into();
        let pieces = split_pattern(&pattern)?;
        let video = is_video(Path::new(&pattern));
        if !video && !pieces.iter().any(|p| matches!(p, Piece::Frame(_))) {
            return Err(format!(
                "{pattern:?} has no {{frame}} or {{frame:0N}} placeholder (and is not a video file: {})",
                VIDEO_EXTENSIONS.join(", ")
            ));
        }
        if video && pieces.iter().any(|p| matches!(p, Piece::Frame(_))) {
            return Err(format!(
                "{pattern:?} is a video file name: it holds every frame, so it takes no {{frame}} placeholder"
            ));
        }
        Ok(FramePattern {
            base: base.into(),
            pattern,
            offset: 0,
            video,
            transfer: Transfer::Auto,
        })
    }

    /// The same pattern reading file number `frame + offset` for `frame`.
    pub fn with_offset(self, offset: i64) -> Self {
        FramePattern { offset, ..self }
    }

    /// The same pattern whose values are `transfer`.
    pub fn with_transfer(self, transfer: Transfer) -> Self {
        FramePattern { transfer, ..self }
    }

    /// Whether the frames are a video file's (every frame's [`FramePattern::path`] is that file).
    pub fn is_video(&self) -> bool {
        self.video
    }

    /// The file of `frame`: `{frame}` becomes the plain number `frame + offset`, `{frame:0N}`
    /// that number zero-padded to `N` digits; relative patterns are joined to `base`. (The scene
    /// reader refuses offsets that make a used frame's number negative.)
    pub fn path(&self, frame: u32) -> PathBuf {
        if self.video {
            return self.base.join(&self.pattern);
        }
        let frame = frame as i64 + self.offset;
        let mut s = String::with_capacity(self.pattern.len() + 8);
        match split_pattern(&self.pattern) {
            Ok(pieces) => {
                for p in pieces {
                    match p {
                        Piece::Text(t) => s.push_str(t),
                        Piece::Frame(w) => s.push_str(&format!("{frame:0w$}")),
                    }
                }
            }
            // Not a valid pattern (built by hand): used as it is.
            Err(_) => s.push_str(&self.pattern),
        }
        self.base.join(s)
    }
}

enum Piece<'a> {
    Text(&'a str),
    /// Zero-padding width (0 = plain).
    Frame(usize),
}

fn split_pattern(p: &str) -> Result<Vec<Piece<'_>>, String> {
    let mut out = Vec::new();
    let mut rest = p;
    while let Some(open) = rest.find(['{', '}']) {
        if rest.as_bytes()[open] == b'}' {
            return Err(format!("{p:?}: unmatched `}}`"));
        }
        if open > 0 {
            out.push(Piece::Text(&rest[..open]));
        }
        let close = rest[open..]
            .find('}')
            .ok_or_else(|| format!("{p:?}: unclosed `{{`"))?
            + open;
        let inner = &rest[open + 1..close];
        let width = if inner == "frame" {
            0
        } else if let Some(w) = inner.strip_prefix("frame:0") {
            w.parse::<usize>()
                .ok()
                .filter(|&w| (1..=32).contains(&w))
                .ok_or_else(|| {
                    format!("{p:?}: bad placeholder {{{inner}}} (expected {{frame}} or {{frame:0N}}, N from 1 to 32)")
                })?
        } else {
            return Err(format!(
                "{p:?}: unknown placeholder {{{inner}}} (expected {{frame}} or {{frame:0N}})"
            ));
        };
        out.push(Piece::Frame(width));
        rest = &rest[close + 1..];
    }
    if !rest.is_empty() {
        out.push(Piece::Text(rest));
    }
    Ok(out)
}

/// Tolerance on `RᵀR = I` and `det R = 1` (Blender and other tools write float32 rotations).
pub const ROTATION_TOLERANCE: f64 = 1e-4;

/// Memory the tracker needs per pixel of a camera, measured (peak resident memory over pixels:
/// 86 bytes on the four 1280×720 webcams of `caliscope-board-sample`), rounded up.
pub const BYTES_PER_PIXEL: u64 = 100;

/// Extra memory per pixel of a camera with a lens (its undistortion map and the raw frame).
pub const LENS_BYTES_PER_PIXEL: u64 = 12;

/// Share of the mesh's vertices a camera must see (inside its image, in front of it) at the
/// first frame to count as seeing the mesh; the scene needs two such cameras.
pub const MIN_VISIBLE_SHARE: f64 = 0.25;

impl SceneFile {
    /// The first and last frame, checked to be in order. Errors name `path`.
    fn frame_range(&self, path: &Path) -> Result<(u32, u32)> {
        let (first, last) = (self.frames.first, self.frames.last);
        if first > last {
            return Err(Error::invalid(
                path,
                "frames",
                format!("first ({first}) is after last ({last})"),
            ));
        }
        Ok((first, last))
    }

    /// The scene's cameras, checked as [`Scene::load`] checks them, without the mesh or any
    /// image (a run's export reads them after the footage may have been archived). Errors name
    /// `path`.
    pub fn cameras_of(&self, path: &Path) -> Result<Vec<Camera>> {
        self.frame_range(path)?;
        if self.cameras.is_empty() {
            return Err(Error::invalid(path, "cameras", "no camera"));
        }
        (0..self.cameras.len())
            .map(|i| self.camera(path, i))
            .collect()
    }

    /// Camera `i`, checked: a unique name, a lag within a frame, a valid calibration.
    fn camera(&self, path: &Path, i: usize) -> Result<Camera> {
        let c = &self.cameras[i];
        if let Some(j) = self.cameras[..i].iter().position(|o| o.name == c.name) {
            return Err(Error::invalid(
                path,
                format!("cameras[{i}].name"),
                format!(
                    "{:?} is also the name of cameras[{j}]; names must be unique",
                    c.name
                ),
            ));
        }
        if !(c.time_offset.is_finite() && (-1.0..=1.0).contains(&c.time_offset)) {
            return Err(Error::invalid(
                path,
                format!("cameras[{i}].time_offset"),
                format!(
                    "{} frames: expected a lag from -1 to 1 frame (a whole frame is frame_offset)",
                    c.time_offset
                ),
            ));
        }
        if !(c.shutter.is_finite() && (0.0..=1.0).contains(&c.shutter)) {
            return Err(Error::invalid(
                path,
                format!("cameras[{i}].shutter"),
                format!(
                    "{}: expected the shutter's opening as a fraction of a frame, from 0 to 1 (0.5 is a 180° shutter)",
                    c.shutter
                ),
            ));
        }
        if !(c.rolling_shutter.is_finite() && (0.0..=1.0).contains(&c.rolling_shutter)) {
            return Err(Error::invalid(
                path,
                format!("cameras[{i}].rolling_shutter"),
                format!(
                    "{}: expected the readout from the top row to the bottom row in frames, from 0 to 1 (0: a global shutter; at 30 fps a 20 ms readout is 0.6)",
                    c.rolling_shutter
                ),
            ));
        }
        let mut camera = build_camera(path, i, c, self.frames.first, self.frames.last)?;
        camera.time_offset = c.time_offset;
        camera.shutter = c.shutter;
        camera.rolling_shutter = c.rolling_shutter;
        Ok(camera)
    }

    /// Writes the scene file as pretty-printed JSON, atomically. Refuses non-finite numbers
    /// (JSON cannot hold them; serde would write `null`).
    pub fn write(&self, path: &Path) -> Result<()> {
        for (i, c) in self.cameras.iter().enumerate() {
            let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
            let bad = [
                ("K", c.k.is_some_and(|k| !finite(k.as_flattened()))),
                ("R", c.r.is_some_and(|r| !finite(r.as_flattened()))),
                ("t", c.t.is_some_and(|t| !finite(&t))),
                (
                    "poses",
                    c.poses.as_ref().is_some_and(|ps| {
                        ps.iter()
                            .any(|p| !finite(p.r.as_flattened()) || !finite(&p.t))
                    }),
                ),
                (
                    "P",
                    c.p.as_ref()
                        .is_some_and(|ps| ps.iter().any(|p| !finite(p.as_flattened()))),
                ),
            ];
            if let Some((field, _)) = bad.iter().find(|(_, b)| *b) {
                return Err(Error::invalid(
                    path,
                    format!("cameras[{i}].{field}"),
                    "cannot be written: it has a non-finite number",
                ));
            }
        }
        let mut text = serde_json::to_string_pretty(self)
            .map_err(|e| Error::invalid(path, "scene", format!("cannot be serialised: {e}")))?;
        text.push('\n');
        write_atomic(path, text.as_bytes())
    }

    /// Reads and parses the scene file at `path` (nothing beyond its JSON is checked: see
    /// [`Scene::load`]).
    pub fn read(path: &Path) -> Result<SceneFile> {
        require_file(path, "scene file")?;
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        SceneFile::parse(path, &text)
    }

    /// Parses scene JSON straight into the typed structures (no intermediate JSON tree, so
    /// memory stays proportional to what the scene holds), naming the line and column of any
    /// error and, for a structural one, the JSON path of the field (`cameras[0].K`,
    /// `cameras[1].width`).
    pub fn parse(path: &Path, text: &str) -> Result<SceneFile> {
        // A byte-order mark (some Windows editors write one) is not part of the JSON.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        #[derive(Deserialize)]
        struct Tag {
            format: Option<serde_json::Value>,
        }
        let syntax = |e: serde_json::Error| {
            let at = format!("line {} column {}", e.line(), e.column());
            let what = e.to_string().replace(&format!(" at {at}"), "");
            let hint = if what.starts_with("number out of range") {
                " (numbers must be finite)"
            } else {
                ""
            };
            Error::invalid(path, at, format!("invalid JSON: {what}{hint}"))
        };
        // The format tag first: a file of another kind is named as such, not by its first
        // unexpected field.
        let tag: Tag = match serde_json::from_str(text) {
            Ok(t) => t,
            Err(e) if e.is_syntax() || e.is_eof() => return Err(syntax(e)),
            Err(_) => {
                return Err(Error::invalid(
                    path,
                    "(top level)",
                    "expected a JSON object",
                ));
            }
        };
        match tag.format {
            Some(serde_json::Value::String(f)) if f == FORMAT => {}
            Some(other) => {
                return Err(Error::invalid(
                    path,
                    "format",
                    format!("expected \"{FORMAT}\", found {other}"),
                ))
            }
            None => {
                return Err(Error::invalid(
                    path,
                    "format",
                    format!("missing (expected \"{FORMAT}\")"),
                ))
            }
        }
        let de = &mut serde_json::Deserializer::from_str(text);
        serde_path_to_error::deserialize::<_, SceneFile>(de).map_err(|e| {
            let field = e.path().to_string();
            let inner = e.into_inner();
            if inner.is_eof() || inner.to_string().starts_with("number out of range") {
                return syntax(inner);
            }
            let at = format!("line {} column {}", inner.line(), inner.column());
            let what = inner.to_string().replace(&format!(" at {at}"), "");
            // The text parsed as JSON above (the format tag), so what serde_json calls a
            // syntax error here is a value of the wrong kind (a number where a name is
            // expected); internal type names are said as the JSON they stand for.
            let what = if inner.is_syntax() {
                format!("a value of the wrong kind here ({what}): see docs/scene-format.md")
            } else {
                struct_names_as_json(&what)
            };
            let field = if field == "." {
                "(top level)".to_string()
            } else {
                field
            };
            Error::invalid(path, format!("{field} ({at})"), what)
        })
    }
}

/// serde's "expected struct Name" (a Rust type the user never sees) said as "expected a JSON
/// object".
fn struct_names_as_json(what: &str) -> String {
    let mut out = String::with_capacity(what.len());
    let mut rest = what;
    while let Some(i) = rest.find("struct ") {
        out.push_str(&rest[..i]);
        let after = &rest[i + "struct ".len()..];
        let end = after
            .find(|c: char| !(c.is_alphanumeric() || c == '_'))
            .unwrap_or(after.len());
        out.push_str("a JSON object");
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

fn mat3(m: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| m[i][j])
}

fn check_k(path: &Path, field: &str, k: &[[f64; 3]; 3]) -> Result<Matrix3<f64>> {
    let bad = |msg: String| Error::invalid(path, field, msg);
    if !k.iter().flatten().all(|v| v.is_finite()) {
        return Err(bad(format!("has a non-finite entry: {k:?}")));
    }
    if k[2] != [0.0, 0.0, 1.0] {
        return Err(bad(format!("last row must be [0, 0, 1], found {:?}", k[2])));
    }
    if k[1][0] != 0.0 {
        return Err(bad(format!(
            "must be upper-triangular: K[1][0] is {}, expected 0",
            k[1][0]
        )));
    }
    if k[0][0] <= 0.0 || k[1][1] <= 0.0 {
        return Err(bad(format!(
            "is singular or mirrored: focal lengths fx = {}, fy = {} must be positive",
            k[0][0], k[1][1]
        )));
    }
    Ok(mat3(k))
}

fn check_r(path: &Path, field: &str, r: &[[f64; 3]; 3]) -> Result<Matrix3<f64>> {
    let m = mat3(r);
    if !r.iter().flatten().all(|v| v.is_finite()) {
        return Err(Error::invalid(
            path,
            field,
            format!("has a non-finite entry: {r:?}"),
        ));
    }
    if !is_rotation(&m, ROTATION_TOLERANCE) {
        let dev = (m.transpose() * m - Matrix3::identity()).abs().max();
        return Err(Error::invalid(
            path,
            field,
            format!(
                "not a rotation matrix (R^T R differs from I by {dev:.3e}, det R = {:.6}; tolerance {ROTATION_TOLERANCE:e})",
                m.determinant()
            ),
        ));
    }
    Ok(m)
}

fn check_t(path: &Path, field: &str, t: &[f64; 3]) -> Result<Vector3<f64>> {
    if !t.iter().all(|v| v.is_finite()) {
        return Err(Error::invalid(
            path,
            field,
            format!("has a non-finite entry: {t:?}"),
        ));
    }
    Ok(Vector3::from(*t))
}

fn projection(
    path: &Path,
    field: &str,
    r: std::result::Result<Projection, ProjectionError>,
) -> Result<Projection> {
    r.map_err(|e| Error::invalid(path, field, format!("the projection {e}")))
}

/// Turns one camera entry into a [`Camera`], validating it.
fn build_camera(path: &Path, i: usize, c: &CameraEntry, first: u32, last: u32) -> Result<Camera> {
    let f = |name: &str| format!("cameras[{i}].{name}");
    let nframes = (last - first) as usize + 1;
    if c.name.trim().is_empty() {
        return Err(Error::invalid(path, f("name"), "must not be empty"));
    }
    if c.width == 0 || c.height == 0 {
        return Err(Error::invalid(
            path,
            f(if c.width == 0 { "width" } else { "height" }),
            format!("image size {}x{} must be positive", c.width, c.height),
        ));
    }
    if let Some(ps) = &c.p {
        if c.distortion.is_some() {
            return Err(Error::invalid(
                path,
                f("distortion"),
                "needs the camera given as K with R and t or poses (a P matrix carries no camera matrix for the lens to apply in)",
            ));
        }
        if c.k.is_some() || c.r.is_some() || c.t.is_some() || c.poses.is_some() {
            return Err(Error::invalid(
                path,
                f("P"),
                "give exactly one of K+R+t, K+poses or P (found P together with K, R, t or poses)",
            ));
        }
        if ps.len() != nframes {
            return Err(Error::invalid(
                path,
                f("P"),
                format!(
                    "needs exactly one matrix per frame: {nframes} for frames {first}..={last}, found {}",
                    ps.len()
                ),
            ));
        }
        let mut poses = ps
            .iter()
            .enumerate()
            .map(|(j, m)| {
                let m = Matrix3x4::from_fn(|a, b| m[a][b]);
                projection(
                    path,
                    &format!("cameras[{i}].P[{j}] (frame {})", first + j as u32),
                    Projection::from_matrix(&m),
                )
            })
            .collect::<Result<Vec<_>>>()?;
        return Ok(if poses.len() == 1 {
            Camera::fixed(&c.name, c.width, c.height, poses.remove(0))
        } else {
            Camera::moving(&c.name, c.width, c.height, first, poses)
        });
    }
    let k = c.k.as_ref().ok_or_else(|| {
        Error::invalid(
            path,
            f("K"),
            "missing: give exactly one of K+R+t, K+poses or P",
        )
    })?;
    let k = check_k(path, &f("K"), k)?;
    let lens = match &c.distortion {
        None => None,
        Some(d) => check_lens(path, &f("distortion"), k, c, d)?,
    };
    let camera = match (&c.poses, &c.r, &c.t) {
        (Some(_), Some(_), _) | (Some(_), _, Some(_)) => Err(Error::invalid(
            path,
            f("poses"),
            "give either poses or R and t, not both",
        )),
        (Some(poses), None, None) => {
            // Keyed by frame: memory bounded by the file, not by the (user-given) frame range.
            let mut by_frame: std::collections::BTreeMap<u32, Projection> = Default::default();
            for (j, pe) in poses.iter().enumerate() {
                let pf = format!("cameras[{i}].poses[{j}]");
                if pe.frame < first || pe.frame > last {
                    return Err(Error::invalid(
                        path,
                        format!("{pf}.frame"),
                        format!(
                            "frame {} outside the scene's frames {first}..={last}",
                            pe.frame
                        ),
                    ));
                }
                let r = check_r(path, &format!("{pf}.R"), &pe.r)?;
                let t = check_t(path, &format!("{pf}.t"), &pe.t)?;
                let proj = projection(path, &pf, Projection::from_krt(&k, &r, &t))?;
                if by_frame.insert(pe.frame, proj).is_some() {
                    return Err(Error::invalid(
                        path,
                        format!("{pf}.frame"),
                        format!("frame {} has more than one pose", pe.frame),
                    ));
                }
            }
            if by_frame.len() != nframes {
                let missing: Vec<u32> = (first..=last)
                    .filter(|f| !by_frame.contains_key(f))
                    .take(11)
                    .collect();
                return Err(Error::invalid(
                    path,
                    f("poses"),
                    format!(
                        "no pose for frame(s) {} ({} poses for {nframes} frames)",
                        list_frames(&missing),
                        by_frame.len()
                    ),
                ));
            }
            let slot = by_frame.into_values();
            let poses: Vec<Projection> = slot.collect();
            Ok(Camera::moving(&c.name, c.width, c.height, first, poses))
        }
        (None, Some(r), Some(t)) => {
            let r = check_r(path, &f("R"), r)?;
            let t = check_t(path, &f("t"), t)?;
            let p = projection(path, &f("K"), Projection::from_krt(&k, &r, &t))?;
            Ok(Camera::fixed(&c.name, c.width, c.height, p))
        }
        (None, None, _) => Err(Error::invalid(
            path,
            f("R"),
            "missing: a camera with K needs R and t, or poses",
        )),
        (None, Some(_), None) => Err(Error::invalid(
            path,
            f("t"),
            "missing: a camera with K and R needs t",
        )),
    }?;
    Ok(camera.with_lens(lens))
}

/// At least two cameras must see the mesh at `first` (see [`MIN_VISIBLE_SHARE`]).
fn check_seen(path: &Path, cameras: &[Camera], first: u32, mesh: &Mesh) -> Result<()> {
    let shares: Vec<f64> = cameras
        .iter()
        .map(|c| visible_share(c, first, mesh))
        .collect();
    if shares.iter().filter(|&&s| s >= MIN_VISIBLE_SHARE).count() < 2 {
        let detail: Vec<String> = cameras
            .iter()
            .zip(&shares)
            .map(|(c, s)| format!("{} sees {:.0}%", c.name, 100.0 * s))
            .collect();
        // A mesh written with another up axis than the cameras' world lies turned 90° about
        // the origin: say which swap the cameras would see.
        let swapped = crate::base::AxisSwap::ALL.iter().find_map(|&swap| {
            let turned = swap.mesh(mesh);
            let n = cameras
                .iter()
                .filter(|c| visible_share(c, first, &turned) >= MIN_VISIBLE_SHARE)
                .count();
            (n >= 2).then(|| {
                format!(
                    "; with its axes {}, {n} cameras would see it: export it with the cameras' up axis, or check the calibration's",
                    swap.describe()
                )
            })
        });
        let why: String = mesh_out_of_scale(cameras, first, mesh)
            .map(|m| format!("; {m}"))
            .into_iter()
            .chain(swapped)
            .chain(
                blind_cameras(cameras, first, mesh)
                    .iter()
                    .map(|b| format!("; {b}")),
            )
            .collect();
        return Err(Error::invalid(
                path,
                "cameras",
                format!(
                    "the mesh is seen by fewer than two cameras at frame {first} (a camera sees it when at least {:.0}% of its vertices project inside the image, in front of the camera): {}",
                    100.0 * MIN_VISIBLE_SHARE,
                    detail.join(", "),
                ) + &why,
            ));
    }
    Ok(())
}

/// A camera's lens, validated: known model, right number of finite coefficients, and a model
/// that stays one-to-one over the image's central region (coefficients in the wrong order or
/// for another unit fold it over near the centre). Identity coefficients give no lens.
fn check_lens(
    path: &Path,
    field: &str,
    k: Matrix3<f64>,
    c: &CameraEntry,
    d: &DistortionEntry,
) -> Result<Option<Lens>> {
    let distortion =
        Distortion::new(&d.model, &d.coefficients).map_err(|m| Error::invalid(path, field, m))?;
    if distortion.is_identity() {
        return Ok(None);
    }
    let lens = Lens::new(k, distortion);
    // The normalised radius of the point halfway from the principal point to the farthest
    // image corner must lie within the model's one-to-one range.
    let kinv = k.try_inverse().unwrap_or_else(Matrix3::identity);
    let (w, h) = (c.width as f64 - 1.0, c.height as f64 - 1.0);
    let centre = kinv * Vector3::new(k[(0, 2)], k[(1, 2)], 1.0);
    let reach = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
        .iter()
        .map(|&(u, v)| {
            let n = kinv * Vector3::new(u, v, 1.0);
            ((n.x - centre.x).hypot(n.y - centre.y)) * 0.5
        })
        .fold(0.0, f64::max);
    if lens.max_radius() < reach {
        return Err(Error::invalid(
            path,
            field,
            format!(
                "the {} model with these coefficients folds over {:.0}% of the way from the principal point to the farthest image corner (it is one-to-one only up to a normalised radius of {:.3}); are the coefficients in OpenCV's order?",
                d.model,
                100.0 * lens.max_radius() / (2.0 * reach),
                lens.max_radius()
            ),
        ));
    }
    Ok(Some(lens))
}

fn list_frames(frames: &[u32]) -> String {
    let shown: Vec<String> = frames.iter().take(10).map(|f| f.to_string()).collect();
    if frames.len() > 10 {
        format!("{}, ...", shown.join(", "))
    } else {
        shown.join(", ")
    }
}

/// Share of `mesh`'s vertices that project inside `cam`'s image, in front of it, at `frame`.
pub fn visible_share(cam: &Camera, frame: u32, mesh: &Mesh) -> f64 {
    if mesh.positions.is_empty() {
        return 0.0;
    }
    let p = cam.at(frame);
    let seen = mesh
        .positions
        .iter()
        .filter(|x| p.project(x).is_some_and(|q| cam.contains(&q)))
        .count();
    seen as f64 / mesh.positions.len() as f64
}

/// Why a camera sees none of the mesh at a frame ([`blind_cameras`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Blind {
    /// Every vertex lies behind the camera (depth ≤ 0).
    Behind,
    /// Some vertices lie in front of the camera but none projects inside its image; `centre` is
    /// the pixel where the mesh's centroid projects (`None` when the centroid is behind it).
    OutsideImage {
        centre: Option<nalgebra::Point2<f64>>,
    },
}

/// A camera that sees none of the mesh at a frame, and why: almost always a calibration that
/// does not follow the scene's convention (docs/scene-format.md, "Convention"), which the
/// tracker would otherwise pass over in silence (it compares what each camera sees, and this
/// one sees nothing).
#[derive(Clone, Debug, PartialEq)]
pub struct BlindCamera {
    /// The camera's index in the scene.
    pub index: usize,
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub frame: u32,
    pub why: Blind,
}

impl std::fmt::Display for BlindCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (name, frame) = (&self.name, self.frame);
        match &self.why {
            Blind::Behind => write!(
                f,
                "camera {name} sees none of the mesh at frame {frame}: every vertex is behind it. \
                 Its R and t must map a world point into the camera (x = R·X + t), not give the \
                 camera's pose in the world (for a camera-to-world R_c, C: R = R_cᵀ, t = −R_cᵀ·C), \
                 and it must look down +z with image y downwards, as OpenCV's cameras do; a camera \
                 from OpenGL or Blender looks down −z with y up: negate the second and third rows \
                 of its R and entries of its t (docs/scene-format.md, \"Convention\")"
            ),
            Blind::OutsideImage { centre } => {
                let at = match centre {
                    Some(c) => format!(" (its centre lands at pixel ({:.0}, {:.0}))", c.x, c.y),
                    None => String::new(),
                };
                write!(
                    f,
                    "camera {name} sees none of the mesh at frame {frame}: the mesh is in front \
                     of it but projects outside its {}×{} image{at}. Check its K (focal lengths \
                     and principal point in pixels of this image size, not millimetres or \
                     normalised units) and its pose: R and t map a world point into the camera \
                     (x = R·X + t), not the camera into the world (docs/scene-format.md, \
                     \"Convention\")",
                    self.width, self.height
                )
            }
        }
    }
}

/// The cameras of `cameras` that see none of `mesh`'s vertices at `frame` (none projects inside
/// the image, in front of the camera), each with why. A rig needs two cameras that see the mesh
/// to load at all ([`MIN_VISIBLE_SHARE`]); a third that sees nothing loads, and is named here.
pub fn blind_cameras(cameras: &[Camera], frame: u32, mesh: &Mesh) -> Vec<BlindCamera> {
    if mesh.positions.is_empty() {
        return Vec::new();
    }
    let centroid = crate::base::centroid(&mesh.positions);
    cameras
        .iter()
        .enumerate()
        .filter(|(_, c)| visible_share(c, frame, mesh) == 0.0)
        .map(|(index, c)| {
            let p = c.at(frame);
            let why = if mesh.positions.iter().all(|x| p.depth(x) <= 0.0) {
                Blind::Behind
            } else {
                Blind::OutsideImage {
                    centre: p.project(&centroid),
                }
            };
            BlindCamera {
                index,
                name: c.name.clone(),
                width: c.width,
                height: c.height,
                frame,
                why,
            }
        })
        .collect()
}

/// Below this many pixels across (median over the cameras) a mesh is too small to track, and is
/// named by [`mesh_out_of_scale`].
pub const TINY_MESH_PX: f64 = 8.0;
/// Above this many times the images' diagonal (median over the cameras) a mesh is named by
/// [`mesh_out_of_scale`].
pub const HUGE_MESH_IMAGES: f64 = 10.0;

/// A mesh whose size in the images is far from anything a tracker can follow: almost always a
/// mesh in another unit than the calibration's `t` (metres against millimetres: 1000 times).
#[derive(Clone, Debug, PartialEq)]
pub struct MeshOutOfScale {
    pub frame: u32,
    /// The mesh's size in the images: the diagonal of its projected vertices' bounding box
    /// (those in front of each camera), median over the cameras that have any in front.
    pub pixels: f64,
    /// The images' diagonal, median over the same cameras.
    pub image: f64,
}

impl std::fmt::Display for MeshOutOfScale {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let frame = self.frame;
        if self.pixels < self.image {
            write!(
                f,
                "the mesh is only {:.1} px across in the cameras' images at frame {frame} \
                 (median over the cameras): too small to track. Are the mesh and the \
                 calibration's t in the same unit? A mesh in metres with cameras calibrated in \
                 millimetres looks 1000 times smaller",
                self.pixels
            )
        } else {
            write!(
                f,
                "the mesh is about {:.0} px across in the cameras' images at frame {frame}, \
                 {:.0} times their size (median over the cameras). Are the mesh and the \
                 calibration's t in the same unit? A mesh in millimetres with cameras \
                 calibrated in metres looks 1000 times larger",
                self.pixels,
                self.pixels / self.image
            )
        }
    }
}

/// The mesh's size in the cameras' images at `frame` when it is below [`TINY_MESH_PX`] or above
/// [`HUGE_MESH_IMAGES`] times the images (`None` otherwise, and when no vertex is in front of
/// any camera: [`blind_cameras`] says that).
pub fn mesh_out_of_scale(cameras: &[Camera], frame: u32, mesh: &Mesh) -> Option<MeshOutOfScale> {
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let mut pixels = Vec::new();
    let mut image = Vec::new();
    for c in cameras {
        let p = c.at(frame);
        let mut lo = nalgebra::Point2::new(f64::INFINITY, f64::INFINITY);
        let mut hi = nalgebra::Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        let mut any = false;
        for q in mesh.positions.iter().filter_map(|x| p.project(x)) {
            lo = lo.inf(&q);
            hi = hi.sup(&q);
            any = true;
        }
        if any && (hi - lo).norm().is_finite() {
            pixels.push((hi - lo).norm());
            image.push((c.width as f64).hypot(c.height as f64));
        }
    }
    if pixels.is_empty() {
        return None;
    }
    let out = MeshOutOfScale {
        frame,
        pixels: median(pixels),
        image: median(image),
    };
    (out.pixels < TINY_MESH_PX || out.pixels > HUGE_MESH_IMAGES * out.image).then_some(out)
}

/// How far from its image's centre a camera's principal point may lie, as a share of the image's
/// width (height) along each axis, before [`off_centre_principal_points`] names it. A lens puts
/// it within a few per cent of the centre (the real webcams of `caliscope-board-sample`: within
/// 5 % of the height, 2 % of the width); a calibration made at another resolution than the
/// footage's (a camera calibrated from 1920×1080 stills and filmed at 1280×720) puts it a
/// quarter of the image off or more.
pub const PRINCIPAL_POINT_OFF: f64 = 0.2;

/// A camera whose image files ask viewers to turn or mirror them ([`Scene::turned_images`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TurnedImages {
    pub index: usize,
    pub name: String,
    /// The first frame's file.
    pub file: PathBuf,
    /// The turn, in words (`"turned 90° clockwise"`).
    pub turn: &'static str,
}

impl std::fmt::Display for TurnedImages {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "camera {}: {} asks viewers to show it {} (its EXIF orientation). modelflow reads the \
             pixels as stored, as PIL does, not as OpenCV's imread and photo viewers show them: \
             the camera's size and calibration must be those of the stored pixels. If the \
             calibration was made on the images as shown, write the frames turned first (e.g. \
             ImageMagick's `mogrify -auto-orient`)",
            self.name,
            self.file.display(),
            self.turn
        )
    }
}

/// A camera whose principal point lies far from its image's centre
/// ([`off_centre_principal_points`]).
#[derive(Clone, Debug, PartialEq)]
pub struct OffCentre {
    pub index: usize,
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// The principal point (pixels, centres at integers).
    pub cx: f64,
    pub cy: f64,
}

impl std::fmt::Display for OffCentre {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h) = (self.width as f64, self.height as f64);
        let (mx, my) = ((w - 1.0) / 2.0, (h - 1.0) / 2.0);
        // The image whose centre the principal point is.
        let (pw, ph) = ((2.0 * self.cx + 1.0).round(), (2.0 * self.cy + 1.0).round());
        let other = if pw >= 1.0 && ph >= 1.0 {
            format!(
                " ((cx, cy) is the centre of a {pw:.0}×{ph:.0} image: scale K's first two rows by {}/{pw:.0})",
                self.width
            )
        } else {
            String::new()
        };
        write!(
            f,
            "camera {}: its principal point ({:.1}, {:.1}) lies {:.0} % of the width and {:.0} % of \
             the height from the centre of its {}×{} image ({mx:.1}, {my:.1}), where a lens puts \
             it within a few per cent. A K made at another resolution than the footage's puts it \
             there{other}, as does a cropped image: check its K, width and height",
            self.name,
            self.cx,
            self.cy,
            100.0 * (self.cx - mx).abs() / w,
            100.0 * (self.cy - my).abs() / h,
            self.width,
            self.height
        )
    }
}

/// The cameras whose principal point at `frame` lies more than [`PRINCIPAL_POINT_OFF`] of the
/// image's width (or height) from its centre.
pub fn off_centre_principal_points(cameras: &[Camera], frame: u32) -> Vec<OffCentre> {
    cameras
        .iter()
        .enumerate()
        .filter_map(|(index, c)| {
            let (k, _, _) = c.at(frame).krt();
            let (cx, cy) = (k[(0, 2)], k[(1, 2)]);
            let (w, h) = (c.width as f64, c.height as f64);
            let off = (cx - (w - 1.0) / 2.0).abs() > PRINCIPAL_POINT_OFF * w
                || (cy - (h - 1.0) / 2.0).abs() > PRINCIPAL_POINT_OFF * h;
            off.then(|| OffCentre {
                index,
                name: c.name.clone(),
                width: c.width,
                height: c.height,
                cx,
                cy,
            })
        })
        .collect()
}

impl Scene {
    /// Reads and validates a scene file: everything a run will need is checked here (images by
    /// their headers: one whose data is cut short is found when its frame is read), so that a
    /// run does not fail half-way on bad input. Errors name the file and the field at fault.
    pub fn load(path: &Path) -> Result<Scene> {
        Scene::load_selected(path, &Selection::default())
    }

    /// Reads a scene file and validates the part of it that `selection` names (`track
    /// --cameras`, `--frames`): the calibration of every camera, but the images only of the
    /// chosen cameras over the chosen frames. So a camera whose footage is broken can be left
    /// out, and a shot tracked over the frames that exist. The same as [`Scene::load`]
    /// followed by [`Scene::with_cameras`] and [`Scene::with_frames`] where those succeed.
    pub fn load_selected(path: &Path, selection: &Selection) -> Result<Scene> {
        let file = SceneFile::read(path)?;
        Scene::from_file_selected(path, &file, selection)
    }

    /// Validates a scene file already in memory as if it had been read from `path` (relative
    /// paths are resolved against `path`'s folder; errors name `path`).
    pub fn from_file(path: &Path, file: &SceneFile) -> Result<Scene> {
        Scene::from_file_selected(path, file, &Selection::default())
    }

    /// [`Scene::from_file`] for the part of the scene that `selection` names (see
    /// [`Scene::load_selected`]).
    pub fn from_file_selected(
        path: &Path,
        file: &SceneFile,
        selection: &Selection,
    ) -> Result<Scene> {
        if file.format != FORMAT {
            return Err(Error::invalid(
                path,
                "format",
                format!("expected \"{FORMAT}\", found {:?}", file.format),
            ));
        }
        let base = path.parent().unwrap_or(Path::new("")).to_path_buf();
        let (first, last) = file.frame_range(path)?;
        let (first, last) = match selection.frames {
            None => (first, last),
            Some((a, b)) if first <= a && a <= b && b <= last => (a, b),
            Some((a, b)) => {
                return Err(Error::option(
                    "--frames",
                    format!("{a}..{b}"),
                    format!(
                        "A..B with {first} <= A <= B <= {last} (the frames of {})",
                        path.display()
                    ),
                ));
            }
        };
        // Mesh.
        let mesh_path = base.join(&file.mesh);
        if let Some(kind) = crate::fsutil::not_a_file(&mesh_path) {
            return Err(Error::invalid(
                path,
                "mesh",
                format!("{} is {kind}, not a mesh file", mesh_path.display()),
            ));
        }
        if !mesh_path.is_file() {
            return Err(Error::invalid(
                path,
                "mesh",
                format!("file not found: {}", mesh_path.display()),
            ));
        }
        let mesh = read_mesh(&mesh_path)?;
        // Cameras.
        if file.cameras.is_empty() {
            return Err(Error::invalid(path, "cameras", "no camera"));
        }
        // Every camera's calibration is checked; the chosen ones (`index`: their places in the
        // file, which the messages name) are kept.
        let mut all = Vec::with_capacity(file.cameras.len());
        for i in 0..file.cameras.len() {
            all.push(file.camera(path, i)?);
        }
        let index: Vec<usize> = match &selection.cameras {
            None => (0..all.len()).collect(),
            Some(names) => pick_cameras(&all, names)?,
        };
        let mut cameras = Vec::with_capacity(index.len());
        let mut images = Vec::with_capacity(index.len());
        for &i in &index {
            let c = &file.cameras[i];
            cameras.push(all[i].clone());
            // Within what a frame number can be: an offset beyond it would wrap around.
            if c.frame_offset.unsigned_abs() > u64::from(u32::MAX) {
                return Err(Error::invalid(
                    path,
                    format!("cameras[{i}].frame_offset"),
                    format!(
                        "{} is beyond any frame number (at most ±{})",
                        c.frame_offset,
                        u32::MAX
                    ),
                ));
            }
            if first as i64 + c.frame_offset < 0 {
                return Err(Error::invalid(
                    path,
                    format!("cameras[{i}].frame_offset"),
                    format!(
                        "{} would read file number {} for frame {first}; file numbers start at 0",
                        c.frame_offset,
                        first as i64 + c.frame_offset
                    ),
                ));
            }
            images.push(
                FramePattern::new(&base, &c.images)
                    .map_err(|m| Error::invalid(path, format!("cameras[{i}].images"), m))?
                    .with_offset(c.frame_offset)
                    .with_transfer(c.transfer),
            );
        }
        let ground_truth = match &file.ground_truth {
            Some(g) => Some(
                FramePattern::new(&base, g).map_err(|m| Error::invalid(path, "ground_truth", m))?,
            ),
            None => None,
        };
        // Every image present and of the declared size (headers only, in parallel). Checked in
        // blocks of 64 frames, so that memory does not grow with the frame range; the problem
        // reported is the first in (block, camera, frame) order, whatever the thread count.
        // Video cameras: the file is probed once for its size and length.
        let mut videos = Vec::with_capacity(cameras.len());
        for ((pat, cam), &i) in images.iter().zip(&cameras).zip(&index) {
            if !pat.video {
                videos.push(None);
                continue;
            }
            let field = format!("cameras[{i}].images");
            let p = pat.path(first);
            if !p.is_file() {
                return Err(Error::invalid(
                    path,
                    field,
                    format!("video not found: {}", p.display()),
                ));
            }
            let reader = VideoReader::open(&p)?;
            let info = reader.info();
            if (info.width, info.height) != (cam.width, cam.height) {
                return Err(Error::invalid(
                    path,
                    field,
                    format!(
                        "{} is {}x{}, but the camera is declared {}x{}{}",
                        p.display(),
                        info.width,
                        info.height,
                        cam.width,
                        cam.height,
                        if info.rotation != 0 {
                            format!(
                                " (the video is stored turned: its display matrix turns it by {}°, which FFmpeg and players apply; the camera's size and calibration must be those of the frames as shown)",
                                info.rotation
                            )
                        } else {
                            String::new()
                        }
                    ),
                ));
            }
            let need = last as i64 + pat.offset;
            if need >= info.frames as i64 {
                return Err(Error::invalid(
                    path,
                    field,
                    format!(
                        "frame {last} is video frame {need} (frame_offset {}), but {} has {} frames (0..={})",
                        pat.offset,
                        p.display(),
                        info.frames,
                        info.frames - 1
                    ),
                ));
            }
            videos.push(Some(Arc::new(Mutex::new(reader))));
        }
        let check = |i: usize, f: u32| -> Result<()> {
            if images[i].video {
                return Ok(());
            }
            let p = images[i].path(f);
            let field = format!("cameras[{}].images", index[i]);
            if !p.is_file() {
                let what = match not_a_file(&p) {
                    Some(kind) => format!("{} is {kind}, not an image file", p.display()),
                    None => format!("image not found: {}", p.display()),
                };
                return Err(Error::invalid(path, field, format!("frame {f}: {what}")));
            }
            let (w, h) = image_size(&p)
                .map_err(|e| Error::invalid(path, field.clone(), format!("frame {f}: {e}")))?;
            let cam = &cameras[i];
            if (w, h) != (cam.width, cam.height) {
                return Err(Error::invalid(
                    path,
                    field,
                    format!(
                        "frame {f}: {} is {w}x{h}, but the camera is declared {}x{}",
                        p.display(),
                        cam.width,
                        cam.height
                    ),
                ));
            }
            Ok(())
        };
        const BLOCK: u32 = 64;
        let mut start = first;
        loop {
            let end = start.saturating_add(BLOCK - 1).min(last);
            let jobs: Vec<(usize, u32)> = (0..cameras.len())
                .flat_map(|i| (start..=end).map(move |f| (i, f)))
                .collect();
            if let Some(Err(e)) = jobs
                .par_iter()
                .map(|&(i, f)| check(i, f))
                .find_first(|r| r.is_err())
            {
                return Err(e);
            }
            if end == last {
                break;
            }
            start = end + 1;
        }
        if let Some(g) = &ground_truth {
            if let Some(f) = (first..=last).find(|&f| !g.path(f).is_file()) {
                return Err(Error::invalid(
                    path,
                    "ground_truth",
                    format!("frame {f}: file not found: {}", g.path(f).display()),
                ));
            }
        }
        // The mesh must be seen by at least two cameras at the first frame.
        check_seen(path, &cameras, first, &mesh)?;
        let undistort = cameras
            .iter()
            .map(|c| {
                c.lens.as_ref().map(|lens| {
                    std::sync::Arc::new(UndistortMap::new(
                        lens,
                        c.width as usize,
                        c.height as usize,
                    ))
                })
            })
            .collect();
        Ok(Scene {
            path: path.to_path_buf(),
            first,
            last,
            mesh,
            cameras,
            images,
            ground_truth,
            units: file.units,
            undistort,
            videos,
        })
    }

    fn check_frame(&self, frame: u32) -> Result<()> {
        if frame < self.first || frame > self.last {
            return Err(Error::option(
                "frame",
                frame,
                format!(
                    "a frame of {} ({}..={})",
                    self.path.display(),
                    self.first,
                    self.last
                ),
            ));
        }
        Ok(())
    }

    /// The images of `frame`, one per camera in the order of `cameras` (read in parallel),
    /// each checked to have its camera's size.
    /// The pinhole images of every camera at `frame`: the files as they are for a camera without
    /// distortion, resampled through its [`UndistortMap`] for one with (what the tracker, the
    /// baseline and the report work on).
    pub fn load_images(&self, frame: u32) -> Result<Vec<RgbImage>> {
        let raw = self.load_raw_images(frame)?;
        Ok(raw
            .into_par_iter()
            .zip(self.undistort.par_iter())
            .map(|(img, map)| match map {
                Some(map) => map.apply(&img),
                None => img,
            })
            .collect())
    }

    /// The image files of every camera at `frame` on their own pixel grids (distorted, for a
    /// camera with a lens), a JPEG's half-resolution colour smoothed
    /// ([`RgbImage::smooth_chroma`]; docs/scene-format.md, "JPEG colour").
    pub fn load_raw_images(&self, frame: u32) -> Result<Vec<RgbImage>> {
        self.check_frame(frame)?;
        self.cameras
            .par_iter()
            .zip(self.images.par_iter())
            .zip(self.videos.par_iter())
            .map(|((cam, pat), video)| {
                let p = pat.path(frame);
                let (mut img, float) = match video {
                    Some(reader) => {
                        let n = (frame as i64 + pat.offset).max(0) as u64;
                        // A reader poisoned by a panic elsewhere is still a valid decoder state.
                        let mut r = reader.lock().unwrap_or_else(|e| e.into_inner());
                        (r.frame(n)?, false)
                    }
                    None => {
                        let stored = read_rgb_stored(&p)?;
                        let mut img = stored.image;
                        // Colour stored at half resolution carries no detail finer than
                        // that; what the decoder interpolated on this camera's grid is
                        // smoothed away (docs/scene-format.md, "JPEG colour").
                        let [h, v] = stored.chroma_halved;
                        img.smooth_chroma(h, v);
                        (img, stored.float)
                    }
                };
                if pat.transfer.encodes(float) {
                    encode_linear(&mut img);
                }
                if (img.width(), img.height()) != (cam.width as usize, cam.height as usize) {
                    return Err(Error::invalid(
                        &p,
                        "size",
                        format!(
                            "{}x{}, but camera {} is declared {}x{}",
                            img.width(),
                            img.height(),
                            cam.name,
                            cam.width,
                            cam.height
                        ),
                    ));
                }
                Ok(img)
            })
            .collect()
    }

    /// The ground-truth mesh of `frame`, if the scene has ground truth; it must have the scene
    /// mesh's vertex count and triangles.
    pub fn ground_truth(&self, frame: u32) -> Option<Result<Mesh>> {
        let g = self.ground_truth.as_ref()?;
        Some(self.check_frame(frame).and_then(|()| {
            let p = g.path(frame);
            let m = read_mesh(&p)?;
            if m.positions.len() != self.mesh.positions.len() {
                return Err(Error::invalid(
                    &p,
                    "vertices",
                    format!(
                        "{} vertices, but the scene mesh has {}",
                        m.positions.len(),
                        self.mesh.positions.len()
                    ),
                ));
            }
            if m.triangles != self.mesh.triangles {
                return Err(Error::invalid(
                    &p,
                    "faces",
                    "the triangles differ from the scene mesh's (ground truth must share its topology)",
                ));
            }
            Ok(m)
        }))
    }
}

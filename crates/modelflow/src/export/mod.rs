//! Results out, for the users' 3D packages: a tracked run (one OBJ per frame, as
//! `run::read_run` reads it) becomes one animated file, USD (`.usda`), Alembic (`.abc`), glTF 2.0
//! (`.glb`, morph targets), or a PC2 / MDD point cache with the first frame's mesh as OBJ beside
//! it. Topology, texture coordinates and normals come from the run's first frame, positions from
//! every frame. The file formats are written by hand (no maintained Rust crate writes USD,
//! Alembic or point caches; glTF's JSON is small enough to build with `serde_json`), each
//! atomically. USD and Alembic also carry the scene's cameras ([`ExportCamera`]: their
//! projections, as pinhole cameras), so the mesh can be looked at through them over the footage. This module
//! knows nothing of images or tracking.

mod alembic;
mod cache;
mod gltf;
mod usd;

use crate::base::mesh::Mesh;
use crate::base::units::Units;
use crate::error::{Error, Result};
use crate::fsutil::write_atomic_with;
use crate::tracker::VertexConfidence;
use std::path::{Path, PathBuf};

/// What [`export`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportFormat {
    /// USD text (`.usda`): one Mesh prim, points as time samples.
    Usda,
    /// Alembic (`.abc`, Ogawa): one PolyMesh under an Xform, points sampled at every frame.
    Abc,
    /// Binary glTF 2.0 (`.glb`): the first frame's mesh, one morph target per frame and an
    /// animation that plays them.
    Glb,
    /// PC2 point cache (Blender's Mesh Cache modifier, 3ds Max, Houdini).
    Pc2,
    /// MDD point cache (LightWave's; Blender, Houdini, Maya plug-ins).
    Mdd,
}

impl ExportFormat {
    pub const ALL: [ExportFormat; 5] = [
        ExportFormat::Usda,
        ExportFormat::Abc,
        ExportFormat::Glb,
        ExportFormat::Pc2,
        ExportFormat::Mdd,
    ];

    /// The file extension (without the dot).
    pub fn extension(self) -> &'static str {
        match self {
            ExportFormat::Usda => "usda",
            ExportFormat::Abc => "abc",
            ExportFormat::Glb => "glb",
            ExportFormat::Pc2 => "pc2",
            ExportFormat::Mdd => "mdd",
        }
    }

    /// The format a file name's extension names, if any.
    pub fn from_path(path: &Path) -> Option<ExportFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        ExportFormat::ALL.into_iter().find(|f| f.extension() == ext)
    }
}

/// Options of [`export`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExportOptions {
    /// Frames per second of the footage: time codes and seconds of the animation.
    pub fps: f64,
    /// The unit of the coordinates (USD's `metersPerUnit`); `None`: not written.
    pub units: Option<Units>,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            fps: 24.0,
            units: None,
        }
    }
}

/// A camera written into the USD and Alembic exports beside the mesh: its name, image size and projection
/// (`P = K·[R | t]`, pixel centres at integer coordinates; the pinhole camera of the frames as
/// the tracker sees them, lens distortion removed). `views`: one projection for a camera that
/// does not move, else one per frame written.
#[derive(Clone, Debug)]
pub struct ExportCamera {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub views: Vec<(u32, crate::base::Projection)>,
}

impl ExportCamera {
    /// The scene camera `camera` at `frames` (one view when it does not move).
    pub fn of(camera: &crate::base::Camera, frames: impl IntoIterator<Item = u32>) -> Self {
        let views = if camera.is_moving() {
            frames
                .into_iter()
                .map(|f| (f, camera.at(f).clone()))
                .collect()
        } else {
            vec![(
                camera.first_frame(),
                camera.at(camera.first_frame()).clone(),
            )]
        };
        ExportCamera {
            name: camera.name.clone(),
            width: camera.width,
            height: camera.height,
            views,
        }
    }
}

/// What [`export`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportSummary {
    pub frames: usize,
    pub vertices: usize,
    pub triangles: usize,
    /// Cameras written (USD and Alembic only, when the run's scene could be read).
    pub cameras: usize,
    /// Why a USD or Alembic export of a run holds no cameras: the run names no scene, or its scene file
    /// could not be read or has a camera that does not check (the message names the file and
    /// the field). `None` when the cameras were written, and for the other formats.
    pub cameras_left_out: Option<String>,
    /// The vertices no face uses (an artist's stray points), and the first of them (0-based).
    /// USD, Alembic and the point caches keep them by index (glTF, which draws corners, has no
    /// use for them), but Blender's OBJ importer leaves them out of the OBJ written beside a
    /// point cache, which then no longer matches it ([`ExportSummary::warnings`]).
    pub loose_vertices: Option<(usize, usize)>,
    /// The format written.
    pub format: ExportFormat,
    /// The files written, the animated file first.
    pub files: Vec<PathBuf>,
}

impl ExportSummary {
    /// What a user should know about the files written, one sentence each: a USD or Alembic
    /// file without its cameras, a point cache whose OBJ has vertices that no face uses.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(why) = &self.cameras_left_out {
            let file = if self.format == ExportFormat::Abc {
                "Alembic file"
            } else {
                "USD"
            };
            out.push(format!(
                "the {file} holds the mesh but not the scene's cameras: {why}"
            ));
        }
        if let (Some((n, first)), ExportFormat::Pc2 | ExportFormat::Mdd) =
            (self.loose_vertices, self.format)
        {
            out.push(format!(
                "{n} of the {} vertices are in no face (the first: vertex {}, 1-based as in the \
                 OBJ): Blender's OBJ importer leaves them out, and its Mesh Cache modifier then \
                 finds fewer points than the {} cache holds; the Alembic and USD exports keep \
                 them by index",
                self.vertices,
                first + 1,
                self.format.extension().to_uppercase()
            ));
        }
        out
    }
}

/// Writes `frames` (frame number and mesh, ascending, all with the first one's triangles) as one
/// animated file `out` in `format`. PC2 and MDD also write the first frame's mesh as OBJ beside
/// `out` (same name, `.obj`), which is what the point cache deforms. `confidence` (frame and
/// per-vertex confidence, as `track` writes it beside each solved frame, frames ascending; may be
/// empty) goes into USD as the `information`, `residual` and `sigma` primvars, and into Alembic as
/// vertex parameters of those names.
pub fn export(
    frames: &[(u32, Mesh)],
    confidence: &[(u32, Vec<VertexConfidence>)],
    format: ExportFormat,
    out: &Path,
    opts: &ExportOptions,
) -> Result<ExportSummary> {
    export_with_cameras(frames, confidence, &[], format, out, opts)
}

/// [`export`], with `cameras` written into USD and Alembic beside the mesh (the other formats
/// hold no cameras and ignore them).
pub fn export_with_cameras(
    frames: &[(u32, Mesh)],
    confidence: &[(u32, Vec<VertexConfidence>)],
    cameras: &[ExportCamera],
    format: ExportFormat,
    out: &Path,
    opts: &ExportOptions,
) -> Result<ExportSummary> {
    if !(opts.fps.is_finite() && opts.fps > 0.0 && opts.fps <= 1000.0) {
        return Err(Error::option(
            "--fps",
            opts.fps,
            "frames per second in (0, 1000]",
        ));
    }
    let Some((_, first)) = frames.first() else {
        return Err(Error::option("frames", "none", "at least one frame mesh"));
    };
    for w in frames.windows(2) {
        if w[1].0 <= w[0].0 {
            return Err(Error::option(
                "frames",
                w[1].0,
                "frame numbers in ascending order",
            ));
        }
    }
    for (f, m) in frames {
        if m.positions.len() != first.positions.len() || m.triangles != first.triangles {
            return Err(Error::Mismatch {
                what: format!("frame {f}'s mesh"),
                expected: format!(
                    "the first frame's topology ({} vertices, {} triangles)",
                    first.positions.len(),
                    first.triangles.len()
                ),
                found: format!(
                    "{} vertices, {} triangles{}",
                    m.positions.len(),
                    m.triangles.len(),
                    if m.positions.len() == first.positions.len() {
                        " (other triangles)"
                    } else {
                        ""
                    }
                ),
            });
        }
    }
    if let Some(w) = confidence.windows(2).find(|w| w[1].0 <= w[0].0) {
        return Err(Error::option(
            "confidence",
            w[1].0,
            "frame numbers in ascending order",
        ));
    }
    if let Some((f, c)) = confidence
        .iter()
        .find(|(_, c)| c.len() != first.positions.len())
    {
        return Err(Error::Mismatch {
            what: format!("frame {f}'s confidence"),
            expected: format!("{} vertices", first.positions.len()),
            found: format!("{}", c.len()),
        });
    }
    let mut files = vec![out.to_path_buf()];
    match format {
        ExportFormat::Usda => {
            let text = usd::usda(frames, confidence, cameras, opts);
            write_atomic_with(out, |w| std::io::Write::write_all(w, text.as_bytes()))?;
        }
        ExportFormat::Abc => {
            let bytes = alembic::abc(frames, confidence, cameras, opts.fps);
            write_atomic_with(out, |w| std::io::Write::write_all(w, &bytes))?;
        }
        ExportFormat::Glb => {
            let bytes = gltf::glb(frames, opts)?;
            write_atomic_with(out, |w| std::io::Write::write_all(w, &bytes))?;
        }
        ExportFormat::Pc2 | ExportFormat::Mdd => {
            let bytes = if format == ExportFormat::Pc2 {
                cache::pc2(frames)?
            } else {
                cache::mdd(frames, opts.fps)
            };
            // The topology goes beside the cache as OBJ, under the cache's name: `--out` must
            // then be the cache's own name, or the OBJ would be written over it.
            let obj = out.with_extension("obj");
            if obj == out {
                return Err(Error::option(
                    "--out",
                    out.display(),
                    format!(
                        "the {} cache's file (ending in .{}): the first frame's mesh is written \
                         beside it as .obj",
                        format.extension().to_uppercase(),
                        format.extension()
                    ),
                ));
            }
            let mut text = Vec::new();
            crate::input::meshio::write_obj_to(&mut text, first).map_err(|e| Error::io(&obj, e))?;
            // Both or neither: a cache without its mesh (or beside another run's) is useless.
            crate::fsutil::write_atomic_pair((out, &bytes), (&obj, &text))?;
            files.push(obj);
        }
    }
    let mut used = vec![false; first.positions.len()];
    for t in &first.triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    let loose = used.iter().filter(|u| !**u).count();
    Ok(ExportSummary {
        cameras_left_out: None,
        loose_vertices: (loose > 0).then(|| (loose, used.iter().position(|u| !*u).unwrap_or(0))),
        format,
        frames: frames.len(),
        vertices: first.positions.len(),
        triangles: first.triangles.len(),
        cameras: if matches!(format, ExportFormat::Usda | ExportFormat::Abc) {
            cameras.len()
        } else {
            0
        },
        files,
    })
}

/// Reads a run folder ([`crate::read_run`]) and its confidence files, and [`export`]s it. Without `opts.units`, the unit is
/// taken from the scene file named in the folder's `run.json`, when both can be read; USD
/// and Alembic also get that scene's cameras when it loads ([`ExportCamera`]).
pub fn export_run(
    run: &Path,
    format: ExportFormat,
    out: &Path,
    opts: &ExportOptions,
) -> Result<ExportSummary> {
    let frames = crate::run::read_run(run)?;
    if frames.is_empty() {
        return Err(Error::invalid(
            run,
            "frames",
            "no frame meshes (files like 0000.obj) in this folder",
        ));
    }
    let scene = scene_of(run);
    let units = opts
        .units
        .or_else(|| scene.as_ref().ok().and_then(|(file, _)| file.units));
    let mut confidence = Vec::new();
    for (f, _) in &frames {
        let p = run.join(crate::run::confidence_file(*f));
        if p.is_file() {
            confidence.push((*f, crate::run::read_confidence(&p)?));
        }
    }
    // The scene's cameras, for USD and Alembic: from the scene file alone (the footage may be
    // archived).
    let with_cameras = matches!(format, ExportFormat::Usda | ExportFormat::Abc);
    let (cameras, left_out) = match (with_cameras, &scene) {
        (true, Ok((file, path))) => match file.cameras_of(path) {
            Ok(cams) => (
                cams.iter()
                    .map(|c| ExportCamera::of(c, frames.iter().map(|(f, _)| *f)))
                    .collect(),
                None,
            ),
            Err(e) => (Vec::new(), Some(e.to_string())),
        },
        (true, Err(why)) => (Vec::new(), Some(why.clone())),
        _ => (Vec::new(), None),
    };
    let summary = export_with_cameras(
        &frames,
        &confidence,
        &cameras,
        format,
        out,
        &ExportOptions { units, ..*opts },
    )?;
    Ok(ExportSummary {
        cameras_left_out: left_out,
        ..summary
    })
}

/// The scene file a run folder's manifest names, parsed, and its path; or why there is none
/// (no manifest, or the scene file missing or unreadable), in words.
fn scene_of(run: &Path) -> std::result::Result<(crate::input::SceneFile, PathBuf), String> {
    let manifest_path = run.join("run.json");
    if !manifest_path.is_file() {
        return Err(format!(
            "{} has no run.json naming its scene",
            run.display()
        ));
    }
    let manifest = crate::run::Manifest::read(&manifest_path).map_err(|e| e.to_string())?;
    let path = manifest.scene.path;
    let text = std::fs::read_to_string(&path).map_err(|e| {
        format!(
            "{}: the run's scene file cannot be read: {e}",
            path.display()
        )
    })?;
    let file = crate::input::SceneFile::parse(&path, &text).map_err(|e| e.to_string())?;
    Ok((file, path))
}

/// Seconds of frame `frame` when `first` is at 0.
fn seconds(frame: u32, first: u32, fps: f64) -> f64 {
    (frame - first) as f64 / fps
}

#[cfg(test)]
mod tests;

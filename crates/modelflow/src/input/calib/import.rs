//! From another tool's calibration to a scene file that can load: the reader for the format,
//! then the checks that a scene needs and a calibration alone does not (every camera named once,
//! an image pattern the scene reader takes for each camera), then the scene file itself. What
//! `modelflow import` and Python's `import_calibration` do; writing the file is the caller's.

use super::{
    read_alembic, read_alicevision, read_colmap, read_kalibr, read_metashape_chunk, read_mrcal,
    read_nerfstudio, read_opencv, read_rig_toml, read_usd, scene_file, CalibratedCamera, NerfWorld,
};
use crate::base::Units;
use crate::error::{Error, Result};
use crate::input::scene::{FramePattern, PoseEntry, SceneFile};
use std::collections::BTreeSet;
use std::path::Path;

/// The calibration formats read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CalibrationFormat {
    /// A COLMAP sparse model folder (text or binary).
    Colmap,
    /// An OpenCV `FileStorage` file (YAML or JSON).
    Opencv,
    /// An Agisoft Metashape camera XML.
    Metashape,
    /// A `transforms.json` (nerfstudio, instant-ngp, NeRF synthetic).
    Nerfstudio,
    /// A TOML rig calibration: anipose's, Pose2Sim's or FreeMoCap's `calibration.toml`,
    /// caliscope's `camera_array.toml`.
    Toml,
    /// Kalibr's `camchain.yaml` (or `camchain-imucam.yaml`).
    Kalibr,
    /// mrcal's `.cameramodel` files: one, or a folder of them.
    Mrcal,
    /// The cameras of an Alembic file (`.abc`): still ones, and moving ones as a pose per frame.
    Alembic,
    /// The cameras of a USD text layer (`.usda`): still ones, and moving ones as a pose per
    /// frame.
    Usd,
    /// An AliceVision (Meshroom) SfM file in JSON (`cameras.sfm`, `sfm.json`).
    AliceVision,
}

impl std::str::FromStr for CalibrationFormat {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        let s_lower = s.to_ascii_lowercase();
        if TOML_TOOLS.contains(&s_lower.as_str()) {
            return Ok(Self::Toml);
        }
        if s_lower == "meshroom" {
            return Ok(Self::AliceVision);
        }
        Self::ALL
            .into_iter()
            .find(|f| f.name() == s_lower)
            .ok_or_else(|| {
                Error::option(
                    "format",
                    s,
                    format!(
                        "{} (toml also named {}; alicevision also meshroom)",
                        Self::names(),
                        TOML_TOOLS.join(", ")
                    ),
                )
            })
    }
}

/// What the scene file names besides the cameras, and the choices some formats need.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportOptions {
    /// The mesh lined up with the first frame, as the scene file names it.
    pub mesh: String,
    /// Each camera's images: `{camera}` becomes its name (or each camera's video file).
    pub images: String,
    /// The frames, inclusive.
    pub frames: (u32, u32),
    /// The image size of cameras whose calibration gives none.
    pub size: Option<(u32, u32)>,
    /// Metashape: the chunk, by label or id.
    pub chunk: Option<String>,
    /// The unit of the calibration's world, written into the scene.
    pub units: Option<Units>,
    /// nerfstudio: the world before the file's `applied_transform`.
    pub before_applied_transform: bool,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            mesh: "mesh/initial.obj".into(),
            images: "images/{camera}/{frame:04}.png".into(),
            frames: (0, 0),
            size: None,
            chunk: None,
            units: None,
            before_applied_transform: false,
        }
    }
}

/// A calibration read and made into a scene file.
#[derive(Clone, Debug)]
pub struct Imported {
    pub cameras: Vec<CalibratedCamera>,
    /// What the user should know about the file as a whole (which world the cameras are in,
    /// fields ignored).
    pub notes: Vec<String>,
    /// The scene file, not yet written.
    pub file: SceneFile,
}

/// Reads `input` in `format` and makes the scene file; refuses, before reading anything, an
/// option the format has no use for or an image pattern the scene reader would refuse, and after
/// reading, a calibration whose cameras a scene cannot hold (a name empty or given twice).
pub fn import_calibration(
    format: CalibrationFormat,
    input: &Path,
    opts: &ImportOptions,
) -> Result<Imported> {
    if let (Some(c), false) = (&opts.chunk, format == CalibrationFormat::Metashape) {
        return Err(Error::option(
            "--chunk",
            c,
            "none: only a Metashape file has chunks",
        ));
    }
    if opts.before_applied_transform && format != CalibrationFormat::Nerfstudio {
        return Err(Error::option(
            "--before-applied-transform",
            "(given)",
            "no such option: only a nerfstudio transforms.json has an applied_transform",
        ));
    }
    let pattern = |name: &str| {
        FramePattern::new("", opts.images.replace("{camera}", name)).map_err(|e| {
            Error::option(
                "--images",
                format!("{:?}", opts.images),
                format!("a pattern the scene reads ({e})"),
            )
        })
    };
    pattern("cam")?;
    let mut notes = Vec::new();
    let mut poses = Vec::new();
    let mut file_units = None;
    let mut read = || -> Result<Vec<CalibratedCamera>> {
        Ok(match format {
            CalibrationFormat::Colmap => read_colmap(input)?,
            CalibrationFormat::Opencv => read_opencv(input, opts.size)?,
            CalibrationFormat::Metashape => read_metashape_chunk(input, opts.chunk.as_deref())?,
            CalibrationFormat::Nerfstudio => {
                let world = if opts.before_applied_transform {
                    NerfWorld::BeforeApplied
                } else {
                    NerfWorld::File
                };
                let read = read_nerfstudio(input, opts.size, world)?;
                notes = read.notes;
                read.cameras
            }
            CalibrationFormat::Toml => {
                let read = read_rig_toml(input, opts.size)?;
                notes = read.notes;
                read.cameras
            }
            CalibrationFormat::Kalibr => read_kalibr(input)?,
            CalibrationFormat::Mrcal => read_mrcal(input)?,
            CalibrationFormat::Alembic => {
                let read = read_alembic(input, opts.size, opts.frames)?;
                notes = read.notes;
                poses = read.poses;
                read.cameras
            }
            CalibrationFormat::Usd => {
                let read = read_usd(input, opts.size, opts.frames)?;
                notes = read.notes;
                poses = read.poses;
                file_units = read.units;
                read.cameras
            }
            CalibrationFormat::AliceVision => {
                let read = read_alicevision(input)?;
                notes = read.notes;
                read.cameras
            }
        })
    };
    let cameras = read().map_err(|e| with_format_hint(e, input, format))?;
    if cameras.len() > 1 && !opts.images.contains("{camera}") {
        return Err(Error::option(
            "--images",
            format!("{:?}", opts.images),
            format!(
                "a {{camera}} placeholder, one pattern for each of the {} cameras",
                cameras.len()
            ),
        ));
    }
    let mut names = BTreeSet::new();
    for c in &cameras {
        if c.name.trim().is_empty() {
            return Err(Error::invalid(
                input,
                "(cameras)",
                "a camera has no name: name every camera in the calibration",
            ));
        }
        if !names.insert(c.name.as_str()) {
            return Err(Error::invalid(
                input,
                "(cameras)",
                format!(
                    "two cameras are named {:?}: camera names must be unique; rename one in the calibration",
                    c.name
                ),
            ));
        }
        pattern(&c.name)
            .map_err(|e| Error::invalid(input, format!("camera {:?}", c.name), e.to_string()))?;
    }
    let (first, last) = opts.frames;
    let mut file = scene_file(&cameras, &opts.mesh, &opts.images, first, last);
    // The unit given wins over the one the file says (USD's metersPerUnit), which is said.
    file.units = opts.units.or(file_units);
    match (opts.units, file_units) {
        (Some(given), Some(said)) if given != said => notes.push(format!(
            "the file says its unit is {}, --units says {}: the scene is written in {}",
            said.name(),
            given.name(),
            given.name()
        )),
        (None, Some(said)) => notes.push(format!(
            "the scene's unit is the file's, {} (written as \"units\")",
            said.name()
        )),
        _ => {}
    }
    // A moving camera (an Alembic or USD one): its pose at every frame instead of one.
    for (entry, poses) in file.cameras.iter_mut().zip(poses) {
        if let Some(poses) = poses {
            let rows = |m: &nalgebra::Matrix3<f64>| [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[(i, j)]));
            entry.poses = Some(
                poses
                    .iter()
                    .map(|(frame, r, t)| PoseEntry {
                        frame: *frame,
                        r: rows(r),
                        t: [t.x, t.y, t.z],
                    })
                    .collect(),
            );
            entry.r = None;
            entry.t = None;
        }
    }
    Ok(Imported {
        cameras,
        notes,
        file,
    })
}

/// The tools whose TOML files `CalibrationFormat::Toml` reads, accepted as its name too.
const TOML_TOOLS: [&str; 4] = ["anipose", "pose2sim", "freemocap", "caliscope"];

impl CalibrationFormat {
    /// Every format read, in the order the docs list them.
    pub const ALL: [CalibrationFormat; 10] = [
        Self::Colmap,
        Self::Opencv,
        Self::Metashape,
        Self::Nerfstudio,
        Self::Toml,
        Self::Kalibr,
        Self::Mrcal,
        Self::Alembic,
        Self::Usd,
        Self::AliceVision,
    ];

    /// "colmap, opencv, ... or mrcal": the names a user may give.
    fn names() -> String {
        let names: Vec<&str> = Self::ALL.iter().map(|f| f.name()).collect();
        let (last, rest) = names.split_last().expect("formats");
        format!("{} or {last}", rest.join(", "))
    }

    /// The name `import` takes for the format.
    pub fn name(self) -> &'static str {
        match self {
            Self::Colmap => "colmap",
            Self::Opencv => "opencv",
            Self::Metashape => "metashape",
            Self::Nerfstudio => "nerfstudio",
            Self::Toml => "toml",
            Self::Kalibr => "kalibr",
            Self::Mrcal => "mrcal",
            Self::Alembic => "alembic",
            Self::Usd => "usd",
            Self::AliceVision => "alicevision",
        }
    }

    /// The format `path` is in, as [`CalibrationFormat::sniff`] tells it (`import auto`), or an
    /// error that says to name it.
    pub fn detect(path: &Path) -> Result<CalibrationFormat> {
        Self::sniff(path).ok_or_else(|| {
            Error::invalid(
                path,
                "(format)",
                format!(
                    "not recognised as any calibration format read: name it ({})",
                    Self::names()
                ),
            )
        })
    }

    /// What `path` looks like, from its name and its first bytes (not a full read): a folder
    /// with COLMAP's files, an XML file (Metashape's), a JSON object with `frames` and
    /// `transform_matrix` (a `transforms.json`), a TOML file with camera tables, YAML with a
    /// `cam0` map and `intrinsics` (Kalibr's), `.cameramodel` files (mrcal's), an Alembic file
    /// (Ogawa's header, or HDF5's with an `.abc` name), a USD file (`#usda`, a `.usdc` or `.usdz`
    /// name), a JSON object with `viewId` and `poseId` or an `.sfm` name (AliceVision's), else
    /// YAML or JSON (OpenCV's
    /// `FileStorage`). `None` when it is none of these or cannot be read.
    pub fn sniff(path: &Path) -> Option<CalibrationFormat> {
        let colmap = ["cameras.txt", "cameras.bin", "images.txt", "images.bin"];
        let cameramodel = |p: &Path| p.extension().is_some_and(|x| x == "cameramodel");
        if path.is_dir() {
            if colmap.iter().any(|f| path.join(f).is_file()) {
                return Some(Self::Colmap);
            }
            let models = std::fs::read_dir(path).ok()?;
            return models
                .filter_map(|e| e.ok())
                .any(|e| cameramodel(&e.path()))
                .then_some(Self::Mrcal);
        }
        if cameramodel(path) {
            return Some(Self::Mrcal);
        }
        let name = path.file_name()?.to_str()?;
        if colmap.contains(&name) {
            return Some(Self::Colmap);
        }
        let mut head = Vec::new();
        let file = std::fs::File::open(path).ok()?;
        std::io::Read::read_to_end(&mut std::io::Read::take(file, 64 * 1024), &mut head).ok()?;
        let abc = path
            .extension()
            .is_some_and(|x| x.eq_ignore_ascii_case("abc"));
        if head.starts_with(b"Ogawa") || (abc && head.starts_with(b"\x89HDF")) {
            return Some(Self::Alembic);
        }
        let usd = path.extension().and_then(|x| x.to_str()).is_some_and(|x| {
            ["usd", "usda", "usdc", "usdz"].contains(&x.to_ascii_lowercase().as_str())
        });
        let text_start = head.strip_prefix("\u{feff}".as_bytes()).unwrap_or(&head);
        if text_start.starts_with(b"#usda ") || head.starts_with(b"PXR-USDC") || usd {
            return Some(Self::Usd);
        }
        let text = String::from_utf8_lossy(&head);
        let text = text.trim_start_matches('\u{feff}').trim_start();
        if text.starts_with('<') {
            // An OpenCV XML FileStorage is OpenCV's (which says how to convert it).
            return Some(if text.contains("<opencv_storage") {
                Self::Opencv
            } else {
                Self::Metashape
            });
        }
        let sfm = path
            .extension()
            .is_some_and(|x| x.eq_ignore_ascii_case("sfm"));
        if text.starts_with('{')
            && (sfm || (text.contains("\"viewId\"") && text.contains("\"poseId\"")))
        {
            return Some(Self::AliceVision);
        }
        if text.starts_with('{') {
            return Some(
                if text.contains("\"transform_matrix\"") || text.contains("\"camera_angle_x\"") {
                    Self::Nerfstudio
                } else {
                    Self::Opencv
                },
            );
        }
        let table = text.lines().any(|l| {
            let l = l.trim();
            l.starts_with('[') && l.ends_with(']') && !l.contains(',')
        });
        let assignment = text.lines().any(|l| {
            let l = l.trim_start();
            l.starts_with("matrix") && l["matrix".len()..].trim_start().starts_with('=')
        });
        if table && assignment {
            return Some(Self::Toml);
        }
        // OpenCV writes its directive, Kalibr never does.
        if text.starts_with("%YAML") {
            return Some(Self::Opencv);
        }
        let has = |key: &str| text.lines().any(|l| l.trim_start().starts_with(key));
        let kalibr = text.lines().any(|l| l.trim_end() == "cam0:")
            && has("intrinsics:")
            && (has("camera_model:") || has("T_cn_cnm1:"));
        kalibr.then_some(Self::Kalibr)
    }
}

/// `e`, a failure to read `input` as `format`, with a hint when the input looks like another
/// format (the commonest mistake: the wrong format named).
fn with_format_hint(e: Error, input: &Path, format: CalibrationFormat) -> Error {
    let Some(other) = CalibrationFormat::sniff(input).filter(|&f| f != format) else {
        return e;
    };
    let hint = format!(
        "(this looks like a `{}` calibration, not `{}`: give the format `{}`)",
        other.name(),
        format.name(),
        other.name()
    );
    match e {
        Error::Invalid {
            path,
            field,
            message,
        } => Error::Invalid {
            path,
            field,
            message: format!("{message} {hint}"),
        },
        Error::Io { path, error } => Error::Invalid {
            path,
            field: "(path)".into(),
            message: format!("{error} {hint}"),
        },
        other => other,
    }
}

//! The Python package `modelflow`: a thin layer over the Rust library, the same way the CLI is.
//! Scenes load from their files; images go in as `numpy` arrays of shape (H, W, 3) (float32 in
//! 0..1, or uint8), positions come out as float64 arrays of shape (V, 3); reports come back as
//! the dicts of the JSON the CLI writes. No algorithm lives here.

use ::modelflow as mf;
use mf::base::RgbImage;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;

create_exception!(
    modelflow,
    ModelflowError,
    PyException,
    "An error of modelflow: a bad file or value (the message names the file and field, or the option), or a failed run."
);

fn err(e: mf::Error) -> PyErr {
    ModelflowError::new_err(e.to_string())
}

/// A JSON-serialisable value as the Python object `json.loads` makes of it.
fn to_py<'py, T: serde::Serialize>(py: Python<'py>, v: &T) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(|e| ModelflowError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A (N, 3) float64 array of points.
fn points<'py>(
    py: Python<'py>,
    p: impl ExactSizeIterator<Item = [f64; 3]>,
) -> Bound<'py, PyArray2<f64>> {
    let n = p.len();
    let flat: Vec<f64> = p.flatten().collect();
    Array2::from_shape_vec((n, 3), flat)
        .expect("n rows of 3")
        .into_pyarray(py)
}

fn mesh_points<'py>(py: Python<'py>, m: &mf::base::Mesh) -> Bound<'py, PyArray2<f64>> {
    points(py, m.positions.iter().map(|p| [p.x, p.y, p.z]))
}

/// Options as a dict (the JSON names of `TrackOptions`, as in a run's `run.json`), laid over the
/// defaults; `None`: the defaults.
fn track_options(
    py: Python<'_>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<mf::TrackOptions> {
    let Some(d) = options else {
        return Ok(mf::TrackOptions::default());
    };
    let given: String = py.import("json")?.call_method1("dumps", (d,))?.extract()?;
    let given: serde_json::Value = serde_json::from_str(&given)
        .map_err(|e| ModelflowError::new_err(format!("options: {e}")))?;
    let mut base = serde_json::to_value(mf::TrackOptions::default())
        .map_err(|e| ModelflowError::new_err(e.to_string()))?;
    fn lay(base: &mut serde_json::Value, over: &serde_json::Value, path: &str) -> PyResult<()> {
        let (Some(b), Some(o)) = (base.as_object_mut(), over.as_object()) else {
            *base = over.clone();
            return Ok(());
        };
        for (k, v) in o {
            let here = if path.is_empty() {
                k.clone()
            } else {
                format!("{path}.{k}")
            };
            match b.get_mut(k) {
                Some(slot) if slot.is_object() => lay(slot, v, &here)?,
                Some(slot) => *slot = v.clone(),
                None => {
                    return Err(ModelflowError::new_err(format!(
                        "options: unknown option {here:?}; the options are {}",
                        b.keys().cloned().collect::<Vec<_>>().join(", ")
                    )))
                }
            }
        }
        Ok(())
    }
    lay(&mut base, &given, "")?;
    let opts: mf::TrackOptions = serde_json::from_value(base)
        .map_err(|e| ModelflowError::new_err(format!("options: {e}")))?;
    opts.validate().map_err(err)?;
    Ok(opts)
}

/// An image from a (H, W, 3) numpy array, float32 in 0..1 or uint8.
fn image(i: usize, a: &Bound<'_, PyAny>) -> PyResult<RgbImage> {
    if let Ok(arr) = a.extract::<PyReadonlyArray3<f32>>() {
        return image_from(i, arr, |c| c);
    }
    if let Ok(arr) = a.extract::<PyReadonlyArray3<u8>>() {
        return image_from(i, arr, |c| c as f32 / 255.0);
    }
    Err(ModelflowError::new_err(format!(
        "images[{i}]: expected a numpy array of float32 (0..1) or uint8, shape (height, width, 3)"
    )))
}

/// The image of a (H, W, 3) array whose values `value` turns into 0..1.
fn image_from<T: numpy::Element + Copy>(
    i: usize,
    arr: PyReadonlyArray3<'_, T>,
    value: impl Fn(T) -> f32,
) -> PyResult<RgbImage> {
    let v = arr.as_array();
    let &[h, w, 3] = v.shape() else {
        return Err(ModelflowError::new_err(format!(
            "images[{i}]: expected an array of shape (height, width, 3), got shape {:?}",
            v.shape()
        )));
    };
    let data = v
        .outer_iter()
        .flat_map(|row| {
            row.outer_iter()
                .map(|px| [value(px[0]), value(px[1]), value(px[2])])
                .collect::<Vec<_>>()
        })
        .collect();
    RgbImage::from_pixels(w, h, data)
        .ok_or_else(|| ModelflowError::new_err(format!("images[{i}]: empty image")))
}

fn image_array<'py>(py: Python<'py>, img: &RgbImage) -> Bound<'py, PyArray3<f32>> {
    let flat: Vec<f32> = img.pixels().iter().flatten().copied().collect();
    Array3::from_shape_vec((img.height(), img.width(), 3), flat)
        .expect("h × w × 3")
        .into_pyarray(py)
}

/// A scene: calibrated cameras, footage and the mesh lined up with the first frame
/// (`docs/scene-format.md`).
#[pyclass(name = "Scene", module = "modelflow", frozen)]
struct Scene {
    inner: mf::Scene,
}

#[pymethods]
impl Scene {
    /// Loads and checks a scene file (`modelflow-scene/1`); `cameras` (names) and `frames`
    /// (`(first, last)`) load only that part, whose images alone are checked (`track
    /// --cameras`, `--frames`).
    #[staticmethod]
    #[pyo3(signature = (path, cameras=None, frames=None))]
    fn load(
        path: PathBuf,
        cameras: Option<Vec<String>>,
        frames: Option<(u32, u32)>,
    ) -> PyResult<Self> {
        let selection = mf::input::Selection { cameras, frames };
        Ok(Scene {
            inner: mf::Scene::load_selected(&path, &selection).map_err(err)?,
        })
    }

    /// The same scene restricted to frames `first..=last` (the mesh is taken as lined up with
    /// `first`).
    fn with_frames(&self, first: u32, last: u32) -> PyResult<Self> {
        Ok(Scene {
            inner: self.inner.with_frames(first, last).map_err(err)?,
        })
    }

    /// The first frame.
    #[getter]
    fn first(&self) -> u32 {
        self.inner.first
    }

    /// The last frame.
    #[getter]
    fn last(&self) -> u32 {
        self.inner.last
    }

    /// The cameras' names, in the scene's order.
    #[getter]
    fn cameras(&self) -> Vec<String> {
        self.inner.cameras.iter().map(|c| c.name.clone()).collect()
    }

    /// The scene's length unit ("m", "cm", "mm") or None.
    #[getter]
    fn units(&self) -> Option<&'static str> {
        self.inner.units.map(|u| u.name())
    }

    /// The mesh's vertex positions at the first frame, (V, 3) float64.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        mesh_points(py, &self.inner.mesh)
    }

    /// The mesh's triangles, (T, 3) uint32 vertex indices.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<u32>> {
        let n = self.inner.mesh.triangles.len();
        let flat: Vec<u32> = self
            .inner
            .mesh
            .triangles
            .iter()
            .flatten()
            .copied()
            .collect();
        Array2::from_shape_vec((n, 3), flat)
            .expect("n × 3")
            .into_pyarray(py)
    }

    /// Every camera's image of `frame`, as the tracker sees it (undistorted when the camera has
    /// a lens): a list of (H, W, 3) float32 arrays in 0..1.
    fn load_images<'py>(
        &self,
        py: Python<'py>,
        frame: u32,
    ) -> PyResult<Vec<Bound<'py, PyArray3<f32>>>> {
        let imgs = self.inner.load_images(frame).map_err(err)?;
        Ok(imgs.iter().map(|i| image_array(py, i)).collect())
    }

    /// The ground-truth positions at `frame`, (V, 3) float64, or None without ground truth.
    fn ground_truth<'py>(
        &self,
        py: Python<'py>,
        frame: u32,
    ) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        Ok(self
            .inner
            .ground_truth(frame)
            .transpose()
            .map_err(err)?
            .map(|m| mesh_points(py, &m)))
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene({:?}: frames {}..={}, {} cameras, {} vertices)",
            self.inner.path.display().to_string(),
            self.inner.first,
            self.inner.last,
            self.inner.cameras.len(),
            self.inner.mesh.positions.len()
        )
    }
}

/// The Model Flow tracker in memory: images in, positions out, one frame at a time.
#[pyclass(name = "Tracker", module = "modelflow", unsendable)]
struct Tracker {
    inner: mf::Tracker,
}

#[pymethods]
impl Tracker {
    /// A tracker at the scene's first frame, with the scene's mesh and cameras. `images`: the
    /// first frame's images (default: read from the scene). `options`: a dict of tracker
    /// options by their JSON names (as in a run's `run.json`, e.g. `{"levels": 3,
    /// "regularisation": {"spring_k": 0.5}}`), laid over the defaults.
    #[new]
    #[pyo3(signature = (scene, images=None, options=None))]
    fn new(
        py: Python<'_>,
        scene: &Scene,
        images: Option<Vec<Bound<'_, PyAny>>>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let s = &scene.inner;
        let opts =
            track_options(py, options)?.resolved_for(s.cameras.iter().map(|c| (c.width, c.height)));
        let first = match images {
            Some(a) => a
                .iter()
                .enumerate()
                .map(|(i, a)| image(i, a))
                .collect::<PyResult<Vec<_>>>()?,
            None => s.load_images(s.first).map_err(err)?,
        };
        Ok(Tracker {
            inner: mf::Tracker::new(&s.mesh, s.cameras.clone(), s.first, &first, opts)
                .map_err(err)?,
        })
    }

    /// Solves `frame` from its images (one (H, W, 3) array per camera, in the scene's camera
    /// order): the mesh moves there. Returns the frame's report as a dict (iterations, costs,
    /// stop reason, timing, per-level solver summaries) with the per-vertex confidence added as
    /// float64 arrays: "information", "residual", "sigma".
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        frame: u32,
        images: Vec<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let imgs = images
            .iter()
            .enumerate()
            .map(|(i, a)| image(i, a))
            .collect::<PyResult<Vec<_>>>()?;
        let report = self.inner.step(frame, &imgs).map_err(err)?;
        let d = to_py(py, &report)?;
        let col = |f: fn(&mf::tracker::VertexConfidence) -> f64| -> Bound<'py, PyArray1<f64>> {
            Array1::from_iter(report.confidence.iter().map(f)).into_pyarray(py)
        };
        d.set_item("information", col(|c| c.information))?;
        d.set_item("residual", col(|c| c.residual))?;
        d.set_item("sigma", col(|c| c.sigma()))?;
        Ok(d)
    }

    /// The current vertex positions, (V, 3) float64.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points(py, self.inner.positions().iter().map(|p| [p.x, p.y, p.z]))
    }

    /// When the scene's mesh lay off the surface the cameras agree on and was moved onto it
    /// before tracking (option "onto_surface", on by default): a dict with "found" (the
    /// check's "pixels", "length", "ratio", "at_limit", "closed", "compared", "texture_kept")
    /// and how far the vertices moved ("median", "max", scene units), as `run.json`'s
    /// `first_mesh_moved`; else None.
    #[getter]
    fn first_mesh_moved<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner
            .first_mesh_moved()
            .map(|m| to_py(py, m))
            .transpose()
    }

    /// The shifts of the cameras' images at which they agree best about the first mesh
    /// (option "shift_cameras", on by default): a dict with "shifts" (one `[dx, dy]` per
    /// camera, pixels), "pairs", "cost_before", "cost_after" and "applied", as `run.json`'s
    /// `camera_shifts`; the tracker sees every camera shifted by them when "applied". None when
    /// not measured or no two cameras compare the mesh.
    #[getter]
    fn camera_shifts<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner.camera_shifts().map(|s| to_py(py, s)).transpose()
    }
}

/// Tracks the whole scene into the run folder `out` (as `modelflow track` does: one OBJ and one
/// confidence file per frame, `log.jsonl`, `run.json`). `options` as for `Tracker`. `force`
/// replaces an earlier run's files there. `device` is "cpu" or "gpu" (the solver's per-pixel
/// work on an NVIDIA GPU, as `--device gpu`). Returns the summary as a dict.
#[pyfunction]
#[pyo3(signature = (scene, out, options=None, force=false, device="cpu"))]
fn track_scene<'py>(
    py: Python<'py>,
    scene: &Scene,
    out: PathBuf,
    options: Option<&Bound<'py, PyDict>>,
    force: bool,
    device: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let opts = track_options(py, options)?;
    let gpu = match device {
        "cpu" => None,
        "gpu" => Some(std::sync::Arc::new(mf::tracker::Gpu::open().map_err(err)?)),
        other => {
            return Err(ModelflowError::new_err(format!(
                "device {other:?}: expected \"cpu\" or \"gpu\""
            )))
        }
    };
    let run = mf::RunOptions {
        mode: if force {
            mf::OpenMode::Force
        } else {
            mf::OpenMode::New
        },
        gpu,
        ..mf::RunOptions::default()
    };
    let summary = mf::track_scene(&scene.inner, &opts, &out, &run, &mut |_| {}).map_err(err)?;
    to_py(py, &summary)
}

/// Runs the optical-flow baseline (pyramidal Lucas–Kanade per camera, then triangulation; as
/// `modelflow baseline` does with its defaults) over the whole scene into the run folder `out`,
/// a run folder like the tracker's, for `evaluate` and `report`. `force` replaces an earlier
/// run's files there. Returns {"solved": frames solved, "median_frame_seconds": ...}.
#[pyfunction]
#[pyo3(signature = (scene, out, force=false))]
fn baseline<'py>(
    py: Python<'py>,
    scene: &Scene,
    out: PathBuf,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let run = mf::RunOptions {
        mode: if force {
            mf::OpenMode::Force
        } else {
            mf::OpenMode::New
        },
        ..mf::RunOptions::default()
    };
    let summary = mf::baseline::run(
        &scene.inner,
        &mf::BaselineOptions::default(),
        &out,
        &run,
        &|_| {},
    )
    .map_err(err)?;
    let d = PyDict::new(py);
    d.set_item("solved", summary.frames.len())?;
    d.set_item(
        "median_frame_seconds",
        mf::tracker::median(&summary.seconds),
    )?;
    Ok(d)
}

/// Writes the HTML report comparing runs, as `modelflow report` does: `runs` maps each run's
/// name to its folder (e.g. {"Model Flow": "run", "LK": "lk"}); `frames` the frames to draw
/// (default: first, middle, last and the first frame each run doubts); `flipbook` every frame's
/// overlays; `shared_scale` one error colour scale for all runs; `residual_frame` the frame
/// whose photometric residual is drawn (default: the last). Returns {"index": the page,
/// "files": every other file written, "frames": the frames drawn}.
#[pyfunction]
#[pyo3(signature = (scene, runs, out, frames=None, flipbook=true, shared_scale=false, residual_frame=None))]
#[allow(clippy::too_many_arguments)]
fn report<'py>(
    py: Python<'py>,
    scene: &Scene,
    runs: &Bound<'py, PyDict>,
    out: PathBuf,
    frames: Option<Vec<u32>>,
    flipbook: bool,
    shared_scale: bool,
    residual_frame: Option<u32>,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = mf::ReportOptions {
        frames,
        flipbook,
        shared_error_scale: shared_scale,
        residual_frame,
        ..mf::ReportOptions::default()
    };
    // In the dict's order, which is the page's.
    let runs: Vec<(String, PathBuf)> = runs
        .iter()
        .map(|(k, v)| Ok((k.extract()?, v.extract()?)))
        .collect::<PyResult<_>>()?;
    let summary = mf::write_report(&scene.inner, &runs, &opts, &out).map_err(err)?;
    let d = PyDict::new(py);
    d.set_item("index", summary.index)?;
    d.set_item("files", summary.files)?;
    d.set_item("frames", summary.frames)?;
    Ok(d)
}

/// Scores a run folder (one OBJ per frame) against the scene's ground truth; returns the report
/// as a dict (per-frame RMS and max error, means, the same over the seen vertices; lengths in
/// the scene's unit, named by "units").
#[pyfunction]
fn evaluate<'py>(py: Python<'py>, scene: &Scene, run: PathBuf) -> PyResult<Bound<'py, PyAny>> {
    let frames = mf::read_run(&run).map_err(err)?;
    let report = mf::evaluate(&scene.inner, &frames).map_err(err)?;
    to_py(py, &report)
}

/// The frames of the scene's range that the tracker's checks flag in the run folder `run`, and
/// why (as `track` said while it ran and the report lists them): a list of {"frame": N,
/// "concerns": [...]}, or None when the folder has no tracker log.
#[pyfunction]
fn frames_to_check<'py>(
    py: Python<'py>,
    scene: &Scene,
    run: PathBuf,
) -> PyResult<Bound<'py, PyAny>> {
    let checks = mf::frames_to_check(&run, scene.inner.first, scene.inner.last).map_err(err)?;
    to_py(py, &checks)
}

/// Writes a run folder as one animated file for a 3D package; the format comes from `out`'s
/// extension (.usda, .abc, .glb, .pc2, .mdd). Returns the files written. USD and Alembic carry the
/// scene's cameras; when the run's scene file cannot be read, they hold the mesh alone and warn
/// why (`UserWarning`); so does a point cache whose mesh has vertices no face uses (Blender's
/// OBJ importer drops them).
#[pyfunction]
#[pyo3(signature = (run, out, fps=24.0))]
fn export(py: Python<'_>, run: PathBuf, out: PathBuf, fps: f64) -> PyResult<Vec<PathBuf>> {
    let format = mf::export::ExportFormat::from_path(&out).ok_or_else(|| {
        ModelflowError::new_err(format!(
            "{}: give a file ending in .usda, .abc, .glb, .pc2 or .mdd",
            out.display()
        ))
    })?;
    let opts = mf::export::ExportOptions {
        fps,
        ..Default::default()
    };
    let summary = mf::export::export_run(&run, format, &out, &opts).map_err(err)?;
    for w in summary.warnings() {
        let msg = std::ffi::CString::new(w).unwrap_or_default();
        PyErr::warn(
            py,
            &py.get_type::<pyo3::exceptions::PyUserWarning>(),
            &msg,
            1,
        )?;
    }
    Ok(summary.files)
}

/// Writes synthetic multi-view footage with ground truth into the folder `out`, as `modelflow
/// synth` does (a scene file, images, the first mesh and the true mesh of every frame), and
/// returns the scene file's path. `preset`: "cloth", "blob", "irregular", "limb" or "crossing";
/// the other arguments are `synth`'s options (`distortion` as "opencv:k1,k2,p1,p2,k3" or
/// "fisheye:k1,k2,k3,k4", `bump` as "CAMERA:FRAME:DEGREES"); `None` keeps the preset's default.
#[pyfunction]
#[pyo3(signature = (out, preset="cloth", cameras=None, width=640, height=480, frames=120, noise=0.0, seed=1, light=true, supersample=None, shake=0.0, distortion=None, cloth_grid=None, sync_error=0.0, motion_blur=0.0, rolling_shutter=0.0, turn=0.0, backdrop=false, bump=None))]
#[allow(clippy::too_many_arguments)]
fn synth(
    out: PathBuf,
    preset: &str,
    cameras: Option<usize>,
    width: u32,
    height: u32,
    frames: u32,
    noise: f64,
    seed: u64,
    light: bool,
    supersample: Option<u32>,
    shake: f64,
    distortion: Option<&str>,
    cloth_grid: Option<usize>,
    sync_error: f64,
    motion_blur: f64,
    rolling_shutter: f64,
    turn: f64,
    backdrop: bool,
    bump: Option<&str>,
) -> PyResult<PathBuf> {
    let base = mf::synth::SynthOptions::preset(preset).map_err(err)?;
    let distortion = distortion
        .map(|d| {
            d.parse::<mf::base::Distortion>()
                .map_err(|m| ModelflowError::new_err(format!("distortion: {m}")))
        })
        .transpose()?;
    let bump = bump
        .map(|b| {
            b.parse::<mf::synth::Bump>()
                .map_err(|m| ModelflowError::new_err(format!("bump: {m}")))
        })
        .transpose()?;
    let opts = mf::synth::SynthOptions {
        cameras,
        width,
        height,
        frames,
        noise,
        light,
        seed,
        supersample: supersample.unwrap_or(base.supersample),
        shake,
        distortion,
        cloth_grid: cloth_grid.unwrap_or(base.cloth_grid),
        sync_error,
        motion_blur,
        rolling_shutter,
        turn,
        backdrop,
        bump,
        ..base
    };
    mf::synth::Synthetic::generate(&opts)
        .and_then(|s| s.write(&out, &|_, _| {}))
        .map_err(err)
}

/// Reads another tool's calibration and makes a scene file of it, as `modelflow import` does:
/// `format` is "colmap" (a sparse model folder), "opencv" (a FileStorage .yml/.json), "metashape"
/// (a camera XML), "nerfstudio" (a transforms.json), "toml" (anipose, Pose2Sim, FreeMoCap or
/// caliscope TOML; also by those names), "kalibr" (a camchain.yaml), "mrcal" (a .cameramodel
/// or a folder of them), "alembic" (the cameras of an .abc file), "usd" (the cameras of a .usda
/// file) or "alicevision" (a Meshroom SfM file, cameras.sfm; also "meshroom"), or "auto"
/// (whichever of these the input is). `mesh`, `images` (with `{camera}`) and
/// `frames` are what the scene file names; `size` (w, h) for cameras whose file gives none;
/// `chunk` a Metashape chunk; `units` "m", "cm" or "mm"; `before_applied_transform` the world
/// before a nerfstudio file's applied_transform. With `out`, the scene file is written there (an
/// existing one is replaced only with `force`). Returns a dict: "scene" (the scene file's
/// content), "notes" (what to know about the file as a whole) and "written" (the path, or None).
#[pyfunction]
#[pyo3(signature = (format, input, out=None, mesh="mesh/initial.obj", images="images/{camera}/{frame:04}.png", frames=(0, 0), size=None, chunk=None, units=None, before_applied_transform=false, force=false))]
#[allow(clippy::too_many_arguments)]
fn import_calibration<'py>(
    py: Python<'py>,
    format: &str,
    input: PathBuf,
    out: Option<PathBuf>,
    mesh: &str,
    images: &str,
    frames: (u32, u32),
    size: Option<(u32, u32)>,
    chunk: Option<String>,
    units: Option<&str>,
    before_applied_transform: bool,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    use mf::input::calib::{import_calibration, CalibrationFormat, ImportOptions};
    let format: CalibrationFormat = if format.eq_ignore_ascii_case("auto") {
        CalibrationFormat::detect(&input).map_err(err)?
    } else {
        format.parse().map_err(err)?
    };
    let units = units
        .map(|u| {
            u.parse::<mf::base::Units>()
                .map_err(|_| err(mf::Error::option("units", u, "m, cm or mm")))
        })
        .transpose()?;
    if let Some(o) = out.as_ref().filter(|o| o.exists() && !force) {
        return Err(ModelflowError::new_err(format!(
            "{} exists; give force=True to replace it",
            o.display()
        )));
    }
    let opts = ImportOptions {
        mesh: mesh.into(),
        images: images.into(),
        frames,
        size,
        chunk,
        units,
        before_applied_transform,
    };
    let imported = import_calibration(format, &input, &opts).map_err(err)?;
    if let Some(o) = &out {
        imported.file.write(o).map_err(err)?;
    }
    let d = PyDict::new(py);
    d.set_item("scene", to_py(py, &imported.file)?)?;
    d.set_item("notes", imported.notes)?;
    d.set_item("written", out)?;
    Ok(d)
}

/// Lines up a mesh with the scene's first frame, as `modelflow align` does: the rigid pose (and
/// with `scale` one uniform scale) that makes every camera agree about the surface. `positions`:
/// the rough placement, (V, 3) (default: the scene's mesh). Returns a dict: "positions" (V, 3),
/// "rotation" (3×3), "translation", "scale" (`X' = scale·R·X + t`), "angle_deg", "levels" (per
/// pyramid level: rounds, iterations, costs) and "loose" (the motions the images hold loosely,
/// with their relative stiffness; below 1e-6 they were kept as placed, or with `outline` set
/// from the contrast across the mesh's border, summarised in "outline"); "passes" and
/// "kept_pass" (the coarse-to-fine passes solved and which one the result is from; `search`
/// adds starts around the placement given, as `modelflow align` does unless `--no-search`);
/// "enlarged" (how many times the images' resolution the cameras were compared at: `enlarge`,
/// 0 chooses as `modelflow align --enlarge` does).
#[pyfunction]
#[pyo3(signature = (scene, positions=None, scale=false, outline=false, search=true, enlarge=0))]
fn align<'py>(
    py: Python<'py>,
    scene: &Scene,
    positions: Option<PyReadonlyArray2<'py, f64>>,
    scale: bool,
    outline: bool,
    search: bool,
    enlarge: u32,
) -> PyResult<Bound<'py, PyDict>> {
    let s = &scene.inner;
    let mesh = scene_mesh(s, positions)?;
    let images = s.load_images(s.first).map_err(err)?;
    let opts = mf::tracker::AlignOptions {
        scale,
        outline,
        search,
        enlarge,
        ..Default::default()
    };
    let a = mf::tracker::align(&mesh, &s.cameras, s.first, &images, &opts).map_err(err)?;
    let d = PyDict::new(py);
    d.set_item(
        "positions",
        points(py, a.positions.iter().map(|p| [p.x, p.y, p.z])),
    )?;
    let r: Vec<Vec<f64>> = (0..3)
        .map(|i| (0..3).map(|j| a.rotation[(i, j)]).collect())
        .collect();
    d.set_item("rotation", r)?;
    d.set_item(
        "translation",
        vec![a.translation.x, a.translation.y, a.translation.z],
    )?;
    d.set_item("scale", a.scale)?;
    d.set_item("angle_deg", a.angle_deg())?;
    d.set_item("levels", to_py(py, &a.levels)?)?;
    d.set_item("loose", to_py(py, &a.loose)?)?;
    d.set_item("outline", to_py(py, &a.outline)?)?;
    d.set_item("agreement", to_py(py, &a.agreement)?)?;
    d.set_item("passes", to_py(py, &a.passes)?)?;
    d.set_item("kept_pass", a.kept_pass)?;
    d.set_item("enlarged", a.enlarged)?;
    Ok(d)
}

/// How much of the mesh's surface the cameras see at the scene's first frame, by area, as a
/// dict: "two_or_more" (depth from the images), "one" (depth from the regularisers alone),
/// "none". `options` as for `Tracker` (its "min_cos" and "margin" decide what counts as seen).
#[pyfunction]
#[pyo3(signature = (scene, options=None))]
fn coverage<'py>(
    py: Python<'py>,
    scene: &Scene,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let opts = track_options(py, options)?;
    let s = &scene.inner;
    to_py(
        py,
        &mf::tracker::coverage(&s.mesh, &s.cameras, s.first, &opts),
    )
}

/// The cameras that see none of the mesh at the scene's first frame, as a list of dicts:
/// "camera" (its name), "index", "why" ("behind": every vertex is behind it;
/// "outside_image": in front, but none projects inside its image) and "message" (what `track`
/// prints: the likely mistake in its calibration). Empty when every camera sees some of it.
#[pyfunction]
fn blind_cameras<'py>(py: Python<'py>, scene: &Scene) -> PyResult<Bound<'py, PyList>> {
    let out = PyList::empty(py);
    for b in scene.inner.blind_cameras() {
        let d = PyDict::new(py);
        d.set_item("camera", &b.name)?;
        d.set_item("index", b.index)?;
        d.set_item(
            "why",
            match b.why {
                mf::input::Blind::Behind => "behind",
                mf::input::Blind::OutsideImage { .. } => "outside_image",
            },
        )?;
        d.set_item("message", b.to_string())?;
        out.append(d)?;
    }
    Ok(out)
}

/// The cameras whose principal point lies more than a fifth of the image from its centre, as
/// a list of dicts: "camera", "index", "cx", "cy", "message" (the likely cause: a K made at
/// another resolution than the footage's, and the scale to apply). Empty when none does.
#[pyfunction]
fn off_centre_principal_points<'py>(
    py: Python<'py>,
    scene: &Scene,
) -> PyResult<Bound<'py, PyList>> {
    let out = PyList::empty(py);
    for o in scene.inner.off_centre_principal_points() {
        let d = PyDict::new(py);
        d.set_item("camera", &o.name)?;
        d.set_item("index", o.index)?;
        d.set_item("cx", o.cx)?;
        d.set_item("cy", o.cy)?;
        d.set_item("message", o.to_string())?;
        out.append(d)?;
    }
    Ok(out)
}

/// The cameras whose image file at the first frame asks viewers to turn or mirror it (its EXIF
/// orientation: a phone's JPEG shot upright), as a list of dicts: "camera", "index", "file",
/// "turn" (in words) and "message". modelflow reads the pixels as stored. Empty when none does.
#[pyfunction]
fn turned_images<'py>(py: Python<'py>, scene: &Scene) -> PyResult<Bound<'py, PyList>> {
    let out = PyList::empty(py);
    for t in scene.inner.turned_images() {
        let d = PyDict::new(py);
        d.set_item("camera", &t.name)?;
        d.set_item("index", t.index)?;
        d.set_item("file", t.file.to_string_lossy())?;
        d.set_item("turn", t.turn)?;
        d.set_item("message", t.to_string())?;
        out.append(d)?;
    }
    Ok(out)
}

/// The mesh's size in the images at the scene's first frame when it is too small to track
/// (under 8 px) or many times the images (over 10 times their diagonal), as a dict: "pixels"
/// (the projected vertices' bounding-box diagonal, median over the cameras), "image" (the
/// images' diagonal) and "message"; `None` otherwise. Almost always a mesh in another unit
/// than the calibration.
#[pyfunction]
fn mesh_out_of_scale<'py>(py: Python<'py>, scene: &Scene) -> PyResult<Option<Bound<'py, PyDict>>> {
    scene
        .inner
        .mesh_out_of_scale()
        .map(|m| {
            let d = PyDict::new(py);
            d.set_item("pixels", m.pixels)?;
            d.set_item("image", m.image)?;
            d.set_item("message", m.to_string())?;
            Ok(d)
        })
        .transpose()
}

/// The scene's mesh, or the same triangles at `positions` ((V, 3), checked).
fn scene_mesh(
    s: &mf::Scene,
    positions: Option<PyReadonlyArray2<'_, f64>>,
) -> PyResult<mf::base::Mesh> {
    Ok(match positions {
        None => s.mesh.clone(),
        Some(a) => {
            let a = a.as_array();
            let n = s.mesh.positions.len();
            if a.shape() != [n, 3] {
                return Err(ModelflowError::new_err(format!(
                    "positions: expected shape ({n}, 3) (one row per mesh vertex), got {:?}",
                    a.shape()
                )));
            }
            let p = a
                .rows()
                .into_iter()
                .map(|r| nalgebra::Point3::new(r[0], r[1], r[2]))
                .collect();
            s.mesh.with_positions(p)
        }
    })
}

/// What `modelflow track` checks about the first mesh before tracking, at the scene's first
/// frame, as a dict: "surface" (how far along its normals the cameras agree best: "pixels",
/// "length", "ratio", "at_limit", "closed"; None when no two cameras see a common triangle) and
/// "placement" (how far `align` would move it: "rms", "fraction" of its size, "degrees",
/// "translation", with the "loose_left_out" motions the images hold loosely, such as a nearly
/// round object's spin, left out; only for a mesh on the surface, off it by more than a
/// quarter of its size, which `track` does not move onto it, or off it by less where the rigid
/// move explains the cameras better than the move along the normals, else None); both with
/// "compared" (pixels compared where the mesh is), "texture_kept" (their texture where the
/// finding puts the mesh, over that where it is) and "disparity" (how many pixels of the frames
/// the move shifts where one camera's view of the surface lands in another's; absent when no
/// two cameras see a vertex well), and the placement "agreement_gain" (the cameras' cost where
/// the mesh is over that where `align` ends); "surface_off" and "misplaced" say whether either
/// is worth a warning (not from fewer than 200 pixels, nor keeping under a quarter of the
/// texture, nor a placement where the cameras agree less than 1.05 times better, nor an offset
/// along the normals whose disparity is under 1.5 px, which a calibration that far off explains
/// as well); "calibration_explains" is True for such an offset, and for a misplacement named
/// whose disparity is that small (a camera's calibration may be what is off); "axes_swapped": None, or {"swap": "y_up_to_z_up" | "z_up_to_y_up",
/// "gain", "message"} when the cameras agree at least 1.25 times better about the mesh with
/// its axes so swapped (a mesh exported with another up axis); "views": {"pairs": [{"a", "b"
/// (camera indices), "contrast" (their comparison's highest cost over its lowest as the mesh is
/// moved up to 10 px along its normals), "compared"}], "disagreeing": the names of the cameras
/// that agree with no other (contrast under 1.4) where another pair does, "none_agree": no pair
/// does}: a camera whose images are another's or from another frame, or whose calibration is
/// far off. `positions` ((V, 3)): another
/// placement of the scene's mesh.
#[pyfunction]
#[pyo3(signature = (scene, positions=None))]
fn first_mesh_check<'py>(
    py: Python<'py>,
    scene: &Scene,
    positions: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    let s = &scene.inner;
    let mesh = scene_mesh(s, positions)?;
    let images = s.load_images(s.first).map_err(err)?;
    // As `track` compares them: in luminance when colour and monochrome cameras mix.
    let images = mf::base::comparable(&images);
    let c = mf::tracker::first_mesh_check(&mesh, &s.cameras, s.first, &images);
    let d = PyDict::new(py);
    d.set_item("surface", to_py(py, &c.surface)?)?;
    d.set_item("placement", to_py(py, &c.placement)?)?;
    d.set_item("surface_off", c.surface.is_some_and(|o| o.is_off()))?;
    d.set_item("misplaced", c.placement.is_some_and(|p| p.is_off()))?;
    let views = mf::tracker::view_agreement(&mesh, &s.cameras, s.first, &images);
    let v = PyDict::new(py);
    v.set_item("pairs", to_py(py, &views.pairs)?)?;
    let names = |c: Vec<usize>| -> Vec<String> {
        c.into_iter().map(|c| s.cameras[c].name.clone()).collect()
    };
    v.set_item("disagreeing", names(views.disagreeing()))?;
    v.set_item("none_agree", views.none_agree())?;
    d.set_item("views", v)?;
    d.set_item(
        "calibration_explains",
        c.surface.is_some_and(|o| o.explained_by_calibration())
            || c.placement
                .is_some_and(|p| p.is_off() && p.calibration_may_explain()),
    )?;
    let axes = match mf::tracker::axes_swapped(&mesh, &s.cameras, s.first, &images) {
        None => None,
        Some(a) => {
            let e = PyDict::new(py);
            e.set_item(
                "swap",
                match a.swap {
                    mf::base::AxisSwap::YUpToZUp => "y_up_to_z_up",
                    mf::base::AxisSwap::ZUpToYUp => "z_up_to_y_up",
                },
            )?;
            e.set_item("gain", a.gain)?;
            e.set_item("message", a.to_string())?;
            Some(e)
        }
    };
    d.set_item("axes_swapped", axes)?;
    Ok(d)
}

/// Reads a run folder's frame meshes: {frame: (V, 3) float64 positions}.
#[pyfunction]
fn read_run<'py>(py: Python<'py>, run: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (f, m) in mf::read_run(&run).map_err(err)? {
        d.set_item(f, mesh_points(py, &m))?;
    }
    Ok(d)
}

#[pymodule]
#[pyo3(name = "modelflow")]
fn modelflow_py(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("ModelflowError", m.py().get_type::<ModelflowError>())?;
    m.add_class::<Scene>()?;
    m.add_class::<Tracker>()?;
    m.add_function(wrap_pyfunction!(track_scene, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(frames_to_check, m)?)?;
    m.add_function(wrap_pyfunction!(export, m)?)?;
    m.add_function(wrap_pyfunction!(read_run, m)?)?;
    m.add_function(wrap_pyfunction!(coverage, m)?)?;
    m.add_function(wrap_pyfunction!(blind_cameras, m)?)?;
    m.add_function(wrap_pyfunction!(mesh_out_of_scale, m)?)?;
    m.add_function(wrap_pyfunction!(off_centre_principal_points, m)?)?;
    m.add_function(wrap_pyfunction!(turned_images, m)?)?;
    m.add_function(wrap_pyfunction!(first_mesh_check, m)?)?;
    m.add_function(wrap_pyfunction!(align, m)?)?;
    m.add_function(wrap_pyfunction!(import_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(synth, m)?)?;
    m.add_function(wrap_pyfunction!(baseline, m)?)?;
    m.add_function(wrap_pyfunction!(report, m)?)?;
    Ok(())
}

//! The report a tracking artist shows their supervisor (thesis Fig. 7.3–7.6, 7.12–7.14): for a
//! scene and some runs, a folder with a per-frame error plot (PNG + SVG) — or, without ground
//! truth, a per-frame photometric cost plot — wireframe overlays of every run on the input images,
//! oblique views where depth errors show, meshes coloured by per-vertex error, and a
//! self-contained `index.html` tying them together with a summary table.
//!
//! Every file is written atomically (`fsutil`); the pictures come from `plot`, `overlay` and
//! `render`, the errors from `eval`, the photometric cost from `report::photometric`.

use super::{html, photometric, residual};

use crate::base::camera::{Camera, Projection};
use crate::base::image::RgbImage;
use crate::base::mesh::{centroid, Mesh};
use crate::base::units::Length;
use crate::error::{Error, Result};
use crate::fsutil;
use crate::input::imageio;
use crate::input::scene::Scene;
use crate::report::colormap;
use crate::report::draw::{self, Rgb};
use crate::report::eval::{self, EvalReport, FrameError};
use crate::report::flipbook;
use crate::report::overlay::{self, WireStyle};
use crate::report::plot::{Band, Dash, LinePlot, Series};
use crate::synth::render::{self, RenderOptions, Surface};
use crate::tracker::{FrameCheck, VertexConfidence};
use nalgebra::Point3;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// What the report shows.
#[derive(Clone, Debug, PartialEq)]
pub struct ReportOptions {
    /// Frames to draw overlays, oblique views and error maps for; `None`: first, middle, last, and each
    /// run's first frame to check (`RunSummary::checks`).
    pub frames: Option<Vec<u32>>,
    /// How far the oblique camera is turned about the vertical axis through the mesh centroid.
    pub oblique_degrees: f64,
    /// Camera images narrower than this are magnified (by a whole factor) for the panels.
    pub min_panel_width: usize,
    /// Write the flipbook (every frame's overlays, scrubbable in the page).
    pub flipbook: bool,
    /// One error colour scale for all runs (to compare them); otherwise each run's error map has
    /// its own scale, so that a good run's map is readable next to a bad one.
    pub shared_error_scale: bool,
    /// The frame whose photometric residual image is drawn (against the previous frame and the
    /// first); `None`: the last frame. Must be after the scene's first frame.
    pub residual_frame: Option<u32>,
}

impl Default for ReportOptions {
    fn default() -> Self {
        ReportOptions {
            frames: None,
            oblique_degrees: 60.0,
            min_panel_width: 480,
            flipbook: true,
            shared_error_scale: false,
            residual_frame: None,
        }
    }
}

/// The figures of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSummary {
    pub name: String,
    pub dir: PathBuf,
    /// Error against ground truth (when the scene has it).
    pub error: Option<EvalReport>,
    /// Photometric cost per scene frame (when the scene has no ground truth).
    pub photometric: Option<Vec<Option<f64>>>,
    /// Median wall time per solved frame from the run's log, image reading included (`None`
    /// without a log or lines).
    pub seconds_per_frame: Option<f64>,
    /// The frames the tracker's own checks flag, and why (`run::frames_to_check` over the
    /// run's `log.jsonl`); `None` when the run has no tracker log (the baseline, a bare folder).
    pub checks: Option<Vec<FrameCheck>>,
    /// When the tracker moved the run's first mesh onto the surface before tracking (the
    /// manifest's `first_mesh_moved`): the run's first frame is not the scene's mesh.
    pub first_mesh_moved: Option<crate::tracker::SurfaceMove>,
}

/// What [`write_report`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ReportSummary {
    /// `index.html`.
    pub index: PathBuf,
    /// Every other file written, in the report folder.
    pub files: Vec<PathBuf>,
    pub runs: Vec<RunSummary>,
    /// The frames the pictures were drawn for.
    pub frames: Vec<u32>,
    /// The photometric residual figure's numbers: per run and reference frame (the previous, then
    /// the first), the RMS residual over every camera's covered pixels; empty when not drawn.
    pub residual: Vec<ResidualRow>,
}

/// One row of the photometric residual figure.
#[derive(Clone, Debug, PartialEq)]
pub struct ResidualRow {
    pub run: String,
    /// The frame the residual is drawn at.
    pub frame: u32,
    /// The frame it is measured against.
    pub reference: u32,
    /// RMS over R, G, B and every covered pixel of every camera (images in 0..1).
    pub rms: f64,
}

/// One run as loaded: its mesh per scene frame.
struct Run {
    name: String,
    dir: PathBuf,
    /// `(frame, mesh)` for every scene frame, in order.
    meshes: Vec<(u32, Mesh)>,
}

impl Run {
    fn at(&self, scene: &Scene, frame: u32) -> &Mesh {
        &self.meshes[(frame - scene.first) as usize].1
    }
}

/// Writes the report for `runs` (name, run folder) on `scene` into `out_dir`, `index.html` first
/// among equals. Each run folder holds one OBJ per scene frame and, optionally, `log.jsonl`.
pub fn write_report(
    scene: &Scene,
    runs: &[(String, PathBuf)],
    opts: &ReportOptions,
    out_dir: &Path,
) -> Result<ReportSummary> {
    let deg = opts.oblique_degrees;
    if !(deg.is_finite() && (-180.0..=180.0).contains(&deg)) {
        return Err(Error::option(
            "--oblique-degrees",
            deg,
            "a number of degrees in [-180, 180]",
        ));
    }
    if runs.is_empty() {
        return Err(Error::option("runs", "none", "at least one run"));
    }
    for (i, (name, _)) in runs.iter().enumerate() {
        if name.trim().is_empty() {
            return Err(Error::option(
                format!("name of run {}", i + 1),
                "\"\"",
                "a name that is not empty",
            ));
        }
        if runs[..i].iter().any(|(n, _)| n == name) {
            return Err(Error::option(
                "two runs are named",
                format!("{name:?}"),
                "one name per run",
            ));
        }
    }
    // The given frames are checked before any run is read.
    chosen_frames(scene, opts.frames.as_deref(), &[])?;
    let residual_frame = match opts.residual_frame {
        Some(f) if !(scene.first < f && f <= scene.last) => {
            return Err(Error::option(
                "--residual-frame",
                f,
                format!(
                    "a frame after the scene's first: {}..={}",
                    scene.first + 1,
                    scene.last
                ),
            ));
        }
        Some(f) => Some(f),
        None => (scene.last > scene.first).then_some(scene.last),
    };
    let loaded: Vec<Run> = runs
        .iter()
        .map(|(name, dir)| load_run(scene, name, dir))
        .collect::<Result<_>>()?;
    // A camera the tracker found turned on its mount took its images turned: every mesh is
    // drawn over them through the cameras as that run used them (the first run that turned one).
    let as_used;
    let scene = match turned_in_runs(scene, runs)? {
        Some(cameras) => {
            as_used = Scene {
                cameras,
                ..scene.clone()
            };
            &as_used
        }
        None => scene,
    };
    let seconds: Vec<Option<f64>> = runs
        .iter()
        .map(|(_, dir)| seconds_per_frame(dir))
        .collect::<Result<_>>()?;
    let health: Vec<Option<Health>> = loaded
        .iter()
        .map(|r| read_health(scene, &r.dir).map_err(|e| context(&r.name, &r.dir, e)))
        .collect::<Result<_>>()?;
    // Drawn by default: first, middle, last, and each run's first frame to check.
    let first_flagged: Vec<u32> = health
        .iter()
        .flatten()
        .filter_map(|h| h.checks.first().map(|c| c.frame))
        .collect();
    let frames = chosen_frames(scene, opts.frames.as_deref(), &first_flagged)?;
    let bands = check_bands(&health);

    let has_truth = scene.ground_truth.is_some();
    let mut files = Vec::new();
    let mut summaries = Vec::new();
    let plot;
    if has_truth {
        let reports: Vec<EvalReport> = loaded
            .iter()
            .map(|r| eval::evaluate(scene, &r.meshes).map_err(|e| context(&r.name, &r.dir, e)))
            .collect::<Result<_>>()?;
        plot = LinePlot {
            title: "RMS vertex error against ground truth".into(),
            x_label: "frame".into(),
            y_label: "RMS vertex error (% of bbox diagonal)".into(),
            series: reports
                .iter()
                .zip(&loaded)
                .enumerate()
                .map(|(i, (rep, r))| Series {
                    dash: None,
                    name: r.name.clone(),
                    colour: colormap::run_colour(i),
                    points: rep
                        .per_frame
                        .iter()
                        .map(|e| [e.frame as f64, e.rms_pct])
                        .collect(),
                })
                .collect(),
            marks: frames.iter().map(|&f| f as f64).collect(),
            bands: bands.clone(),
            levels: Vec::new(),
            width: 960,
            height: 480,
        };
        // The same in length units (mm when the scene gives its unit).
        let len = Length::of(scene.units);
        let length_plot = LinePlot {
            title: "RMS vertex error against ground truth".into(),
            y_label: format!("RMS vertex error ({})", len.unit()),
            series: plot
                .series
                .iter()
                .zip(&reports)
                .map(|(s, rep)| Series {
                    points: rep
                        .per_frame
                        .iter()
                        .map(|e| [e.frame as f64, len.value(e.rms)])
                        .collect(),
                    ..s.clone()
                })
                .collect(),
            ..plot.clone()
        };
        // How the error spreads over the vertices, per frame: median, 90th percentile and max.
        let bands_plot = LinePlot {
            title: "Vertex error over the mesh: median, 90th percentile, max".into(),
            y_label: format!("vertex error ({})", len.unit()),
            series: reports
                .iter()
                .zip(&loaded)
                .enumerate()
                .flat_map(|(i, (rep, r))| {
                    let c = colormap::run_colour(i);
                    let fade = |t: f32| colormap::lighter(c, t);
                    let band: [(&str, f32, Statistic); 3] = [
                        ("median", 0.0, |e| e.median),
                        ("90th percentile", 0.35, |e| e.p90),
                        ("max", 0.6, |e| e.max),
                    ];
                    band.map(|(what, t, value)| Series {
                        dash: None,
                        name: format!("{} {what}", r.name),
                        colour: fade(t),
                        points: rep
                            .per_frame
                            .iter()
                            .map(|e| [e.frame as f64, len.value(value(e))])
                            .collect(),
                    })
                })
                .collect(),
            ..plot.clone()
        };
        // Where the error lies, per frame: the whole mesh's, the shape's alone once the best
        // rigid fit is taken out (misshaping against misplacement), and that of the vertices no
        // camera and only one camera sees (the regularisers' guess and depth from one view).
        let where_plot = LinePlot {
            title: "Where the error lies: the shape alone, and what few cameras see".into(),
            y_label: "RMS vertex error (% of bbox diagonal)".into(),
            series: reports
                .iter()
                .zip(&loaded)
                .enumerate()
                .flat_map(|(i, (rep, r))| {
                    let c = colormap::run_colour(i);
                    let fade = |t: f32| colormap::lighter(c, t);
                    let seen_by = |k: usize| -> Vec<[f64; 2]> {
                        rep.per_frame
                            .iter()
                            .filter_map(|e| {
                                let v = e.by_views.iter().find(|v| v.cameras == k)?;
                                Some([e.frame as f64, v.rms_pct])
                            })
                            .collect()
                    };
                    let lines: [(&str, f32, Dash, Vec<[f64; 2]>); 4] = [
                        (
                            "all",
                            0.0,
                            None,
                            rep.per_frame
                                .iter()
                                .map(|e| [e.frame as f64, e.rms_pct])
                                .collect(),
                        ),
                        (
                            "shape alone",
                            0.25,
                            Some([10.0, 5.0]),
                            rep.per_frame
                                .iter()
                                .map(|e| [e.frame as f64, e.shape_rms_pct])
                                .collect(),
                        ),
                        ("seen by none", 0.45, Some([2.0, 4.0]), seen_by(0)),
                        ("seen by one", 0.6, Some([6.0, 3.0]), seen_by(1)),
                    ];
                    lines
                        .into_iter()
                        .filter(|(_, _, _, points)| !points.is_empty())
                        .map(move |(what, t, dash, points)| Series {
                            name: format!("{} {what}", r.name),
                            colour: fade(t),
                            points,
                            dash,
                        })
                        .collect::<Vec<_>>()
                })
                .collect(),
            ..plot.clone()
        };
        let png = out_dir.join("error_where.png");
        let svg = out_dir.join("error_where.svg");
        imageio::write_png(&png, &where_plot.render())?;
        fsutil::write_atomic(&svg, where_plot.to_svg().as_bytes())?;
        files.push(png);
        files.push(svg);
        let png = out_dir.join("vertex_error_bands.png");
        let svg = out_dir.join("vertex_error_bands.svg");
        imageio::write_png(&png, &bands_plot.render())?;
        fsutil::write_atomic(&svg, bands_plot.to_svg().as_bytes())?;
        files.push(png);
        files.push(svg);
        let png = out_dir.join("error_length.png");
        let svg = out_dir.join("error_length.svg");
        imageio::write_png(&png, &length_plot.render())?;
        fsutil::write_atomic(&svg, length_plot.to_svg().as_bytes())?;
        files.push(png);
        files.push(svg);
        for (((r, rep), s), h) in loaded.iter().zip(reports).zip(&seconds).zip(&health) {
            summaries.push(RunSummary {
                name: r.name.clone(),
                dir: r.dir.clone(),
                error: Some(rep),
                photometric: None,
                seconds_per_frame: *s,
                checks: h.as_ref().map(|h| h.checks.clone()),
                first_mesh_moved: first_mesh_moved(&r.dir)
                    .map_err(|e| context(&r.name, &r.dir, e))?,
            });
        }
    } else {
        let meshes: Vec<Vec<&Mesh>> = loaded
            .iter()
            .map(|r| r.meshes.iter().map(|(_, m)| m).collect())
            .collect();
        let costs = photometric::cost_per_frame(scene, &meshes)?;
        plot = LinePlot {
            title: "Photometric cost (no ground truth)".into(),
            x_label: "frame".into(),
            y_label: format!(
                "mean squared RGB difference to frame {} (×10⁻³, RGB in 0–1)",
                scene.first
            ),
            series: costs
                .iter()
                .zip(&loaded)
                .enumerate()
                .map(|(i, (c, r))| Series {
                    dash: None,
                    name: r.name.clone(),
                    colour: colormap::run_colour(i),
                    points: scene
                        .frames()
                        .zip(c)
                        .map(|(f, v)| [f as f64, v.map_or(f64::NAN, |v| 1e3 * v)])
                        .collect(),
                })
                .collect(),
            marks: frames.iter().map(|&f| f as f64).collect(),
            bands: bands.clone(),
            levels: Vec::new(),
            width: 960,
            height: 480,
        };
        for (((r, c), s), h) in loaded.iter().zip(costs).zip(&seconds).zip(&health) {
            summaries.push(RunSummary {
                name: r.name.clone(),
                dir: r.dir.clone(),
                error: None,
                photometric: Some(c),
                seconds_per_frame: *s,
                checks: h.as_ref().map(|h| h.checks.clone()),
                first_mesh_moved: first_mesh_moved(&r.dir)
                    .map_err(|e| context(&r.name, &r.dir, e))?,
            });
        }
    }
    let plot_stem = if has_truth { "error" } else { "photometric" };
    let plot_png = out_dir.join(format!("{plot_stem}.png"));
    let plot_svg = out_dir.join(format!("{plot_stem}.svg"));
    imageio::write_png(&plot_png, &plot.render())?;
    fsutil::write_atomic(&plot_svg, plot.to_svg().as_bytes())?;
    files.push(plot_png.clone());
    files.push(plot_svg.clone());
    let checks_plotted = health.iter().any(Option::is_some);
    let mut cameras_plotted = false;
    if checks_plotted {
        for (stem, plot) in health_plots(scene, &loaded, &health, &plot, bands) {
            cameras_plotted |= stem == CAMERAS_PLOT;
            let png = out_dir.join(format!("{stem}.png"));
            let svg = out_dir.join(format!("{stem}.svg"));
            imageio::write_png(&png, &plot.render())?;
            fsutil::write_atomic(&svg, plot.to_svg().as_bytes())?;
            files.push(png);
            files.push(svg);
        }
    }

    let truth: Option<Vec<(u32, Mesh)>> = if has_truth {
        Some(
            frames
                .iter()
                .map(|&f| Ok((f, scene.ground_truth(f).expect("scene has ground truth")?)))
                .collect::<Result<_>>()?,
        )
    } else {
        None
    };
    let truth_at = |f: u32| {
        truth
            .as_ref()
            .and_then(|t| t.iter().find(|(g, _)| *g == f).map(|(_, m)| m))
    };

    let mut figures = html::Figures {
        coverage: crate::tracker::coverage(
            &scene.mesh,
            &scene.cameras,
            scene.first,
            &crate::tracker::TrackOptions::default(),
        ),
        ..html::Figures::default()
    };
    for &f in &frames {
        let images = scene.load_images(f)?;
        for (c, (cam, img)) in scene.cameras.iter().zip(&images).enumerate() {
            let sheet = overlay_sheet(scene, &loaded, f, c, img, opts)?;
            let name = format!("overlay_f{f:04}_c{c}_{}.png", file_safe(&cam.name));
            let path = out_dir.join(&name);
            imageio::write_png(&path, &sheet)?;
            files.push(path);
            figures
                .overlays
                .push((format!("{} — frame {f}", cam.name), name));
        }
        let sheet = oblique_sheet(scene, &loaded, truth_at(f), f, opts)?;
        let name = format!("oblique_f{f:04}.png");
        let path = out_dir.join(&name);
        imageio::write_png(&path, &sheet)?;
        files.push(path);
        figures.obliques.push((format!("frame {f}"), name));
    }
    if let Some(truth) = &truth {
        let max = error_scales(scene, &loaded, truth, opts.shared_error_scale);
        for (f, gt) in truth {
            let sheet = error_sheet(scene, &loaded, gt, *f, &max, opts)?;
            let name = format!("errormap_f{f:04}.png");
            let path = out_dir.join(&name);
            imageio::write_png(&path, &sheet)?;
            files.push(path);
            figures.error_maps.push((format!("frame {f}"), name));
        }
    }
    // Confidence maps of the runs that wrote confidence files, at the drawn frames that have them.
    let confidence: Vec<Vec<(u32, Vec<VertexConfidence>)>> = loaded
        .iter()
        .map(|r| {
            frames
                .iter()
                .filter_map(|&f| {
                    let p = r.dir.join(crate::run::confidence_file(f));
                    p.is_file().then(|| {
                        let c = crate::run::read_confidence(&p)?;
                        if c.len() != scene.mesh.positions.len() {
                            return Err(Error::invalid(
                                &p,
                                "rows",
                                format!(
                                    "{} vertices, but the scene mesh has {}",
                                    c.len(),
                                    scene.mesh.positions.len()
                                ),
                            ));
                        }
                        Ok((f, c))
                    })
                })
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<_>>()?;
    if let Some(scale) = sigma_scale(&confidence) {
        for &f in &frames {
            if let Some(sheet) = confidence_sheet(scene, &loaded, &confidence, f, scale, opts)? {
                let name = format!("confidence_f{f:04}.png");
                let path = out_dir.join(&name);
                imageio::write_png(&path, &sheet)?;
                files.push(path);
                figures.confidence_maps.push((format!("frame {f}"), name));
            }
        }
    }
    let mut residual_rows = Vec::new();
    if let Some(t) = residual_frame {
        let (sheet, rms) = residual_sheet(scene, &loaded, t, opts)?;
        let name = format!("residual_f{t:04}.png");
        let path = out_dir.join(&name);
        imageio::write_png(&path, &sheet)?;
        files.push(path);
        figures.residual = Some((t, name, rms.clone()));
        residual_rows = rms;
    }
    if opts.flipbook {
        let fb_frames = flipbook::frames(scene);
        let meshes: Vec<(&str, Vec<&Mesh>)> = loaded
            .iter()
            .map(|r| {
                (
                    r.name.as_str(),
                    fb_frames.iter().map(|&f| r.at(scene, f)).collect(),
                )
            })
            .collect();
        files.extend(flipbook::write(scene, &meshes, &fb_frames, out_dir)?);
        figures.flipbook = fb_frames;
    }
    let index = out_dir.join("index.html");
    figures.checks_plotted = checks_plotted;
    figures.cameras_plotted = cameras_plotted;
    let page = html::page(scene, &summaries, &frames, plot_stem, &figures, opts);
    fsutil::write_atomic(&index, page.as_bytes())?;
    Ok(ReportSummary {
        index,
        files,
        runs: summaries,
        frames,
        residual: residual_rows,
    })
}

fn context(name: &str, dir: &Path, e: Error) -> Error {
    Error::InRun {
        name: name.to_string(),
        dir: dir.to_path_buf(),
        error: Box::new(e),
    }
}

/// The frames to draw: the given ones (each in the scene), or first, middle, last and `also`
/// (each run's first frame to check).
fn chosen_frames(scene: &Scene, given: Option<&[u32]>, also: &[u32]) -> Result<Vec<u32>> {
    let mut frames = match given {
        Some(fs) if !fs.is_empty() => {
            if let Some(f) = fs.iter().find(|f| !scene.frames().contains(f)) {
                return Err(Error::option(
                    "frame",
                    f,
                    format!("a frame of the scene ({}..={})", scene.first, scene.last),
                ));
            }
            fs.to_vec()
        }
        _ => [
            scene.first,
            scene.first + (scene.last - scene.first) / 2,
            scene.last,
        ]
        .into_iter()
        .chain(also.iter().copied().filter(|f| scene.frames().contains(f)))
        .collect(),
    };
    frames.sort_unstable();
    frames.dedup();
    Ok(frames)
}

/// Reads a run folder and checks it has every scene frame with the scene mesh's topology.
fn load_run(scene: &Scene, name: &str, dir: &Path) -> Result<Run> {
    let mut got = crate::run::read_run(dir)?;
    got.retain(|(f, _)| scene.frames().contains(f));
    let missing: Vec<String> = scene
        .frames()
        .filter(|f| got.binary_search_by_key(f, |(g, _)| *g).is_err())
        .map(crate::run::frame_file)
        .collect();
    if !missing.is_empty() {
        let shown: Vec<&str> = missing.iter().take(5).map(String::as_str).collect();
        return Err(Error::invalid(
            dir,
            shown.join(", ") + if missing.len() > 5 { ", ..." } else { "" },
            format!(
                "run {name} lacks {} of the scene's frames {}..={} (one OBJ per frame expected)",
                missing.len(),
                scene.first,
                scene.last
            ),
        ));
    }
    for (f, m) in &got {
        if m.positions.len() != scene.mesh.positions.len() || m.triangles != scene.mesh.triangles {
            return Err(Error::invalid(
                dir.join(crate::run::frame_file(*f)),
                "faces",
                format!(
                    "run {name}: {} vertices / {} triangles, but the scene mesh has {} / {} (a run keeps the mesh's topology)",
                    m.positions.len(),
                    m.triangles.len(),
                    scene.mesh.positions.len(),
                    scene.mesh.triangles.len()
                ),
            ));
        }
    }
    Ok(Run {
        name: name.to_string(),
        dir: dir.to_path_buf(),
        meshes: got,
    })
}

/// What a run's tracker log says about its own frames.
struct Health {
    checks: Vec<FrameCheck>,
    /// Per logged frame: the information share and the contradicted share's rise over the first
    /// frame's, both as they are logged (shares, 0 to 1).
    measures: Vec<(u32, f64, f64)>,
    /// Per logged frame with each camera's own contradicted share (`contradicted_by_camera`),
    /// each camera's rise over its first frame's (shares); empty in logs without them.
    by_camera: Vec<(u32, Vec<f64>)>,
}

/// The tracker's checks on the scene's frames (`run::frames_to_check`) and its measures per
/// logged frame (the last line of a frame a resumed run logged twice); `None` without tracker
/// lines.
fn read_health(scene: &Scene, dir: &Path) -> Result<Option<Health>> {
    let lines = crate::run::read_frame_log(dir)?;
    let Some(checks) = crate::run::checks_in(dir, &lines, scene.first, scene.last)? else {
        return Ok(None);
    };
    let mut by_frame = std::collections::BTreeMap::new();
    let mut cameras = std::collections::BTreeMap::new();
    for l in &lines {
        if let Some(r) = l.model_flow().filter(|_| scene.frames().contains(&l.frame)) {
            by_frame.insert(
                l.frame,
                (
                    r.information_share,
                    r.contradicted_share - r.contradicted_at_first,
                ),
            );
            let (now, first) = (
                &r.contradicted_by_camera,
                &r.contradicted_by_camera_at_first,
            );
            if !now.is_empty() && now.len() == first.len() {
                // A camera not measured in either is a gap in its line.
                let rise = now
                    .iter()
                    .zip(first)
                    .map(|(n, f)| n.zip(*f).map_or(f64::NAN, |(n, f)| n - f))
                    .collect();
                cameras.insert(l.frame, rise);
            } else {
                cameras.remove(&l.frame);
            }
        }
    }
    let measures = by_frame.into_iter().map(|(f, (i, c))| (f, i, c)).collect();
    Ok(Some(Health {
        checks,
        measures,
        by_camera: cameras.into_iter().collect(),
    }))
}

/// The scene's cameras as the first of `runs` whose tracker found a camera turned on its mount
/// used them (`tracker::steady`, the log's `camera_turns`); `None` when no run turned one.
fn turned_in_runs(scene: &Scene, runs: &[(String, PathBuf)]) -> Result<Option<Vec<Camera>>> {
    for (_, dir) in runs {
        let lines = crate::run::read_frame_log(dir)?;
        let turns: Vec<(u32, Vec<[f64; 3]>)> = lines
            .iter()
            .filter_map(|l| Some((l.frame, l.model_flow()?.camera_turns.clone())))
            .collect();
        if turns.iter().any(|(_, t)| !t.is_empty()) {
            return Ok(Some(crate::tracker::steady::cameras_as_used(
                &scene.cameras,
                scene.first,
                &turns,
            )));
        }
    }
    Ok(None)
}

/// The manifest's `first_mesh_moved`, when the folder has a manifest.
fn first_mesh_moved(dir: &Path) -> Result<Option<crate::tracker::SurfaceMove>> {
    let manifest = dir.join(crate::run::MANIFEST);
    if !manifest.is_file() {
        return Ok(None);
    }
    Ok(crate::run::Manifest::read(&manifest)?.first_mesh_moved)
}

/// Band colours: suspect frames, stalled frames.
const SUSPECT_BAND: Rgb = [1.0, 0.55, 0.0];
const STALLED_BAND: Rgb = [0.85, 0.05, 0.05];

/// Shaded bands over the frames any run's checks flag (stalled over suspect), runs of
/// consecutive frames merged.
fn check_bands(health: &[Option<Health>]) -> Vec<Band> {
    let mut kind: std::collections::BTreeMap<u32, bool> = std::collections::BTreeMap::new();
    for c in health.iter().flatten().flat_map(|h| &h.checks) {
        *kind.entry(c.frame).or_default() |= c.stalled();
    }
    let mut bands: Vec<Band> = Vec::new();
    for (&f, &stalled) in &kind {
        let (colour, label) = if stalled {
            (STALLED_BAND, "stalled frames")
        } else {
            (SUSPECT_BAND, "suspect frames")
        };
        match bands.last_mut() {
            Some(b) if b.colour == colour && b.to == f as f64 - 0.5 => b.to = f as f64 + 0.5,
            _ => bands.push(Band {
                from: f as f64 - 0.5,
                to: f as f64 + 0.5,
                colour,
                label: label.into(),
            }),
        }
    }
    bands
}

/// The tracker's own measures per frame, one line per run with a log, each with the threshold
/// past which a frame is suspect: how much the images constrain the mesh, and how much the
/// cameras contradict where the previous frame left the surface; and, for the first run whose
/// log has them in a rig of three cameras or more, the same per camera
/// ([`CAMERAS_PLOT`], one line per camera, with the level a camera is named above).
fn health_plots(
    scene: &Scene,
    loaded: &[Run],
    health: &[Option<Health>],
    like: &LinePlot,
    bands: Vec<Band>,
) -> Vec<(&'static str, LinePlot)> {
    let series = |value: fn(&(u32, f64, f64)) -> f64| -> Vec<Series> {
        loaded
            .iter()
            .zip(health)
            .enumerate()
            .filter_map(|(i, (r, h))| {
                h.as_ref().map(|h| Series {
                    dash: None,
                    name: r.name.clone(),
                    colour: colormap::run_colour(i),
                    points: h
                        .measures
                        .iter()
                        .map(|m| [m.0 as f64, 100.0 * value(m)])
                        .collect(),
                })
            })
            .collect()
    };
    let floor = 100.0 * crate::tracker::INFORMATION_FLOOR;
    let rise = 100.0 * crate::tracker::SUSPECT_RISE;
    let per_camera = loaded.iter().zip(health).find_map(|(r, h)| {
        let h = h.as_ref()?;
        let n = h.by_camera.first()?.1.len();
        (n >= 3).then_some((r, h, n))
    });
    let cameras = per_camera.map(|(run, h, n)| {
        let named = 100.0 * crate::tracker::DISAGREE_RISE;
        let series = (0..n)
            .map(|c| Series {
                dash: None,
                name: scene
                    .cameras
                    .get(c)
                    .map_or_else(|| format!("camera {c}"), |k| k.name.clone()),
                colour: colormap::run_colour(c),
                points: h
                    .by_camera
                    .iter()
                    .filter(|(_, v)| v.len() == n && v[c].is_finite())
                    .map(|(f, v)| [*f as f64, 100.0 * v[c]])
                    .collect(),
            })
            .collect();
        (
            CAMERAS_PLOT,
            LinePlot {
                title: format!(
                    "Each camera's own pixels the others contradict ({})",
                    run.name
                ),
                y_label: "contradicted pixels of the camera, rise over its first frame (points)"
                    .into(),
                series,
                bands: bands.clone(),
                levels: vec![(
                    named,
                    format!(
                        "named above {named:.1} points for {} frames",
                        crate::tracker::DISAGREE_FRAMES
                    ),
                )],
                ..like.clone()
            },
        )
    });
    let mut plots = vec![
        (
            "checks_information",
            LinePlot {
                title: "How much the images constrain the mesh".into(),
                y_label: "information at the solution (% of the first frame's)".into(),
                series: series(|m| m.1),
                bands: bands.clone(),
                levels: vec![(floor, format!("suspect below {floor:.0} %"))],
                ..like.clone()
            },
        ),
        (
            "checks_contradicted",
            LinePlot {
                title: "Cameras contradicting where the previous frame left the surface".into(),
                y_label: "contradicted pixels, rise over the first frame (points)".into(),
                series: series(|m| m.2),
                bands,
                levels: vec![(rise, format!("suspect above {rise:.0} points"))],
                ..like.clone()
            },
        ),
    ];
    plots.extend(cameras);
    plots
}

/// The file stem of the per-camera plot of [`health_plots`].
pub(crate) const CAMERAS_PLOT: &str = "checks_cameras";

/// Median wall time per solved frame (image reading included) from a run folder's log;
/// `None` if there is no log or no line.
pub fn seconds_per_frame(dir: &Path) -> Result<Option<f64>> {
    let lines = crate::run::read_frame_log(dir)?;
    let walls: Vec<f64> = lines.iter().map(|l| l.wall_seconds).collect();
    Ok((!walls.is_empty()).then(|| crate::tracker::median(&walls)))
}

/// A file-name-safe form of a camera name.
fn file_safe(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Magnification of camera images for panels: a whole factor for small images, none otherwise.
fn panel_scale(width: u32, min_width: usize) -> f64 {
    if (width as usize) < min_width {
        (min_width as f64 / width as f64).ceil()
    } else {
        1.0
    }
}

const SHEET_BG: Rgb = [0.15, 0.15, 0.15];

/// Every run's wireframe over camera `c`'s image at `frame`, side by side, each panel labelled.
fn overlay_sheet(
    scene: &Scene,
    runs: &[Run],
    frame: u32,
    c: usize,
    img: &RgbImage,
    opts: &ReportOptions,
) -> Result<RgbImage> {
    let cam = &scene.cameras[c];
    let s = panel_scale(cam.width, opts.min_panel_width);
    let proj = overlay::magnified(cam.at(frame), s);
    let base = overlay::magnify_image(img, s);
    let panels = runs
        .par_iter()
        .enumerate()
        .map(|(i, run)| {
            let mesh = run.at(scene, frame);
            let mut p = base.clone();
            let style = WireStyle {
                colour: colormap::overlay_colour(i),
                width: 1.0,
                alpha: 0.75,
                hidden_alpha: 0.2,
            };
            overlay::wireframe_self_hidden(&mut p, mesh, &proj, &style)?;
            draw::label(
                &mut p,
                &format!("{} — {} — frame {frame}", run.name, cam.name),
                6.0,
                6.0,
                14.0,
            );
            Ok(p)
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(overlay::side_by_side(&panels, 6, SHEET_BG))
}

/// The camera of the oblique views at `frame`: the first camera turned about the centroid of the
/// ground truth (or of the first run).
fn oblique_camera(
    scene: &Scene,
    runs: &[Run],
    truth: Option<&Mesh>,
    frame: u32,
    opts: &ReportOptions,
    size: (usize, usize),
) -> Projection {
    let reference = truth.unwrap_or_else(|| runs[0].at(scene, frame));
    let pivot = centroid(&reference.positions);
    let mut fit: Vec<Point3<f64>> = runs
        .iter()
        .flat_map(|r| r.at(scene, frame).positions.iter().copied())
        .collect();
    if let Some(t) = truth {
        fit.extend(t.positions.iter().copied());
    }
    overlay::oblique(
        scene.cameras[0].at(frame),
        &pivot,
        opts.oblique_degrees,
        &fit,
        size.0,
        size.1,
    )
}

/// Every run's wireframe (with the ground truth's behind it, grey) from the oblique camera.
fn oblique_sheet(
    scene: &Scene,
    runs: &[Run],
    truth: Option<&Mesh>,
    frame: u32,
    opts: &ReportOptions,
) -> Result<RgbImage> {
    let cam0 = &scene.cameras[0];
    let s = panel_scale(cam0.width, opts.min_panel_width);
    let size = (
        (cam0.width as f64 * s) as usize,
        (cam0.height as f64 * s) as usize,
    );
    let proj = oblique_camera(scene, runs, truth, frame, opts, size);
    let truth_layer = match truth {
        Some(t) => {
            let mut img = draw::filled(size.0, size.1, [0.08; 3]);
            let style = WireStyle {
                colour: colormap::TRUTH,
                width: 1.0,
                alpha: 0.7,
                hidden_alpha: 0.15,
            };
            overlay::wireframe_self_hidden(&mut img, t, &proj, &style)?;
            img
        }
        None => draw::filled(size.0, size.1, [0.08; 3]),
    };
    let panels = runs
        .par_iter()
        .enumerate()
        .map(|(i, run)| {
            let mesh = run.at(scene, frame);
            let mut p = truth_layer.clone();
            let style = WireStyle {
                colour: colormap::overlay_colour(i),
                width: 1.0,
                alpha: 0.95,
                hidden_alpha: 0.25,
            };
            overlay::wireframe_self_hidden(&mut p, mesh, &proj, &style)?;
            let what = if truth.is_some() {
                " (grey: ground truth)"
            } else {
                ""
            };
            draw::label(
                &mut p,
                &format!(
                    "{} — {} turned {:.0}° — frame {frame}{what}",
                    run.name, cam0.name, opts.oblique_degrees
                ),
                6.0,
                6.0,
                14.0,
            );
            Ok(p)
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(overlay::side_by_side(&panels, 6, SHEET_BG))
}

/// Distance of each vertex to its ground-truth position.
fn vertex_errors(mesh: &Mesh, truth: &Mesh) -> Vec<f64> {
    mesh.positions
        .iter()
        .zip(&truth.positions)
        .map(|(a, b)| (a - b).norm())
        .collect()
}

/// The top of each run's error colour scale: its largest vertex error over the drawn frames, or
/// the largest over all runs when `shared`.
fn error_scales(scene: &Scene, runs: &[Run], truth: &[(u32, Mesh)], shared: bool) -> Vec<f64> {
    let mut max: Vec<f64> = runs
        .iter()
        .map(|r| {
            truth.iter().fold(0.0f64, |m, (f, gt)| {
                vertex_errors(r.at(scene, *f), gt)
                    .into_iter()
                    .fold(m, f64::max)
            })
        })
        .collect();
    if shared {
        let all = max.iter().copied().fold(0.0, f64::max);
        max.iter_mut().for_each(|m| *m = all);
    }
    // All exact: any positive scale shows them at the bottom of the map.
    let floor = scene.mesh.bbox_diagonal().max(1.0) * 1e-3;
    max.into_iter()
        .map(|m| if m > 0.0 { m } else { floor })
        .collect()
}

/// One line of the vertex-error bands plot: a statistic of a frame's vertex errors.
type Statistic = fn(&FrameError) -> f64;

/// One run's mesh at `frame` seen from the first camera (magnified like the overlays), filled
/// with per-vertex `colours` on a dark background and labelled "run — camera — frame{note}".
fn coloured_panel(
    scene: &Scene,
    mesh: &Mesh,
    frame: u32,
    colours: &[[f32; 3]],
    run: &str,
    note: &str,
    opts: &ReportOptions,
) -> Result<RgbImage> {
    let cam0 = &scene.cameras[0];
    let s = panel_scale(cam0.width, opts.min_panel_width);
    let proj = overlay::magnified(cam0.at(frame), s);
    let ropts = RenderOptions {
        background: [0.08; 3],
        ..RenderOptions::default()
    };
    let mut p = render::render(
        mesh,
        &[],
        &Surface::VertexColors(colours),
        &proj,
        (cam0.width as f64 * s) as usize,
        (cam0.height as f64 * s) as usize,
        &ropts,
    )?;
    draw::label(
        &mut p,
        &format!("{run} — {} — frame {frame}{note}", cam0.name),
        6.0,
        6.0,
        14.0,
    );
    Ok(p)
}

/// Each run's mesh at `frame` from the first camera, coloured by vertex error (viridis over
/// `[0, max[run]]`), with a colour bar after each run, or one after all when the scales are
/// equal.
fn error_sheet(
    scene: &Scene,
    runs: &[Run],
    truth: &Mesh,
    frame: u32,
    max: &[f64],
    opts: &ReportOptions,
) -> Result<RgbImage> {
    let panels = runs
        .par_iter()
        .zip(max)
        .map(|(run, &max)| {
            let mesh = run.at(scene, frame);
            let colours: Vec<[f32; 3]> = vertex_errors(mesh, truth)
                .iter()
                .map(|e| colormap::viridis(e / max))
                .collect();
            coloured_panel(scene, mesh, frame, &colours, &run.name, "", opts)
        })
        .collect::<Result<Vec<_>>>()?;
    let h = panels[0].height();
    let diag = scene.mesh.bbox_diagonal();
    let len = Length::of(scene.units);
    let bar = |max: f64| {
        overlay::colour_bar(
            colormap::viridis,
            max,
            h,
            &format!("vertex error ({}, % of bbox diag.)", len.unit()),
            |v| {
                if diag > 0.0 {
                    format!("{} ({:.2}%)", fmt_sig(len.value(v)), 100.0 * v / diag)
                } else {
                    fmt_sig(len.value(v))
                }
            },
        )
    };
    let mut sheet = Vec::with_capacity(2 * panels.len());
    if max.windows(2).all(|w| w[0] == w[1]) {
        sheet.extend(panels);
        sheet.push(bar(max[0]));
    } else {
        for (p, &m) in panels.into_iter().zip(max) {
            sheet.push(p);
            sheet.push(bar(m));
        }
    }
    Ok(overlay::side_by_side(&sheet, 6, SHEET_BG))
}

/// The σ colour scale, logarithmic: `(lo, hi)`, the 2nd and 98th percentiles of the finite σ
/// over the drawn frames and runs (σ spans orders of magnitude between the middle of a
/// textured surface and its grazing rim); `None` when there is none.
fn sigma_scale(confidence: &[Vec<(u32, Vec<VertexConfidence>)>]) -> Option<(f64, f64)> {
    let mut s: Vec<f64> = confidence
        .iter()
        .flatten()
        .flat_map(|(_, c)| c.iter().map(VertexConfidence::sigma))
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if s.is_empty() {
        return None;
    }
    s.sort_by(f64::total_cmp);
    let at = |q: f64| s[((s.len() - 1) as f64 * q) as usize];
    let (lo, hi) = (at(0.02), at(0.98));
    Some(if hi > lo {
        (lo, hi)
    } else {
        (lo / 2.0, lo * 2.0)
    })
}

/// Colour of a vertex no pixel constrains.
const UNCONSTRAINED: Rgb = [0.55, 0.55, 0.55];

/// Each run with confidence at `frame`: its mesh from the first camera coloured by σ (viridis over
/// log σ in `scale`, grey where unconstrained), with a colour bar; `None` when no run has it.
fn confidence_sheet(
    scene: &Scene,
    runs: &[Run],
    confidence: &[Vec<(u32, Vec<VertexConfidence>)>],
    frame: u32,
    scale: (f64, f64),
    opts: &ReportOptions,
) -> Result<Option<RgbImage>> {
    let (lo, hi) = (scale.0.ln(), scale.1.ln());
    let shown: Vec<(&Run, &Vec<VertexConfidence>)> = runs
        .iter()
        .zip(confidence)
        .filter_map(|(r, c)| c.iter().find(|(f, _)| *f == frame).map(|(_, c)| (r, c)))
        .collect();
    if shown.is_empty() {
        return Ok(None);
    }
    let mut panels = shown
        .par_iter()
        .map(|(run, conf)| {
            let mesh = run.at(scene, frame);
            let colours: Vec<[f32; 3]> = conf
                .iter()
                .map(|c| {
                    let s = c.sigma();
                    if s.is_finite() {
                        colormap::viridis(((s.max(1e-300).ln() - lo) / (hi - lo)).clamp(0.0, 1.0))
                    } else {
                        UNCONSTRAINED
                    }
                })
                .collect();
            let unconstrained = conf.iter().filter(|c| c.information == 0.0).count();
            let note = format!(
                " — {unconstrained} of {} vertices unconstrained",
                conf.len()
            );
            coloured_panel(scene, mesh, frame, &colours, &run.name, &note, opts)
        })
        .collect::<Result<Vec<_>>>()?;
    let h = panels[0].height();
    let len = Length::of(scene.units);
    let bar = overlay::colour_bar(
        colormap::viridis,
        1.0,
        h,
        &format!("sigma ({}, log scale); grey: unconstrained", len.unit()),
        |t| fmt_sig(len.value((lo + t * (hi - lo)).exp())),
    );
    panels.push(bar);
    Ok(Some(overlay::side_by_side(&panels, 6, SHEET_BG)))
}

/// Each run's photometric residual image at frame `t` in every camera (see `report::residual`):
/// one row against the previous frame and, when that is not the first, one against the first;
/// one colour scale per reference frame, shared by the runs, shown by the bar ending each row. Also returns each row's
/// RMS residual over the cameras' covered pixels.
fn residual_sheet(
    scene: &Scene,
    runs: &[Run],
    t: u32,
    opts: &ReportOptions,
) -> Result<(RgbImage, Vec<ResidualRow>)> {
    let now = scene.load_images(t)?;
    let mut refs = vec![(t - 1, scene.load_images(t - 1)?)];
    if t - 1 != scene.first {
        refs.push((scene.first, scene.load_images(scene.first)?));
    }
    // rows[run-major]: (run, reference index, maps per camera).
    let mut rows = Vec::new();
    for run in runs {
        for (j, (r, imgs)) in refs.iter().enumerate() {
            let maps: Vec<residual::ResidualMap> = (0..scene.cameras.len())
                .map(|c| {
                    let cam = &scene.cameras[c];
                    residual::residual_map(
                        run.at(scene, t),
                        cam.at(t),
                        &now[c],
                        run.at(scene, *r),
                        cam.at(*r),
                        &imgs[c],
                    )
                })
                .collect();
            rows.push((run, j, maps));
        }
    }
    // One scale per reference frame, shared by the runs: the first frame's residual also holds
    // every lighting change since, and would flatten the previous frame's.
    let tops: Vec<f64> = (0..refs.len())
        .map(|j| {
            let maps: Vec<&residual::ResidualMap> = rows
                .iter()
                .filter(|(_, k, _)| *k == j)
                .flat_map(|(_, _, m)| m)
                .collect();
            residual::scale(&maps)
        })
        .collect();
    let mut rms_rows = Vec::new();
    let pictures: Vec<RgbImage> = rows
        .iter()
        .map(|(run, j, maps)| {
            let (r, top) = (refs[*j].0, tops[*j]);
            let (mut sum, mut n) = (0.0, 0usize);
            let mut panels: Vec<RgbImage> = maps
                .iter()
                .enumerate()
                .map(|(c, m)| {
                    let (rms, k) = m.rms();
                    sum += rms * rms * k as f64;
                    n += k;
                    let cam = &scene.cameras[c];
                    let mut p = residual::picture(m, &now[c], top, colormap::viridis);
                    // Keep wide sheets viewable: halve panels wider than 1000 px, magnify small.
                    if p.width() > 1000 {
                        p = p.downsample2();
                    } else {
                        p = overlay::magnify_image(
                            &p,
                            panel_scale(cam.width, opts.min_panel_width),
                        );
                    }
                    let against = if *j == 1 {
                        format!("first frame {r}")
                    } else {
                        format!("frame {r}")
                    };
                    draw::label(
                        &mut p,
                        &format!(
                            "{} — {} — frame {t} against {against} — RMS {} over {k} px",
                            run.name,
                            cam.name,
                            fmt_sig(rms)
                        ),
                        6.0,
                        6.0,
                        14.0,
                    );
                    p
                })
                .collect();
            rms_rows.push(ResidualRow {
                run: run.name.clone(),
                frame: t,
                reference: r,
                rms: if n > 0 {
                    (sum / n as f64).sqrt()
                } else {
                    f64::NAN
                },
            });
            let h = panels[0].height();
            panels.push(overlay::colour_bar(
                colormap::viridis,
                top,
                h,
                &format!("|RGB difference| to frame {r} (RMS of channels, 0-1)"),
                fmt_sig,
            ));
            overlay::side_by_side(&panels, 6, SHEET_BG)
        })
        .collect();
    Ok((overlay::stacked(&pictures, 0, SHEET_BG), rms_rows))
}

/// A number with about 3 significant digits, for labels.
pub(crate) use crate::base::units::significant as fmt_sig;

#[cfg(test)]
#[path = "tests.rs"]
mod tests;

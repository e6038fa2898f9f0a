//! The report's `index.html`: one self-contained page (inline style, no scripts, no fonts or
//! anything else fetched from the network; images by relative links into the report folder).

use super::page::{fmt_sig, ReportOptions, ResidualRow, RunSummary};
use crate::base::units::Length;
use crate::input::scene::Scene;
use crate::report::plot::xml_escape as esc;
use crate::tracker::Coverage;
use std::fmt::Write;

/// Captioned image files of each section, in order, and the scene's coverage.
#[derive(Default)]
pub(super) struct Figures {
    pub overlays: Vec<(String, String)>,
    pub obliques: Vec<(String, String)>,
    pub error_maps: Vec<(String, String)>,
    pub confidence_maps: Vec<(String, String)>,
    /// The residual image: its frame, file and rows.
    pub residual: Option<(u32, String, Vec<ResidualRow>)>,
    /// Frames of the flipbook (`flipbook/fNNNN.jpg`); empty: none.
    pub flipbook: Vec<u32>,
    /// How much of the surface the cameras see at the first frame (`tracker::coverage`).
    pub coverage: Coverage,
    /// Whether the tracker's own measures were plotted (`checks_information`,
    /// `checks_contradicted`): some run has a tracker log.
    pub checks_plotted: bool,
    /// Whether each camera's own contradicted share was plotted (`checks_cameras`): some run's
    /// log has it for three cameras or more.
    pub cameras_plotted: bool,
}

/// Rows of the "Frames to check" table shown per run; the rest are counted.
const CHECK_ROWS: usize = 40;

/// The tracker's own checks: per run, the frames to look at and why, and the plots of the two
/// measures behind them.
fn checks_section(o: &mut String, runs: &[RunSummary], figs: &Figures, len: Length) {
    let plotted = figs.checks_plotted;
    if runs.iter().all(|r| r.checks.is_none()) {
        return;
    }
    let _ = writeln!(o, "<h2>Frames to check</h2>");
    let _ = writeln!(
        o,
        "<p>What the tracker itself found doubtful, from each run's <code>log.jsonl</code> (no ground truth needed): frames where no step lowered the cost (<b>stalled</b>: the mesh kept the previous frame's shape), frames where the other cameras contradict where the frame left the surface (found when the next frame's templates were taken from it) and the frames that started from there, and frames whose images constrain the mesh less than {:.0} % as much as the first frame's own images do (it sees next to none of the surface's texture). These are shaded in the plots above and below; the first one of each run is among the frames drawn.</p>",
        100.0 * crate::tracker::INFORMATION_FLOOR
    );
    for (i, r) in runs.iter().enumerate() {
        let swatch = format!(
            "<span class=\"swatch\" style=\"background:{}\"></span>",
            crate::report::draw::css(crate::report::colormap::run_colour(i))
        );
        if let Some(m) = &r.first_mesh_moved {
            let _ = writeln!(
                o,
                "<p>{swatch}{}: the scene's mesh lay {:.1} px {} the surface the cameras agree on at the first frame (they agreed {:.1}× better there), so the tracker moved every vertex along its normal onto it before tracking (median {} {}, at most {} {}) and the run starts from the moved mesh: its first frame is not the scene's mesh (docs/tracker.md, \"The first mesh must lie on the surface\").</p>",
                esc(&r.name),
                m.found.pixels.abs(),
                match (m.found.closed, m.found.pixels < 0.0) {
                    (true, true) => "outside",
                    (true, false) => "inside",
                    (false, _) => "off",
                },
                m.found.ratio,
                len.show(m.median),
                len.unit(),
                len.show(m.max),
                len.unit()
            );
        }
        match &r.checks {
            None => {
                let _ = writeln!(
                    o,
                    "<p>{swatch}{}: no tracker log, so no checks (the baseline keeps none).</p>",
                    esc(&r.name)
                );
            }
            Some(c) if c.is_empty() => {
                let _ = writeln!(
                    o,
                    "<p>{swatch}{}: <b>no frame to check</b>. Every frame's solve moved the mesh, the cameras agreed about where each frame left the surface as well as at the first frame, and the images constrained every frame's mesh at least {:.0} % as much as the first frame's.</p>",
                    esc(&r.name),
                    100.0 * crate::tracker::INFORMATION_FLOOR
                );
            }
            Some(c) => {
                let stalled = c.iter().filter(|f| f.stalled()).count();
                let suspect = c.iter().filter(|f| f.suspect()).count();
                let _ = writeln!(
                    o,
                    "<p>{swatch}{}: <b>{} frame{} to check</b> ({stalled} stalled, {suspect} suspect), from frame {}.</p>",
                    esc(&r.name),
                    c.len(),
                    if c.len() == 1 { "" } else { "s" },
                    c[0].frame
                );
                let _ = writeln!(
                    o,
                    "<table class=\"kv\"><tr><th>frame</th><th>what the tracker found</th></tr>"
                );
                for f in c.iter().take(CHECK_ROWS) {
                    let what = f
                        .concerns
                        .iter()
                        .map(|c| esc(&c.describe()))
                        .collect::<Vec<_>>()
                        .join("<br>");
                    let _ = writeln!(o, "<tr><td>{}</td><td>{what}</td></tr>", f.frame);
                }
                if c.len() > CHECK_ROWS {
                    let _ = writeln!(
                        o,
                        "<tr><td colspan=\"2\">and {} more frames (the run's <code>log.jsonl</code> has them all)</td></tr>",
                        c.len() - CHECK_ROWS
                    );
                }
                let _ = writeln!(o, "</table>");
            }
        }
    }
    if plotted {
        let _ = writeln!(
            o,
            "<figure><img src=\"checks_information.png\" alt=\"information share per frame, one line per run\"><figcaption>How much the images constrain each frame's solution, as a share of what the first frame's own images give its mesh (<code>information_share</code>); a frame below the dashed line is suspect. Also as <a href=\"checks_information.svg\">SVG</a>.</figcaption></figure>"
        );
        let _ = writeln!(
            o,
            "<figure><img src=\"checks_contradicted.png\" alt=\"rise of the contradicted share per frame, one line per run\"><figcaption>The share of each frame's finest template (taken from the previous frame's solution) that the other cameras contradict, less that share at the first frame (<code>contradicted_share − contradicted_at_first</code>); above the dashed line the previous frame's solution, and this frame, are suspect. Also as <a href=\"checks_contradicted.svg\">SVG</a>.</figcaption></figure>"
        );
    }
    if figs.cameras_plotted {
        let _ = writeln!(
            o,
            "<figure><img src=\"checks_cameras.png\" alt=\"rise of each camera's own contradicted share per frame, one line per camera\"><figcaption>The same share camera by camera: of each camera's own template pixels that another camera sees alike (same side, not edge-on, at comparable detail), those all such cameras contradict, less that camera's share at the first frame (<code>contradicted_by_camera − contradicted_by_camera_at_first</code>, the first run whose log has them). Cameras that came up above the dashed line within a few frames (not a slow climb, as a highlight moving into one view makes) and stay there for {} frames running, not all at once, are named as disagreeing with the others: a camera knocked off its calibration in front of a plain background raises the two cameras that share its part of the surface, frame after frame. Also as <a href=\"checks_cameras.svg\">SVG</a>.</figcaption></figure>",
            crate::tracker::DISAGREE_FRAMES
        );
    }
}

const STYLE: &str = "body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,'DejaVu Sans',sans-serif;\
margin:2em auto;max-width:1400px;padding:0 1em;color:#1a1a1a;background:#fff;line-height:1.45}\
h1{font-size:1.6em;margin-bottom:.2em}h2{margin-top:1.8em;border-bottom:1px solid #ddd;padding-bottom:.2em}\
table{border-collapse:collapse;margin:.6em 0}th,td{border:1px solid #ccc;padding:.3em .7em;text-align:right}\
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}\
figure{margin:1em 0}figure img{max-width:100%;height:auto;border:1px solid #ccc;display:block}\
figcaption{color:#555;font-size:.9em;margin-top:.3em}.swatch{display:inline-block;width:1.6em;height:.35em;\
vertical-align:middle;margin-right:.4em}.muted{color:#666}.kv td{text-align:left}";

fn num(v: Option<f64>) -> String {
    v.filter(|v| v.is_finite()).map_or("—".to_string(), fmt_sig)
}

fn figures(o: &mut String, items: &[(String, String)], alt: &str) {
    for (caption, file) in items {
        let _ = writeln!(
            o,
            "<figure><a href=\"{f}\"><img src=\"{f}\" alt=\"{a}: {c}\" loading=\"lazy\"></a><figcaption>{c}</figcaption></figure>",
            f = esc(file),
            a = esc(alt),
            c = esc(caption)
        );
    }
}

/// The scene's name for a title: its folder and file stem (`blender-hard-sample / scene`), as
/// a user names the shot, rather than the bare `scene.json`.
fn scene_title(path: &std::path::Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string());
    let folder = path.canonicalize().ok().and_then(|p| {
        p.parent()
            .and_then(|d| d.file_name())
            .map(|d| d.to_string_lossy().into_owned())
    });
    match folder {
        Some(d) if !d.is_empty() => format!("{d} / {stem}"),
        _ => stem,
    }
}

/// The flipbook: one image per frame (`flipbook/fNNNN.jpg`), a slider, play/pause and the arrow
/// keys; the images are preloaded so that scrubbing is smooth.
fn flipbook_section(o: &mut String, runs: &[RunSummary], frames: &[u32], cameras: usize) {
    let _ = writeln!(o, "<h2>Flipbook</h2>");
    let legend = runs
        .iter()
        .enumerate()
        .map(|(i, r)| {
            format!(
                "<span class=\"swatch\" style=\"background:{}\"></span>{}",
                crate::report::draw::css(crate::report::colormap::overlay_colour(i)),
                esc(&r.name)
            )
        })
        .collect::<Vec<_>>()
        .join(" &nbsp; ");
    let _ = writeln!(
        o,
        "<p>{} frames, all {cameras} cameras side by side, every run's wireframe on the footage ({legend}; hidden edges faint). Drag the slider, press play (or the space bar), step with ← →; <code>index.html#frame=N</code> opens at frame N.</p>",
        frames.len()
    );
    let list = frames
        .iter()
        .map(|f| f.to_string())
        .collect::<Vec<_>>()
        .join(",");
    let _ = writeln!(
        o,
        "<div class=\"flipbook\"><img id=\"fb-img\" src=\"flipbook/f{:04}.jpg\" alt=\"wireframes over all cameras, one frame\" style=\"max-width:100%\">\n<div style=\"display:flex;gap:.8em;align-items:center;margin:.4em 0\"><button id=\"fb-play\" type=\"button\">▶ play</button><input id=\"fb-slider\" type=\"range\" min=\"0\" max=\"{}\" value=\"0\" style=\"flex:1\"><span id=\"fb-label\" style=\"min-width:7em\">frame {}</span></div></div>",
        frames[0],
        frames.len() - 1,
        frames[0]
    );
    let _ = writeln!(
        o,
        "<script>(function(){{const F=[{list}];const img=document.getElementById('fb-img'),s=document.getElementById('fb-slider'),l=document.getElementById('fb-label'),b=document.getElementById('fb-play');\
const src=f=>'flipbook/f'+String(f).padStart(4,'0')+'.jpg';const cache=F.map(f=>{{const i=new Image();i.src=src(f);return i;}});let k=0,timer=null;\
function show(i){{k=(i+F.length)%F.length;s.value=k;img.src=cache[k].src;l.textContent='frame '+F[k];}}\
function play(on){{if(on&&!timer){{timer=setInterval(()=>show(k+1),1000/12);b.textContent='❚❚ pause';}}else if(!on&&timer){{clearInterval(timer);timer=null;b.textContent='▶ play';}}}}\
s.addEventListener('input',()=>{{play(false);show(+s.value);}});b.addEventListener('click',()=>play(!timer));\
const m=location.hash.match(/frame=(\\d+)/);if(m&&F.indexOf(+m[1])>=0)show(F.indexOf(+m[1]));\
document.addEventListener('keydown',e=>{{if(e.target.tagName==='INPUT'&&e.target!==s)return;if(e.key==='ArrowRight'){{play(false);show(k+1);e.preventDefault();}}else if(e.key==='ArrowLeft'){{play(false);show(k-1);e.preventDefault();}}else if(e.key===' '){{play(!timer);e.preventDefault();}}}});}})();</script>"
    );
}

pub(super) fn page(
    scene: &Scene,
    runs: &[RunSummary],
    frames: &[u32],
    plot_stem: &str,
    figs: &Figures,
    opts: &ReportOptions,
) -> String {
    let title = format!("modelflow report — {}", scene_title(&scene.path));
    let has_truth = scene.ground_truth.is_some();
    let len = Length::of(scene.units);
    let mut o = String::new();
    let _ = writeln!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{}</h1>",
        esc(&title),
        esc(&title)
    );
    let _ = writeln!(
        o,
        "<p class=\"muted\">Scene file: <code>{}</code></p>",
        esc(&scene.path.display().to_string())
    );

    // Scene summary.
    let n_frames = scene.last - scene.first + 1;
    let _ = writeln!(o, "<h2>Scene</h2>\n<table class=\"kv\">");
    let _ = writeln!(
        o,
        "<tr><th>frames</th><td>{} – {} ({n_frames})</td></tr>",
        scene.first, scene.last
    );
    let _ = writeln!(
        o,
        "<tr><th>mesh</th><td>{} vertices, {} triangles, bbox diagonal {} {}</td></tr>",
        scene.mesh.positions.len(),
        scene.mesh.triangles.len(),
        fmt_sig(len.value(scene.mesh.bbox_diagonal())),
        len.unit()
    );
    let _ = writeln!(
        o,
        "<tr><th>ground truth</th><td>{}</td></tr>",
        if has_truth {
            "yes"
        } else {
            "no (real footage)"
        }
    );
    let _ = writeln!(
        o,
        "<tr><th>cameras</th><td>{}</td></tr>",
        scene.cameras.len()
    );
    let c = &figs.coverage;
    let _ = writeln!(
        o,
        "<tr><th>surface seen at frame {}</th><td>by two or more cameras {:.0} %, by one only {:.0} %, by none {:.0} % (of its area; where one camera alone sees it, depth comes from the regularisers alone)</td></tr>\n</table>",
        scene.first,
        100.0 * c.two_or_more,
        100.0 * c.one,
        100.0 * c.none
    );
    let _ = writeln!(
        o,
        "<table>\n<tr><th>camera</th><th>image size</th><th>pose</th></tr>"
    );
    for c in &scene.cameras {
        let _ = writeln!(
            o,
            "<tr><td>{}</td><td>{} × {}</td><td>{}</td></tr>",
            esc(&c.name),
            c.width,
            c.height,
            if c.is_moving() {
                "moving (one per frame)"
            } else {
                "fixed"
            }
        );
    }
    let _ = writeln!(o, "</table>");

    // Plot and table.
    if has_truth {
        let _ = writeln!(o, "<h2>Error against ground truth</h2>");
        let _ = writeln!(
            o,
            "<p>Per frame, the RMS over vertices of the distance between each run's vertex and its ground-truth position, as a percentage of the bounding-box diagonal of the scene mesh ({} {}).</p>",
            fmt_sig(len.value(scene.mesh.bbox_diagonal())),
            len.unit()
        );
    } else {
        let _ = writeln!(o, "<h2>Photometric cost</h2>");
        let _ = writeln!(
            o,
            "<p>The scene has no ground truth, so this plots a cost that needs none: per frame, the mean squared RGB difference (channels in 0–1, ×10<sup>−3</sup>) between the colour under each vertex in frame {} and under the same vertex in that frame, over the vertices front-most in both (depth test) and inside the image, averaged over cameras. A run that stays on the surface keeps it low; drift raises it.</p>",
            scene.first
        );
    }
    let _ = writeln!(
        o,
        "<figure><img src=\"{p}.png\" alt=\"{p} per frame, one line per run\"><figcaption>Also as <a href=\"{p}.svg\">SVG</a>. Dashed lines: the frames drawn below; shaded: the frames to check (below).</figcaption></figure>",
        p = plot_stem
    );
    if has_truth {
        let _ = writeln!(
            o,
            "<figure><img src=\"error_length.png\" alt=\"RMS vertex error in {u} per frame, one line per run\"><figcaption>The same in {u}. Also as <a href=\"error_length.svg\">SVG</a>.</figcaption></figure>",
            u = len.unit()
        );
        let _ = writeln!(
            o,
            "<figure><img src=\"vertex_error_bands.png\" alt=\"median, 90th percentile and largest vertex error per frame, per run\"><figcaption>How the error spreads over the mesh: per frame, the median, 90th percentile and largest vertex error of each run (lighter: higher percentile). Also as <a href=\"vertex_error_bands.svg\">SVG</a>.</figcaption></figure>"
        );
        let _ = writeln!(
            o,
            "<figure><img src=\"error_where.png\" alt=\"RMS vertex error per frame: all vertices, the shape alone after the best rigid fit, and the vertices no camera or one camera sees, per run\"><figcaption>Where the error lies: all vertices; the shape alone, once each frame's best rigid fit to the truth is taken out (the rest is the whole mesh misplaced); the vertices no camera sees (the regularisers' guess) and those only one camera sees (depth from one view), in the truth. Also as <a href=\"error_where.svg\">SVG</a>.</figcaption></figure>"
        );
    }
    let _ = writeln!(o, "<table>");
    if has_truth {
        let _ = writeln!(
            o,
            "<tr><th>run</th><th>mean RMS error<br>({u})</th><th>mean RMS error<br>(% bbox)</th><th>final RMS error<br>({u})</th><th>final RMS error<br>(% bbox)</th><th>max vertex error, final<br>({u})</th><th>time per frame<br>(ms, median)</th></tr>",
            u = len.unit()
        );
    } else {
        let _ = writeln!(
            o,
            "<tr><th>run</th><th>mean photometric cost<br>(×10<sup>−3</sup>)</th><th>final photometric cost<br>(×10<sup>−3</sup>)</th><th>time per frame<br>(ms, median)</th></tr>"
        );
    }
    for (i, r) in runs.iter().enumerate() {
        let swatch = format!(
            "<span class=\"swatch\" style=\"background:{}\"></span>",
            crate::report::draw::css(crate::report::colormap::run_colour(i))
        );
        let _ = write!(o, "<tr><td>{swatch}{}</td>", esc(&r.name));
        if let Some(e) = &r.error {
            let _ = write!(
                o,
                "<td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
                num(Some(len.value(e.rms_mean))),
                num(Some(e.rms_mean_pct)),
                num(Some(len.value(e.rms_final))),
                num(Some(e.rms_final_pct)),
                num(e.per_frame.last().map(|f| len.value(f.max)))
            );
        }
        if let Some(c) = &r.photometric {
            let vals: Vec<f64> = c.iter().flatten().copied().collect();
            let mean =
                (!vals.is_empty()).then(|| 1e3 * vals.iter().sum::<f64>() / vals.len() as f64);
            let _ = write!(
                o,
                "<td>{}</td><td>{}</td>",
                num(mean),
                num(c.last().copied().flatten().map(|v| 1e3 * v))
            );
        }
        let _ = writeln!(
            o,
            "<td>{}</td></tr>",
            match r.seconds_per_frame {
                Some(s) => format!("{:.0}", s * 1e3),
                None => "—".into(),
            }
        );
    }
    let _ = writeln!(o, "</table>");
    let _ = writeln!(
        o,
        "<p class=\"muted\">Time per frame: median wall time per solved frame, image reading included (<code>wall_seconds</code> in each run's <code>log.jsonl</code>; — when there is none). Run folders: {}.</p>",
        runs.iter()
            .map(|r| format!("{} = <code>{}</code>", esc(&r.name), esc(&r.dir.display().to_string())))
            .collect::<Vec<_>>()
            .join(", ")
    );

    checks_section(&mut o, runs, figs, len);

    let frame_list = frames
        .iter()
        .map(|f| f.to_string())
        .collect::<Vec<_>>()
        .join(", ");
    if !figs.flipbook.is_empty() {
        flipbook_section(&mut o, runs, &figs.flipbook, scene.cameras.len());
    }
    let _ = writeln!(o, "<h2>Wireframes over the input images</h2>");
    let _ = writeln!(
        o,
        "<p>Frames {frame_list}, every camera; one panel per run. Hidden edges (behind the run's own surface) are faint.</p>"
    );
    figures(&mut o, &figs.overlays, "wireframe overlay");
    let _ = writeln!(o, "<h2>Oblique views</h2>");
    let _ = writeln!(
        o,
        "<p>Camera {} turned {:.0}° about the vertical axis through the mesh centroid, where errors in depth, invisible from the input cameras, show.{}</p>",
        esc(&scene.cameras[0].name),
        opts.oblique_degrees,
        if has_truth { " The ground truth is drawn in grey behind each run." } else { "" }
    );
    figures(&mut o, &figs.obliques, "oblique wireframe");
    if !figs.error_maps.is_empty() {
        let _ = writeln!(o, "<h2>Per-vertex error</h2>");
        let _ = writeln!(
            o,
            "<p>Each run's mesh seen from camera {}, coloured by the distance of each vertex to its ground-truth position (viridis; {}).</p>",
            esc(&scene.cameras[0].name),
            if opts.shared_error_scale { "one scale for all frames and runs, shown by the colour bar" } else { "each run on its own scale, the largest error of that run over the drawn frames, shown by the colour bar beside it; --shared-scale puts all runs on one" }
        );
        figures(&mut o, &figs.error_maps, "error-coloured mesh");
    }
    if !figs.confidence_maps.is_empty() {
        let _ = writeln!(o, "<h2>Per-vertex confidence</h2>");
        let _ = writeln!(
            o,
            "<p>Each tracked run's mesh seen from camera {}, coloured by how well the images pin each vertex down: σ, one standard deviation of its position along its worst-constrained direction (the residual of its pixels over the square root of the smallest eigenvalue of its 3×3 block of the photometric normal equations; <code>NNNN.confidence.csv</code> in the run folder). Dark is well constrained; grey vertices are constrained by no pixel of any camera (hidden, outside every view, or rejected as outliers) and follow the regularisers alone. One scale for all frames and runs. Runs without confidence files (e.g. the baseline) are not shown.</p>",
            esc(&scene.cameras[0].name)
        );
        figures(&mut o, &figs.confidence_maps, "confidence-coloured mesh");
    }
    if let Some((t, file, rows)) = &figs.residual {
        let _ = writeln!(o, "<h2>Photometric residual at frame {t}</h2>");
        let _ = writeln!(
            o,
            "<p>What each run leaves unexplained in the footage, pixel by pixel, in every camera: for each pixel the run's mesh covers at frame {t}, the colour there minus the colour at the same surface point in the reference frame (found through the run's mesh at both frames, as the tracker's warp does) times the triangle's brightness gain (fitted by least squares, as the tracker does, so that shading that changes as the surface turns is not counted), as the RMS over R, G and B (images in 0–1). The previous frame is what the tracker matches frame by frame; the first frame is its anchor against drift. A run that sticks to the surface leaves only noise, lighting change and highlights; one that slides leaves the texture's edges. Pixels whose surface point was hidden at the reference frame are left dark. The runs share one colour scale per reference frame (the first frame's residual also holds every change of lighting since, so it gets its own). <code>--residual-frame N</code> picks the frame.</p>"
        );
        let _ = writeln!(
            o,
            "<table><tr><th>run</th><th>against frame</th><th>RMS residual (0–1)</th></tr>"
        );
        for row in rows {
            let _ = writeln!(
                o,
                "<tr><td>{}</td><td>{}</td><td>{}</td></tr>",
                esc(&row.run),
                row.reference,
                num(Some(row.rms))
            );
        }
        let _ = writeln!(o, "</table>");
        figures(
            &mut o,
            &[(format!("frame {t}"), file.clone())],
            "photometric residual",
        );
    }
    let _ = writeln!(
        o,
        "<p class=\"muted\">Written by modelflow {}.</p>\n</body>\n</html>",
        env!("CARGO_PKG_VERSION")
    );
    o
}

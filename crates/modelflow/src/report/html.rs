//! The report's `index.html`: one self-contained page (inline style, no scripts, no fonts or
//! anything else fetched from the network; images by relative links into the report folder).

use super::page::{fmt_sig, ReportOptions, RunSummary};
use crate::base::units::Length;
use crate::input::scene::Scene;
use crate::report::plot::xml_escape as esc;
use std::fmt::Write;

/// Captioned image files of each section, in order.
#[derive(Default)]
pub(super) struct Figures {
    pub overlays: Vec<(String, String)>,
    pub obliques: Vec<(String, String)>,
    pub error_maps: Vec<(String, String)>,
    pub confidence_maps: Vec<(String, String)>,
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

pub(super) fn page(
    scene: &Scene,
    runs: &[RunSummary],
    frames: &[u32],
    plot_stem: &str,
    figs: &Figures,
    opts: &ReportOptions,
) -> String {
    let title = format!(
        "modelflow report — {}",
        scene.path.file_name().map_or_else(
            || scene.path.display().to_string(),
            |n| n.to_string_lossy().into_owned()
        )
    );
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
        "<tr><th>cameras</th><td>{}</td></tr>\n</table>",
        scene.cameras.len()
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
        "<figure><img src=\"{p}.png\" alt=\"{p} per frame, one line per run\"><figcaption>Also as <a href=\"{p}.svg\">SVG</a>.</figcaption></figure>",
        p = plot_stem
    );
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

    let frame_list = frames
        .iter()
        .map(|f| f.to_string())
        .collect::<Vec<_>>()
        .join(", ");
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
            "<p>Each run's mesh seen from camera {}, coloured by the distance of each vertex to its ground-truth position (viridis; one scale for all frames and runs, shown by the colour bar).</p>",
            esc(&scene.cameras[0].name)
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
    let _ = writeln!(
        o,
        "<p class=\"muted\">Written by modelflow {}.</p>\n</body>\n</html>",
        env!("CARGO_PKG_VERSION")
    );
    o
}

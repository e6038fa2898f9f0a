//! Line plots of per-frame quantities (error or photometric cost per run), drawn twice from one
//! layout: as a raster image (anti-aliased, via `draw`) for the PNG, and as hand-written SVG text.
//! A plotting crate would bring a font stack or a large dependency tree for what is here one
//! layout (nice ticks, margins, a legend right of the axes) and two small back ends.

use crate::base::image::RgbImage;
use crate::report::draw::{self, Anchor, Rgb};
use std::fmt::Write;

/// A line's dash pattern: `[on, off]` pixels along it; `None`: solid.
pub type Dash = Option<[f64; 2]>;

/// One line of a plot: `(x, y)` points in order; a non-finite `y` breaks the line.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub name: String,
    pub colour: Rgb,
    pub points: Vec<[f64; 2]>,
    /// Drawn dashed, `[on, off]` pixels along the line (`None`: solid), so that lines of one
    /// colour family stay apart in grey print and for colour-blind readers.
    pub dash: Dash,
}

/// A line plot with a title, axis labels (with units) and a legend naming every series.
#[derive(Clone, Debug, PartialEq)]
pub struct LinePlot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// x positions marked by a dashed vertical line (e.g. the frames drawn elsewhere in the
    /// report), labelled at the top.
    pub marks: Vec<f64>,
    /// Shaded x ranges behind the lines (e.g. frames to check), each named once in the legend.
    pub bands: Vec<Band>,
    /// Horizontal dashed lines at a y value (e.g. a threshold), labelled inside the plot's right
    /// edge; the y axis always reaches them.
    pub levels: Vec<(f64, String)>,
    pub width: u32,
    pub height: u32,
}

/// A shaded x range `from..to` of a plot, in a light colour named `label` in the legend.
#[derive(Clone, Debug, PartialEq)]
pub struct Band {
    pub from: f64,
    pub to: f64,
    pub colour: Rgb,
    pub label: String,
}

/// Opacity of the bands over the white plot area.
const BAND_ALPHA: f32 = 0.22;

/// Colour of the marks.
const MARK: Rgb = [0.55, 0.55, 0.55];
/// Colour of the horizontal level lines (thresholds).
const LEVEL: Rgb = [0.75, 0.2, 0.15];

const TITLE_PX: f32 = 18.0;
const LABEL_PX: f32 = 14.0;
const TICK_PX: f32 = 12.0;
const INK: Rgb = [0.1, 0.1, 0.1];
const GRID: Rgb = [0.88, 0.88, 0.88];

/// A mark's label: the x value, as a whole number when it is one (frames).
fn format_mark(v: f64) -> String {
    if v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v}")
    }
}

/// Axis ticks: the axis range and the tick values with their labels.
#[derive(Clone, Debug, PartialEq)]
struct Axis {
    lo: f64,
    hi: f64,
    ticks: Vec<(f64, String)>,
}

/// A "nice" step (1, 2, 2.5 or 5 times a power of ten) giving about `target` intervals over `span`.
fn nice_step(span: f64, target: f64) -> f64 {
    let raw = (span / target).max(f64::MIN_POSITIVE);
    let mag = 10f64.powf(raw.log10().floor());
    let m = raw / mag;
    let nice = if m <= 1.0 {
        1.0
    } else if m <= 2.0 {
        2.0
    } else if m <= 2.5 {
        2.5
    } else if m <= 5.0 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

fn format_tick(v: f64, step: f64) -> String {
    let mut decimals = (-step.log10().floor()).max(0.0) as usize;
    if ((step / 10f64.powi(-(decimals as i32))) - (step / 10f64.powi(-(decimals as i32))).round())
        .abs()
        > 1e-6
    {
        decimals += 1;
    }
    let s = format!("{:.*}", decimals, v);
    if s.starts_with('-') && s.trim_start_matches(['-', '0', '.']).is_empty() {
        s[1..].to_string()
    } else {
        s
    }
}

/// Ticks for `[lo, hi]`; `extend` widens the range to whole steps (for the value axis), otherwise
/// the range is kept and `integer` forces whole-number steps (frames).
fn axis(lo: f64, hi: f64, extend: bool, integer: bool) -> Axis {
    let (mut lo, mut hi) = if lo.is_finite() && hi.is_finite() {
        (lo, hi)
    } else {
        (0.0, 1.0)
    };
    if hi - lo <= 0.0 {
        let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        lo -= if extend && lo >= 0.0 && lo - pad < 0.0 {
            lo
        } else {
            pad
        };
        hi += pad;
    }
    let mut step = nice_step(hi - lo, 6.0);
    if integer {
        step = step.max(1.0).round();
    }
    if extend {
        lo = (lo / step).floor() * step;
        hi = (hi / step).ceil() * step;
    }
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    let ticks = (first..=last)
        .map(|k| {
            let v = k as f64 * step;
            (v, format_tick(v, step))
        })
        .collect();
    Axis { lo, hi, ticks }
}

/// Pixel geometry shared by both back ends.
struct Layout {
    /// Plot area: left, top, right, bottom.
    area: [f64; 4],
    x: Axis,
    y: Axis,
    legend_x: f64,
}

impl Layout {
    fn px(&self, p: [f64; 2]) -> [f64; 2] {
        let [l, t, r, b] = self.area;
        [
            l + (p[0] - self.x.lo) / (self.x.hi - self.x.lo) * (r - l),
            b - (p[1] - self.y.lo) / (self.y.hi - self.y.lo) * (b - t),
        ]
    }
}

impl LinePlot {
    fn layout(&self) -> Layout {
        let finite = |i: usize| {
            self.series
                .iter()
                .flat_map(|s| s.points.iter())
                .filter(|p| p[0].is_finite() && p[1].is_finite())
                .map(move |p| p[i])
        };
        let (xlo, xhi) = finite(0).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        let (ylo, yhi) = finite(1)
            .chain(self.levels.iter().map(|l| l.0).filter(|v| v.is_finite()))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        // Non-negative quantities start their axis at zero.
        let ylo = if ylo >= 0.0 { 0.0 } else { ylo };
        let mut x = axis(xlo, xhi, false, true);
        // A little room so that markers at the ends are not cut by the frame.
        let pad = 0.015 * (x.hi - x.lo);
        x.lo -= pad;
        x.hi += pad;
        let y = axis(ylo, yhi, true, false);
        let tick_w = y
            .ticks
            .iter()
            .map(|(_, s)| draw::text_width(s, TICK_PX))
            .fold(0.0, f64::max);
        let legend_w = self
            .legend()
            .iter()
            .map(|(name, _, _, _)| draw::text_width(name, LABEL_PX))
            .fold(0.0, f64::max)
            + 46.0;
        let (w, h) = (self.width as f64, self.height as f64);
        let left = 20.0 + LABEL_PX as f64 + 10.0 + tick_w + 8.0;
        let right = w - legend_w - 24.0;
        let area = [left, 48.0, right.max(left + 50.0), h - 58.0];
        Layout {
            area,
            x,
            y,
            legend_x: area[2] + 16.0,
        }
    }

    /// The legend's entries: every series (a line), then every band label once (a swatch).
    fn legend(&self) -> Vec<(String, Rgb, bool, Dash)> {
        let mut items: Vec<(String, Rgb, bool, Dash)> = self
            .series
            .iter()
            .map(|s| (s.name.clone(), s.colour, false, s.dash))
            .collect();
        for b in &self.bands {
            if !items.iter().any(|(n, _, band, _)| *band && *n == b.label) {
                items.push((b.label.clone(), b.colour, true, None));
            }
        }
        items
    }

    /// Pixel rectangles `[left, right]` of the bands, clipped to the plot area.
    fn band_spans(&self, lay: &Layout) -> Vec<(f64, f64, Rgb)> {
        let [l, _, r, _] = lay.area;
        self.bands
            .iter()
            .filter_map(|b| {
                let x0 = lay.px([b.from, lay.y.lo])[0].max(l);
                let x1 = lay.px([b.to, lay.y.lo])[0].min(r);
                (x1 > x0).then_some((x0, x1, b.colour))
            })
            .collect()
    }

    /// Pixel polylines of each series, split where `y` is not finite.
    fn runs(&self, lay: &Layout) -> Vec<Vec<Vec<[f64; 2]>>> {
        self.series
            .iter()
            .map(|s| {
                let mut parts: Vec<Vec<[f64; 2]>> = vec![Vec::new()];
                for p in &s.points {
                    if p[0].is_finite() && p[1].is_finite() {
                        parts.last_mut().expect("non-empty").push(lay.px(*p));
                    } else if !parts.last().expect("non-empty").is_empty() {
                        parts.push(Vec::new());
                    }
                }
                parts.retain(|p| !p.is_empty());
                parts
            })
            .collect()
    }

    fn show_markers(&self) -> bool {
        self.series
            .iter()
            .map(|s| s.points.len())
            .max()
            .unwrap_or(0)
            <= 60
    }

    /// The plot as a raster image.
    pub fn render(&self) -> RgbImage {
        let lay = self.layout();
        let (w, h) = (self.width as usize, self.height as usize);
        let mut img = draw::filled(w.max(1), h.max(1), [1.0; 3]);
        let [l, t, r, b] = lay.area;
        for (v, s) in &lay.y.ticks {
            let y = lay.px([lay.x.lo, *v])[1];
            draw::line(&mut img, [l, y], [r, y], GRID, 1.0, 1.0);
            draw::line(&mut img, [l - 5.0, y], [l, y], INK, 1.0, 1.0);
            draw::text(&mut img, s, l - 8.0, y, TICK_PX, INK, Anchor::Right);
        }
        for (v, s) in &lay.x.ticks {
            let x = lay.px([*v, lay.y.lo])[0];
            draw::line(&mut img, [x, b], [x, b + 5.0], INK, 1.0, 1.0);
            draw::text(&mut img, s, x, b + 16.0, TICK_PX, INK, Anchor::Centre);
        }
        for (x0, x1, c) in self.band_spans(&lay) {
            draw::fill_rect(&mut img, x0, t, x1, b, c, BAND_ALPHA);
        }
        draw::stroke_rect(&mut img, l, t, r, b, INK, 1.0);
        for (v, label) in &self.levels {
            let y = lay.px([lay.x.lo, *v])[1];
            if !(t..=b).contains(&y) {
                continue;
            }
            let mut x = l;
            while x < r {
                draw::line(&mut img, [x, y], [(x + 6.0).min(r), y], LEVEL, 1.5, 1.0);
                x += 10.0;
            }
            draw::text(
                &mut img,
                label,
                r - 6.0,
                y - 9.0,
                TICK_PX,
                LEVEL,
                Anchor::Right,
            );
        }
        for &m in &self.marks {
            let x = lay.px([m, lay.y.lo])[0];
            if x < l || x > r {
                continue;
            }
            let mut y = t;
            while y < b {
                draw::line(&mut img, [x, y], [x, (y + 5.0).min(b)], MARK, 1.0, 1.0);
                y += 9.0;
            }
            draw::text(
                &mut img,
                &format_mark(m),
                x,
                t - 8.0,
                TICK_PX,
                MARK,
                Anchor::Centre,
            );
        }
        for (s, parts) in self.series.iter().zip(self.runs(&lay)) {
            for part in &parts {
                match s.dash {
                    Some(dash) => draw::dashed_polyline(&mut img, part, s.colour, 2.0, dash),
                    None => draw::polyline(&mut img, part, s.colour, 2.0, 1.0),
                }
                if self.show_markers() || part.len() == 1 {
                    for p in part {
                        draw::line(&mut img, *p, *p, s.colour, 5.0, 1.0);
                    }
                }
            }
        }
        draw::text(
            &mut img,
            &self.title,
            w as f64 / 2.0,
            22.0,
            TITLE_PX,
            INK,
            Anchor::Centre,
        );
        draw::text(
            &mut img,
            &self.x_label,
            (l + r) / 2.0,
            h as f64 - 20.0,
            LABEL_PX,
            INK,
            Anchor::Centre,
        );
        draw::text_vertical(
            &mut img,
            &self.y_label,
            20.0 + LABEL_PX as f64 / 2.0,
            (t + b) / 2.0,
            LABEL_PX,
            INK,
        );
        for (i, (name, colour, band, dash)) in self.legend().iter().enumerate() {
            let y = t + 12.0 + 22.0 * i as f64;
            let x = lay.legend_x;
            if *band {
                draw::fill_rect(&mut img, x, y - 7.0, x + 26.0, y + 7.0, *colour, BAND_ALPHA);
            } else if let Some(dash) = dash {
                draw::dashed_polyline(&mut img, &[[x, y], [x + 26.0, y]], *colour, 2.5, *dash);
            } else {
                draw::line(&mut img, [x, y], [x + 26.0, y], *colour, 2.5, 1.0);
            }
            draw::text(&mut img, name, x + 34.0, y, LABEL_PX, INK, Anchor::Left);
        }
        img
    }

    /// The plot as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let lay = self.layout();
        let (w, h) = (self.width as f64, self.height as f64);
        let [l, t, r, b] = lay.area;
        let ink = draw::css(INK);
        let mut o = String::new();
        let _ = writeln!(
            o,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="DejaVu Sans, Verdana, Arial, sans-serif">"#
        );
        let _ = writeln!(
            o,
            r#"<rect x="0" y="0" width="{w}" height="{h}" fill="white"/>"#
        );
        for (v, s) in &lay.y.ticks {
            let y = lay.px([lay.x.lo, *v])[1];
            let _ = writeln!(
                o,
                r#"<line x1="{l:.1}" y1="{y:.1}" x2="{r:.1}" y2="{y:.1}" stroke="{}" stroke-width="1"/>"#,
                draw::css(GRID)
            );
            let _ = writeln!(
                o,
                r#"<line x1="{:.1}" y1="{y:.1}" x2="{l:.1}" y2="{y:.1}" stroke="{ink}"/>"#,
                l - 5.0
            );
            let _ = writeln!(
                o,
                r#"<text x="{:.1}" y="{y:.1}" font-size="{TICK_PX}" text-anchor="end" dominant-baseline="central" fill="{ink}">{}</text>"#,
                l - 8.0,
                xml_escape(s)
            );
        }
        for (v, s) in &lay.x.ticks {
            let x = lay.px([*v, lay.y.lo])[0];
            let _ = writeln!(
                o,
                r#"<line x1="{x:.1}" y1="{b:.1}" x2="{x:.1}" y2="{:.1}" stroke="{ink}"/>"#,
                b + 5.0
            );
            let _ = writeln!(
                o,
                r#"<text x="{x:.1}" y="{:.1}" font-size="{TICK_PX}" text-anchor="middle" dominant-baseline="central" fill="{ink}">{}</text>"#,
                b + 16.0,
                xml_escape(s)
            );
        }
        for (x0, x1, c) in self.band_spans(&lay) {
            let _ = writeln!(
                o,
                r#"<rect x="{x0:.1}" y="{t:.1}" width="{:.1}" height="{:.1}" fill="{}" fill-opacity="{BAND_ALPHA}" class="band"/>"#,
                x1 - x0,
                b - t,
                draw::css(c)
            );
        }
        let _ = writeln!(
            o,
            r#"<rect x="{l:.1}" y="{t:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="{ink}"/>"#,
            r - l,
            b - t
        );
        for (v, label) in &self.levels {
            let y = lay.px([lay.x.lo, *v])[1];
            if !(t..=b).contains(&y) {
                continue;
            }
            let lc = draw::css(LEVEL);
            let _ = writeln!(
                o,
                r#"<line x1="{l:.1}" y1="{y:.1}" x2="{r:.1}" y2="{y:.1}" stroke="{lc}" stroke-width="1.5" stroke-dasharray="6 4"/>"#
            );
            let _ = writeln!(
                o,
                r#"<text x="{:.1}" y="{:.1}" font-size="{TICK_PX}" text-anchor="end" dominant-baseline="central" fill="{lc}">{}</text>"#,
                r - 6.0,
                y - 9.0,
                xml_escape(label)
            );
        }
        for &m in &self.marks {
            let x = lay.px([m, lay.y.lo])[0];
            if x < l || x > r {
                continue;
            }
            let mc = draw::css(MARK);
            let _ = writeln!(
                o,
                r#"<line x1="{x:.1}" y1="{t:.1}" x2="{x:.1}" y2="{b:.1}" stroke="{mc}" stroke-dasharray="5 4"/>"#
            );
            let _ = writeln!(
                o,
                r#"<text x="{x:.1}" y="{:.1}" font-size="{TICK_PX}" text-anchor="middle" dominant-baseline="central" fill="{mc}">{}</text>"#,
                t - 8.0,
                xml_escape(&format_mark(m))
            );
        }
        for (s, parts) in self.series.iter().zip(self.runs(&lay)) {
            let c = draw::css(s.colour);
            let _ = writeln!(
                o,
                r#"<g stroke="{c}" fill="{c}"><title>{}</title>"#,
                xml_escape(&s.name)
            );
            for part in &parts {
                let pts: Vec<String> = part
                    .iter()
                    .map(|p| format!("{:.2},{:.2}", p[0], p[1]))
                    .collect();
                let _ = writeln!(
                    o,
                    r#"<polyline points="{}" fill="none" stroke-width="2" stroke-linejoin="round" stroke-linecap="round"{}/>"#,
                    pts.join(" "),
                    dash_attribute(s.dash)
                );
                if self.show_markers() || part.len() == 1 {
                    for p in part {
                        let _ = writeln!(
                            o,
                            r#"<circle cx="{:.2}" cy="{:.2}" r="2.5" stroke="none"/>"#,
                            p[0], p[1]
                        );
                    }
                }
            }
            let _ = writeln!(o, "</g>");
        }
        let _ = writeln!(
            o,
            r#"<text x="{:.1}" y="22" font-size="{TITLE_PX}" text-anchor="middle" dominant-baseline="central" fill="{ink}">{}</text>"#,
            w / 2.0,
            xml_escape(&self.title)
        );
        let _ = writeln!(
            o,
            r#"<text x="{:.1}" y="{:.1}" font-size="{LABEL_PX}" text-anchor="middle" dominant-baseline="central" fill="{ink}">{}</text>"#,
            (l + r) / 2.0,
            h - 20.0,
            xml_escape(&self.x_label)
        );
        let (yx, yy) = (20.0 + LABEL_PX as f64 / 2.0, (t + b) / 2.0);
        let _ = writeln!(
            o,
            r#"<text x="{yx:.1}" y="{yy:.1}" font-size="{LABEL_PX}" text-anchor="middle" dominant-baseline="central" transform="rotate(-90 {yx:.1} {yy:.1})" fill="{ink}">{}</text>"#,
            xml_escape(&self.y_label)
        );
        let _ = writeln!(o, r#"<g class="legend">"#);
        for (i, (name, colour, band, dash)) in self.legend().iter().enumerate() {
            let y = t + 12.0 + 22.0 * i as f64;
            let x = lay.legend_x;
            if *band {
                let _ = writeln!(
                    o,
                    r#"<rect x="{x:.1}" y="{:.1}" width="26" height="14" fill="{}" fill-opacity="{BAND_ALPHA}"/>"#,
                    y - 7.0,
                    draw::css(*colour)
                );
            } else {
                let _ = writeln!(
                    o,
                    r#"<line x1="{x:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="{}" stroke-width="2.5"{}/>"#,
                    x + 26.0,
                    draw::css(*colour),
                    dash_attribute(*dash)
                );
            }
            let _ = writeln!(
                o,
                r#"<text x="{:.1}" y="{y:.1}" font-size="{LABEL_PX}" dominant-baseline="central" fill="{ink}">{}</text>"#,
                x + 34.0,
                xml_escape(name)
            );
        }
        let _ = writeln!(o, "</g>\n</svg>");
        o
    }
}

/// The SVG attribute that dashes a line (nothing for a solid one).
fn dash_attribute(dash: Dash) -> String {
    dash.map_or(String::new(), |[on, off]| {
        format!(r#" stroke-dasharray="{on} {off}""#)
    })
}

/// Escapes text for XML/HTML element content and attribute values.
pub fn xml_escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            c => o.push(c),
        }
    }
    o
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Checks that every tag is closed in order (a small well-formedness check, enough for the
    /// SVG this module writes: no comments, CDATA or processing instructions).
    pub(crate) fn assert_well_formed(xml: &str) {
        let mut stack: Vec<String> = Vec::new();
        let mut rest = xml;
        while let Some(i) = rest.find('<') {
            let after = &rest[i + 1..];
            let j = after.find('>').expect("every tag is closed by '>'");
            let tag = &after[..j];
            assert!(!tag.contains('<'), "stray '<' in {tag:?}");
            if let Some(name) = tag.strip_prefix('/') {
                let open = stack
                    .pop()
                    .unwrap_or_else(|| panic!("close </{name}> without open"));
                assert_eq!(open, name.trim(), "mismatched close tag");
            } else if !tag.ends_with('/') {
                let name = tag.split_whitespace().next().expect("tag name");
                stack.push(name.to_string());
            }
            // Quotes in attributes must balance.
            assert_eq!(
                tag.matches('"').count() % 2,
                0,
                "unbalanced quotes in {tag:?}"
            );
            rest = &after[j + 1..];
        }
        assert!(stack.is_empty(), "unclosed tags {stack:?}");
        assert!(!rest.contains('>'), "stray '>' after the last tag");
    }

    fn sample() -> LinePlot {
        LinePlot {
            marks: vec![2.0],
            title: "RMS vertex error".into(),
            x_label: "frame".into(),
            y_label: "RMS vertex error (% of bbox diagonal)".into(),
            series: vec![
                Series {
                    name: "tracker <v2> & co".into(),
                    colour: crate::report::colormap::run_colour(0),
                    points: (0..12).map(|f| [f as f64, 0.1 * f as f64]).collect(),
                    dash: None,
                },
                Series {
                    name: "baseline".into(),
                    colour: crate::report::colormap::run_colour(1),
                    points: (0..12)
                        .map(|f| [f as f64, if f == 5 { f64::NAN } else { 0.3 * f as f64 }])
                        .collect(),
                    dash: Some([6.0, 4.0]),
                },
            ],
            bands: Vec::new(),
            levels: Vec::new(),
            width: 800,
            height: 450,
        }
    }

    /// A plot of values below 1 with a threshold at 2, and two flagged ranges of one kind.
    fn flagged() -> LinePlot {
        let orange = [1.0, 0.55, 0.0];
        let band = |from: f64, to: f64| Band {
            from,
            to,
            colour: orange,
            label: "suspect frames".into(),
        };
        LinePlot {
            bands: vec![band(3.5, 5.5), band(8.5, 9.5)],
            levels: vec![(2.0, "suspect above 2".into())],
            series: vec![Series {
                name: "tracker".into(),
                colour: crate::report::colormap::run_colour(0),
                points: (0..12).map(|f| [f as f64, 0.05 * f as f64]).collect(),
                dash: None,
            }],
            ..sample()
        }
    }

    #[test]
    fn flagged_frames_are_shaded_and_a_threshold_is_drawn_even_above_the_data() {
        let p = flagged();
        let lay = p.layout();
        // The y axis reaches the threshold although every value is below 0.6.
        assert!(lay.y.hi >= 2.0, "{:?}", lay.y);
        let img = p.render();
        // Inside a band, away from the line and the grid: white tinted orange; outside: white.
        let inside = lay.px([4.5, 1.25]);
        let outside = lay.px([6.5, 1.25]);
        let px = |q: [f64; 2]| img.get(q[0].round() as usize, q[1].round() as usize);
        let tint = px(inside);
        assert!(
            (tint[0] - 1.0).abs() < 0.02 && tint[2] < 0.9 && tint[1] < tint[0],
            "{tint:?}"
        );
        assert_eq!(px(outside), [1.0, 1.0, 1.0]);
        // The dashed threshold line is drawn in its colour where a dash falls.
        let y = lay.px([0.0, 2.0])[1].round() as usize;
        let x0 = lay.area[0].round() as usize;
        let on_line = (x0..x0 + 12).any(|x| {
            let c = img.get(x, y);
            (c[0] - LEVEL[0]).abs() < 0.1 && (c[1] - LEVEL[1]).abs() < 0.1
        });
        assert!(on_line, "no dash of the threshold line at y = {y}");
        // The SVG has both bands, names the kind once in the legend, and labels the threshold.
        let svg = p.to_svg();
        assert_well_formed(&svg);
        assert_eq!(svg.matches("class=\"band\"").count(), 2);
        assert_eq!(svg.matches(">suspect frames</text>").count(), 1);
        assert!(svg.contains(">suspect above 2</text>"));
    }

    #[test]
    fn svg_is_well_formed_and_names_every_series() {
        let svg = sample().to_svg();
        assert_well_formed(&svg);
        assert!(svg.contains("tracker &lt;v2&gt; &amp; co"));
        assert!(svg.contains(">baseline</text>"));
        assert!(svg.contains(">RMS vertex error (% of bbox diagonal)</text>"));
        // The NaN splits the baseline into two polylines: 3 polylines in all.
        assert_eq!(svg.matches("<polyline").count(), 3);
        // The baseline is dashed, in both its pieces and in the legend; the tracker is solid.
        assert_eq!(svg.matches(r#"stroke-dasharray="6 4""#).count(), 3);
    }

    #[test]
    fn a_dashed_line_is_drawn_on_and_off_along_its_length() {
        let ink = [0.0f32, 0.0, 0.0];
        let mut img = draw::filled(60, 9, [1.0; 3]);
        // 50 px along row 4, 6 on and 4 off, the pattern carried across the segments' joint.
        draw::dashed_polyline(
            &mut img,
            &[[5.0, 4.0], [28.0, 4.0], [55.0, 4.0]],
            ink,
            2.0,
            [6.0, 4.0],
        );
        let dark = |x: usize| img.get(x, 4)[0] < 0.5;
        // Dashes over 5–11, 15–21, 25–31, 35–41, 45–51; gaps between.
        for x in [7, 9, 17, 19, 27, 29, 37, 39, 47, 49] {
            assert!(dark(x), "on at x = {x}");
        }
        for x in [13, 23, 33, 43, 53] {
            assert!(!dark(x), "off at x = {x}");
        }
    }

    #[test]
    fn ticks_are_nice_and_cover_the_data() {
        let a = axis(0.0, 3.3, true, false);
        assert_eq!((a.lo, a.hi), (0.0, 4.0));
        let labels: Vec<&str> = a.ticks.iter().map(|t| t.1.as_str()).collect();
        assert_eq!(labels, ["0", "1", "2", "3", "4"]);
        let f = axis(0.0, 119.0, false, true);
        assert_eq!((f.lo, f.hi), (0.0, 119.0));
        assert_eq!(f.ticks.last().unwrap().1, "100");
        let b = axis(0.0, 2.9, true, false);
        let labels: Vec<&str> = b.ticks.iter().map(|t| t.1.as_str()).collect();
        assert_eq!(labels, ["0.0", "0.5", "1.0", "1.5", "2.0", "2.5", "3.0"]);
        let small = axis(0.0, 4.0, false, true);
        assert!(small.ticks.iter().all(|t| t.0.fract() == 0.0));
        assert_eq!(axis(0.0, 0.0023, true, false).ticks[1].1, "0.0005");
    }

    #[test]
    fn raster_plot_draws_series_colours_inside_the_area() {
        let p = sample();
        let img = p.render();
        let lay = p.layout();
        let c = p.series[1].colour;
        // The baseline's point at frame 8 is drawn in its colour.
        let q = lay.px([8.0, 2.4]);
        let got = img.get(q[0].round() as usize, q[1].round() as usize);
        assert!(
            got.iter().zip(c).all(|(a, b)| (a - b).abs() < 0.05),
            "{got:?} vs {c:?}"
        );
    }
}

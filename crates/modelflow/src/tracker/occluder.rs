//! Template pixels whose way into the next frame crosses a still occluder (our addition to the
//! thesis). A rod or a frame edge that stands still in front of a moving surface pulls the mesh
//! toward standing still too: the surface's template pixels just upstream of the occluder's
//! edge land on the occluder under the true motion (a large residual, capped by the robust loss,
//! and at its edge a steep one that pushes back) but beside it under no motion. The cross-camera
//! check (`consensus`) already leaves out the occluder's own pixels; this leaves out the pixels
//! whose path to where the prediction puts them would cross one, the previous frame's and the
//! first frame's (the anchor's, whose path is the whole way the surface went since, so it pulled
//! back hardest: a sheet starting to move behind a 10 cm rod in two cameras, 5.7 mm off after
//! six frames with the previous frame's pixels left out alone, 1.5 mm with the anchor's too).
//!
//! A still occluder is found from the check's verdict: a pixel that every other camera seeing
//! its surface point contradicts (the pixel itself, not its whole patch) and whose colour the
//! next frame shows unchanged at the same place (within the check's own limit, widened by its
//! misalignment tolerance times the gradient there) is marked in its camera. Marks are kept
//! where they cover a patch of the image ([`DENSE_SHARE`] of the window around them: single
//! contradicted pixels that happen to look unchanged are scattered, over a textured blob by the
//! thousand) and grown by [`MARGIN_PX`] (full-resolution pixels, scaled to the level). A kept
//! template pixel is then left out when its position in the previous frame, or any point of the
//! straight path from it to its predicted position in the frame being solved (the
//! constant-velocity prediction, its own triangle's vertices), falls on a mark. Only the
//! upstream side loses pixels: the downstream side moves away from the occluder, where standing
//! still is no better an explanation. An occluder that moves with the surface (a hand holding it)
//! changes at its edges and marks little; highlights that stay put while the surface slides
//! under them are left out as the rod is, for the same reason.
//!
//! Measured on the clips of docs/tracker.md ("Still occluders", 2026-12-01). Hand-written: the
//! tracker's own data on its own warps; deterministic whatever the thread count (each pixel's
//! verdict depends only on the marks, which are built in a fixed order).

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::tracker::consensus::Limit;
use crate::tracker::patch::{Patch, PatchSet, PixelSample};
use nalgebra::{Point2, Point3};
use rayon::prelude::*;

/// How far (full-resolution pixels, Chebyshev) the marks of a still occluder are grown: the
/// prediction's error and the pixels' own footprint.
pub(crate) const MARGIN_PX: f64 = 2.0;
/// A mark is kept when at least this share of the `(2·DENSE_R + 1)²` pixels around it are
/// marked: an occluder covers a patch of the image (on the full-resolution checkerboard half of
/// its pixels are template pixels, so a solid patch shows 12 or 13 of 25, its edge 7 or 8).
pub(crate) const DENSE_SHARE: f64 = 0.3;
/// The half-width of that window, pixels of the level.
const DENSE_R: usize = 2;

/// Where template pixels go: from the surface point on `from` (the template's mesh) to the same
/// point on `to` (the prediction of the frame being solved), seen by `projections` (the
/// template frame's, at one level).
pub(crate) struct Way<'a> {
    pub from: &'a [Point3<f64>],
    pub to: &'a [Point3<f64>],
    pub triangles: &'a [[u32; 3]],
    pub projections: &'a [Projection],
}

impl Way<'_> {
    /// The pixel's surface point on mesh `at`.
    fn point(&self, at: &[Point3<f64>], p: &Patch, s: &PixelSample) -> Point3<f64> {
        let t = self.triangles[p.triangle as usize];
        Point3::from(
            at[t[0] as usize].coords * s.lambda[0] as f64
                + at[t[1] as usize].coords * s.lambda[1] as f64
                + at[t[2] as usize].coords * s.lambda[2] as f64,
        )
    }

    /// Where the pixel's own camera sees its surface point on mesh `at`.
    fn seen(&self, at: &[Point3<f64>], p: &Patch, s: &PixelSample) -> Option<Point2<f64>> {
        self.projections[p.camera as usize].project(&self.point(at, p, s))
    }
}

/// What marks are found from: the template's way into the frame being solved, that frame's
/// images at the template's level, and [`MARGIN_PX`] at that level, in its pixels.
pub(crate) struct Ahead<'a> {
    pub way: Way<'a>,
    pub next: &'a [&'a RgbImage],
    pub margin: f64,
}

/// Per camera, the marks of its still occluders at one level (grown), as the cross-camera check
/// of the previous frame's template found them; the anchor's pixels are judged by them too.
#[derive(Debug)]
pub(crate) struct StillMarks(Vec<Option<Marks>>);

/// One camera's marks, over a window of its image (`x0`, `y0`, `width` × `height`) that holds
/// them all and the room they grow into: occluders cover a small part of most frames, and the
/// work is then over that part only.
#[derive(Debug)]
struct Marks {
    x0: usize,
    y0: usize,
    width: usize,
    height: usize,
    on: Vec<bool>,
}

impl Marks {
    /// The window around `pixels` (image coordinates), grown by `room` and clipped to the
    /// `w` × `h` image, with those pixels marked; `None` without pixels.
    fn of(pixels: &[(usize, usize)], room: usize, w: usize, h: usize) -> Option<Marks> {
        let x0 = pixels.iter().map(|p| p.0).min()?.saturating_sub(room);
        let y0 = pixels.iter().map(|p| p.1).min()?.saturating_sub(room);
        let x1 = (pixels.iter().map(|p| p.0).max()? + room + 1).min(w);
        let y1 = (pixels.iter().map(|p| p.1).max()? + room + 1).min(h);
        let (width, height) = (x1 - x0, y1 - y0);
        let mut on = vec![false; width * height];
        for &(x, y) in pixels {
            on[(y - y0) * width + x - x0] = true;
        }
        Some(Marks {
            x0,
            y0,
            width,
            height,
            on,
        })
    }

    fn at(&self, q: Point2<f64>) -> bool {
        let (x, y) = (q.x.round() - self.x0 as f64, q.y.round() - self.y0 as f64);
        x >= 0.0
            && y >= 0.0
            && (x as usize) < self.width
            && (y as usize) < self.height
            && self.on[y as usize * self.width + x as usize]
    }

    /// Whether the box `[lo, hi]` (image coordinates) overlaps the window.
    fn overlaps(&self, lo: Point2<f64>, hi: Point2<f64>) -> bool {
        hi.x >= self.x0 as f64 - 0.5
            && hi.y >= self.y0 as f64 - 0.5
            && lo.x <= (self.x0 + self.width) as f64 - 0.5
            && lo.y <= (self.y0 + self.height) as f64 - 0.5
    }

    /// Only the marks with at least `share` of the `(2r+1)²` window around them marked (a
    /// summed-area table; the window's part outside the image counts as unmarked).
    fn dense(self, r: usize, share: f64) -> Marks {
        let (w, h) = (self.width, self.height);
        let mut sat = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0u32;
            for x in 0..w {
                row += self.on[y * w + x] as u32;
                sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + row;
            }
        }
        let need = (share * ((2 * r + 1) * (2 * r + 1)) as f64).ceil() as u32;
        let on = (0..w * h)
            .map(|i| {
                if !self.on[i] {
                    return false;
                }
                let (x, y) = (i % w, i / w);
                let (x0, y0) = (x.saturating_sub(r), y.saturating_sub(r));
                let (x1, y1) = ((x + r + 1).min(w), (y + r + 1).min(h));
                let n = sat[y1 * (w + 1) + x1] + sat[y0 * (w + 1) + x0]
                    - sat[y0 * (w + 1) + x1]
                    - sat[y1 * (w + 1) + x0];
                n >= need
            })
            .collect();
        Marks { on, ..self }
    }

    /// Grown by `r` pixels (Chebyshev): a row pass, then a column pass.
    fn grown(self, r: usize) -> Marks {
        let (w, h) = (self.width, self.height);
        let mut rows = vec![false; w * h];
        for y in 0..h {
            for x in (0..w).filter(|&x| self.on[y * w + x]) {
                rows[y * w + x.saturating_sub(r)..=y * w + (x + r).min(w - 1)].fill(true);
            }
        }
        let mut on = vec![false; w * h];
        for y in 0..h {
            for x in (0..w).filter(|&x| rows[y * w + x]) {
                for yy in y.saturating_sub(r)..=(y + r).min(h - 1) {
                    on[yy * w + x] = true;
                }
            }
        }
        Marks { on, ..self }
    }
}

impl Ahead<'_> {
    /// The marks of the still occluders (`None` where there are none) from the check's verdict
    /// on the template's own patches: `contradicted[patch][pixel]`, true where every other
    /// camera that sees the pixel's surface point disagreed with it.
    pub(crate) fn still_marks(
        &self,
        set: &PatchSet,
        contradicted: &[Vec<bool>],
        limit: &Limit,
    ) -> Option<StillMarks> {
        let ncam = self.way.projections.len();
        let mut raw: Vec<Vec<(usize, usize)>> = vec![Vec::new(); ncam];
        for (p, k) in set.patches.iter().zip(contradicted) {
            if p.source != p.camera {
                continue;
            }
            let c = p.camera as usize;
            let img = self.next[c];
            for (j, _) in k.iter().enumerate().filter(|(_, k)| **k) {
                let s = &set.pixels[p.start as usize + j];
                let Some(q) = self.way.seen(self.way.from, p, s) else {
                    continue;
                };
                if !img
                    .sample_exact(q.x, q.y)
                    .is_some_and(|b| limit.matches(s, &b))
                {
                    // It changed: what stood there moved on.
                    continue;
                }
                let (x, y) = (q.x.round() as usize, q.y.round() as usize);
                if x < img.width() && y < img.height() {
                    raw[c].push((x, y));
                }
            }
        }
        let r = self.margin.ceil() as usize;
        let marks: Vec<Option<Marks>> = raw
            .into_par_iter()
            .enumerate()
            .map(|(c, pixels)| {
                let (w, h) = (self.next[c].width(), self.next[c].height());
                Marks::of(&pixels, DENSE_R + r, w, h)
                    .map(|m| m.dense(DENSE_R, DENSE_SHARE))
                    .filter(|m| m.on.iter().any(|&b| b))
                    .map(|m| m.grown(r))
            })
            .collect();
        marks
            .iter()
            .any(Option::is_some)
            .then_some(StillMarks(marks))
    }
}

impl StillMarks {
    /// Leaves out (in `keep`) the kept pixels of `set` whose way (`way`) crosses a mark;
    /// returns how many.
    pub(crate) fn leave_out(&self, set: &PatchSet, keep: &mut [Vec<bool>], way: &Way) -> usize {
        set.patches
            .par_iter()
            .zip(keep.par_iter_mut())
            .map(|(p, k)| {
                let Some(m) = self.0[p.camera as usize]
                    .as_ref()
                    .filter(|_| p.source == p.camera)
                else {
                    return 0;
                };
                // The triangle's corners where the template saw them and where the prediction
                // puts them bound every pixel's way: most patches are far from any mark.
                let proj = &way.projections[p.camera as usize];
                let corners = way.triangles[p.triangle as usize]
                    .iter()
                    .flat_map(|&v| [way.from[v as usize], way.to[v as usize]])
                    .map(|x| proj.project(&x));
                let (mut lo, mut hi) = (
                    Point2::new(f64::INFINITY, f64::INFINITY),
                    Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
                );
                for q in corners {
                    let Some(q) = q else {
                        // A corner behind the camera: no bound, every pixel is looked at.
                        lo = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
                        hi = Point2::new(f64::INFINITY, f64::INFINITY);
                        break;
                    };
                    lo = lo.inf(&q);
                    hi = hi.sup(&q);
                }
                if !m.overlaps(lo, hi) {
                    return 0;
                }
                let mut left = 0;
                for (j, kept) in k.iter_mut().enumerate().filter(|(_, k)| **k) {
                    let s = &set.pixels[p.start as usize + j];
                    let Some(a) = way.seen(way.from, p, s) else {
                        continue;
                    };
                    let b = way.seen(way.to, p, s).unwrap_or(a);
                    // In steps of at most a pixel from the template's position to the
                    // prediction's, both included.
                    let steps = (b - a).norm().ceil() as usize;
                    let crosses = (0..=steps).any(|i| {
                        let f = if steps == 0 {
                            0.0
                        } else {
                            i as f64 / steps as f64
                        };
                        m.at(a + (b - a) * f)
                    });
                    if crosses {
                        *kept = false;
                        left += 1;
                    }
                }
                left
            })
            .sum()
    }

    /// [`StillMarks::leave_out`] on every pixel of `set`, the left-out ones removed.
    pub(crate) fn remove_from(&self, set: &mut PatchSet, way: &Way) -> usize {
        let mut keep: Vec<Vec<bool>> = set
            .patches
            .iter()
            .map(|p| vec![true; (p.end - p.start) as usize])
            .collect();
        let left = self.leave_out(set, &mut keep, way);
        if left > 0 {
            set.retain_pixels(&keep);
        }
        left
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn marks(w: usize, h: usize, on: &[(usize, usize)]) -> Marks {
        let mut m = Marks {
            x0: 0,
            y0: 0,
            width: w,
            height: h,
            on: vec![false; w * h],
        };
        for &(x, y) in on {
            m.on[y * w + x] = true;
        }
        m
    }

    #[test]
    fn marks_grow_by_their_margin_and_no_further() {
        let (w, h) = (9, 7);
        let m = marks(w, h, &[(4, 3)]).grown(2);
        for y in 0..h {
            for x in 0..w {
                let inside = x.abs_diff(4) <= 2 && y.abs_diff(3) <= 2;
                assert_eq!(m.on[y * w + x], inside, "({x}, {y})");
            }
        }
        assert!(m.at(Point2::new(5.6, 1.4)));
        assert!(!m.at(Point2::new(-0.6, 3.0)));
        assert!(!m.at(Point2::new(9.2, 3.0)));
    }

    #[test]
    fn a_window_of_marks_answers_in_image_coordinates() {
        // Two marks near the corner of a 50×32 image, with room for 2 pixels of growth.
        let m = Marks::of(&[(40, 30), (42, 31)], 2, 50, 32).expect("marks");
        assert_eq!((m.x0, m.y0, m.width, m.height), (38, 28, 7, 4));
        assert!(m.at(Point2::new(40.2, 29.6)));
        assert!(!m.at(Point2::new(41.0, 30.0)));
        let m = m.grown(2);
        assert!(m.at(Point2::new(44.0, 31.0)) && m.at(Point2::new(38.0, 28.0)));
        assert!(!m.at(Point2::new(37.0, 30.0)) && !m.at(Point2::new(45.0, 30.0)));
        assert!(m.overlaps(Point2::new(0.0, 0.0), Point2::new(38.0, 28.0)));
        assert!(!m.overlaps(Point2::new(0.0, 0.0), Point2::new(37.0, 40.0)));
        assert!(Marks::of(&[], 2, 50, 32).is_none());
    }

    #[test]
    fn scattered_marks_are_dropped_and_a_covered_patch_is_kept() {
        // A checkerboard patch (as the full-resolution template covers an occluder) from x = 10
        // on, and three single marks far from it and from each other.
        let (w, h) = (24, 12);
        let mut on: Vec<(usize, usize)> = (0..h)
            .flat_map(|y| (10..w).map(move |x| (x, y)))
            .filter(|(x, y)| (x + y) % 2 == 0)
            .collect();
        on.extend([(1, 1), (5, 6), (2, 10)]);
        let m = marks(w, h, &on).dense(DENSE_R, DENSE_SHARE);
        for (x, y) in [(1, 1), (5, 6), (2, 10)] {
            assert!(!m.on[y * w + x], "scattered ({x}, {y}) kept");
        }
        // The patch's inside is kept, one pixel in from its edge included, where the window
        // shows 4 of its 5 columns (10 of 20 checkerboard pixels).
        for y in 2..h - 2 {
            for x in (11..w - 2).filter(|x| (x + y) % 2 == 0) {
                assert!(m.on[y * w + x], "({x}, {y}) of the patch dropped");
            }
        }
    }
}

//! Pictures of meshes for the report: wireframes drawn over camera images (hidden edges faint,
//! decided against a depth map of the same mesh), the oblique "turned" camera where depth errors
//! show, magnified copies of images and cameras for legible panels, side-by-side panel sheets and
//! a labelled colour bar. Filled triangles come from `render`; this module only draws lines.

use crate::base::camera::Projection;
use crate::base::image::RgbImage;
use crate::base::mesh::Mesh;
use crate::report::draw::{self, Anchor, Rgb};
use nalgebra::{Matrix3, Matrix3x4, Matrix4, Point3, Rotation3, Unit, Vector3};

/// Relative depth slack when deciding whether a point on an edge is the front-most surface.
const EDGE_DEPTH_TOLERANCE: f64 = 0.01;

/// Whether a world point at pixel `(u, v)` with depth `z` is not behind the surface of `depth`
/// (row-major, `width` wide, `INFINITY` where empty). Lenient by one pixel (the largest depth in
/// the 3×3 neighbourhood counts), so edges on silhouettes and grazing faces stay visible.
pub fn visible_lenient(depth: &[f64], width: usize, u: f64, v: f64, z: f64) -> bool {
    let height = depth.len() / width.max(1);
    let (i, j) = (u.round() as i64, v.round() as i64);
    let mut far = f64::NEG_INFINITY;
    for y in j - 1..=j + 1 {
        for x in i - 1..=i + 1 {
            if x >= 0 && y >= 0 && (x as usize) < width && (y as usize) < height {
                far = far.max(depth[y as usize * width + x as usize]);
            } else {
                far = f64::INFINITY;
            }
        }
    }
    z <= far * (1.0 + EDGE_DEPTH_TOLERANCE)
}

/// How a wireframe is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WireStyle {
    pub colour: Rgb,
    /// Line width in pixels.
    pub width: f64,
    /// Opacity of visible edges.
    pub alpha: f32,
    /// Opacity of hidden edges (0 skips them).
    pub hidden_alpha: f32,
}

/// Draws `mesh`'s wireframe over `img`, its edges hidden by its own surface (a depth map of
/// `mesh` through `proj` at the image's size) drawn with `style.hidden_alpha`: what every
/// report picture of a mesh over an image draws.
pub fn wireframe_self_hidden(
    img: &mut RgbImage,
    mesh: &Mesh,
    proj: &Projection,
    style: &WireStyle,
) -> crate::error::Result<()> {
    let depth = crate::synth::render::depth_map(mesh, proj, img.width(), img.height())?;
    wireframe(img, mesh, proj, Some(&depth), style);
    Ok(())
}

/// Draws every edge of `mesh` seen through `proj` onto `img`. With a `depth` map (of the image's
/// size, e.g. `render::depth_map` of the same mesh and camera) the parts of edges behind the
/// surface are drawn with `hidden_alpha`; without one all edges are visible. Edges with an end
/// behind the camera are skipped.
pub fn wireframe(
    img: &mut RgbImage,
    mesh: &Mesh,
    proj: &Projection,
    depth: Option<&[f64]>,
    style: &WireStyle,
) {
    let w = img.width();
    for [a, b] in mesh.edges() {
        let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
        let (Some(ua), Some(ub)) = (proj.project(&pa), proj.project(&pb)) else {
            continue;
        };
        let Some(depth) = depth else {
            draw::line(
                img,
                [ua.x, ua.y],
                [ub.x, ub.y],
                style.colour,
                style.width,
                style.alpha,
            );
            continue;
        };
        // Pieces of about 2 px, each visible or not by its midpoint; runs of equal visibility are
        // drawn as one segment so that joints do not blend twice.
        let n = (((ub - ua).norm() / 2.0).ceil() as usize).clamp(1, 4096);
        let at = |t: f64| -> ([f64; 2], f64) {
            let x = pa + (pb - pa) * t;
            let h = proj.project_h(&x);
            ([h.x / h.z, h.y / h.z], h.z)
        };
        let mut run_start = 0usize;
        let mut run_vis = None;
        for k in 0..=n {
            let vis = (k < n).then(|| {
                let (m, z) = at((k as f64 + 0.5) / n as f64);
                visible_lenient(depth, w, m[0], m[1], z)
            });
            if k > 0 && vis != run_vis {
                let alpha = if run_vis == Some(true) {
                    style.alpha
                } else {
                    style.hidden_alpha
                };
                if alpha > 0.0 {
                    let p0 = at(run_start as f64 / n as f64).0;
                    let p1 = at(k as f64 / n as f64).0;
                    draw::line(img, p0, p1, style.colour, style.width, alpha);
                }
                run_start = k;
            }
            run_vis = vis;
        }
    }
}

/// The image-plane affine map that magnifies by `s` about the pixel-centre convention
/// (`u' = (u + 0.5)·s − 0.5`) — the inverse of `Projection::downscaled`.
pub fn magnified(proj: &Projection, s: f64) -> Projection {
    let off = 0.5 * s - 0.5;
    let a = Matrix3::new(s, 0.0, off, 0.0, s, off, 0.0, 0.0, 1.0);
    Projection::from_matrix(&(a * proj.matrix())).expect("a scaled valid projection stays valid")
}

/// `img` magnified by `s` (bilinear, edges clamped), matching [`magnified`].
pub fn magnify_image(img: &RgbImage, s: f64) -> RgbImage {
    if s == 1.0 {
        return img.clone();
    }
    let w = ((img.width() as f64 * s).round() as usize).max(1);
    let h = ((img.height() as f64 * s).round() as usize).max(1);
    let (mu, mv) = ((img.width() - 1) as f64, (img.height() - 1) as f64);
    RgbImage::from_fn(w, h, |x, y| {
        let u = ((x as f64 + 0.5) / s - 0.5).clamp(0.0, mu);
        let v = ((y as f64 + 0.5) / s - 0.5).clamp(0.0, mv);
        img.sample_unchecked(u, v)
    })
}

/// The world direction that points up in the image of `proj` (the camera's −y axis).
pub fn image_up(proj: &Projection) -> Vector3<f64> {
    let m = proj.matrix();
    let m2 = Vector3::new(m[(1, 0)], m[(1, 1)], m[(1, 2)]);
    let m3 = Vector3::new(m[(2, 0)], m[(2, 1)], m[(2, 2)]);
    // For P = K·[R | t] normalised so that row 3 of K·R is r3: row 2 is fy·r2 + cy·r3.
    let r2 = m2 - m3 * m2.dot(&m3);
    -r2.normalize()
}

/// `proj` turned by `degrees` about the vertical (image-up) axis through `pivot`, then re-aimed
/// and zoomed (an image-plane affine map) so that `fit` points fill a `width × height` image with
/// a margin. Where the first camera sees depth as a small image change, the turned one sees it
/// across the image, so depth errors show.
pub fn oblique(
    proj: &Projection,
    pivot: &Point3<f64>,
    degrees: f64,
    fit: &[Point3<f64>],
    width: usize,
    height: usize,
) -> Projection {
    let axis = Unit::new_normalize(image_up(proj));
    // Turning the camera by +θ about the axis = turning the world by −θ.
    let rot = Rotation3::from_axis_angle(&axis, -degrees.to_radians());
    let mut world = Matrix4::identity();
    world.fixed_view_mut::<3, 3>(0, 0).copy_from(rot.matrix());
    let shift = pivot.coords - rot * pivot.coords;
    world.fixed_view_mut::<3, 1>(0, 3).copy_from(&shift);
    let turned: Matrix3x4<f64> = proj.matrix() * world;
    let turned = Projection::from_matrix(&turned).expect("a rotated valid projection stays valid");
    let pts: Vec<_> = fit.iter().filter_map(|p| turned.project(p)).collect();
    if pts.is_empty() {
        return turned;
    }
    let (mut lo, mut hi) = (pts[0], pts[0]);
    for p in &pts {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let margin = 0.08;
    let (sw, sh) = ((hi.x - lo.x).max(1e-9), (hi.y - lo.y).max(1e-9));
    let s = ((width as f64 * (1.0 - 2.0 * margin)) / sw)
        .min((height as f64 * (1.0 - 2.0 * margin)) / sh);
    let c = [(lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0];
    let a = Matrix3::new(
        s,
        0.0,
        (width as f64 - 1.0) / 2.0 - s * c[0],
        0.0,
        s,
        (height as f64 - 1.0) / 2.0 - s * c[1],
        0.0,
        0.0,
        1.0,
    );
    Projection::from_matrix(&(a * turned.matrix())).expect("a zoomed valid projection stays valid")
}

/// Lays panels side by side (one row, equal heights assumed) with a `gap` of `background`.
pub fn side_by_side(panels: &[RgbImage], gap: usize, background: Rgb) -> RgbImage {
    let w: usize = panels.iter().map(|p| p.width()).sum::<usize>()
        + gap * (panels.len().saturating_sub(1))
        + 2 * gap;
    let h = panels.iter().map(|p| p.height()).max().unwrap_or(1) + 2 * gap;
    let mut out = draw::filled(w.max(1), h.max(1), background);
    let mut x = gap;
    for p in panels {
        draw::blit(&mut out, p, x as i64, gap as i64);
        x += p.width() + gap;
    }
    out
}

/// Stacks rows vertically (left-aligned) with a `gap` of `background`, as `side_by_side` does
/// across.
pub fn stacked(rows: &[RgbImage], gap: usize, background: Rgb) -> RgbImage {
    let w = rows.iter().map(|p| p.width()).max().unwrap_or(1);
    let h: usize =
        rows.iter().map(|p| p.height()).sum::<usize>() + gap * rows.len().saturating_sub(1);
    let mut out = draw::filled(w.max(1), h.max(1), background);
    let mut y = 0;
    for r in rows {
        draw::blit(&mut out, r, 0, y as i64);
        y += r.height() + gap;
    }
    out
}

/// A vertical colour bar for `map` over `[0, max]`, `height` px tall, with `ticks` labelled by
/// `label(value)` and a `title` above it, on a white background.
pub fn colour_bar(
    map: impl Fn(f64) -> Rgb,
    max: f64,
    height: usize,
    title: &str,
    label: impl Fn(f64) -> String,
) -> RgbImage {
    let ticks: Vec<f64> = (0..=4).map(|k| max * k as f64 / 4.0).collect();
    let tick_w = ticks
        .iter()
        .map(|&t| draw::text_width(&label(t), 12.0))
        .fold(0.0, f64::max);
    let title_w = draw::text_width(title, 13.0);
    let bar_w = 22.0;
    let width = (16.0 + bar_w + 8.0 + tick_w + 12.0)
        .max(title_w + 16.0)
        .ceil() as usize;
    let mut img = draw::filled(width, height, [1.0; 3]);
    let (top, bottom) = (40.0, height as f64 - 20.0);
    let x0 = 16.0;
    for y in top as usize..bottom as usize {
        let t = (bottom - y as f64) / (bottom - top);
        draw::fill_rect(
            &mut img,
            x0,
            y as f64,
            x0 + bar_w,
            y as f64 + 1.0,
            map(t),
            1.0,
        );
    }
    draw::stroke_rect(&mut img, x0, top, x0 + bar_w, bottom, [0.2; 3], 1.0);
    for &t in &ticks {
        let y = bottom - t / max.max(f64::MIN_POSITIVE) * (bottom - top);
        draw::line(
            &mut img,
            [x0 + bar_w, y],
            [x0 + bar_w + 5.0, y],
            [0.1; 3],
            1.0,
            1.0,
        );
        draw::text(
            &mut img,
            &label(t),
            x0 + bar_w + 8.0,
            y,
            12.0,
            [0.1; 3],
            Anchor::Left,
        );
    }
    draw::text(&mut img, title, 8.0, 18.0, 13.0, [0.1; 3], Anchor::Left);
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Projection {
        let k = Matrix3::new(200.0, 0.0, 79.5, 0.0, 200.0, 59.5, 0.0, 0.0, 1.0);
        Projection::from_krt(&k, &Matrix3::identity(), &Vector3::new(0.0, 0.0, 4.0)).unwrap()
    }

    #[test]
    fn wireframe_edge_lands_where_the_camera_projects_it() {
        // One triangle; its edge (0,1) from (-0.5,-0.3,0) to (0.6,0.2,0) projects (depth 4) to
        // u = 200·x/4 + 79.5, v = 200·y/4 + 59.5: (54.5, 44.5) → (109.5, 69.5).
        let mesh = Mesh::new(
            vec![
                Point3::new(-0.5, -0.3, 0.0),
                Point3::new(0.6, 0.2, 0.0),
                Point3::new(0.0, 0.5, 0.0),
            ],
            vec![[0, 1, 2]],
        );
        let mut img = draw::filled(160, 120, [0.0; 3]);
        let style = WireStyle {
            colour: [1.0, 0.0, 0.0],
            width: 1.0,
            alpha: 1.0,
            hidden_alpha: 0.0,
        };
        wireframe(&mut img, &mesh, &camera(), None, &style);
        for k in 0..=40 {
            let t = k as f64 / 40.0;
            let (u, v) = (54.5 + t * 55.0, 44.5 + t * 25.0);
            // Within 1 px of the projected point some pixel is strongly red.
            let hit = (-1i64..=1).any(|dy| {
                (-1i64..=1).any(|dx| {
                    img.get(
                        (u.round() as i64 + dx) as usize,
                        (v.round() as i64 + dy) as usize,
                    )[0] > 0.6
                })
            });
            assert!(hit, "edge missing near ({u}, {v})");
        }
        // Nothing far from the triangle's edges is drawn.
        assert_eq!(img.get(20, 100), [0.0; 3]);
        assert_eq!(img.get(150, 10), [0.0; 3]);
    }

    #[test]
    fn hidden_edges_use_the_hidden_opacity() {
        let mesh = Mesh::new(
            vec![
                Point3::new(-0.5, 0.0, 0.0),
                Point3::new(0.5, 0.0, 0.0),
                Point3::new(0.0, 0.5, 0.0),
            ],
            vec![[0, 1, 2]],
        );
        // A wall at depth 2 everywhere hides the mesh (at depth 4).
        let depth = vec![2.0; 160 * 120];
        let mut img = draw::filled(160, 120, [0.0; 3]);
        let style = WireStyle {
            colour: [1.0; 3],
            width: 1.0,
            alpha: 1.0,
            hidden_alpha: 0.25,
        };
        wireframe(&mut img, &mesh, &camera(), Some(&depth), &style);
        // Edge (0,1) at v = 59.5 → rows 59 and 60 half covered each: 0.25·0.5 at most... > 0 and faint.
        let p = img.get(80, 59)[0].max(img.get(80, 60)[0]);
        assert!(p > 0.05 && p <= 0.25 + 1e-6, "{p}");
        // With the wall far behind, the same edge is drawn fully.
        let depth = vec![10.0; 160 * 120];
        let mut img = draw::filled(160, 120, [0.0; 3]);
        wireframe(&mut img, &mesh, &camera(), Some(&depth), &style);
        let p = img.get(80, 59)[0].max(img.get(80, 60)[0]);
        assert!(p >= 0.5, "{p}");
    }

    #[test]
    fn back_edges_of_a_box_are_faint_against_the_rendered_depth() {
        // Unit cube at the origin, camera 4 in front: the front face (depth 3.5) hides the
        // back face (depth 4.5), whose edges project inside the front face's outline.
        let mut pos = Vec::new();
        for z in [-0.5, 0.5] {
            for y in [-0.5, 0.5] {
                for x in [-0.5, 0.5] {
                    pos.push(Point3::new(x, y, z));
                }
            }
        }
        let quads = [
            [0, 1, 3, 2],
            [4, 6, 7, 5],
            [0, 4, 5, 1],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 5, 7, 3],
        ];
        let tris = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        let mesh = Mesh::new(pos, tris);
        let p = camera();
        let depth = crate::synth::render::depth_map(&mesh, &p, 160, 120).unwrap();
        let mut img = draw::filled(160, 120, [0.0; 3]);
        let style = WireStyle {
            colour: [1.0; 3],
            width: 1.0,
            alpha: 1.0,
            hidden_alpha: 0.3,
        };
        wireframe(&mut img, &mesh, &p, Some(&depth), &style);
        // Front top edge: v = 59.5 − 200·0.5/3.5 = 30.93; back top edge: v = 59.5 − 200·0.5/4.5 = 37.28.
        let col = |v: usize| img.get(79, v)[0].max(img.get(80, v)[0]);
        assert!(col(31) > 0.85, "front edge drawn fully: {}", col(31));
        let back = col(37).max(col(38));
        assert!(back > 0.1 && back <= 0.3 + 1e-6, "back edge faint: {back}");
    }

    #[test]
    fn magnified_camera_matches_magnified_image() {
        let p = camera();
        let m = magnified(&p, 3.0);
        let x = Point3::new(0.1, -0.2, 0.3);
        let (a, b) = (p.project(&x).unwrap(), m.project(&x).unwrap());
        assert!((b.x - ((a.x + 0.5) * 3.0 - 0.5)).abs() < 1e-9);
        // Bilinear magnification of a ramp keeps the value at corresponding points.
        let img = RgbImage::from_fn(8, 6, |x, _| [x as f32, 0.0, 0.0]);
        let big = magnify_image(&img, 3.0);
        assert_eq!((big.width(), big.height()), (24, 18));
        // Pixel 7 of the big image is centred at u = (7 + 0.5)/3 − 0.5 = 2.0.
        assert!((big.get(7, 4)[0] - 2.0).abs() < 1e-6);
    }

    #[test]
    fn oblique_camera_turns_about_the_vertical_and_keeps_the_mesh_in_view() {
        let p = camera();
        // Image up is world −y for R = I.
        let up = image_up(&p);
        assert!((up - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
        let pts = vec![
            Point3::new(-1.0, -1.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 0.5),
        ];
        let o = oblique(&p, &Point3::origin(), 60.0, &pts, 320, 240);
        // The centre moved by 60° around the pivot at the same distance.
        let c = o.center();
        assert!((c.coords.norm() - 4.0).abs() < 1e-9);
        let cos = c.coords.normalize().dot(&p.center().coords.normalize());
        assert!((cos - 0.5).abs() < 1e-9, "{cos}");
        for x in &pts {
            let q = o.project(x).unwrap();
            assert!(
                q.x > 0.0 && q.x < 319.0 && q.y > 0.0 && q.y < 239.0,
                "{q:?}"
            );
        }
    }
}

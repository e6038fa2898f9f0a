//! Tracker behaviour on exactly rendered planar footage (ray-traced analytically here, so the
//! test does not depend on the project's own renderer): zero motion stays put, a rigid motion is
//! recovered, a moving camera is handled.

use modelflow::camera::{look_at, Camera, Projection};
use modelflow::image::RgbImage;
use modelflow::mesh::{grid, Mesh};
use modelflow::track::{TrackOptions, Tracker};
use nalgebra::{Matrix3, Point3, Vector3};

/// A smooth, colourful, non-periodic texture on the unit square.
fn texture(s: f64, t: f64) -> [f32; 3] {
    let f = |a: f64, b: f64, c: f64, d: f64| (a * s * 6.28 + b * t * 6.28 + c).sin() * d;
    let r = 0.5 + f(7.3, 2.1, 0.3, 0.2) + f(3.1, 11.7, 1.1, 0.15) + f(17.0, 5.3, 2.0, 0.1);
    let g = 0.5 + f(2.9, 8.3, 0.7, 0.2) + f(13.1, 3.7, 2.1, 0.15) + f(6.0, 19.3, 0.4, 0.1);
    let b = 0.5 + f(9.7, 6.1, 1.7, 0.2) + f(4.3, 15.1, 0.2, 0.15) + f(21.0, 9.0, 1.3, 0.1);
    [r as f32, g as f32, b as f32]
}

struct Plane {
    origin: Point3<f64>,
    u: Vector3<f64>,
    v: Vector3<f64>,
}

impl Plane {
    fn at(&self, s: f64, t: f64) -> Point3<f64> {
        self.origin + self.u * s + self.v * t
    }
}

/// Ray-traces the plane with 3×3 supersampling (pixel centres at integer coordinates).
fn render(
    plane: &Plane,
    k: &Matrix3<f64>,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    w: usize,
    h: usize,
) -> RgbImage {
    let kinv = k.try_inverse().unwrap();
    let c = -(r.transpose() * t);
    let n = plane.u.cross(&plane.v);
    RgbImage::from_fn(w, h, |x, y| {
        let mut acc = [0.0f32; 3];
        for sy in 0..3 {
            for sx in 0..3 {
                let px = x as f64 + (sx as f64 - 1.0) / 3.0;
                let py = y as f64 + (sy as f64 - 1.0) / 3.0;
                let d = r.transpose() * (kinv * Vector3::new(px, py, 1.0));
                let lam = (plane.origin - Point3::from(c)).dot(&n) / d.dot(&n);
                let p = Point3::from(c) + d * lam - plane.origin;
                let s = p.dot(&plane.u) / plane.u.norm_squared();
                let tt = p.dot(&plane.v) / plane.v.norm_squared();
                let col = if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&tt) {
                    texture(s, tt)
                } else {
                    [0.1, 0.1, 0.1]
                };
                for ch in 0..3 {
                    acc[ch] += col[ch] / 9.0;
                }
            }
        }
        acc
    })
}

struct Rig {
    k: Matrix3<f64>,
    poses: Vec<(Matrix3<f64>, Vector3<f64>)>,
}

impl Rig {
    fn new(eyes: &[Point3<f64>]) -> Self {
        let k = Matrix3::new(300.0, 0.0, 79.5, 0.0, 300.0, 59.5, 0.0, 0.0, 1.0);
        let poses = eyes
            .iter()
            .map(|e| look_at(e, &Point3::new(0.0, 0.0, 0.0), &Vector3::z()))
            .collect();
        Rig { k, poses }
    }
    fn cameras(&self) -> Vec<Camera> {
        self.poses
            .iter()
            .enumerate()
            .map(|(i, (r, t))| {
                Camera::fixed(
                    format!("cam{i}"),
                    160,
                    120,
                    Projection::from_krt(&self.k, r, t).unwrap(),
                )
            })
            .collect()
    }
    fn images(&self, plane: &Plane) -> Vec<RgbImage> {
        self.poses
            .iter()
            .map(|(r, t)| render(plane, &self.k, r, t, 160, 120))
            .collect()
    }
}

fn plane_at(offset: Vector3<f64>) -> Plane {
    Plane {
        origin: Point3::new(-0.3, 0.0, -0.25) + offset,
        u: Vector3::new(0.6, 0.0, 0.0),
        v: Vector3::new(0.0, 0.1, 0.5),
    }
}

fn mesh_of(plane: &Plane) -> Mesh {
    grid(9, 9, |s, t| plane.at(s, t))
}

fn rms(a: &[Point3<f64>], b: &[Point3<f64>]) -> f64 {
    (a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm_squared())
        .sum::<f64>()
        / a.len() as f64)
        .sqrt()
}

fn rig() -> Rig {
    Rig::new(&[Point3::new(-0.15, -1.5, 0.2), Point3::new(0.15, -1.5, 0.25)])
}

#[test]
fn zero_motion_stays_put() {
    let rig = rig();
    let plane = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane);
    let imgs = rig.images(&plane);
    let mut tr = Tracker::new(&mesh, rig.cameras(), 0, &imgs, TrackOptions::default()).unwrap();
    for f in 1..3 {
        let rep = tr.step(f, &imgs).unwrap();
        assert!(rep.pixels > 5000, "{}", rep.pixels);
    }
    let err = rms(tr.positions(), &mesh.positions);
    assert!(err < 1e-4, "drifted {err} m with no motion");
}

#[test]
fn rigid_motion_is_recovered() {
    let rig = rig();
    let motion = Vector3::new(0.006, -0.004, 0.005);
    let plane0 = plane_at(Vector3::zeros());
    let mesh = mesh_of(&plane0);
    let mut tr = Tracker::new(
        &mesh,
        rig.cameras(),
        0,
        &rig.images(&plane0),
        TrackOptions::default(),
    )
    .unwrap();
    for f in 1..=4u32 {
        let plane = plane_at(motion * f as f64);
        tr.step(f, &rig.images(&plane)).unwrap();
        let truth = mesh_of(&plane).positions;
        let err = rms(tr.positions(), &truth);
        eprintln!("frame {f}: rms error {err:.2e} m");
        // 0.6 m plane; 1 pixel at 1.5 m is 5 mm. Ask for a small fraction of a pixel.
        assert!(err < 1.0e-3, "frame {f}: rms {err}");
    }
}

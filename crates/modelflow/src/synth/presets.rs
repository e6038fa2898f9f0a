//! Synthetic multi-view footage with exact ground truth (our own version of the thesis' "CG cloth
//! data set", §7.1): an analytically moving surface, textured with the procedural pattern of
//! `texture`, rendered by `render` into the images of calibrated cameras, plus the true mesh of
//! every frame. Presets:
//!
//! - `cloth` (default): a 1 m × 1 m sheet of 41 × 41 vertices hanging from a nearly fixed top
//!   edge, with waves travelling down it, a gentle sideways swing and a pleat (a fold across the
//!   sheet, bulging towards the cameras and hiding a strip of cloth) forming over the sequence;
//!   two cameras 25 cm apart at 2.2 m, 20° to the side and 8° above, slightly converging (thesis
//!   Fig. 7.2). Vertical edges keep their rest length exactly (each column is a chain of
//!   unit-length segments); horizontal and diagonal ones stay within 8 % (the columns differ
//!   only slowly).
//! - `blob`: a closed surface (icosphere of radius 0.4 m, 2562 vertices) with five lobes that
//!   swell and shrink while the whole body turns, seen by cameras on a ring around it; the lobes
//!   occlude other parts of the surface.
//! - `irregular`: the blob's surface and motion on an artist-like triangulation (`remesh`): fine
//!   on one side, about four times coarser on the other, jittered vertices (uneven valences,
//!   1 125 vertices, edges from 1.5 to 31 cm at the first frame, median 3.6 cm) and a hole with a
//!   border, through which the inside shows.
//! - `limb`: articulated motion, as a person's arm makes: a capsule 1.24 m long and 24 cm thick
//!   (1 826 vertices in rings) that bends at its middle by up to 60° while its forearm twists
//!   by up to 30°, the whole swinging from its shoulder end and turning slowly, seen by four
//!   cameras on a ring. The bend is spread over 20 cm of the elbow, whose skin along the limb
//!   stretches by about three quarters on the outside and is compressed by two thirds on the inside
//!   (a crook the forearm hides from some cameras). Its texture is baked over the capsule's
//!   `(x, angle)` (`texture::CapsuleTexture`).
//!
//! Any preset can be carried by a hand-held motion on top of its own (`shake`, in pixels per
//! frame): the whole object travels round a circle of 12 frames in the first camera's image
//! plane, with a chord of `shake` pixels at its centre in that camera, while rolling about that
//! camera's axis by a quarter of that motion at its rim. It starts from rest at frame 0, so the
//! first mesh does not change. This makes large per-frame motion (the tracker's capture range)
//! without making the deformation itself faster. `turn` turns the object in the hand instead:
//! degrees per frame about the first camera's image vertical through the object's centre, so
//! that sides come into view and others leave it (a rotation the cameras see out of plane).
//!
//! The texture is a function of the material (rest-pose) coordinates, so it sticks to the
//! surface. Everything is deterministic for a seed (the seed chooses the texture and the image
//! noise; the motion of a preset is fixed). [`Synthetic::generate`] builds everything in memory;
//! [`write_dataset`] writes a scene (`modelflow-scene/1`) with images, initial mesh and ground
//! truth.

use crate::base::camera::{look_at, Camera, Projection};
use crate::base::image::RgbImage;
use crate::base::lens::{DistortMap, Distortion, Lens};
use crate::base::mesh::{grid, Mesh};
use crate::base::units::Units;
use crate::error::{Error, Result};
use crate::input::imageio::write_png;
use crate::input::meshio::write_obj;
use crate::input::scene::{CameraEntry, DistortionEntry, FrameRange, SceneFile, FORMAT};
use crate::synth::remesh::{irregular_sphere, Irregularity};
use crate::synth::render::{render, Light, RenderOptions, Surface};
use crate::synth::texture::{mix64, CapsuleTexture, CubeTexture, PlaneTexture, Texture};
use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector3};
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Frames per second of the synthetic clips (the motion is defined in seconds).
pub const FPS: f64 = 30.0;

/// A synthetic scene type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Preset {
    Cloth,
    Blob,
    Irregular,
    Limb,
    Crossing,
}

impl Preset {
    pub const ALL: [Preset; 5] = [
        Preset::Cloth,
        Preset::Blob,
        Preset::Irregular,
        Preset::Limb,
        Preset::Crossing,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Preset::Cloth => "cloth",
            Preset::Blob => "blob",
            Preset::Irregular => "irregular",
            Preset::Limb => "limb",
            Preset::Crossing => "crossing",
        }
    }

    /// The preset called `name`, or an error listing the presets.
    pub fn from_name(name: &str) -> Result<Preset> {
        Preset::ALL
            .into_iter()
            .find(|p| p.name() == name)
            .ok_or_else(|| {
                let names: Vec<&str> = Preset::ALL.iter().map(|p| p.name()).collect();
                Error::option(
                    "unknown synthetic preset",
                    format!("'{name}'"),
                    format!("one of: {}", names.join(", ")),
                )
            })
    }

    /// Number of cameras when none is asked for.
    pub fn default_cameras(self) -> usize {
        match self {
            Preset::Cloth => 2,
            Preset::Blob | Preset::Irregular | Preset::Limb | Preset::Crossing => 4,
        }
    }
}

impl std::fmt::Display for Preset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What to generate.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthOptions {
    pub preset: Preset,
    /// Number of cameras; `None` = the preset's default (cloth 2, blob 4).
    pub cameras: Option<usize>,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// Standard deviation of additive Gaussian image noise (intensities in [0, 1]).
    pub noise: f64,
    /// Diffuse lighting (off: flat albedo).
    pub light: bool,
    pub seed: u64,
    /// Anti-aliasing subsamples per pixel along each axis.
    pub supersample: u32,
    /// Hand-held motion added to the preset's own, in pixels per frame at the object's centre in
    /// the first camera (0: none); see the module documentation.
    pub shake: f64,
    /// Lens distortion of every camera: the images are rendered through it and the scene file
    /// gives it (`None`: pinhole footage).
    pub distortion: Option<Distortion>,
    /// Vertices along each side of the cloth's grid (`cloth` only; 41 by default: 1 681
    /// vertices). The benchmark's cost model raises it to time larger meshes.
    pub cloth_grid: usize,
    /// Camera clocks out of step, in frames: camera `c` of `n` records frame `f` at time
    /// `f + sync_error·c/(n − 1)` (the first camera on time, the last one the most late; 0: a
    /// genlocked rig). 0.1 is 3.3 ms at 30 fps. The ground truth stays at the frame times.
    pub sync_error: f64,
    /// The shutter's opening as a fraction of a frame, centred on the frame's time (0: an
    /// instant): each image is the mean of renders spread over it, so moving texture smears
    /// along its motion; the scene file records it as each camera's `shutter`.
    pub motion_blur: f64,
    /// A rolling shutter's readout, in frames from the top row to the bottom row (0: a global
    /// shutter): row `y` of `h` is recorded at the camera's time plus
    /// `rolling_shutter·((y + 0.5)/h − 1/2)`, so a moving object leans and stretches; the
    /// scene file records it as each camera's `rolling_shutter`.
    pub rolling_shutter: f64,
    /// A hand-held object turned in the hand: degrees per frame about the first camera's image
    /// vertical through the object's centre, on top of the preset's motion and `shake` (0:
    /// none); it starts from rest at frame 0. Sides come into view and others leave it.
    pub turn: f64,
    /// A textured wall behind the object in every camera's view (off: the flat background
    /// colour). Each camera sees its own wall, square to its optical axis and behind everything
    /// the object reaches, as a room's walls stand behind a rig's subject; it never moves.
    pub backdrop: bool,
    /// A camera knocked off its calibration while filming: rendered turned from a frame on,
    /// while the scene file keeps its calibration.
    pub bump: Option<Bump>,
}

/// A camera turned about its own centre from `frame` on ([`SynthOptions::bump`]), as a knock on
/// its tripod turns it: by `degrees` about the axis `(1, 2, 0.3)` of its own frame (mostly a
/// pan, some tilt, a little roll). The images show it; the scene file does not.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bump {
    pub camera: usize,
    pub frame: u32,
    pub degrees: f64,
}

impl std::str::FromStr for Bump {
    type Err = String;

    /// `CAMERA:FRAME:DEGREES`, e.g. `0:5:0.2`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let parts: Vec<&str> = s.split(':').collect();
        let bad = || format!("expected CAMERA:FRAME:DEGREES (e.g. 0:5:0.2), got `{s}`");
        if parts.len() != 3 {
            return Err(bad());
        }
        Ok(Bump {
            camera: parts[0].trim().parse().map_err(|_| bad())?,
            frame: parts[1].trim().parse().map_err(|_| bad())?,
            degrees: parts[2].trim().parse().map_err(|_| bad())?,
        })
    }
}

impl Bump {
    /// The turn, in the camera's own frame.
    pub fn rotation(&self) -> Rotation3<f64> {
        let axis = Unit::new_normalize(Vector3::new(1.0, 2.0, 0.3));
        Rotation3::from_axis_angle(&axis, self.degrees.to_radians())
    }
}

/// Renders averaged per image for [`SynthOptions::motion_blur`], at least.
const BLUR_SAMPLES: usize = 8;
/// ... and more where the surface moves farther over the shutter: at most this many pixels
/// apart at the fastest vertex, so a long smear is a continuous streak as a real shutter
/// records it, not a few sharp copies of the texture.
const BLUR_SPACING_PX: f64 = 1.0;
/// The most renders one image averages.
const BLUR_SAMPLES_MAX: usize = 160;

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            preset: Preset::Cloth,
            cameras: None,
            width: 640,
            height: 480,
            frames: 120,
            noise: 0.0,
            light: true,
            seed: 1,
            supersample: 3,
            shake: 0.0,
            distortion: None,
            cloth_grid: CLOTH_N,
            sync_error: 0.0,
            motion_blur: 0.0,
            rolling_shutter: 0.0,
            turn: 0.0,
            backdrop: false,
            bump: None,
        }
    }
}

impl SynthOptions {
    /// Defaults for a preset given by name.
    pub fn preset(name: &str) -> Result<Self> {
        Ok(SynthOptions {
            preset: Preset::from_name(name)?,
            ..Default::default()
        })
    }

    pub fn camera_count(&self) -> usize {
        self.cameras.unwrap_or(self.preset.default_cameras())
    }

    /// Checks the options, naming the one at fault.
    pub fn validate(&self) -> Result<()> {
        let n = self.camera_count();
        if !(2..=16).contains(&n) {
            return Err(Error::option(
                "--cameras",
                n,
                "2 to 16 (a scene needs two views of the mesh)",
            ));
        }
        if !(16..=8192).contains(&self.width) {
            return Err(Error::option("--width", self.width, "16 to 8192 pixels"));
        }
        if !(16..=8192).contains(&self.height) {
            return Err(Error::option("--height", self.height, "16 to 8192 pixels"));
        }
        if !(1..=10000).contains(&self.frames) {
            return Err(Error::option("--frames", self.frames, "1 to 10000"));
        }
        if !(self.noise.is_finite() && (0.0..=1.0).contains(&self.noise)) {
            return Err(Error::option("--noise", self.noise, "a sigma in [0, 1]"));
        }
        if !(self.shake.is_finite() && (0.0..=1000.0).contains(&self.shake)) {
            return Err(Error::option(
                "--shake",
                self.shake,
                "0 to 1000 pixels per frame",
            ));
        }
        if !(self.turn.is_finite() && (0.0..=90.0).contains(&self.turn)) {
            return Err(Error::option(
                "--turn",
                self.turn,
                "0 to 90 degrees per frame",
            ));
        }
        if !(self.sync_error.is_finite() && (0.0..=1.0).contains(&self.sync_error)) {
            return Err(Error::option(
                "--sync-error",
                self.sync_error,
                "0 to 1 frame (the last camera's lag)",
            ));
        }
        if !(self.motion_blur.is_finite() && (0.0..=1.0).contains(&self.motion_blur)) {
            return Err(Error::option(
                "--motion-blur",
                self.motion_blur,
                "0 to 1 (the shutter's opening, in frames)",
            ));
        }
        if !(self.rolling_shutter.is_finite() && (0.0..=1.0).contains(&self.rolling_shutter)) {
            return Err(Error::option(
                "--rolling-shutter",
                self.rolling_shutter,
                "0 to 1 (the readout from the top row to the bottom row, in frames)",
            ));
        }
        if !(1..=8).contains(&self.supersample) {
            return Err(Error::option("--supersample", self.supersample, "1 to 8"));
        }
        if !(3..=1000).contains(&self.cloth_grid) {
            return Err(Error::option(
                "--cloth-grid",
                self.cloth_grid,
                "3 to 1000 vertices per side",
            ));
        }
        if let Some(b) = &self.bump {
            if b.camera >= n {
                return Err(Error::option(
                    "--bump",
                    format!("camera {}", b.camera),
                    format!("a camera index below {n}"),
                ));
            }
            if b.frame == 0 || b.frame >= self.frames {
                return Err(Error::option(
                    "--bump",
                    format!("frame {}", b.frame),
                    format!("a frame from 1 to {}", self.frames.saturating_sub(1)),
                ));
            }
            if !(b.degrees.is_finite() && b.degrees.abs() <= 10.0) {
                return Err(Error::option(
                    "--bump",
                    format!("{} degrees", b.degrees),
                    "a turn of at most 10 degrees either way",
                ));
            }
        }
        Ok(())
    }
}

/// The baked texture of a preset.
#[derive(Clone, Debug)]
enum Skin {
    Plane(PlaneTexture),
    Cube(CubeTexture),
    Capsule(CapsuleTexture),
}

/// A generated synthetic sequence, in memory.
#[derive(Clone, Debug)]
pub struct Synthetic {
    pub options: SynthOptions,
    pub cameras: Vec<Camera>,
    /// The mesh at the first frame (frame 0), with texture coordinates.
    pub mesh: Mesh,
    /// Material (rest-pose) coordinate of every vertex; the texture is a function of it.
    pub material: Vec<[f64; 3]>,
    /// True vertex positions of every frame `0..frames`.
    pub truth: Vec<Vec<Point3<f64>>>,
    skin: Skin,
    render_options: RenderOptions,
    /// (K, R, t) of each camera, for the scene file.
    krt: Vec<Krt>,
    /// Per camera, how its raw frame reads the pinhole render (with distortion only).
    distort: Vec<Option<std::sync::Arc<DistortMap>>>,
    /// Per camera, the wall behind the object ([`SynthOptions::backdrop`]).
    backdrops: Vec<Backdrop>,
}

/// One camera's wall ([`SynthOptions::backdrop`]): two triangles and their baked pattern.
#[derive(Clone, Debug)]
struct Backdrop {
    corners: [Point3<f64>; 4],
    /// The corners' material coordinates (the wall's own metres).
    material: [[f64; 3]; 4],
    texture: Muted,
}

/// A wall's pattern, greyer and of less contrast than the objects' (a room's surfaces are
/// duller than the painted subject in front of them).
#[derive(Clone, Debug)]
struct Muted(PlaneTexture);

impl crate::synth::render::Material for Muted {
    fn albedo(&self, m: &[f64; 3]) -> [f32; 3] {
        let c = self.0.sample(m[0], m[1]);
        let lum = 0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2];
        c.map(|v| 0.2 + 0.5 * (0.3 * v + 0.7 * lum))
    }
}

/// Per-frame image motion of the vertices, in pixels, over all cameras and frame pairs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionStats {
    pub max: f64,
    pub median: f64,
}

/// Intrinsics: square pixels, principal point at the image centre, focal length so that a 1 m
/// object at ~2.2 m fills about 80 % of the image height at 4:3.
fn intrinsics(width: u32, height: u32) -> Matrix3<f64> {
    let (w, h) = (width as f64, height as f64);
    let f = 1.3 * w.min(h * 4.0 / 3.0);
    Matrix3::new(
        f,
        0.0,
        (w - 1.0) / 2.0,
        0.0,
        f,
        (h - 1.0) / 2.0,
        0.0,
        0.0,
        1.0,
    )
}

type Krt = (Matrix3<f64>, Matrix3<f64>, Vector3<f64>);

fn camera_looking(
    name: String,
    opts: &SynthOptions,
    eye: Point3<f64>,
    target: Point3<f64>,
) -> (Camera, Krt) {
    let (r, t) = look_at(&eye, &target, &Vector3::z());
    let k = intrinsics(opts.width, opts.height);
    let p = Projection::from_krt(&k, &r, &t).expect("look_at gives a rotation and K is regular");
    (Camera::fixed(name, opts.width, opts.height, p), (k, r, t))
}

/// `count` cameras on a ring round `target` at `distance`, every one aimed at it: the first 15°
/// round from behind the target (−y), the rest evenly spaced, alternately `elevation[0]` and
/// `elevation[1]` degrees above it.
fn ring_rig(
    opts: &SynthOptions,
    count: usize,
    target: Point3<f64>,
    distance: f64,
    elevation: [f64; 2],
) -> (Vec<Camera>, Vec<Krt>) {
    (0..count)
        .map(|c| {
            let az = (15.0 + 360.0 * c as f64 / count as f64).to_radians();
            let el = elevation[c % 2].to_radians();
            let eye = Point3::new(
                distance * el.cos() * az.sin(),
                -distance * el.cos() * az.cos(),
                distance * el.sin(),
            ) + target.coords;
            camera_looking(format!("cam{c}"), opts, eye, target)
        })
        .unzip()
}

fn smoothstep(a: f64, b: f64, x: f64) -> f64 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

// ---------------------------------------------------------------------------------------------
// Cloth

const CLOTH_N: usize = 41;
const CLOTH_SIZE: f64 = 1.0;
const CLOTH_TOP: f64 = 0.5;

/// Vertex positions of the `n × n` cloth at time `t` seconds. Vertex `j·n + i` has material
/// coordinate `X = (i/(n-1) - 0.5)·size` across and arc length `s = j/(n-1)·size` down from the
/// top edge.
fn cloth_positions(n: usize, t: f64) -> Vec<Point3<f64>> {
    use std::f64::consts::PI;
    let ds = CLOTH_SIZE / (n - 1) as f64;
    let h = CLOTH_SIZE;
    // The fold: a pleat bulging towards the cameras, forming between 0.6 s and 3 s, a little
    // lower and stronger on the right than on the left.
    let fold = smoothstep(0.6, 3.0, t);
    let mut out = Vec::with_capacity(n * n);
    out.resize(n * n, Point3::origin());
    for i in 0..n {
        let x = (i as f64 / (n - 1) as f64 - 0.5) * CLOTH_SIZE;
        let (sf, depth, width) = (0.6 + 0.08 * x, 0.85 + 0.25 * x, 0.065 + 0.01 * x);
        // Chain of unit-length segments down this column: every vertical edge keeps its rest
        // length exactly; neighbouring columns differ only slowly, so horizontal and diagonal
        // edges stay within a few per cent.
        let mut p = Vector3::new(0.0, 0.0, CLOTH_TOP);
        for j in 0..n {
            out[j * n + i] = Point3::new(x + p.x, p.y, p.z);
            let sm = (j as f64 + 0.5) * ds;
            let ramp = smoothstep(0.0, 0.35, sm);
            let d = (sm - sf) / width;
            // Depth angle: slow pendulum + two travelling waves + the pleat (derivative of a
            // Gaussian: turns towards the cameras and back, so the cloth below continues
            // parallel to the cloth above).
            let b = 0.12 * (2.0 * PI * t / 4.0).sin() * (sm / h)
                + ramp
                    * (0.3 * (10.0 * sm - 3.3 * t + 1.2 * x).sin()
                        + 0.16 * (17.0 * sm - 4.6 * t - 1.5 * x + 1.3).sin())
                + fold * depth * d * (0.5 - 0.5 * d * d).exp();
            // Lateral angle: a gentle sideways swing (the same for every column).
            let a = 0.05 * (sm / h) * (2.0 * PI * t / 3.2 + 0.4).sin();
            p += Vector3::new(a.sin(), a.cos() * b.sin(), -a.cos() * b.cos()) * ds;
        }
    }
    out
}

fn cloth(opts: &SynthOptions) -> Synthetic {
    let n = opts.cloth_grid;
    let mut mesh = grid(n, n, |_, _| Point3::origin());
    let material: Vec<[f64; 3]> = (0..n * n)
        .map(|k| {
            let (i, j) = (k % n, k / n);
            let x = (i as f64 / (n - 1) as f64 - 0.5) * CLOTH_SIZE;
            let z = CLOTH_TOP - j as f64 / (n - 1) as f64 * CLOTH_SIZE;
            [x, z, 0.0]
        })
        .collect();
    let truth: Vec<Vec<Point3<f64>>> = (0..opts.frames)
        .into_par_iter()
        .map(|f| cloth_positions(n, f as f64 / FPS))
        .collect();
    mesh.positions = truth[0].clone();
    let tex = Texture::new(opts.seed, 0.006);
    let skin = Skin::Plane(tex.bake_plane(
        [-0.5 * CLOTH_SIZE - 0.01, CLOTH_TOP - CLOTH_SIZE - 0.01],
        [CLOTH_SIZE + 0.02, CLOTH_SIZE + 0.02],
        1000.0,
    ));
    // A rig of cameras 25 cm apart, 2.2 m from the cloth, 20° to its left and 8° above,
    // all aimed at the cloth's centre.
    let target = Point3::new(0.0, 0.0, 0.02);
    let (az, el, dist) = (20f64.to_radians(), 8f64.to_radians(), 2.2);
    let view = Vector3::new(-az.sin() * el.cos(), -az.cos() * el.cos(), el.sin());
    let side = Vector3::z().cross(&view).normalize();
    let count = opts.camera_count();
    let (cameras, krt): (Vec<Camera>, Vec<Krt>) = (0..count)
        .map(|c| {
            let off = (c as f64 - (count as f64 - 1.0) / 2.0) * 0.25;
            let eye = target + view * dist + side * off;
            camera_looking(format!("cam{c}"), opts, eye, target)
        })
        .unzip();
    Synthetic {
        options: opts.clone(),
        cameras,
        mesh,
        material,
        truth,
        skin,
        krt,
        distort: Vec::new(),
        backdrops: Vec::new(),
        render_options: render_options(opts, Vector3::new(-0.5, -0.5, 1.0), [0.13, 0.14, 0.17]),
    }
}

// ---------------------------------------------------------------------------------------------
// Blob

const BLOB_RADIUS: f64 = 0.4;

/// A unit icosphere: the icosahedron with each triangle split `levels` times into four.
/// Triangles are counter-clockwise seen from outside.
pub fn icosphere(levels: u32) -> Mesh {
    let p = (1.0 + 5f64.sqrt()) / 2.0;
    let mut pos: Vec<Vector3<f64>> = [
        [-1.0, p, 0.0],
        [1.0, p, 0.0],
        [-1.0, -p, 0.0],
        [1.0, -p, 0.0],
        [0.0, -1.0, p],
        [0.0, 1.0, p],
        [0.0, -1.0, -p],
        [0.0, 1.0, -p],
        [p, 0.0, -1.0],
        [p, 0.0, 1.0],
        [-p, 0.0, -1.0],
        [-p, 0.0, 1.0],
    ]
    .iter()
    .map(|v| Vector3::from(*v).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, pos: &mut Vec<Vector3<f64>>| {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                pos.push(((pos[a as usize] + pos[b as usize]) * 0.5).normalize());
                (pos.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut pos);
            let bc = midpoint(b, c, &mut pos);
            let ca = midpoint(c, a, &mut pos);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    Mesh::new(pos.into_iter().map(Point3::from).collect(), tris)
}

/// Lobe directions (body frame), phases and rates of the blob.
const LOBES: [([f64; 3], f64, f64); 5] = [
    ([0.9, 0.3, 0.3], 0.0, 1.0),
    ([-0.5, 0.8, -0.2], 1.9, 0.8),
    ([-0.3, -0.6, 0.7], 3.7, 1.25),
    ([0.2, -0.4, -0.9], 5.1, 0.9),
    ([-0.8, -0.3, -0.3], 2.6, 1.1),
];

fn blob_positions(dirs: &[Point3<f64>], t: f64) -> Vec<Point3<f64>> {
    let lobes: Vec<(Vector3<f64>, f64)> = LOBES
        .iter()
        .map(|(d, phase, rate)| {
            let amp = 0.5 + 0.16 * (2.0 * std::f64::consts::PI * t * rate / 2.7 + phase).sin();
            (Vector3::from(*d).normalize(), amp)
        })
        .collect();
    let axis = Unit::new_normalize(Vector3::new(0.3, 0.2, 1.0));
    let rot = Rotation3::from_axis_angle(&axis, 0.34 * t);
    dirs.iter()
        .map(|d| {
            let r: f64 = 1.0
                + lobes
                    .iter()
                    .map(|(c, a)| a * (16.0 * (d.coords.dot(c) - 1.0)).exp())
                    .sum::<f64>();
            Point3::from(rot * (d.coords * (BLOB_RADIUS * r)))
        })
        .collect()
}

fn blob(opts: &SynthOptions) -> Synthetic {
    lobed(opts, icosphere(4))
}

fn irregular(opts: &SynthOptions) -> Synthetic {
    let how = Irregularity {
        coarsening: 4.0,
        // Fine towards the first camera, coarse behind; the hole between the first and the last
        // camera, away from the lobes.
        fine_side: Vector3::new(0.3, -0.9, 0.3),
        jitter: 0.3,
        hole: Some((Vector3::new(-0.6, -0.6, 0.2), 0.22)),
        seed: 0x1BE6 ^ opts.seed,
    };
    lobed(opts, irregular_sphere(&icosphere(4), &how))
}

/// The blob's lobed, turning surface on the triangulation `sphere` (vertices on the unit sphere).
fn lobed(opts: &SynthOptions, sphere: Mesh) -> Synthetic {
    let dirs = sphere.positions.clone();
    let material: Vec<[f64; 3]> = dirs
        .iter()
        .map(|d| [d.x * BLOB_RADIUS, d.y * BLOB_RADIUS, d.z * BLOB_RADIUS])
        .collect();
    let truth: Vec<Vec<Point3<f64>>> = (0..opts.frames)
        .into_par_iter()
        .map(|f| blob_positions(&dirs, f as f64 / FPS))
        .collect();
    // Texture coordinates: longitude/latitude of the rest direction (for viewers only).
    let uvs = dirs
        .iter()
        .map(|d| {
            [
                0.5 + d.y.atan2(d.x) / (2.0 * std::f64::consts::PI),
                0.5 + d.z.clamp(-1.0, 1.0).asin() / std::f64::consts::PI,
            ]
        })
        .collect();
    let mesh = Mesh::with_vertex_uvs(truth[0].clone(), sphere.triangles, uvs);
    let tex = Texture::new(opts.seed, 0.006);
    let skin = Skin::Cube(tex.bake_cube(BLOB_RADIUS, 512));
    let ring = Ring {
        target: Point3::origin(),
        distance: 2.5,
        elevation: [12.0, 28.0],
    };
    on_ring(opts, ring, mesh, material, truth, skin)
}

/// Where [`on_ring`] puts its cameras (see [`ring_rig`]).
struct Ring {
    target: Point3<f64>,
    distance: f64,
    elevation: [f64; 2],
}

/// A closed object's scene: `mesh` at the first frame, its `truth` per frame, coloured by `skin`
/// at its `material` coordinates, seen by the preset's cameras on `ring`, lit from the upper
/// front over a dark grey background.
fn on_ring(
    opts: &SynthOptions,
    ring: Ring,
    mesh: Mesh,
    material: Vec<[f64; 3]>,
    truth: Vec<Vec<Point3<f64>>>,
    skin: Skin,
) -> Synthetic {
    let count = opts.camera_count();
    let (cameras, krt) = ring_rig(opts, count, ring.target, ring.distance, ring.elevation);
    Synthetic {
        options: opts.clone(),
        cameras,
        mesh,
        material,
        truth,
        skin,
        krt,
        distort: Vec::new(),
        backdrops: Vec::new(),
        render_options: render_options(opts, Vector3::new(0.4, -0.6, 0.8), [0.12, 0.12, 0.12]),
    }
}

// ---------------------------------------------------------------------------------------------
// Limb

/// Half the length of the limb's cylinder (between its caps' centres), and its radius.
const LIMB_HALF: f64 = 0.5;
const LIMB_RADIUS: f64 = 0.12;

/// A capsule along x: a cylinder from `−half` to `half` of radius `radius` with hemispherical
/// caps, as rings of `around` vertices about `spacing` apart, closed by a vertex at each pole.
/// Triangles are counter-clockwise seen from outside.
fn capsule(half: f64, radius: f64, around: usize, spacing: f64) -> Mesh {
    use std::f64::consts::FRAC_PI_2;
    // The profile (x, distance from the axis) from the −x pole to the +x pole, poles excluded.
    let cap = ((FRAC_PI_2 * radius / spacing).round() as usize).max(2);
    let along = ((2.0 * half / spacing).round() as usize).max(1);
    let mut profile: Vec<(f64, f64)> = Vec::new();
    for k in 1..cap {
        let a = FRAC_PI_2 * k as f64 / cap as f64;
        profile.push((-half - radius * a.cos(), radius * a.sin()));
    }
    for i in 0..=along {
        profile.push((-half + 2.0 * half * i as f64 / along as f64, radius));
    }
    for k in (1..cap).rev() {
        let a = FRAC_PI_2 * k as f64 / cap as f64;
        profile.push((half + radius * a.cos(), radius * a.sin()));
    }
    let mut pos = vec![Point3::new(-half - radius, 0.0, 0.0)];
    for &(x, rho) in &profile {
        for s in 0..around {
            let th = 2.0 * std::f64::consts::PI * s as f64 / around as f64;
            pos.push(Point3::new(x, rho * th.cos(), rho * th.sin()));
        }
    }
    pos.push(Point3::new(half + radius, 0.0, 0.0));
    let ring = |r: usize, s: usize| (1 + r * around + s % around) as u32;
    let last = (pos.len() - 1) as u32;
    let mut tris = Vec::new();
    for s in 0..around {
        tris.push([0, ring(0, s + 1), ring(0, s)]);
    }
    for r in 0..profile.len() - 1 {
        for s in 0..around {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s + 1),
                ring(r + 1, s),
            );
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    let r = profile.len() - 1;
    for s in 0..around {
        tris.push([ring(r, s), ring(r, s + 1), last]);
    }
    Mesh::new(pos, tris)
}

/// The limb's vertices at time `t` seconds from their rest positions `rest` (the capsule along
/// x, the elbow at the origin): the forearm (x > 0) twists about its axis, up to 30° at the
/// wrist, and bends at the elbow by up to 60° (the bend spread over 20 cm of the elbow, so the
/// skin there stretches on the outside and folds on the inside); the whole limb swings about the
/// shoulder (the −x end) and turns slowly.
fn limb_positions(rest: &[Point3<f64>], t: f64) -> Vec<Point3<f64>> {
    use std::f64::consts::PI;
    let twist = 30f64.to_radians() * (2.0 * PI * t / 5.0).sin();
    let bend = 60f64.to_radians() * 0.5 * (1.0 - (2.0 * PI * t / 5.2).cos());
    let swing = Rotation3::from_axis_angle(
        &Vector3::y_axis(),
        8f64.to_radians() * (2.0 * PI * t / 6.0).sin(),
    );
    let turn =
        Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.2, 0.1, 1.0)), 0.15 * t);
    let shoulder = Vector3::new(-LIMB_HALF - LIMB_RADIUS, 0.0, 0.0);
    let extent = LIMB_HALF + LIMB_RADIUS;
    rest.iter()
        .map(|p| {
            let x = p.x;
            let twisted =
                Rotation3::from_axis_angle(&Vector3::x_axis(), twist * smoothstep(0.0, extent, x))
                    * p.coords;
            let bent =
                Rotation3::from_axis_angle(&Vector3::z_axis(), bend * smoothstep(-0.1, 0.1, x))
                    * twisted;
            let swung = swing * (bent - shoulder) + shoulder;
            Point3::from(turn * swung)
        })
        .collect()
}

/// A limb: a capsule 1.24 m long and 24 cm thick (1 826 vertices) that bends at its middle like
/// an elbow while its forearm twists, the whole swinging and turning, seen by cameras on a ring.
fn limb(opts: &SynthOptions) -> Synthetic {
    let rest = capsule(LIMB_HALF, LIMB_RADIUS, 32, 0.0236);
    let material: Vec<[f64; 3]> = rest.positions.iter().map(|p| [p.x, p.y, p.z]).collect();
    let truth: Vec<Vec<Point3<f64>>> = (0..opts.frames)
        .into_par_iter()
        .map(|f| limb_positions(&rest.positions, f as f64 / FPS))
        .collect();
    let mesh = Mesh::with_vertex_uvs(truth[0].clone(), rest.triangles, capsule_uvs(&material));
    let ring = Ring {
        target: Point3::new(0.0, 0.1, 0.0),
        distance: 2.6,
        elevation: [14.0, 32.0],
    };
    on_ring(opts, ring, mesh, material, truth, capsule_skin(opts))
}

/// Texture coordinates of points given in the limb capsule's material coordinates: the angle
/// round its axis, and the position along it.
fn capsule_uvs(material: &[[f64; 3]]) -> Vec<[f64; 2]> {
    let extent = LIMB_HALF + LIMB_RADIUS;
    material
        .iter()
        .map(|m| {
            [
                0.5 + m[2].atan2(m[1]) / (2.0 * std::f64::consts::PI),
                (m[0] + extent) / (2.0 * extent),
            ]
        })
        .collect()
}

/// The limb capsule's texture, baked over its surface.
fn capsule_skin(opts: &SynthOptions) -> Skin {
    let tex = Texture::new(opts.seed, 0.006);
    Skin::Capsule(tex.bake_capsule(LIMB_HALF, LIMB_RADIUS, 1000.0))
}

// ---------------------------------------------------------------------------------------------
// Crossing

/// The crossing's two pieces at time `t` seconds, from the limb's capsule `rest` (along x): a
/// body (the capsule stood up along z) swaying 5° about y, and an arm (the capsule lying along
/// x, 40 cm in front of the body on the −y side) that sweeps up and down 35 cm across it while
/// tilting by up to 12°. One mesh: the body's vertices first, then the arm's.
fn crossing_positions(rest: &[Point3<f64>], t: f64) -> Vec<Point3<f64>> {
    use std::f64::consts::PI;
    let sway = Rotation3::from_axis_angle(
        &Vector3::y_axis(),
        5f64.to_radians() * (2.0 * PI * t / 7.0).sin(),
    );
    let phase = 2.0 * PI * t / 6.0;
    let tilt = Rotation3::from_axis_angle(&Vector3::y_axis(), 12f64.to_radians() * phase.cos());
    let arm_at = Vector3::new(0.0, -0.4, 0.35 * phase.sin());
    let body = rest
        .iter()
        .map(|p| Point3::from(sway * Vector3::new(p.y, p.z, p.x)));
    let arm = rest.iter().map(|p| Point3::from(tilt * p.coords + arm_at));
    body.chain(arm).collect()
}

/// A crossing: a body and an arm that sweeps up and down across in front of it (the limb's
/// capsule twice, 3 652 vertices in one mesh of two pieces), seen by cameras on a ring: the
/// cameras in front see the arm cover and uncover the body every frame, those behind see the
/// body hide the arm. What people do in front of a rig; docs/tracker.md, "What the mesh itself
/// hides".
fn crossing(opts: &SynthOptions) -> Synthetic {
    let piece = capsule(LIMB_HALF, LIMB_RADIUS, 32, 0.0236);
    let n = piece.positions.len();
    let rest: Vec<Point3<f64>> = piece.positions.clone();
    // The arm reads the capsule's texture mirrored end to end and side to side: another pattern.
    let material: Vec<[f64; 3]> = rest
        .iter()
        .map(|p| [p.x, p.y, p.z])
        .chain(rest.iter().map(|p| [-p.x, -p.y, p.z]))
        .collect();
    let mut triangles = piece.triangles.clone();
    triangles.extend(piece.triangles.iter().map(|t| t.map(|v| v + n as u32)));
    let truth: Vec<Vec<Point3<f64>>> = (0..opts.frames)
        .into_par_iter()
        .map(|f| crossing_positions(&rest, f as f64 / FPS))
        .collect();
    let mesh = Mesh::with_vertex_uvs(truth[0].clone(), triangles, capsule_uvs(&material));
    let ring = Ring {
        target: Point3::new(0.0, -0.2, 0.0),
        distance: 3.1,
        elevation: [10.0, 25.0],
    };
    on_ring(opts, ring, mesh, material, truth, capsule_skin(opts))
}

fn render_options(opts: &SynthOptions, light: Vector3<f64>, background: [f32; 3]) -> RenderOptions {
    RenderOptions {
        supersample: opts.supersample,
        background,
        light: opts.light.then_some(Light {
            direction: light,
            ambient: 0.25,
            diffuse: 0.85,
        }),
        near: 1e-3,
    }
}

// ---------------------------------------------------------------------------------------------

/// Adds seeded Gaussian noise (Box–Muller over SplitMix64) and clamps to [0, 1].
fn add_noise(img: &mut RgbImage, sigma: f64, seed: u64) {
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        ((mix64(state) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    for px in img.pixels_mut() {
        for pair in [[0usize, 1], [2, 3]] {
            let (u1, u2) = (next(), next());
            let r = (-2.0 * u1.ln()).sqrt() * sigma;
            let th = 2.0 * std::f64::consts::PI * u2;
            for (k, ch) in pair.into_iter().enumerate() {
                if ch < 3 {
                    let z = if k == 0 { r * th.cos() } else { r * th.sin() };
                    px[ch] = (px[ch] as f64 + z).clamp(0.0, 1.0) as f32;
                }
            }
        }
    }
}

impl Synthetic {
    /// Generates a preset's geometry, cameras and texture (images are rendered on demand).
    pub fn generate(opts: &SynthOptions) -> Result<Self> {
        opts.validate()?;
        let mut s = match opts.preset {
            Preset::Cloth => cloth(opts),
            Preset::Blob => blob(opts),
            Preset::Irregular => irregular(opts),
            Preset::Limb => limb(opts),
            Preset::Crossing => crossing(opts),
        };
        if opts.turn > 0.0 {
            s.turn(opts.turn);
        }
        if opts.shake > 0.0 {
            s.shake(opts.shake);
        }
        // The rig's clocks, as the scene file tells them to the tracker.
        let n = s.cameras.len();
        let lags: Vec<f64> = (0..n).map(|c| s.exposure_lag(c, n)).collect();
        for (cam, lag) in s.cameras.iter_mut().zip(lags) {
            cam.time_offset = lag;
            // The shutter the images were rendered with, as the scene file tells it.
            cam.shutter = opts.motion_blur;
            cam.rolling_shutter = opts.rolling_shutter;
        }
        if let Some(d) = opts.distortion.as_ref().filter(|d| !d.is_identity()) {
            for (cam, (k, _, _)) in s.cameras.iter_mut().zip(&s.krt) {
                let lens = Lens::new(*k, d.clone());
                s.distort.push(Some(std::sync::Arc::new(DistortMap::new(
                    &lens,
                    cam.width as usize,
                    cam.height as usize,
                ))));
                cam.lens = Some(lens);
            }
        }
        if opts.backdrop {
            s.backdrops = (0..s.cameras.len()).map(|c| s.backdrop(c)).collect();
        }
        if let Some(b) = opts.bump {
            // Rendered turned from the bump on; the scene file keeps `krt`.
            let (k, r, t) = &s.krt[b.camera];
            let turn = b.rotation();
            let (r2, t2) = (turn.matrix() * r, turn * t);
            let before = Projection::from_krt(k, r, t).expect("a rig camera is regular");
            let after = Projection::from_krt(k, &r2, &t2).expect("a turned camera is regular");
            let poses = (0..=b.frame)
                .map(|f| {
                    if f < b.frame {
                        before.clone()
                    } else {
                        after.clone()
                    }
                })
                .collect();
            let cam = &s.cameras[b.camera];
            let mut moved = Camera::moving(cam.name.clone(), cam.width, cam.height, 0, poses)
                .with_lens(cam.lens.clone());
            moved.time_offset = cam.time_offset;
            moved.shutter = cam.shutter;
            s.cameras[b.camera] = moved;
        }
        Ok(s)
    }

    /// Camera `c`'s wall: square to its optical axis, half the object's size behind the
    /// farthest point the object reaches in any frame, a quarter wider than the image on every
    /// side, its pattern baked at about a texel per pixel.
    fn backdrop(&self, c: usize) -> Backdrop {
        let (k, r, t) = &self.krt[c];
        let cam = &self.cameras[c];
        let first = &self.truth[0];
        let size = crate::base::mesh::bbox_diagonal(first);
        let far = self
            .truth
            .iter()
            .flatten()
            .map(|p| (r * p.coords + t).z)
            .fold(f64::NEG_INFINITY, f64::max);
        let z = far + 0.5 * size;
        let kinv = k.try_inverse().expect("intrinsics are regular");
        let (w, h) = (cam.width as f64, cam.height as f64);
        let (mx, my) = (0.25 * w, 0.25 * h);
        let corner = |u: f64, v: f64| kinv * Vector3::new(u, v, 1.0) * z;
        let ends = [
            corner(-0.5 - mx, -0.5 - my),
            corner(w - 0.5 + mx, -0.5 - my),
            corner(w - 0.5 + mx, h - 0.5 + my),
            corner(-0.5 - mx, h - 0.5 + my),
        ];
        let world = |q: &Vector3<f64>| Point3::from(r.transpose() * (q - t));
        let texels_per_metre = k[(0, 0)] / z;
        let (x0, y0) = (ends[0].x, ends[0].y);
        let extent = [ends[2].x - x0, ends[2].y - y0];
        let pattern = Texture::new(
            mix64(self.options.seed ^ 0xBAC0_D809 ^ c as u64),
            2.5 / texels_per_metre,
        );
        Backdrop {
            corners: ends.each_ref().map(world),
            material: ends.map(|q| [q.x, q.y, 0.0]),
            texture: Muted(pattern.bake_plane([x0, y0], extent, texels_per_metre)),
        }
    }

    pub fn frames(&self) -> u32 {
        self.truth.len() as u32
    }

    /// The mean of the first frame's vertices: what `turn` and `shake` move the object about.
    fn first_centre(&self) -> Point3<f64> {
        let first = &self.truth[0];
        Point3::from(first.iter().map(|p| p.coords).sum::<Vector3<f64>>() / first.len() as f64)
    }

    /// Turns the object by `degrees` per frame about the first camera's image vertical through
    /// its first frame's centre (see the module documentation).
    fn turn(&mut self, degrees: f64) {
        let centre = self.first_centre();
        let r = &self.krt[0].1;
        // The camera's y axis (image down) in the world: its second row of R.
        let down = Unit::new_normalize(Vector3::new(r[(1, 0)], r[(1, 1)], r[(1, 2)]));
        // Frame 0 stays as it is, to the bit: the scene's mesh.
        for (f, frame) in self.truth.iter_mut().enumerate().skip(1) {
            let rot = Rotation3::from_axis_angle(&down, (degrees * f as f64).to_radians());
            for p in frame.iter_mut() {
                *p = centre + rot * (*p - centre);
            }
        }
    }

    /// Adds the hand-held motion of `px` pixels per frame (see the module documentation).
    fn shake(&mut self, px: f64) {
        const PERIOD: f64 = 12.0;
        let first = &self.truth[0];
        let centre = self.first_centre();
        let radius = first
            .iter()
            .map(|p| (p - centre).norm())
            .fold(0.0, f64::max);
        let (k, r, _) = &self.krt[0];
        let cam = self.cameras[0].at(0);
        // The camera's axes in the world: rows of R (x right, y down, z forward).
        let (right, down, axis) = (
            Vector3::new(r[(0, 0)], r[(0, 1)], r[(0, 2)]),
            Vector3::new(r[(1, 0)], r[(1, 1)], r[(1, 2)]),
            Vector3::new(r[(2, 0)], r[(2, 1)], r[(2, 2)]),
        );
        // World distance per frame that moves the centre `px` pixels in the first camera.
        let step = px * cam.depth(&centre) / k[(0, 0)];
        let circle = step / (2.0 * (std::f64::consts::PI / PERIOD).sin());
        let roll = 0.25 * step / radius;
        let axis = Unit::new_normalize(axis);
        for (f, frame) in self.truth.iter_mut().enumerate() {
            let a = 2.0 * std::f64::consts::PI * f as f64 / PERIOD;
            let offset = (right * (1.0 - a.cos()) + down * a.sin()) * circle;
            let rot = Rotation3::from_axis_angle(&axis, roll * f as f64);
            for p in frame.iter_mut() {
                *p = centre + rot * (*p - centre) + offset;
            }
        }
    }

    /// The true mesh at `frame` (panics past the last frame).
    pub fn frame_mesh(&self, frame: u32) -> Mesh {
        self.mesh.with_positions(self.truth[frame as usize].clone())
    }

    /// The true positions at time `t` in frames: through the frames around it by a Catmull–Rom
    /// spline (exact at the frames, with a velocity that changes smoothly through them, as a
    /// moving object's does), and continued along the first or last frame pair before the
    /// first or past the last frame.
    pub fn positions_at(&self, t: f64) -> Vec<Point3<f64>> {
        let n = self.truth.len();
        if n == 1 || t == t.floor() && (0.0..n as f64).contains(&t) {
            return self.truth[(t.max(0.0) as usize).min(n - 1)].clone();
        }
        let i = (t.floor().max(0.0) as usize).min(n - 2);
        let a = t - i as f64;
        let (p1, p2) = (&self.truth[i], &self.truth[i + 1]);
        if !(0.0..=1.0).contains(&a) {
            return p1.iter().zip(p2).map(|(p, q)| p + (q - p) * a).collect();
        }
        // Neighbours beyond the ends are continued linearly.
        let p0: Vec<Point3<f64>> = match i {
            0 => p1.iter().zip(p2).map(|(p, q)| p - (q - p)).collect(),
            _ => self.truth[i - 1].clone(),
        };
        let p3: Vec<Point3<f64>> = match self.truth.get(i + 2) {
            Some(p) => p.clone(),
            None => p2.iter().zip(p1).map(|(q, p)| q + (q - p)).collect(),
        };
        let (a2, a3) = (a * a, a * a * a);
        let w = [
            0.5 * (-a3 + 2.0 * a2 - a),
            0.5 * (3.0 * a3 - 5.0 * a2 + 2.0),
            0.5 * (-3.0 * a3 + 4.0 * a2 + a),
            0.5 * (a3 - a2),
        ];
        (0..p1.len())
            .map(|v| {
                Point3::from(
                    p0[v].coords * w[0]
                        + p1[v].coords * w[1]
                        + p2[v].coords * w[2]
                        + p3[v].coords * w[3],
                )
            })
            .collect()
    }

    /// How late camera `camera` of `n` records each frame, in frames
    /// ([`SynthOptions::sync_error`]).
    fn exposure_lag(&self, camera: usize, n: usize) -> f64 {
        if n > 1 {
            self.options.sync_error * camera as f64 / (n - 1) as f64
        } else {
            0.0
        }
    }

    /// The times (in frames) whose renders make camera `camera`'s image of `frame` exposed
    /// `shift` frames after its own time (a rolling shutter's band of rows): its clock's lag
    /// ([`SynthOptions::sync_error`]) and the shutter's samples
    /// ([`SynthOptions::motion_blur`]).
    fn exposure_times(&self, camera: usize, frame: u32, shift: f64) -> Vec<f64> {
        let t = frame as f64 + self.exposure_lag(camera, self.cameras.len()) + shift;
        let s = self.options.motion_blur;
        if s > 0.0 {
            // The longest way a vertex's image goes while the shutter is open.
            let longest = self.longest_way(camera, frame, t, s);
            let n =
                ((longest / BLUR_SPACING_PX).ceil() as usize).clamp(BLUR_SAMPLES, BLUR_SAMPLES_MAX);
            (0..n)
                .map(|k| t + s * ((k as f64 + 0.5) / n as f64 - 0.5))
                .collect()
        } else {
            vec![t]
        }
    }

    /// The image of camera `camera` at `frame` (with the configured noise, clock lag and motion
    /// blur). Panics if either is out of range (`cameras.len()`, [`Synthetic::frames`]).
    pub fn render(&self, camera: usize, frame: u32) -> RgbImage {
        let rs = self.options.rolling_shutter;
        let mut img = if rs > 0.0 {
            // A rolling shutter: bands of rows, each rendered (and smeared) at its own
            // instant, so close that the fastest vertex moves at most half a pixel from one
            // band's instant to the next (a row is at most a quarter pixel from where it was
            // at its exact instant).
            let bands = self.readout_bands(camera, frame);
            let mut out = self.exposed(camera, frame, rs * (0.5 / bands as f64 - 0.5));
            let (w, h) = (out.width(), out.height());
            let band_of = |y: usize| (((y as f64 + 0.5) / h as f64) * bands as f64) as usize;
            for b in 1..bands {
                let rows: Vec<usize> = (0..h).filter(|&y| band_of(y) == b).collect();
                let (Some(&first), Some(&last)) = (rows.first(), rows.last()) else {
                    continue;
                };
                let shift = rs * ((b as f64 + 0.5) / bands as f64 - 0.5);
                let part = self.exposed(camera, frame, shift);
                out.pixels_mut()[first * w..(last + 1) * w]
                    .copy_from_slice(&part.pixels()[first * w..(last + 1) * w]);
            }
            out
        } else {
            self.exposed(camera, frame, 0.0)
        };
        if self.options.noise > 0.0 {
            let seed =
                mix64(self.options.seed ^ 0x0153_E000 ^ ((camera as u64) << 40) ^ frame as u64);
            add_noise(&mut img, self.options.noise, seed);
        }
        img
    }

    /// The longest way, in pixels, that any vertex's image in camera `camera` (posed as at
    /// `frame`) goes over the `span` frames centred on time `t`, measured over four parts.
    fn longest_way(&self, camera: usize, frame: u32, t: f64, span: f64) -> f64 {
        let proj = self.cameras[camera].at(frame);
        let seen = |time: f64| -> Vec<Option<nalgebra::Point2<f64>>> {
            self.positions_at(time)
                .iter()
                .map(|p| proj.project(p))
                .collect()
        };
        let mut way = vec![0.0f64; self.mesh.positions.len()];
        let mut last = seen(t - 0.5 * span);
        for k in 1..=4 {
            let now = seen(t + span * (k as f64 / 4.0 - 0.5));
            for ((w, a), b) in way.iter_mut().zip(&last).zip(&now) {
                if let (Some(a), Some(b)) = (a, b) {
                    *w += (b - a).norm();
                }
            }
            last = now;
        }
        way.iter().cloned().fold(0.0, f64::max)
    }

    /// How many bands of rows make camera `camera`'s rolling-shutter image of `frame`: the
    /// fastest vertex's image moves at most half a pixel between two bands' instants (at
    /// least 4 bands, at most one per row).
    fn readout_bands(&self, camera: usize, frame: u32) -> usize {
        let t = frame as f64 + self.exposure_lag(camera, self.cameras.len());
        let longest = self.longest_way(camera, frame, t, self.options.rolling_shutter);
        let rows = self.cameras[camera].height.max(4) as usize;
        ((longest / 0.5).ceil() as usize).clamp(4, rows)
    }

    /// The noiseless image of camera `camera` at `frame` exposed `shift` frames after its own
    /// time (its clock's lag and the shutter's samples, [`Synthetic::exposure_times`]).
    fn exposed(&self, camera: usize, frame: u32, shift: f64) -> RgbImage {
        let times = self.exposure_times(camera, frame, shift);
        let mut img = self.render_at(camera, frame, times[0]);
        if times.len() > 1 {
            let mut sum: Vec<[f64; 3]> = img.pixels().iter().map(|p| p.map(|v| v as f64)).collect();
            for &t in &times[1..] {
                for (s, p) in sum
                    .iter_mut()
                    .zip(self.render_at(camera, frame, t).pixels())
                {
                    for k in 0..3 {
                        s[k] += p[k] as f64;
                    }
                }
            }
            let inv = 1.0 / times.len() as f64;
            for (p, s) in img.pixels_mut().iter_mut().zip(&sum) {
                *p = s.map(|v| (v * inv) as f32);
            }
        }
        img
    }

    /// The noiseless render of camera `camera` (posed as at `frame`) of the surface at time `t`.
    fn render_at(&self, camera: usize, frame: u32, t: f64) -> RgbImage {
        let mut mesh = self.mesh.with_positions(self.positions_at(t));
        let object = match &self.skin {
            Skin::Plane(t) => Surface::Material(t),
            Skin::Cube(t) => Surface::Material(t),
            Skin::Capsule(t) => Surface::Material(t),
        };
        let mut material = std::borrow::Cow::Borrowed(&self.material[..]);
        let wall = self
            .backdrops
            .get(camera)
            .map(|b| Surface::Material(&b.texture));
        let surface = match (&wall, self.backdrops.get(camera)) {
            (Some(wall), Some(b)) => {
                // The wall's two triangles after the object's.
                let at = mesh.triangles.len() as u32;
                let v = mesh.positions.len() as u32;
                mesh = Mesh::new(
                    mesh.positions.iter().copied().chain(b.corners).collect(),
                    mesh.triangles
                        .iter()
                        .copied()
                        .chain([[v, v + 1, v + 2], [v, v + 2, v + 3]])
                        .collect(),
                );
                material = std::borrow::Cow::Owned(
                    self.material.iter().copied().chain(b.material).collect(),
                );
                Surface::Split {
                    at,
                    first: &object,
                    rest: wall,
                }
            }
            _ => object,
        };
        let material = &material[..];
        let cam = &self.cameras[camera];
        match self.distort.get(camera).and_then(|d| d.as_deref()) {
            None => render(
                &mesh,
                material,
                &surface,
                cam.at(frame),
                cam.width as usize,
                cam.height as usize,
                &self.render_options,
            ),
            Some(map) => {
                // The pinhole render on a canvas that holds every raw pixel's ray, then
                // resampled through the lens.
                let ((u0, v0), (w, h)) = map.canvas();
                let shift = Matrix3::new(1.0, 0.0, -u0 as f64, 0.0, 1.0, -v0 as f64, 0.0, 0.0, 1.0);
                let proj = Projection::from_matrix(&(shift * cam.at(frame).matrix()))
                    .expect("a shifted projection stays regular");
                render(&mesh, material, &surface, &proj, w, h, &self.render_options)
                    .map(|canvas| map.apply(&canvas))
            }
        }
        .expect("synthetic meshes and materials are consistent")
    }

    /// Image motion of every vertex from one frame to the next, over all cameras.
    pub fn motion_stats(&self) -> MotionStats {
        let mut d: Vec<f64> = self
            .cameras
            .iter()
            .flat_map(|cam| {
                self.truth.windows(2).enumerate().flat_map(move |(f, w)| {
                    let (p0, p1) = (cam.at(f as u32), cam.at(f as u32 + 1));
                    w[0].iter()
                        .zip(&w[1])
                        .filter_map(move |(a, b)| Some((p1.project(b)? - p0.project(a)?).norm()))
                })
            })
            .collect();
        if d.is_empty() {
            return MotionStats {
                max: 0.0,
                median: 0.0,
            };
        }
        d.sort_by(f64::total_cmp);
        MotionStats {
            max: d[d.len() - 1],
            median: d[d.len() / 2],
        }
    }

    /// The scene file describing this sequence as [`write_dataset`] lays it out.
    pub fn scene_file(&self) -> SceneFile {
        let rows = |m: &Matrix3<f64>| {
            [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ]
        };
        SceneFile {
            format: FORMAT.to_string(),
            frames: FrameRange {
                first: 0,
                last: self.frames() - 1,
            },
            mesh: "mesh/initial.obj".to_string(),
            cameras: self
                .cameras
                .iter()
                .zip(&self.krt)
                .map(|(cam, (k, r, t))| CameraEntry {
                    name: cam.name.clone(),
                    width: cam.width,
                    height: cam.height,
                    k: Some(rows(k)),
                    r: Some(rows(r)),
                    t: Some([t.x, t.y, t.z]),
                    poses: None,
                    p: None,
                    distortion: cam.lens.as_ref().map(|l| DistortionEntry {
                        model: l.distortion().model().to_string(),
                        coefficients: l.distortion().coefficients(),
                    }),
                    frame_offset: 0,
                    time_offset: cam.time_offset,
                    shutter: cam.shutter,
                    rolling_shutter: cam.rolling_shutter,
                    images: format!("images/{}/{{frame:04}}.png", cam.name),
                    transfer: Default::default(),
                })
                .collect(),
            ground_truth: Some("truth/{frame:04}.obj".to_string()),
            units: Some(Units::Metres),
        }
    }
}

/// Generates the sequence of `opts` and writes it under `dir`: `scene.json`
/// (`modelflow-scene/1`), `mesh/initial.obj` (frame 0, with texture coordinates),
/// `images/camN/{frame:04}.png` (8-bit) and `truth/{frame:04}.obj`. Frames are rendered and
/// written in parallel; `progress(done, total)` is called after each file (from worker threads).
/// The scene file is written last, so a scene file present means a complete data set. Returns
/// the scene file's path.
pub fn write_dataset(
    opts: &SynthOptions,
    dir: &Path,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<PathBuf> {
    Synthetic::generate(opts)?.write(dir, progress)
}

impl Synthetic {
    /// Writes this sequence under `dir`; see [`write_dataset`].
    pub fn write(&self, dir: &Path, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<PathBuf> {
        let synth = self;
        let frames = synth.frames();
        let ncam = synth.cameras.len();
        let total = frames as usize * (ncam + 1) + 1;
        let done = AtomicUsize::new(0);
        let tick = || progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
        write_obj(&dir.join("mesh/initial.obj"), &synth.mesh)?;
        tick();
        let jobs: Vec<(Option<usize>, u32)> = (0..frames)
            .flat_map(|f| (0..=ncam).map(move |c| ((c < ncam).then_some(c), f)))
            .collect();
        jobs.par_iter().try_for_each(|&(cam, f)| -> Result<()> {
            match cam {
                Some(c) => {
                    let name = &synth.cameras[c].name;
                    let path = dir.join(format!("images/{name}/{f:04}.png"));
                    write_png(&path, &synth.render(c, f))?;
                }
                None => write_obj(&dir.join(format!("truth/{f:04}.obj")), &synth.frame_mesh(f))?,
            }
            tick();
            Ok(())
        })?;
        let scene = dir.join("scene.json");
        synth.scene_file().write(&scene)?;
        Ok(scene)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::render::depth_map;
    use crate::synth::render::vertex_normals;

    fn opts(preset: Preset, frames: u32) -> SynthOptions {
        SynthOptions {
            preset,
            frames,
            ..Default::default()
        }
    }

    #[test]
    fn unknown_preset_lists_the_presets() {
        let e = SynthOptions::preset("sheet").unwrap_err().to_string();
        assert!(
            e.contains("'sheet'") && e.contains("cloth, blob, irregular, limb, crossing"),
            "{e}"
        );
        assert_eq!(SynthOptions::preset("blob").unwrap().preset, Preset::Blob);
    }

    #[test]
    fn bad_options_are_named() {
        let mut o = SynthOptions {
            cameras: Some(0),
            ..Default::default()
        };
        assert!(Synthetic::generate(&o)
            .unwrap_err()
            .to_string()
            .contains("--cameras 0"));
        o.cameras = None;
        o.supersample = 0;
        assert!(o
            .validate()
            .unwrap_err()
            .to_string()
            .contains("--supersample 0"));
        o.supersample = 3;
        o.noise = f64::NAN;
        assert!(o.validate().unwrap_err().to_string().contains("--noise"));
    }

    #[test]
    fn cloth_edges_stay_near_rest_length_and_top_edge_stays_put() {
        let s = Synthetic::generate(&opts(Preset::Cloth, 120)).unwrap();
        assert!(s.mesh.vertex_count() >= 41 * 41);
        let edges = s.mesh.edges();
        let rest: Vec<f64> = edges
            .iter()
            .map(|&[a, b]| {
                let (p, q) = (s.material[a as usize], s.material[b as usize]);
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
            })
            .collect();
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for frame in &s.truth {
            for (e, r) in edges.iter().zip(&rest) {
                let l = (frame[e[0] as usize] - frame[e[1] as usize]).norm() / r;
                lo = lo.min(l);
                hi = hi.max(l);
            }
        }
        eprintln!("cloth edge length / rest length in [{lo:.4}, {hi:.4}]");
        assert!(lo > 0.9 && hi < 1.1, "edge length ratios in [{lo}, {hi}]");
        // The top row moves less than 2 mm over the whole clip; the bottom moves a lot.
        let first = &s.truth[0];
        let top_move = s
            .truth
            .iter()
            .flat_map(|f| (0..CLOTH_N).map(move |i| (f[i] - first[i]).norm()))
            .fold(0.0, f64::max);
        assert!(top_move < 2e-3, "top edge moved {top_move} m");
        let bottom = CLOTH_N * (CLOTH_N - 1) + CLOTH_N / 2;
        let bottom_move = s
            .truth
            .iter()
            .map(|f| (f[bottom] - first[bottom]).norm())
            .fold(0.0, f64::max);
        assert!(bottom_move > 0.05, "bottom moved only {bottom_move} m");
    }

    #[test]
    fn every_vertex_stays_in_frame_and_motion_is_moderate() {
        for preset in Preset::ALL {
            let s = Synthetic::generate(&opts(preset, 120)).unwrap();
            for cam in &s.cameras {
                for (f, frame) in s.truth.iter().enumerate() {
                    let p = cam.at(f as u32);
                    for x in frame {
                        let q = p.project(x).unwrap();
                        assert!(
                            q.x > 20.0 && q.y > 20.0 && q.x < 620.0 && q.y < 460.0,
                            "{preset} {} frame {f}: vertex at {q:?}",
                            cam.name
                        );
                    }
                }
            }
            let m = s.motion_stats();
            assert!(m.max < 6.0 && m.median > 0.3, "{preset}: {m:?}");
        }
    }

    #[test]
    fn blob_is_closed_and_self_occluding() {
        let s = Synthetic::generate(&opts(Preset::Blob, 60)).unwrap();
        assert!(s.mesh.is_closed());
        assert!(s.cameras.len() >= 3);
        // Outward-facing triangles on the rest sphere.
        let sphere = icosphere(2);
        for i in 0..sphere.triangles.len() {
            let c = sphere.positions[sphere.triangles[i][0] as usize];
            assert!(sphere.triangle_normal(i).dot(&c.coords) > 0.0);
        }
        // Some vertex faces a camera but is hidden behind another part of the surface.
        let mut occluded = 0;
        for frame in [0u32, 30, 59] {
            let mesh = s.frame_mesh(frame);
            let normals = vertex_normals(&mesh);
            for cam in &s.cameras {
                let p = cam.at(frame);
                let (w, h) = (cam.width as usize, cam.height as usize);
                let depth = depth_map(&mesh, p, w, h).unwrap();
                for (x, n) in mesh.positions.iter().zip(&normals) {
                    let to_cam = (p.center() - x).normalize();
                    if n.dot(&to_cam) < 0.2 {
                        continue;
                    }
                    let q = p.project(x).unwrap();
                    let d = depth[q.y.round() as usize * w + q.x.round() as usize];
                    if p.depth(x) > d + 0.03 {
                        occluded += 1;
                    }
                }
            }
        }
        assert!(
            occluded > 10,
            "only {occluded} front-facing vertices hidden"
        );
    }

    #[test]
    fn crossing_is_two_closed_pieces_and_the_arm_sweeps_over_the_body_in_a_front_camera() {
        // The arm covers, frame after frame, body pixels the first camera (in front) saw at the
        // first frame.
        let s = Synthetic::generate(&opts(Preset::Crossing, 100)).unwrap();
        assert!(s.mesh.is_closed());
        let n = s.mesh.positions.len() / 2;
        assert!(s.mesh.triangles.iter().all(|t| {
            let body = (t[0] as usize) < n;
            t.iter().all(|&v| ((v as usize) < n) == body)
        }));
        // Pixels the body owns at frame 0 that the arm owns later: the most over the clip.
        let half = s.mesh.triangles.len() / 2;
        let owners = |cam: usize, f: u32| {
            let ib = crate::base::raster::rasterize(
                &s.truth[f as usize],
                &s.mesh.triangles,
                s.cameras[cam].at(f),
                640,
                480,
            );
            (0..640 * 480)
                .map(|i| ib.owner_at(i % 640, i / 640))
                .collect::<Vec<u32>>()
        };
        let covered = |cam: usize| -> usize {
            let first = owners(cam, 0);
            let piece = |o: u32| (o != crate::base::raster::NONE).then_some(o as usize >= half);
            (5..100u32)
                .step_by(5)
                .map(|f| {
                    owners(cam, f)
                        .iter()
                        .zip(&first)
                        .filter(|&(&now, &then)| {
                            piece(then) == Some(false) && piece(now) == Some(true)
                        })
                        .count()
                })
                .max()
                .unwrap()
        };
        let arm_over_body = covered(0);
        assert!(
            arm_over_body > 2000,
            "cam0: the arm covered {arm_over_body} body pixels"
        );
    }

    #[test]
    fn limb_is_a_closed_capsule_whose_elbow_skin_stretches_outside_and_folds_inside() {
        let s = Synthetic::generate(&opts(Preset::Limb, 79)).unwrap();
        assert!(s.mesh.is_closed());
        assert_eq!(s.mesh.vertex_count(), 1826);
        // Wound outward: every triangle's normal points away from the axis (or the pole).
        for (i, t) in s.mesh.triangles.iter().enumerate() {
            let c = t
                .iter()
                .map(|&v| s.material[v as usize])
                .fold([0.0; 3], |a, m| {
                    [a[0] + m[0] / 3.0, a[1] + m[1] / 3.0, a[2] + m[2] / 3.0]
                });
            let axis = [c[0].clamp(-LIMB_HALF, LIMB_HALF), 0.0, 0.0];
            let out = Vector3::new(c[0] - axis[0], c[1], c[2]);
            let rest = s.mesh.with_positions(
                s.material
                    .iter()
                    .map(|m| Point3::new(m[0], m[1], m[2]))
                    .collect(),
            );
            assert!(rest.triangle_normal(i).dot(&out) > 0.0, "triangle {i}");
        }
        // At the full bend (frame 78, 60°) the elbow's skin along the limb stretches by half
        // on the outside of the bend and is compressed by half on the inside, while the upper
        // arm and the forearm keep their lengths.
        let last = &s.truth[78];
        let (mut inner, mut outer, mut upper) = (Vec::new(), Vec::new(), Vec::new());
        for [a, b] in s.mesh.edges() {
            let (ma, mb) = (s.material[a as usize], s.material[b as usize]);
            let rest = (s.mesh.positions[b as usize] - s.mesh.positions[a as usize]).norm();
            if (ma[0] - mb[0]).abs() < 0.8 * rest {
                continue; // not along the limb
            }
            let strain = (last[b as usize] - last[a as usize]).norm() / rest - 1.0;
            let (x, side) = (0.5 * (ma[0] + mb[0]), 0.5 * (ma[1] + mb[1]) / LIMB_RADIUS);
            if x.abs() < 0.05 && side > 0.9 {
                inner.push(strain);
            } else if x.abs() < 0.05 && side < -0.9 {
                outer.push(strain);
            } else if x < -0.3 {
                upper.push(strain.abs());
            }
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        assert!(!inner.is_empty() && !outer.is_empty());
        assert!(mean(&inner) < -0.5, "inside of the elbow {}", mean(&inner));
        assert!(mean(&outer) > 0.5, "outside of the elbow {}", mean(&outer));
        assert!(upper.iter().all(|&e| e < 1e-9), "the upper arm stretched");
    }

    #[test]
    fn turn_turns_the_object_about_the_first_cameras_vertical_and_leaves_the_first_mesh() {
        let plain = Synthetic::generate(&opts(Preset::Blob, 4)).unwrap();
        let turned = Synthetic::generate(&SynthOptions {
            turn: 10.0,
            ..opts(Preset::Blob, 4)
        })
        .unwrap();
        assert_eq!(plain.mesh, turned.mesh);
        assert!(plain.truth[0] == turned.truth[0], "frame 0 moved");
        // Frame 3: the preset's own motion turned by 30° about the first camera's image
        // vertical through the first frame's centre.
        let first = &plain.truth[0];
        let centre =
            Point3::from(first.iter().map(|p| p.coords).sum::<Vector3<f64>>() / first.len() as f64);
        let r = &plain.krt[0].1;
        let down = Unit::new_normalize(Vector3::new(r[(1, 0)], r[(1, 1)], r[(1, 2)]));
        let rot = Rotation3::from_axis_angle(&down, 30f64.to_radians());
        let worst = plain.truth[3]
            .iter()
            .zip(&turned.truth[3])
            .map(|(p, q)| (centre + rot * (p - centre) - q).norm())
            .fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst}");
        // The object does turn: its rim moves by about a sixth of the mesh's size.
        let moved = plain.truth[3]
            .iter()
            .zip(&turned.truth[3])
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max);
        assert!(moved > 0.12 * plain.mesh.bbox_diagonal(), "{moved}");
        assert!(SynthOptions {
            turn: 91.0,
            ..opts(Preset::Blob, 4)
        }
        .validate()
        .unwrap_err()
        .to_string()
        .contains("--turn"));
    }

    #[test]
    fn shake_moves_the_object_by_the_asked_pixels_and_leaves_the_first_mesh() {
        let plain = Synthetic::generate(&opts(Preset::Blob, 13)).unwrap();
        let shaken = Synthetic::generate(&SynthOptions {
            shake: 40.0,
            ..opts(Preset::Blob, 13)
        })
        .unwrap();
        assert_eq!(plain.mesh, shaken.mesh);
        // In the first camera, the shake's own share of each vertex's motion: 40 px along the
        // circle at the centre, plus the roll's ±10 px at the rim.
        let cam = &shaken.cameras[0];
        let (p0, p1) = (cam.at(5), cam.at(6));
        let mut d: Vec<f64> = (0..shaken.mesh.vertex_count())
            .map(|v| {
                let own =
                    |s: &Synthetic, f: usize, p: &Projection| p.project(&s.truth[f][v]).unwrap();
                ((own(&shaken, 6, p1) - own(&shaken, 5, p0))
                    - (own(&plain, 6, p1) - own(&plain, 5, p0)))
                .norm()
            })
            .collect();
        d.sort_by(f64::total_cmp);
        let (lo, med, hi) = (d[0], d[d.len() / 2], d[d.len() - 1]);
        assert!(
            (med - 40.0).abs() < 4.0 && lo > 28.0 && hi < 53.0,
            "{lo} {med} {hi}"
        );
        // A full circle brings it back (12 frames), rolled.
        let back = (shaken.truth[12]
            .iter()
            .map(|p| p.coords)
            .sum::<Vector3<f64>>()
            - plain.truth[12]
                .iter()
                .map(|p| p.coords)
                .sum::<Vector3<f64>>())
        .norm()
            / shaken.mesh.vertex_count() as f64;
        assert!(back < 0.05, "centre off by {back} m after a circle");
        let bad = SynthOptions {
            shake: f64::INFINITY,
            ..opts(Preset::Blob, 3)
        };
        assert!(bad.validate().unwrap_err().to_string().contains("--shake"));
    }

    /// Σ of absolute differences between horizontally and vertically adjacent pixels.
    fn variation(img: &RgbImage) -> f64 {
        let (w, h) = (img.width(), img.height());
        let mut s = 0.0;
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                let (p, r, d) = (img.get(x, y), img.get(x + 1, y), img.get(x, y + 1));
                for k in 0..3 {
                    s += ((p[k] - r[k]).abs() + (p[k] - d[k]).abs()) as f64;
                }
            }
        }
        s
    }

    #[test]
    fn a_late_camera_sees_the_scene_later_and_a_slow_shutter_smears_it() {
        let small = |sync_error: f64, motion_blur: f64| {
            Synthetic::generate(&SynthOptions {
                shake: 20.0,
                width: 160,
                height: 120,
                sync_error,
                motion_blur,
                ..opts(Preset::Blob, 5)
            })
            .unwrap()
        };
        let locked = small(0.0, 0.0);
        // The last of four cameras a whole frame late shows at frame 2 what the genlocked rig
        // shows at frame 3; the first camera is on time; a third of a frame late (camera 1)
        // is neither.
        let late = small(1.0, 0.0);
        assert_eq!(late.render(3, 2), locked.render(3, 3));
        assert_eq!(late.render(0, 2), locked.render(0, 2));
        assert_ne!(late.render(1, 2), locked.render(1, 2));
        assert_ne!(late.render(1, 2), locked.render(1, 3));
        // Between frames the surface is on the Catmull–Rom spline through the frames around
        // it: halfway, the mean of the middle two less an eighth of the outer ones' excess.
        let mid = locked.positions_at(2.5);
        let tr = |f: usize| locked.truth[f][7].coords;
        let want = (tr(2) + tr(3)) * 0.5625 - (tr(1) + tr(4)) * 0.0625;
        assert!((mid[7].coords - want).norm() < 1e-12);
        // Past the last frame it goes on along the last pair.
        let past = locked.positions_at(5.0);
        let want = locked.truth[4][7] + (locked.truth[4][7] - locked.truth[3][7]);
        assert!((past[7] - want).norm() < 1e-12);
        // A shutter open for a whole frame smears the moving blob: less detail, the same
        // light.
        let blurred = small(0.0, 1.0);
        let (sharp, smear) = (locked.render(0, 3), blurred.render(0, 3));
        assert!(
            variation(&smear) < 0.9 * variation(&sharp),
            "{} vs {}",
            variation(&smear),
            variation(&sharp)
        );
        let mean = |img: &RgbImage| {
            img.pixels()
                .iter()
                .map(|p| (p[0] + p[1] + p[2]) as f64)
                .sum::<f64>()
                / img.pixels().len() as f64
        };
        assert!((mean(&smear) - mean(&sharp)).abs() < 0.02 * mean(&sharp));
        for (field, bad) in [
            (
                "--sync-error",
                SynthOptions {
                    sync_error: 1.5,
                    ..opts(Preset::Blob, 3)
                },
            ),
            (
                "--sync-error",
                SynthOptions {
                    sync_error: f64::NAN,
                    ..opts(Preset::Blob, 3)
                },
            ),
            (
                "--motion-blur",
                SynthOptions {
                    motion_blur: -0.1,
                    ..opts(Preset::Blob, 3)
                },
            ),
        ] {
            assert!(bad.validate().unwrap_err().to_string().contains(field));
        }
    }

    #[test]
    fn deterministic_for_a_seed_and_different_across_seeds() {
        let mut o = SynthOptions {
            frames: 3,
            width: 160,
            height: 120,
            noise: 0.02,
            ..Default::default()
        };
        let a = Synthetic::generate(&o).unwrap().render(1, 2);
        let b = Synthetic::generate(&o).unwrap().render(1, 2);
        assert_eq!(a, b);
        o.seed = 2;
        let c = Synthetic::generate(&o).unwrap().render(1, 2);
        let differ = a
            .pixels()
            .iter()
            .zip(c.pixels())
            .filter(|(x, y)| x != y)
            .count();
        assert!(differ > a.pixels().len() / 3, "{differ}");
    }

    #[test]
    fn noise_has_the_requested_sigma() {
        let o = SynthOptions {
            frames: 1,
            width: 160,
            height: 120,
            light: false,
            ..Default::default()
        };
        let clean = Synthetic::generate(&o).unwrap().render(0, 0);
        let noisy = Synthetic::generate(&SynthOptions { noise: 0.03, ..o })
            .unwrap()
            .render(0, 0);
        let (mut s2, mut n) = (0.0, 0.0);
        for (a, b) in clean.pixels().iter().zip(noisy.pixels()) {
            for ch in 0..3 {
                // Skip values the clamp could have cut.
                if a[ch] > 0.15 && a[ch] < 0.85 {
                    s2 += ((b[ch] - a[ch]) as f64).powi(2);
                    n += 1.0;
                }
            }
        }
        let sigma = (s2 / n).sqrt();
        assert!((sigma - 0.03).abs() < 0.002, "{sigma}");
    }

    #[test]
    fn written_dataset_loads_and_matches_memory() {
        let o = SynthOptions {
            frames: 3,
            width: 160,
            height: 120,
            cameras: Some(3),
            ..Default::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let calls = AtomicUsize::new(0);
        let path = write_dataset(&o, dir.path(), &|done, total| {
            assert!(done <= total && total == 3 * 4 + 1);
            calls.fetch_add(1, Ordering::Relaxed);
        })
        .unwrap();
        assert_eq!(calls.load(Ordering::Relaxed), 13);
        let scene = crate::input::scene::Scene::load(&path).unwrap();
        let s = Synthetic::generate(&o).unwrap();
        assert_eq!((scene.first, scene.last), (0, 2));
        assert_eq!(scene.cameras.len(), 3);
        assert_eq!(scene.mesh.triangles, s.mesh.triangles);
        for (a, b) in scene.cameras.iter().zip(&s.cameras) {
            let x = s.truth[1][100];
            let (pa, pb) = (a.at(1).project(&x).unwrap(), b.at(1).project(&x).unwrap());
            assert!((pa - pb).norm() < 1e-9);
        }
        let truth = scene.ground_truth(2).unwrap().unwrap();
        assert_eq!(truth.positions, s.truth[2], "OBJ round trip is exact");
        let imgs = scene.load_images(2).unwrap();
        let mem = s.render(2, 2);
        let worst = imgs[2]
            .pixels()
            .iter()
            .zip(mem.pixels())
            .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
            .fold(0.0f32, f32::max);
        assert!(worst <= 0.5 / 255.0 + 1e-6, "{worst}");
    }
}

//! What the readers of 3D packages' scene files (Alembic, USD) share: a camera given as a
//! camera-to-world transform in the packages' convention (looking down its −Z with +Y up) made
//! into our world-to-camera `R`, `t`, and a camera read at every frame of the range made into a
//! still camera or one with a pose per frame.

use super::CalibratedCamera;
use nalgebra::{Matrix3, Matrix4, Vector3};

/// A moving camera's world-to-camera `R`, `t` at a frame.
pub type FramePose = (u32, Matrix3<f64>, Vector3<f64>);

/// The cameras of a 3D package's scene file (Alembic, USD): still ones, and moving ones with a
/// pose per frame.
#[derive(Clone, Debug)]
pub struct SceneCameras {
    /// Every camera, with its pose at the first frame of the range.
    pub cameras: Vec<CalibratedCamera>,
    /// Per camera, its world-to-camera `R`, `t` at every frame of the range when it moves
    /// (`None` when it holds still).
    pub poses: Vec<Option<Vec<FramePose>>>,
    /// What the user should know (the file's world, a film back fitted, frames held).
    pub notes: Vec<String>,
    /// The unit of the file's world, where the file says it (USD's `metersPerUnit`) and it is
    /// one a scene file names.
    pub units: Option<crate::base::Units>,
}

/// The most frames one import reads (an hour at 240 fps).
const MAX_FRAMES: u64 = 864_000;

/// Refuses a frame range that is empty (`A..B` with `A > B`) or longer than any shot.
pub(crate) fn check_frames((first, last): (u32, u32)) -> Result<(), String> {
    if first > last {
        return Err(format!("{first}..{last}: expected A..B with A <= B"));
    }
    if (last - first) as u64 + 1 > MAX_FRAMES {
        return Err(format!(
            "{first}..{last}: {} frames, more than the {MAX_FRAMES} one import reads",
            (last - first) as u64 + 1
        ));
    }
    Ok(())
}

/// A camera's `K`, `R`, `t` at one frame.
pub(crate) type View = (u32, Matrix3<f64>, Matrix3<f64>, Vector3<f64>);

/// The camera `name` from its views at every frame of the range (at least one): still when its
/// pose holds, else with a pose per frame (`moving`, said in its note); refused, with the reason,
/// when its `K` changes (a zoom), since a scene camera keeps one `K`.
pub(crate) fn still_or_moving(
    name: String,
    (width, height): (u32, u32),
    views: &[View],
    moving_note: impl FnOnce() -> String,
) -> Result<(CalibratedCamera, Option<Vec<FramePose>>), String> {
    let (first, k0, r0, t0) = views[0];
    if let Some((f, k, ..)) = views.iter().find(|v| !close(&v.1, &k0, 1e-9)) {
        return Err(format!(
            "the lens or film back changes over the frames (fx {:.3} at frame {first}, {:.3} at frame {f}): modelflow's cameras keep one K; import a range over which it holds",
            k0[(0, 0)],
            k[(0, 0)]
        ));
    }
    let moving = views
        .iter()
        .any(|v| !close(&v.2, &r0, 1e-12) || (v.3 - t0).norm() > 1e-12 * (1.0 + t0.norm()));
    let camera = CalibratedCamera {
        name,
        width,
        height,
        k: k0,
        r: r0,
        t: t0,
        distortion: None,
        note: moving.then(moving_note),
    };
    let poses = moving.then(|| views.iter().map(|v| (v.0, v.2, v.3)).collect());
    Ok((camera, poses))
}

fn close(a: &Matrix3<f64>, b: &Matrix3<f64>, tol: f64) -> bool {
    (a - b).abs().max() <= tol * (1.0 + b.abs().max())
}

/// World-to-camera `R`, `t` (ours: x right, y down, looking down +z) of a 3D package's
/// camera-to-world transform (column vectors here: `p_world = M·p_camera`; the camera looking
/// down its −Z with +Y up, as Alembic's and USD's), whose axes may be scaled (a scaled parent),
/// never sheared or mirrored.
pub(crate) fn world_to_camera(m: &Matrix4<f64>) -> Result<(Matrix3<f64>, Vector3<f64>), String> {
    let mut axes = m.fixed_view::<3, 3>(0, 0).into_owned();
    if !m.iter().all(|x| x.is_finite()) {
        return Err("a transform that is not finite".into());
    }
    for mut c in axes.column_iter_mut() {
        let n = c.norm();
        if n < 1e-12 {
            return Err("a transform that scales an axis to zero".into());
        }
        c /= n;
    }
    let dots = [(0, 1), (0, 2), (1, 2)].map(|(i, j)| axes.column(i).dot(&axes.column(j)).abs());
    if dots.iter().any(|d| *d > 1e-4) {
        return Err("a transform that shears the camera (its axes not at right angles)".into());
    }
    if axes.determinant() < 0.0 {
        return Err("a transform that mirrors the camera (a negative scale)".into());
    }
    // Camera-to-world axes X, Y, Z of the package's camera; ours are X, −Y, −Z.
    let flip = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
    let r = flip * axes.transpose();
    let c = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    Ok((r, -(r * c)))
}

/// The worst distance, in pixels, between where `read`'s cameras put a fixture's points and
/// where the package that wrote it puts them: `expected` is a JSON file of `points` and `views`
/// (`camera`, `frame` counted from `first`, `pixels`), as tools/make_alembic_fixture.py and
/// tools/make_usd_fixture.py write them.
#[cfg(test)]
pub(crate) fn worst_miss(read: &SceneCameras, expected: &std::path::Path, first: u32) -> f64 {
    let text = std::fs::read_to_string(expected).unwrap();
    let want: serde_json::Value = serde_json::from_str(&text).unwrap();
    let num = |v: &serde_json::Value| v.as_f64().unwrap();
    let points: Vec<Vector3<f64>> = want["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| Vector3::new(num(&p[0]), num(&p[1]), num(&p[2])))
        .collect();
    let mut worst: f64 = 0.0;
    for view in want["views"].as_array().unwrap() {
        let name = view["camera"].as_str().unwrap();
        let frame = view["frame"].as_u64().unwrap() as u32;
        let i = read
            .cameras
            .iter()
            .position(|c| c.name == name)
            .unwrap_or_else(|| panic!("no camera {name}"));
        let cam = &read.cameras[i];
        let (r, t) = match &read.poses[i] {
            Some(p) => {
                let (f, r, t) = p[(frame - first) as usize];
                assert_eq!(f, frame);
                (r, t)
            }
            None => (cam.r, cam.t),
        };
        for (p, px) in points.iter().zip(view["pixels"].as_array().unwrap()) {
            let x = cam.k * (r * p + t);
            let e = (x.x / x.z - num(&px[0])).hypot(x.y / x.z - num(&px[1]));
            assert!(e.is_finite(), "{name} frame {frame}");
            worst = worst.max(e);
        }
    }
    worst
}

/// What the export round-trip tests of the Alembic and USD readers share: a webcam's `K`
/// (principal point off centre, `fx ≠ fy`), and the world-to-camera pose of a camera at `eye`
/// looking at one point, +Y up.
#[cfg(test)]
pub(crate) mod rig {
    use nalgebra::{Matrix3, Point3, Vector3};

    pub fn k() -> Matrix3<f64> {
        Matrix3::new(903.5, 0.0, 618.3, 0.0, 907.9, 394.2, 0.0, 0.0, 1.0)
    }

    pub fn pose(eye: [f64; 3]) -> (Matrix3<f64>, Vector3<f64>) {
        crate::base::look_at(
            &Point3::from(eye),
            &Point3::new(1.0, 0.5, -0.5),
            &Vector3::new(0.0, 1.0, 0.0),
        )
    }

    /// Exports, in `format` at `out`, a triangle at `frames` seen by two 1280x720 cameras of
    /// `k()`: "web cam" still at (0.3, −2, 4), given at frame 10, and "handheld" given at frame
    /// 10 at (3, 1, 3) and at frame 12 at (2, 2.5, 3.5).
    pub fn export(format: crate::export::ExportFormat, out: &std::path::Path, frames: &[u32]) {
        use crate::export::{export_with_cameras, ExportCamera, ExportOptions};
        let view = |eye| {
            let (r, t) = pose(eye);
            crate::base::Projection::from_krt(&k(), &r, &t).unwrap()
        };
        let camera = |name: &str, views| ExportCamera {
            name: name.into(),
            width: 1280,
            height: 720,
            views,
        };
        let cameras = [
            camera("web cam", vec![(10, view([0.3, -2.0, 4.0]))]),
            camera(
                "handheld",
                vec![(10, view([3.0, 1.0, 3.0])), (12, view([2.0, 2.5, 3.5]))],
            ),
        ];
        let mesh = crate::base::Mesh::new(
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
            ],
            vec![[0, 1, 2]],
        );
        let meshes: Vec<(u32, crate::base::Mesh)> =
            frames.iter().map(|f| (*f, mesh.clone())).collect();
        export_with_cameras(
            &meshes,
            &[],
            &cameras,
            format,
            out,
            &ExportOptions::default(),
        )
        .unwrap();
    }
}

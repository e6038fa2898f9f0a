//! The camera model agrees with a renderer that is not ours: Mitsuba 3, a physically based path
//! tracer, rendered small glowing spheres at known world points through five cameras (off-centre
//! principal points, a 16:9 film), and the centroid of each sphere's image was measured
//! (`tools/render_mitsuba.py markers`, written once into `fixtures/mitsuba/markers.json`). Where
//! modelflow's projection puts each centre must be that centroid: a half-pixel slip in the
//! pixel-centre convention, a flipped axis or a principal point read from the wrong corner would
//! be off by half a pixel or far more.

use modelflow::base::Projection;
use nalgebra::{Matrix3, Point3, Vector3};
use serde_json::Value;

fn matrix(v: &Value) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| v[i][j].as_f64().expect("a number"))
}

#[test]
fn mitsubas_renders_put_each_marker_where_the_camera_model_projects_it() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/mitsuba/markers.json"
    ))
    .unwrap();
    let file: Value = serde_json::from_str(&text).unwrap();
    let points: Vec<Point3<f64>> = file["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            Point3::new(
                p[0].as_f64().unwrap(),
                p[1].as_f64().unwrap(),
                p[2].as_f64().unwrap(),
            )
        })
        .collect();
    let mut measured = 0;
    let mut worst: f64 = 0.0;
    let mut off_centre = 0;
    for view in file["views"].as_array().unwrap() {
        let cam = &view["camera"];
        let k = matrix(&cam["K"]);
        let (w, h) = (
            cam["width"].as_f64().unwrap(),
            cam["height"].as_f64().unwrap(),
        );
        if (k[(0, 2)] - (w - 1.0) / 2.0).abs() > 1.0 && (k[(1, 2)] - (h - 1.0) / 2.0).abs() > 1.0 {
            off_centre += 1;
        }
        let t = &cam["t"];
        let t = Vector3::new(
            t[0].as_f64().unwrap(),
            t[1].as_f64().unwrap(),
            t[2].as_f64().unwrap(),
        );
        let p = Projection::from_krt(&k, &matrix(&cam["R"]), &t).unwrap();
        for (x, c) in points.iter().zip(view["centroids"].as_array().unwrap()) {
            let Some(c) = c.as_array() else { continue };
            let q = p.project(x).unwrap();
            let miss = (q.x - c[0].as_f64().unwrap()).hypot(q.y - c[1].as_f64().unwrap());
            assert!(
                miss < 0.06,
                "camera {}: a marker's image centre is {miss:.3} px from its projection {q}",
                cam["name"]
            );
            worst = worst.max(miss);
            measured += 1;
        }
    }
    assert!(
        off_centre >= 4,
        "the fixture's cameras have off-centre principal points"
    );
    assert!(measured >= 50, "{measured} markers measured");
    eprintln!("{measured} markers, the largest miss {worst:.3} px");
}

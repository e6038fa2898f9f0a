//! The worked example of `docs/scene-format.md` is true: its camera, read from the document's
//! own JSON, projects the stated points to the stated pixels, and its error example is what the
//! loader prints.

use modelflow::base::grid;
use modelflow::base::Projection;
use modelflow::base::RgbImage;
use modelflow::input::write_obj;
use modelflow::input::write_png;
use modelflow::input::{Scene, SceneFile};
use nalgebra::{Matrix3, Point3, Vector3};
use std::path::Path;

const DOC: &str = include_str!("../../../docs/scene-format.md");

fn doc_scene() -> SceneFile {
    let start = DOC.find("```json\n").expect("a json block") + 8;
    let len = DOC[start..].find("```").unwrap();
    SceneFile::parse(Path::new("docs/scene-format.md"), &DOC[start..start + len]).unwrap()
}

#[test]
fn docs_worked_example_projects_exactly() {
    let file = doc_scene();
    let c = &file.cameras[0];
    let m = |a: [[f64; 3]; 3]| Matrix3::from_fn(|i, j| a[i][j]);
    let p = Projection::from_krt(
        &m(c.k.unwrap()),
        &m(c.r.unwrap()),
        &Vector3::from(c.t.unwrap()),
    )
    .unwrap();
    let x = Point3::new(0.505, 1.0, 1.505);
    let q = p.project(&x).unwrap();
    assert!(
        (q.x - 370.0).abs() < 1e-9 && (q.y - 189.0).abs() < 1e-9,
        "{q}"
    );
    assert!((p.depth(&x) - 5.0).abs() < 1e-12);
    let o = p.project(&Point3::origin()).unwrap();
    assert_eq!((o.x, o.y), (319.5, 364.5));
    assert!((p.center() - Point3::new(0.0, -4.0, 1.0)).norm() < 1e-12);
    for s in [
        "X = (0.505, 1, 1.505)",
        "= 370",
        "= 189",
        "(u, v) = (319.5, 364.5)",
        "C = −Rᵀt = (0, −4, 1)",
    ] {
        assert!(DOC.contains(s), "the document states {s:?}");
    }
}

#[test]
fn docs_error_example_is_what_load_says() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut file = doc_scene();
    // One frame, a second camera beside the first, a cloth-sized grid in front of them.
    file.frames.last = 0;
    let mut cam1 = file.cameras[0].clone();
    cam1.name = "cam1".into();
    cam1.images = "images/cam1/{frame:04}.png".into();
    cam1.t = Some([-0.2, 1.0, 4.0]);
    file.cameras.push(cam1);
    write_obj(
        &d.join("mesh/initial.obj"),
        &grid(5, 5, |u, v| Point3::new(u - 0.5, 0.0, 0.5 + v)),
    )
    .unwrap();
    for c in ["cam0", "cam1"] {
        write_png(
            &d.join(format!("images/{c}/0000.png")),
            &RgbImage::new(640, 480),
        )
        .unwrap();
    }
    write_obj(
        &d.join("truth/0000.obj"),
        &grid(5, 5, |u, v| Point3::new(u - 0.5, 0.0, 0.5 + v)),
    )
    .unwrap();
    let path = d.join("scene.json");
    file.write(&path).unwrap();
    Scene::load(&path).unwrap();

    file.cameras[0].r.as_mut().unwrap()[0][0] = 1.2;
    file.write(&path).unwrap();
    let msg = Scene::load(&path).unwrap_err().to_string();
    let shown = msg.replace(&format!("{}/", d.display()), "");
    assert!(DOC.contains(&shown), "the document shows {shown:?}");
}

//! `modelflow align` as a user runs it: the lined-up mesh written where asked, the report of
//! what moved and what the images leave to the user, `--json`, and errors for bad requests.

use modelflow::input::read_mesh;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn scene() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/blender-cloth-sample/scene.json"
    ))
}

/// `modelflow align --scene <the Blender cloth> --out OUT EXTRA...`.
fn align(out: &Path, extra: &[&OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_modelflow"))
        .arg("align")
        .arg("--scene")
        .arg(scene())
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn align_writes_the_lined_up_mesh_and_says_what_the_images_cannot_fix() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("aligned.obj");
    let o = align(&out, &["--perturb".as_ref(), "5,10".as_ref()]);
    let err = text(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(text(&o.stdout).trim(), out.display().to_string());
    let mesh = read_mesh(&out).unwrap();
    assert_eq!(mesh.positions.len(), 41 * 41);
    // The sheet is flat at frame 0: its place within its plane is the user's.
    assert_eq!(err.matches("not fixed by the images").count(), 3, "{err}");
    assert!(err.contains("--outline sets the motions"), "{err}");
    let line = err
        .lines()
        .find(|l| l.starts_with("error against the ground truth"))
        .unwrap_or_else(|| panic!("{err}"));
    // "... surface (where the mesh is over it) B before, A after"
    let after: f64 = line
        .rsplit("before, ")
        .next()
        .and_then(|t| t.trim_end_matches(" after").parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!(after < 0.1, "{line}");

    // --picture: both meshes over each camera's frame (320×240 panels magnified to 640×480,
    // the two cameras side by side), the aligned one in cyan.
    let pic = dir.path().join("align.png");
    let o = align(
        &out,
        &[
            "--perturb".as_ref(),
            "5,10".as_ref(),
            "--picture".as_ref(),
            pic.as_os_str(),
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let img = modelflow::input::read_rgb(&pic).unwrap();
    assert_eq!((img.width(), img.height()), (2 * 640 + 3 * 6, 480 + 2 * 6));
    let cyan = img
        .pixels()
        .iter()
        .filter(|p| p[0] < 0.35 && p[1] > 0.6 && p[2] > 0.7)
        .count();
    assert!(cyan > 2000, "{cyan} cyan pixels");

    // --json: the same as data.
    let o = align(&out, &["--json".as_ref()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["frame"], 0);
    assert_eq!(v["loose"].as_array().map(|a| a.len()), Some(3));
    assert!(v["surface_error_after_pct"].as_f64().unwrap() < 0.1);
    assert_eq!(
        v["levels"][v["levels"].as_array().unwrap().len() - 1]["level"],
        0
    );
}

#[test]
fn bad_requests_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("aligned.obj");
    let run = |extra: &[&str]| {
        let extra: Vec<&OsStr> = extra.iter().map(OsStr::new).collect();
        align(&out, &extra)
    };
    let o = run(&["--perturb", "5"]);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("PCT,DEG"), "{}", text(&o.stderr));
    let o = run(&["--cameras", "cam0"]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("at least 2"),
        "{}",
        text(&o.stderr)
    );
    let o = run(&["--levels", "9"]);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("levels"), "{}", text(&o.stderr));
    assert!(
        !out.exists(),
        "nothing is written when the request is refused"
    );
}

#[test]
fn surface_moves_a_mesh_outside_the_surface_onto_it_and_leaves_one_on_it_alone() {
    // The blob's mesh moved outward along its normals by 2 % of its size, as a visual hull
    // lies outside the surface: `--surface` moves every vertex back onto it.
    use modelflow::synth::{write_dataset, SynthOptions};
    let dir = tempfile::tempdir().unwrap();
    let opts = SynthOptions {
        preset: modelflow::synth::Preset::Blob,
        frames: 1,
        supersample: 1,
        ..SynthOptions::default()
    };
    let scene = write_dataset(&opts, &dir.path().join("footage"), &|_, _| {}).unwrap();
    let mesh = read_mesh(&scene.parent().unwrap().join("mesh/initial.obj")).unwrap();
    let normals = mesh.vertex_normals();
    let size = mesh.bbox_diagonal();
    let outside = mesh.with_positions(
        mesh.positions
            .iter()
            .zip(&normals)
            .map(|(p, n)| p + n * 0.02 * size)
            .collect(),
    );
    let hull = dir.path().join("hull.obj");
    modelflow::input::write_obj(&hull, &outside).unwrap();
    let run = |mesh: &Path, out: &Path| {
        let o = Command::new(env!("CARGO_BIN_EXE_modelflow"))
            .args(["align", "--surface", "--json", "--scene"])
            .arg(&scene)
            .arg("--mesh")
            .arg(mesh)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", text(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        (v, text(&o.stderr))
    };
    let (v, err) = run(&hull, &dir.path().join("onto.obj"));
    assert!(err.contains("every vertex was moved onto it"), "{err}");
    let (before, after) = (
        v["error_before_pct"].as_f64().unwrap(),
        v["error_after_pct"].as_f64().unwrap(),
    );
    // (Per cent of the given mesh's size, 2 % larger than the surface's.)
    assert!((1.7..2.1).contains(&before), "{before}");
    assert!(after < 0.5 * before, "{before} % -> {after} %");
    // On the surface already: left as it is (the pose aligned as without --surface).
    let given = scene.parent().unwrap().join("mesh/initial.obj");
    let (v, err) = run(&given, &dir.path().join("same.obj"));
    assert!(err.contains("its shape is left as it is"), "{err}");
    assert!(v["error_after_pct"].as_f64().unwrap() < 0.1, "{v}");
}

#[test]
fn output_paths_of_another_kind_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    // A mesh asked for as PLY would have been OBJ text under a .ply name.
    let ply = dir.path().join("aligned.ply");
    let o = align(&ply, &[]);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains(".obj"), "{}", text(&o.stderr));
    assert!(!ply.exists());
    // A picture that is not a PNG file: refused before the mesh is written.
    let out = dir.path().join("aligned.obj");
    for bad in ["picture.jpg", "."] {
        let o = align(
            &out,
            &["--picture".as_ref(), dir.path().join(bad).as_os_str()],
        );
        assert!(!o.status.success(), "{bad}");
        assert!(text(&o.stderr).contains("--picture"), "{}", text(&o.stderr));
        assert!(
            !out.exists(),
            "{bad}: the mesh was written before the refusal"
        );
    }
}

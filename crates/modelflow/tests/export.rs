//! Exports as their consumers read them: a run with UV seams, split normals and motion, and the
//! Blender cloth sample's ground truth as a run, are exported to USD and opened by Pixar's USD
//! library (`tools/check_usd.py`, with the `usd-core` package that `tools/pyenv.sh` installs;
//! CI runs it, and without it the USD check says SKIPPED). The glTF is read back by the `gltf`
//! crate; the point caches' layout is checked byte for byte in the library's unit tests.

use modelflow::base::Units;
use modelflow::export::{export_run, ExportFormat, ExportOptions};
use modelflow::input::{read_mesh, write_obj};
use nalgebra::{Point3, Rotation3, Vector3};
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// Two quads folded along x = 1, with a UV seam and split normals (as in tests/meshio.rs).
const FOLDED: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 1 0 0\nv 1 1 0\nv 2 0 1\nv 2 1 1\n\
    vt 0 0\nvt 0.5 0\nvt 0.5 1\nvt 0 1\nvt 0.6 0\nvt 1 0\nvt 1 1\nvt 0.6 1\n\
    vn 0 0 1\nvn -0.7071067811865475 0 0.7071067811865475\n\
    f 1/1/1 2/2/1 3/3/1 4/4/1\nf 2/5/2 7/6/2 8/7/2 3/8/2\n";

/// A run folder of the folded quads turning and travelling over frames 5..=14.
fn folded_run(dir: &Path) -> PathBuf {
    let src = dir.join("folded.obj");
    std::fs::write(&src, FOLDED).unwrap();
    let m = read_mesh(&src).unwrap();
    let run = dir.join("run");
    std::fs::create_dir_all(&run).unwrap();
    for f in 5..15u32 {
        let t = (f - 5) as f64;
        let r = Rotation3::from_axis_angle(&Vector3::y_axis(), 0.1 * t);
        let moved: Vec<Point3<f64>> = m
            .positions
            .iter()
            .map(|p| r * p + Vector3::new(0.03 * t, 0.0, 0.2))
            .collect();
        write_obj(&run.join(format!("{f:04}.obj")), &m.with_positions(moved)).unwrap();
    }
    run
}

/// The Python that has `pxr` (Pixar's USD): `$MODELFLOW_PYTHON` or the venv `tools/pyenv.sh`
/// makes in `target/pyenv`.
fn usd_python() -> Option<PathBuf> {
    let candidates = std::env::var_os("MODELFLOW_PYTHON")
        .map(PathBuf::from)
        .into_iter()
        .chain([repo().join("target/pyenv/bin/python")]);
    for p in candidates {
        let ok = Command::new(&p)
            .args(["-c", "import pxr"])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return Some(p);
        }
    }
    None
}

fn check_usd(run: &Path, usd: &Path, extra: &[&str]) {
    let Some(py) = usd_python() else {
        if std::env::var_os("CI").is_some() {
            panic!("CI must check USD files with usd-core: run tools/pyenv.sh first");
        }
        eprintln!(
            "SKIPPED: the USD check needs usd-core; run tools/pyenv.sh (or set MODELFLOW_PYTHON)"
        );
        return;
    };
    let out = Command::new(py)
        .arg(repo().join("tools/check_usd.py"))
        .arg(run)
        .arg(usd)
        .args(extra)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{text}");
    assert!(text.contains("usd check OK"), "{text}");
    eprintln!("{text}");
}

#[test]
fn usd_export_opens_in_pixar_usd_with_seams_normals_and_motion() {
    let dir = tempfile::tempdir().unwrap();
    let run = folded_run(dir.path());
    let usd = dir.path().join("folded.usda");
    let opts = ExportOptions {
        fps: 25.0,
        units: Some(Units::Centimetres),
    };
    let s = export_run(&run, ExportFormat::Usda, &usd, &opts).unwrap();
    assert_eq!((s.frames, s.vertices, s.triangles), (10, 8, 4));
    check_usd(&run, &usd, &["--fps", "25", "--meters-per-unit", "0.01"]);
}

#[test]
fn usd_export_of_the_cloth_sample_opens_in_pixar_usd() {
    let dir = tempfile::tempdir().unwrap();
    let run = repo().join("fixtures/blender-cloth-sample/truth");
    let usd = dir.path().join("cloth.usda");
    export_run(&run, ExportFormat::Usda, &usd, &ExportOptions::default()).unwrap();
    check_usd(&run, &usd, &[]);
}

#[test]
fn usd_export_of_a_tracked_run_carries_its_confidence() {
    let dir = tempfile::tempdir().unwrap();
    let scene =
        modelflow::input::Scene::load(&repo().join("fixtures/blender-cloth-sample/scene.json"))
            .unwrap()
            .with_frames(0, 3)
            .unwrap();
    let run = dir.path().join("run");
    modelflow::track_scene(
        &scene,
        &modelflow::TrackOptions::default(),
        &run,
        &modelflow::RunOptions::default(),
        &mut |_| {},
    )
    .unwrap();
    // One confidence file per solved frame, one row per vertex, every vertex of the cloth seen.
    for f in 1..=3 {
        let c =
            modelflow::run::read_confidence(&run.join(modelflow::run::confidence_file(f))).unwrap();
        assert_eq!(c.len(), scene.mesh.positions.len());
        assert!(c
            .iter()
            .all(|c| c.information > 0.0 && c.sigma().is_finite()));
    }
    assert!(!run.join(modelflow::run::confidence_file(0)).exists());
    let usd = dir.path().join("tracked.usda");
    export_run(&run, ExportFormat::Usda, &usd, &ExportOptions::default()).unwrap();
    check_usd(&run, &usd, &[]);
}

#[test]
fn usd_export_carries_the_scenes_cameras_as_pixar_usd_projects_them() {
    // The real webcams of the caliscope sample: principal points off centre, fx ≠ fy, four
    // cameras around the board. A run folder of its first frames (the fitted truth) whose
    // run.json names the scene: the USD export holds one Camera prim per scene camera, and
    // Pixar's own camera model (Gf.Camera's frustum) projects the mesh's vertices where the
    // scene's K, R, t do, to a thousandth of a pixel (tools/check_usd.py).
    let dir = tempfile::tempdir().unwrap();
    let scene_path = repo().join("fixtures/caliscope-board-sample/scene.json");
    let scene = modelflow::input::Scene::load(&scene_path)
        .unwrap()
        .with_frames(0, 2)
        .unwrap();
    let run = dir.path().join("run");
    std::fs::create_dir_all(&run).unwrap();
    for f in 0..=2u32 {
        let truth =
            read_mesh(&repo().join(format!("fixtures/caliscope-board-sample/truth/{f:04}.obj")))
                .unwrap();
        write_obj(&run.join(format!("{f:04}.obj")), &truth).unwrap();
    }
    let mut manifest = modelflow::run::Manifest::new(
        modelflow::run::Method::ModelFlow,
        &scene,
        Vec::new(),
        modelflow::run::Options {
            given: Default::default(),
            used: serde_json::Value::Null,
        },
    )
    .unwrap();
    std::fs::write(
        run.join("run.json"),
        serde_json::to_string(&manifest).unwrap(),
    )
    .unwrap();
    let usd = dir.path().join("board.usda");
    let s = export_run(&run, ExportFormat::Usda, &usd, &ExportOptions::default()).unwrap();
    assert_eq!(s.cameras, 4);
    let text = std::fs::read_to_string(&usd).unwrap();
    assert_eq!(text.matches("def Camera \"").count(), 4);
    check_usd(&run, &usd, &[]);
    assert_eq!(s.cameras_left_out, None);
    // Alembic carries the same cameras (their projection is checked in the library's
    // `export::tests::alembic_cameras_*` and by Blender in tools/check_blender.sh).
    let abc = dir.path().join("board.abc");
    let s = export_run(&run, ExportFormat::Abc, &abc, &ExportOptions::default()).unwrap();
    assert_eq!((s.cameras, s.cameras_left_out.clone()), (4, None));
    assert!(s.warnings().is_empty());
    // The footage archived, the scene file kept: the cameras come from the scene file alone.
    let archived = dir.path().join("archived");
    std::fs::create_dir_all(&archived).unwrap();
    std::fs::copy(&scene_path, archived.join("scene.json")).unwrap();
    manifest.scene.path = archived.join("scene.json");
    std::fs::write(
        run.join("run.json"),
        serde_json::to_string(&manifest).unwrap(),
    )
    .unwrap();
    let s = export_run(&run, ExportFormat::Usda, &usd, &ExportOptions::default()).unwrap();
    assert_eq!((s.cameras, s.cameras_left_out), (4, None));
    check_usd(&run, &usd, &[]);
    // The scene file gone too: the mesh alone, and the summary says why.
    std::fs::remove_file(archived.join("scene.json")).unwrap();
    let s = export_run(&run, ExportFormat::Usda, &usd, &ExportOptions::default()).unwrap();
    assert_eq!(s.cameras, 0);
    let why = s.cameras_left_out.unwrap();
    assert!(
        why.contains("scene.json") && why.contains("cannot be read"),
        "{why}"
    );
    // Without a run.json to name a scene, the same.
    std::fs::remove_file(run.join("run.json")).unwrap();
    let s = export_run(&run, ExportFormat::Usda, &usd, &ExportOptions::default()).unwrap();
    assert_eq!(s.cameras, 0);
    assert!(s.cameras_left_out.unwrap().contains("run.json"));
    let s = export_run(&run, ExportFormat::Abc, &abc, &ExportOptions::default()).unwrap();
    assert_eq!(s.cameras, 0);
    let said = s.warnings().join("\n");
    assert!(
        said.contains("the Alembic file holds the mesh but not the scene's cameras")
            && said.contains("run.json"),
        "{said}"
    );
    assert!(!std::fs::read_to_string(&usd)
        .unwrap()
        .contains("def Camera"));
    // Formats that hold no cameras do not mention them.
    let glb = dir.path().join("board.glb");
    let s = export_run(&run, ExportFormat::Glb, &glb, &ExportOptions::default()).unwrap();
    assert_eq!(s.cameras_left_out, None);
}

#[test]
fn point_caches_come_with_the_first_frame_as_obj_and_glb_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let run = folded_run(dir.path());
    for (format, name) in [
        (ExportFormat::Pc2, "c.pc2"),
        (ExportFormat::Mdd, "c.mdd"),
        (ExportFormat::Glb, "c.glb"),
    ] {
        let out = dir.path().join(name);
        let s = export_run(&run, format, &out, &ExportOptions::default()).unwrap();
        assert_eq!(s.files[0], out);
        // Vertices 5 and 6 are in no face: a point cache's OBJ loses them in Blender, said.
        assert_eq!(s.loose_vertices, Some((2, 4)));
        let said = s
            .warnings()
            .iter()
            .any(|w| w.starts_with("2 of the 8 vertices are in no face (the first: vertex 5"));
        assert_eq!(said, format != ExportFormat::Glb, "{:?}", s.warnings());
        if format != ExportFormat::Glb {
            // The OBJ beside the cache is the run's first frame, seams and normals included.
            let obj = read_mesh(&s.files[1]).unwrap();
            let first = read_mesh(&run.join("0005.obj")).unwrap();
            assert_eq!(obj, first);
        }
    }
    // The glTF: 4 triangles, 12 corners; the seam and the hard edge split the 8 vertices into 8
    // glTF vertices (each corner group here has one uv and one normal).
    let (doc, buffers, _) = gltf::import(dir.path().join("c.glb")).unwrap();
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    assert_eq!(reader.read_positions().unwrap().count(), 8);
    assert_eq!(reader.read_normals().unwrap().count(), 8);
    assert_eq!(reader.read_morph_targets().count(), 10);
}

#[test]
fn a_run_folder_without_frames_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let e = export_run(
        dir.path(),
        ExportFormat::Usda,
        &dir.path().join("x.usda"),
        &ExportOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("no frame meshes"), "{e}");
    assert!(!dir.path().join("x.usda").exists());
}

#[test]
fn a_point_cache_is_not_written_over_by_its_own_mesh_nor_left_without_it() {
    let dir = tempfile::tempdir().unwrap();
    let run = folded_run(dir.path());
    let opts = ExportOptions {
        fps: 24.0,
        units: None,
    };
    // `--out a.obj`: the OBJ beside the cache would be the cache's own file.
    for format in [ExportFormat::Pc2, ExportFormat::Mdd] {
        let out = dir.path().join("a.obj");
        let err = export_run(&run, format, &out, &opts)
            .unwrap_err()
            .to_string();
        assert!(err.contains("--out") && err.contains(".obj"), "{err}");
        assert!(!out.exists(), "nothing written for {format:?}");
    }
    // The OBJ's place is a folder: neither file is written (no cache without its mesh).
    let out = dir.path().join("b.pc2");
    std::fs::create_dir_all(dir.path().join("b.obj")).unwrap();
    let err = export_run(&run, ExportFormat::Pc2, &out, &opts).unwrap_err();
    assert!(err.to_string().contains("b.obj"), "{err}");
    assert!(!out.exists());
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "temporaries left: {left:?}");
    // And where both can be written, both are.
    let out = dir.path().join("c.mdd");
    export_run(&run, ExportFormat::Mdd, &out, &opts).unwrap();
    assert!(out.is_file() && dir.path().join("c.obj").is_file());
}

#[test]
fn a_glb_export_reads_back_as_the_runs_first_mesh_in_its_vertex_order() {
    // The folded quads (a UV seam, a hard edge, two vertices in no face) exported as glTF, whose
    // vertices are split at the seam and the edge, then read as a first mesh: the same surface,
    // its vertices numbered as the run's (those in no face left out: glTF draws corners), the
    // same triangles, UVs and normals per corner. So a shot's glTF can start another track.
    let dir = tempfile::tempdir().unwrap();
    let run = folded_run(dir.path());
    let glb = dir.path().join("f.glb");
    export_run(&run, ExportFormat::Glb, &glb, &ExportOptions::default()).unwrap();
    let back = read_mesh(&glb).unwrap();
    let first = read_mesh(&run.join("0005.obj")).unwrap();
    let used = [0usize, 1, 2, 3, 6, 7];
    assert_eq!(back.positions.len(), used.len());
    for (i, &v) in used.iter().enumerate() {
        assert!(
            (back.positions[i] - first.positions[v]).norm() < 1e-6,
            "vertex {i}"
        );
    }
    let number = |v: u32| used.iter().position(|&u| u == v as usize).unwrap() as u32;
    let want: Vec<[u32; 3]> = first.triangles.iter().map(|t| t.map(number)).collect();
    assert_eq!(back.triangles, want);
    let (bu, fu) = (
        back.corner_uvs.as_ref().unwrap(),
        first.corner_uvs.as_ref().unwrap(),
    );
    let (bn, fln) = (
        back.corner_normals.as_ref().unwrap(),
        first.corner_normals.as_ref().unwrap(),
    );
    for i in 0..want.len() {
        for k in 0..3 {
            let (a, b) = (
                bu.values[bu.index[i][k] as usize],
                fu.values[fu.index[i][k] as usize],
            );
            assert!((a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6);
            let (a, b) = (
                bn.table.values[bn.table.index[i][k] as usize],
                fln.table.values[fln.table.index[i][k] as usize],
            );
            assert!((0..3).all(|c| (a[c] - b[c]).abs() < 1e-6), "{a:?} {b:?}");
        }
    }
}

"""The Python API as a researcher uses it, on the Blender cloth sample in fixtures/: the tracker
driven frame by frame from numpy images gives the CLI's result to 1e-9, and so does
track_scene; evaluate, export and read_run agree with the files; bad input raises
ModelflowError naming what is wrong."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import modelflow

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCENE = ROOT / "fixtures" / "blender-cloth-sample" / "scene.json"


def cli():
    """The modelflow binary: $MODELFLOW_BIN, or one cargo built in target/."""
    env = os.environ.get("MODELFLOW_BIN")
    if env:
        return env
    for p in (ROOT / "target" / "release" / "modelflow", ROOT / "target" / "debug" / "modelflow"):
        if p.is_file():
            return str(p)
    pytest.skip("no modelflow binary: build it with cargo build (or set MODELFLOW_BIN)")


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "run"
    subprocess.run([cli(), "track", "--scene", str(SCENE), "--out", str(out)],
                   check=True, capture_output=True)
    return out


def test_scene_loads_with_numpy_views():
    s = modelflow.Scene.load(SCENE)
    assert (s.first, s.last) == (0, 11)
    assert s.cameras == ["cam0", "cam1"]
    assert s.positions.shape == (1681, 3) and s.positions.dtype == np.float64
    assert s.triangles.shape == (3200, 3) and s.triangles.max() == 1680
    imgs = s.load_images(0)
    assert [i.shape for i in imgs] == [(240, 320, 3)] * 2 and imgs[0].dtype == np.float32
    assert 0.0 <= imgs[0].min() and imgs[0].max() <= 1.0
    np.testing.assert_array_equal(s.ground_truth(0), s.positions)


def test_tracker_loop_gives_the_clis_result(cli_run):
    """The whole cloth sample, frame by frame from numpy images."""
    s = modelflow.Scene.load(SCENE)
    tracker = modelflow.Tracker(s)
    for f in range(1, 12):
        report = tracker.step(f, s.load_images(f))
        assert report["iterations"] > 0 and report["stop"] in ("converged", "cost_rose", "max_iterations")
        assert report["sigma"].shape == (1681,) and np.isfinite(report["sigma"]).all()
        cli_mesh = modelflow.read_run(cli_run)[f]
        assert np.abs(tracker.positions - cli_mesh).max() <= 1e-9
    # The sample's mesh lies on the surface: nothing was moved before tracking.
    assert tracker.first_mesh_moved is None
    # Its calibration is exact (rendered): the cameras were measured and seen as calibrated.
    shifts = tracker.camera_shifts
    assert shifts is not None and len(shifts["shifts"]) == 2 and not shifts["applied"]


def test_part_of_a_scene_loads_by_cameras_and_frames():
    s = modelflow.Scene.load(SCENE, cameras=["cam1", "cam0"], frames=(1, 2))
    assert (s.first, s.last) == (1, 2)
    assert s.cameras == ["cam1", "cam0"]
    with pytest.raises(modelflow.ModelflowError, match="--cameras"):
        modelflow.Scene.load(SCENE, cameras=["cam7"])


def test_uint8_images_are_taken_too():
    s = modelflow.Scene.load(SCENE).with_frames(0, 1)
    as_u8 = [np.round(i * 255).astype(np.uint8) for i in s.load_images(0)]
    tracker = modelflow.Tracker(s, images=as_u8)
    tracker.step(1, [np.round(i * 255).astype(np.uint8) for i in s.load_images(1)])
    assert np.abs(tracker.positions - s.ground_truth(1)).max() < 0.05


def test_track_scene_evaluate_and_export(cli_run, tmp_path):
    s = modelflow.Scene.load(SCENE)
    summary = modelflow.track_scene(s, tmp_path / "run")
    assert summary["frames"] == 12 and summary["stalled_frames"] == []
    assert summary["suspect_frames"] == []
    assert summary["checks"] == []
    assert modelflow.frames_to_check(s, tmp_path / "run") == []
    ours = modelflow.read_run(tmp_path / "run")
    theirs = modelflow.read_run(cli_run)
    assert sorted(ours) == list(range(12))
    for f in ours:
        assert np.abs(ours[f] - theirs[f]).max() <= 1e-9
    report = modelflow.evaluate(s, tmp_path / "run")
    assert report["frames"] == 12 and report["rms_mean_pct"] < 0.1
    # Where the error lies: the shape alone is at most the whole error, and every vertex of the
    # cloth is seen by its two cameras.
    assert report["shape_rms_mean_pct"] <= report["rms_mean_pct"] + 1e-12
    assert [g["cameras"] for g in report["by_views"]] == [2]
    assert report["per_frame"][5]["by_views"][0]["vertices"] == 1681
    files = modelflow.export(tmp_path / "run", tmp_path / "cloth.pc2")
    assert [pathlib.Path(f).name for f in files] == ["cloth.pc2", "cloth.obj"]
    data = (tmp_path / "cloth.pc2").read_bytes()
    assert data[:12] == b"POINTCACHE2\0"
    pts = np.frombuffer(data[32:], dtype="<f4").reshape(12, 1681, 3)
    np.testing.assert_allclose(pts[11], ours[11], atol=1e-6)
    # A USD export of a run without its run.json holds no cameras, and says why.
    (tmp_path / "run" / "run.json").unlink()
    with pytest.warns(UserWarning, match="not the scene's cameras: .*run.json"):
        modelflow.export(tmp_path / "run", tmp_path / "cloth.usda")


def test_options_are_checked_and_named():
    s = modelflow.Scene.load(SCENE)
    with pytest.raises(modelflow.ModelflowError, match="--blur"):
        modelflow.Tracker(s, options={"blur": -1.0})
    with pytest.raises(modelflow.ModelflowError, match="unknown option \"sprng_k\""):
        modelflow.Tracker(s, options={"sprng_k": 1.0})
    t = modelflow.Tracker(s, options={"levels": 2, "regularisation": {"spring_k": 0.5}})
    assert t.positions.shape == (1681, 3)


def test_bad_input_raises_modelflow_error():
    with pytest.raises(modelflow.ModelflowError, match="no_such_scene.json"):
        modelflow.Scene.load("no_such_scene.json")
    s = modelflow.Scene.load(SCENE)
    t = modelflow.Tracker(s)
    with pytest.raises(modelflow.ModelflowError, match=r"images\[1\]: expected an array of shape"):
        t.step(1, [np.zeros((240, 320, 3), np.float32), np.zeros((240, 320, 4), np.float32)])
    with pytest.raises(modelflow.ModelflowError, match=r"images\[0\]: expected a numpy array"):
        t.step(1, [np.zeros((240, 320, 3), np.float64)] * 2)


def test_track_scene_on_the_gpu_runs_or_says_what_is_missing(cli_run, tmp_path):
    s = modelflow.Scene.load(SCENE)
    with pytest.raises(modelflow.ModelflowError, match=r'device "tpu": expected "cpu" or "gpu"'):
        modelflow.track_scene(s, tmp_path / "tpu", device="tpu")
    assert not (tmp_path / "tpu").exists()
    try:
        summary = modelflow.track_scene(s, tmp_path / "gpu", device="gpu")
    except modelflow.ModelflowError as e:
        # No GPU here (CI): the message names what is missing, and nothing was written.
        assert "GPU:" in str(e) and ("CUDA" in str(e) or "NVRTC" in str(e)), str(e)
        assert not (tmp_path / "gpu").exists()
        return
    # With one: the CLI's (CPU) meshes to rounding.
    assert summary["stalled_frames"] == []
    ours, cpu = modelflow.read_run(tmp_path / "gpu"), modelflow.read_run(cli_run)
    size = np.linalg.norm(np.ptp(cpu[0], axis=0))
    for f, p in cpu.items():
        assert np.abs(ours[f] - p).max() <= 1e-5 * size, f


def test_align_brings_a_tilted_sheet_back_into_its_plane():
    s = modelflow.Scene.load(SCENE)
    p = s.positions
    c = p.mean(axis=0)
    # Tilt the flat sheet by 6 degrees about x through its centroid and push it 3 cm.
    a = np.radians(6.0)
    r = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    rough = (p - c) @ r.T + c + np.array([0.0, 0.03, 0.0])
    out = modelflow.align(s, rough)
    x = out["positions"]
    assert x.shape == p.shape and x.dtype == np.float64
    normal = np.cross(p[40] - p[0], p[-1] - p[0])
    normal /= np.linalg.norm(normal)
    size = np.linalg.norm(p.max(axis=0) - p.min(axis=0))
    off_plane = lambda q: np.sqrt((((q - p[0]) @ normal) ** 2).mean()) / size
    assert off_plane(rough) > 0.01
    assert off_plane(x) < 1e-3
    # The sheet is flat: its place within its plane is left to the user, and said so.
    free = [m for m in out["loose"] if m["stiffness"] < 1e-6]
    assert len(free) == 3
    assert abs(out["angle_deg"] - 6.0) < 1.0
    assert out["outline"] is None
    # 320x240 images are compared enlarged twice; enlarge=1 compares them as they are.
    assert out["enlarged"] == 2
    plain = modelflow.align(s, rough, search=False, enlarge=1)
    assert plain["enlarged"] == 1 and off_plane(plain["positions"]) < 1e-3
    with pytest.raises(modelflow.ModelflowError, match="--enlarge"):
        modelflow.align(s, rough, enlarge=3)
    # The sheet's border is its outline against the background: with outline=True the in-plane
    # placement comes back too.
    slid = rough + np.array([0.04, 0.0, 0.02])  # and slid within its plane (x, z)
    fit = modelflow.align(s, slid, outline=True)
    rms = np.sqrt(((fit["positions"] - p) ** 2).sum(axis=1).mean()) / size
    assert rms < 1e-3
    assert fit["outline"]["contrast_after"] > fit["outline"]["contrast_before"]
    with pytest.raises(modelflow.ModelflowError, match="positions: expected shape"):
        modelflow.align(s, p[:10])


def test_coverage_says_how_much_of_the_surface_two_cameras_see():
    # The Blender cloth sample: two cameras in front of the sheet see all of it together.
    c = modelflow.coverage(modelflow.Scene.load(SCENE))
    assert set(c) == {"two_or_more", "one", "none"}
    assert c["two_or_more"] > 0.99
    assert abs(c["two_or_more"] + c["one"] + c["none"] - 1.0) < 1e-12
    # The options decide what counts as seen: facing a camera by a cosine of 0.999 or more,
    # hardly any of the sheet is seen by both (6 % is, by one).
    strict = modelflow.coverage(modelflow.Scene.load(SCENE), {"min_cos": 0.999})
    assert strict["two_or_more"] < 0.01 and strict["none"] > 0.9


def test_a_camera_in_another_convention_is_named_by_blind_cameras(tmp_path):
    import json
    assert modelflow.blind_cameras(modelflow.Scene.load(SCENE)) == []
    assert modelflow.off_centre_principal_points(modelflow.Scene.load(SCENE)) == []
    # A third camera: cam1 as OpenGL or Blender would give it (looking down -z, y up).
    scene = json.loads(SCENE.read_text())
    folder = SCENE.parent
    scene["mesh"] = str(folder / scene["mesh"])
    for c in scene["cameras"]:
        c["images"] = str(folder / c["images"])
    flipped = json.loads(json.dumps(scene["cameras"][1]))
    flipped["name"] = "gl"
    for i in (1, 2):
        flipped["R"][i] = [-v for v in flipped["R"][i]]
        flipped["t"][i] = -flipped["t"][i]
    scene["cameras"].append(flipped)
    scene.pop("ground_truth", None)
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    blind = modelflow.blind_cameras(modelflow.Scene.load(path))
    assert [(b["camera"], b["index"], b["why"]) for b in blind] == [("gl", 2, "behind")]
    # A K calibrated at twice the footage's resolution: its principal point is named.
    scene["cameras"][2]["K"][0][2] = 319.5
    scene["cameras"][2]["K"][1][2] = 239.5
    path.write_text(json.dumps(scene))
    off = modelflow.off_centre_principal_points(modelflow.Scene.load(path))
    assert [o["camera"] for o in off] == ["gl"]
    assert (off[0]["cx"], off[0]["cy"]) == (pytest.approx(319.5), pytest.approx(239.5))
    assert "the centre of a 640×480 image: scale K's first two rows by 320/640" in off[0]["message"]
    assert "negate the second and third rows of its R" in blind[0]["message"]


def test_jpegs_that_ask_to_be_shown_turned_are_named_by_turned_images(tmp_path):
    import json
    assert modelflow.turned_images(modelflow.Scene.load(SCENE)) == []
    # The real board's camera 0 frames with an EXIF orientation of 3 (turned 180°) added.
    board = ROOT / "fixtures" / "caliscope-board-sample" / "scene.json"
    scene = json.loads(board.read_text())
    scene["mesh"] = str(board.parent / scene["mesh"])
    scene.pop("ground_truth", None)
    for c in scene["cameras"]:
        c["images"] = str(board.parent / c["images"])
    exif = (b"\xff\xe1\x00\x22Exif\x00\x00II*\x00\x08\x00\x00\x00\x01\x00"
            b"\x12\x01\x03\x00\x01\x00\x00\x00\x03\x00\x00\x00\x00\x00\x00\x00")
    (tmp_path / "cam0").mkdir()
    for f in range(scene["frames"]["first"], scene["frames"]["last"] + 1):
        src = scene["cameras"][0]["images"].replace("{frame:04}", f"{f:04}")
        data = open(src, "rb").read()
        (tmp_path / "cam0" / f"{f:04}.jpg").write_bytes(data[:2] + exif + data[2:])
    scene["cameras"][0]["images"] = str(tmp_path / "cam0" / "{frame:04}.jpg")
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    turned = modelflow.turned_images(modelflow.Scene.load(path))
    assert [(t["camera"], t["index"], t["turn"]) for t in turned] == [("cam0", 0, "turned 180°")]
    assert "as stored" in turned[0]["message"]


def test_a_mesh_in_another_unit_is_named_by_mesh_out_of_scale(tmp_path):
    import json
    assert modelflow.mesh_out_of_scale(modelflow.Scene.load(SCENE)) is None
    # The sheet written a thousand times smaller about its centre (metres for millimetres).
    scene = json.loads(SCENE.read_text())
    folder = SCENE.parent
    for c in scene["cameras"]:
        c["images"] = str(folder / c["images"])
    scene.pop("ground_truth", None)
    lines = (folder / scene["mesh"]).read_text().splitlines()
    v = np.array([[float(x) for x in l.split()[1:4]] for l in lines if l.startswith("v ")])
    c = v.mean(axis=0)
    small = iter(c + (v - c) * 1e-3)
    out = [
        ("v %r %r %r" % tuple(float(x) for x in next(small))) if l.startswith("v ") else l
        for l in lines
    ]
    (tmp_path / "small.obj").write_text("\n".join(out) + "\n")
    scene["mesh"] = str(tmp_path / "small.obj")
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    m = modelflow.mesh_out_of_scale(modelflow.Scene.load(path))
    assert m is not None and m["pixels"] < 8 and m["image"] == pytest.approx(400.0)
    assert "too small to track" in m["message"]


def test_first_mesh_check_names_a_misplaced_mesh(tmp_path):
    s = modelflow.Scene.load(SCENE)
    c = modelflow.first_mesh_check(s)
    assert not c["surface_off"] and not c["misplaced"] and not c["calibration_explains"]
    assert c["views"]["disagreeing"] == [] and not c["views"]["none_agree"], c["views"]
    assert [(p["a"], p["b"]) for p in c["views"]["pairs"]] == [(0, 1)]
    assert c["views"]["pairs"][0]["contrast"] > 100.0, c["views"]
    assert c["axes_swapped"] is None
    assert c["placement"]["fraction"] < 0.01
    # The cloth tilted 6° about an axis in its plane (what the images fix of a flat sheet; a
    # lift along its normal is the surface check's, and the tracker moves that onto the
    # surface itself): named, with how far.
    p = s.positions
    c0 = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c0)
    axis = vt[0]
    a = np.radians(6.0)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    r = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k
    moved = (p - c0) @ r.T + c0
    c = modelflow.first_mesh_check(s, moved)
    assert c["misplaced"], c
    # Two cameras 12° apart see a flat sheet's tilt as little shift between their views (about
    # a pixel here): a camera's calibration off by as much reads the same, and the check says so.
    assert 0.5 < c["placement"]["disparity"] < 1.5 and c["calibration_explains"], c
    assert 0.01 < c["placement"]["fraction"] < 0.06, c
    assert 4.0 < c["placement"]["degrees"] < 8.0, c
    with pytest.raises(modelflow.ModelflowError, match="positions"):
        modelflow.first_mesh_check(s, moved[:10])


def test_import_calibration_writes_a_scene_in_our_conventions(tmp_path):
    # nerfstudio's transforms.json of the COLMAP fixture, in the world before its applied
    # transform: the same cameras as the COLMAP model itself, principal points moved by half a
    # pixel to our convention.
    ns = ROOT / "fixtures" / "nerfstudio" / "transforms.json"
    out = tmp_path / "scene.json"
    got = modelflow.import_calibration(
        "nerfstudio", ns, out=out, frames=(0, 9), before_applied_transform=True
    )
    assert got["written"] == out and out.exists()
    assert any("applied_transform" in n for n in got["notes"])
    colmap = modelflow.import_calibration("colmap", ROOT / "fixtures" / "colmap" / "text")
    assert colmap["written"] is None
    cams = {c["name"]: c for c in colmap["scene"]["cameras"]}
    for c in got["scene"]["cameras"]:
        np.testing.assert_allclose(c["R"], cams[c["name"]]["R"], atol=1e-12)
        np.testing.assert_allclose(c["t"], cams[c["name"]]["t"], atol=1e-12)
        assert c["K"][0][2] == pytest.approx(cams[c["name"]]["K"][0][2])
    assert got["scene"]["frames"] == {"first": 0, "last": 9}
    # An existing file is kept unless force; a bad pattern or format is named.
    with pytest.raises(modelflow.ModelflowError, match="force"):
        modelflow.import_calibration("nerfstudio", ns, out=out)
    with pytest.raises(modelflow.ModelflowError, match="--images"):
        modelflow.import_calibration("nerfstudio", ns, images="x/{frame:4}.png")
    with pytest.raises(modelflow.ModelflowError, match="colmap, opencv, metashape, nerfstudio, toml"):
        modelflow.import_calibration("bundler", ns)
    # caliscope's own calibration of the real board sample: the sample's cameras, named as
    # caliscope names their recordings.
    cal = modelflow.import_calibration(
        "caliscope", ROOT / "fixtures" / "caliscope-board-sample" / "camera_array.toml"
    )
    sample = json.loads((ROOT / "fixtures" / "caliscope-board-sample" / "scene.json").read_text())
    assert [c["name"] for c in cal["scene"]["cameras"]] == ["cam_0", "cam_1", "cam_2", "cam_3"]
    for c, s in zip(cal["scene"]["cameras"], sample["cameras"]):
        assert (c["K"], c["R"], c["t"]) == (s["K"], s["R"], s["t"])
    # "auto": the format told from the file.
    kal = modelflow.import_calibration("auto", ROOT / "fixtures" / "kalibr" / "camchain.yaml")
    assert [c["name"] for c in kal["scene"]["cameras"]] == ["cam0", "cam1", "cam2"]
    # Blender's Alembic cameras: one of them moving, a pose per frame.
    abc = modelflow.import_calibration(
        "alembic", ROOT / "fixtures" / "alembic" / "cameras.abc", frames=(1, 5)
    )
    cams = {c["name"]: c for c in abc["scene"]["cameras"]}
    assert sorted(cams) == ["front", "moving", "side", "tall"]
    assert [p["frame"] for p in cams["moving"]["poses"]] == [1, 2, 3, 4, 5]
    assert "R" not in cams["moving"] or cams["moving"]["R"] is None
    assert (cams["side"]["width"], cams["side"]["height"]) == (1280, 720)
    assert any("Y up" in n for n in abc["notes"])
    # The same cameras as Blender's USD exporter writes them: no image size in the file.
    with pytest.raises(modelflow.ModelflowError, match="--size"):
        modelflow.import_calibration("usd", ROOT / "fixtures" / "usd" / "blender.usda", frames=(1, 5))
    usd = modelflow.import_calibration(
        "auto", ROOT / "fixtures" / "usd" / "blender.usda", frames=(1, 5), size=(1280, 720)
    )
    ucams = {c["name"]: c for c in usd["scene"]["cameras"]}
    assert sorted(ucams) == ["front", "moving", "side", "tall"]
    assert [p["frame"] for p in ucams["moving"]["poses"]] == [1, 2, 3, 4, 5]
    for name in ["front", "side", "tall"]:
        for row_a, row_b in zip(ucams[name]["K"], cams[name]["K"]):
            assert all(abs(a - b) < 1e-3 for a, b in zip(row_a, row_b)), name
    assert any("Z up" in n for n in usd["notes"])
    # A Meshroom reconstruction: the view without a pose left out and said.
    sfm = modelflow.import_calibration("meshroom", ROOT / "fixtures" / "alicevision" / "cameras.sfm")
    assert [c["name"] for c in sfm["scene"]["cameras"]] == [f"cam{i}" for i in range(6)]
    assert any("cam6" in n and "no pose" in n for n in sfm["notes"])


def test_synth_makes_footage_that_tracks_to_its_truth(tmp_path):
    # The researcher's loop without the CLI: synthesise, track, score.
    path = modelflow.synth(
        tmp_path / "blob", preset="blob", width=160, height=120, frames=3, supersample=1
    )
    s = modelflow.Scene.load(path)
    assert (s.first, s.last) == (0, 2) and len(s.cameras) == 4
    assert s.ground_truth(2).shape == s.positions.shape
    modelflow.track_scene(s, tmp_path / "run")
    report = modelflow.evaluate(s, tmp_path / "run")
    # 0.14 % when written (a 3-frame, 160x120 blob).
    assert report["rms_final_pct"] < 0.5, report["rms_final_pct"]
    # Its options are checked and named as the CLI's are.
    with pytest.raises(modelflow.ModelflowError, match="--width"):
        modelflow.synth(tmp_path / "bad", width=8)
    with pytest.raises(modelflow.ModelflowError, match="distortion"):
        modelflow.synth(tmp_path / "bad", distortion="opencv:x")
    with pytest.raises(modelflow.ModelflowError, match="--rolling-shutter"):
        modelflow.synth(tmp_path / "bad", rolling_shutter=2.0)


def test_baseline_and_report_from_python(tmp_path):
    path = modelflow.synth(
        tmp_path / "cloth", preset="cloth", width=160, height=120, frames=3, supersample=1
    )
    s = modelflow.Scene.load(path)
    modelflow.track_scene(s, tmp_path / "mf")
    done = modelflow.baseline(s, tmp_path / "lk")
    assert done["solved"] == 2
    ours = modelflow.evaluate(s, tmp_path / "mf")["rms_mean_pct"]
    theirs = modelflow.evaluate(s, tmp_path / "lk")["rms_mean_pct"]
    assert ours < theirs, (ours, theirs)
    rep = modelflow.report(
        s, {"Model Flow": tmp_path / "mf", "LK": tmp_path / "lk"}, tmp_path / "report",
        flipbook=False,
    )
    page = pathlib.Path(rep["index"]).read_text()
    assert "Model Flow" in page and "LK" in page
    assert rep["frames"][0] == 0 and any(str(f).endswith("error.png") for f in rep["files"])
    with pytest.raises(modelflow.ModelflowError, match="at least one run"):
        modelflow.report(s, {}, tmp_path / "empty")

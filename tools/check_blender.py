"""Imports modelflow's Alembic, glTF, PC2 and MDD exports into Blender (the `bpy` package) and
checks the vertex positions Blender evaluates at the first, middle and last frame against the run
folder's OBJs (within 1e-6 of the run's largest coordinate; the files hold 32-bit floats); for
Alembic also the faces (each the OBJ's, corner for corner: Alembic winds them the other way and the
importer turns them back), where the OBJ has them the texture coordinates and normals per
corner, and, where the run's run.json names a scene, its cameras (each must project the first
frame's vertices where the scene's K, R, t do, within 1e-3 px).

    python tools/check_blender.py RUN_DIR STEM [abc|glb|pc2|mdd ...] [FPS]   # reads STEM.abc, .glb, .pc2, .mdd, .obj

The Alembic and glTF importers turn +Y up into Blender's +Z up: (x, y, z) -> (x, -z, y); the OBJ is
imported with forward Y, up Z so that its coordinates stay as they are. `tools/check_blender.sh`
makes the environment and runs this on a tracked run.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402
from objread import close, read_run, scale_of  # noqa: E402


def reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def evaluated(obj, frame):
    bpy.context.scene.frame_set(frame)
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    m = ev.to_mesh()
    pts = [tuple(v.co) for v in m.vertices]
    ev.to_mesh_clear()
    return pts


def check_cache(run, stem, ext, fps, frames, scale):
    reset()
    bpy.context.scene.render.fps = int(fps)
    bpy.ops.wm.obj_import(filepath=stem + ".obj", forward_axis="Y", up_axis="Z")
    obj = bpy.context.selected_objects[0]
    mod = obj.modifiers.new("cache", "MESH_CACHE")
    mod.cache_format = ext.upper()
    mod.filepath = stem + "." + ext
    mod.frame_start = frames[0]
    mod.forward_axis = "POS_Y"
    mod.up_axis = "POS_Z"
    out = []
    for f in sorted({frames[0], frames[len(frames) // 2], frames[-1]}):
        w, ok = close(evaluated(obj, f), run[f]["v"], scale)
        out.append((f, w, ok))
    return out


def check_glb(run, stem, fps, frames, scale):
    reset()
    bpy.context.scene.render.fps = int(fps)
    bpy.ops.import_scene.gltf(filepath=stem + ".glb")
    obj = [o for o in bpy.context.scene.objects if o.type == "MESH"][0]
    keys = obj.data.shape_keys
    n = len(keys.key_blocks) - 1 if keys else 0
    if n != len(frames):
        return [(None, f"{n} shape keys for {len(frames)} frames", False)]
    # Blender's frame for each run frame: the animation starts at Blender frame 0 or 1; find it
    # from the action's first keyframe.
    action = keys.animation_data.action
    start = min(min(k.co[0] for k in fc.keyframe_points) for fc in _fcurves(action))
    base = [tuple(v.co) for v in obj.data.vertices]
    # glTF vertices -> run vertices: nearest first-frame vertex (in Blender's axes).
    first = [(x, -z, y) for (x, y, z) in run[frames[0]]["v"]]
    index = _nearest(base, first)
    out = []
    for f in sorted({frames[0], frames[len(frames) // 2], frames[-1]}):
        pts = evaluated(obj, int(round(start + (f - frames[0]))))
        want = [(lambda p: (p[0], -p[2], p[1]))(run[f]["v"][i]) for i in index]
        w, ok = close(pts, want, scale)
        out.append((f, w, ok))
    return out


def check_abc(run, stem, fps, frames, scale):
    reset()
    bpy.context.scene.render.fps = int(fps)
    bpy.ops.wm.alembic_import(filepath=stem + ".abc", as_background_job=False)
    obj = [o for o in bpy.context.scene.objects if o.type == "MESH"][0]
    first = run[frames[0]]
    faces, at = [], 0
    for n in first["fc"]:
        faces.append(first["fv"][at:at + n])
        at += n
    polygons = [list(p.vertices) for p in obj.data.polygons]
    if polygons != faces:
        return [("faces", f"{len(polygons)} polygons, not the OBJ's {len(faces)} faces in order", False)]
    out = [("faces", 0.0, True)]
    if first["vt"] and all(t is not None for t in first["ft"]):
        if not obj.data.uv_layers:
            return out + [("uv", "no UV layer", False)]
        uv = obj.data.uv_layers[0].data
        got = [tuple(uv[i].uv) for p in obj.data.polygons for i in p.loop_indices]
        w, ok = close(got, [first["vt"][t] for t in first["ft"]], 1.0)
        out.append(("uv", w, ok))
    # Frame f is at f / fps seconds: Blender's frame f at the same rate.
    for f in sorted({frames[0], frames[len(frames) // 2], frames[-1]}):
        want = [(x, -z, y) for (x, y, z) in run[f]["v"]]
        w, ok = close(evaluated(obj, f), want, scale)
        out.append((f, w, ok))
        r = run[f]
        if r["vn"] and all(n is not None for n in r["fn"]):
            # The OBJ's normals per corner, as Blender's custom normals (which it stores to
            # about 1e-4: relative to each face's own normal, in 16-bit integers).
            bpy.context.scene.frame_set(f)
            ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
            m = ev.to_mesh()
            got = [tuple(c.vector) for c in m.corner_normals]
            ev.to_mesh_clear()
            want = [(lambda n: (n[0], -n[2], n[1]))(r["vn"][i]) for i in r["fn"]]
            w, ok = close(got, want, 1.0, rel=1e-3)
            out.append((f"{f} normals", w, ok))
    return out + check_abc_cameras(run, frames)


def check_abc_cameras(run, frames):
    """The scene's cameras (from the run's run.json), as Blender imported them from the Alembic
    file: each must project the first frame's vertices where the scene's K, R, t do (OpenCV's
    pinhole, pixel centres at integer coordinates), with the render size set to the camera's
    image size and the pixel aspect to fx / fy (Alembic carries neither)."""
    import json
    from bpy_extras.object_utils import world_to_camera_view
    path = os.path.join(RUN_DIR, "run.json")
    if not os.path.isfile(path):
        return []
    scene_file = json.load(open(path))["scene"]["path"]
    scene = json.load(open(scene_file))
    objs = {o.name: o for o in bpy.context.scene.objects if o.type == "CAMERA"}
    out = []
    render = bpy.context.scene.render
    for c in scene["cameras"]:
        if "K" not in c or not (("R" in c and "t" in c) or "poses" in c):
            continue
        cam = objs.get(c["name"])
        if cam is None:
            out.append((f"camera {c['name']}", "not imported", False))
            continue
        K, W, H = c["K"], c["width"], c["height"]
        render.resolution_x, render.resolution_y, render.resolution_percentage = W, H, 100
        render.pixel_aspect_x = max(1.0, K[1][1] / K[0][0])
        render.pixel_aspect_y = max(1.0, K[0][0] / K[1][1])
        poses = {p["frame"]: (p["R"], p["t"]) for p in c.get("poses", [])}
        # A camera that moves: at the first, middle and last frame, each with its own pose.
        for f in sorted({frames[0], frames[len(frames) // 2], frames[-1]}) if poses else [frames[0]]:
            R, t = poses[f] if poses else (c["R"], c["t"])
            bpy.context.scene.frame_set(f)
            worst = 0.0
            for X in run[f]["v"]:
                xc = [sum(R[i][j] * X[j] for j in range(3)) + t[i] for i in range(3)]
                u = (K[0][0] * xc[0] + K[0][1] * xc[1]) / xc[2] + K[0][2]
                v = K[1][1] * xc[1] / xc[2] + K[1][2]
                n = world_to_camera_view(bpy.context.scene, cam, Vector((X[0], -X[2], X[1])))
                worst = max(worst, abs(n.x * W - 0.5 - u), abs((1 - n.y) * H - 0.5 - v))
            out.append((f"{f} camera {c['name']} (px)", worst, worst < 1e-3))
    return out


def _fcurves(action):
    if hasattr(action, "fcurves") and len(action.fcurves):
        return action.fcurves
    # Blender 4.4+ layered actions.
    return [fc for layer in action.layers for strip in layer.strips
            for bag in strip.channelbags for fc in bag.fcurves]


def _nearest(points, targets):
    idx = []
    for p in points:
        best = min(range(len(targets)), key=lambda i: sum((a - b) ** 2 for a, b in zip(p, targets[i])))
        idx.append(best)
    return idx


RUN_DIR = "."


def main():
    global RUN_DIR
    run_dir, stem = sys.argv[1], sys.argv[2]
    RUN_DIR = run_dir
    # The rest: formats to check (abc, glb, pc2, mdd; default all) and the frame rate.
    rest = sys.argv[3:]
    only = [a for a in rest if a in ("abc", "glb", "pc2", "mdd")] or ["abc", "glb", "pc2", "mdd"]
    fps = next((float(a) for a in rest if a not in only), 24.0)
    run = read_run(run_dir)
    frames = list(run)
    scale = scale_of(run[frames[0]]["v"])
    checks = {
        "abc": lambda: check_abc(run, stem, fps, frames, scale),
        "glb": lambda: check_glb(run, stem, fps, frames, scale),
        "pc2": lambda: check_cache(run, stem, "pc2", fps, frames, scale),
        "mdd": lambda: check_cache(run, stem, "mdd", fps, frames, scale),
    }
    results = {name: checks[name]() for name in only}
    bad = False
    for name, rows in results.items():
        for f, w, ok in rows:
            print(f"blender {bpy.app.version_string} {name}: frame {f}: largest difference {w} -> {'ok' if ok else 'FAILED'}")
            bad |= not ok
    sys.exit(1 if bad else 0)


main()

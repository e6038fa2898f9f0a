"""Opens a modelflow USD export with Pixar's USD library (the `usd-core` package) and checks it
against the run folder it came from: the topology, the texture coordinates and normals with
their face-varying indices, the time codes, the points at the first, middle and last frame
(within 1e-6 of the run's largest coordinate; USD stores points as 32-bit floats), and the
per-vertex confidence primvars against the run's confidence files.

    python tools/check_usd.py RUN_DIR FILE.usda [--fps 24] [--meters-per-unit 1]
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from objread import close, read_run, scale_of  # noqa: E402
from pxr import Gf, Usd, UsdGeom  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run")
    ap.add_argument("usd")
    ap.add_argument("--fps", type=float, default=24.0)
    ap.add_argument("--meters-per-unit", type=float)
    a = ap.parse_args()
    run = read_run(a.run)
    frames = list(run)
    first = run[frames[0]]
    stage = Usd.Stage.Open(a.usd)
    if stage is None:
        sys.exit(f"{a.usd}: USD could not open it")
    fail = []
    prim = stage.GetDefaultPrim().GetChild("mesh")
    mesh = UsdGeom.Mesh(prim)
    if not mesh:
        sys.exit(f"{a.usd}: no Mesh prim under the default prim")
    if stage.GetStartTimeCode() != frames[0] or stage.GetEndTimeCode() != frames[-1]:
        fail.append(f"time codes {stage.GetStartTimeCode()}..{stage.GetEndTimeCode()}, run {frames[0]}..{frames[-1]}")
    if stage.GetTimeCodesPerSecond() != a.fps:
        fail.append(f"timeCodesPerSecond {stage.GetTimeCodesPerSecond()}, expected {a.fps}")
    if a.meters_per_unit is not None and UsdGeom.GetStageMetersPerUnit(stage) != a.meters_per_unit:
        fail.append(f"metersPerUnit {UsdGeom.GetStageMetersPerUnit(stage)}, expected {a.meters_per_unit}")
    if list(mesh.GetFaceVertexIndicesAttr().Get()) != first["fv"]:
        fail.append("faceVertexIndices differ from the OBJ's faces")
    if list(mesh.GetFaceVertexCountsAttr().Get()) != first["fc"]:
        fail.append("faceVertexCounts differ from the OBJ's faces' corner counts")
    api = UsdGeom.PrimvarsAPI(prim)
    if first["vt"]:
        st = api.GetPrimvar("st")
        vals = [tuple(x) for x in st.Get()]
        if st.GetInterpolation() == "faceVarying":
            idx = list(st.GetIndices())
            got = [vals[i] for i in idx]
            want = [first["vt"][i] for i in first["ft"]]
        else:
            got = vals
            want = first["vt"]
        w, ok = close(got, want, 1.0)
        if not ok:
            fail.append(f"texture coordinates differ by {w}")
    if first["vn"]:
        nv = api.GetPrimvar("normals")
        if nv.GetInterpolation() != "faceVarying":
            fail.append(f"normals interpolation {nv.GetInterpolation()}")
        idx = list(nv.GetIndices())
        for f in (frames[0], frames[-1]):
            vals = [tuple(x) for x in nv.Get(f)]
            got = [vals[i] for i in idx]
            want = [run[f]["vn"][i] for i in run[f]["fn"]]
            w, ok = close(got, want, 1.0)
            if not ok:
                fail.append(f"frame {f}: normals differ by {w}")
    scale = scale_of(first["v"])
    checked = sorted({frames[0], frames[len(frames) // 2], frames[-1]})
    for f in checked:
        pts = [tuple(p) for p in mesh.GetPointsAttr().Get(f)]
        if len(pts) != len(run[f]["v"]):
            fail.append(f"frame {f}: {len(pts)} points, the OBJ has {len(run[f]['v'])}")
            continue
        w, ok = close(pts, run[f]["v"], scale)
        if not ok:
            fail.append(f"frame {f}: points differ by {w} (scale {scale})")
    # Per-vertex confidence: the primvars equal the run's confidence files (32-bit floats).
    conf = sorted(n for n in os.listdir(a.run) if n.endswith(".confidence.csv"))
    if conf:
        import csv
        name = conf[len(conf) // 2]
        f = int(name.split(".")[0])
        rows = list(csv.DictReader(open(os.path.join(a.run, name))))
        for field in ("information", "residual", "sigma"):
            pv = api.GetPrimvar(field)
            got = list(pv.Get(f)) if pv else []
            want = [float(r[field]) for r in rows]
            if len(got) != len(want) or pv.GetInterpolation() != "vertex":
                fail.append(f"frame {f}: primvar {field}: {len(got)} values, the run has {len(want)}")
                continue
            for g, w in zip(got, want):
                if not (g == w or abs(g - w) <= 1e-6 * abs(w)):
                    fail.append(f"frame {f}: primvar {field}: {g} where the run has {w}")
                    break
        checked_conf = f" and confidence at frame {f}"
    else:
        checked_conf = ""
    # The cameras: each scene camera (K, R, t, as OpenCV projects: pixel centres at integer
    # coordinates) projects the first frame's vertices where USD's own camera (Gf.Camera's
    # frustum, its view and projection matrices) puts them, within 1e-3 px.
    checked_cams = ""
    manifest = os.path.join(a.run, "run.json")
    if os.path.isfile(manifest):
        import json
        scene_path = json.load(open(manifest))["scene"]["path"]
        scene = json.load(open(scene_path))
        by_name = {}
        cams_prim = stage.GetDefaultPrim().GetChild("cameras")
        for p in (cams_prim.GetChildren() if cams_prim else []):
            by_name[p.GetAttribute("modelflow:name").Get()] = p
        worst = 0.0
        for c in scene["cameras"]:
            if not all(k in c for k in ("K", "R", "t")):
                continue
            p = by_name.get(c["name"])
            if p is None:
                fail.append(f"camera {c['name']}: no Camera prim")
                continue
            K, R, t = c["K"], c["R"], c["t"]
            W, H = c["width"], c["height"]
            frustum = UsdGeom.Camera(p).GetCamera(Usd.TimeCode(frames[0])).frustum
            view, proj = frustum.ComputeViewMatrix(), frustum.ComputeProjectionMatrix()
            for X in first["v"]:
                xc = [sum(R[i][j] * X[j] for j in range(3)) + t[i] for i in range(3)]
                u = (K[0][0] * xc[0] + K[0][1] * xc[1]) / xc[2] + K[0][2]
                v = K[1][1] * xc[1] / xc[2] + K[1][2]
                n = proj.Transform(view.Transform(Gf.Vec3d(*X)))
                gu = (n[0] + 1) / 2 * W - 0.5
                gv = (1 - n[1]) / 2 * H - 0.5
                worst = max(worst, abs(gu - u), abs(gv - v))
        if worst > 1e-3:
            fail.append(f"cameras: USD projects the vertices up to {worst:.2e} px from the scene's cameras")
        if by_name:
            checked_cams = f", {len(by_name)} cameras project as the scene's (within {worst:.1e} px)"
    if fail:
        print(f"usd check FAILED ({a.usd}):\n  " + "\n  ".join(fail))
        sys.exit(1)
    print(f"usd check OK: {a.usd} opened by USD {Usd.GetVersion()}, {len(frames)} frames, "
          f"points equal the run's OBJs at frames {checked} (within 1e-6 of {scale:.3g}){checked_conf}{checked_cams}")


main()

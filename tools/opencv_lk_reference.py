#!/usr/bin/env python3
"""Reference pipeline for the optical-flow baseline: OpenCV's own pyramidal Lucas-Kanade.

For every frame t -> t+1 and every camera, the vertices of the current mesh estimate that the
camera sees (in front, inside the image, not hidden: a small z-buffer of the mesh's triangles) are
tracked with cv2.calcOpticalFlowPyrLK (grey images, winSize 21x21, maxLevel 3, 30 iterations /
eps 0.01, minEigThreshold 1e-4: OpenCV's defaults) starting from the reprojection of the vertex,
with a forward-backward check of 1 px; each vertex tracked by two or more cameras is triangulated
(cv2.triangulatePoints for two cameras, the linear DLT for more) with each camera's projection at
frame t+1; the others keep their position. One OBJ per frame ({frame:04}.obj, the first = input
mesh, same faces) and log.jsonl (the run-folder log schema) are written like `modelflow baseline`, so
`modelflow eval` and `modelflow report` read it.

    pip install opencv-python-headless numpy
    python3 tools/opencv_lk_reference.py --scene S/scene.json --out DIR [--chained] [--no-fb]
    python3 tools/opencv_lk_reference.py --score DIR --scene S/scene.json   # RMS vs ground truth
                                        (same figures as `modelflow eval --scene S --track DIR`)

It reads the scene format modelflow-scene/1 (K/R/t, "poses" or "P" cameras; {frame:04} patterns).
"""
import argparse
import json
import os
import re
import sys
import time

import cv2
import numpy as np


def fail(msg):
    sys.exit(f"error: {msg}")


def pattern_path(base, pattern, frame):
    def sub(m):
        width = m.group(1)
        return f"{frame:0{int(width)}d}" if width else str(frame)

    return os.path.join(base, re.sub(r"\{frame(?::0(\d+))?\}", sub, pattern))


def read_obj(path):
    verts, faces, lines = [], [], []
    with open(path) as f:
        for line in f:
            lines.append(line)
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                for k in range(1, len(idx) - 1):
                    faces.append([idx[0], idx[k], idx[k + 1]])
    return np.array(verts, dtype=np.float64), np.array(faces, dtype=np.int64)


def write_obj(path, verts, faces):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        for v in verts:
            f.write(f"v {v[0]:.9f} {v[1]:.9f} {v[2]:.9f}\n")
        for t in faces:
            f.write(f"f {t[0] + 1} {t[1] + 1} {t[2] + 1}\n")
    os.replace(tmp, path)


def load_scene(path):
    with open(path) as f:
        s = json.load(f)
    if s.get("format") != "modelflow-scene/1":
        fail(f"{path}: format: expected modelflow-scene/1")
    base = os.path.dirname(os.path.abspath(path))
    first, last = s["frames"]["first"], s["frames"]["last"]
    cams = []
    for i, c in enumerate(s["cameras"]):
        if "P" in c:
            ps = [np.array(p, dtype=np.float64) for p in c["P"]]
        elif "poses" in c:
            k = np.array(c["K"], dtype=np.float64)
            ps = [k @ np.hstack([np.array(p["R"]), np.array(p["t"]).reshape(3, 1)]) for p in c["poses"]]
        else:
            k = np.array(c["K"], dtype=np.float64)
            ps = [k @ np.hstack([np.array(c["R"]), np.array(c["t"]).reshape(3, 1)])]
        # Normalise like camera.rs: positive det of the left block, unit third row (depth = z).
        ps = [p * np.sign(np.linalg.det(p[:, :3])) / np.linalg.norm(p[2, :3]) for p in ps]
        cams.append({"name": c["name"], "w": c["width"], "h": c["height"], "P": ps, "images": c["images"]})
    mesh, faces = read_obj(os.path.join(base, s["mesh"]))
    truth = s.get("ground_truth")
    return {"base": base, "first": first, "last": last, "cams": cams, "mesh": mesh, "faces": faces, "truth": truth}


def proj_at(cam, frame, first):
    ps = cam["P"]
    return ps[0] if len(ps) == 1 else ps[min(max(frame - first, 0), len(ps) - 1)]


def project(P, X):
    h = X @ P[:, :3].T + P[:, 3]
    z = h[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = h[:, :2] / z[:, None]
    return uv, z


def visible(P, X, faces, w, h):
    """Vertices in front, inside the image and not behind another triangle (z-buffer at the
    vertex's nearest pixel centre, 0.1% depth tolerance, own triangles always pass)."""
    uv, z = project(P, X)
    depth = np.full((h, w), np.inf)
    owner = np.full((h, w), -1, dtype=np.int64)
    for ti, (a, b, c) in enumerate(faces):
        if min(z[a], z[b], z[c]) <= 0:
            continue
        pa, pb, pc = uv[a], uv[b], uv[c]
        area = (pb[0] - pa[0]) * (pc[1] - pa[1]) - (pb[1] - pa[1]) * (pc[0] - pa[0])
        if abs(area) < 1e-12:
            continue
        x0 = max(int(np.ceil(min(pa[0], pb[0], pc[0]))), 0)
        x1 = min(int(np.floor(max(pa[0], pb[0], pc[0]))), w - 1)
        y0 = max(int(np.ceil(min(pa[1], pb[1], pc[1]))), 0)
        y1 = min(int(np.floor(max(pa[1], pb[1], pc[1]))), h - 1)
        if x0 > x1 or y0 > y1:
            continue
        xs, ys = np.meshgrid(np.arange(x0, x1 + 1), np.arange(y0, y1 + 1))
        wa = ((pb[0] - xs) * (pc[1] - ys) - (pb[1] - ys) * (pc[0] - xs)) / area
        wb = ((pc[0] - xs) * (pa[1] - ys) - (pc[1] - ys) * (pa[0] - xs)) / area
        wc = 1 - wa - wb
        inside = (wa >= -1e-9) & (wb >= -1e-9) & (wc >= -1e-9)
        zz = 1.0 / (wa / z[a] + wb / z[b] + wc / z[c])
        sub = depth[y0:y1 + 1, x0:x1 + 1]
        better = inside & (zz < sub)
        sub[better] = zz[better]
        owner[y0:y1 + 1, x0:x1 + 1][better] = ti
    vis = np.zeros(len(X), dtype=bool)
    for i in range(len(X)):
        u, v = uv[i]
        if not (z[i] > 0 and -0.5 <= u < w - 0.5 and -0.5 <= v < h - 0.5):
            continue
        x, y = min(max(int(np.floor(u + 0.5)), 0), w - 1), min(max(int(np.floor(v + 0.5)), 0), h - 1)
        o = owner[y, x]
        vis[i] = o < 0 or i in faces[o] or z[i] <= depth[y, x] * (1 + 1e-3)
    return vis


def dlt(Ps, pts):
    rows = []
    for P, (u, v) in zip(Ps, pts):
        for r in (u * P[2] - P[0], v * P[2] - P[1]):
            rows.append(r / np.linalg.norm(r))
    _, _, vt = np.linalg.svd(np.array(rows))
    X = vt[-1]
    return X[:3] / X[3]


def run(args):
    sc = load_scene(args.scene)
    os.makedirs(args.out, exist_ok=True)
    first, last, cams, faces = sc["first"], sc["last"], sc["cams"], sc["faces"]
    X = sc["mesh"].copy()
    write_obj(os.path.join(args.out, f"{first:04d}.obj"), X, faces)
    lk = dict(winSize=(21, 21), maxLevel=3,
              criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01))

    def grey(cam, frame):
        p = pattern_path(sc["base"], cam["images"], frame)
        img = cv2.imread(p, cv2.IMREAD_GRAYSCALE)
        if img is None:
            fail(f"{p}: cannot read image")
        return img

    prev = [grey(c, first) for c in cams]
    chained = [dict() for _ in cams]
    log_path = os.path.join(args.out, "log.jsonl")
    open(log_path, "w").close()
    for frame in range(first + 1, last + 1):
        t0 = time.time()
        cur = [grey(c, frame) for c in cams]
        t_load = time.time() - t0
        tracks = []
        for ci, cam in enumerate(cams):
            P = proj_at(cam, frame - 1, first)
            vis = np.nonzero(visible(P, X, faces, cam["w"], cam["h"]))[0]
            uv, _ = project(P, X[vis])
            if args.chained:
                for k, v in enumerate(vis):
                    if v in chained[ci]:
                        uv[k] = chained[ci][v]
            p0 = uv.astype(np.float32).reshape(-1, 1, 2)
            res = {}
            if len(vis):
                p1, st, _ = cv2.calcOpticalFlowPyrLK(prev[ci], cur[ci], p0, None, **lk)
                ok = st.ravel() == 1
                if not args.no_fb:
                    pb, stb, _ = cv2.calcOpticalFlowPyrLK(cur[ci], prev[ci], p1, None, **lk)
                    fb = np.linalg.norm((pb - p0).reshape(-1, 2), axis=1)
                    ok &= (stb.ravel() == 1) & (fb <= 1.0)
                q = p1.reshape(-1, 2).astype(np.float64)
                inside = (q[:, 0] >= -0.5) & (q[:, 1] >= -0.5) & (q[:, 0] < cam["w"] - 0.5) & (q[:, 1] < cam["h"] - 0.5)
                ok &= inside
                res = {int(v): q[k] for k, v in enumerate(vis) if ok[k]}
            tracks.append(res)
            chained[ci] = res
        Ps = [proj_at(c, frame, first) for c in cams]
        tri = 0
        ntracked = sum(len(t) for t in tracks)
        pair = {}
        for v in range(len(X)):
            cs = [ci for ci in range(len(cams)) if v in tracks[ci]]
            if len(cs) < 2:
                continue
            if len(cs) == 2:
                pair.setdefault(tuple(cs), []).append(v)
            else:
                X[v] = dlt([Ps[c] for c in cs], [tracks[c][v] for c in cs])
                tri += 1
        for (a, b), vs in pair.items():
            pa = np.array([tracks[a][v] for v in vs]).T
            pb = np.array([tracks[b][v] for v in vs]).T
            h = cv2.triangulatePoints(Ps[a], Ps[b], pa, pb)
            X[vs] = (h[:3] / h[3]).T
            tri += len(vs)
        secs = time.time() - t0
        write_obj(os.path.join(args.out, f"{frame:04d}.obj"), X, faces)
        wall = time.time() - t0
        # One line per frame, appended, in the run-folder log schema (docs/run-folder.md).
        line = {"frame": frame, "seconds": secs - t_load, "load_seconds": t_load,
                "wall_seconds": wall, "method": "baseline", "tracked": ntracked,
                "triangulated": tri}
        with open(log_path, "a") as f:
            f.write(json.dumps(line) + "\n")
        prev = cur
        print(f"frame {frame}: {ntracked} tracks, {tri} triangulated, {secs:.3f} s", file=sys.stderr)


def score(args):
    """RMS vertex error per frame of a run folder against the scene's ground truth."""
    sc = load_scene(args.scene)
    if not sc["truth"]:
        fail(f"{args.scene}: ground_truth: the scene has no ground truth")
    rms = []
    diag = None
    for frame in range(sc["first"], sc["last"] + 1):
        t, _ = read_obj(pattern_path(sc["base"], sc["truth"], frame))
        r, _ = read_obj(os.path.join(args.score, f"{frame:04d}.obj"))
        if diag is None:
            diag = np.linalg.norm(t.max(0) - t.min(0))
        rms.append(float(np.sqrt(np.mean(np.sum((r - t) ** 2, axis=1)))))
    # Like `modelflow eval`: the mean runs over every frame, the first (error 0) included.
    mean = float(np.mean(rms))
    print(json.dumps({"frames": len(rms), "rms": rms, "mean_rms": mean, "final_rms": rms[-1],
                      "bbox_diagonal": diag, "mean_pct_diag": 100 * mean / diag,
                      "final_pct_diag": 100 * rms[-1] / diag}))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", required=True)
    ap.add_argument("--out")
    ap.add_argument("--score", metavar="RUN_DIR")
    ap.add_argument("--chained", action="store_true", help="chain each camera's 2D tracks")
    ap.add_argument("--no-fb", action="store_true", help="disable the forward-backward check")
    args = ap.parse_args()
    if args.score:
        score(args)
    elif args.out:
        run(args)
    else:
        fail("give --out DIR to run or --score DIR to score a run")


if __name__ == "__main__":
    main()

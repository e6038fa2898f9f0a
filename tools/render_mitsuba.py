#!/usr/bin/env python3
"""Footage of a modelflow scene rendered again by another renderer, Mitsuba 3.

modelflow's conventions (docs/scene-format.md: OpenCV's pinhole, pixel centres at integers) are a
contract with every renderer and camera a user brings; this script checks them against a
physically based path tracer written by others, and makes a clip that no part of modelflow
rendered, for the tracker to be judged on (docs/tracker.md, "Footage from another renderer").

  python3 -m venv target/mitsuba && target/mitsuba/bin/pip install mitsuba numpy
  target/mitsuba/bin/python tools/render_mitsuba.py markers SCENE          # the convention check
  target/mitsuba/bin/python tools/render_mitsuba.py clip SCENE OUT [--spp 32]

`markers` renders small glowing spheres at known world points through every camera of SCENE and
prints, per camera, how far the centroid of each sphere's image lies from where modelflow's camera
model projects its centre (it should be a few hundredths of a pixel: the sphere's image is not
exactly centred on its centre's projection, and the sampling is noisy).

`clip` renders SCENE's ground-truth meshes (its `ground_truth` pattern, with the mesh's texture
coordinates) with a procedural colour texture, under a sun and a sky, through every camera, with
Mitsuba's defaults otherwise (its path tracer, Gaussian pixel filter, independent sampler), and
writes OUT/scene.json: SCENE's cameras, mesh and truth with the new images. Cameras need square
pixels, no skew and no lens distortion (Mitsuba's perspective camera has none of them).

Mitsuba's camera looks down its local +Z with +Y up and +X to the image's left (its `look_at`),
and its film spans [0, W] × [0, H] with pixel centres at half-integers; its principal-point
offsets are fractions of the film's width and height. The conversion below follows from those.
"""

import argparse
import json
import math
import os
import re
import shutil
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from objread import read_obj  # noqa: E402  (the tools' one OBJ reader)

try:
    import mitsuba as mi
except ImportError:
    sys.exit(
        "render_mitsuba.py needs Mitsuba 3: python3 -m venv target/mitsuba && "
        "target/mitsuba/bin/pip install mitsuba numpy, then run it with target/mitsuba/bin/python"
    )

mi.set_variant("scalar_rgb")


def load_scene(path):
    with open(path) as f:
        scene = json.load(f)
    return scene, os.path.dirname(os.path.abspath(path))


def camera_dict(cam, spp, seed=0):
    """Mitsuba's perspective sensor for one scene camera (OpenCV pinhole, pixel centres at integers)."""
    K = np.array(cam["K"], dtype=float)
    R = np.array(cam["R"], dtype=float)
    t = np.array(cam["t"], dtype=float)
    W, H = int(cam["width"]), int(cam["height"])
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if abs(K[0, 1]) > 1e-12 or abs(fx - fy) > 1e-9 * fx:
        sys.exit(f"camera {cam['name']}: Mitsuba's perspective camera needs square pixels and no skew")
    if cam.get("distortion"):
        sys.exit(f"camera {cam['name']}: Mitsuba's perspective camera has no lens distortion")
    centre = -R.T @ t
    to_world = np.eye(4)
    # OpenCV's camera axes (x right, y down, z forward) are Mitsuba's local (-x, -y, z).
    to_world[:3, :3] = R.T @ np.diag([-1.0, -1.0, 1.0])
    to_world[:3, 3] = centre
    return {
        "type": "perspective",
        "fov": math.degrees(2.0 * math.atan(W / (2.0 * fx))),
        "fov_axis": "x",
        # The optical axis at continuous film position (cx + 0.5, cy + 0.5). Mitsuba's offsets
        # are fractions of the film from its centre, positive moving the image's content toward
        # −x, −y: found by `markers` (the other sign misses every marker by the offset twice).
        "principal_point_offset_x": (W / 2.0 - cx - 0.5) / W,
        "principal_point_offset_y": (H / 2.0 - cy - 0.5) / H,
        "near_clip": 0.01,
        "far_clip": 1000.0,
        "to_world": mi.ScalarTransform4f(to_world.tolist()),
        "film": {"type": "hdrfilm", "width": W, "height": H},
        "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
    }


def project(cam, X):
    K = np.array(cam["K"], dtype=float)
    x = np.array(cam["R"], dtype=float) @ X + np.array(cam["t"], dtype=float)
    return (K @ x)[:2] / x[2]


def positions(path):
    return np.array(read_obj(path)["v"])


def write_ply(path, positions, uvs, tris):
    """A binary PLY with per-vertex positions and texture coordinates."""
    head = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(positions)}\n"
        "property float x\nproperty float y\nproperty float z\nproperty float u\nproperty float v\n"
        f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    verts = np.hstack([positions, uvs]).astype("<f4")
    faces = np.zeros(len(tris), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"] = 3
    faces["i"] = tris
    with open(path, "wb") as f:
        f.write(head.encode())
        f.write(verts.tobytes())
        f.write(faces.tobytes())


def split_corners(mesh):
    """One render vertex per distinct (position, uv) corner of `mesh` (`objread.read_obj`'s),
    its polygons as fans of triangles: the positions are then `v[index]`."""
    key_of = {}
    index, uvs, tris = [], [], []
    corner = 0
    for count in mesh["fc"]:
        ids = []
        for vi, ti in zip(mesh["fv"][corner : corner + count], mesh["ft"][corner : corner + count]):
            key = (vi, ti)
            if key not in key_of:
                key_of[key] = len(index)
                index.append(vi)
                uvs.append(mesh["vt"][ti] if ti is not None else (0.0, 0.0))
            ids.append(key_of[key])
        corner += count
        tris.extend([ids[0], ids[k], ids[k + 1]] for k in range(1, count - 1))
    return np.array(index), np.array(uvs), np.array(tris)


def texture(path, size=1024, seed=3):
    """A colour texture with detail at every scale (filtered noise, one octave per factor 2)."""
    rng = np.random.default_rng(seed)
    img = np.zeros((size, size, 3))
    fy = np.fft.fftfreq(size)[:, None]
    fx = np.fft.fftfreq(size)[None, :]
    f = np.sqrt(fx * fx + fy * fy)
    for octave in range(2, 9):
        band = np.exp(-((np.log2(np.maximum(f, 1e-9) * size) - octave) ** 2) / 0.5)
        for c in range(3):
            noise = np.fft.ifft2(np.fft.fft2(rng.standard_normal((size, size))) * band).real
            img[..., c] += noise / (noise.std() + 1e-12) * (0.9 ** octave)
    img = (img - img.mean(axis=(0, 1))) / img.std(axis=(0, 1))
    img = np.clip(0.45 + 0.2 * img, 0.02, 0.98)
    mi.Bitmap(img.astype(np.float32)).convert(
        mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True
    ).write(path)


def surface(gloss, tex):
    """Matte paint, or with `gloss` a varnish over it (a rough dielectric coat: the sun's
    highlight moves over the surface as it turns)."""
    paint = {"type": "bitmap", "filename": tex}
    if gloss <= 0:
        return {"type": "diffuse", "reflectance": paint}
    return {"type": "roughplastic", "diffuse_reflectance": paint, "alpha": gloss}


def to_png(image, path):
    mi.Bitmap(image).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True).write(path)


def markers(args):
    scene, base = load_scene(args.scene)
    v = positions(os.path.join(base, scene["mesh"]))
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    rng = np.random.default_rng(1)
    points = lo + rng.random((12, 3)) * (hi - lo)
    radius = args.radius * size
    shapes = {
        f"m{i}": {
            "type": "sphere",
            "center": p.tolist(),
            "radius": radius,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
        }
        for i, p in enumerate(points)
    }
    worst = 0.0
    record = []
    for cam in scene["cameras"]:
        d = {"type": "scene", "integrator": {"type": "direct"}, **shapes}
        img = np.array(mi.render(mi.load_dict(d), sensor=mi.load_dict(camera_dict(cam, args.spp))))
        lum = img.mean(axis=2)
        W, H = int(cam["width"]), int(cam["height"])
        offsets, centroids = [], []
        for p in points:
            u, w = project(cam, p)
            r = 8
            x0, x1 = int(round(u)) - r, int(round(u)) + r + 1
            y0, y1 = int(round(w)) - r, int(round(w)) + r + 1
            if x0 < 0 or y0 < 0 or x1 > W or y1 > H:
                centroids.append(None)
                continue
            win = lum[y0:y1, x0:x1]
            mass = win.sum()
            if mass <= 0:
                offsets.append((math.inf, math.inf))
                centroids.append(None)
                continue
            # Pixel (i, j)'s centre at (j, i): modelflow's convention.
            ys, xs = np.mgrid[y0:y1, x0:x1]
            cu, cv = (win * xs).sum() / mass, (win * ys).sum() / mass
            offsets.append((cu - u, cv - w))
            centroids.append([round(float(cu), 5), round(float(cv), 5)])
        keep = ("name", "width", "height", "K", "R", "t")
        record.append({"camera": {k: cam[k] for k in keep}, "centroids": centroids})
        o = np.array(offsets)
        far = np.hypot(o[:, 0], o[:, 1])
        worst = max(worst, float(far.max()))
        print(
            f"{cam['name']}: {len(o)} markers, centroid − projection: mean ({o[:, 0].mean():+.3f}, "
            f"{o[:, 1].mean():+.3f}) px, largest {far.max():.3f} px"
        )
    print(f"largest offset over all cameras: {worst:.3f} px")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {
                    "made_by": f"tools/render_mitsuba.py markers (Mitsuba {mi.__version__}, "
                    f"scalar_rgb, direct integrator, {args.spp} samples per pixel)",
                    "radius": radius,
                    "points": [p.tolist() for p in points],
                    "views": record,
                },
                f,
                indent=1,
            )
        print(f"wrote {args.json}")


def clip(args):
    scene, base = load_scene(args.scene)
    if "ground_truth" not in scene:
        sys.exit(f"{args.scene}: no ground_truth to render")
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    work = os.path.join(out, "render")
    os.makedirs(work, exist_ok=True)
    tex = os.path.join(work, "texture.png")
    texture(tex)
    mesh = read_obj(os.path.join(base, scene["mesh"]))
    if not mesh["vt"]:
        sys.exit(f"{scene['mesh']}: the mesh has no texture coordinates to put a texture on")
    index, uvs, tris = split_corners(mesh)
    first, last = scene["frames"]["first"], scene["frames"]["last"]
    sun = np.array([0.4, -0.5, 0.75])
    cams = scene["cameras"]
    for cam in cams:
        os.makedirs(os.path.join(out, "images", cam["name"]), exist_ok=True)
    pattern = scene["ground_truth"]
    for frame in range(first, last + 1):
        truth = os.path.join(base, fill(pattern, frame))
        v = positions(truth)
        ply = os.path.join(work, "mesh.ply")
        write_ply(ply, v[index], uvs, tris)
        d = {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 4},
            "object": {
                "type": "ply",
                "filename": ply,
                # Two-sided: the inside seen through a hole or past a rim is lit as the outside.
                "bsdf": {"type": "twosided", "bsdf": surface(args.gloss, tex)},
            },
            "sun": {"type": "directional", "direction": (-sun).tolist(), "irradiance": 2.2},
            "sky": {"type": "constant", "radiance": 0.35},
        }
        world = mi.load_dict(d)
        for ci, cam in enumerate(cams):
            img = mi.render(world, sensor=mi.load_dict(camera_dict(cam, args.spp, seed=frame * 97 + ci)))
            to_png(np.array(img), os.path.join(out, "images", cam["name"], f"{frame:04d}.png"))
        print(f"frame {frame} of {first}..{last}", flush=True)
    os.remove(os.path.join(work, "mesh.ply"))
    new = dict(scene)
    new["mesh"] = os.path.join(base, scene["mesh"])
    new["ground_truth"] = os.path.join(base, pattern)
    new["cameras"] = []
    for cam in cams:
        c = dict(cam)
        c["images"] = f"images/{cam['name']}/{{frame:04}}.png"
        c.pop("shutter", None)
        c.pop("time_offset", None)
        new["cameras"].append(c)
    with open(os.path.join(out, "scene.json"), "w") as f:
        json.dump(new, f, indent=2)
    print(f"wrote {out}/scene.json ({last - first + 1} frames, {len(cams)} cameras, Mitsuba {mi.__version__})")


def fill(pattern, frame):
    return re.sub(r"\{frame(?::0?(\d+))?\}", lambda m: f"{frame:0{m.group(1) or 1}d}", pattern)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("markers", help="the convention check")
    m.add_argument("scene")
    m.add_argument("--spp", type=int, default=256)
    m.add_argument("--radius", type=float, default=0.004, help="marker radius, fraction of the mesh's size")
    m.add_argument("--json", help="write the cameras, the markers and their centroids here")
    c = sub.add_parser("clip", help="render the scene's ground truth")
    c.add_argument("scene")
    c.add_argument("out")
    c.add_argument("--spp", type=int, default=32)
    c.add_argument(
        "--gloss", type=float, default=0.0, help="a glossy coat of this roughness (e.g. 0.1); 0: matte"
    )
    args = ap.parse_args()
    {"markers": markers, "clip": clip}[args.cmd](args)


if __name__ == "__main__":
    main()

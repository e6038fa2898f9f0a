"""A minimal OBJ reader for the export checks (v, vt, vn, and f with v/vt/vn; faces of any
corner count, as modelflow writes them: the input's polygons, or triangles). Pure Python, so the
checks need nothing but the consumer itself."""

import os
import re


def read_obj(path):
    v, vt, vn, fv, ft, fn, fc = [], [], [], [], [], [], []
    with open(path) as f:
        for line in f:
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                v.append(tuple(float(x) for x in p[1:4]))
            elif p[0] == "vt":
                vt.append(tuple(float(x) for x in p[1:3]))
            elif p[0] == "vn":
                vn.append(tuple(float(x) for x in p[1:4]))
            elif p[0] == "f":
                fc.append(len(p) - 1)
                for c in p[1:]:
                    parts = c.split("/") + ["", ""]
                    fv.append(int(parts[0]) - 1)
                    ft.append(int(parts[1]) - 1 if parts[1] else None)
                    fn.append(int(parts[2]) - 1 if parts[2] else None)
    return {"v": v, "vt": vt, "vn": vn, "fv": fv, "ft": ft, "fn": fn, "fc": fc}


def read_run(run_dir):
    """{frame: mesh} of a run folder (frame = the last number in the file name)."""
    out = {}
    for name in os.listdir(run_dir):
        if name.lower().endswith(".obj"):
            nums = re.findall(r"\d+", name[:-4])
            if nums:
                out[int(nums[-1])] = read_obj(os.path.join(run_dir, name))
    return dict(sorted(out.items()))


def close(a, b, scale, rel=1e-6):
    """Largest coordinate difference of two point lists, and whether it is within rel * scale."""
    worst = max(max(abs(x - y) for x, y in zip(p, q)) for p, q in zip(a, b))
    return worst, worst <= rel * scale


def scale_of(points):
    return max(max(abs(c) for c in p) for p in points) or 1.0

"""A scene whose first mesh lies off the surface, as a visual hull made from silhouettes lies
outside it: copies a scene folder (as `modelflow synth` writes one: `scene.json`,
`mesh/initial.obj`, `truth/NNNN.obj`, images) and moves the mesh and every truth frame along
their area-weighted vertex normals by PCT % of the first mesh's bounding-box diagonal (negative:
inward). The images are unchanged, so the moved truth is where the moved mesh's points go when
tracked as given (`track --keep-shape`); score a run that moved the mesh onto the surface (the
default) against the original scene's truth instead (docs/tracker.md, "The first mesh must lie
on the surface").

    python3 tools/offset_scene.py SRC_FOLDER DST_FOLDER PCT

Pure Python (no numpy); the OBJ's other lines are copied as they are.
"""

import glob
import math
import os
import shutil
import sys


def load(path):
    lines = open(path).read().splitlines()
    v = [[float(x) for x in l.split()[1:4]] for l in lines if l.startswith("v ")]
    f = [[int(t.split("/")[0]) - 1 for t in l.split()[1:]] for l in lines if l.startswith("f ")]
    return lines, v, f


def normals(v, faces):
    n = [[0.0] * 3 for _ in v]
    for face in faces:
        for k in range(1, len(face) - 1):
            a, b, c = v[face[0]], v[face[k]], v[face[k + 1]]
            u = [b[i] - a[i] for i in range(3)]
            w = [c[i] - a[i] for i in range(3)]
            x = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]]
            for i in (face[0], face[k], face[k + 1]):
                for j in range(3):
                    n[i][j] += x[j]
    out = []
    for x in n:
        length = math.sqrt(sum(c * c for c in x)) or 1.0
        out.append([c / length for c in x])
    return out


def move(src, dst, distance):
    lines, v, f = load(src)
    n = normals(v, f)
    i = 0
    out = []
    for l in lines:
        if l.startswith("v "):
            p = [v[i][k] + distance * n[i][k] for k in range(3)]
            i += 1
            out.append("v %.9g %.9g %.9g" % tuple(p))
        else:
            out.append(l)
    open(dst, "w").write("\n".join(out) + "\n")


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    src, dst, pct = sys.argv[1], sys.argv[2], float(sys.argv[3])
    mesh = os.path.join(src, "mesh", "initial.obj")
    if not os.path.isfile(mesh):
        sys.exit(f"{mesh}: not found (a scene folder as modelflow synth writes one)")
    if os.path.exists(dst):
        sys.exit(f"{dst}: exists; choose another folder")
    _, v, _ = load(mesh)
    lo = [min(p[k] for p in v) for k in range(3)]
    hi = [max(p[k] for p in v) for k in range(3)]
    distance = pct / 100.0 * math.sqrt(sum((hi[k] - lo[k]) ** 2 for k in range(3)))
    shutil.copytree(src, dst)
    move(mesh, os.path.join(dst, "mesh", "initial.obj"), distance)
    for p in sorted(glob.glob(os.path.join(src, "truth", "*.obj"))):
        move(p, os.path.join(dst, "truth", os.path.basename(p)), distance)
    print(f"{dst}: mesh and truth moved {distance:.6g} scene units along their normals")


main()

#!/usr/bin/env bash
# The Blender check of the exports (too heavy for CI: bpy is a 370 MB download). Makes
# target/bpyenv with Blender as a Python module (bpy; needs Python 3.11), tracks the Blender cloth
# sample, exports it as Alembic, glTF, PC2 and MDD, and has Blender import each and compare the vertex
# positions it evaluates with the run's OBJs, and the Alembic cameras' projections with the
# scene's (tools/check_blender.py), on the cloth and on the real webcams' board. Exit 0 when all agree.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
env="$root/target/bpyenv"
if ! "$env/bin/python" -c "import bpy" 2>/dev/null; then
    python3 -m venv "$env"
    "$env/bin/pip" install -q --disable-pip-version-check bpy
fi
cd "$root"
cargo build --release -q
bin="$root/target/release/modelflow"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
"$bin" track --scene fixtures/blender-cloth-sample/scene.json --out "$work/run" 2>/dev/null
for ext in abc glb pc2 mdd; do
    "$bin" export --run "$work/run" --out "$work/cloth.$ext" >/dev/null 2>&1
done
"$env/bin/python" tools/check_blender.py "$work/run" "$work/cloth" 2>&1 | grep '^blender '
# Real webcams (principal points off centre, fx != fy): the Alembic file's cameras.
"$bin" track --scene fixtures/caliscope-board-sample/scene.json --frames 0..2 --out "$work/board" 2>/dev/null
for ext in abc glb pc2 mdd; do
    "$bin" export --run "$work/board" --out "$work/board.$ext" >/dev/null 2>&1
done
"$env/bin/python" tools/check_blender.py "$work/board" "$work/board" 2>&1 | grep '^blender '
# The same with cam0 moving (a pose per frame, each 3-5 cm apart): sampled at every frame.
python3 - "$root/fixtures/caliscope-board-sample" "$work/moving.json" <<'PY'
import json, os, sys
d, out = sys.argv[1], sys.argv[2]
s = json.load(open(os.path.join(d, "scene.json")))
s["frames"]["last"] = 2
for k in ("mesh", "ground_truth"):
    s[k] = os.path.join(d, s[k])
for c in s["cameras"]:
    c["images"] = os.path.join(d, c["images"])
c = s["cameras"][0]
R, t = c.pop("R"), c.pop("t")
c["poses"] = [{"frame": f, "R": R, "t": [t[0] + 0.05 * (f == 1), t[1] + 0.04 * (f == 2), t[2] + 0.03 * f]}
              for f in range(3)]
json.dump(s, open(out, "w"))
PY
"$bin" track --scene "$work/moving.json" --out "$work/moving" 2>/dev/null
"$bin" export --run "$work/moving" --out "$work/moving.abc" >/dev/null 2>&1
"$env/bin/python" tools/check_blender.py "$work/moving" "$work/moving" abc 2>&1 | grep '^blender '

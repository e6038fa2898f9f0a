#!/usr/bin/env bash
# The Blender check of the exports (too heavy for CI: bpy is a 370 MB download). Makes
# target/bpyenv with Blender as a Python module (bpy; needs Python 3.11), tracks the Blender cloth
# sample, exports it as Alembic, glTF, PC2 and MDD, and has Blender import each and compare the vertex
# positions it evaluates with the run's OBJs (tools/check_blender.py). Exit 0 when all agree.
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

#!/usr/bin/env bash
# The Python package's checks, as CI runs them: formatting and lints of its Rust crate
# (python/), `pip install ./python` into target/pyenv (tools/pyenv.sh makes it; the build takes
# minutes the first time), then pytest on python/tests against the CLI binary that
# `cargo build` made (MODELFLOW_BIN, default target/debug/modelflow).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
tools/pyenv.sh >/dev/null
py="$root/target/pyenv/bin/python"
cargo fmt --manifest-path python/Cargo.toml --check
PYO3_PYTHON="$py" cargo clippy --manifest-path python/Cargo.toml --release -q -- -D warnings
"$py" -m pip install -q --disable-pip-version-check ./python
export MODELFLOW_BIN="${MODELFLOW_BIN:-$root/target/debug/modelflow}"
[ -x "$MODELFLOW_BIN" ] || cargo build -q --bin modelflow
"$py" -m pytest -q python/tests

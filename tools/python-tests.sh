#!/usr/bin/env bash
# The Python package's tests, as CI runs them (after `cargo test --workspace`): the extension
# module (python/, a workspace member) built by cargo into target/debug, loaded from
# target/python-module by the Python of target/pyenv (tools/pyenv.sh makes it), and pytest on
# python/tests against the CLI binary built from the same sources (MODELFLOW_BIN, default
# target/debug/modelflow).
#
# The module is built with the `test` profile and every target of the workspace selected, so
# that cargo resolves the same features as `cargo test --workspace` and reuses the library that
# command compiled: only pyo3, numpy and the bindings are compiled here (seconds, where a wheel
# built by maturin compiled the library once more: minutes of CI). Run on its own, the same
# command builds what it needs. A user's `pip install ./python` (maturin) builds the same crate.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
tools/pyenv.sh >/dev/null
py="$root/target/pyenv/bin/python"
PYO3_PYTHON="$py" cargo build -q --workspace --lib --bins --tests --examples --profile test
# The module's file name is what Python imports it by (`modelflow`, the name its #[pymodule]
# gives it); abi3: one file for every Python from 3.9.
module="$root/target/python-module"
rm -rf "$module"
mkdir -p "$module"
cp target/debug/libmodelflow_py.so "$module/modelflow.abi3.so"
export MODELFLOW_BIN="${MODELFLOW_BIN:-$root/target/debug/modelflow}"
export PYTHONPATH="$module${PYTHONPATH:+:$PYTHONPATH}"
# The module just built, not a wheel installed earlier.
"$py" -c 'import modelflow, sys; f = modelflow.__file__; assert f.startswith(sys.argv[1]), f"modelflow imported from {f}"' "$module"
"$py" -m pytest -q python/tests

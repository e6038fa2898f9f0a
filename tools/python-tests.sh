# The Python package's checks, as CI runs them: formatting and lints of its Rust crate
# (python/), a wheel built by maturin and installed into target/pyenv (tools/pyenv.sh makes it),
# then pytest on python/tests against the CLI binary that `cargo build` made (MODELFLOW_BIN,
# default target/debug/modelflow).
#
# The wheel is built with the dev profile into the workspace's target folder: python/Cargo.toml
# copies the workspace's profiles and python/Cargo.lock pins the same versions, so the
# dependencies `cargo build` already compiled are reused instead of compiled again in release
# (that saved minutes of CI). A user's `pip install ./python` builds in release as usual.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
tools/pyenv.sh >/dev/null
py="$root/target/pyenv/bin/python"
cargo fmt --manifest-path python/Cargo.toml --check
export CARGO_TARGET_DIR="$root/target"
PYO3_PYTHON="$py" cargo clippy --manifest-path python/Cargo.toml -q -- -D warnings
wheels="$root/target/python-wheels"
rm -rf "$wheels"
"$py" -m maturin build -q --profile dev -i "$py" -m python/Cargo.toml --out "$wheels"
"$py" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps "$wheels"/modelflow-*.whl
# The CLI the tests compare with is built from the same sources as the wheel (a stale binary
# would differ from it by whatever changed since).
if [ -z "${MODELFLOW_BIN:-}" ]; then
    cargo build -q --bin modelflow
    export MODELFLOW_BIN="$root/target/debug/modelflow"
fi
"$py" -m pytest -q python/tests

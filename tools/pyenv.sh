#!/usr/bin/env bash
# Makes the Python environment the checks use: target/pyenv with Pixar's USD library (usd-core,
# for the USD export check), and numpy and pytest (for the Python package's tests,
# tools/python-tests.sh). Run from anywhere; idempotent. The tests find it at
# target/pyenv/bin/python.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
env="$root/target/pyenv"
if ! "$env/bin/python" -c "import pxr, numpy, pytest" 2>/dev/null; then
    [ -x "$env/bin/python" ] || python3 -m venv "$env" \
        || { apt-get install -y -q python3-venv >/dev/null && python3 -m venv "$env"; }
    "$env/bin/pip" install -q --disable-pip-version-check usd-core numpy pytest
fi
"$env/bin/python" -c "from pxr import Usd; print('pyenv: usd-core', Usd.GetVersion())"

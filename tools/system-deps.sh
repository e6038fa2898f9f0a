#!/usr/bin/env bash
# Installs the system programs modelflow can use beyond its crates, where they are missing:
#   ffmpeg, ffprobe  video files as a camera's images (docs/scene-format.md); the video tests skip without them
#   clang            compiles the GPU kernels' CUDA text to PTX without a GPU (a test skips without it)
# Through apt-get, as root; elsewhere it says what to install and exits 0 (nothing else needs them).
# Called by .ci/run; run it once on a fresh machine before reading video files.
set -uo pipefail
install() { # install PACKAGE: apt-get, updating the lists once if the first try fails
  export DEBIAN_FRONTEND=noninteractive
  apt-get install -y --no-install-recommends "$1" >/dev/null 2>&1 \
    || { apt-get update >/dev/null 2>&1 && apt-get install -y --no-install-recommends "$1" >/dev/null 2>&1; }
}
need() { # need PACKAGE WHAT COMMAND...: installs PACKAGE unless every COMMAND is on the PATH
  local package=$1 what=$2; shift 2
  local c missing=0
  for c in "$@"; do command -v "$c" >/dev/null || missing=1; done
  if [ "$missing" = 0 ]; then
    echo "$package: $(command -v "$1")"
  elif [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    install "$package" && echo "$package: installed" \
      || echo "warning: could not install $package; $what"
  else
    echo "warning: $package not found and cannot be installed here (apt-get as root); $what"
  fi
}
need ffmpeg "video files cannot be read and the video tests will be skipped" ffmpeg ffprobe
if command -v clang-14 >/dev/null; then
  echo "clang: $(command -v clang-14)"
else
  need clang "the GPU kernels' PTX test will be skipped" clang
fi
exit 0

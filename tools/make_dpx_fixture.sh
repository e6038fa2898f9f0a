#!/usr/bin/env bash
# Writes fixtures/dpx/: one small picture (ffmpeg's testsrc2, 6 × 4) as a 16-bit PNG and, from it,
# DPX files in the layouts `input::dpx` reads, all written by ffmpeg's own DPX encoder, plus
# ffmpeg's grey PNG of the picture (the luma DPX's reference). Made with ffmpeg 5.1.9 (Debian 12).
set -euo pipefail
out="$(dirname "$0")/../fixtures/dpx"
mkdir -p "$out"
cd "$out"
ffmpeg -hide_banner -loglevel error -y -f lavfi -i "testsrc2=size=8x6:rate=1" -frames:v 1 \
  -vf crop=7:5:0:0 -pix_fmt rgb48be src.png
ffmpeg -hide_banner -loglevel error -y -i src.png -pix_fmt gray gray.png
for f in gbrp10be gbrp10le rgb48le rgb48be rgb24 gbrp12be gray rgba; do
  ffmpeg -hide_banner -loglevel error -y -i src.png -pix_fmt "$f" "$f.dpx"
done

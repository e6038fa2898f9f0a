#!/usr/bin/env bash
# Opens a modelflow report's index.html in headless Chromium (Debian package `chromium`), takes a
# full-page screenshot and fails if the browser logs a console error or a failed resource load
# (a missing or undecodable image), if the page references the network, or if the screenshot is
# missing. With a flipbook, it also opens the page at the flipbook's middle frame
# (index.html#frame=N) and fails unless the page's script moved the slider and the image there.
# Usage: tools/check-report-chromium.sh REPORT_DIR [SCREENSHOT.png]
set -euo pipefail

dir=${1:?usage: $0 REPORT_DIR [SCREENSHOT.png]}
shot=${2:-$dir/screenshot.png}
index="$(cd "$dir" && pwd)/index.html"
[ -f "$index" ] || { echo "FAIL: $index does not exist" >&2; exit 1; }
command -v chromium >/dev/null || { echo "FAIL: chromium is not installed (apt-get install -y chromium)" >&2; exit 1; }

if grep -Eqi '(src|href)="(https?:)?//' "$index"; then
  echo "FAIL: $index references the network:" >&2
  grep -Eoi '(src|href)="(https?:)?//[^"]*' "$index" >&2
  exit 1
fi

profile=$(mktemp -d)
log=$(mktemp)
dom=$(mktemp)
trap 'rm -rf "$profile" "$log" "$dom"' EXIT
flags=(--headless --no-sandbox --disable-gpu --disable-background-networking --no-first-run
  --user-data-dir="$profile" --enable-logging=stderr --v=0 --hide-scrollbars
  --virtual-time-budget=5000 --run-all-compositor-stages-before-draw)

# Chromium logs console messages but not failed image loads, so a probe page (same origin via
# --allow-file-access-from-files) loads the report in a frame and decodes every <img> itself.
probe="$profile/probe.html"
cat >"$probe" <<PROBE
<!DOCTYPE html><html><body><pre id="result">pending</pre>
<iframe id="f" src="file://$index" style="width:1400px;height:900px"></iframe>
<script>
document.getElementById('f').onload = async () => {
  const doc = document.getElementById('f').contentDocument;
  const out = [];
  for (const img of doc.querySelectorAll('img')) {
    const ok = await new Promise(res => { const i = new Image();
      i.onload = () => res(i.naturalWidth > 0); i.onerror = () => res(false); i.src = img.src; });
    out.push('IMG' + (ok ? '-OK ' : '-BROKEN ') + img.getAttribute('src'));
  }
  out.push('TI' + 'TLE ' + (doc.querySelector('h1') ? doc.querySelector('h1').textContent : ''));
  document.getElementById('result').textContent = out.join('\\n');
};
</script></body></html>
PROBE
# One run for the DOM and image checks (with the console log), one for the screenshot.
timeout 120 chromium "${flags[@]}" --allow-file-access-from-files --dump-dom "file://$probe" \
  >"$dom" 2>"$log" || { echo "FAIL: chromium exited with an error" >&2; cat "$log" >&2; exit 1; }
height=$(( $(grep -c '<figure' "$index" || true) * 700 + 2500 ))
timeout 120 chromium "${flags[@]}" --window-size=1400,"$height" --screenshot="$shot" "file://$index" \
  >/dev/null 2>>"$log" || { echo "FAIL: chromium could not take a screenshot" >&2; cat "$log" >&2; exit 1; }

errors=$(grep -E 'CONSOLE|Failed to load resource|net::ERR_|Uncaught' "$log" | grep -Ev 'ERR_BLOCKED_BY_CLIENT' || true)
if [ -n "$errors" ]; then
  echo "FAIL: browser console errors:" >&2
  echo "$errors" >&2
  exit 1
fi
if grep -q 'IMG-BROKEN' "$dom"; then
  echo "FAIL: images that do not load or decode:" >&2
  grep -o 'IMG-BROKEN [^<]*' "$dom" >&2
  exit 1
fi
grep -q 'TITLE .' "$dom" || { echo "FAIL: the page did not load or has no <h1> title" >&2; exit 1; }
imgs=$(grep -o 'IMG-OK' "$dom" | wc -l)
[ -s "$shot" ] || { echo "FAIL: no screenshot written" >&2; exit 1; }
book=""
if [ -d "$(dirname "$index")/flipbook" ]; then
  frames=($(ls "$(dirname "$index")/flipbook" | sed -n 's/^f0*\([0-9][0-9]*\)\.jpg$/\1/p' | sort -n))
  mid=${frames[$(( ${#frames[@]} / 2 ))]}
  timeout 120 chromium "${flags[@]}" --dump-dom "file://$index#frame=$mid" >"$dom" 2>>"$log"
  grep -q "<span id=\"fb-label\"[^>]*>frame $mid</span>" "$dom" \
    && grep -q "flipbook/f$(printf %04d "$mid").jpg" "$dom" \
    || { echo "FAIL: the flipbook did not move to frame $mid (index.html#frame=$mid)" >&2; exit 1; }
  book=", flipbook of ${#frames[@]} frames scrubs to frame $mid"
fi
echo "OK: $index rendered ($imgs images, no console errors$book); screenshot $shot"

#!/usr/bin/env bash
# Re-makes the README's screenshots of the viewer and the sweep report in Debian's headless
# Chromium (the same script as the browser test, cli/tests/view.rs):
#   bash docs/viewer/make.sh [path/to/animcodec]
# Needs Chromium and playwright-core (bash cli/tests/browser/install.sh) and, for the viewer
# shot, ../shared/data/samba (else the synthetic flag is shown).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=${1:-$root/target/release/animcodec}
out=$root/docs/viewer
check=$root/cli/tests/browser/check_page.mjs
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The report: the default sweep (each codec's lower envelope) of the built-in flag.
"$bin" sweep synth:flag --html "$work/report.html" --view-points hosvd:0 >/dev/null
VIEWPORT=1400x900 node "$check" "$work/report.html" "$out/report.png" >/dev/null

# The viewer: samba against its default pca-aoi decode (heat map = per-vertex error).
samba=$(realpath -m "$root/../shared/data/samba/samba.pc2")
if [ -f "$samba" ]; then
  "$bin" encode "$samba" -c pca-aoi -o "$work/s.anim" >/dev/null
  "$bin" decode "$work/s.anim" -o "$work/decoded.pc2" --topology-obj >/dev/null
  "$bin" view "$samba" "$work/decoded.pc2" -o "$work/view.html" >/dev/null
else
  echo "make.sh: $samba not found: the viewer shot shows the synthetic flag" >&2
  "$bin" view synth:flag quant-delta:bits=6 -o "$work/view.html" >/dev/null
fi
node "$check" "$work/view.html" "$out/viewer.png" >/dev/null
NO_WEBGL=1 node "$check" "$work/view.html" "$out/viewer-no-webgl.png" >/dev/null
ls -l "$out"/*.png

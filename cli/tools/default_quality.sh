#!/usr/bin/env bash
# What the plain `encode -c CODEC` gives on every animation in ../shared/data: bytes, bpvf, the
# KG and STED reached, encodes measured, and the default encode's wall time as a ratio to one encode at
# the `ss` it chose (both timed here, one after the other, on the same machine).
#   cli/tools/default_quality.sh [BINARY] [CODEC]   (default: target/release/animcodec hosvd)
set -euo pipefail
A=${1:-target/release/animcodec}
C=${2:-hosvd}
D=$(dirname "$0")/../../../shared/data
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
run() { # label input [extra args]
  local label=$1 input=$2; shift 2
  local s e s2 e2 ss
  s=$(date +%s.%N)
  if ! "$A" encode "$input" "$@" -c "$C" -o "$W/x.anim" -f --json > "$W/j.json" 2> "$W/err.txt"; then
    echo "$label FAILED: $(tail -n 1 "$W/err.txt")"; return
  fi
  e=$(date +%s.%N)
  ss=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['params']['ss'])" "$W/j.json")
  s2=$(date +%s.%N)
  "$A" encode "$input" "$@" -c "$C" -p "ss=$ss" -o "$W/y.anim" -f > /dev/null 2>&1
  e2=$(date +%s.%N)
  python3 - "$W/j.json" "$label" "$s" "$e" "$s2" "$e2" <<'PY'
import json, sys
d = json.load(open(sys.argv[1])); label = sys.argv[2]; s, e, s2, e2 = map(float, sys.argv[3:])
r = d['reached']
print(f"{label}\t{d['frames']}x{d['vertices']}\tbytes {d['bytes']}\tbpvf {d['bpvf']:.4f}\tKG {r['kg']:.4f}\tSTED {r['sted']:.4f}"
      f"\tss {d['params']['ss']}\tencodes {len(d['tried'])}\tdefault {e - s:.2f} s\tone encode {e2 - s2:.2f} s"
      f"\tratio {(e - s) / (e2 - s2):.2f}")
PY
}
for name in samba horse-gallop pcow chicken-crossing; do run "$name" "$D/$name/$name.pc2"; done
for i in $(seq 0 13); do run "robot-$i" "$D/robot-expressive/RobotExpressive.glb" --animation "$i"; done

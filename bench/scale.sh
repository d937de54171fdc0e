#!/usr/bin/env bash
# Scale benchmark of issue 30 (not a test): for each size COLSxROWSxFRAMES, writes the synthetic
# flag as a PC2 frame by frame (`animcodec synth flag:…`), then for each codec measures the
# streamed encode (PC2 → .anim, fixed parameters, --memory budget) and the streamed decode
# (.anim → PC2): wall time, peak RSS (/usr/bin/time), throughput in vertex-frames per second and
# as a ratio to reading the raw file (`cat FILE > /dev/null`, same page cache state: the file was
# just written). Prints one Markdown table row per codec and size. Then a second table: the
# default command (no -p: the default-quality search, --eval) within the same --memory, per codec
# and size (DEFAULT_ROWS=0 skips it; DEFAULT_ONLY=1 runs only it). Its "search" column says how
# the search read the input: streamed (every candidate over the whole input) or, over 1 GiB of
# coordinates, sampled (candidates on a sample of the frames, the whole encoded and measured).
#
#   cargo build -p animcodec-cli --release
#   bench/scale.sh 100x100x1000 400x250x1000 1000x1000x1000
#
# Environment: ANIMCODEC (binary; default target/release/animcodec), SCALE_DIR (where the big
# files go; default /work/scale), CODECS (default "quant-delta pca-aoi hosvd"), MEMORY (encode
# --memory; default 4G), KEEP_FREE_GB (refuse a size that would leave less disk free; default 15),
# INPUT (an existing PC2 of the one size given, used instead of writing it and never deleted:
# runs of different codecs at once share it). Every file written is deleted when its size is
# done.
set -euo pipefail
BIN=${ANIMCODEC:-target/release/animcodec}
DIR=${SCALE_DIR:-/work/scale}
CODECS=${CODECS:-"quant-delta pca-aoi hosvd"}
MEMORY=${MEMORY:-4G}
KEEP_FREE_GB=${KEEP_FREE_GB:-15}
mkdir -p "$DIR"
rm -f "$DIR/default-rows.md"

# Fixed parameters equal to each codec's defaults: with -p the encode streams (without it, encode
# searches for the default quality, which holds the whole animation). PARAMS_<CODEC> (codec name
# upper-cased, '-' as '_'; e.g. PARAMS_HOSVD="ss=0.9 block=100") replaces them: space-separated
# key=value pairs, each passed as one -p.
params() {
  local var="PARAMS_$(echo "$1" | tr 'a-z-' 'A-Z_')"
  if [[ -n "${!var:-}" ]]; then
    echo "${!var}"
    return
  fi
  case "$1" in
    quant-delta) echo "bits=12" ;;
    pca-aoi) echo "block=40" ;;
    hosvd) echo "ss=0.9" ;;
    *) echo "level=19" ;;
  esac
}

# "-p K=V" for each pair of params().
param_args() {
  local kv
  for kv in $(params "$1"); do printf -- '-p\n%s\n' "$kv"; done
}

# Runs a command under /usr/bin/time; prints "WALL_SECONDS PEAK_RSS_KB".
measure() {
  /usr/bin/time -f "%e %M" -o "$DIR/time.txt" "$@" > "$DIR/out.txt" 2> "$DIR/err.txt" || {
    echo "FAILED: $*" >&2; cat "$DIR/err.txt" >&2; echo "nan nan"; return 0; }
  cat "$DIR/time.txt"
}

echo "| vertices × frames | codec | encode wall s | encode peak RSS MB | encode Mvf/s | encode ÷ raw read | decode wall s | decode peak RSS MB | decode Mvf/s | bpvf |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for size in "$@"; do
  IFS=x read -r cols rows frames <<< "$size"
  v=$((cols * rows)); vf=$((v * frames)); bytes=$((vf * 12 + 32))
  free_kb=$(df -k --output=avail "$DIR" | tail -1)
  # The PC2 (or one decoded PC2) and the streams: at most 1.6 × the raw size at once.
  need_kb=$(( (bytes * 16 / 10) / 1024 ))
  if (( free_kb - need_kb < KEEP_FREE_GB * 1024 * 1024 )); then
    echo "skip $size: needs $((need_kb / 1048576)) GB, $((free_kb / 1048576)) GB free, $KEEP_FREE_GB GB must stay free" >&2
    continue
  fi
  pc2="${INPUT:-$DIR/flag-$size.pc2}"
  [[ -n "${INPUT:-}" ]] || "$BIN" synth "flag:$size" -o "$pc2" -f > /dev/null
  read -r raw_s _ < <(measure sh -c 'cat "$1" > /dev/null' sh "$pc2")
  # Every codec encodes first; the input is deleted before the decodes, so the disk holds the
  # input or one decoded PC2 (plus the streams), never both.
  declare -A enc_s enc_kb bpvf
  for codec in $( [[ "${DEFAULT_ONLY:-0}" == 1 ]] || echo $CODECS ); do
    anim="$DIR/flag-$size.$codec.anim"
    mapfile -t pargs < <(param_args "$codec")
    read -r enc_s[$codec] enc_kb[$codec] < <(measure "$BIN" encode "$pc2" -c "$codec" "${pargs[@]}" --memory "$MEMORY" -o "$anim" -f --json)
    bpvf[$codec]=$(python3 -c 'import json,sys; print("%.3f" % json.load(open(sys.argv[1]))["bpvf"])' "$DIR/out.txt" 2>/dev/null || echo nan)
    echo "encoded $size $codec: ${enc_s[$codec]} s, ${enc_kb[$codec]} KB" >&2
  done
  # The default commands (no -p: the default-quality search) within --memory, with --eval:
  # peak RSS (also as a multiple of the raw size), wall, the parameters chosen, the KG reached,
  # and which path the search took (whole or streamed). DEFAULT_ROWS=0 skips them.
  if [[ "${DEFAULT_ROWS:-1}" != 0 ]]; then
    for codec in $CODECS; do
      anim="$DIR/flag-$size.$codec.default.anim"
      read -r def_s def_kb < <(measure "$BIN" encode "$pc2" -c "$codec" --memory "$MEMORY" --eval -o "$anim" -f --json)
      python3 - "$v" "$frames" "$codec" "$def_s" "$def_kb" "$DIR/out.txt" "$MEMORY" >> "$DIR/default-rows.md" <<'PY'
import json, sys
v, f, codec, s, kb, out, memory = sys.argv[1:]
v, f = int(v), int(f)
raw_mb = v * f * 12 / 2**20
try:
    d = json.load(open(out))
    params = " ".join(f"{k}={d['params'][k]}" for k in ("bits", "kg", "ss", "block") if k in d["params"])
    kg = d.get("kg")
    kg = "n/a" if kg is None else f"{kg:.3f}"
    sted = d.get("sted")
    sted = "n/a" if sted is None else f"{sted:.4f}"
    path, bpvf, n = d["search_input"], f"{d['bpvf']:.3f}", len(d["tried"])
    if d.get("sample_frames"):
        path += f" ({d['sample_frames']} frames; whole encoded {d['whole_encodes']}×)"
except Exception:
    params, kg, sted, path, bpvf, n = "FAILED", "", "", "", "", ""
mb = float(kb) / 1024 if kb != "nan" else float("nan")
print(f"| {v:,} × {f:,} | {codec} | {memory} | {path} | {float(s):.0f} | {mb:.0f} | {mb / raw_mb:.2f} | {params} | {n} | {bpvf} | {kg} | {sted} |")
PY
      echo "default $size $codec: $def_s s, $def_kb KB" >&2
      rm -f "$anim"
    done
  fi
  [[ -n "${INPUT:-}" ]] || rm -f "$pc2"
  for codec in $( [[ "${DEFAULT_ONLY:-0}" == 1 ]] || echo $CODECS ); do
    anim="$DIR/flag-$size.$codec.anim"
    out="$DIR/flag-$size.$codec.decoded.pc2"
    read -r dec_s dec_kb < <(measure "$BIN" decode "$anim" -o "$out" -f)
    echo "decoded $size $codec: $dec_s s, $dec_kb KB" >&2
    python3 - "$v" "$frames" "$codec" "${enc_s[$codec]}" "${enc_kb[$codec]}" "$raw_s" "$dec_s" "$dec_kb" "${bpvf[$codec]}" <<'PY'
import sys
v, f, codec, es, ek, rs, ds, dk, bpvf = sys.argv[1:]
v, f = int(v), int(f)
def num(x):
    try: return float(x)
    except ValueError: return float("nan")
es, ek, rs, ds, dk = map(num, (es, ek, rs, ds, dk))
vf = v * f
print(f"| {v:,} × {f:,} | {codec} | {es:.1f} | {ek/1024:.0f} | {vf/max(es,0.01)/1e6:.2f} | {es/max(rs,0.01):.1f} | {ds:.1f} | {dk/1024:.0f} | {vf/max(ds,0.01)/1e6:.2f} | {bpvf} |")
PY
    rm -f "$anim" "$out" "${out%.pc2}.obj"
  done
  unset enc_s enc_kb bpvf
  [[ -n "${INPUT:-}" ]] || rm -f "${pc2%.pc2}.obj"
done
if [[ -s "$DIR/default-rows.md" ]]; then
  echo
  echo "| vertices × frames | codec (default command, --eval) | --memory | search | wall s | peak RSS MB | × raw | chosen | points | bpvf | KG % | STED |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
  cat "$DIR/default-rows.md"
fi
rm -f "$DIR/time.txt" "$DIR/out.txt" "$DIR/err.txt" "$DIR/default-rows.md"

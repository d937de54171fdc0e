#!/bin/sh
# Per-frame decode cost through the C library (capi/): bulk, sequential player, random access,
# cold open + one frame, and a memcpy of one frame, per codec, on one animation; with DRACO=1,
# also Google Draco's per-frame decode (DracoPy) at each stream's KG, in the same run.
#
#   sh bench/capi_playback.sh            # debug profile (what the tests build; workspace crates at opt-level 1)
#   PROFILE=release sh bench/capi_playback.sh   # the numbers to quote
#   INPUT=../shared/data/samba/samba.pc2 DRACO=1 sh bench/capi_playback.sh
#   INPUT=flag:400x250x60 DRACO=1 sh bench/capi_playback.sh   # a 100k-vertex synthetic
#
# INPUT: any input `animcodec encode` reads, `synth:NAME[:SIZE]`, or `flag:COLSxROWSxFRAMES`
# (written by `animcodec synth`). STREAMS: space-separated NAME:CODEC[:KEY=VALUE,...] (default:
# every codec at its defaults, plus the block settings that make packets short). The library
# and CLI are taken from $CARGO_TARGET_DIR (default target/). Output: Markdown table(s) on stdout.
set -eu
cd "$(dirname "$0")/.."
profile=${PROFILE:-debug}
input=${INPUT:-synth:cylinder:medium}
target=${CARGO_TARGET_DIR:-$PWD/target}
flag=""
[ "$profile" = release ] && flag=--release
# BUILD=0 uses what is already built (e.g. after `cargo test -p animcodec-capi` and a build of the CLI).
if [ "${BUILD:-1}" != 0 ]; then
    nice -n 10 cargo build $flag -p animcodec-capi -p animcodec-cli >&2
fi
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
lib="$target/$profile"
cc -O2 -std=c11 -Icapi/include bench/capi_playback.c -L"$lib" -lanimcodec_capi -Wl,-rpath,"$lib" -o "$dir/capi_playback"
cli="$lib/animcodec"
case $input in
flag:*)
    "$cli" synth "$input" -o "$dir/input.pc2" >&2
    input="$dir/input.pc2"
    ;;
esac
default_streams="quant-delta:quant-delta pca-aoi:pca-aoi hosvd:hosvd sac:sac stseg:stseg laplacian:laplacian
quant-delta-block8:quant-delta:block=8 pca-aoi-block16:pca-aoi:block=16 hosvd-block16:hosvd:block=16
laplacian-block16:laplacian:block=16 sac-keyframe16:sac:keyframe_interval=16"
streams=""
for spec in ${STREAMS:-$default_streams}; do
    name=${spec%%:*}
    rest=${spec#*:}
    codec=${rest%%:*}
    params=""
    if [ "$rest" != "$codec" ]; then
        for p in $(echo "${rest#*:}" | tr ',' ' '); do params="$params -p $p"; done
    fi
    # shellcheck disable=SC2086
    "$cli" encode "$input" -c "$codec" $params -o "$dir/$name.anim" >&2
    streams="$streams $dir/$name.anim"
done
echo "input: ${INPUT:-synth:cylinder:medium}, profile: $profile"
# shellcheck disable=SC2086
"$dir/capi_playback" $streams | tee "$dir/table.md"
if [ "${DRACO:-0}" = 1 ]; then
    # The original (with its triangles) and every stream's decode, as PC2 files, for the KGs.
    "$cli" decode "$(echo $streams | cut -d' ' -f1)" -o "$dir/mesh.pc2" --topology-obj >&2
    case $input in
    *.pc2 | *.mdd) original=$input ;;
    *)
        "$cli" encode "$input" -c quant-delta -p bits=24 -o "$dir/lossless.anim" >&2
        "$cli" decode "$dir/lossless.anim" -o "$dir/original.pc2" >&2
        original="$dir/original.pc2"
        ;;
    esac
    decoded=""
    for s in $streams; do
        name=$(basename "$s" .anim)
        "$cli" decode "$s" -o "$dir/$name.pc2" >&2
        decoded="$decoded $name=$dir/$name.pc2"
    done
    echo
    # shellcheck disable=SC2086
    python3 bench/capi_playback_draco.py "$dir/table.md" "$original" "$dir/mesh.obj" $decoded
fi

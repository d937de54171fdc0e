#!/bin/sh
# Per-frame decode cost through the C library (capi/): bulk, sequential player, random access,
# cold open + one frame, and a memcpy of one frame, per codec, on a synthetic animation.
#
#   sh bench/capi_playback.sh            # debug profile (what the tests build; workspace crates at opt-level 1)
#   PROFILE=release sh bench/capi_playback.sh   # the numbers to quote
#   INPUT=../shared/data/… sh bench/capi_playback.sh   # any input `animcodec encode` reads
#
# Streams: every codec at its defaults, plus the block settings that make packets short
# (random access decodes one packet): hosvd block=16, laplacian block=16, pca-aoi block=16,
# quant-delta block=8, sac keyframe_interval=16. Output: a Markdown table on stdout.
set -eu
cd "$(dirname "$0")/.."
profile=${PROFILE:-debug}
input=${INPUT:-synth:cylinder:medium}
flag=""
[ "$profile" = release ] && flag=--release
# BUILD=0 uses what is already in target/ (e.g. after `cargo test -p animcodec-capi`, which
# builds the library, and a build of the CLI).
if [ "${BUILD:-1}" != 0 ]; then
    nice -n 10 cargo build $flag -p animcodec-capi -p animcodec-cli >&2
fi
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
cc -O2 -std=c11 -Icapi/include bench/capi_playback.c -Ltarget/$profile -lanimcodec_capi \
    -Wl,-rpath,"$PWD/target/$profile" -o "$dir/capi_playback"
cli=target/$profile/animcodec
streams=""
encode() { # NAME CODEC PARAMS…
    name=$1; codec=$2; shift 2
    params=""
    for p in "$@"; do params="$params -p $p"; done
    # shellcheck disable=SC2086
    "$cli" encode "$input" -c "$codec" $params -o "$dir/$name.anim" >&2
    streams="$streams $dir/$name.anim"
}
for codec in quant-delta pca-aoi hosvd sac stseg laplacian; do encode "$codec" "$codec"; done
encode quant-delta-block8 quant-delta block=8
encode pca-aoi-block16 pca-aoi block=16
encode hosvd-block16 hosvd block=16
encode laplacian-block16 laplacian block=16
encode sac-keyframe16 sac keyframe_interval=16
echo "input: $input, profile: $profile"
# shellcheck disable=SC2086
"$dir/capi_playback" $streams

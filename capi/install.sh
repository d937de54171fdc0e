#!/bin/sh
# Installs the animcodec C library built by cargo into PREFIX:
#   cargo build --release -p animcodec-capi
#   sh capi/install.sh target/release /usr/local
# PREFIX/lib: libanimcodec_capi.so and .a; PREFIX/include/animcodec.h;
# PREFIX/lib/pkgconfig/animcodec.pc (from capi/animcodec.pc.in); PREFIX/lib/cmake/animcodec/.
set -eu
if [ $# -ne 2 ]; then
    echo "usage: sh capi/install.sh CARGO_BUILD_DIR PREFIX" >&2
    exit 2
fi
build=$1
prefix=$2
here=$(cd "$(dirname "$0")" && pwd)
version=$(sed -n 's/^version = "\(.*\)"/\1/p' "$here/../Cargo.toml" | head -n 1)
mkdir -p "$prefix/lib/pkgconfig" "$prefix/lib/cmake/animcodec" "$prefix/include"
found=0
for lib in libanimcodec_capi.so libanimcodec_capi.dylib libanimcodec_capi.a; do
    if [ -f "$build/$lib" ]; then
        cp "$build/$lib" "$prefix/lib/"
        found=1
    fi
done
if [ $found -eq 0 ]; then
    echo "install.sh: no libanimcodec_capi in $build (run cargo build -p animcodec-capi first)" >&2
    exit 1
fi
cp "$here/include/animcodec.h" "$prefix/include/"
cp "$here/cmake/animcodecConfig.cmake" "$prefix/lib/cmake/animcodec/"
sed -e "s|@PREFIX@|$prefix|" -e "s|@LIBDIR@|$prefix/lib|" -e "s|@INCLUDEDIR@|$prefix/include|" \
    -e "s|@VERSION@|$version|" "$here/animcodec.pc.in" > "$prefix/lib/pkgconfig/animcodec.pc"

#!/usr/bin/env bash
# Installs what the glTF interoperability tests (cli/tests/gltf.rs) need: npm `three` (three.js:
# GLTFLoader, AnimationMixer, CPU skinning, MeshoptDecoder), `gltf-validator` (the Khronos
# glTF Validator) and `gltfpack` (meshoptimizer's packer, whose -cc output the reader must
# read), pinned by package-lock.json, run under the machine's Node.js. Without them the tests
# skip with a message (a failure under ANIMCODEC_REQUIRE_ALL=1). Safe to run again.
set -euo pipefail
cd "$(dirname "$0")"
command -v node >/dev/null || { echo "node not found" >&2; exit 1; }
npm ci --no-audit --no-fund --silent
node -e "console.log('three', require('./node_modules/three/package.json').version, '/ gltf-validator', require('./node_modules/gltf-validator/package.json').version, '/ gltfpack', require('./node_modules/gltfpack/package.json').version)"

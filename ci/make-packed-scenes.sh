#!/usr/bin/env bash
# Regenerates tests/data/gltfpack/: the project's scenes passed through gltfpack's default settings (KHR_mesh_quantization),
# which tests/quantized.rs renders against the originals. The npm tool goes into a cache folder, not the system.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
TOOLS=${PATHWAVE_TOOLS:-$HOME/.cache/pathwave-tools}
mkdir -p "$TOOLS"
[ -x "$TOOLS/node_modules/.bin/gltfpack" ] || (cd "$TOOLS" && npm install --no-audit --no-fund gltfpack@1.3.0 >/dev/null)
OUT=$ROOT/tests/data/gltfpack
mkdir -p "$OUT"
for s in cornell-box textured glass animated; do
  "$TOOLS/node_modules/.bin/gltfpack" -i "$ROOT/scenes/$s.gltf" -o "$OUT/$s.gltf" >/dev/null
  echo "wrote tests/data/gltfpack/$s.gltf"
done

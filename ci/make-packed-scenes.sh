#!/usr/bin/env bash
# Regenerates tests/data/gltfpack/, tests/data/gltfpack-cc/ and tests/data/draco/: the project's scenes passed through gltfpack's default
# settings (KHR_mesh_quantization) and through `gltfpack -cc` (EXT_meshopt_compression, every filter), which
# tests/quantized.rs renders against the originals. The npm tool goes into a cache folder, not the system.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
TOOLS=${PATHWAVE_TOOLS:-$HOME/.cache/pathwave-tools}
mkdir -p "$TOOLS"
[ -x "$TOOLS/node_modules/.bin/gltfpack" ] || (cd "$TOOLS" && npm install --no-audit --no-fund gltfpack@1.3.0 >/dev/null)
for variant in "gltfpack:" "gltfpack-cc:-cc"; do
  dir=${variant%%:*}; flags=${variant#*:}
  mkdir -p "$ROOT/tests/data/$dir"
  for s in cornell-box textured glass animated; do
    # shellcheck disable=SC2086
    "$TOOLS/node_modules/.bin/gltfpack" $flags -i "$ROOT/scenes/$s.gltf" -o "$ROOT/tests/data/$dir/$s.gltf" >/dev/null
    echo "wrote tests/data/$dir/$s.gltf"
  done
done
# gltf-pipeline -d: every primitive KHR_draco_mesh_compression-compressed (edgebreaker, quantised attributes), which
# tests/quantized.rs renders against the originals too.
[ -x "$TOOLS/node_modules/.bin/gltf-pipeline" ] || (cd "$TOOLS" && npm install --no-audit --no-fund gltf-pipeline@4.3.1 >/dev/null)
mkdir -p "$ROOT/tests/data/draco"
for s in cornell-box textured glass animated; do
  "$TOOLS/node_modules/.bin/gltf-pipeline" -d -i "$ROOT/scenes/$s.gltf" -o "$ROOT/tests/data/draco/$s.gltf" >/dev/null
  echo "wrote tests/data/draco/$s.gltf"
done

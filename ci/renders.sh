#!/usr/bin/env bash
# Renders every project scene in 18 ways (both schedules, two seeds, an environment, a thin lens with a depth cap) with
# BIN into OUT: run it with the binaries before and after a change and `cmp` the files to check they are the same bytes.
set -euo pipefail
BIN=$1; OUT=$2; SCENES=${3:-$(cd "$(dirname "$0")/.." && pwd)/scenes}
mkdir -p "$OUT"
[ -f /usr/share/vulkan/icd.d/lvp_icd.x86_64.json ] && export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.x86_64.json}
for s in "$SCENES"/*.gltf; do
  n=$(basename "$s" .gltf)
  "$BIN" render "$s" -o "$OUT/$n.exr" --size 80x60 --spp 8 >/dev/null 2>&1 || echo "FAIL $n"
  PATHWAVE_SCHEDULE=fused "$BIN" render "$s" -o "$OUT/$n.fused.exr" --size 64x48 --spp 20 --seed 3 >/dev/null 2>&1 || echo "FAIL fused $n"
done
"$BIN" render "$SCENES/material-grid.gltf" -o "$OUT/grid-env.exr" --size 80x60 --spp 8 --env-color 1,0.9,0.8 >/dev/null 2>&1 || echo FAIL grid-env
"$BIN" render "$SCENES/cornell-box.gltf" -o "$OUT/cornell-lens.exr" --size 80x60 --spp 8 --aperture 0.05 --max-depth 3 >/dev/null 2>&1 || echo FAIL lens
echo done

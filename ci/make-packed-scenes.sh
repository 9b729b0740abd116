#!/usr/bin/env bash
# Regenerates tests/data/gltfpack/, tests/data/gltfpack-cc/, tests/data/draco/ and tests/data/shared-geometry.gltf: the project's scenes passed through gltfpack's default
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
# Two meshes of one geometry (the Cornell box's short block top again, raised, in red): gltf-pipeline -d writes one
# Draco stream and one set of accessors for both.
python3 - "$ROOT" <<'PY'
import json, sys
root = sys.argv[1]
d = json.load(open(f"{root}/scenes/cornell-box.gltf"))
top = d["meshes"][10]
d["meshes"].append({"name": "short block top, raised copy", "primitives": [dict(top["primitives"][0], material=1)]})
d["nodes"].insert(16, {"mesh": 16, "name": "raised copy", "translation": [0, 0.12, 0]})
d["scenes"][0]["nodes"] = list(range(len(d["nodes"])))
json.dump(d, open(f"{root}/tests/data/shared-geometry.gltf", "w"), indent=1)
PY
"$TOOLS/node_modules/.bin/gltf-pipeline" -d -i "$ROOT/tests/data/shared-geometry.gltf" -o "$ROOT/tests/data/draco/shared-geometry.gltf" >/dev/null
echo "wrote tests/data/shared-geometry.gltf and tests/data/draco/shared-geometry.gltf"

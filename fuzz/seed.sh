#!/usr/bin/env bash
# Fills fuzz/corpus/ with seeds: the project's scenes and the glTF-Validator corpus (beside the clone, as in CI)
# for `gltf`, and a small render of the Cornell box as EXR for `environment` and `exr`.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p fuzz/corpus/gltf fuzz/corpus/environment fuzz/corpus/exr
cp scenes/*.gltf fuzz/corpus/gltf/
if [ -d ../shared/gltf-validator-corpus ]; then
  find ../shared/gltf-validator-corpus \( -name '*.gltf' -o -name '*.glb' \) -size -256k -print0 |
    while IFS= read -r -d '' f; do cp "$f" "fuzz/corpus/gltf/$(echo "$f" | md5sum | cut -c1-12)-$(basename "$f")"; done
fi
# A built binary is used as it is; otherwise cargo builds one.
pathwave() { if [ -x target/release/pathwave ]; then target/release/pathwave "$@"; else cargo run --release --quiet -- "$@"; fi; }
pathwave render scenes/cornell-box.gltf -o fuzz/corpus/exr/cornell.exr --size 16x8 --spp 1 >/dev/null
cp fuzz/corpus/exr/cornell.exr fuzz/corpus/environment/
echo "seeded: $(ls fuzz/corpus/gltf | wc -l) glTF, 1 EXR"

#!/usr/bin/env bash
# The README's first command: set up the machine, build, and render the sample scene to EXR and PNG.
set -euo pipefail
cd "$(dirname "$0")/.."
bash ci/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
cargo build --release --locked
./target/release/pathwave render scenes/cornell-box.gltf -o cornell-box.exr --size 256x256 --spp 64
./target/release/pathwave render scenes/cornell-box.gltf -o cornell-box.png --size 256x256 --spp 64
echo "wrote cornell-box.exr (linear) and cornell-box.png (sRGB)"

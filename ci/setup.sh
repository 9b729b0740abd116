#!/usr/bin/env bash
# Installs what a fresh Debian machine lacks to build and test pathwave: Vulkan loader, lavapipe, glslang, validation
# layers, and an X server for the viewer.
set -euo pipefail

PACKAGES=(
  libvulkan1            # the Vulkan loader
  mesa-vulkan-drivers   # lavapipe: Vulkan on the CPU
  vulkan-validationlayers
  glslang-tools         # glslangValidator, used by build.rs and hot reload
  spirv-tools
  vulkan-tools          # vulkaninfo, for diagnosing a machine
  pkg-config
  g++                   # builds meshoptimizer (the meshopt crate), the EXT_meshopt_compression decoder
  xvfb xauth            # a headless X server for the viewer's tests (xvfb-run)
  libx11-6 libx11-xcb1 libxcursor1 libxrandr2 libxi6 libxkbcommon-x11-0   # loaded by winit at run time
  python3 python3-venv  # venvs for Open Image Denoise and for the Python module's tests (below)
  libllvm19             # Mitsuba 3's LLVM variant JIT-compiles through it (tests/media.rs): with bookworm's
                        # LLVM 15 alone, drjit's 16-wide code on an AVX-512 host stops at "LLVM ERROR: Cannot
                        # select ... fminimum"
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" -eq 0 ]; then SUDO=(); else SUDO=(sudo); fi
  echo "ci/setup.sh: installing ${missing[*]}"
  "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

if ! command -v cargo >/dev/null 2>&1; then
  if [ -x "$HOME/.cargo/bin/cargo" ]; then
    export PATH="$HOME/.cargo/bin:$PATH"
  else
    echo "ci/setup.sh: cargo not found; install Rust (rustup) first" >&2
    exit 1
  fi
fi

# Makes the venv $1 hold what `pip install` of the remaining arguments installs, once: a stamp named after those
# arguments marks it done, and other arguments (a new pin) rebuild it from scratch.
venv_with() {
  local venv="$1"
  shift
  local stamp
  stamp="$venv/.installed-$(echo "$*" | tr ' ' '+')"
  [ -f "$stamp" ] && return 0
  echo "ci/setup.sh: installing $* into $venv"
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q --disable-pip-version-check "$@"
  touch "$stamp"
}

# Intel Open Image Denoise for --denoise and tests/denoise.rs: no Debian package has it, PyPI's pyoidn wheel ships
# libOpenImageDenoise.so.2 with its CPU device. Installed without its Python dependencies (pathwave only loads the
# library) into a venv of its own, where pathwave looks for it (src/denoise.rs).
venv_with "$HOME/.cache/pathwave/oidn-venv" --no-deps pyoidn==2.5.1.0

# The Python module's build and test tools (ci/test.sh installs the module itself, built from the checkout, into
# this venv): maturin builds it, pytest runs python/tests, OpenEXR reads the EXRs pathwave writes (a reader pathwave
# did not write), numpy is what the module returns, matplotlib draws the guide's example (python/tests/test_guide.py).
venv_with "$HOME/.cache/pathwave/python-venv" maturin==1.16.0 numpy==2.4.6 pytest==9.0.3 OpenEXR==3.5.3 matplotlib==3.10.8

# Mitsuba 3, the independent reference tests/media.rs compares scattering media with (tests/mitsuba/render_gltf.py).
# Its LLVM variant JIT-compiles through the system's newest libLLVM (libllvm19, above).
venv_with "$HOME/.cache/pathwave/mitsuba-venv" mitsuba==3.9.1 drjit==1.5.0 numpy==2.4.6

# A second lavapipe, Mesa 25 from the backports suite, beside the system's: tests/ray_query.rs runs ray-query
# traversal on it while everything else keeps the system's driver.
bash "$(dirname "$0")/lavapipe-rt.sh" >/dev/null

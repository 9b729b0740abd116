#!/usr/bin/env bash
# The README's test command: set up the machine if needed, then check formatting, lints and run every test on lavapipe.
set -euo pipefail
cd "$(dirname "$0")/.."
bash ci/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
# A clean clone is built once: incremental state would only cost disk (2 GB) and time.
if [ "${CI:-}" = "true" ]; then
  export CARGO_INCREMENTAL=0
fi
# Prefer lavapipe when several drivers exist, so results match CI; any device works when this is unset.
if [ -z "${VK_DRIVER_FILES:-}${VK_ICD_FILENAMES:-}" ] && [ -f /usr/share/vulkan/icd.d/lvp_icd.x86_64.json ] && [ "${CI:-}" = "true" ]; then
  export VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
fi
if rustup component list --installed 2>/dev/null | grep -q rustfmt; then
  cargo fmt --all --check
fi
if rustup component list --installed 2>/dev/null | grep -q clippy; then
  # The library, binary, tests and the Python module's crate in one run, so the two share the machine's cores.
  cargo clippy --workspace --all-targets --locked -- -D warnings
fi
# tests/farm.rs starts a one-node Slurm (ci/slurm.sh installs slurm-wlm and munge with apt if missing): here it must run.
export PATHWAVE_FARM_TEST=1
cargo test --locked

# The Python module (python/, pyproject.toml): built once from this checkout as `pip install .` builds it, with the
# dev profile so it reuses what `cargo test` just compiled, into the venv ci/setup.sh made; then its pytest suite,
# which compares it with the CLI built above.
PY_VENV="$HOME/.cache/pathwave/python-venv"
# The venv's bin/ on PATH: without build isolation maturin's build hook runs the `maturin` it installed there.
PATH="$PY_VENV/bin:$PATH" MATURIN_PEP517_ARGS="--profile dev --locked" "$PY_VENV/bin/pip" install -q --disable-pip-version-check \
  --no-build-isolation --no-deps --force-reinstall .
# As the Rust tests do: with the validation layer when it is installed, so a render fails on any of its errors.
layer=explicit_layer.d/VkLayer_khronos_validation.json
if [ -z "${PATHWAVE_VALIDATION:-}" ] && { [ -f "/usr/share/vulkan/$layer" ] || [ -f "/etc/vulkan/$layer" ]; }; then
  export PATHWAVE_VALIDATION=1
fi
PATHWAVE_BIN="$PWD/target/debug/pathwave" "$PY_VENV/bin/python" -m pytest -q python/tests

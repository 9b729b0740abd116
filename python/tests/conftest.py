"""Fixtures of pathwave's Python tests: the repository, the command-line binary to compare against, and one
Renderer and Cornell box for the whole session (every render runs on whatever Vulkan device there is, lavapipe on
a CPU: renders stay tiny and seeded).

The CLI is $PATHWAVE_BIN, else <repo>/target/debug/pathwave; a missing one fails the tests that need it, naming the
path (it is never skipped)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

import pathwave

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO


@pytest.fixture(scope="session")
def cli() -> Path:
    """The `pathwave` binary the module is compared with."""
    path = Path(os.environ.get("PATHWAVE_BIN") or REPO / "target" / "debug" / "pathwave")
    if not (path.is_file() and os.access(path, os.X_OK)):
        pytest.fail(
            f"the pathwave CLI is not at {path} (or not executable): build it (cargo build) or set PATHWAVE_BIN "
            "to the binary",
            pytrace=False,
        )
    return path


@pytest.fixture(scope="session")
def run_cli(cli):
    """run_cli(*args, cwd=..., check=None) runs the CLI and returns the CompletedProcess (text stdout/stderr).
    check=N asserts the exit code is N, showing both streams when it is not."""

    def run(*args, cwd=None, check=None, timeout=120):
        argv = [os.fspath(cli)] + [os.fspath(a) for a in args]
        out = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, timeout=timeout)
        if check is not None:
            assert out.returncode == check, (
                f"{' '.join(argv)} exited {out.returncode}, not {check}\nstdout:\n{out.stdout}\nstderr:\n{out.stderr}"
            )
        return out

    return run


@pytest.fixture(scope="session")
def cornell_path(repo_root) -> Path:
    """scenes/cornell-box.gltf: self-contained (data URIs), its light material 'light' at emissiveStrength 17."""
    path = repo_root / "scenes" / "cornell-box.gltf"
    assert path.is_file(), f"{path} is missing"
    return path


@pytest.fixture(scope="session")
def renderer():
    """One renderer for the session: a test that finds another's options leaking into its render catches that."""
    return pathwave.Renderer()


@pytest.fixture(scope="session")
def scene(cornell_path):
    return pathwave.Scene.load(cornell_path)


@pytest.fixture
def ctrl_c():
    """Python's own Ctrl-C handler for the test, as an interactive session has it. A process started in the
    background by a non-interactive shell inherits SIGINT ignored, and Python then installs no handler, so a
    signal the test sends would be dropped and the render run to its end (hours for the tests that interrupt)."""
    import signal

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)

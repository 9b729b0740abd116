"""README's Python example and the Python page of the guide (docs/guide/python.md) run as written: README's renders,
saves and compares; the guide's example renders, plots and saves, its pytest test passes against the golden image
the example saved, and its Ctrl-C block gets a partial film. Catches documentation that has rotted (a renamed
keyword, a changed attribute) while the module's own tests still pass."""

import os
import re
import signal
import threading
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def blocks(page="docs/guide/python.md"):
    return re.findall(r"```python\n(.*?)```", (ROOT / page).read_text(), re.S)


def test_the_pages_have_their_python_blocks():
    """Catches a block dropped or renamed, which the tests below would then silently not run."""
    assert len(blocks()) == 3
    assert len(blocks("README.md")) == 1


def test_the_readme_example_runs(tmp_path, monkeypatch, capsys):
    (tmp_path / "scenes").symlink_to(ROOT / "scenes")
    monkeypatch.chdir(tmp_path)
    (example,) = blocks("README.md")
    exec(compile(example, "README.md: From Python", "exec"), {})
    assert (tmp_path / "cornell-box.exr").stat().st_size > 0
    assert capsys.readouterr().out.splitlines()[-1] == "True"


def test_the_guide_examples_run(tmp_path, monkeypatch, ctrl_c):
    pytest.importorskip("matplotlib")
    os.environ.setdefault("MPLBACKEND", "Agg")
    (tmp_path / "scenes").symlink_to(ROOT / "scenes")
    monkeypatch.chdir(tmp_path)
    example, regression, long_render = blocks()
    names = {}
    exec(compile(example, "python.md: the example", "exec"), names)
    for written in ["cornell-preview.png", "golden.exr", "cornell.png"]:
        assert (tmp_path / written).stat().st_size > 0, written
    exec(compile(regression, "python.md: the pytest block", "exec"), names)
    names["test_cornell_box_matches_its_golden_image"]()
    # The long render, stopped as a reader's Ctrl-C would stop it.
    timer = threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        exec(compile(long_render, "python.md: the long render", "exec"), names)
    finally:
        timer.cancel()
    film = names["film"]
    assert film is not None and 0 < film.spp < 1 << 16

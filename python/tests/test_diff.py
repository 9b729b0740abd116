"""pathwave.diff judges as `pathwave diff` does, on the fixtures of tests/diff.rs
(`the_cli_exits_0_when_consistent_1_when_different_and_2_on_errors`): the same verdicts as the CLI's exit codes,
the same summary as its stdout, the same heat map, and the same error for a missing file."""

from __future__ import annotations

import numpy as np
import pytest

import pathwave
from support import exr_layer, read_exr, read_png

SIZE = "40x30"
SPP = "128"
REJECTED = [0, 255, 0]  # pathwave::diff::HEAT_REJECTED: green where a test rejected


@pytest.fixture(scope="module")
def fixtures(tmp_path_factory, run_cli, cornell_path):
    """The four renders of the Rust test, by the CLI: a (seed 1) and b (seed 2) with film statistics, dark (seed 2,
    --max-depth 1: darker, a real difference) with statistics, plain (seed 3) without: an exact reference."""
    d = tmp_path_factory.mktemp("diff")
    for out, seed, extra in [
        ("a.exr", "1", ["--film-stats"]),
        ("b.exr", "2", ["--film-stats"]),
        ("dark.exr", "2", ["--film-stats", "--max-depth", "1"]),
        ("plain.exr", "3", []),
    ]:
        run_cli("render", cornell_path, "--size", SIZE, "--spp", SPP, "--seed", seed, "-o", out, *extra, cwd=d, check=0)
    return d


# (candidate, reference, Python keywords, CLI options, the exit code tests/diff.rs expects)
CASES = [
    ("a.exr", "b.exr", {}, [], 0),
    ("a.exr", "plain.exr", {}, [], 0),
    ("dark.exr", "a.exr", {}, [], 1),
    ("a.exr", "b.exr", {"plain": True, "max_rel_mse": 1, "max_flip": 1}, ["--plain", "--max-rel-mse", "1", "--max-flip", "1"], 0),
    ("a.exr", "b.exr", {"plain": True, "max_rel_mse": 0}, ["--plain", "--max-rel-mse", "0"], 1),
]


@pytest.mark.parametrize(
    "candidate,reference,keywords,options,expected",
    CASES,
    ids=["two-seeds", "plain-reference", "dark-vs-a", "plain-mode-loose", "plain-mode-zero"],
)
def test_diff_gives_the_cli_verdict_and_summary(
    fixtures, run_cli, monkeypatch, candidate, reference, keywords, options, expected
):
    """Catches a Python diff that reaches another verdict than the CLI (options mapped wrongly, the statistical test
    chosen when plain was asked or the reverse, another alpha or threshold), or reports it differently (summary
    not the CLI's stdout byte for byte); and fixtures that no longer show what the Rust test expects of them."""
    monkeypatch.chdir(fixtures)  # both sides see the same (relative) names
    out = run_cli("diff", candidate, reference, *options, cwd=fixtures)
    assert out.returncode == expected, f"the CLI's verdict changed:\n{out.stdout}{out.stderr}"
    result = pathwave.diff(candidate, reference, **keywords)
    assert result.consistent == (out.returncode == 0)
    assert result.summary == out.stdout
    if keywords.get("plain"):
        assert result.p_value is None and result.rel_mse is not None and result.flip is not None
    else:
        assert 0 <= result.p_value <= 1 and result.alpha == 0.01 and result.rel_mse is None
        assert (result.p_value <= result.alpha) == (not result.consistent)
    with pytest.raises(TypeError):
        bool(result)  # a DiffResult has no truth value: .consistent says it


def test_a_film_against_a_file_is_judged_as_the_file_would_be(fixtures, run_cli, renderer, scene):
    """Catches diff() reading a Film's statistics wrongly (mean, variance or count other than its file's): a Python
    render at seed 2 is b.exr, so against a.exr it must give what `diff b.exr a.exr` prints."""
    film = renderer.render(scene, spp=int(SPP), size=(40, 30), seed=2, film_stats=True)
    channels, _ = read_exr(fixtures / "b.exr")
    assert np.array_equal(film.rgb, exr_layer(channels, "RGB")), "the Python render is not b.exr"
    out = run_cli("diff", "b.exr", "a.exr", cwd=fixtures, check=0)
    result = pathwave.diff(film, fixtures / "a.exr")
    assert result.consistent
    assert result.summary == out.stdout
    # Against the darker render (also seed 2: diff warns that the noise is shared), the film is different.
    with pytest.warns(UserWarning, match="both renders use seed 2"):
        assert not pathwave.diff(film, fixtures / "dark.exr").consistent


def test_heatmap_writes_the_cli_png_with_rejected_pixels(fixtures, run_cli, tmp_path):
    """Catches a heat map of the wrong size or orientation, without the rejected pixels drawn, unlike the CLI's
    `--heatmap` file, or an array that is not the PNG written (decoded here, not by pathwave)."""
    run_cli("diff", fixtures / "dark.exr", fixtures / "a.exr", "--heatmap", tmp_path / "cli.png", check=1)
    result = pathwave.diff(fixtures / "dark.exr", fixtures / "a.exr")
    assert not result.consistent
    array = result.heatmap(tmp_path / "heat.png")
    assert array.dtype == np.uint8 and array.shape == (30, 40, 3)
    png = read_png(tmp_path / "heat.png")
    assert png.shape == (30, 40, 3)
    assert np.array_equal(png, array)
    assert np.all(png == REJECTED, axis=-1).any(), "no rejected pixel drawn"
    assert (tmp_path / "heat.png").read_bytes() == (tmp_path / "cli.png").read_bytes()
    # The worst tests say where: each within the image, rejected ones at or below the threshold.
    worst = result.worst
    assert worst and all(0 <= w["x"] < 40 and 0 <= w["y"] < 30 and w["channel"] in "RGB" for w in worst)
    assert worst[0]["p"] <= result.alpha


def test_a_missing_file_raises_input_error_naming_it(fixtures, run_cli, monkeypatch, tmp_path):
    """Catches a missing film file reported as another kind of error, without its name, or with another message
    than the CLI's (which exits 2 and writes no heat map)."""
    monkeypatch.chdir(fixtures)
    out = run_cli("diff", "a.exr", "missing.exr", "--heatmap", tmp_path / "x.png", cwd=fixtures, check=2)
    assert not (tmp_path / "x.png").exists()
    with pytest.raises(pathwave.InputError) as info:
        pathwave.diff("a.exr", "missing.exr")
    assert "missing.exr" in str(info.value)
    assert str(info.value) == out.stderr.splitlines()[0].removeprefix("error: ")
    with pytest.raises(pathwave.InputError, match="missing.exr"):
        pathwave.diff("missing.exr", "a.exr")

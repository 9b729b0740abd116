"""Ctrl-C during a render raises pathwave.Interrupted holding a valid partial film; the progress callback hears
every pass."""

from __future__ import annotations

import os
import signal
import threading

import numpy as np
import pytest

import pathwave
from support import film_meta, read_exr

SIZE = (32, 24)


def test_ctrl_c_raises_interrupted_with_a_valid_partial_film(
    renderer, scene, run_cli, cornell_path, tmp_path, ctrl_c
):
    """Catches Ctrl-C ignored until the render ends (2^16 spp here: minutes), raised as a plain KeyboardInterrupt
    or an Error, losing the samples done (no .film), or a partial film that is not valid: a sample count other
    than film.spp in some pixel, non-finite pixels, a file `pathwave diff` refuses (exit 2), or a file whose
    counts and sample range (read by OpenEXR) are not the film's."""
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler, "Python's own Ctrl-C handler is needed"
    spp = 1 << 16
    run_cli(
        "render", cornell_path, "--size", "32x24", "--spp", "64", "--seed", "6", "--film-stats", "-o", "full.exr",
        cwd=tmp_path, check=0,
    )
    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(pathwave.Interrupted) as info:
            renderer.render(scene, spp=spp, size=SIZE, seed=5, film_stats=True)
    finally:
        timer.cancel()
        timer.join()
    error = info.value
    assert isinstance(error, KeyboardInterrupt) and not isinstance(error, pathwave.Error)
    film = error.film
    assert film is not None, f"no film in {error!r}"
    assert isinstance(film, pathwave.Film)
    assert 0 < film.spp < spp, film.spp
    assert f"{film.spp} of {spp}" in str(error)
    assert (film.width, film.height) == SIZE
    assert film.stats["interrupted"] is True
    assert np.all(film.count == film.spp)
    assert np.all(np.isfinite(film.rgb)) and film.rgb.max() > 0
    assert np.all(np.isfinite(film.mean)) and np.all(np.isfinite(film.variance))

    film.save(tmp_path / "partial.exr")
    channels, header = read_exr(tmp_path / "partial.exr")
    assert np.all(channels["pathwave.count"] == film.spp)
    assert film_meta(header)["samples"] == [[0, film.spp]]
    out = run_cli("diff", "partial.exr", "full.exr", cwd=tmp_path)
    assert out.returncode in (0, 1), f"diff refused the partial film:\n{out.stdout}{out.stderr}"
    assert out.stdout.startswith(("CONSISTENT", "DIFFERENT"))


def test_progress_hears_every_pass_up_to_the_total(renderer, scene):
    """Catches a progress callback never called, called with another total, with done going backwards or
    repeating, called fewer or more times than there were passes, or not ending at the total for a render that
    ran to its end."""
    spp = 1400  # two passes on lavapipe (a pass holds about a million paths: 1365 spp at 32x24)
    calls = []
    film = renderer.render(scene, spp=spp, size=SIZE, seed=4, progress=lambda done, total: calls.append((done, total)))
    assert film.spp == spp and film.stats["interrupted"] is False
    assert len(calls) == film.stats["passes"]
    assert len(calls) >= 2, f"one pass only ({calls}): nothing shows done increasing; raise spp"
    assert all(total == spp for _, total in calls)
    done = [d for d, _ in calls]
    assert all(0 < a < b for a, b in zip(done, done[1:])), done
    assert done[-1] == spp


def test_an_exception_in_the_progress_callback_ends_the_render_and_propagates(renderer, scene):
    """Catches an exception raised in the callback swallowed (the render going on to its end) or replaced by
    another."""

    class Stop(Exception):
        pass

    calls = []

    def progress(done, total):
        calls.append(done)
        raise Stop(done)

    with pytest.raises(Stop):
        renderer.render(scene, spp=1400, size=SIZE, seed=4, progress=progress)
    assert len(calls) == 1


def test_ctrl_c_during_the_last_pass_keeps_the_whole_film(renderer, scene):
    """Catches a Ctrl-C that lands in the last pass throwing away a complete film (Interrupted with .film None):
    the KeyboardInterrupt is raised where Python runs the handler, here the callback of the last pass, which is
    deterministic where a timed signal is not."""

    def progress(done, total):
        if done == total:
            raise KeyboardInterrupt

    with pytest.raises(pathwave.Interrupted) as info:
        renderer.render(scene, spp=64, size=SIZE, seed=4, film_stats=True, progress=progress)
    film = info.value.film
    assert film is not None and film.spp == 64
    assert np.all(film.count == 64)

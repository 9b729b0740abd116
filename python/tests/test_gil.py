"""A render releases the GIL: other Python threads keep running while the device works."""

from __future__ import annotations

import threading
import time

import numpy as np


def test_another_thread_runs_throughout_a_render(renderer, scene):
    """Catches a render that holds the GIL (every other Python thread frozen until it returns: a GUI, a progress
    bar, a server): a counter thread must advance in every tenth of a render of about a second, not only at its
    ends or at pass boundaries, where the module takes the GIL back briefly."""
    renderer.render(scene, spp=4, size=(32, 24), seed=8)  # the pipelines built, so the render below is rendering
    ticks = []
    stop = threading.Event()

    def count():
        n = 0
        while not stop.is_set():
            n += 1
            if n % 1000 == 0:
                ticks.append(time.perf_counter())

    thread = threading.Thread(target=count, daemon=True)
    thread.start()
    try:
        time.sleep(0.05)
        start = time.perf_counter()
        film = renderer.render(scene, spp=1365, size=(32, 24), seed=8)
        end = time.perf_counter()
    finally:
        stop.set()
        thread.join()
    assert film.spp == 1365
    assert end - start > 0.3, f"the render took {end - start:.2f} s: too short to tell"
    during = np.array([t for t in ticks if start < t < end])
    per_tenth = np.histogram(during, bins=10, range=(start, end))[0]
    assert len(during) * 1000 > 100_000, f"{len(during) * 1000} increments in {end - start:.2f} s of render"
    assert np.all(per_tenth > 0), f"the counter stood still in part of the render: thousands per tenth {per_tenth}"

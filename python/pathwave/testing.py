"""Assertions for test suites: a render against a golden image, judged by pathwave's statistical test."""

from __future__ import annotations

import os
import tempfile
from typing import Optional, Union

from ._pathwave import DiffResult, Film, diff

Side = Union[Film, str, "os.PathLike[str]"]


def _name(side: Side) -> str:
    if isinstance(side, Film):
        return repr(side)
    return os.fspath(side)


def _heatmap_path(candidate: Side) -> str:
    """Beside a candidate file (render.exr: render.diff.png), else in the temporary folder."""
    if not isinstance(candidate, Film):
        root, _ = os.path.splitext(os.fspath(candidate))
        return root + ".diff.png"
    handle, path = tempfile.mkstemp(prefix="pathwave-diff-", suffix=".png")
    os.close(handle)
    return path


def assert_consistent(
    candidate: Side,
    reference: Side,
    *,
    alpha: float = 0.01,
    heatmap: Optional[Union[str, "os.PathLike[str]"]] = None,
    **options,
) -> DiffResult:
    """Passes when `candidate` and `reference` are consistent as `pathwave diff` judges them (a per-pixel
    statistical test at family-wise false-positive rate `alpha` when either carries film statistics, else relMSE
    and FLIP against `max_rel_mse` and `max_flip`); returns the result.

    On failure, raises AssertionError stating the verdict and what it rests on (the p-value and the worst pixels),
    and saves the heat map of where they differ to `heatmap` (default: beside a candidate file as NAME.diff.png,
    or in the temporary folder), naming it in the message.
    """
    __tracebackhide__ = True  # pytest shows the caller's line, not this one
    result = diff(candidate, reference, alpha=alpha, **options)
    if result.consistent:
        return result
    path = os.fspath(heatmap) if heatmap is not None else _heatmap_path(candidate)
    result.heatmap(path)
    raise AssertionError(
        f"{_name(candidate)} is not consistent with {_name(reference)}:\n"
        f"{result.summary.rstrip()}\n"
        f"heat map of where they differ: {path}"
    )

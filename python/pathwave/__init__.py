"""pathwave: a physically based wavefront path tracer on Vulkan compute, from Python.

Load a glTF scene, render it on any Vulkan device (a GPU, or Mesa's lavapipe on a CPU), get the image as a numpy
array, save it exactly as `pathwave render` writes it, and compare renders with the statistical test of
`pathwave diff`:

    import pathwave
    scene = pathwave.Scene.load("scenes/cornell-box.gltf")
    film = pathwave.Renderer().render(scene, spp=64, size=(256, 256), film_stats=True)
    film.rgb            # float32, (256, 256, 3), linear
    film.save("cornell.exr")
    pathwave.diff(film, "golden.exr").consistent

The options are `pathwave render`'s, as keywords (`max_depth=3` is `--max-depth 3`); see docs/guide/python.md.
"""

from ._pathwave import (
    DeviceError,
    DiffResult,
    Error,
    Film,
    InputError,
    Interrupted,
    LimitError,
    Renderer,
    Scene,
    SettingsError,
    ShaderError,
    __version__,
    devices,
    diff,
)
from . import testing

__all__ = [
    "DeviceError",
    "DiffResult",
    "Error",
    "Film",
    "InputError",
    "Interrupted",
    "LimitError",
    "Renderer",
    "Scene",
    "SettingsError",
    "ShaderError",
    "__version__",
    "devices",
    "diff",
    "testing",
]

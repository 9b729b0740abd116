# Types of the extension module; the options are `pathwave render`'s (docs/guide/rendering.md), as keywords.
import os
from typing import Any, Callable, Literal, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str
PathLike = Union[str, "os.PathLike[str]"]
Triple = Tuple[float, float, float]

class Error(Exception):
    """Every error pathwave raises, with the command line's message."""

class InputError(Error):
    """A file that cannot be read or is not valid (scene, image, film file)."""

class SettingsError(Error):
    """An option out of its range, or options that do not go together."""

class LimitError(Error):
    """Work or memory past a limit (max_memory, the device's memory)."""

class DeviceError(Error):
    """The Vulkan device failed, or the validation layer reported errors."""

class ShaderError(Error):
    """A user shader that does not compile."""

class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a render, raised after the pass under way; `film` holds the samples done (None before the
    first pass ended)."""

    film: Optional[Film]

class Scene:
    @staticmethod
    def load(
        path: PathLike,
        *,
        variant: Optional[str] = None,
        time: Optional[float] = None,
        animation: Optional[Union[int, str]] = None,
        shutter: Optional[float] = None,
        camera: Optional[int] = None,
        max_memory: Optional[Union[int, str]] = None,
        max_texture_pixels: Optional[int] = None,
        allow_outside_paths: bool = False,
        strict: bool = False,
    ) -> Scene:
        """Reads a glTF (.gltf or .glb) file as `pathwave render` does, posed at `time` (seconds) with `animation`,
        blurred over `shutter` seconds. The loader's limits: `max_memory` (bytes, or "512M", "8G"),
        `max_texture_pixels`, `allow_outside_paths` (URIs leaving the scene's folder), `strict` (refuse missing
        images)."""
    @property
    def path(self) -> str: ...
    def info(self) -> dict[str, Any]:
        """What `pathwave info` reports: counts (triangles, materials, cameras, ...), variants, animations,
        extensions used, warnings, and `report`, the command's lines by label."""

class Film:
    @staticmethod
    def load(path: PathLike) -> Film:
        """Reads a film file (an EXR from `pathwave render`, `merge`, or any RGB EXR)."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def spp(self) -> int:
        """Samples per pixel the film holds (fewer than asked after an interrupt)."""
    @property
    def rgb(self) -> npt.NDArray[np.float32]:
        """Linear RGB radiance, shape (height, width, 3), top row first; denoised with denoise=True."""
    @property
    def aovs(self) -> dict[str, npt.NDArray[Any]]:
        """The AOVs asked for with aov=[...], by name: float32 (height, width[, channels]), uint32 for ids and
        sample counts."""
    @property
    def mean(self) -> Optional[npt.NDArray[np.float64]]:
        """Per pixel and channel, the samples' mean from the exact sums (film_stats=True)."""
    @property
    def variance(self) -> Optional[npt.NDArray[np.float64]]:
        """Per pixel and channel, the unbiased variance of one sample (film_stats=True)."""
    @property
    def count(self) -> Optional[npt.NDArray[np.uint32]]:
        """Per pixel, the samples taken, shape (height, width) (film_stats=True)."""
    @property
    def stats(self) -> Optional[dict[str, Any]]:
        """How the render went: wall, passes, samples, extension_rays, shadow_rays, samples_per_sec, interrupted,
        device, stage_ms, summary."""
    def save(
        self,
        path: PathLike,
        *,
        exposure: Optional[float] = None,
        tonemap: Optional[Literal["none", "aces", "agx", "pbr-neutral"]] = None,
    ) -> list[str]:
        """Writes what `pathwave render -o PATH` writes with the render's options (EXR or PNG by the extension);
        returns every path written."""

class Renderer:
    def __init__(
        self,
        device: Optional[Union[int, str]] = None,
        *,
        traversal: Optional[Literal["auto", "compute", "ray-query"]] = None,
    ) -> None:
        """A renderer on a Vulkan device, by index or part of its name (`devices()` lists them)."""
    def render(
        self,
        scene: Scene,
        *,
        spp: int = 64,
        size: Tuple[int, int] = (512, 512),
        seed: int = 0,
        camera: Optional[Union[int, Mapping[str, Union[Triple, float]]]] = None,
        progress: Optional[Callable[[int, int], None]] = None,
        max_depth: Optional[int] = None,
        aperture: float = 0.0,
        focus_distance: Optional[float] = None,
        spectral: bool = False,
        rgb: bool = False,
        light_sampler: Literal["bvh", "power", "uniform"] = "bvh",
        texture_filter: Literal["trilinear", "bilinear"] = "trilinear",
        env: Optional[PathLike] = None,
        env_color: Optional[Triple] = None,
        env_intensity: float = 1.0,
        env_rotation: float = 0.0,
        hide_env: bool = False,
        aov: Optional[Sequence[str]] = None,
        film_stats: bool = False,
        samples: Optional[Tuple[int, int]] = None,
        alpha: bool = False,
        exposure: float = 0.0,
        tonemap: Literal["none", "aces", "agx", "pbr-neutral"] = "none",
        denoise: bool = False,
        adaptive: bool = False,
        noise_threshold: float = 0.01,
        min_spp: int = 16,
        estimator: Literal["mis", "light", "bsdf"] = "mis",
        no_energy_compensation: bool = False,
    ) -> Film:
        """Renders `scene` as `pathwave render` does with the same options, the GIL released. `camera` is a file
        camera's index or a mapping of eye, target, up, yfov, orbit. `progress(done, total)` is called after each
        pass; Ctrl-C ends the render after its pass and raises Interrupted holding the film."""

class DiffResult:
    @property
    def consistent(self) -> bool: ...
    @property
    def p_value(self) -> Optional[float]:
        """The family-wise p-value of the statistical test (None for a plain comparison)."""
    @property
    def alpha(self) -> Optional[float]: ...
    @property
    def rel_mse(self) -> Optional[float]: ...
    @property
    def flip(self) -> Optional[float]: ...
    @property
    def worst(self) -> list[dict[str, Any]]:
        """The lowest-p tests: x, y, size, channel, candidate, reference, stat, df, p."""
    @property
    def summary(self) -> str:
        """What `pathwave diff` prints."""
    def heatmap(self, path: Optional[PathLike] = None) -> npt.NDArray[np.uint8]:
        """Where they differ, as sRGB (height, width, 3); also written as a PNG to `path` when given."""

def diff(
    candidate: Union[Film, PathLike],
    reference: Union[Film, PathLike],
    *,
    alpha: float = 0.01,
    plain: bool = False,
    max_rel_mse: float = 0.001,
    max_flip: float = 0.05,
    worst: int = 10,
) -> DiffResult:
    """Compares as `pathwave diff` does: a per-pixel statistical test when either side carries film statistics,
    else relMSE and FLIP against the thresholds."""

def devices() -> list[dict[str, Any]]:
    """The Vulkan devices (index, name, kind, driver, ray_queries), as `pathwave info --devices` lists them."""

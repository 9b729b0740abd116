"""A Python render equals `pathwave render`'s with the same options: its arrays against the CLI's EXR read by
OpenEXR, and Film.save against the CLI's files byte for byte (EXR, PNG, film file, AOVs and statistics)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np

import pathwave
from support import exact_sums, exr_layer, film_meta, read_exr, read_png, srgb8

SIZE = (40, 30)
SPP = 16
SEED = 3
CLI_SETTINGS = ["--size", "40x30", "--spp", str(SPP), "--seed", str(SEED)]


def _bytes(path):
    return path.read_bytes()


def test_rgb_and_saved_exr_and_png_equal_the_cli_byte_for_byte(renderer, scene, run_cli, cornell_path, tmp_path):
    """Catches a Python render that is not the CLI's (other defaults, another seed or sample order, options mapped
    wrongly to the command line), an rgb array of the wrong dtype, shape, row order or channel order (checked
    against OpenEXR's reading of the CLI's file), and Film.save writing other bytes than `render -o` (EXR
    compression, attributes, PNG encoding)."""
    run_cli("render", cornell_path, *CLI_SETTINGS, "-o", "a.exr", cwd=tmp_path, check=0)
    run_cli("render", cornell_path, *CLI_SETTINGS, "-o", "a.png", cwd=tmp_path, check=0)

    film = renderer.render(scene, spp=SPP, size=SIZE, seed=SEED)
    assert (film.width, film.height, film.spp) == (40, 30, SPP)

    channels, _ = read_exr(tmp_path / "a.exr")
    reference = exr_layer(channels, "RGB")
    assert reference.dtype == np.float32 and reference.shape == (30, 40, 3)
    rgb = film.rgb
    assert rgb.dtype == np.float32, rgb.dtype
    assert rgb.shape == (30, 40, 3), rgb.shape
    assert np.array_equal(rgb, reference), f"max |diff| {np.abs(rgb - reference).max()}"
    assert rgb.max() > 0, "a black image would match a black reference trivially"

    written = film.save(tmp_path / "b.exr")
    assert [str(p) for p in written] == [str(tmp_path / "b.exr")]
    assert _bytes(tmp_path / "b.exr") == _bytes(tmp_path / "a.exr")

    film.save(tmp_path / "b.png")
    assert _bytes(tmp_path / "b.png") == _bytes(tmp_path / "a.png")
    # And the PNG is the image: 8-bit sRGB of the linear pixels (decoded here, not by pathwave).
    png = read_png(tmp_path / "b.png")
    assert png.shape == (30, 40, 3)
    assert np.abs(png.astype(np.float64) - srgb8(rgb)).max() <= 1


def test_a_film_stats_render_saves_the_cli_film_file_byte_for_byte(renderer, scene, run_cli, cornell_path, tmp_path):
    """Catches Film.save of a film_stats render differing from `render --film-stats`: the exact sums' words, the
    count, or the `pathwave` header (fingerprints of scene, settings and shaders, seed, sample ranges, options)
    built from other options than the CLI's; and film.rgb not being the file's mean."""
    run_cli("render", cornell_path, *CLI_SETTINGS, "--film-stats", "-o", "a.exr", cwd=tmp_path, check=0)
    film = renderer.render(scene, spp=SPP, size=SIZE, seed=SEED, film_stats=True)
    film.save(tmp_path / "b.exr")
    a, b = _bytes(tmp_path / "a.exr"), _bytes(tmp_path / "b.exr")
    if a != b:
        ca, ha = read_exr(tmp_path / "a.exr")
        cb, hb = read_exr(tmp_path / "b.exr")
        differing = [k for k in set(ha) | set(hb) if str(ha.get(k)) != str(hb.get(k))]
        channels = [k for k in set(ca) | set(cb) if k not in ca or k not in cb or not np.array_equal(ca[k], cb[k])]
        raise AssertionError(f"film files differ: header attributes {differing}, channels {sorted(channels)}")
    channels, header = read_exr(tmp_path / "a.exr")
    assert np.array_equal(film.rgb, exr_layer(channels, "RGB"))
    assert film_meta(header)["samples"] == [[0, SPP]]


def test_a_renderer_reused_after_other_options_renders_the_cli_bytes(renderer, scene, run_cli, cornell_path, tmp_path):
    """Catches state of an earlier render leaking into the next on the same Renderer (the scene kept on the device
    with another camera or environment, the light sampler, depth limit, AOV buffers, exact film or spectral mode
    of the previous render)."""
    run_cli("render", cornell_path, *CLI_SETTINGS, "-o", "a.exr", cwd=tmp_path, check=0)
    renderer.render(
        scene,
        spp=4,
        size=(24, 16),
        seed=9,
        max_depth=1,
        light_sampler="uniform",
        estimator="bsdf",
        spectral=True,
        aov=["albedo"],
        film_stats=True,
        camera={"orbit": (30, 10, 4)},
        env_color=(0.2, 0.3, 0.4),
    )
    film = renderer.render(scene, spp=SPP, size=SIZE, seed=SEED)
    channels, _ = read_exr(tmp_path / "a.exr")
    assert np.array_equal(film.rgb, exr_layer(channels, "RGB"))


def test_aovs_and_film_statistics_match_the_cli_exr(renderer, scene, run_cli, cornell_path, tmp_path):
    """Catches AOVs that differ from the CLI's layers (wrong AOV, channel order, dtype, row order, or a depth or
    sample count taken from another render), and film statistics (mean, variance, count) that do not follow from
    the exact sums the CLI writes: mean = sum / count and the unbiased variance (sum of squares - sum^2 / n) /
    (n - 1), computed here exactly from the file's fixed-point words."""
    aovs = ["albedo", "normal", "depth", "sample-count"]
    run_cli(
        "render",
        cornell_path,
        *CLI_SETTINGS,
        "--aov",
        ",".join(aovs),
        "--film-stats",
        "-o",
        "a.exr",
        cwd=tmp_path,
        check=0,
    )
    film = renderer.render(scene, spp=SPP, size=SIZE, seed=SEED, aov=aovs, film_stats=True)
    channels, header = read_exr(tmp_path / "a.exr")
    assert set(film.aovs) == set(aovs)
    # The layers the CLI's EXR holds (docs: albedo.R, normal.X, depth.Z, ...).
    expected = {
        "albedo": ["albedo.R", "albedo.G", "albedo.B"],
        "normal": ["normal.X", "normal.Y", "normal.Z"],
        "depth": ["depth.Z"],
        "sample-count": ["sample-count.N"],
    }
    for name, layers in expected.items():
        array = film.aovs[name]
        reference = exr_layer(channels, layers)
        if len(layers) == 1:
            reference = reference[..., 0]
        assert array.dtype == reference.dtype, (name, array.dtype, reference.dtype)
        assert array.shape == reference.shape, (name, array.shape, reference.shape)
        assert np.array_equal(array, reference), name
    assert film.aovs["sample-count"].dtype == np.uint32
    assert np.any(film.aovs["albedo"] > 0) and np.any(film.aovs["depth"] > 0)
    # Pixel means of unit normals: never longer than 1, unit inside flat walls (a third of the image at least).
    lengths = np.linalg.norm(film.aovs["normal"], axis=-1)
    assert lengths.max() <= 1 + 1e-4
    assert np.mean(np.abs(lengths - 1) < 1e-3) > 1 / 3

    # Statistics: the count is the sample-count AOV and the file's count, every pixel spp.
    count = film.count
    assert count.dtype == np.uint32 and count.shape == (30, 40)
    assert np.array_equal(count, film.aovs["sample-count"])
    assert np.array_equal(count, channels["pathwave.count"])
    assert np.all(count == SPP) and film.spp == SPP
    assert film_meta(header)["samples"] == [[0, SPP]]

    mean, variance = film.mean, film.variance
    assert mean.dtype == np.float64 and mean.shape == (30, 40, 3)
    assert variance.dtype == np.float64 and variance.shape == (30, 40, 3)
    assert np.all(np.isfinite(variance)) and np.all(variance >= 0)
    assert np.any(variance > 0)
    # The mean agrees with the EXR's RGB to float32 rounding (and film.rgb is that RGB).
    rgb = exr_layer(channels, "RGB")
    assert np.array_equal(mean.astype(np.float32), rgb)
    assert np.array_equal(film.rgb, rgb)

    # Against the exact sums in the file: mean * count = sum, and the variance from sum and sum of squares.
    n, sums, squares = exact_sums(channels)
    for y in range(30):
        for x in range(40):
            k = int(n[y, x])
            for c in range(3):
                s, q = sums[y][x][c], squares[y][x][c]
                exact_mean = float(s / k)
                assert abs(mean[y, x, c] - exact_mean) <= 1e-14 * abs(exact_mean) + 1e-300, (x, y, c)
                exact_var = max(Fraction(0), (q - s * s / k) / (k - 1))
                # The module takes the variance in float64 from the sums, so it cancels to q's rounding: allow
                # 1e-12 of the sum of squares' scale.
                tolerance = 1e-9 * float(exact_var) + 1e-12 * float(q) / (k - 1)
                assert abs(variance[y, x, c] - float(exact_var)) <= tolerance, (x, y, c, variance[y, x, c], exact_var)

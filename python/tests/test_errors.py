"""Failures raise pathwave's exception classes with the command line's messages: a missing scene, bad option values,
unknown keywords, a scene over the memory limit."""

from __future__ import annotations

import pytest

import pathwave


def _cli_message(out) -> str:
    """The CLI's error: its stderr without "error: " and clap's usage hint (the possible values stay)."""
    text = out.stderr
    assert text.startswith("error: "), text
    return text[len("error: ") :].split("\n\nFor more information")[0].strip()


def test_the_exception_classes_form_one_family():
    """Catches an exception class outside pathwave.Error (so `except pathwave.Error` would miss it), or Interrupted
    not being a KeyboardInterrupt (so Ctrl-C handling would swallow it as an error)."""
    for kind in [
        pathwave.InputError,
        pathwave.SettingsError,
        pathwave.LimitError,
        pathwave.DeviceError,
        pathwave.ShaderError,
    ]:
        assert issubclass(kind, pathwave.Error) and kind is not pathwave.Error
    assert issubclass(pathwave.Error, Exception)
    assert issubclass(pathwave.Interrupted, KeyboardInterrupt)
    assert not issubclass(pathwave.Interrupted, Exception)


def test_a_missing_scene_raises_input_error_naming_it(run_cli, tmp_path):
    """Catches a missing scene file reported as another kind of error, without its path, or with another message
    than `pathwave render`'s."""
    missing = tmp_path / "nothere.gltf"
    with pytest.raises(pathwave.InputError) as info:
        pathwave.Scene.load(missing)
    assert str(missing) in str(info.value)
    out = run_cli("render", missing, "-o", tmp_path / "x.exr", check=1)
    assert str(info.value) == _cli_message(out)
    assert not (tmp_path / "x.exr").exists()


# (keywords, the CLI's spelling of the same value)
BAD_VALUES = [
    ({"spp": -1}, ["--spp", "-1"]),
    ({"size": (0, 5)}, ["--size", "0x5"]),
    ({"light_sampler": "nope"}, ["--light-sampler", "nope"]),
    ({"aov": ["nope"]}, ["--aov", "nope"]),
]


@pytest.mark.parametrize("keywords,options", BAD_VALUES, ids=["spp", "size", "light_sampler", "aov"])
def test_a_bad_option_value_raises_settings_error_with_the_cli_message(
    renderer, scene, run_cli, cornell_path, tmp_path, keywords, options
):
    """Catches a bad value accepted (rendered anyway), raised as another class, or worded otherwise than the CLI's
    first line for the same option (keywords mapped to other options, or values spelled otherwise)."""
    with pytest.raises(pathwave.SettingsError) as info:
        renderer.render(scene, **{"spp": 4, "size": (8, 6), "seed": 1, **keywords})
    out = run_cli("render", cornell_path, "-o", tmp_path / "x.exr", *options, check=2)
    assert str(info.value) == _cli_message(out)
    assert not (tmp_path / "x.exr").exists()


def test_an_unknown_keyword_raises_type_error(renderer, scene, cornell_path):
    """Catches an unknown keyword silently ignored or turned into an option error (a typo like max_dept=3 must not
    render with the default), and options given to the wrong call accepted."""
    with pytest.raises(TypeError, match="max_dept") as info:
        renderer.render(scene, spp=4, size=(8, 6), max_dept=3)
    assert not isinstance(info.value, pathwave.Error)
    with pytest.raises(TypeError, match="time"):
        renderer.render(scene, spp=4, size=(8, 6), time=1.0)  # a Scene.load option
    with pytest.raises(TypeError, match="bogus"):
        pathwave.Scene.load(cornell_path, bogus=1)
    with pytest.raises(TypeError, match="bogus"):
        pathwave.diff(cornell_path, cornell_path, bogus=1)


def test_an_oversized_scene_raises_limit_error(run_cli, cornell_path, tmp_path):
    """Catches max_memory ignored by Scene.load, or its refusal raised as another class or worded otherwise than
    the CLI's."""
    with pytest.raises(pathwave.LimitError) as info:
        pathwave.Scene.load(cornell_path, max_memory="1K")
    assert "--max-memory" in str(info.value)
    out = run_cli("render", cornell_path, "--max-memory", "1K", "-o", tmp_path / "x.exr", check=1)
    assert str(info.value) == _cli_message(out)
    # The limit, not the scene, refused it: with room it loads.
    assert pathwave.Scene.load(cornell_path, max_memory="1M").info()["triangles"] == 32


def test_true_or_false_for_an_option_that_takes_a_value_is_refused(renderer, scene):
    """Catches max_depth=True passed on as a bare --max-depth, which swallowed the next option as its value (the
    error then named the wrong option), or False silently dropped (rendering with the default)."""
    for keywords in [{"max_depth": True, "exposure": -2}, {"max_depth": False}]:
        with pytest.raises(pathwave.SettingsError, match="max_depth=(True|False): --max-depth takes a value"):
            renderer.render(scene, spp=4, size=(8, 6), **keywords)


def test_an_empty_aov_list_asks_for_none(renderer, scene):
    """Catches aov=[] refused as an empty --aov value instead of meaning no AOVs."""
    assert renderer.render(scene, spp=4, size=(8, 6), aov=[]).aovs == {}

"""pathwave.testing.assert_consistent: a real 3 % regression fails with a readable message and a heat map, and the
same scene at another seed passes."""

from __future__ import annotations

import json

import pytest

import pathwave
from pathwave.testing import assert_consistent
from support import read_png

SIZE = (48, 36)
# At 512 spp the 3 % brighter light is caught with a family-wise p-value of 1.5e-14 at seeds 2 against 1 (and
# between 1e-10 and 8e-19 for six other seed pairs tried, 100/101 .. 110/111), 8 orders of magnitude or more below
# alpha 0.01; the unchanged pair's p-value is 1.0. At 256 spp it was 9e-6, at 128 spp 0.02: not caught.
SPP = 512


@pytest.fixture(scope="module")
def renders(cornell_path, renderer, scene, tmp_path_factory):
    """The reference (seed 1), the unchanged scene at seed 2, and the scene with the light's emissiveStrength times
    1.03 (the whole image 3 % brighter) at seed 2, all with film statistics."""
    gltf = json.loads(cornell_path.read_text())
    (light,) = [m for m in gltf["materials"] if m["name"] == "light"]
    strength = light["extensions"]["KHR_materials_emissive_strength"]
    assert strength["emissiveStrength"] == 17
    strength["emissiveStrength"] *= 1.03
    path = tmp_path_factory.mktemp("brighter") / "cornell-box-brighter.gltf"
    path.write_text(json.dumps(gltf))
    brighter = pathwave.Scene.load(path)
    reference = renderer.render(scene, spp=SPP, size=SIZE, seed=1, film_stats=True)
    same = renderer.render(scene, spp=SPP, size=SIZE, seed=2, film_stats=True)
    changed = renderer.render(brighter, spp=SPP, size=SIZE, seed=2, film_stats=True)
    # The change is what it says: about 3 % more light over the image.
    ratio = changed.rgb.mean() / reference.rgb.mean()
    assert 1.01 < ratio < 1.05, ratio
    return reference, same, changed


def test_a_three_percent_brighter_light_fails_with_a_readable_message(renders, tmp_path):
    """Catches an assertion too weak to see a 3 % regression, or one whose failure does not say why: the message
    must state the verdict ("not consistent"), the p-value it rests on, and where the heat map was saved (which
    must exist, as a PNG of the image's size)."""
    reference, _, changed = renders
    with pytest.warns(UserWarning, match="different scenes"):
        result = pathwave.diff(changed, reference)
    assert not result.consistent, result.summary
    heat = tmp_path / "heat.png"
    with pytest.warns(UserWarning, match="different scenes"):
        with pytest.raises(AssertionError) as info:
            assert_consistent(changed, reference, heatmap=heat)
    message = str(info.value)
    assert "not consistent" in message
    (p_line,) = [line for line in result.summary.splitlines() if line.startswith("family-wise p-value")]
    assert p_line in message
    assert f"heat map of where they differ: {heat}" in message
    assert heat.is_file()
    assert read_png(heat).shape == (36, 48, 3)


def test_a_failing_candidate_file_gets_its_heat_map_beside_it(renders, tmp_path):
    """Catches the default heat map path going astray: for a candidate file NAME.exr it is NAME.diff.png beside it,
    named in the message."""
    reference, _, changed = renders
    changed.save(tmp_path / "candidate.exr")
    with pytest.warns(UserWarning):
        with pytest.raises(AssertionError) as info:
            assert_consistent(tmp_path / "candidate.exr", reference)
    heat = tmp_path / "candidate.diff.png"
    assert heat.is_file()
    assert str(heat) in str(info.value)
    assert str(tmp_path / "candidate.exr") in str(info.value)


def test_the_unchanged_scene_at_another_seed_passes(renders):
    """Catches an assertion that calls noise a regression: the same scene at seeds 2 and 1 passes and returns the
    consistent result."""
    reference, same, _ = renders
    result = assert_consistent(same, reference)
    assert result.consistent and result.p_value > 0.01

"""Underside evidence: the frontal gate tells a car rolled about its length axis by its floor."""

from __future__ import annotations

import numpy as np
import pytest

from frontal3d.eval_gate import evaluate_gate
from frontal3d.plugins import Plugins
from frontal3d.stages.underside import floor_band
from shapes import box_car_meshes

LENGTH = 300
#: Rows of the side outline: its top (roof) and bottom (sill) in a 200 x 340 frame.
TOP, BOTTOM = 40, 140


def _side(paint: float = 70.0) -> tuple[np.ndarray, np.ndarray]:
    """A side-like outline, ``LENGTH`` long, of one shade of paint; and its lightness map."""
    mask = np.zeros((200, LENGTH + 40), bool)
    mask[TOP:BOTTOM + 1, 20:20 + LENGTH] = True
    return np.where(mask, paint, 0.0).astype(np.float32), mask


def _band(lightness: np.ndarray, mask: np.ndarray, **ceiling) -> float:
    return floor_band(lightness, mask, 100, 240, **ceiling).band


def test_a_plain_side_shows_no_floor():
    assert _band(*_side()) == 0.0


def test_a_dark_band_ending_in_a_step_is_a_floor_as_tall_as_the_band():
    lightness, mask = _side()
    lightness[BOTTOM - 59 : BOTTOM + 1, 20 : 20 + LENGTH] = 40.0  # 60 rows: 0.2 of the length, a 30° roll
    assert _band(lightness, mask) == pytest.approx(0.2, abs=0.01)


def test_a_side_darkening_smoothly_towards_the_sill_is_no_floor():
    # Light from above: the lower side darkens by 30 L over 60 rows, with no edge anywhere.
    lightness, mask = _side()
    rows = np.arange(lightness.shape[0])[:, None]
    lightness[mask] = (70.0 - 30.0 * np.clip((rows - (BOTTOM - 60)) / 60.0, 0, 1) * np.ones_like(lightness))[mask]
    assert _band(lightness, mask) == 0.0


def test_a_side_below_lighter_windows_is_no_floor():
    """Paint darker than the windows above it: a band ending in a step, but the step is the windows' edge."""
    lightness, mask = _side(paint=40.0)
    lightness[TOP : BOTTOM - 59, 20 : 20 + LENGTH] = 75.0
    ceiling = np.full(mask.shape[1], BOTTOM - 60)
    assert _band(lightness, mask) > 0.15  # without knowing where the windows are, it looks like a floor
    assert _band(lightness, mask, ceiling=ceiling) == 0.0


def test_a_side_below_a_lit_shoulder_is_no_floor():
    # The paint is the side's shade; a thin lit ledge above it is no reason to call the side a floor.
    lightness, mask = _side(paint=45.0)
    lightness[BOTTOM - 70 : BOTTOM - 59, 20 : 20 + LENGTH] = 80.0
    assert _band(lightness, mask) == 0.0


#: Gate settings leaving the underside test the only one that can turn the box car's rolls down.
ISOLATED = {"turned_margin": 1.0, "frontal_threshold": 0.3}


def test_gate_turns_down_a_car_rolled_30_degrees_by_its_floor(tmp_path):
    """The box car rolled 30° bottom towards the camera (about image-right) shows its floor: the underside
    test rejects it, and with the test off the same view passes; its side and 10° views stay accepted, and
    rolled the other way (roof towards the camera) it shows no floor. The other tests are kept out of the
    way: the turned-template test already rejects this boxy car's 10° views, and its 30° rolls fall just
    under the silhouette threshold (0.44 < 0.45), which is lowered to 0.3 here."""
    folder = box_car_meshes(tmp_path / "meshes")
    rows, _ = evaluate_gate(Plugins(), "car", folder, angles=(0, 10, 30), resolution=200, subtype="sedan",
                            settings=ISOLATED)
    by_view = {(r["axis"], r["degrees"]): r for r in rows}
    for view in (("yaw", 0.0), ("pitch", 10.0), ("pitch", -10.0)):
        assert by_view[view]["accepted"] == 1
    assert by_view[("pitch", -30.0)]["accepted"] == 0
    assert "floor shows" in by_view[("pitch", -30.0)]["reason"]
    assert "floor shows" not in by_view[("pitch", 30.0)]["reason"]
    off, _ = evaluate_gate(Plugins(), "car", folder, angles=(30,), resolution=200, subtype="sedan",
                           settings=ISOLATED | {"underside_margin": 1.0})
    assert next(r for r in off if (r["axis"], r["degrees"]) == ("pitch", -30.0))["accepted"] == 1

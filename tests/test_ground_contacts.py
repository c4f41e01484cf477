"""Ground-contact evidence: the frontal gate tells a car turned about image-up by its far wheels."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from frontal3d.eval_gate import evaluate_gate
from frontal3d.plugins import Plugins
from frontal3d.stages.ground_contacts import contact_split
from shapes import box_car_meshes


def _outline(wheel_centres: list[float], length: int = 300) -> np.ndarray:
    """A profile-like outline: a body slab above the ground and round wheels (x as shares of the length) standing on it."""
    mask = np.zeros((160, length + 40), np.uint8)
    cv2.rectangle(mask, (20, 40), (20 + length, 100), 1, -1)
    for share in wheel_centres:
        cv2.circle(mask, (20 + round(share * length), 110), 30, 1, -1)
    return mask > 0


def test_one_contact_per_axle_is_no_split():
    evidence = contact_split(_outline([0.2, 0.8]))
    assert evidence.runs == 2
    assert evidence.split == 0.0


def test_far_wheels_beside_the_near_ones_split_both_axles_by_their_offset():
    evidence = contact_split(_outline([0.15, 0.33, 0.67, 0.85]))
    assert evidence.runs == 4
    assert evidence.split == pytest.approx(0.18, abs=0.01)


def test_far_wheels_come_out_further_than_half_the_wheelbase_past_40_degrees():
    # At 45° a near and a far wheel stand further apart than the two axles do: each end's two runs are its pair.
    assert contact_split(_outline([0.08, 0.33, 0.5, 0.75])).split == pytest.approx(0.25, abs=0.015)


def test_near_60_degrees_three_evenly_spaced_contacts_are_two_pairs_sharing_the_middle():
    # One axle's far wheel stands where the other's near wheel does: three contacts, evenly spaced.
    evidence = contact_split(_outline([0.1, 0.5, 0.9]))
    assert evidence.runs == 3
    assert evidence.split == pytest.approx(0.4, abs=0.01)


def test_a_tilted_photo_still_stands_on_its_ground_line():
    # Two degrees of tilt lift one end by about 10 px, three times the contact depth: the ground is the hull's line.
    mask = _outline([0.15, 0.33, 0.67, 0.85]).astype(np.uint8)
    centre = (mask.shape[1] / 2, mask.shape[0] / 2)
    tilted = cv2.warpAffine(mask, cv2.getRotationMatrix2D(centre, 2.0, 1.0), mask.shape[::-1], flags=cv2.INTER_NEAREST) > 0
    assert contact_split(tilted).split == pytest.approx(0.18, abs=0.015)
    assert contact_split(cv2.warpAffine(_outline([0.2, 0.8]).astype(np.uint8), cv2.getRotationMatrix2D(centre, -2.0, 1.0),
                                        mask.shape[::-1], flags=cv2.INTER_NEAREST) > 0).split == 0.0


def test_a_pair_at_one_axle_only_is_no_turn():
    # A low front spoiler or a twin front axle splits one end only: the smaller split is the other end's, none.
    assert contact_split(_outline([0.1, 0.25, 0.8])).split == 0.0
    assert contact_split(_outline([0.1, 0.25, 0.8, 0.82])).split < 0.05


def test_gate_turns_down_a_car_turned_30_degrees_sideways_by_its_contacts(tmp_path):
    """The box car turned 30° about image-up shows all four wheels: the contact test rejects it, and
    nothing else does (with the test off the same views pass); its side and 10° views stay accepted.
    The turned-template test is off: on this boxy car it already rejects 10° views."""
    folder = box_car_meshes(tmp_path / "meshes")
    rows, _ = evaluate_gate(Plugins(), "car", folder, angles=(0, 10, 30), resolution=200, subtype="sedan",
                            settings={"turned_margin": 1.0})
    by_view = {(r["axis"], r["degrees"]): r for r in rows}
    for degrees in (0.0, 10.0, -10.0):
        assert by_view[("yaw", degrees)]["accepted"] == 1
    for degrees in (30.0, -30.0):
        assert by_view[("yaw", degrees)]["accepted"] == 0
        assert "ground contacts" in by_view[("yaw", degrees)]["reason"]
    off, _ = evaluate_gate(Plugins(), "car", folder, angles=(30,), resolution=200, subtype="sedan",
                           settings={"turned_margin": 1.0, "contact_pair_margin": 1.0})
    assert all(r["accepted"] == 1 for r in off if r["axis"] == "yaw")

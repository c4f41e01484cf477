"""Alignment of a template mask onto an object mask (paper 3.2.1)."""

import cv2
import numpy as np
import pytest

from frontal3d.errors import InputError
from frontal3d.stages.align import Similarity, align_template, warp_mask

# A guitar-like outline (y down: neck at the top, body with an asymmetric cutaway below),
# centred on its own centroid so any similarity of it is easy to keep inside the frame.
GUITAR = np.array([(-12, -120), (12, -120), (14, -95), (12, 90), (60, 100), (70, 150), (55, 200), (0, 215),
                   (-55, 200), (-70, 150), (-45, 110), (-30, 95), (-12, 90), (-14, -95)], dtype=float)
GUITAR = 0.6 * (GUITAR - GUITAR.mean(axis=0))
TO_TEMPLATE = Similarity(1.0, 0.0, 150.0, 150.0)  # outline -> 300x300 template image


def draw(points: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [np.round(points * 16).astype(np.int32)], 1, shift=4)
    return mask > 0


def outline_contour(mask: np.ndarray) -> np.ndarray:
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    return max(contours, key=len)[:, 0, :].astype(float)


def angle_error_deg(a: float, b: float) -> float:
    return abs(np.rad2deg(np.angle(np.exp(1j * (a - b)))))


def test_similarity_algebra():
    sim = Similarity(1.7, 0.6, 12.0, -30.0)
    other = Similarity(0.5, -2.0, 3.0, 4.0)
    pts = np.array([[0.0, 0.0], [10.0, -3.0], [250.0, 100.0]])
    assert np.allclose(sim.inverse().apply(sim.apply(pts)), pts)
    assert np.allclose(sim.compose(other).apply(pts), sim.apply(other.apply(pts)))
    assert np.allclose(sim.apply(pts), pts @ sim.matrix[:, :2].T + sim.matrix[:, 2])
    assert sim.matrix.shape == (2, 3) and sim.matrix.dtype == np.float64
    assert Similarity(**sim.to_dict()) == sim
    # positive angle: x-right turns to y-down (clockwise on screen)
    assert np.allclose(Similarity(1.0, np.pi / 2, 0, 0).apply(np.array([[1.0, 0.0]])), [[0.0, 1.0]])


def test_warp_mask_moves_the_mask():
    mask = np.zeros((40, 40), bool)
    mask[5:10, 5:15] = True
    moved = warp_mask(mask, Similarity(1.0, 0.0, 20.0, 3.0), (50, 60))
    assert moved.shape == (50, 60) and moved.dtype == bool
    assert moved.sum() == mask.sum() and moved[8:13, 25:35].all()


@pytest.mark.parametrize("angle_deg, scale, shift", [
    (37.0, 1.0, (250.0, 260.0)),
    (120.0, 0.6, (110.0, 380.0)),
    (-170.0, 1.7, (256.0, 250.0)),
    (-75.0, 1.3, (300.0, 200.0)),
])
def test_recovers_rotation_scale_and_shift(angle_deg, scale, shift):
    template = draw(TO_TEMPLATE.apply(GUITAR), (300, 300))
    outline_to_image = Similarity(scale, np.deg2rad(angle_deg), *shift)
    truth = outline_to_image.compose(TO_TEMPLATE.inverse())
    obj = draw(outline_to_image.apply(GUITAR), (512, 512))
    assert not obj[[0, -1], :].any() and not obj[:, [0, -1]].any()  # fully inside the frame

    sim, info = align_template(template, obj)

    contour = outline_contour(template)
    error = np.linalg.norm(sim.apply(contour) - truth.apply(contour), axis=1).mean()
    assert error < 2.0
    assert angle_error_deg(sim.angle, truth.angle) < 2.0
    assert info["iou"] > 0.95
    assert set(info) >= {"iou", "mutual_information", "coarse_iou", "seconds"}


def test_far_away_template_still_converges():
    """Template in the left half of its image, object in the bottom-right of the photo: no initial overlap."""
    to_template = Similarity(0.8, 0.0, 80.0, 150.0)
    template = draw(to_template.apply(GUITAR), (300, 400))
    outline_to_image = Similarity(1.4, 0.2, 420.0, 280.0)
    truth = outline_to_image.compose(to_template.inverse())
    obj = draw(outline_to_image.apply(GUITAR), (480, 640))
    assert not (warp_mask(template, Similarity(1, 0, 0, 0), obj.shape) & obj).any()

    sim, info = align_template(template, obj)

    contour = outline_contour(template)
    assert np.linalg.norm(sim.apply(contour) - truth.apply(contour), axis=1).mean() < 2.0
    assert info["iou"] > 0.95


def test_max_angle_limits_the_rotation():
    template = draw(TO_TEMPLATE.apply(GUITAR), (300, 300))
    upright = draw(Similarity(1.0, np.deg2rad(12.0), 256, 256).apply(GUITAR), (512, 512))
    sim, _ = align_template(template, upright, max_angle=np.pi / 6)
    assert angle_error_deg(sim.angle, np.deg2rad(12.0)) < 2.0

    lying = draw(Similarity(1.0, np.deg2rad(90.0), 256, 256).apply(GUITAR), (512, 512))
    sim, _ = align_template(template, lying, max_angle=np.pi / 6)
    assert abs(sim.angle) <= np.pi / 6 + 1e-6


def test_grey_images_resolve_a_symmetric_silhouette():
    """A rectangle looks the same turned by 180 degrees; a dark mark on one end tells them apart."""
    template = np.zeros((200, 200), bool)
    template[40:160, 70:130] = True
    template_grey = np.where(template, 200, 0).astype(np.uint8)
    template_grey[50:70, 85:115] = 40  # mark near the top

    turn = Similarity(1.2, np.pi, 300.0, 260.0).compose(Similarity(1.0, 0.0, -100.0, -100.0))
    obj = warp_mask(template, turn, (512, 512))
    obj_grey = cv2.warpAffine(template_grey, turn.matrix, (512, 512), flags=cv2.INTER_NEAREST)

    sim, _ = align_template(template, obj, template_grey, obj_grey)
    assert angle_error_deg(sim.angle, np.pi) < 2.0


def test_empty_mask_is_an_input_error():
    template = draw(TO_TEMPLATE.apply(GUITAR), (300, 300))
    with pytest.raises(InputError, match="object mask is empty"):
        align_template(template, np.zeros((100, 100), bool))
    with pytest.raises(InputError, match="grey"):
        align_template(template, template, template_grey=np.zeros((10, 10)))


def planform(length: float, span: float, chord: float, shape: tuple[int, int], angle: float) -> np.ndarray:
    """A plane seen from above, nose up: a fuselage, a wing at a third of the length, a tailplane."""
    pieces = [
        [(-0.06 * length, -0.5 * length), (0.06 * length, -0.5 * length), (0.06 * length, 0.5 * length), (-0.06 * length, 0.5 * length)],
        [(-0.5 * span, -0.1 * length), (0.5 * span, -0.1 * length), (0.5 * span, -0.1 * length + chord), (-0.5 * span, -0.1 * length + chord)],
        [(-0.15 * span, 0.35 * length), (0.15 * span, 0.35 * length), (0.15 * span, 0.45 * length), (-0.15 * span, 0.45 * length)],
    ]
    place = Similarity(1.0, angle, shape[1] / 2.0, shape[0] / 2.0)
    return np.any([draw(place.apply(np.array(p, dtype=float)), shape) for p in pieces], axis=0)


def test_a_symmetric_template_lands_on_the_objects_mirror_axis():
    """A long-bodied template on a plane twice as wide as long overlays best turned by 90 degrees
    (fuselage along the wings); the mirror axis of both keeps the fuselage on the fuselage."""
    template = planform(length=200.0, span=150.0, chord=40.0, shape=(300, 300), angle=0.0)
    for turn_deg in (0.0, 30.0):
        obj = planform(length=110.0, span=240.0, chord=30.0, shape=(400, 400), angle=np.deg2rad(turn_deg))
        sim, diagnostics = align_template(template, obj)
        axis_error = min(angle_error_deg(sim.angle, np.deg2rad(turn_deg)), angle_error_deg(sim.angle, np.deg2rad(turn_deg) + np.pi))
        assert axis_error < 8.0, (turn_deg, np.rad2deg(sim.angle))
        assert diagnostics["placed_on_mirror_axis"]


def test_an_aligned_symmetric_object_keeps_its_placement():
    template = planform(length=200.0, span=150.0, chord=40.0, shape=(300, 300), angle=0.0)
    obj = planform(length=220.0, span=170.0, chord=45.0, shape=(400, 400), angle=np.deg2rad(-50.0))
    sim, diagnostics = align_template(template, obj)
    assert angle_error_deg(sim.angle, np.deg2rad(-50.0)) < 3.0
    assert not diagnostics["placed_on_mirror_axis"]


def test_hidden_pixels_do_not_shrink_the_template_onto_the_visible_part():
    """An arm along the whole neck leaves the body: scored on every pixel, the template shrinks
    onto the body; with the arm's pixels hidden, the body alone places it at the true scale."""
    template = draw(TO_TEMPLATE.apply(GUITAR), (300, 300))
    outline_to_image = Similarity(0.8, np.deg2rad(8.0), 150.0, 160.0)
    truth = outline_to_image.compose(TO_TEMPLATE.inverse())
    obj = draw(outline_to_image.apply(GUITAR), (300, 300))
    # The forearm runs down the neck's axis from beyond the headstock to near the body.
    head, neck_base = outline_to_image.apply(GUITAR[[0, 1, 12, 3]].reshape(2, 2, 2).mean(axis=1))
    beyond = head + 3.0 * (head - neck_base)
    arm = np.zeros(obj.shape, np.uint8)
    cv2.line(arm, tuple(np.round(beyond).astype(int)), tuple(np.round(head + 0.85 * (neck_base - head)).astype(int)), 1, 21)
    arm = arm > 0
    visible = obj & ~arm
    assert 0.1 * obj.sum() < (obj & arm).sum() < 0.3 * obj.sum()
    hidden = cv2.dilate(arm.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    contour = outline_contour(template)

    def error(sim: Similarity) -> float:
        return float(np.linalg.norm(sim.apply(contour) - truth.apply(contour), axis=1).mean())

    blind, _ = align_template(template, visible)
    seen, _ = align_template(template, visible, hidden=hidden)

    assert error(blind) > 10.0
    assert error(seen) < 2.0
    assert abs(seen.scale / truth.scale - 1.0) < 0.03

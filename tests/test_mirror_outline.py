"""Mirror completion of a hidden outline: the seen other half stands in for a template unlike the object."""

from __future__ import annotations

import cv2
import numpy as np

from frontal3d.stages.mirror_outline import find_mirror_line, reflected
from frontal3d.stages.occlusion import rebuild_silhouette

SHAPE = (320, 280)


def _star(tilt_deg: float = 0.0, centre: tuple[float, float] = (140.0, 165.0)) -> np.ndarray:
    """A five-pointed body, mirror-symmetric about a line turned ``tilt_deg`` counter-clockwise from image-up."""
    angles = np.linspace(0.0, 2 * np.pi, 11)[:-1]
    radii = np.where(np.arange(10) % 2 == 0, 120.0, 55.0)
    points = np.stack([radii * np.sin(angles), -radii * np.cos(angles)], axis=1)
    a = np.deg2rad(tilt_deg)
    turn = np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    mask = np.zeros(SHAPE, np.uint8)
    cv2.fillPoly(mask, [np.round(points @ turn.T + centre).astype(np.int32)], 1)
    return mask > 0


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def _arm_over_the_right_point() -> np.ndarray:
    arm = np.zeros(SHAPE, np.uint8)
    cv2.line(arm, (279, 60), (190, 170), 1, 46)
    return arm > 0


def _round_template(truth: np.ndarray) -> np.ndarray:
    """The family's only template: a disc of the star's area, on its centre (no pointed template exists)."""
    rows, cols = np.nonzero(truth)
    template = np.zeros(SHAPE, np.uint8)
    cv2.circle(template, (round(cols.mean()), round(rows.mean())), round(np.sqrt(truth.sum() / np.pi)), 1, -1)
    return template > 0


def test_a_hidden_point_of_a_symmetric_body_is_rebuilt_from_its_seen_twin():
    truth = _star()
    arm = _arm_over_the_right_point()
    visible = truth & ~arm
    template = _round_template(truth)

    from_template = rebuild_silhouette(visible, arm, template)
    mirrored = rebuild_silhouette(visible, arm, template, mirror_axis=0.0)

    assert _iou(from_template.mask, truth) < 0.93
    assert _iou(mirrored.mask, truth) > 0.98
    summary = mirrored.summary()
    assert summary["mirror"]["used"] and summary["mirror"]["agreement"] > 0.95
    assert mirrored.occluded[mirrored.mask & arm].all()  # still inpainted: the image shows the arm there


def test_the_mirror_line_is_found_off_the_templates_axis():
    truth = _star(tilt_deg=20.0)
    arm = _arm_over_the_right_point()
    line = find_mirror_line(truth & ~arm, cv2.dilate(arm.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0, _round_template(truth), np.deg2rad(14.0))
    assert line is not None and line.agreement > 0.95
    # The reflection's fixed direction is the mirror line: (sin, -cos) of its angle from image-up, turned counter-clockwise.
    reflection = line.matrix[:, :2]
    direction = np.array([-np.sin(np.deg2rad(20.0)), -np.cos(np.deg2rad(20.0))])
    assert np.allclose(reflection @ direction, direction, atol=np.sin(np.deg2rad(1.5)))


def test_a_lopsided_body_its_template_fits_keeps_the_templates_outline():
    """A single-cutaway body: its seen halves disagree, the template (the same body) agrees: no mirror."""
    truth = np.zeros(SHAPE, np.uint8)
    cv2.ellipse(truth, (140, 190), (100, 110), 0, 0, 360, 1, -1)
    cv2.circle(truth, (205, 95), 48, 0, -1)  # the cutaway, upper right
    truth = truth > 0
    arm = np.zeros(SHAPE, np.uint8)
    cv2.line(arm, (0, 230), (70, 200), 1, 40)  # over the left bout, whose twin is seen
    arm = arm > 0
    template = cv2.warpAffine(truth.astype(np.uint8), np.float32([[1, 0, 2], [0, 1, -1]]), SHAPE[::-1]) > 0

    from_template = rebuild_silhouette(truth & ~arm, arm, template)
    with_mirror = rebuild_silhouette(truth & ~arm, arm, template, mirror_axis=0.0)

    assert not with_mirror.summary()["mirror"]["used"]
    assert np.array_equal(with_mirror.mask, from_template.mask)
    assert _iou(with_mirror.mask, truth) > 0.98


def _pointed_guitar(shape: tuple[int, int]) -> np.ndarray:
    """A star-bodied electric (four points, no template has them), neck and headstock up."""
    mask = np.zeros(shape, np.uint8)
    cx, cy, s = shape[1] // 2, int(shape[0] * 0.72), shape[0] // 9
    body = [(0, -1.0), (1.3, -1.7), (0.55, -0.2), (1.2, 1.6), (0, 0.9), (-1.2, 1.6), (-0.55, -0.2), (-1.3, -1.7)]
    cv2.fillPoly(mask, [np.round([(cx + s * x, cy + s * y) for x, y in body]).astype(np.int32)], 1)
    mask[cy - int(s * 4.6) : cy - s + 4, cx - s // 7 : cx + s // 7] = 1
    mask[cy - int(s * 5.2) : cy - int(s * 4.6), cx - s // 4 : cx + s // 4] = 1
    return mask > 0


def test_the_pipeline_rebuilds_a_hidden_point_of_a_star_body_from_its_twin():
    import frontal3d
    from frontal3d.photo_render import frontal_camera, render_frontal

    truth = _pointed_guitar((480, 480))
    image = np.full(truth.shape + (3,), 235, np.uint8)
    image[truth] = (150, 60, 40)
    hand = np.zeros(truth.shape, np.uint8)
    cv2.circle(hand, (300, 410), 50, 1, -1)  # over the lower right point
    hand = hand > 0
    assert (hand & truth).sum() > 0.05 * truth.sum()

    def outline(result):
        return render_frontal(result.mesh, frontal_camera(result.mesh, 240, 0.8))[..., 3] > 0

    clean = frontal3d.reconstruct(image, "guitar", mask=truth, subtype="electric")
    runs = {mirror: frontal3d.reconstruct(image, "guitar", mask=truth & ~hand, occluder_mask=hand, subtype="electric", outline_mirror=mirror)
            for mirror in (False, True)}

    assert runs[True].report["occlusion"]["mirror"]["used"]
    assert "mirror" not in runs[False].report["occlusion"]
    assert runs[True].mesh.is_watertight
    mirrored, from_template = (_iou(outline(runs[mirror]), outline(clean)) for mirror in (True, False))
    assert mirrored > 0.94 and mirrored > from_template + 0.03  # 0.954 and 0.907 when written


def test_on_a_large_photo_the_line_is_searched_small_and_reflects_at_full_size():
    truth = _star(tilt_deg=12.0)
    big = cv2.resize(truth.astype(np.uint8), (SHAPE[1] * 3, SHAPE[0] * 3), interpolation=cv2.INTER_NEAREST) > 0
    line = find_mirror_line(big, np.zeros_like(big), cv2.dilate(big.astype(np.uint8), np.ones((15, 15), np.uint8)) > 0, np.deg2rad(10.0))
    assert line is not None and line.agreement > 0.95
    assert _iou(reflected(big, line.matrix), big) > 0.95


def test_a_person_biting_a_bout_the_templates_cutaway_fits_is_still_in_front():
    """The template explains the bite (its outline is the bite's), so on its own it expects no
    object there and the person passes for one behind; the other bout, mirrored, expects the body."""
    from frontal3d.stages.occlusion import in_front

    truth = np.zeros(SHAPE, np.uint8)
    cv2.ellipse(truth, (140, 200), (90, 100), 0, 0, 360, 1, -1)
    cv2.rectangle(truth, (130, 20), (150, 110), 1, -1)
    truth = truth > 0
    person = np.zeros(SHAPE, np.uint8)
    cv2.circle(person, (40, 250), 75, 1, -1)
    person = person > 0
    visible = truth & ~person
    # A template of another body (5 % slimmer) with a cutaway just where the person bites.
    template = cv2.warpAffine(visible.astype(np.uint8), np.float32([[0.95, 0, 7], [0, 1, 0]]), SHAPE[::-1]) > 0

    assert not in_front(person, visible, template).any()
    found = in_front(person, visible, template, mirror_axis=0.0)
    bite = truth & person
    assert (found & bite).sum() > 0.9 * bite.sum()
    assert not (found & ~person).any()


def test_a_neck_beyond_the_seen_body_keeps_the_templates_guess():
    """A person hides a guitar's neck and the top of its body; the seen lower body is symmetric
    and the template's neck leans 4° off the body's mirror line. Where the mirror line has no
    seen object beside it, it cannot judge: the template's neck stays (a reflection a few
    degrees off swings the neck's mirror image off the neck, onto seen background)."""
    shape = (400, 300)
    body = np.zeros(shape, np.uint8)
    cv2.ellipse(body, (150, 300), (80, 70), 0, 0, 360, 1, -1)
    template = np.zeros(shape, np.uint8)
    cv2.ellipse(template, (150, 300), (88, 64), 0, 0, 360, 1, -1)  # a body unlike the object's: the mirror is used
    top = np.array([150.0, 300.0]) + 240 * np.array([np.sin(np.deg2rad(4)), -1.0])  # the neck, from the body's centre
    cv2.line(template, (150, 300), (round(top[0]), round(top[1])), 1, 16)
    person = (np.indices(shape)[0] < 265) & (cv2.dilate(template, np.ones((17, 17), np.uint8)) > 0)
    visible = (body > 0) & ~person

    rebuilt = rebuild_silhouette(visible, person, template > 0, mirror_axis=0.0)

    assert rebuilt.summary()["mirror"]["used"]
    neck_top = rebuilt.mask[60:140]
    assert neck_top.sum() > 0.8 * (template[60:140] > 0).sum()  # 27 % when the mirror judged beyond the body

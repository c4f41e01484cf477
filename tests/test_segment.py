"""Object segmentation defaults: user masks, alpha channels and the GrabCut fallback."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from frontal3d.errors import InputError
from frontal3d.imageio import read_mask
from frontal3d.render import TemplateRenders
from frontal3d.stages.classify import silhouette_agreement
from frontal3d.stages.segment import grabcut_segment, mask_from_alpha, refine_with_shape_prior, split_objects


def _ellipse_mask(shape: tuple[int, int]) -> np.ndarray:
    mask = np.zeros(shape, np.uint8)
    h, w = shape
    cv2.ellipse(mask, (w // 2 + 10, h // 2 - 5), (w // 5, h // 3), 20, 0, 360, 1, -1)
    return mask > 0


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def _composite(background: np.ndarray, mask: np.ndarray, colour: tuple[int, int, int], rng: np.random.Generator) -> np.ndarray:
    """An object with a little shading and sensor noise over ``background``."""
    h, w = mask.shape
    shading = np.linspace(0.85, 1.1, w)[None, :, None]
    obj = np.clip(np.array(colour, np.float64)[None, None] * shading, 0, 255)
    image = np.where(mask[..., None], obj, background)
    return np.clip(image + rng.normal(0, 6, image.shape), 0, 255).astype(np.uint8)


def test_grabcut_finds_an_ellipse_on_a_noisy_plain_background():
    rng = np.random.default_rng(1)
    shape = (480, 640)
    truth = _ellipse_mask(shape)
    background = np.full(shape + (3,), (225, 228, 232), np.float64)
    found = grabcut_segment(_composite(background, truth, (170, 40, 35), rng))
    assert found is not None and found.shape == shape
    assert _iou(found, truth) > 0.9


def test_grabcut_finds_an_ellipse_on_a_mildly_cluttered_background():
    rng = np.random.default_rng(2)
    shape = (480, 640)
    truth = _ellipse_mask(shape)
    background = np.empty(shape + (3,))
    background[:] = np.linspace(150, 205, shape[1])[None, :, None] * np.array([0.9, 1.0, 1.05])
    for _ in range(12):
        blob = np.zeros(shape, np.float32)
        centre = (int(rng.integers(0, shape[1])), int(rng.integers(0, shape[0])))
        cv2.circle(blob, centre, int(rng.integers(25, 70)), 1.0, -1)
        blob = cv2.GaussianBlur(blob, (0, 0), 15)[..., None]
        background = background * (1 - blob) + blob * rng.uniform(110, 230, 3)
    found = grabcut_segment(_composite(background, truth, (30, 70, 160), rng))
    assert found is not None
    assert _iou(found, truth) > 0.85


def _airplane_mask(shape: tuple[int, int]) -> np.ndarray:
    """A top-view airplane: fuselage, swept wings and a tailplane (thin parts included)."""
    h, w = shape
    mask = np.zeros(shape, np.uint8)
    cx = w // 2
    cv2.ellipse(mask, (cx, h // 2), (w // 40, int(h * 0.4)), 0, 0, 360, 1, -1)
    wing = np.array([[cx, h // 2 - 30], [cx + int(w * 0.3), h // 2 + 40], [cx + int(w * 0.3), h // 2 + 60], [cx, h // 2 + 30]])
    tail = np.array([[cx, int(h * 0.8)], [cx + w // 10, int(h * 0.86)], [cx + w // 10, int(h * 0.89)], [cx, int(h * 0.87)]])
    for part in (wing, tail):
        cv2.fillPoly(mask, [part, part * [-1, 1] + [2 * cx, 0]], 1)
    return mask > 0


def _light_gradient(shape: tuple[int, int]) -> np.ndarray:
    """A sky: light blue at the top, grey-green toward the horizon."""
    t = np.linspace(0, 1, shape[0])[:, None, None]
    return (1 - t) * np.array([200.0, 215, 235]) + t * np.array([120.0, 130, 110]) + np.zeros(shape + (3,))


def _mild_clutter(shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """A soft vignette over a tinted gradient, low-contrast texture and a few faint shapes."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    background = (1 - xx[..., None]) * np.array([205.0, 195, 215]) + xx[..., None] * np.array([190.0, 210, 180])
    background *= (1 - 0.4 * ((xx - 0.5 * w / max(h, w)) ** 2 + (yy - 0.5 * h / max(h, w)) ** 2))[..., None]
    texture = cv2.GaussianBlur(rng.normal(0, 1, shape).astype(np.float32), (0, 0), 3)
    background += (texture / texture.std() * 4)[..., None]
    for _ in range(3):
        shape_mask = np.zeros(shape, np.float32)
        cv2.circle(shape_mask, (int(rng.integers(0, w // 5)), int(rng.integers(0, h))), int(rng.integers(20, 50)), 1.0, -1)
        background += cv2.GaussianBlur(shape_mask, (0, 0), 2)[..., None] * rng.uniform(-15, 15, 3)
    return background


def test_grabcut_finds_a_light_grey_airplane_on_a_light_sky_gradient():
    rng = np.random.default_rng(4)
    shape = (480, 640)
    truth = _airplane_mask(shape)
    found = grabcut_segment(_composite(_light_gradient(shape), truth, (200, 200, 205), rng))
    assert found is not None
    assert _iou(found, truth) > 0.9


def test_grabcut_finds_a_light_smooth_object_on_a_grainy_background():
    rng = np.random.default_rng(8)
    shape = (480, 640)
    truth = _airplane_mask(shape)
    grain = cv2.GaussianBlur(np.clip(rng.normal(170, 25, shape + (3,)), 0, 255), (0, 0), 1.0)
    image = np.where(truth[..., None], np.array([198.0, 196, 194]), grain)
    found = grabcut_segment(np.clip(image + rng.normal(0, 2, image.shape), 0, 255).astype(np.uint8))
    assert found is not None
    assert _iou(found, truth) > 0.85


def test_grabcut_finds_a_car_like_object_on_mild_clutter_with_a_vignette():
    rng = np.random.default_rng(5)
    shape = (480, 640)
    truth = np.zeros(shape, np.uint8)
    cv2.rectangle(truth, (140, 230), (520, 330), 1, -1)
    cv2.rectangle(truth, (230, 170), (420, 240), 1, -1)
    for x in (200, 460):
        cv2.circle(truth, (x, 330), 40, 1, -1)
    truth = truth > 0
    found = grabcut_segment(_composite(_mild_clutter(shape, rng), truth, (150, 160, 175), rng))
    assert found is not None
    assert _iou(found, truth) > 0.9


def test_grabcut_finds_an_object_in_front_of_a_multicoloured_scene():
    rng = np.random.default_rng(6)
    shape = (360, 640)
    background = np.empty(shape + (3,))
    background[:120] = (70, 120, 50)  # grass
    background[120:150] = (200, 60, 60)  # kerb
    background[150:] = (95, 95, 100)  # road
    truth = np.zeros(shape, np.uint8)
    cv2.ellipse(truth, (320, 200), (220, 70), 0, 0, 360, 1, -1)
    truth = truth > 0
    found = grabcut_segment(_composite(background, truth, (235, 235, 240), rng))
    assert found is not None
    assert _iou(found, truth) > 0.9


def test_grabcut_sets_a_white_print_border_aside():
    rng = np.random.default_rng(7)
    shape = (400, 560)
    truth = _ellipse_mask(shape)
    picture = np.clip(_composite(_light_gradient(shape) * 0.6, truth, (230, 230, 235), rng), 0, 255)
    picture[:20] = picture[-20:] = 250
    picture[:, :20] = picture[:, -20:] = 250
    found = grabcut_segment(picture)
    assert found is not None
    assert not found[:20].any() and not found[:, :20].any()
    assert _iou(found, truth) > 0.9


def test_grabcut_returns_none_for_an_image_without_an_object():
    rng = np.random.default_rng(3)
    plain = np.clip(rng.normal(128, 5, (200, 300, 3)), 0, 255).astype(np.uint8)
    assert grabcut_segment(plain) is None


def test_alpha_channel_is_the_mask_unless_uniform():
    rgba = np.zeros((40, 50, 4), np.uint8)
    rgba[10:30, 5:20, 3] = 255
    mask = mask_from_alpha(rgba)
    assert mask is not None and mask.sum() == 20 * 15 and mask[15, 10] and not mask[0, 0]
    rgba[..., 3] = 255
    assert mask_from_alpha(rgba) is None
    rgba[..., 3] = 0  # a wrongly exported, wholly transparent PNG: its colours are still the photo
    assert mask_from_alpha(rgba) is None
    assert mask_from_alpha(rgba[..., :3]) is None


def test_user_mask_is_resized_only_when_the_aspect_ratio_matches(tmp_path):
    mask = np.zeros((50, 100), np.uint8)
    mask[10:40, 20:60] = 255
    path = tmp_path / "mask.png"
    cv2.imwrite(str(path), mask)
    same = read_mask(path, (50, 100))
    assert same.dtype == bool and same.sum() == 30 * 40
    doubled = read_mask(path, (100, 200))
    assert doubled.shape == (100, 200) and doubled.sum() == 60 * 80
    with pytest.raises(InputError, match=r"100x50.*120x50"):
        read_mask(path, (50, 120))


def test_split_objects_orders_by_size_and_drops_specks():
    mask = np.zeros((100, 100), bool)
    mask[5:45, 5:45] = True
    mask[60:90, 60:90] = True
    mask[95:97, 2:4] = True
    objects = split_objects(mask)
    assert [int(o.sum()) for o in objects] == [1600, 900]


def _silhouette_template(mask: np.ndarray) -> TemplateRenders:
    """Template renders of which only the silhouette matters (the shape prior uses nothing else)."""
    depth = np.where(mask, 0.0, np.nan)
    normals = np.zeros(mask.shape + (3,))
    regions = np.where(mask, 0, -1)
    return TemplateRenders((0.0, 0.0), 1.0, mask, depth, depth, normals, normals, regions, regions, ("body",))


def _airplane_template() -> dict[str, TemplateRenders]:
    template = np.zeros((256, 256), bool)
    template[16:240, 16:240] = _airplane_mask((224, 224))
    return {"airliner": _silhouette_template(template)}


def _airplane_over_colour_spots(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A dark fuselage with wings barely off a grey background whose colour spots fool the first pass."""
    shape = (480, 480)
    truth = _airplane_mask(shape)
    background = np.full(shape + (3,), 190.0)
    for centre in [(40, 60), (420, 50), (60, 420), (430, 430), (240, 20), (20, 240), (460, 240)]:
        spot = np.zeros(shape, np.float32)
        cv2.circle(spot, centre, int(rng.integers(30, 50)), 1.0, -1)
        spot = cv2.GaussianBlur(spot, (0, 0), 12)[..., None]
        background = background * (1 - spot) + spot * rng.uniform(90, 240, 3)
    shading = np.linspace(0.97, 1.03, shape[1])[None, :, None]
    image = np.where(truth[..., None], np.array([196.0, 201, 207]) * shading, background)
    fuselage = np.zeros(shape, np.uint8)
    cv2.ellipse(fuselage, (240, 240), (12, 192), 0, 0, 360, 1, -1)
    image = np.where((fuselage > 0)[..., None], np.array([150.0, 155, 165]), image)
    return np.clip(image + rng.normal(0, 3, image.shape), 0, 255).astype(np.uint8), truth


def test_shape_prior_recovers_wings_the_first_pass_lost_on_a_cluttered_background():
    image, truth = _airplane_over_colour_spots(np.random.default_rng(0))
    first = split_objects(grabcut_segment(image))[0]
    templates = _airplane_template()
    refined = refine_with_shape_prior(image, first, templates, silhouette_agreement(first, templates, np.pi))
    assert _iou(first, truth) < 0.6
    assert _iou(refined, truth) > 0.95


def test_shape_prior_never_takes_excluded_pixels():
    image, truth = _airplane_over_colour_spots(np.random.default_rng(0))
    first = split_objects(grabcut_segment(image))[0]
    occluder = np.zeros_like(truth)
    occluder[200:330, 300:330] = True  # an arm across the right wing
    image[occluder] = (205, 150, 120)
    templates = _airplane_template()
    refined = refine_with_shape_prior(image, first & ~occluder, templates, silhouette_agreement(first & ~occluder, templates, np.pi), exclude=occluder)
    assert not (refined & occluder).any()
    assert _iou(refined, truth & ~occluder) >= _iou(first, truth & ~occluder)


def test_shape_prior_leaves_a_good_mask_on_a_plain_background_unchanged():
    rng = np.random.default_rng(9)
    truth = _airplane_mask((480, 480))
    image = _composite(np.full((480, 480, 3), (225.0, 228, 232)), truth, (120, 125, 140), rng)
    first = grabcut_segment(image)
    templates = _airplane_template()
    refined = refine_with_shape_prior(image, first, templates, silhouette_agreement(first, templates, np.pi))
    assert _iou(first, truth) > 0.95
    assert np.array_equal(refined, first)


def test_grabcut_finds_a_grey_green_airplane_on_strongly_textured_grass():
    """Coarse grain of ±25 % spreads the border's colours widely; a grey-green airplane differs
    from the green by less than three such spreads yet clearly beyond their range."""
    from frontal3d.synth import smooth_noise

    rng = np.random.default_rng(7)
    shape = (320, 320)
    truth = _airplane_mask(shape)
    grain = smooth_noise(shape[0], rng, cells=60)[..., None]
    background = np.clip(np.array([90.0, 200.0, 110.0]) * (1 + 0.25 * grain), 0, 255)
    image = np.where(truth[..., None], np.array([140.0, 150.0, 140.0]), background)
    image = np.clip(image + rng.normal(0, 3, image.shape), 0, 255).astype(np.uint8)
    found = grabcut_segment(image)
    assert found is not None
    assert _iou(found, truth) > 0.9


def _network_like_probability(truth: np.ndarray, size: int = 96) -> np.ndarray:
    """What a small learned segmenter gives: the true mask seen at ``size`` px, blurred, upsampled."""
    h, w = truth.shape
    scale = size / max(h, w)
    small = cv2.resize(truth.astype(np.float32), (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA)
    return cv2.resize(cv2.GaussianBlur(small, (0, 0), 1.0), (w, h), interpolation=cv2.INTER_LINEAR)


def test_a_learned_probability_seeds_an_object_the_colour_cues_lost():
    image, truth = _airplane_over_colour_spots(np.random.default_rng(0))
    alone = split_objects(grabcut_segment(image))[0]
    seeded = grabcut_segment(image, object_probability=_network_like_probability(truth))
    assert _iou(alone, truth) < 0.6
    assert seeded is not None and _iou(seeded, truth) > 0.88  # the tailplane, 3 px wide at 96 px, stays lost


def _car_like_mask(shape: tuple[int, int]) -> np.ndarray:
    truth = np.zeros(shape, np.uint8)
    cv2.rectangle(truth, (120, 250), (420, 330), 1, -1)
    cv2.rectangle(truth, (190, 200), (350, 260), 1, -1)
    return truth > 0


def _blob(shape: tuple[int, int], centre: tuple[int, int], axes: tuple[int, int]) -> np.ndarray:
    blob = np.zeros(shape, np.float32)
    cv2.ellipse(blob, centre, axes, 30, 0, 360, 1.0, -1)
    return cv2.GaussianBlur(blob, (0, 0), 3)[..., None]


def _car_before_a_blue_blob(seed: int, centre: tuple[int, int], axes: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A red car-like shape over a pale background with a soft blue blob: (image, truth, blob weight)."""
    shape = (480, 640)
    truth = _car_like_mask(shape)
    blob = _blob(shape, centre, axes)
    background = np.full(shape + (3,), (205.0, 210, 200)) * (1 - blob) + blob * np.array([40.0, 60, 170])
    return _composite(background, truth, (170, 40, 35), np.random.default_rng(seed)), truth, blob


def test_a_learned_probability_keeps_a_separate_coloured_blob_out():
    image, truth, blob = _car_before_a_blue_blob(9, (540, 130), (70, 50))
    alone = grabcut_segment(image)
    seeded = grabcut_segment(image, object_probability=_network_like_probability(truth))
    assert (alone & (blob[..., 0] > 0.5)).sum() > 1000  # the colour cues take the blob for an object too
    assert seeded is not None and not (seeded & (blob[..., 0] > 0.5)).any()
    assert _iou(seeded, truth) > 0.97


def test_a_learned_probability_cuts_off_a_blob_touching_the_object():
    # The blob lies behind the roof: the colour cues see one seed region, the network
    # sees the blob's far side as background, and the blob is not the car's colour.
    image, truth, blob = _car_before_a_blue_blob(10, (400, 170), (90, 70))
    beyond = (blob[..., 0] > 0.5) & ~truth
    fooled = grabcut_segment(image, object_probability=_network_like_probability(truth | beyond))
    seeded = grabcut_segment(image, object_probability=_network_like_probability(truth))
    assert (fooled & beyond).sum() > 0.5 * beyond.sum()  # a network that also saw the blob keeps it
    assert seeded is not None and (seeded & beyond).sum() < 0.02 * beyond.sum()
    assert _iou(seeded, truth) > 0.97


def test_a_learned_probability_cuts_off_a_blob_of_another_hue_within_its_reach():
    # The blob sits on the roof and reaches only ~30 px beyond it: within the network's reach,
    # so no piece of it is "far", and a coarse network (48 px) blurs p > 0.5 onto its near side.
    # Most of the blob's colour still has low p, unlike the car's: that colour is cut.
    image, truth, blob = _car_before_a_blue_blob(13, (300, 190), (60, 30))
    beyond = (blob[..., 0] > 0.5) & ~truth
    found = grabcut_segment(image, object_probability=_network_like_probability(truth, 48))
    assert found is not None and (found & beyond).sum() < 0.02 * beyond.sum()  # 3206 of its 3814 px before
    assert _iou(found, truth) > 0.97


def test_a_network_that_sees_the_object_faintly_still_cuts_off_a_blob_of_another_hue():
    # The same scene seen by a network unsure of the whole car (p at most 0.45): no colour has a
    # mean p of 0.5, so the car's best-believed colours stand for it and the blob's is still cut.
    image, truth, blob = _car_before_a_blue_blob(13, (300, 190), (60, 30))
    beyond = (blob[..., 0] > 0.5) & ~truth
    found = grabcut_segment(image, object_probability=0.45 * _network_like_probability(truth, 48))
    assert found is not None and (found & beyond).sum() < 0.02 * beyond.sum()
    assert _iou(found, truth) > 0.97


def test_a_learned_probability_keeps_a_part_of_the_object_s_colour_it_missed():
    # A long boom of the car's colour reaches far beyond what the network saw: it stays,
    # though the background darkens under it (its colour is judged as seen, not flattened).
    rng = np.random.default_rng(11)
    shape = (480, 640)
    body = _car_like_mask(shape)
    boom = np.zeros(shape, np.uint8)
    cv2.rectangle(boom, (420, 280), (560, 292), 1, -1)
    truth = body | (boom > 0)
    ramp = np.linspace(0, 1, shape[1])[None, :, None]
    background = np.array([215.0, 220, 210]) * (1 - ramp) + np.array([90.0, 110, 150]) * ramp + np.zeros(shape + (1,))
    image = _composite(background, truth, (170, 40, 35), rng)
    seeded = grabcut_segment(image, object_probability=_network_like_probability(body))
    assert seeded is not None and (seeded & (boom > 0)).sum() > 0.9 * (boom > 0).sum()
    assert _iou(seeded, truth) > 0.97


def test_a_learned_probability_that_saw_only_part_of_the_object_does_not_cut_the_rest_off():
    # An orange bar hanging from the top edge, over grey with orange strips down both sides:
    # the border shows the bar's colour, so the colour cues seed nothing, and the network saw
    # only the bar's top third. The sure background its seeds' reach drew cut the bar off 40 px
    # below what the network saw (IoU 0.53); GrabCut's foreground now pushes that reach out.
    shape = (400, 400)
    truth = np.zeros(shape, bool)
    truth[:260, 170:230] = True
    background = np.full(shape + (3,), (120.0, 130, 140))
    background[:, :12] = background[:, -12:] = (200, 120, 40)
    image = _composite(background, truth, (200, 120, 40), np.random.default_rng(12))
    seen = truth.copy()
    seen[110:] = False
    found = grabcut_segment(image, object_probability=_network_like_probability(seen))
    assert found is not None
    assert _iou(found, truth) > 0.9


def _labels_for(found: np.ndarray) -> np.ndarray:
    """GrabCut labels of a foreground it settled on: probable object on ``found``, probable background elsewhere."""
    return np.where(found, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)


def _brown_body_by_red(red_beyond: bool, hedging: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A brown body with a red piece on its right that GrabCut took as object: (image, body, red piece,
    network p). With ``red_beyond`` the red goes on as a large blob behind the body (a blob the
    network's blur lent p 0.8 next to the body); without, the red piece is all the red there is.
    A ``hedging`` network is sure (p > 0.9) of the body's lowest 29 % only, as the guitar network
    trained with people is of psb_m628's wood (26 % of it)."""
    shape = (240, 320)
    body = np.zeros(shape, np.uint8)
    cv2.ellipse(body, (150, 130), (60, 80), 0, 0, 360, 1, -1)
    body = body > 0
    piece = np.zeros(shape, bool)
    piece[90:170, 205:222] = True
    red = piece.copy()
    if red_beyond:
        blob = np.zeros(shape, np.uint8)
        cv2.circle(blob, (215, 130), 90, 1, -1)
        red |= (blob > 0) & ~body
    background = np.full(shape + (3,), (190.0, 200, 205))
    background[red] = (215, 45, 35)
    image = _composite(background, body, (120, 75, 45), np.random.default_rng(3))
    image[piece] = np.clip(np.array([215, 45, 35]) + np.random.default_rng(4).normal(0, 6, (piece.sum(), 3)), 0, 255)
    probability = np.where(body, 0.97, np.where(piece, 0.8, 0.05)).astype(np.float32)
    if hedging:
        probability[:157][body[:157]] = 0.8
    return image, body, piece, probability


@pytest.mark.parametrize("red_beyond, hedging", [(True, False), (False, False), (True, True), (False, True)])
def test_a_colour_the_background_shows_more_of_leaves_the_foreground(red_beyond, hedging):
    from frontal3d.stages.segment import _cut_background_colours, _foreground

    image, body, piece, probability = _brown_body_by_red(red_beyond, hedging)
    labels = _labels_for(body | piece)
    lab = cv2.GaussianBlur(cv2.cvtColor(image, cv2.COLOR_RGB2LAB).astype(np.float32), (0, 0), 1.5)
    _cut_background_colours(labels, probability, lab, image)
    found = _foreground(labels)
    assert _iou(found & body, body) > 0.97  # the body's own colour stays
    if red_beyond:
        assert (found & piece).sum() < 0.05 * piece.sum()  # the red the background is full of goes
    else:
        assert (found & piece).sum() > 0.9 * piece.sum()  # a red part of the object stays


def test_a_piece_the_network_rules_out_leaves_when_it_has_the_background_s_colour():
    # A dark blue car over a pale wall with a dark blob behind its roof (normalcar1 over blobs):
    # GrabCut took the blob's part above the roof, where the network gives p ~ 0. The network also
    # missed the car's rear wheel (p ~ 0, as on some car renders), but the tyre's colour is that
    # of the front wheel it is sure of, so the wheel stays. It missed the bonnet's tip, pale under
    # highlights, too (the shared beach wagon photo): nearer the wall's colour than the car's (32
    # and 110 Lab units), but not within 10 of it, so the tip stays.
    from frontal3d.stages.segment import _cut_unvouched_pieces, _foreground

    shape = (240, 400)
    body = np.zeros(shape, bool)
    body[100:170, 40:360] = True
    front_wheel, rear_wheel = np.zeros(shape, np.uint8), np.zeros(shape, np.uint8)
    cv2.circle(front_wheel, (100, 175), 25, 1, -1)
    cv2.circle(rear_wheel, (300, 175), 25, 1, -1)
    front_wheel, rear_wheel = front_wheel > 0, rear_wheel > 0
    blob = np.zeros(shape, np.uint8)
    cv2.ellipse(blob, (200, 60), (120, 55), 0, 0, 360, 1, -1)
    blob = (blob > 0) & ~body
    piece = blob.copy()
    piece[:50] = False  # GrabCut took the blob's lower part, next to the roof
    background = np.full(shape + (3,), (200.0, 200, 195))
    background[blob] = (45, 40, 40)
    tip = np.zeros(shape, bool)
    tip[110:160, 320:360] = True
    car = body | front_wheel | rear_wheel
    image = _composite(background, body, (50, 60, 120), np.random.default_rng(8))
    for wheel in (front_wheel, rear_wheel):
        image[wheel] = np.clip(20 + np.random.default_rng(9).normal(0, 4, (wheel.sum(), 3)), 0, 255)
    image[tip] = np.clip(165 + np.random.default_rng(10).normal(0, 4, (tip.sum(), 3)), 0, 255)
    probability = np.where((body & ~tip) | front_wheel, 0.97, 0.01).astype(np.float32)
    lab = cv2.GaussianBlur(cv2.cvtColor(image, cv2.COLOR_RGB2LAB).astype(np.float32), (0, 0), 1.5)
    labels = _labels_for(car | piece)
    _cut_unvouched_pieces(labels, probability, lab, image)
    found = _foreground(labels)
    assert (found & piece).sum() < 0.05 * piece.sum()
    assert (found & rear_wheel).sum() > 0.9 * rear_wheel.sum()
    assert (found & tip).sum() > 0.9 * tip.sum()
    assert _iou(found & car, car) > 0.97


def test_the_backdrop_grabcut_keeps_around_the_object_leaves_under_the_network_s_haze():
    # A brown guitar-like body on a flat black backdrop (the people composites with no mask): a
    # person crossing the border bends the background model, and GrabCut keeps a wide band of
    # the backdrop around the body. The network is sure of the body but, on black, never quite
    # rules the rest out: p 0.06 everywhere else, above the 0.03 the test once asked for.
    from frontal3d.stages.segment import _cut_unvouched_pieces, _foreground

    shape = (300, 300)
    body = np.zeros(shape, np.uint8)
    cv2.ellipse(body, (150, 200), (50, 60), 0, 0, 360, 1, -1)
    body[40:150, 142:158] = 1
    body = body > 0
    band = cv2.dilate(body.astype(np.uint8), np.ones((61, 61), np.uint8)) > 0
    image = _composite(np.zeros(shape + (3,)), body, (150, 100, 60), np.random.default_rng(3))
    probability = np.where(body, 0.97, 0.06).astype(np.float32)
    lab = cv2.GaussianBlur(cv2.cvtColor(image, cv2.COLOR_RGB2LAB).astype(np.float32), (0, 0), 1.5)
    labels = _labels_for(band)
    _cut_unvouched_pieces(labels, probability, lab, image)
    found = _foreground(labels)
    assert (found & ~body).sum() < 0.05 * (band & ~body).sum()
    assert _iou(found & body, body) > 0.97


def test_long_thin_gaps_the_network_vouches_for_join_the_foreground_and_corners_do_not():
    from frontal3d.stages.segment import _fill_vouched_strips, _foreground

    shape = (400, 400)
    truth = _airplane_mask(shape)
    strip = np.zeros(shape, bool)
    strip[110:290, 192:196] = True  # a fuselage's shaded side GrabCut gave to the background
    strip &= truth
    speck = np.zeros(shape, bool)
    speck[150:156, 215:221] = True  # clutter beside the fuselage, 2 px from it
    image = _composite(np.full(shape + (3,), (90.0, 120, 160)), truth, (225, 225, 228), np.random.default_rng(5))
    image[strip] = (150, 150, 155)  # darker than the lit fuselage, nothing like the sky
    lab = cv2.GaussianBlur(cv2.cvtColor(image, cv2.COLOR_RGB2LAB).astype(np.float32), (0, 0), 1.5)
    probability = _network_like_probability(truth)
    corner = (probability > 0.5) & ~truth & ~speck  # the network's blur past concave corners
    labels = _labels_for((truth & ~strip) | speck)
    _fill_vouched_strips(labels, probability, lab)
    found = _foreground(labels)
    assert (found & strip).sum() > 0.95 * strip.sum()
    assert not (found & corner).any()
    assert not (found & ~truth & ~speck).any()  # nothing bridges the gap to the speck


def _guitar_with_a_pale_neck(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A dark guitar on a grainy beige carpet whose grey fretboard, 8 px wide, lies 11 Lab units
    below the carpet's lightness (the shared two-guitar photo's case): (image, truth, neck)."""
    shape = (360, 320)
    truth = np.zeros(shape, np.uint8)
    cv2.ellipse(truth, (160, 270), (70, 60), 0, 0, 360, 1, -1)
    neck = np.zeros(shape, np.uint8)
    neck[50:215, 156:164] = 1
    cv2.rectangle(truth, (150, 20), (170, 55), 1, -1)  # the headstock
    truth = (truth > 0) | (neck > 0)
    carpet = np.full(shape + (3,), (205.0, 200, 185)) + rng.normal(0, 9, shape)[..., None]
    image = _composite(carpet, truth, (90, 40, 30), rng).astype(np.float64)
    image[neck > 0] = np.clip(np.array([172.0, 170, 168]) + rng.normal(0, 6, (int(neck.sum()), 3)), 0, 255)
    return image.astype(np.uint8), truth, neck > 0


def test_a_thin_part_the_network_sees_stays_though_its_colour_is_near_the_background_s():
    image, truth, neck = _guitar_with_a_pale_neck(np.random.default_rng(3))
    found = grabcut_segment(image, object_probability=_network_like_probability(truth))
    assert found is not None
    assert (found & neck).sum() > 0.9 * neck.sum()
    assert _iou(found, truth) > 0.95


def test_a_thin_stroke_the_network_strays_onto_over_grain_is_not_made_sure_foreground(monkeypatch):
    # The network's p also runs out onto grain in thin fragments, in the grain's colour: forced
    # in as sure foreground, they teach GrabCut's object model the grain (a car over pink grain
    # took a third of it in).
    from frontal3d.stages import segment

    rng = np.random.default_rng(4)
    shape = (300, 400)
    truth = _car_like_mask((480, 640))[150:450, 60:460]
    grain = cv2.resize(rng.normal(0, 25, (75, 100)), shape[::-1], interpolation=cv2.INTER_NEAREST)
    image = _composite(np.clip(np.full(shape + (3,), (215.0, 180, 200)) + grain[..., None], 0, 255), truth, (30, 40, 120), rng)
    stroke = np.zeros(shape, np.uint8)
    cv2.line(stroke, (140, 60), (10, 8), 1, 6)  # 140 px long, out of the car's cabin
    stroke = (stroke > 0) & ~truth
    probability = np.maximum(_network_like_probability(truth), np.minimum(1.0, cv2.GaussianBlur(stroke.astype(np.float32), (0, 0), 2) * 1.5))
    drawn = []
    original = segment._sure_thin_parts

    def recording(*args):
        drawn.append(original(*args))
        return drawn[-1]

    monkeypatch.setattr(segment, "_sure_thin_parts", recording)
    found = grabcut_segment(image, object_probability=probability)
    assert found is not None and _iou(found, truth) > 0.95
    assert len(drawn) == 1 and not (segment._dilated(drawn[0], 3) & stroke).any()


def test_a_thin_gap_showing_the_background_stays_a_gap():
    # The slit between a pick-up's cab and its bed over a plain wall: thin, long and vouched for
    # by the network's blur like a shaded strip, but its colour is the wall's.
    from frontal3d.stages.segment import _fill_vouched_strips, _foreground

    shape = (300, 400)
    truth = np.zeros(shape, bool)
    truth[100:200, 60:340] = True
    slit = np.zeros(shape, bool)
    slit[100:170, 200:203] = True
    truth &= ~slit
    image = _composite(np.full(shape + (3,), (110.0, 115, 140)), truth, (30, 60, 170), np.random.default_rng(6))
    lab = cv2.GaussianBlur(cv2.cvtColor(image, cv2.COLOR_RGB2LAB).astype(np.float32), (0, 0), 1.5)
    probability = _network_like_probability(truth)
    labels = _labels_for(truth)
    _fill_vouched_strips(labels, probability, lab)
    assert (probability[slit] > 0.5).mean() > 0.8 and not (_foreground(labels) & slit).any()


def test_a_faint_shape_of_the_background_s_hue_leaves_though_the_edge_blend_is_believed():
    # A pale plane over grass with a faint lighter-grass shape touching it (psb_m1280 over mild
    # clutter). The blend of plane and grass along the plane's edge is believed (p 0.55) and lies
    # within 20 in hue of the shape, so hue measured from every believed colour kept the shape;
    # measured from the colours the network is sure of, it goes.
    from frontal3d.stages.segment import _cut_doubted_colours, _foreground

    shape = (240, 320)
    plane = np.zeros(shape, np.uint8)
    cv2.rectangle(plane, (60, 100), (260, 130), 1, -1)
    cv2.rectangle(plane, (150, 40), (170, 200), 1, -1)
    plane = plane > 0
    edge = (cv2.dilate(plane.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0) & ~plane
    faint = np.zeros(shape, np.uint8)
    cv2.ellipse(faint, (220, 80), (70, 45), 0, 0, 360, 1, -1)
    faint = (faint > 0) & ~plane & ~edge
    grey, light = np.array([200.0, 200, 205]), np.array([120.0, 160, 100])
    background = np.zeros(shape + (3,)) + (80, 130, 60)
    background[faint] = light
    background[edge] = 0.3 * grey + 0.7 * light
    image = _composite(background, plane, (200, 200, 205), np.random.default_rng(7))
    probability = np.where(plane, 0.95, np.where(edge, 0.55, np.where(faint, 0.05, 0.02))).astype(np.float32)
    lab = cv2.GaussianBlur(cv2.cvtColor(image, cv2.COLOR_RGB2LAB).astype(np.float32), (0, 0), 1.5)
    labels = _labels_for(plane | edge | faint)
    _cut_doubted_colours(labels, probability, lab, image)
    found = _foreground(labels)
    assert (found & faint).sum() < 0.02 * faint.sum()
    assert (found & plane).sum() > 0.99 * plane.sum()


def _guitar_with_face(neck_through_face: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A guitar mask (body and neck) with a face's blob stuck to it, the face's box, and the guitar alone."""
    guitar = np.zeros((320, 300), np.uint8)
    cv2.ellipse(guitar, (150, 240), (70, 60), 0, 0, 360, 1, -1)
    guitar[20:190, 140:160] = 1
    face_centre = (150, 90) if neck_through_face else (210, 175)
    face = np.zeros_like(guitar)
    cv2.circle(face, face_centre, 32, 1, -1)
    box = np.zeros(guitar.shape, bool)
    box[face_centre[1] - 45 : face_centre[1] + 33, face_centre[0] - 33 : face_centre[0] + 34] = True
    return (guitar | face) > 0, box, guitar > 0


def test_a_face_stuck_to_the_object_is_cut():
    from frontal3d.stages.segment import without_faces

    found, box, guitar = _guitar_with_face(neck_through_face=False)
    kept = without_faces(found, box)
    assert not (kept & box).any()
    assert (kept == (guitar & ~box)).all()


def test_a_neck_across_a_face_stays_and_the_face_beside_it_goes():
    from frontal3d.stages.segment import without_faces

    found, box, guitar = _guitar_with_face(neck_through_face=True)
    kept = without_faces(found, box)
    assert kept[box & guitar].mean() > 0.95  # the neck between where it enters the face and leaves it
    assert (kept & box & ~guitar).sum() <= 0.03 * (box & ~guitar & found).sum()


def test_faces_are_cut_from_what_the_segmenters_find_not_from_a_given_mask(monkeypatch):
    from frontal3d import pipeline
    from frontal3d.plugins import Plugins

    found, box, guitar = _guitar_with_face(neck_through_face=False)
    photo = np.zeros(found.shape + (3,), np.uint8)
    photo[guitar] = (150, 100, 60)
    photo[found & ~guitar] = (230, 180, 150)
    monkeypatch.setattr(pipeline.people_detector, "detect_faces", lambda image: box)
    plugins = Plugins()
    fam = plugins.family("guitar")
    settings = plugins.settings("guitar")

    def segmented(segmenter: str):
        def fake(plugins, rgb, fam, settings, user_mask, report):
            report.data["segmenter"] = segmenter
            return found.copy() if user_mask is None else user_mask
        monkeypatch.setattr(pipeline, "_segment", fake)
        report = pipeline.Report()
        return pipeline.segment_object(plugins, photo, fam, settings, user_mask=found if segmenter == "user mask" else None,
                                       report=report).segmented, report.data

    mask, data = segmented("learned segmenter (weights/segmenter.pt)")
    assert not (mask & box).any() and data["face_pixels_cut"] == int((found & box).sum())
    mask, data = segmented("user mask")
    assert (mask == found).all() and "face_pixels_cut" not in data

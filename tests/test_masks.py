"""frontal3d.masks' morphology by radius agrees with OpenCV's disc morphology at every radius."""

import cv2
import numpy as np
import pytest

from frontal3d.masks import disc, inset, opened, within


def _blobs(seed: int, shape: tuple[int, int] = (160, 200)) -> np.ndarray:
    """A few filled ellipses and a thin line: convex and slender parts, pieces near the border."""
    rng = np.random.default_rng(seed)
    image = np.zeros(shape, np.uint8)
    for _ in range(4):
        centre = (int(rng.integers(0, shape[1])), int(rng.integers(0, shape[0])))
        axes = (int(rng.integers(5, 40)), int(rng.integers(5, 40)))
        cv2.ellipse(image, centre, axes, float(rng.uniform(0, 180)), 0, 360, 1, -1)
    cv2.line(image, (10, 150), (190, 20), 1, 2)
    return image > 0


def _same_but_the_rim(ours: np.ndarray, theirs: np.ndarray) -> bool:
    """Whether the masks agree but for a two-pixel rim along ``theirs``'s outline and a sliver
    (a part barely as wide as the disc) of at most 2 % of their union."""
    theirs_u8 = theirs.astype(np.uint8)
    rim = np.ones((5, 5), np.uint8)
    ring = (cv2.dilate(theirs_u8, rim) > 0) & ~(cv2.erode(theirs_u8, rim) > 0)
    return np.count_nonzero((ours ^ theirs) & ~ring) <= 0.02 * max(np.count_nonzero(ours | theirs), 1)


@pytest.mark.parametrize("radius", [1, 8, 21, 40])
def test_within_inset_and_opened_match_disc_morphology(radius):
    for seed in range(3):
        mask = _blobs(seed)
        kernel = disc(radius)
        dilated = cv2.dilate(mask.astype(np.uint8), kernel) > 0
        eroded = cv2.erode(mask.astype(np.uint8), kernel) > 0
        opening = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, kernel) > 0
        # The same up to OpenCV's rounding of the disc (its rows are a pixel wider or narrower).
        assert _same_but_the_rim(within(mask, radius), dilated)
        assert _same_but_the_rim(inset(mask, radius), eroded)
        assert _same_but_the_rim(opened(mask, radius), opening)
        assert np.all(inset(mask, radius) <= mask) and np.all(opened(mask, radius) <= mask)


def test_within_reaches_exactly_the_radius():
    mask = np.zeros((81, 81), bool)
    mask[40, 40] = True
    grown = within(mask, 30)  # past DISC_MORPHOLOGY_MAX_RADIUS: the distance transform
    assert grown[40, 70] and grown[70, 40] and not grown[40, 71]
    assert grown[61, 61] and not grown[62, 62]  # 29.7 px away is in, 31.1 px is not


def test_empty_masks_grow_to_nothing_and_full_ones_keep_everything():
    empty = np.zeros((30, 40), bool)
    full = np.ones((30, 40), bool)
    for radius in (5, 25):
        assert not within(empty, radius).any() and not opened(empty, radius).any()
        assert inset(full, radius).all()  # the image border is not the mask's outside

"""Silhouette warping: MLS inverse map and the fit of template renders to a mask."""

import cv2
import numpy as np
import pytest
from scipy import ndimage

from frontal3d.errors import InputError
from frontal3d.stages.warp import mls_inverse_map, warp_maps, warp_template_to_silhouette

TEMPLATE_RES = 128


def _pixel_grid(shape):
    cols, rows = np.meshgrid(np.arange(shape[1], dtype=float), np.arange(shape[0], dtype=float))
    return np.stack([cols, rows], axis=-1)


def _similarity(scale, angle, tx, ty):
    c, s = scale * np.cos(angle), scale * np.sin(angle)
    return np.array([[c, -s, tx], [s, c, ty]])


def _apply(matrix, points):
    return points @ matrix[:, :2].T + matrix[:, 2]


def _snowman(points):
    """Inside test of a two-disc 'guitar' in template pixels: body below, upper bout above."""
    x, y = points[..., 0], points[..., 1]
    body = (x - 64) ** 2 + (y - 78) ** 2 < 34**2
    bout = (x - 64) ** 2 + (y - 40) ** 2 < 24**2
    return body | bout, body


def _template_maps():
    inside, body = _snowman(_pixel_grid((TEMPLATE_RES, TEMPLATE_RES)))
    radius2 = np.square(_pixel_grid(inside.shape) - [64, 70]).sum(-1)
    front = np.where(inside, 0.05 - 1e-6 * radius2, np.nan)
    normals = np.zeros(inside.shape + (3,))
    normals[inside] = [0.0, 0.0, 1.0]
    back_normals = -normals
    regions = np.where(inside, np.where(body, 0, 1), -1)
    return {
        "mask": inside,
        "front_depth": front,
        "back_depth": -front,
        "front_normals": normals,
        "back_normals": back_normals,
        "front_regions": regions,
        "back_regions": regions.copy(),
    }


def _template_contour(mask, count=300):
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contour = max(contours, key=len)[:, 0, :].astype(float)
    return contour[np.linspace(0, len(contour), count, endpoint=False).astype(int)]


def test_identical_pivots_give_identity_map():
    rng = np.random.default_rng(1)
    pivots = rng.uniform(0, 90, size=(40, 2))
    coords = mls_inverse_map(pivots, pivots, (70, 90))
    np.testing.assert_allclose(coords, _pixel_grid((70, 90)), atol=1e-4)


@pytest.mark.parametrize("grid_step", [1, 4])
def test_similarity_between_pivot_sets_is_reproduced_exactly(grid_step):
    rng = np.random.default_rng(2)
    out_pivots = rng.uniform(0, 100, size=(60, 2))
    matrix = _similarity(1.3, 0.4, 12.0, -5.0)
    coords = mls_inverse_map(out_pivots, _apply(matrix, out_pivots), (100, 100), grid_step=grid_step)
    np.testing.assert_allclose(coords, _apply(matrix, _pixel_grid((100, 100))), atol=1e-3)


def test_rigid_kind_reproduces_a_rotation():
    rng = np.random.default_rng(3)
    out_pivots = rng.uniform(0, 60, size=(30, 2))
    rotation = _similarity(1.0, -0.7, 3.0, 4.0)
    coords = mls_inverse_map(out_pivots, _apply(rotation, out_pivots), (60, 60), kind="rigid")
    np.testing.assert_allclose(coords, _apply(rotation, _pixel_grid((60, 60))), atol=1e-3)


def test_pixels_on_a_pivot_map_to_its_target_without_nan():
    out_pivots = np.array([[10.0, 10.0], [40.0, 12.0], [25.0, 45.0], [5.0, 30.0]])
    src_pivots = out_pivots + [[3.0, -2.0], [-1.0, 4.0], [2.0, 2.0], [0.0, -3.0]]
    coords = mls_inverse_map(out_pivots, src_pivots, (50, 50))
    assert np.isfinite(coords).all()
    for (x, y), target in zip(out_pivots.astype(int), src_pivots):
        np.testing.assert_allclose(coords[y, x], target, atol=1e-3)


def test_coarse_grid_stays_close_to_the_full_evaluation():
    angles = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    out_pivots = np.stack([100 + 70 * np.cos(angles), 100 + 50 * np.sin(angles)], axis=1)
    src_pivots = out_pivots + 4 * np.stack([np.sin(3 * angles), np.cos(2 * angles)], axis=1)
    full = mls_inverse_map(out_pivots, src_pivots, (200, 200))
    coarse = mls_inverse_map(out_pivots, src_pivots, (200, 200), grid_step=4)
    inside = np.square(_pixel_grid((200, 200)) - 100).sum(-1) < 45**2
    assert np.abs(full - coarse)[inside].max() < 0.25


def test_warp_maps_does_not_bleed_nan_into_valid_pixels():
    depth = np.full((20, 20), np.nan)
    depth[5:15, 5:15] = 1.0
    labels = np.where(np.isfinite(depth), 3, -1)
    coords = _pixel_grid((20, 20)) + 0.5  # every sample straddles four source pixels
    warped = warp_maps({"depth": depth, "labels": labels}, coords, nearest={"labels"})
    nearest = np.clip(np.rint(coords).astype(int), 0, 19)
    nearest_valid = np.isfinite(depth)[nearest[..., 1], nearest[..., 0]]
    np.testing.assert_array_equal(np.isfinite(warped["depth"]), nearest_valid)
    np.testing.assert_allclose(warped["depth"][nearest_valid], 1.0)
    assert set(np.unique(warped["labels"])) == {-1, 3}


def _warp_scene(stretch=(1.25, 0.9), out_equals_src=False):
    """Template aligned by a similarity, then stretched anisotropically into the object."""
    maps = _template_maps()
    to_image = _similarity(1.5, 0.2, 20.0, 10.0)
    centre = _apply(to_image, np.array([64.0, 64.0]))
    stretch_matrix = np.diag(stretch)
    template_points = _template_contour(maps["mask"])
    src_pivots = _apply(to_image, template_points)
    out_pivots = src_pivots if out_equals_src else (src_pivots - centre) @ stretch_matrix.T + centre
    image = _pixel_grid((240, 280))
    unstretched = (image - centre) @ np.linalg.inv(stretch_matrix).T + centre
    to_template = np.linalg.inv(np.vstack([to_image, [0, 0, 1]]))[:2]
    object_mask, _ = _snowman(_apply(to_template, unstretched if not out_equals_src else image))
    result = warp_template_to_silhouette(object_mask, maps, to_image, out_pivots, src_pivots)
    return maps, object_mask, result


def test_warped_front_and_back_cover_exactly_the_object_mask():
    _, object_mask, result = _warp_scene()
    for name in ("front_depth", "back_depth"):
        np.testing.assert_array_equal(np.isfinite(result.__dict__[name]), object_mask)
    for name in ("front_regions", "back_regions"):
        assert (result.__dict__[name][object_mask] >= 0).all()
        assert (result.__dict__[name][~object_mask] == -1).all()
    for name in ("front_normals", "back_normals"):
        np.testing.assert_allclose(np.linalg.norm(result.__dict__[name][object_mask], axis=-1), 1.0, atol=1e-5)
        assert (result.__dict__[name][~object_mask] == 0).all()
    assert (result.back_depth[object_mask] < result.front_depth[object_mask]).all()


def test_object_boundary_comes_from_the_template_boundary():
    maps, object_mask, result = _warp_scene()
    object_edge = object_mask & ~ndimage.binary_erosion(object_mask)
    template_edge = maps["mask"] & ~ndimage.binary_erosion(maps["mask"])
    distance_to_edge = ndimage.distance_transform_edt(~template_edge)
    sources = result.source_coords[object_edge]
    rows = np.clip(np.rint(sources[:, 1]).astype(int), 0, TEMPLATE_RES - 1)
    cols = np.clip(np.rint(sources[:, 0]).astype(int), 0, TEMPLATE_RES - 1)
    # Template pixels are 1.5 image pixels wide here: "within one image pixel" plus rounding.
    assert distance_to_edge[rows, cols].max() <= 1.0 / 1.5 + 1.0


def test_regions_follow_the_warp():
    _, object_mask, result = _warp_scene()
    rows = np.nonzero(object_mask.any(axis=1))[0]
    top_row, bottom_row = rows.min(), rows.max()
    assert (result.front_regions[top_row][object_mask[top_row]] == 1).all()
    assert (result.front_regions[bottom_row][object_mask[bottom_row]] == 0).all()


def test_local_scale_is_the_alignment_scale_when_mls_is_identity():
    _, object_mask, result = _warp_scene(out_equals_src=True)
    np.testing.assert_allclose(result.local_scale[object_mask], 1.5, rtol=0.01)
    _, _, stretched = _warp_scene(stretch=(1.2, 1.2))
    interior = ndimage.binary_erosion(object_mask, iterations=10)
    assert np.median(stretched.local_scale[interior]) == pytest.approx(1.5 * 1.2, rel=0.03)


def test_local_scale_stays_bounded_where_crossing_pivots_fold_the_map():
    maps = _template_maps()
    to_image = _similarity(1.5, 0.0, 20.0, 10.0)
    src_pivots = _apply(to_image, _template_contour(maps["mask"]))
    out_pivots = src_pivots.copy()
    out_pivots[100:110] = out_pivots[100:110][::-1]  # a run matched backwards
    to_template = np.linalg.inv(np.vstack([to_image, [0, 0, 1]]))[:2]
    object_mask, _ = _snowman(_apply(to_template, _pixel_grid((240, 280))))
    result = warp_template_to_silhouette(object_mask, maps, to_image, out_pivots, src_pivots)
    typical = np.median(result.local_scale[object_mask])
    assert typical == pytest.approx(1.5, rel=0.05)
    assert result.local_scale.max() <= 2 * typical + 1e-5
    assert result.local_scale.min() >= typical / 2 - 1e-5


def test_empty_mask_and_degenerate_pivots_are_user_errors():
    maps = _template_maps()
    identity = _similarity(1.0, 0.0, 0.0, 0.0)
    pivots = _template_contour(maps["mask"])
    with pytest.raises(InputError, match="empty"):
        warp_template_to_silhouette(np.zeros((50, 50), bool), maps, identity, pivots, pivots)
    with pytest.raises(InputError, match="pivots"):
        mls_inverse_map(np.ones((5, 2)), np.zeros((5, 2)), (10, 10))


def _shrunk_scene(maps, shift):
    """The template placed at 0.6x (each image pixel stands for 1.7 template pixels), identity MLS."""
    to_image = _similarity(0.6, 0.0, 10.0 + shift, 8.0 + 0.7 * shift)
    src_pivots = _apply(to_image, _template_contour(maps["mask"]))
    to_template = np.linalg.inv(np.vstack([to_image, [0, 0, 1]]))[:2]
    object_mask, _ = _snowman(_apply(to_template, _pixel_grid((100, 100))))
    return object_mask, warp_template_to_silhouette(object_mask, maps, to_image, src_pivots, src_pivots.copy())


def test_a_one_pixel_ridge_keeps_its_height_when_the_warp_shrinks_the_template():
    # An airplane's fin seen from above: one template pixel wide, far above the body.
    maps = _template_maps()
    maps["front_depth"][50:90, 64] = 0.5
    maps["back_depth"][50:90, 63] = -0.4
    for shift in np.linspace(0.0, 1.0, 6):
        _, result = _shrunk_scene(maps, shift)
        assert np.nanmax(result.front_depth) == pytest.approx(0.5)
        assert np.nanmin(result.back_depth) == pytest.approx(-0.4)


def test_smooth_depth_is_not_moved_by_the_ridge_keeping():
    maps = _template_maps()
    object_mask, result = _shrunk_scene(maps, 0.37)
    interior = ndimage.binary_erosion(object_mask, iterations=2)
    expected = 0.05 - 1e-6 * np.square(result.source_coords - [64, 70]).sum(-1)
    # the slope of the dome over half a 3-pixel window, at most
    np.testing.assert_allclose(result.front_depth[interior], expected[interior], atol=2e-4)

"""Texture stage: the photo lands back on the front, the back follows the family rule,
the rim stretches the silhouette pixels, and the atlas keeps the photo's resolution."""

import cv2
import numpy as np
import pytest

from frontal3d.back_rules import BUILTIN_BACK_RULES, mirror_front, solid_from_region, synthesize_from_region
from frontal3d.errors import ConfigError, InputError
from frontal3d.preview import render_view
from frontal3d.stages.mesh import build_mesh
from frontal3d.stages.texture import build_textured_mesh

PIXEL_SIZE = 0.01  # metres per working pixel
REGIONS = ("body", "neck")


def _scene(scale=4, occluded=False):
    """A guitar-like working mask (round body + neck), meshed, and its full-res photo."""
    rows, cols = np.mgrid[:60, :50]
    work_mask = ((cols - 25) ** 2 / 20**2 + (rows - 38) ** 2 / 18**2 < 1) | ((np.abs(cols - 25) < 4) & (rows > 3))
    front_z = np.where(work_mask, 0.05 + 0.02 * np.cos((cols - 25) / 20), np.nan)
    back_z = np.where(work_mask, -0.05, np.nan)
    mesh_result = build_mesh(work_mask, front_z, back_z, PIXEL_SIZE, smooth_iterations=0)
    height, width = 60 * scale, 50 * scale
    mask = cv2.resize(work_mask.astype(np.uint8), (width, height), interpolation=cv2.INTER_NEAREST) > 0
    y, x = np.mgrid[:height, :width] / scale
    image = np.stack([x * 5, y * 4, 128 + 100 * np.sin(x / 1.3) * np.sin(y / 1.3)], axis=-1).clip(0, 255)
    image = image.astype(np.uint8)
    region_map = np.where(mask, np.where(y > 20, 0, 1), -1)
    occlusion = mask & ((x - 25) ** 2 + (y - 38) ** 2 < 5**2) if occluded else np.zeros_like(mask)
    return mesh_result, image, mask, region_map, occlusion


def _texture(scale=4, occluded=False, rule="mirror_front", params=None, bump=1.0):
    mesh_result, image, mask, region_map, occlusion = _scene(scale, occluded)
    textured = build_textured_mesh(mesh_result, image, mask, region_map, occlusion, REGIONS, rule,
                                   params, working_to_full=scale, bump_strength=bump)
    return textured, mesh_result, image, mask


def _psnr(a, b):
    mse = max(np.mean((a.astype(float) - b.astype(float)) ** 2), 1e-12)
    return 10 * np.log10(255**2 / mse)


def test_front_render_reprojects_the_photo():
    scale = 4
    textured, _, image, mask = _texture(scale)
    height, width = mask.shape
    full_pixel = PIXEL_SIZE / scale
    centre = np.array([width / 2 * full_pixel, -height / 2 * full_pixel, 0.0])
    rendered, hit = render_view(textured, np.array([0.0, 0.0, 1.0]), width, height, centre,
                                (width / 2 * full_pixel, height / 2 * full_pixel), shade=False)
    inner = cv2.erode(mask.astype(np.uint8), np.ones((2 * scale + 1, 2 * scale + 1), np.uint8),
                      borderType=cv2.BORDER_CONSTANT, borderValue=0) > 0
    assert hit[inner].all()
    psnr = _psnr(rendered[inner], image[inner])
    print(f"front reprojection PSNR: {psnr:.1f} dB")
    assert psnr > 30


def test_uvs_lie_in_the_unit_square_and_rim_ends_share_uvs():
    textured, mesh_result, _, _ = _texture()
    uv = np.asarray(textured.mesh.visual.uv)
    assert uv.min() >= 0 and uv.max() <= 1
    n_closed = len(mesh_result.mesh.vertices)
    rim = np.asarray(textured.mesh.vertices)[n_closed:]
    rim_uv = uv[n_closed:]
    assert len(rim) > 0
    # A front boundary vertex and its back twin share x, y (they differ only in depth).
    _, twin_group = np.unique(np.round(rim[:, :2], 9), axis=0, return_inverse=True)
    first_of_group = np.zeros(twin_group.max() + 1, int)
    first_of_group[twin_group[::-1]] = np.arange(len(rim))[::-1]
    np.testing.assert_allclose(rim_uv, rim_uv[first_of_group[twin_group]])
    assert np.bincount(twin_group).min() == 2


def test_front_and_back_vertices_map_to_their_own_halves():
    textured, mesh_result, _, _ = _texture()
    uv = np.asarray(textured.mesh.visual.uv)[: len(mesh_result.vertex_side)]
    assert np.all(uv[mesh_result.vertex_side == 0, 0] < 0.5)
    assert np.all(uv[mesh_result.vertex_side == 1, 0] > 0.5)


def test_textured_mesh_keeps_a_watertight_copy():
    textured, mesh_result, _, _ = _texture()
    assert textured.watertight_mesh.is_watertight
    assert len(textured.mesh.faces) == len(mesh_result.mesh.faces)
    np.testing.assert_allclose(textured.mesh.area, textured.watertight_mesh.area)


def test_atlas_follows_the_input_resolution():
    small, _, _, _ = _texture(scale=2)
    large, _, _, _ = _texture(scale=4)
    ratio = np.array(large.atlas.shape[:2]) / np.array(small.atlas.shape[:2])
    np.testing.assert_allclose(ratio, 2.0, rtol=0.05)
    assert large.atlas.shape[1] % 2 == 0 and large.normal_map.shape == large.atlas.shape


def test_occluded_pixels_are_inpainted_in_the_front_texture():
    mesh_result, image, mask, region_map, occlusion = _scene(occluded=True)
    image[occlusion] = (0, 255, 0)
    textured = build_textured_mesh(mesh_result, image, mask, region_map, occlusion, REGIONS, "mirror_front",
                                   None, working_to_full=4)
    front_half = textured.atlas[:, : textured.atlas.shape[1] // 2]
    assert not np.any(np.all(front_half == (0, 255, 0), axis=-1))


def test_normal_map_is_flat_without_bump_and_tilted_at_texture_edges():
    flat, _, _, _ = _texture(bump=0.0)
    assert np.all(np.abs(flat.normal_map.astype(int) - (128, 128, 255)) <= 1)
    bumpy, _, _, _ = _texture(bump=4.0)
    assert np.abs(bumpy.normal_map[..., 0].astype(int) - 128).max() > 20


def test_mirror_front_back_is_the_flipped_front():
    _, image, mask, region_map, _ = _scene()
    back = mirror_front(image, mask, region_map, REGIONS, {})
    flipped = np.fliplr(mask)
    np.testing.assert_array_equal(back[flipped], np.fliplr(image)[flipped])
    assert not back[~flipped].any()


def test_synthesized_back_uses_only_the_named_region_colours():
    _, image, mask, region_map, _ = _scene()
    image[region_map == 0] = np.clip(image[region_map == 0].astype(int) // 2, 0, 120)  # body: dark
    image[region_map == 1] = (250, 250, 250)  # neck: white
    back = synthesize_from_region(image, mask, region_map, REGIONS, {"region": "body"})
    flipped = np.fliplr(mask)
    assert back[flipped].max() <= 120
    assert not back[~flipped].any()


def test_synthesized_back_leaves_out_a_hole_in_the_body():
    """The body's largest square holds a dark f-hole; quilted, it would streak the whole
    back. The sample is taken clear of it, so no dark pixel reaches the back."""
    rng = np.random.default_rng(0)
    shape = (240, 160)
    mask = np.zeros(shape, np.uint8)
    cv2.ellipse(mask, (80, 120), (70, 110), 0, 0, 360, 1, -1)
    mask = mask > 0
    image = np.clip(rng.normal((170, 90, 40), 4, shape + (3,)), 0, 255).astype(np.uint8)  # wood, a little grain
    cv2.line(image, (80, 95), (86, 145), (25, 15, 10), 4)  # the f-hole, across the body's centre
    region_map = np.where(mask, 0, -1)

    back = synthesize_from_region(image, mask, region_map, REGIONS, {"region": "body"})

    assert back[np.fliplr(mask)][:, 0].min() > 120  # red: wood 170, the hole 25


def test_solid_back_is_the_region_mean_colour():
    _, image, mask, region_map, _ = _scene()
    back = solid_from_region(image, mask, region_map, REGIONS, {"region": "neck"})
    expected = np.rint(image[region_map == 1].mean(axis=0))
    np.testing.assert_array_equal(back[np.fliplr(mask)], np.broadcast_to(expected, back[np.fliplr(mask)].shape))


def test_back_rules_registry_and_errors():
    assert set(BUILTIN_BACK_RULES) >= {"synthesize_from_region", "mirror_front", "solid_from_region"}
    _, image, mask, region_map, _ = _scene()
    with pytest.raises(ConfigError, match="unknown region 'strings'"):
        synthesize_from_region(image, mask, region_map, REGIONS, {"region": "strings"})
    with pytest.raises(ConfigError, match="unknown back rule"):
        _texture(rule="paint_it_black")


def test_mismatched_mask_is_rejected():
    mesh_result, image, mask, region_map, occlusion = _scene()
    with pytest.raises(InputError, match="mask"):
        build_textured_mesh(mesh_result, image, mask[:-1], region_map, occlusion, REGIONS, "mirror_front",
                            None, working_to_full=4)

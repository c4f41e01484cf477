"""Meshing: closed, outward-oriented solids from front/back depth maps on any mask."""

import numpy as np
import open3d as o3d
import pytest
from scipy import ndimage

from frontal3d.errors import ConfigError, InputError
from frontal3d.stages.mesh import MAX_SMOOTHING_SHIFT_PIXELS, apply_symmetry, build_mesh

PIXEL_SIZE = 0.01


def _grid(shape):
    return np.mgrid[: shape[0], : shape[1]].astype(float)


def _disk(shape=(80, 80), centre=(40, 40), radius=30):
    rows, cols = _grid(shape)
    return (rows - centre[0]) ** 2 + (cols - centre[1]) ** 2 < radius**2


def _ring():
    return _disk(radius=32) & ~_disk(radius=14)


def _two_blobs():
    return _disk((60, 120), (30, 30), 22) | _disk((60, 120), (30, 88), 18)


def _pinches():
    """Squares meeting at one pixel corner, at one shared pixel, an isolated pixel and a 1-px line."""
    mask = np.zeros((50, 50), bool)
    mask[2:10, 2:10] = True
    mask[10:18, 10:18] = True  # diagonal pixel pinch with the first square
    mask[20:28, 2:10] = True
    mask[27:35, 9:17] = True  # shares pixel (27, 9) with the square above: a block-corner pinch
    mask[40, 40] = True
    mask[45, 20:31] = True
    return mask


def _dome(mask, height=0.2):
    """Rounded front and flat back, in metres."""
    depth = ndimage.distance_transform_edt(mask) * PIXEL_SIZE
    front = np.where(mask, 0.02 + height * np.sqrt(depth / max(depth.max(), 1e-9)), np.nan)
    back = np.where(mask, -0.02, np.nan)
    return front, back


def _silhouette(mesh, shape):
    """Pixels whose ray (along -Z, nudged off the vertex at the pixel centre) hits the mesh."""
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(mesh.faces.astype(np.uint32))
    )
    rows, cols = _grid(shape)
    origins = np.stack([(cols + 0.6) * PIXEL_SIZE, -(rows + 0.53) * PIXEL_SIZE, np.full(shape, 10.0)], -1)
    directions = np.broadcast_to([0.0, 0.0, -1.0], origins.shape)
    rays = np.concatenate([origins, directions], -1).reshape(-1, 6).astype(np.float32)
    hits = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    return np.isfinite(hits).reshape(shape)


def _boundary_band(mask):
    """Pixels within one pixel (8-neighbourhood) of the mask's boundary."""
    square = np.ones((3, 3), bool)
    return ndimage.binary_dilation(mask, square) & ~ndimage.binary_erosion(mask, square)


def _assert_closed_solid(mesh):
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.volume > 0


MASKS = {"disk": (_disk, 2), "ring": (_ring, 0), "two_blobs": (_two_blobs, 4)}


@pytest.mark.parametrize("name", sorted(MASKS))
def test_masks_give_closed_solids_with_the_mask_silhouette(name):
    make_mask, euler_number = MASKS[name]
    mask = make_mask()
    result = build_mesh(mask, *_dome(mask), PIXEL_SIZE)
    _assert_closed_solid(result.mesh)
    assert result.mesh.euler_number == euler_number  # spheres per blob; the ring is a torus
    assert result.dropped_pixels == 0
    boundary_band = _boundary_band(mask)
    silhouette = _silhouette(result.mesh, mask.shape)
    assert not ((silhouette ^ mask) & ~boundary_band).any()


def test_pinches_and_stray_pixels_are_dropped_and_counted():
    mask = _pinches()
    result = build_mesh(mask, *_dome(mask), PIXEL_SIZE)
    _assert_closed_solid(result.mesh)
    assert result.dropped_pixels == 1 + 11  # the isolated pixel and the one-pixel line
    edges = result.mesh.edges_sorted
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert (uses == 2).all()
    boundary_band = _boundary_band(mask)
    assert not ((_silhouette(result.mesh, mask.shape) ^ mask) & ~boundary_band).any()


def test_random_masks_give_manifold_closed_solids():
    rng = np.random.default_rng(7)
    for density in (0.45, 0.6, 0.75, 0.9):
        mask = rng.random((40, 40)) < density
        result = build_mesh(mask, np.full(mask.shape, 0.05), np.zeros(mask.shape), PIXEL_SIZE)
        _assert_closed_solid(result.mesh)
        front = result.mesh.faces[(result.vertex_side[result.mesh.faces] == 0).all(axis=1)]
        edges = np.sort(np.concatenate([front[:, [0, 1]], front[:, [1, 2]], front[:, [2, 0]]]), axis=1)
        unique_edges, uses = np.unique(edges, axis=0, return_counts=True)
        boundary_degree = np.bincount(unique_edges[uses == 1].ravel(), minlength=len(result.vertex_side))
        assert np.isin(boundary_degree, [0, 2]).all()  # no pinched vertex anywhere


def test_slab_volume_is_area_times_thickness():
    mask = _disk((240, 240), (120, 120), 105)
    thickness = 0.05
    front = np.full(mask.shape, 0.03)
    result = build_mesh(mask, front, front - thickness, PIXEL_SIZE)
    expected = mask.sum() * PIXEL_SIZE**2 * thickness
    assert result.mesh.volume == pytest.approx(expected, rel=0.02)


def test_back_is_pushed_behind_the_front():
    mask = _disk()
    front = np.zeros(mask.shape)
    back = np.where(_disk(radius=15), 0.05, -0.01)  # crosses the front in the middle
    result = build_mesh(mask, front, back, PIXEL_SIZE, min_thickness=0.004)
    _assert_closed_solid(result.mesh)
    z = result.mesh.vertices[:, 2]
    front_z, back_z = z[result.vertex_side == 0], z[result.vertex_side == 1]
    assert (front_z - back_z >= 0.004 - 1e-12).all()


def test_vertices_stay_on_their_pixels_and_smoothing_removes_noise():
    mask = _disk()
    noise = np.random.default_rng(0).normal(0, 0.01, mask.shape)
    front, back = _dome(mask)
    rough = build_mesh(mask, front + noise, back, PIXEL_SIZE, smooth_iterations=0)
    smooth = build_mesh(mask, front + noise, back, PIXEL_SIZE, smooth_iterations=10)
    for result in (rough, smooth):
        np.testing.assert_allclose(result.mesh.vertices[:, 0], (result.vertex_pixel[:, 0] + 0.5) * PIXEL_SIZE)
        np.testing.assert_allclose(result.mesh.vertices[:, 1], -(result.vertex_pixel[:, 1] + 0.5) * PIXEL_SIZE)
    front_vertices = smooth.vertex_side == 0
    cols, rows = smooth.vertex_pixel[front_vertices].astype(int).T
    rough_error = rough.mesh.vertices[front_vertices, 2] - front[rows, cols]
    smooth_error = smooth.mesh.vertices[front_vertices, 2] - front[rows, cols]
    assert np.abs(smooth_error).mean() < 0.5 * np.abs(rough_error).mean()


def test_smoothing_keeps_a_tall_narrow_ridge():
    """A fin seen edge-on is a ridge a few pixels wide: smoothing must not flatten it."""
    mask = _disk()
    front, back = _dome(mask)
    ridge = np.zeros(mask.shape, dtype=bool)
    ridge[20:60, 39:42] = True
    fin_height = 40 * PIXEL_SIZE
    front = np.where(ridge, front + fin_height, front)
    result = build_mesh(mask, front, back, PIXEL_SIZE, smooth_iterations=10)
    front_vertices = result.vertex_side == 0
    cols, rows = result.vertex_pixel[front_vertices].astype(int).T
    on_ridge = ridge[rows, cols]
    lost = front[rows, cols][on_ridge] - result.mesh.vertices[front_vertices, 2][on_ridge]
    assert lost.max() <= MAX_SMOOTHING_SHIFT_PIXELS * PIXEL_SIZE + 1e-9


def test_front_and_back_twins_share_pixels():
    mask = _ring()
    result = build_mesh(mask, *_dome(mask), PIXEL_SIZE)
    half = len(result.vertex_side) // 2
    assert (result.vertex_side[:half] == 0).all() and (result.vertex_side[half:] == 1).all()
    np.testing.assert_array_equal(result.vertex_pixel[:half], result.vertex_pixel[half:])
    cols, rows = result.vertex_pixel[:half].astype(int).T
    assert mask[rows, cols].all()


def test_max_vertices_coarsens_the_grid_and_stays_closed():
    mask = _disk((200, 200), (100, 100), 90)
    result = build_mesh(mask, *_dome(mask), PIXEL_SIZE, max_vertices=3000)
    assert len(result.mesh.vertices) <= 3000
    _assert_closed_solid(result.mesh)
    full = build_mesh(mask, *_dome(mask), PIXEL_SIZE)
    assert result.mesh.volume == pytest.approx(full.mesh.volume, rel=0.1)


def test_unusable_inputs_are_user_errors():
    mask = _disk()
    front, back = _dome(mask)
    with pytest.raises(InputError, match="nothing to mesh"):
        build_mesh(np.zeros((10, 10), bool), np.zeros((10, 10)), np.zeros((10, 10)), PIXEL_SIZE)
    with pytest.raises(InputError, match="NaN"):
        build_mesh(mask, np.where(_disk(radius=20), front, np.nan), back, PIXEL_SIZE)
    with pytest.raises(InputError, match="do not match"):
        build_mesh(mask, front[:-1], back, PIXEL_SIZE)


def test_mirror_z_makes_the_back_mirror_the_front():
    mask = _disk()
    front, back = _dome(mask)
    mirrored_front, mirrored_back = apply_symmetry(front, back, mask, "mirror_z")
    np.testing.assert_allclose(mirrored_front, front)
    sums = (mirrored_front + mirrored_back)[mask]
    np.testing.assert_allclose(sums, sums[0])
    assert sums[0] / 2 == pytest.approx(np.median(((front + back) / 2)[mask]))
    kept_front, kept_back = apply_symmetry(front, back, mask, "none")
    np.testing.assert_allclose(kept_back, back)
    with pytest.raises(ConfigError, match="symmetry rule"):
        apply_symmetry(front, back, mask, "mirror_x")

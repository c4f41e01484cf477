"""The synthetic occlusion benchmark's composites (generated inputs only)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from frontal3d.eval_occlusion import OCCLUDED_SHARE, Cutout, arm_occluder, occluder_texels, paste_person, summarize, summary_lines
from frontal3d.errors import InputError


def _guitar(shape=(300, 300)) -> tuple[np.ndarray, np.ndarray]:
    """A blue drawn guitar on black: a body ellipse and a neck."""
    mask = np.zeros(shape, np.uint8)
    cv2.ellipse(mask, (150, 220), (60, 70), 0, 0, 360, 1, -1)
    mask[20:160, 140:160] = 1
    image = np.zeros(shape + (3,), np.uint8)
    image[mask > 0] = (40, 70, 150)
    return image, mask > 0


def _person() -> Cutout:
    """A head and shoulders in a blue shirt with a pink face."""
    mask = np.zeros((200, 160), np.uint8)
    cv2.circle(mask, (80, 40), 30, 1, -1)
    cv2.ellipse(mask, (80, 200), (80, 130), 0, 180, 360, 1, -1)
    rgb = np.zeros((200, 160, 3), np.uint8)
    rgb[:] = (40, 60, 200)
    rgb[:75] = (230, 170, 150)
    return Cutout("drawn", rgb, mask > 0)


def test_an_arm_hides_a_tenth_to_a_third_of_the_object_in_skin_tones():
    image, guitar = _guitar()
    for seed in range(5):
        composite = arm_occluder(image, guitar, np.random.default_rng(seed))
        assert OCCLUDED_SHARE[0] <= composite.share(guitar) <= OCCLUDED_SHARE[1]
        assert np.array_equal(composite.visible, guitar & ~composite.occluder)
        painted = composite.image[composite.occluder].astype(int)
        assert (painted[:, 0] > painted[:, 2]).mean() > 0.95  # skin: more red than blue
        assert np.array_equal(composite.image[~composite.occluder], image[~composite.occluder])
        # it reaches in from the image's border, as an arm does
        border = np.concatenate([composite.occluder[0], composite.occluder[-1], composite.occluder[:, 0], composite.occluder[:, -1]])
        assert border.any()


@pytest.mark.parametrize("mode", ["guitarist", "whole person"])
def test_a_pasted_person_hides_only_what_stands_in_front(mode):
    image, guitar = _guitar()
    composite = paste_person(image, guitar, _person(), mode, np.random.default_rng(3))
    assert OCCLUDED_SHARE[0] <= composite.share(guitar) <= OCCLUDED_SHARE[1]
    # the guitar is untouched where nothing is in front of it, and shows the person where something is
    assert np.array_equal(composite.image[composite.visible], image[composite.visible])
    assert not np.array_equal(composite.image[composite.occluder & guitar], image[composite.occluder & guitar])
    if mode == "guitarist":  # the body is seen around the guitar but is not counted as an occluder
        changed = np.any(composite.image != image, axis=2)
        assert (changed & ~guitar & ~composite.occluder).sum() > composite.occluder.sum()


def test_an_impossible_share_is_a_one_line_error():
    image, guitar = _guitar()
    thread = Cutout("thread", np.full((400, 1, 3), 200, np.uint8), np.ones((400, 1), bool))  # too thin to hide a tenth
    with pytest.raises(InputError, match="10-30 %"):
        paste_person(image, guitar, thread, "whole person", np.random.default_rng(0))


def test_occluder_pixels_left_counts_the_occluders_own_pixels_in_the_texture():
    image, guitar = _guitar()
    composite = arm_occluder(image, guitar, np.random.default_rng(1))
    rows, cols = np.nonzero(guitar)
    window = np.s_[rows.min() - 5 : rows.max() + 6, cols.min() - 5 : cols.max() + 6]
    as_seen = composite.image[window]
    inpainted = np.where(composite.occluder[window][..., None], image[window], as_seen)
    hidden_in_object = int((composite.occluder & guitar).sum())
    assert np.count_nonzero(occluder_texels(np.concatenate([as_seen, as_seen], axis=1), composite.image, image, composite.occluder, guitar)) == hidden_in_object
    assert np.count_nonzero(occluder_texels(np.concatenate([inpainted, inpainted], axis=1), composite.image, image, composite.occluder, guitar)) == 0


def test_only_texels_the_model_shows_count_when_told_which():
    """An outline left unrebuilt under an arm: the texels there lie beyond the silhouette and
    only pad its rim, so the count on the model leaves them out; the atlas count keeps them."""
    image, guitar = _guitar()
    composite = arm_occluder(image, guitar, np.random.default_rng(1))
    rows, cols = np.nonzero(guitar)
    window = np.s_[rows.min() - 5 : rows.max() + 6, cols.min() - 5 : cols.max() + 6]
    atlas = np.concatenate([composite.image[window], composite.image[window]], axis=1)
    hidden_in_object = int((composite.occluder & guitar).sum())
    notch = composite.occluder[window] & guitar[window]
    half_shown = notch & (np.arange(notch.shape[1]) % 2 == 0)  # every other column on the model
    assert hidden_in_object > 100
    left = occluder_texels(atlas, composite.image, image, composite.occluder, guitar)
    assert np.count_nonzero(left & ~notch) == 0
    assert np.count_nonzero(left & (~notch | half_shown)) == half_shown.sum()
    assert np.count_nonzero(occluder_texels(atlas, composite.image, image, composite.occluder, guitar)) == hidden_in_object


def test_the_texture_is_located_by_its_texels_taken_from_the_photo():
    """Bled beyond the silhouette, the atlas's margin holds the object's colours where the
    photo shows background: matched on every texel, the front lands off the object."""
    image, guitar = _guitar()
    image[guitar] = image[guitar] + np.random.default_rng(0).integers(0, 60, (int(guitar.sum()), 1)).astype(np.uint8)
    composite = arm_occluder(image, guitar, np.random.default_rng(1))
    rows, cols = np.nonzero(guitar)
    window = np.s_[rows.min() - 15 : rows.max() + 6, cols.min() - 40 : cols.max() + 41]
    front = composite.image[window].copy()
    beyond = ~guitar[window]
    front[beyond] = (40, 130, 210)  # the bled margin: bright, unlike the black background
    atlas = np.concatenate([front, front], axis=1)
    kept = int((composite.occluder & guitar).sum())
    assert np.count_nonzero(occluder_texels(atlas, composite.image, image, composite.occluder, guitar, beyond)) == kept


def test_a_made_up_texel_counts_only_when_the_object_shows_nowhere_its_colour():
    """The inpainting copies the object's own colours, and a dark wood may match a dark skin
    tone by chance: such a texel is not the occluder's. Skin it smeared in from outside is."""
    image, guitar = _guitar()
    image[guitar & (np.arange(300)[:, None] < 60)] = (90, 55, 35)  # a dark brown headstock
    composite = arm_occluder(image, guitar, np.random.default_rng(1))
    hidden = composite.occluder & guitar & (np.arange(300)[:, None] >= 60)
    rows, cols = np.nonzero(guitar)
    window = np.s_[rows.min() - 5 : rows.max() + 6, cols.min() - 5 : cols.max() + 6]
    dark, hidden_here = (90, 55, 35), hidden[window]
    composite.image[hidden] = dark  # an arm as dark as the headstock's wood
    front = np.where(composite.occluder[window][..., None], image[window], composite.image[window])
    front[hidden_here] = dark  # ... and the inpainting filled it with that wood
    synthesized = composite.occluder[window].copy()
    atlas = np.concatenate([front, front], axis=1)
    assert hidden.sum() > 50
    assert np.count_nonzero(occluder_texels(atlas, composite.image, image, composite.occluder, guitar)) == hidden.sum()  # not told apart
    assert np.count_nonzero(occluder_texels(atlas, composite.image, image, composite.occluder, guitar, synthesized)) == 0
    image[guitar & (np.arange(300)[:, None] < 60)] = (40, 70, 150)  # no wood that dark on the object: skin smeared in
    composite.image[guitar & ~composite.occluder] = image[guitar & ~composite.occluder]
    assert np.count_nonzero(occluder_texels(atlas, composite.image, image, composite.occluder, guitar, synthesized)) == hidden.sum()


def test_the_summary_compares_means_with_the_same_renders_unoccluded():
    rows = [
        {"mode": "guitarist", "occluded_share": 0.2, "rejected": "", "iou": 0.45, "iou_clean": 0.5, "chamfer_l1": 0.11, "chamfer_l1_clean": 0.1,
         "fscore": 0.8, "fscore_clean": 0.8, "occluder_pixels_left": 3, "iou_true_mask": 0.5, "chamfer_l1_true_mask": 0.1,
         "fscore_true_mask": 0.8, "subtype": "electric", "subtype_clean": "classical", "subtype_true_mask": "classical"},
        {"mode": "whole person", "occluded_share": 0.1, "rejected": "not frontal", "occluder_pixels_left": 0},
    ]
    summary = summarize(rows)
    overall = summary[0]
    assert overall["n"] == 2 and overall["scored"] == 1 and overall["rejected"] == 1
    assert overall["iou_change"] == pytest.approx(-0.1)
    assert overall["chamfer_l1_change"] == pytest.approx(0.1)
    assert overall["occluder_pixels_left"] == 3
    # the detected run took the classical guitar for an electric one; with the true mask it did not
    assert overall["subtype_changed"] == 1 and overall["subtype_changed_true_mask"] == 0
    assert "subtype changed: 1" in summary_lines(summary)[0] and "subtype changed: 0)" in summary_lines(summary)[0]


def test_the_command_has_help_and_names_a_missing_input_in_one_line(tmp_path, capsys):
    from frontal3d.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate-occlusion", "--help"])
    assert exit_info.value.code == 0 and "--occluders" in capsys.readouterr().out
    argv = ["evaluate-occlusion", "--family", "guitar", "--meshes", str(tmp_path), "--renders", str(tmp_path), "--occluders", "arms", "-o", str(tmp_path / "out")]
    assert main(argv) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("frontal3d: error: no *.glb meshes"), err


def _renders_folder(folder, count: int):
    """``count`` drawn guitars, each a little wider than the last, as the shared renders' layout."""
    paths = []
    for number in range(count):
        image, mask = _guitar()
        mask = cv2.dilate(mask.astype(np.uint8), np.ones((2 * number + 1,) * 2, np.uint8)) > 0
        image[mask] = (40, 70, 150)
        cv2.imwrite(str(folder / f"g{number}.png"), image[..., ::-1])
        cv2.imwrite(str(folder / f"g{number}_mask.png"), mask.astype(np.uint8) * 255)
        (folder / f"g{number}.json").write_text("{}")
        paths.append(folder / f"g{number}.glb")
    return paths


def test_a_slice_meets_the_composites_the_whole_run_gives_its_meshes(tmp_path):
    from frontal3d.eval_occlusion import selected_composites

    paths = _renders_folder(tmp_path, 4)

    def occluders(every: int, offset: int) -> dict[tuple[str, int], np.ndarray]:
        return {(path.stem, index): composite.occluder
                for path, _image, _mask, index, composite in selected_composites("arms", paths, tmp_path, 2, 7, every, offset)}

    whole, odd, even = occluders(1, 0), occluders(2, 1), occluders(2, 0)
    assert set(odd) == {("g1", 0), ("g1", 1), ("g3", 0), ("g3", 1)}
    assert set(odd) | set(even) == set(whole) and not set(odd) & set(even)
    for key, occluder in {**odd, **even}.items():
        assert np.array_equal(occluder, whole[key]), key
    assert not np.array_equal(whole[("g1", 0)], whole[("g3", 0)])


def test_a_slice_out_of_range_is_a_one_line_error(tmp_path):
    from frontal3d.errors import ConfigError
    from frontal3d.eval_occlusion import selected_composites

    paths = _renders_folder(tmp_path, 2)
    with pytest.raises(ConfigError, match="--offset in 0 .. every-1"):
        next(selected_composites("arms", paths, tmp_path, 1, 0, every=2, offset=2))


@pytest.mark.parametrize("segment", [False, True])
def test_with_segment_no_object_mask_is_given(tmp_path, monkeypatch, segment):
    """``--segment`` scores what a user with a photo and no mask gets: every reconstruction,
    the clean render's too, segments the object itself; otherwise the visible mask is given."""
    import trimesh
    from types import SimpleNamespace

    from frontal3d import eval_occlusion

    _renders_folder(tmp_path, 1)
    trimesh.creation.box().export(tmp_path / "g0.glb")
    given_masks = []

    def fake_reconstruct(plugins, family, image, mask, occluder, settings):
        given_masks.append(mask)
        sheet = {"occlusion_sheet": np.zeros((4, 12, 3), np.uint8)} if occluder is not None else {}
        return SimpleNamespace(report={}, mesh=None, maps=sheet,
                               textured=SimpleNamespace(atlas=None, front_synthesized=None, front_shown=np.ones((2, 2), bool)))

    monkeypatch.setattr(eval_occlusion, "_reconstruct", fake_reconstruct)
    monkeypatch.setattr(eval_occlusion, "evaluate_pair", lambda mesh, gt: dict.fromkeys(eval_occlusion.METRIC_KEYS, 0.5))
    monkeypatch.setattr(eval_occlusion, "occluder_texels", lambda *args: np.zeros((2, 2), bool))
    rows = eval_occlusion.run_occlusion_evaluation("guitar", tmp_path, tmp_path, "arms", None, tmp_path / "out", per_object=2,
                                                   progress=False, segment=segment)
    assert len(rows) == 2 and len(given_masks) == 3  # the clean render, then each composite
    assert sorted(p.name for p in (tmp_path / "out" / "images").glob("*_sheet.png")) == ["g0_0_sheet.png", "g0_1_sheet.png"]
    if segment:
        assert all(mask is None for mask in given_masks)
    else:
        assert all(isinstance(mask, np.ndarray) and mask.any() for mask in given_masks)

"""Learned classifiers made by the project's own commands: synth data, training, checkpoints, the chain."""

from __future__ import annotations

import csv
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import trimesh

from frontal3d.cli import main
from frontal3d.errors import ConfigError
from frontal3d.learned import load_classifier
from frontal3d.pipeline import reconstruct
from frontal3d.plugins import Plugins
from frontal3d.stages.classify import ClassifierContext, FrontalGate, SubtypeClassifier
from frontal3d.synth import FRONTAL_LIMIT_DEG, TURNED_RANGE_DEG


def _synth(out, count: int, seed: int = 5, resolution: int = 64) -> None:
    assert main(["synth", "--family", "car", "-n", str(count), "-o", str(out), "--seed", str(seed), "--resolution", str(resolution)]) == 0


def _rows(folder) -> list[dict[str, str]]:
    with (folder / "labels.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny car data set and one-epoch gate and subtype checkpoints trained on it."""
    root = tmp_path_factory.mktemp("learned")
    data = root / "data"
    _synth(data, 18, resolution=96)
    gate, subtype = root / "gate.pt", root / "subtype.pt"
    assert main(["train", "frontal", "--data", str(data), "-o", str(gate), "--epochs", "1"]) == 0
    assert main(["train", "subtype", "--data", str(data), "-o", str(subtype), "--epochs", "1"]) == 0
    return {"data": data, "gate": gate, "subtype": subtype, "root": root}


def _sample(data, index: int) -> tuple[np.ndarray, np.ndarray]:
    name = f"{index:06d}.png"
    image = cv2.cvtColor(cv2.imread(str(data / "images" / name)), cv2.COLOR_BGR2RGB)
    return image, cv2.imread(str(data / "masks" / name), cv2.IMREAD_GRAYSCALE) > 0


def test_synth_writes_consistent_images_masks_regions_and_labels_deterministically(tmp_path):
    first, second = tmp_path / "a", tmp_path / "b"
    _synth(first, 6)
    _synth(second, 6)
    rows = _rows(first)
    assert [row["file"] for row in rows] == [f"{i:06d}.png" for i in range(6)]
    assert {row["subtype"] for row in rows} == {"sedan", "suv", "sports"} and {row["family"] for row in rows} == {"car"}
    for row in rows:
        name = row["file"]
        image = cv2.imread(str(first / "images" / name))
        mask = cv2.imread(str(first / "masks" / name), cv2.IMREAD_GRAYSCALE) > 0
        regions = cv2.imread(str(first / "regions" / name), cv2.IMREAD_GRAYSCALE)
        assert image.shape == (64, 64, 3) and 0.02 < mask.mean() < 0.95
        np.testing.assert_array_equal(regions > 0, mask)  # region index + 1 exactly on the object
        assert regions.max() <= 4  # body, windows, wheels, lights
        largest_turn = max(abs(float(row["yaw"])), abs(float(row["pitch"])))
        if row["frontal"] == "1":
            assert largest_turn <= FRONTAL_LIMIT_DEG
        else:
            assert TURNED_RANGE_DEG[0] <= largest_turn <= TURNED_RANGE_DEG[1]
        for folder in ("images", "masks", "regions"):
            assert (first / folder / name).read_bytes() == (second / folder / name).read_bytes()
    assert (first / "labels.csv").read_text() == (second / "labels.csv").read_text()
    _synth(tmp_path / "c", 6, seed=6)
    assert (tmp_path / "c" / "images" / "000000.png").read_bytes() != (first / "images" / "000000.png").read_bytes()


def test_synth_grain_adds_fine_texture_to_backgrounds_and_nothing_else(tmp_path):
    plain, grainy = tmp_path / "plain", tmp_path / "grainy"
    _synth(plain, 8, resolution=128)
    assert main(["synth", "--family", "car", "-n", "8", "-o", str(grainy), "--seed", "5", "--resolution", "128", "--grain", "1"]) == 0
    assert main(["synth", "--family", "car", "-n", "1", "-o", str(tmp_path / "bad"), "--grain", "1.5"]) == 2
    for index in range(8):
        (image, mask), (grained, same_mask) = _sample(plain, index), _sample(grainy, index)
        np.testing.assert_array_equal(mask, same_mask)
        np.testing.assert_array_equal(image[mask], grained[mask])  # the object is untouched
        def fine(picture):  # detail finer than 3 px on the background
            grey = cv2.cvtColor(picture, cv2.COLOR_RGB2GRAY).astype(np.float32)
            return np.abs(grey - cv2.GaussianBlur(grey, (0, 0), 3))[~mask].mean()
        assert fine(grained) > fine(image)


def test_synth_clutter_puts_blobs_behind_the_object_and_leaves_it_untouched(tmp_path):
    plain, cluttered = tmp_path / "plain", tmp_path / "cluttered"
    _synth(plain, 8, resolution=128)
    assert main(["synth", "--family", "car", "-n", "8", "-o", str(cluttered), "--seed", "5", "--resolution", "128", "--clutter", "1"]) == 0
    assert main(["synth", "--family", "car", "-n", "1", "-o", str(tmp_path / "bad"), "--clutter", "-0.1"]) == 2
    ring_changed = []
    for index in range(8):
        (image, mask), (busy, same_mask) = _sample(plain, index), _sample(cluttered, index)
        np.testing.assert_array_equal(mask, same_mask)
        np.testing.assert_array_equal(image[mask], busy[mask])  # the object is untouched
        ring = cv2.dilate(mask.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool) & ~mask
        changed = np.abs(image.astype(int) - busy.astype(int)).max(axis=2) > 10
        ring_changed.append(changed[ring].mean())
    assert min(ring_changed) > 0.1  # every sample has clutter touching its outline


def test_synth_people_stand_behind_or_across_the_object_and_what_is_in_front_leaves_its_mask(tmp_path):
    plain, peopled = tmp_path / "plain", tmp_path / "peopled"
    _synth(plain, 8, resolution=128)
    assert main(["synth", "--family", "car", "-n", "8", "-o", str(peopled), "--seed", "5", "--resolution", "128", "--people", "1"]) == 0
    assert main(["synth", "--family", "car", "-n", "1", "-o", str(tmp_path / "bad"), "--people", "2"]) == 2
    hidden_shares, skin_beside = [], []
    for index in range(8):
        (image, mask), (busy, kept) = _sample(plain, index), _sample(peopled, index)
        assert not (kept & ~mask).any()  # a person never adds to the object
        hidden = mask & ~kept
        clear = kept & ~cv2.dilate(hidden.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
        np.testing.assert_allclose(image[clear], busy[clear], atol=2)  # the object away from the person's soft edge is untouched
        hidden_shares.append(1 - kept.sum() / mask.sum())
        changed = np.abs(image.astype(int) - busy.astype(int)).max(axis=2) > 10
        skin_beside.append(changed[~mask].mean())
    assert all(share <= 0.5 for share in hidden_shares)  # the object stays mostly seen
    assert sum(share > 0.01 for share in hidden_shares) >= 4  # arms or a body cross most objects
    assert min(skin_beside) > 0.02  # every sample shows a person beside the object


def test_trained_checkpoint_loads_and_reproduces_its_stored_prediction(trained):
    stored = torch.load(trained["subtype"], weights_only=True)
    model = load_classifier(trained["subtype"], "subtype", Plugins().family("car"))
    assert model.classes == ["sedan", "sports", "suv"] and model.task == "subtype" and model.family == "car"
    np.testing.assert_allclose(model.probabilities_of_crop(stored["reference_input"].numpy()), stored["reference_probabilities"], atol=1e-5)
    image, mask = _sample(trained["data"], 0)
    label, confidence, runner_up, runner_up_confidence = model.predict(image, mask)
    assert label in model.classes and runner_up in model.classes and label != runner_up
    assert 1.0 >= confidence >= runner_up_confidence >= 0.0
    assert load_classifier(trained["subtype"]).predict(image, mask) == (label, confidence, runner_up, runner_up_confidence)


def test_the_subtype_trains_as_a_resnet18_that_loads_and_replays(trained, capsys):
    """`train --arch resnet18` builds torchvision's ResNet-18 (its parameter count and module
    names), and the checkpoint loads, replays its reference and classifies like the compact one."""
    from frontal3d.train import ResNet18

    assert sum(p.numel() for p in ResNet18(1000).parameters()) == 11_689_512  # torchvision's resnet18()
    names = set(ResNet18(3).state_dict())
    assert {"conv1.weight", "bn1.running_mean", "layer1.1.conv2.weight", "layer2.0.downsample.0.weight", "fc.bias"} <= names
    assert not any(name.startswith("layer1.0.downsample") for name in names)

    out = trained["root"] / "subtype_resnet18.pt"
    assert main(["train", "subtype", "--data", str(trained["data"]), "-o", str(out), "--epochs", "1", "--arch", "resnet18"]) == 0
    assert "held-out accuracy" in capsys.readouterr().out
    assert torch.load(out, weights_only=True)["architecture"] == "resnet18_v1"
    model = load_classifier(out, "subtype", Plugins().family("car"))
    image, mask = _sample(trained["data"], 0)
    label, confidence, runner_up, _ = model.predict(image, mask)
    assert label in model.classes and runner_up in model.classes and 1.0 >= confidence > 0.0
    assert main(["train", "segmenter", "--data", str(trained["data"]), "-o", str(out), "--arch", "resnet18"]) != 0
    assert "--arch is for the frontal and subtype classifiers" in capsys.readouterr().err


def _one_line_config_error(path, task="subtype", family="car") -> str:
    with pytest.raises(ConfigError) as info:
        load_classifier(path, task, Plugins().family(family))
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    return message


def test_missing_corrupt_truncated_and_mismatched_checkpoints_give_one_line_errors(trained, tmp_path):
    assert "not found" in _one_line_config_error(tmp_path / "nope.pt")
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(np.random.default_rng(0).bytes(5000))
    assert "not a readable frontal3d checkpoint" in _one_line_config_error(garbage)
    truncated = tmp_path / "truncated.pt"
    content = trained["subtype"].read_bytes()
    truncated.write_bytes(content[: len(content) // 2])
    assert "not a readable frontal3d checkpoint" in _one_line_config_error(truncated)
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, other)
    assert "not a frontal3d checkpoint" in _one_line_config_error(other)

    assert "classifies 'frontal'" in _one_line_config_error(trained["gate"], task="subtype")
    assert "trained for family 'car', not 'guitar'" in _one_line_config_error(trained["subtype"], family="guitar")
    checkpoint = torch.load(trained["subtype"], weights_only=True)
    wrong_classes = tmp_path / "classes.pt"
    torch.save({**checkpoint, "classes": ["sedan", "suv", "truck"]}, wrong_classes)
    assert "do not match the car family's subtypes" in _one_line_config_error(wrong_classes)
    damaged = tmp_path / "damaged.pt"
    state = {k: (v + 0.5 if v.is_floating_point() else v) for k, v in checkpoint["state_dict"].items()}
    torch.save({**checkpoint, "state_dict": state}, damaged)
    assert "no longer reproduces" in _one_line_config_error(damaged)


def test_cli_reports_bad_weights_on_one_line(trained, tmp_path, capsys):
    image = tmp_path / "car.png"
    sample, mask = _sample(trained["data"], 0)
    cv2.imwrite(str(image), np.dstack([sample[..., ::-1], mask.astype(np.uint8) * 255]))
    code = main(["reconstruct", str(image), "--family", "car", "-o", str(tmp_path / "out"), "--set", f'weights={{subtype = "{trained["gate"]}"}}'])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and len(err) == 1 and "classifies 'frontal'" in err[0]


def _context(plugins: Plugins, image: np.ndarray, mask: np.ndarray, weights: dict[str, str]) -> ClassifierContext:
    from frontal3d.pipeline import _renders

    family = plugins.family("car")
    settings = plugins.settings("car", {"weights": weights, "template_resolution": 128})
    renders = {s: _renders(plugins, family, s, settings) for s in family.subtypes}
    return ClassifierContext(image=image, object_mask=mask, family=family, renders=renders, settings=settings)


def test_chain_has_one_classifier_per_name_and_uses_the_learned_one_only_with_weights(trained):
    plugins = Plugins()
    classifiers = [c for group in plugins.hook.frontal3d_classifiers(family=plugins.family("car")) for c in group]
    names = [c.name for c in classifiers]
    assert names.count("frontal") == 1 and names.count("subtype") == 1
    image, mask = _sample(trained["data"], 0)
    by_name = {c.name: c for c in classifiers}

    plain = _context(plugins, image, mask, {})
    assert by_name["frontal"].classify(plain) == FrontalGate().classify(plain)
    assert by_name["subtype"].classify(plain) == SubtypeClassifier().classify(plain)

    weighted = _context(plugins, image, mask, {"frontal": str(trained["gate"]), "subtype": str(trained["subtype"])})
    gate = by_name["frontal"].classify(weighted)
    probabilities = load_classifier(trained["gate"]).probabilities(image, mask)
    assert gate.confidence == pytest.approx(probabilities[1]) and gate.accepted == (probabilities[1] >= 0.5)
    assert "learned model gate.pt" in gate.reason
    subtype = by_name["subtype"].classify(weighted)
    expected = load_classifier(trained["subtype"]).predict(image, mask)
    assert (subtype.label, subtype.confidence, subtype.runner_up) == pytest.approx(expected[:3])
    assert "learned model subtype.pt" in subtype.reason


def test_reconstruction_reports_the_learned_decision_with_its_confidence(trained):
    frontal_index = next(i for i, row in enumerate(_rows(trained["data"])) if row["frontal"] == "1")
    image, mask = _sample(trained["data"], frontal_index)
    rgba = np.dstack([image, mask.astype(np.uint8) * 255])
    # Threshold 0 lets the training-free gate pass any view: this test is about the subtype decision.
    result = reconstruct(rgba, "car", weights={"subtype": str(trained["subtype"])}, frontal_threshold=0.0,
                         working_resolution=96, template_resolution=128)
    decision = next(d for d in result.report["decisions"] if d["name"] == "subtype")
    label, confidence, _, _ = load_classifier(trained["subtype"]).predict(rgba[..., :3], mask)
    assert decision["label"] == label == result.report["subtype"]
    assert decision["confidence"] == pytest.approx(confidence, abs=1e-4) and "learned model" in decision["reason"]


SHIPPED_GATES = sorted((Path(__file__).parents[1] / "families").glob("*/weights/frontal.pt"))


@pytest.mark.parametrize("checkpoint", SHIPPED_GATES, ids=lambda path: path.parts[-3])
def test_shipped_gate_loads_and_tells_its_template_frontal_from_turned_60_degrees(checkpoint):
    from frontal3d.photo_render import frontal_camera, render_frontal

    plugins = Plugins()
    family = plugins.family(checkpoint.parts[-3])
    model = load_classifier(checkpoint, "frontal", family)  # replays the stored reference prediction
    template = plugins.hook.frontal3d_template(family=family, subtype=family.subtypes[0], settings=plugins.settings(family.name))
    palette = np.array([[200, 60, 40, 255], [40, 40, 60, 255], [30, 30, 30, 255], [230, 200, 60, 255], [90, 160, 90, 255], [60, 90, 200, 255]], np.uint8)
    frontal_probability = {}
    for yaw in (0.0, 60.0):
        mesh = template.mesh.copy()
        mesh.visual = trimesh.visual.ColorVisuals(mesh, face_colors=palette[template.face_regions % len(palette)])
        mesh.apply_transform(trimesh.transformations.rotation_matrix(np.deg2rad(yaw), [0, 1, 0]))
        rgba = render_frontal(mesh, frontal_camera(mesh, 256, 0.8))
        frontal_probability[yaw] = model.probabilities(rgba[..., :3], rgba[..., 3] > 0)[model.classes.index("frontal")]
    assert frontal_probability[0.0] > 0.5 > frontal_probability[60.0]


def test_synth_shades_a_template_with_a_degenerate_triangle_like_the_same_template_without_it():
    from frontal3d.family import Template
    from frontal3d.synth import render_sample

    box = trimesh.creation.box(extents=[1.0, 0.6, 0.2])
    clean = Template("car", "sedan", box, np.zeros(len(box.faces), np.int64), ("body",))
    with_sliver = trimesh.Trimesh(box.vertices, np.vstack([[0, 0, 1], box.faces]), process=False)
    degenerate = Template("car", "sedan", with_sliver, np.zeros(len(with_sliver.faces), np.int64), ("body",))
    for index in range(3):
        expected = render_sample(clean, np.random.default_rng([0, index]), 64)
        found = render_sample(degenerate, np.random.default_rng([0, index]), 64)
        np.testing.assert_array_equal(found.mask, expected.mask)
        np.testing.assert_array_equal(found.image, expected.image)

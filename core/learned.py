"""Learned weak classifiers (paper 3.1.2): a small CNN on the masked object crop.

A checkpoint (written by ``frontal3d train``) is a plain dict of tensors, strings and
lists, loaded with ``torch.load(weights_only=True)`` so a checkpoint cannot run code. It
names its task (``frontal`` or ``subtype``), family, class names, input size and
architecture, and carries one reference input with the probabilities it gave at
training time: loading replays it, so a checkpoint whose weights were damaged, or that
this version computes differently, is refused instead of giving silent nonsense.

Torch is imported only when a checkpoint is loaded, so runs without weights start as
fast as before. The chain uses a learned model only when the family's ``weights`` setting names a
checkpoint for that classifier (``{"frontal": "gate.pt", "subtype": "subtype.pt"}``);
otherwise the training-free silhouette classifier of the same name answers.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import cv2
import numpy as np

from frontal3d.errors import ConfigError
from frontal3d.family import Family
from frontal3d.masks import mask_extent
from frontal3d.stages.classify import Classifier, ClassifierContext, Decision

if TYPE_CHECKING:
    import torch

#: Bump when the checkpoint layout changes meaning; older checkpoints are then refused.
FORMAT_VERSION = 1
ARCHITECTURE = "compact_resnet_v1"
#: The classifiers' larger option: torchvision's ResNet-18 layout (``train --arch resnet18``).
RESNET18_ARCHITECTURE = "resnet18_v1"
#: ``train --arch`` names of the classifier architectures.
CLASSIFIER_ARCHITECTURES = {"compact": ARCHITECTURE, "resnet18": RESNET18_ARCHITECTURE}
#: Side of the square crop the networks see (the paper's 3.1.2 crops to the object too).
INPUT_SIZE = 128
#: Channel widths of the four residual stages (about 0.3 M parameters, 1.2 MB).
WIDTHS = (16, 32, 64, 128)
#: Whole-object classifiers (this module) and dense per-pixel models (:mod:`frontal3d.learned_dense`).
CLASSIFIER_TASKS = ("frontal", "subtype")
DENSE_TASKS = ("segmenter", "regions")
TASKS = CLASSIFIER_TASKS + DENSE_TASKS
#: The dense tasks' small encoder-decoder.
DENSE_ARCHITECTURE = "tiny_unet_v1"
#: The architectures a checkpoint of each task may have.
ARCHITECTURES = {**{task: tuple(CLASSIFIER_ARCHITECTURES.values()) for task in CLASSIFIER_TASKS}, **{task: (DENSE_ARCHITECTURE,) for task in DENSE_TASKS}}
#: Class names of the frontal gate, in output order.
GATE_CLASSES = ("not frontal", "frontal")
#: Margin around the object's box kept in the crop, as a fraction of its long side.
CROP_MARGIN = 0.06
#: Largest difference allowed when replaying the stored reference prediction.
REFERENCE_TOLERANCE = 1e-3
_REQUIRED_KEYS = ("format_version", "task", "family", "classes", "input_size", "architecture", "widths", "state_dict", "reference_input", "reference_probabilities")


def crop_square(mask: np.ndarray) -> tuple[int, int, int]:
    """(top, left, side) of the square around the object's box plus margin; it may reach outside the image."""
    ys, xs = np.nonzero(mask)
    side = mask_extent(mask)
    side += 2 * int(np.ceil(CROP_MARGIN * side))
    centre_y, centre_x = (ys.min() + ys.max() + 1) // 2, (xs.min() + xs.max() + 1) // 2
    return int(centre_y - side // 2), int(centre_x - side // 2), side


def cut_square(array: np.ndarray, top: int, left: int, side: int) -> np.ndarray:
    """``array[top:top+side, left:left+side]``, zero-padded where the square leaves the image."""
    square = np.zeros((side, side) + array.shape[2:], array.dtype)
    src_y0, src_x0 = max(0, top), max(0, left)
    src_y1, src_x1 = min(array.shape[0], top + side), min(array.shape[1], left + side)
    square[src_y0 - top : src_y1 - top, src_x0 - left : src_x1 - left] = array[src_y0:src_y1, src_x0:src_x1]
    return square


def object_crop(image: np.ndarray, mask: np.ndarray, size: int = INPUT_SIZE) -> np.ndarray:
    """The object alone on black, its box (plus margin) padded to a square and resized: size x size x 3 uint8.

    Training and prediction both go through here, so the network sees the same kind of input.
    """
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return np.zeros((size, size, 3), np.uint8)
    object_only = np.where(mask[..., None], image[..., :3], 0).astype(np.uint8)
    return cv2.resize(cut_square(object_only, *crop_square(mask)), (size, size), interpolation=cv2.INTER_AREA)


def to_tensor(crops: np.ndarray) -> "torch.Tensor":
    """N x H x W x 3 uint8 crops -> N x 3 x H x W floats in [0, 1]."""
    import torch

    return torch.from_numpy(np.ascontiguousarray(crops)).permute(0, 3, 1, 2).float() / 255.0


@dataclass
class LoadedModel:
    """A loaded checkpoint: its network and what it was trained for (``training``: epochs, held-out score...)."""

    path: Path
    task: str
    family: str
    classes: list[str]
    input_size: int
    model: "torch.nn.Module"
    training: dict[str, Any]


class LearnedClassifier(LoadedModel):
    """A loaded classifier: predicts one of ``classes`` from a photo and the object's mask."""

    def probabilities(self, image: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """Class probabilities, in ``classes`` order."""
        return self.probabilities_of_crop(object_crop(image, mask, self.input_size))

    def predict(self, image: np.ndarray, mask: np.ndarray) -> tuple[str, float, str | None, float | None]:
        """(label, confidence, runner-up, runner-up confidence) for the object under ``mask``."""
        probabilities = self.probabilities(image, mask)
        order = np.argsort(-probabilities, kind="stable")
        runner_up = (self.classes[order[1]], float(probabilities[order[1]])) if len(order) > 1 else (None, None)
        return self.classes[order[0]], float(probabilities[order[0]]), *runner_up

    def probabilities_of_crop(self, crop: np.ndarray) -> np.ndarray:
        import torch

        with torch.no_grad():
            return torch.softmax(self.model(to_tensor(crop[None])), dim=1)[0].numpy().astype(np.float64)


def load_classifier(path: Path | str, task: str | None = None, family: Family | None = None) -> LearnedClassifier:
    """Load a checkpoint written by ``frontal3d train``, checking it fits ``task`` and ``family``.

    Raises :class:`ConfigError` with a one-line message for a missing, unreadable,
    corrupt or mismatched checkpoint (wrong task, family or classes).
    """
    from frontal3d.train import classifier_network

    path = Path(path)
    checkpoint = read_checkpoint(path, task)
    if checkpoint["task"] not in CLASSIFIER_TASKS:
        raise ConfigError(f"{path}: a {checkpoint['task']!r} checkpoint is not a classifier")
    if family is not None:
        gate = checkpoint["task"] == "frontal"
        check_family(path, checkpoint, family, list(GATE_CLASSES) if gate else sorted(family.subtypes), "gate" if gate else "subtypes")
    classes = [str(c) for c in checkpoint["classes"]]
    model = classifier_network(checkpoint["architecture"], len(classes), tuple(int(w) for w in checkpoint["widths"]))
    try:
        model.load_state_dict(checkpoint["state_dict"])
    except (RuntimeError, KeyError, TypeError) as exc:
        raise ConfigError(f"{path}: weights do not fit the {checkpoint['architecture']} network ({one_line(exc)})") from exc
    model.eval()
    classifier = LearnedClassifier(path, checkpoint["task"], checkpoint["family"], classes, int(checkpoint["input_size"]), model, dict(checkpoint.get("training", {})))
    check_reference(path, lambda: classifier.probabilities_of_crop(checkpoint["reference_input"].numpy()), checkpoint["reference_probabilities"])
    return classifier


def read_checkpoint(path: Path, task: str | None) -> dict[str, Any]:
    """The checkpoint dict at ``path``, refused with a one-line ConfigError when missing, corrupt, of another format or task."""
    import torch

    if not path.is_file():
        raise ConfigError(f"weights file not found: {path}")
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # a damaged file fails inside zipfile, pickle or torch with many exception types
        raise ConfigError(f"{path}: not a readable frontal3d checkpoint ({one_line(exc)})") from exc
    if not isinstance(checkpoint, dict) or any(key not in checkpoint for key in _REQUIRED_KEYS):
        raise ConfigError(f"{path}: not a frontal3d checkpoint (written by `frontal3d train`)")
    expected = ARCHITECTURES.get(checkpoint["task"], ())
    if checkpoint["format_version"] != FORMAT_VERSION or checkpoint["architecture"] not in expected:
        raise ConfigError(
            f"{path}: checkpoint format {checkpoint['format_version']} / {checkpoint['architecture']} is not the supported "
            f"{FORMAT_VERSION} / {' or '.join(expected) or 'any'}; retrain it with `frontal3d train`"
        )
    if task is not None and checkpoint["task"] != task:
        raise ConfigError(f"{path}: this checkpoint classifies {checkpoint['task']!r}, but it is configured as the {task!r} weights")
    return checkpoint


def check_reference(path: Path, replay: Callable[[], np.ndarray], reference: Any) -> None:
    """Refuse a checkpoint whose network no longer gives the stored reference output (damaged weights)."""
    try:
        reproduced = np.allclose(replay(), np.asarray(reference, dtype=np.float64), atol=REFERENCE_TOLERANCE)
    except (AttributeError, RuntimeError, ValueError, TypeError) as exc:
        raise ConfigError(f"{path}: corrupt checkpoint: its reference input cannot be replayed ({one_line(exc)})") from exc
    if not reproduced:
        raise ConfigError(f"{path}: corrupt checkpoint: it no longer reproduces its stored reference prediction")


def check_family(path: Path, checkpoint: dict[str, Any], family: Family, expected: list[str], what: str) -> None:
    """Refuse a checkpoint trained for another family, or whose classes are not the family's ``what``."""
    if checkpoint["family"] != family.name:
        raise ConfigError(f"{path}: trained for family {checkpoint['family']!r}, not {family.name!r}")
    if sorted(checkpoint["classes"]) != sorted(expected):
        raise ConfigError(
            f"{path}: classes {', '.join(checkpoint['classes'])} do not match the {family.name} family's {what} {', '.join(expected)}"
        )


def one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."


_LOADED: dict[tuple[str, str, str, float], Any] = {}


def cached_model(path: Path | str, task: str, family: Family, loader: Callable[[Path, str, Family], Any] | None = None) -> Any:
    """``loader`` (default :func:`load_classifier`), once per file version, task and family per process (a batch reuses the network)."""
    path = Path(path)
    key = (str(path.resolve()), task, family.name, path.stat().st_mtime if path.is_file() else 0.0)
    if key not in _LOADED:
        _LOADED[key] = (loader or load_classifier)(path, task, family)
    return _LOADED[key]


class WeightsOrDefault:
    """The chain's ``frontal`` or ``subtype`` classifier: learned when weights are configured, else the default.

    The classifiers hook is asked before settings are known, while plugins.toml and
    ``--set`` may configure weights per family; deciding at classify time, from the
    family's merged settings, keeps one classifier per name either way.
    """

    def __init__(self, default: Classifier):
        self.default = default
        self.name = default.name
        self.order = default.order

    def classify(self, context: ClassifierContext) -> Decision:
        weights = context.settings.get("weights") or {}
        if not weights.get(self.name):
            return self.default.classify(context)
        model = cached_model(weights[self.name], self.name, context.family)
        source = f"learned model {model.path.name}"
        if self.name == "subtype":
            label, confidence, runner_up, runner_up_confidence = model.predict(context.image, context.object_mask)
            return Decision(name=self.name, label=label, confidence=confidence, reason=f"{label}: {source}, confidence {confidence:.2f}",
                            runner_up=runner_up, runner_up_confidence=runner_up_confidence)
        probabilities = model.probabilities(context.image, context.object_mask)
        frontal_probability = float(probabilities[model.classes.index("frontal")])
        accepted = frontal_probability >= 0.5
        family = context.family
        view = family.view_hint or f"a {family.canonical_view} view"
        reason = (
            f"the {family.name} is seen in a {family.canonical_view} view ({source}, p(frontal) {frontal_probability:.2f})"
            if accepted
            else f"the {family.name} is not seen in a {family.canonical_view} view ({source}, p(frontal) {frontal_probability:.2f}); "
            f"this family needs {view}"
        )
        return Decision(name=self.name, label="frontal" if accepted else "not frontal", confidence=frontal_probability,
                        accepted=accepted, reason=reason)

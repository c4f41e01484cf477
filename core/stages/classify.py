"""The chain of weak classifiers (paper 3.1.2-3.1.3): is the view frontal, which subtype?

The training-free defaults judge by silhouette agreement: the object's mask is aligned
with each subtype's template render (scale, rotation, translation) and the overlap
(IoU) says how well a template in its canonical view explains the silhouette. A car
seen from the front, or a guitar seen edge-on, agrees with no template.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import cv2
import numpy as np

from frontal3d.family import Family
from frontal3d.render import TemplateRenders
from frontal3d.stages.align import align_template

#: Long side, in pixels, of the masks compared by the silhouette classifiers.
AGREEMENT_SIZE = 128
#: Softmax temperature turning subtype IoUs into confidences.
SUBTYPE_TEMPERATURE = 0.02


@dataclass
class Decision:
    """One classifier's verdict, as report.json shows it."""

    name: str
    label: str
    confidence: float
    accepted: bool = True
    reason: str = ""
    runner_up: str | None = None
    runner_up_confidence: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in self.__dict__.items()}


@dataclass
class ClassifierContext:
    """What every classifier may look at; silhouette agreements are computed once and shared."""

    image: np.ndarray
    object_mask: np.ndarray
    family: Family
    renders: dict[str, TemplateRenders]
    settings: dict[str, Any]
    _agreement: dict[str, float] | None = field(default=None, repr=False)

    def agreement(self) -> dict[str, float]:
        """IoU of the object's silhouette with each subtype's aligned template."""
        if self._agreement is None:
            self._agreement = silhouette_agreement(self.object_mask, self.renders, np.deg2rad(self.settings["max_angle_deg"]))
        return self._agreement


class Classifier(Protocol):
    """A weak classifier: ``name`` (``frontal`` and ``subtype`` are special), ``order``."""

    name: str
    order: int

    def classify(self, context: ClassifierContext) -> Decision: ...


def silhouette_agreement(object_mask: np.ndarray, renders: dict[str, TemplateRenders], max_angle: float) -> dict[str, float]:
    """IoU after alignment of ``object_mask`` with each subtype's template mask, at low resolution."""
    small_object = _shrink(_crop(object_mask))
    result = {}
    for subtype, render in renders.items():
        small_template = _shrink(_crop(render.mask))
        _, diagnostics = align_template(small_template, small_object, max_angle=max_angle)
        result[subtype] = float(diagnostics["iou"])
    return result


class FrontalGate:
    """Rejects views too far from the family's canonical view (the paper allows about ±10°)."""

    name = "frontal"
    order = 10

    def classify(self, context: ClassifierContext) -> Decision:
        agreement = context.agreement()
        best = max(agreement.values())
        threshold = float(context.settings["frontal_threshold"])
        family = context.family
        accepted = best >= threshold
        reason = "" if accepted else (
            f"the {family.name} does not look like a {family.canonical_view} view (silhouette agreement "
            f"{best:.2f} < {threshold:.2f}); this family needs {family.view_hint or 'a ' + family.canonical_view + ' view'}"
        )
        return Decision(name=self.name, label="frontal" if accepted else "not frontal", confidence=best, accepted=accepted, reason=reason)


class SubtypeClassifier:
    """Picks the subtype whose template silhouette agrees best with the object's."""

    name = "subtype"
    order = 20

    def classify(self, context: ClassifierContext) -> Decision:
        agreement = context.agreement()
        names = list(agreement)
        ious = np.array([agreement[n] for n in names])
        weights = np.exp((ious - ious.max()) / SUBTYPE_TEMPERATURE)
        confidences = weights / weights.sum()
        order = np.argsort(-confidences)
        best = names[order[0]]
        runner_up = names[order[1]] if len(names) > 1 else None
        return Decision(
            name=self.name, label=best, confidence=float(confidences[order[0]]),
            runner_up=runner_up, runner_up_confidence=float(confidences[order[1]]) if runner_up else None,
        )


def _crop(mask: np.ndarray) -> np.ndarray:
    """The mask's bounding box with a 10 % margin, so the object fills the comparison grid."""
    ys, xs = np.nonzero(mask)
    box = mask[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    return np.pad(box, int(0.1 * max(box.shape)) + 2)


def _shrink(mask: np.ndarray) -> np.ndarray:
    scale = AGREEMENT_SIZE / max(mask.shape)
    size = (max(8, round(mask.shape[1] * scale)), max(8, round(mask.shape[0] * scale)))
    return cv2.resize(mask.astype(np.uint8), size, interpolation=cv2.INTER_AREA) > 0

"""The chain of weak classifiers (paper 3.1.2-3.1.3): is the view frontal, which subtype?

The training-free defaults judge by silhouette agreement: the object's mask is aligned
with each subtype's template render (scale, rotation, translation) and the overlap
(IoU) says how well a template in its canonical view explains the silhouette. A car
seen from the front, or a guitar seen edge-on, agrees with no template: turning an
object away from its canonical view narrows its silhouette, which no in-plane
similarity can undo. Smaller turns (30-60°) are caught by comparing the outline with
the templates turned (:mod:`frontal3d.stages.turned_views`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import cv2
import numpy as np

from frontal3d.config import CORE_FAMILY_SETTINGS
from frontal3d.family import Family
from frontal3d.masks import within
from frontal3d.render import TemplateRenders
from frontal3d.stages.align import Similarity, align_template, placed_off_grid, warp_labels, warp_mask
from frontal3d.stages.ground_contacts import ContactEvidence, contact_evidence
from frontal3d.stages.mirror_symmetry import MirrorEvidence, mirror_evidence
from frontal3d.stages.neck_parallax import NECK_WINDOW, WIDE_NECK_FILL, ParallaxEvidence, neckless_share, parallax_evidence
from frontal3d.stages.rim_band import RimEvidence, rim_evidence
from frontal3d.stages.turned_views import TurnEvidence, turn_evidence
from frontal3d.stages.underside import UndersideEvidence, underside_evidence

#: Long side, in pixels, of the masks compared by the silhouette classifiers.
AGREEMENT_SIZE = 128
#: Softmax temperature turning subtype scores (IoUs) into confidences: an IoU margin
#: of 0.05 gives about 92 % / 8 %.
SUBTYPE_TEMPERATURE = 0.02
#: Region name of a template's dark opening (a classical guitar's sound hole).
HOLE_REGION = "hole"
#: How much a visible (or missing) dark opening adds to (or takes from) a subtype's score.
HOLE_WEIGHT = 0.08
#: Lab lightness drop, below the surrounding region's median, that counts as "dark".
HOLE_DARKNESS = 25.0
#: Share of the hole spot that must be seen (not under occluders or people) for the hole cue to judge it.
HOLE_SEEN_SHARE = 0.3
#: A circle near the template's hole spot with this share of its points on a lightness step
#: of one sign across it is a round outline (a rosette, or a hole drawn in the body's colour):
#: as good as a dark disc. Electric bodies reach 0.36 on the shared renders, 0.57 on the two
#: electric-guitar photos and 0.76 on synthetic samples; a drawn ring 1.00.
HOLE_RIM_SHARE = 0.85
#: Lab lightness change per pixel across such a circle that counts as a step.
HOLE_RIM_STEP = 2.0
#: The circles tried: centres within half the hole's radius of the template's, radii 0.6-1.5 times it.
HOLE_RIM_SHIFT = 0.5
HOLE_RIM_RADII = (0.6, 1.5)


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
class Agreement:
    """How well one subtype's template explains the silhouette, and where it landed."""

    iou: float
    similarity: Similarity


@dataclass
class ClassifierContext:
    """What every classifier may look at; silhouette agreements are computed once and shared.

    ``settings`` needs ``max_angle_deg`` (rotation searched) and ``frontal_threshold``;
    ``turned_margin``, ``mirror_margin``, ``parallax_margin``, ``rim_margin``, ``neck_wall_margin``, ``contact_pair_margin`` and
    ``underside_margin`` are optional (default: the core settings', which leave those tests off).
    """

    image: np.ndarray
    object_mask: np.ndarray
    family: Family
    renders: dict[str, TemplateRenders]
    settings: dict[str, Any]
    _agreement: dict[str, Agreement] | None = field(default=None, repr=False)
    _turn_evidence: TurnEvidence | None = field(default=None, repr=False)
    #: Evidence measured on the best-agreeing template's placement, by kind (see :meth:`_on_best_template`).
    _placed_evidence: dict[str, Any] = field(default_factory=dict, repr=False)

    def agreement(self) -> dict[str, Agreement]:
        """Per subtype: IoU with the aligned template and the template -> image similarity."""
        if self._agreement is None:
            self._agreement = silhouette_agreement(self.object_mask, self.renders, self.max_angle(), past_box=self.past_box())
        return self._agreement

    def max_angle(self) -> float:
        """In-plane rotation (radians, either way) the template placements search."""
        return float(np.deg2rad(float(self.settings.get("max_angle_deg", 180.0))))

    def past_box(self) -> bool:
        """Whether the template placed past the object's box counts against the agreement (``template_past_box``)."""
        return counts_template_past_box(self.settings)

    def margin(self, name: str) -> float:
        """A frontal-gate test's margin: the family's setting, else the core's (1 = the test is off)."""
        return float(self.settings.get(name, CORE_FAMILY_SETTINGS[name]))

    def view_agreement(self) -> dict[str, Agreement]:
        """The agreement the frontal gate judges the view by (the same unless a context hides more from it)."""
        return self.agreement()

    def subtype_agreement(self) -> dict[str, Agreement]:
        """The agreement the subtype classifier judges by (the same unless a context tries more placements)."""
        return self.agreement()

    def outline_partly_hidden(self) -> bool:
        """Whether some of the outline may be hidden (by occluders or people beside the object)."""
        return False

    def view_hidden_pixels(self) -> np.ndarray | None:
        """The pixels the frontal gate leaves out (None: it sees them all)."""
        return None

    def turn_evidence(self) -> TurnEvidence:
        """Best canonical-view vs best turned-view template agreement with the outline."""
        if self._turn_evidence is None:
            similarities = {subtype: found.similarity for subtype, found in self.agreement().items()}
            self._turn_evidence = turn_evidence(self.object_mask, self.renders, similarities)
        return self._turn_evidence

    def mirror_evidence(self) -> MirrorEvidence:
        """Mirror symmetry of the outline vs the best-agreeing template's, about that template's axis."""
        return self._on_best_template("mirror", lambda render, similarity: mirror_evidence(self.object_mask, render, similarity))

    def parallax_evidence(self) -> ParallaxEvidence:
        """How far the neck sits off the body's midline, in the best-agreeing template's frame."""
        return self._on_best_template("parallax", lambda render, similarity: parallax_evidence(self.object_mask, render, similarity))

    def neckless_share(self) -> float | None:
        """Share of the best-agreeing template's lower-neck rows where the outline shows no neck (None: no neck)."""
        return self._on_best_template("neckless", lambda render, similarity: neckless_share(self.object_mask, render, similarity))

    def rim_evidence(self) -> RimEvidence:
        """Side-wall band widths along the body's outline, by direction, in the best-agreeing template's frame."""
        return self._on_best_template("rim", lambda render, similarity: rim_evidence(self.image, self.object_mask, render, similarity))

    def contact_evidence(self) -> ContactEvidence:
        """How the outline's ground contacts split into pairs, in the best-agreeing template's frame."""
        return self._on_best_template("contact", lambda render, similarity: contact_evidence(self.object_mask, render, similarity))

    def underside_evidence(self) -> UndersideEvidence:
        """The dark band along the outline's bottom between the wheels, in the best-agreeing template's frame."""
        return self._on_best_template("underside", lambda render, similarity: underside_evidence(self.image, self.object_mask, render, similarity))

    def _on_best_template(self, kind: str, measure: Callable[[TemplateRenders, Similarity], Any]) -> Any:
        """``measure`` on the best-agreeing template's renders and placement, once per context and kind."""
        if kind not in self._placed_evidence:
            best, found = self._best_agreement()
            self._placed_evidence[kind] = measure(self.renders[best], found.similarity)
        return self._placed_evidence[kind]

    def _best_agreement(self) -> tuple[str, Agreement]:
        """The subtype whose placed template overlaps the outline most, and its agreement."""
        return max(self.agreement().items(), key=lambda item: item[1].iou)


class Classifier(Protocol):
    """A weak classifier: ``name`` (``frontal`` and ``subtype`` are special), ``order``."""

    name: str
    order: int

    def classify(self, context: ClassifierContext) -> Decision: ...


def counts_template_past_box(settings: dict[str, Any]) -> bool:
    """The family's ``template_past_box`` setting (see :func:`silhouette_agreement`)."""
    return bool(settings.get("template_past_box", CORE_FAMILY_SETTINGS["template_past_box"]))


def silhouette_agreement(object_mask: np.ndarray, renders: dict[str, TemplateRenders], max_angle: float,
                         hidden: np.ndarray | None = None, past_box: bool = False) -> dict[str, Agreement]:
    """Align each subtype's template mask to ``object_mask`` at ~128 px and report the IoU.

    The returned similarity maps full-resolution template render pixels to
    ``object_mask`` pixels, so it can place the template's region maps on the image.
    ``hidden`` pixels (under occluders) do not vote on the placement (see
    :func:`~frontal3d.stages.align.align_template`); the IoU is still the plain one.
    With ``past_box`` (the family's ``template_past_box``) template pixels placed off the grid
    (the object's box with a 10 % margin) count as missed too: a guitar template's neck placed
    off a limousine's end is a neck the photo does not show. Where people may hide the outline
    the template past the box may lie under them, so those agreements leave it out
    (:class:`~frontal3d.stages.occlusion.VisibleAgreementContext` scores the seen pixels only).
    """
    object_small, object_to_small, hidden_small = _normalised(object_mask, hidden)
    result = {}
    for subtype, render in renders.items():
        template_small, template_to_small, _ = _normalised(render.mask)
        small_sim, diagnostics = align_template(template_small, object_small, max_angle=max_angle, hidden=hidden_small)
        full_sim = object_to_small.inverse().compose(small_sim.compose(template_to_small))
        iou = float(diagnostics["iou"])
        missed = placed_off_grid(template_small, small_sim, object_small.shape) if past_box else 0
        if missed:
            union = np.count_nonzero(warp_mask(template_small, small_sim, object_small.shape) | object_small)
            iou *= union / (union + missed)
        result[subtype] = Agreement(iou=iou, similarity=full_sim)
    return result


class FrontalGate:
    """Rejects views too far from the family's canonical view (the paper allows about ±10°).

    Silhouette and image tests, all training-free:

    - score = best over subtypes of IoU x :func:`foreshortening` must reach the family's
      ``frontal_threshold``: IoU alone barely drops when a car turns (a front view of a
      car is still a box), but turning squashes the silhouette along one axis. This
      catches views turned 60-90°.
    - no template turned by 30-90° may explain the outline better than the templates in
      their canonical view by more than ``turned_margin`` (see
      :mod:`frontal3d.stages.turned_views`). This catches the 30-60° turns that
      scale and shape variation hide from the first test; off (1.0) unless the family
      sets it (planes, whose planforms vary most, would lose frontal photos to it), and
      skipped when the outline is partly hidden (a bite in it can fit a turned template).
    - the outline may not be less mirror-symmetric about the aligned template's axis than
      the template by more than ``mirror_margin`` (see
      :mod:`frontal3d.stages.mirror_symmetry`). This catches turns about that axis (a
      plane rolled, a guitar turned about its neck) that keep the outline's size; off
      (1.0) unless the family sets it, since a side-view car has no such axis, and
      skipped when occluders hide part of the outline.
    - the neck's centre line may not run beside the body's midline by more than
      ``parallax_margin`` of the body's width (see :mod:`frontal3d.stages.neck_parallax`).
      This catches a guitar turned about its neck by 30-60°, whose outline stays
      symmetric and plausible; off (1.0) unless the family sets it, and skipped, as the
      mirror test, when the outline is partly hidden.
    - the body's side wall may not show along one side of its outline wider than along
      the opposite side by more than ``rim_margin`` of the body's width (see
      :mod:`frontal3d.stages.rim_band`). This is the one test that sees a guitar pitched
      (tipped about image-right), whose outline is just a shorter one; off (1.0) unless
      the family sets it, and skipped when the outline is partly hidden.
    - the neck's slide and the side wall's left-right gap, when they point to the same turn
      about the neck (turned left-towards, the neck moves right and the left wall shows),
      each as a share of its own test's margin (``parallax_margin``, ``rim_margin``), may not
      average more than ``neck_wall_margin``. Each stays under its own margin on a
      thin-walled electric turned 45°, but noise on a frontal view points either way, so
      only agreeing cues are pooled; off (1.0: an average past 1 has one cue past its own
      margin) unless the family sets it, skipped when the outline is partly hidden.
    - the outline's ground contacts may not split into a pair at both axles further apart
      than ``contact_pair_margin`` of its length (see :mod:`frontal3d.stages.ground_contacts`).
      This catches a car turned about image-up, whose far wheels come out beside the near
      ones; off (1.0) unless the family sets it, skipped when the outline is partly hidden.
    - the outline's bottom between the wheels may not show a dark band taller than
      ``underside_margin`` of its length (see :mod:`frontal3d.stages.underside`). This catches
      a car rolled about its length axis, bottom towards the camera, whose floor comes into
      view; off (1.0) unless the family sets it, skipped when the outline is partly hidden.
    - across at most ``neckless_margin`` of the placed template's lower-neck rows may the
      outline show no neck: nothing, or more than 1.5 necks' width (see
      :func:`frontal3d.stages.neck_parallax.neckless_share`). This is no turn: it catches an
      outline only the template's body fits (a limousine seen from the front three-quarter,
      the template's neck over its bonnet or off it), which the agreement alone let pass at
      0.47-0.48; off (1.0) unless the family sets it, skipped when the outline is partly
      hidden (a person's arm along a neck widens it, one across it cuts it).

    ``frontal_threshold`` 0 switches the gate off (evaluation runs on known-frontal data).
    """

    name = "frontal"
    order = 10

    def classify(self, context: ClassifierContext) -> Decision:
        agreement = context.view_agreement()
        scores = {
            subtype: found.iou * foreshortening(context.object_mask, context.renders[subtype], found.similarity, context.view_hidden_pixels())
            for subtype, found in agreement.items()
        }
        best = max(scores.values())
        threshold = float(context.settings["frontal_threshold"])
        family = context.family
        view = family.view_hint or f"a {family.canonical_view} view"
        if best < threshold:
            reason = (f"the {family.name} is not seen in a {family.canonical_view} view (silhouette agreement {best:.2f} < "
                      f"{threshold:.2f}); this family needs {view}")
            return Decision(name=self.name, label="not frontal", confidence=best, accepted=False, reason=reason)
        if threshold > 0:
            for setting, judge, whole_outline_only in TURN_TESTS:
                margin = context.margin(setting)
                if margin >= 1.0 or (whole_outline_only and context.outline_partly_hidden()):
                    continue
                evidence = judge(context, margin)
                if evidence:
                    reason = f"the {family.name} {evidence}; this family needs {view}"
                    return Decision(name=self.name, label="not frontal", confidence=best, accepted=False, reason=reason)
        reason = f"the {family.name} matches a {family.canonical_view} view (silhouette agreement {best:.2f} >= {threshold:.2f})"
        return Decision(name=self.name, label="frontal", confidence=best, accepted=True, reason=reason)


def _turned_template(context: ClassifierContext, margin: float) -> str | None:
    """A template turned 30-90° fits the outline better (:mod:`frontal3d.stages.turned_views`)."""
    evidence = context.turn_evidence()
    if evidence.margin >= -margin:
        return None
    direction = "sideways" if evidence.turned_axis == "yaw" else "up or down"
    # Enough digits that "better" shows: a near tie read to two places says "0.85 vs 0.85".
    digits = 2 if round(evidence.turned_iou, 2) != round(evidence.frontal_iou, 2) else 3
    return (f"looks turned about {abs(evidence.turned_degrees):.0f}° {direction} from a {context.family.canonical_view} view (a turned "
            f"template fits its outline better: {evidence.turned_iou:.{digits}f} vs {evidence.frontal_iou:.{digits}f})")


def _lopsided(context: ClassifierContext, margin: float) -> str | None:
    """The outline is less mirror-symmetric than the template (:mod:`frontal3d.stages.mirror_symmetry`)."""
    mirror = context.mirror_evidence()
    if mirror.asymmetry <= margin:
        return None
    return (f"looks turned about its length axis: its outline is lopsided (mirror agreement {mirror.object_iou:.2f} vs the "
            f"template's {mirror.template_iou:.2f})")


def _neck_beside_midline(context: ClassifierContext, margin: float) -> str | None:
    """The neck runs beside the body's midline (:mod:`frontal3d.stages.neck_parallax`)."""
    parallax = context.parallax_evidence()
    if abs(parallax.offset) <= margin:
        return None
    return (f"looks turned sideways: its neck runs {abs(parallax.offset):.1%} of the body's width beside the body's midline "
            f"(at most {margin:.1%} in a {context.family.canonical_view} view)")


def _side_wall_shows(context: ClassifierContext, margin: float) -> str | None:
    """The body shows its side wall along one edge (:mod:`frontal3d.stages.rim_band`)."""
    rim = context.rim_evidence()
    if rim.asymmetry <= margin:
        return None
    return (f"looks turned: its side wall shows along its {rim.side} edge as a band {rim.asymmetry:.1%} of the body's width wider "
            f"than along the opposite edge (at most {margin:.1%} in a {context.family.canonical_view} view)")


def _neck_and_wall_agree(context: ClassifierContext, margin: float) -> str | None:
    """The neck's slide and the side wall both point to one turn about the neck (see :class:`FrontalGate`)."""
    offset = context.parallax_evidence().offset
    bands = context.rim_evidence().bands
    wall = bands.get("left", 0.0) - bands.get("right", 0.0) if {"left", "right"} <= bands.keys() else 0.0
    if offset * wall <= 0:
        return None
    share = 0.5 * (abs(offset) / context.margin("parallax_margin") + abs(wall) / context.margin("rim_margin"))
    if share <= margin:
        return None
    return (f"looks turned sideways: its neck runs {abs(offset):.1%} of the body's width beside the body's midline and its side wall "
            f"shows {abs(wall):.1%} of it wider on the {'left' if wall > 0 else 'right'}, as one turn about the neck makes "
            f"(on average {share:.0%} of those tests' margins, at most {margin:.0%} in a {context.family.canonical_view} view)")


def _far_wheels_show(context: ClassifierContext, margin: float) -> str | None:
    """Both axles stand on a pair of contacts (:mod:`frontal3d.stages.ground_contacts`)."""
    contacts = context.contact_evidence()
    if contacts.split <= margin:
        return None
    return (f"looks turned sideways: it stands on {contacts.runs} separate ground contacts, the far side's beside the near side's "
            f"({contacts.split:.0%} of its length apart; a {context.family.canonical_view} view shows one per axle)")


def _no_neck(context: ClassifierContext, margin: float) -> str | None:
    """The outline shows no neck where the template's lies (:func:`frontal3d.stages.neck_parallax.neckless_share`)."""
    share = context.neckless_share()
    if share is None or share <= margin:
        return None
    return (f"has no neck where its template's lies: across {share:.0%} of the template's lower neck the outline is "
            f"missing or wider than {WIDE_NECK_FILL * 2 * NECK_WINDOW:.1f} necks (at most {margin:.0%} in a "
            f"{context.family.canonical_view} view)")


def _floor_shows(context: ClassifierContext, margin: float) -> str | None:
    """The floor shows below the sill (:mod:`frontal3d.stages.underside`)."""
    underside = context.underside_evidence()
    if underside.band <= margin:
        return None
    return (f"looks turned about its length axis: its floor shows below the sill as a dark band {underside.band:.0%} of its length "
            f"tall (at most {margin:.0%} in a {context.family.canonical_view} view)")


#: The frontal gate's tests after the agreement threshold, in order: (setting holding the margin,
#: judge returning what gives the view away, as the clause after "the <family>", or None; skipped
#: when the outline is partly hidden).
#: An arm across the object, or a person beside it whose pixels may be the object's, bites into
#: the outline (which a turned template may then fit better), makes it lopsided, cuts a neck or a
#: wheel, or hides a side wall: only whole outlines are judged by those. A margin of 1 or more switches a test off.
TURN_TESTS: tuple[tuple[str, Callable[[ClassifierContext, float], str | None], bool], ...] = (
    ("turned_margin", _turned_template, True),
    ("mirror_margin", _lopsided, True),
    ("parallax_margin", _neck_beside_midline, True),
    ("rim_margin", _side_wall_shows, True),
    ("neck_wall_margin", _neck_and_wall_agree, True),
    ("contact_pair_margin", _far_wheels_show, True),
    ("underside_margin", _floor_shows, True),
    ("neckless_margin", _no_neck, True),
)


class SubtypeClassifier:
    """Picks the subtype whose template silhouette agrees best with the object's.

    Score = IoU, plus an image cue for templates with a dark opening (region ``hole``):
    a dark disc or a round outline where the aligned template puts the hole (a classical
    guitar's sound hole or its rosette) raises that subtype's score, a plain hole spot as
    light as its surroundings lowers it. Confidence = softmax of the scores with :data:`SUBTYPE_TEMPERATURE`.
    """

    name = "subtype"
    order = 20

    def classify(self, context: ClassifierContext) -> Decision:
        agreement = context.subtype_agreement()
        names = list(agreement)
        holes = {n: _hole_evidence(context, n) for n in names}
        scores = np.array([agreement[n].iou + HOLE_WEIGHT * holes[n] for n in names])
        weights = np.exp((scores - scores.max()) / SUBTYPE_TEMPERATURE)
        confidences = weights / weights.sum()
        order = np.argsort(-confidences, kind="stable")
        best = names[order[0]]
        runner_up = names[order[1]] if len(names) > 1 else None
        reason = f"{best}: {_evidence_words(agreement[best].iou, holes[best])}" + (
            f"; {runner_up}: {_evidence_words(agreement[runner_up].iou, holes[runner_up])}" if runner_up else ""
        )
        return Decision(
            name=self.name, label=best, confidence=float(confidences[order[0]]), reason=reason,
            runner_up=runner_up, runner_up_confidence=float(confidences[order[1]]) if runner_up else None,
        )


def _evidence_words(iou: float, hole: float) -> str:
    """One subtype's evidence for report.json: the hole cue is named when it voted, so a
    pick it decided between near-equal silhouettes does not read as a tie."""
    return f"silhouette agreement {iou:.2f}" + (f", hole cue {hole:+.2f}" if hole else "")


def _hole_evidence(context: ClassifierContext, subtype: str) -> float:
    """In [-1, 1]: +1 when the template's hole lands on a dark disc or a round outline
    (:func:`_round_outline_near`), -1 when on plain surface, 0 without a hole or when
    occluders hide all but HOLE_SEEN_SHARE of the spot."""
    render = context.renders[subtype]
    if HOLE_REGION not in render.region_names:
        return 0.0
    hole_label = render.region_names.index(HOLE_REGION)
    regions = warp_labels(render.front_regions, context.subtype_agreement()[subtype].similarity, context.object_mask.shape)
    spot = (regions == hole_label) & context.object_mask
    hidden = context.view_hidden_pixels()
    # Occluded pixels inside the object's hull count as object for the silhouettes, but
    # what they show is the occluder (a dark jacket, a light face): no evidence either way.
    seen = context.object_mask if hidden is None else context.object_mask & ~hidden
    hole = spot & seen
    if hole.sum() < max(12, HOLE_SEEN_SHARE * spot.sum()):
        return 0.0
    radius = max(2, round(0.5 * np.sqrt(spot.sum() / np.pi)))
    ring = within(spot, radius) & ~spot & seen & (regions >= 0)
    if ring.sum() < 12:
        return 0.0
    lightness = cv2.cvtColor(np.ascontiguousarray(context.image[..., :3], dtype=np.uint8), cv2.COLOR_RGB2LAB)[..., 0]
    lightness = lightness.astype(np.float64) * (100.0 / 255.0)
    dark = lightness < np.median(lightness[ring]) - HOLE_DARKNESS
    # A sound hole fills its disc with dark and leaves the ring light; pickups or a
    # dark finish leave the ring dark too.
    evidence = float(np.clip(2.0 * (dark[hole].mean() - dark[ring].mean()) - 0.5, -1.0, 1.0))
    if evidence < 1.0 and _round_outline_near(lightness, spot, seen):
        return 1.0
    return evidence


def _round_outline_near(lightness: np.ndarray, hole: np.ndarray, seen: np.ndarray) -> bool:
    """Whether some circle near the ``hole`` spot crosses a lightness step of one sign on
    HOLE_RIM_SHARE of its points: a hole edge or a drawn ring, whose points all step the same
    way across it, where wood grain, strings and pickup edges step either way or along it.
    Circles with over a tenth of their points off the ``seen`` object are not judged (a person's
    arm may hide the hole)."""
    ys, xs = np.nonzero(hole)
    radius = float(np.sqrt(len(ys) / np.pi))
    reach = HOLE_RIM_SHIFT * radius
    height, width = lightness.shape
    # Gradients only around the circles (blur and Sobel reach 5 px): a photo may be far larger.
    span = int(np.ceil(reach + HOLE_RIM_RADII[1] * radius)) + 7
    y0, y1 = max(0, int(ys.mean()) - span), min(height, int(ys.mean()) + span + 1)
    x0, x1 = max(0, int(xs.mean()) - span), min(width, int(xs.mean()) + span + 1)
    smooth = cv2.GaussianBlur(lightness[y0:y1, x0:x1].astype(np.float32), (0, 0), 1.0)
    gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3, scale=1.0 / 8.0)
    gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3, scale=1.0 / 8.0)
    seen = seen[y0:y1, x0:x1]
    angles = np.linspace(0.0, 2.0 * np.pi, 96, endpoint=False)
    ux, uy = np.cos(angles), np.sin(angles)
    offsets = np.arange(-reach, reach + 1e-6, max(1.0, 0.08 * radius))
    cy, cx = np.meshgrid(ys.mean() + offsets, xs.mean() + offsets, indexing="ij")
    cy, cx = cy.reshape(-1, 1), cx.reshape(-1, 1)
    for r in np.arange(HOLE_RIM_RADII[0] * radius, HOLE_RIM_RADII[1] * radius + 1e-6, max(1.0, 0.05 * radius)):
        px, py = np.rint(cx + r * ux).astype(int), np.rint(cy + r * uy).astype(int)
        inside = (px >= 0) & (px < width) & (py >= 0) & (py < height)
        px, py = np.clip(px, 0, width - 1) - x0, np.clip(py, 0, height - 1) - y0
        judged = (inside & seen[py, px]).mean(axis=1) >= 0.9
        across = gx[py, px] * ux + gy[py, px] * uy
        along = np.abs(gy[py, px] * ux - gx[py, px] * uy)
        crossing = np.abs(across) > 2.0 * along
        share = np.maximum(((across > HOLE_RIM_STEP) & crossing).mean(axis=1), ((across < -HOLE_RIM_STEP) & crossing).mean(axis=1))
        if np.any(judged & (share >= HOLE_RIM_SHARE)):
            return True
    return False


def _normalised(mask: np.ndarray, hidden: np.ndarray | None = None) -> tuple[np.ndarray, Similarity, np.ndarray | None]:
    """The mask cropped to its box (10 % margin) and shrunk to AGREEMENT_SIZE, that map as a
    similarity, and ``hidden`` on the same grid (a grid pixel any of whose area is hidden).

    With ``hidden`` pixels the box also takes in those within one box size of it at the
    same scale: a template part under an occluder must not fall off the grid.
    """
    ys, xs = np.nonzero(mask)
    height, width = ys.max() - ys.min() + 1, xs.max() - xs.min() + 1
    margin = int(0.1 * max(height, width)) + 2
    y0, x0 = ys.min() - margin, xs.min() - margin
    y1, x1 = ys.max() + 1 + margin, xs.max() + 1 + margin
    scale = AGREEMENT_SIZE / (max(height, width) + 2 * margin)
    if hidden is not None and hidden.any():
        reach = max(y1 - y0, x1 - x0)
        hy, hx = np.nonzero(hidden[max(0, y0 - reach) : y1 + reach, max(0, x0 - reach) : x1 + reach])
        if len(hy):
            hy, hx = hy + max(0, y0 - reach), hx + max(0, x0 - reach)
            y0, x0, y1, x1 = min(y0, hy.min()), min(x0, hx.min()), max(y1, hy.max() + 1), max(x1, hx.max() + 1)
    box = np.zeros((y1 - y0, x1 - x0), np.uint8)
    box[ys - y0, xs - x0] = mask[ys, xs]
    size = (max(8, round(box.shape[1] * scale)), max(8, round(box.shape[0] * scale)))
    small = cv2.resize(box, size, interpolation=cv2.INTER_AREA) > 0
    sx, sy = size[0] / box.shape[1], size[1] / box.shape[0]
    scale = (sx + sy) / 2.0
    hidden_small = None
    if hidden is not None:
        hidden_box = np.zeros_like(box)
        top, left = max(0, y0), max(0, x0)
        window = hidden[top:y1, left:x1]
        hidden_box[top - y0 : top - y0 + window.shape[0], left - x0 : left - x0 + window.shape[1]] = window
        hidden_small = cv2.resize(hidden_box, size, interpolation=cv2.INTER_AREA) > 0
    # Pixel centres: small = (full - origin + 0.5) * scale - 0.5.
    return small, Similarity(scale, 0.0, (0.5 - x0) * scale - 0.5, (0.5 - y0) * scale - 0.5), hidden_small


def foreshortening(object_mask: np.ndarray, render: TemplateRenders, similarity: Similarity, hidden: np.ndarray | None = None) -> float:
    """How squashed the object is along one template axis relative to the other, in (0, 1].

    Turning an object away from the canonical view by an angle a shrinks its
    silhouette along one template axis by about cos(a) while the other keeps its
    length; the isotropic alignment cannot undo that. Measured as the ratio of the
    per-axis spreads (object over template, in the template's frame), smaller over larger.
    With ``hidden`` pixels both spreads are taken outside them only (the object's and the
    placed template's): a person over a guitar's lower body shortens the object seen, not
    the view, and the template loses the same part. The spreads come from image moments,
    not pixel lists: on a 50-megapixel photo the lists took 2 s per subtype.
    """
    to_template = similarity.inverse().matrix[:, :2]
    object_spread, template_spread = _covariance(object_mask), _covariance(render.mask)
    if hidden is not None and hidden.any():
        seen_object = object_mask & ~hidden
        seen_template = warp_mask(render.mask, similarity, object_mask.shape) & ~hidden
        if np.count_nonzero(seen_object) >= 3 and np.count_nonzero(seen_template) >= 3:
            object_spread = _covariance(seen_object)
            template_spread = to_template @ _covariance(seen_template) @ to_template.T
    object_spread = to_template @ object_spread @ to_template.T
    spread = np.sqrt(np.diag(object_spread)) / np.maximum(np.sqrt(np.diag(template_spread)), 1e-9)
    return float(spread.min() / spread.max())


def _covariance(mask: np.ndarray) -> np.ndarray:
    """The 2x2 covariance of the mask's pixel coordinates (x, y), as ``np.cov(..., bias=True)`` gives."""
    moments = cv2.moments(np.asarray(mask, dtype=np.uint8), binaryImage=True)
    area = max(moments["m00"], 1.0)
    return np.array([[moments["mu20"], moments["mu11"]], [moments["mu11"], moments["mu02"]]]) / area

"""Neck-parallax evidence: the frontal gate tells a guitar turned about its neck from a frontal one."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from frontal3d.eval_gate import turned
from frontal3d.evaluate import render_frontal
from frontal3d.family import Template
from frontal3d.plugins import Plugins
from frontal3d.render import TemplateRenders, render_template
from frontal3d.stages.align import Similarity
from frontal3d.stages.classify import ClassifierContext, FrontalGate
from frontal3d.stages.neck_parallax import parallax_evidence
from frontal3d.stages.occlusion import VisibleAgreementContext

from shapes import SLAB_GUITAR_FAMILY as FAMILY, slab_guitar, strip_beside

#: Side of the template and of the views: fine enough for a neck a dozen pixels wide.
RESOLUTION = 400


@pytest.fixture(scope="module")
def guitar() -> trimesh.Trimesh:
    return slab_guitar()[0]


@pytest.fixture(scope="module")
def template() -> TemplateRenders:
    mesh, labels = slab_guitar()
    return render_template(Template("guitar", "classical", mesh, labels, ("body", "neck")), RESOLUTION)


def _settings(parallax_margin: float) -> dict:
    return {"max_angle_deg": 120.0, "frontal_threshold": 0.45, "parallax_margin": parallax_margin}


def _gate(template: TemplateRenders, mask: np.ndarray, parallax_margin: float):
    context = ClassifierContext(image=np.zeros(mask.shape + (3,), np.uint8), object_mask=mask, family=FAMILY,
                                renders={"classical": template}, settings=_settings(parallax_margin))
    return FrontalGate().classify(context)


@pytest.mark.parametrize(("axis", "degrees", "frontal"), [("yaw", 0.0, True), ("yaw", 10.0, True), ("pitch", 10.0, True),
                                                          ("yaw", 45.0, False), ("yaw", -45.0, False), ("yaw", 60.0, False)])
def test_shipped_guitar_margin_rejects_a_guitar_turned_about_its_neck_only(guitar, template, axis, degrees, frontal):
    margin = Plugins().settings("guitar")["parallax_margin"]
    mask = render_frontal(turned(guitar, axis, degrees), RESOLUTION)[1]
    decision = _gate(template, mask, margin)
    assert decision.accepted is frontal
    if not frontal:
        assert "turned sideways" in decision.reason and "front view" in decision.reason
        # Without the parallax test the silhouette tests let the turned guitar through.
        assert _gate(template, mask, 1.0).accepted


def test_the_offset_grows_with_the_turn_and_changes_sign_with_its_direction(guitar, template):
    def offset(degrees: float) -> float:
        mask = render_frontal(turned(guitar, "yaw", degrees), RESOLUTION)[1]
        context = ClassifierContext(image=np.zeros(mask.shape + (3,), np.uint8), object_mask=mask, family=FAMILY,
                                    renders={"classical": template}, settings=_settings(1.0))
        return context.parallax_evidence().offset

    offsets = [offset(d) for d in (0.0, 20.0, 40.0, 60.0)]
    assert abs(offsets[0]) < 0.01
    assert 0.01 < abs(offsets[1]) < abs(offsets[2]) < abs(offsets[3])
    assert np.sign(offset(-40.0)) == -np.sign(offsets[2])


def test_a_bent_photo_of_a_frontal_guitar_is_not_taken_for_a_turn(template):
    """Rows shifted along a parabola (synth's banana bend, lens distortion): the neck and body lines still meet."""
    mask = template.mask
    rows = np.flatnonzero(mask.any(axis=1))
    along = (np.arange(mask.shape[0]) - rows.mean()) / (np.ptp(rows) / 2)
    shift = np.round(0.05 * np.ptp(rows) * (along**2 - 1 / 3)).astype(int)
    bent = np.array([np.roll(row, s) for row, s in zip(mask, shift)])
    identity = Similarity(1.0, 0.0, 0.0, 0.0)
    assert abs(parallax_evidence(bent, template, identity).offset) < Plugins().settings("guitar")["parallax_margin"]
    # The same neck moved sideways by a constant (what a turn does) is seen: by 12 px, a tenth of the body's width.
    above_body = np.arange(mask.shape[0]) < np.flatnonzero((template.front_regions == 0).any(axis=1)).min()
    shifted = mask.copy()
    shifted[above_body] = np.roll(mask[above_body], 12, axis=1)
    body_width = np.ptp(np.flatnonzero(mask.any(axis=0)))
    assert parallax_evidence(shifted, template, identity).offset == pytest.approx(12 / body_width, abs=0.01)


def test_an_arm_across_the_body_that_nobody_flagged_is_not_taken_for_a_turn(template):
    """An unflagged arm cuts the right part off a band of body rows: those rows are outliers of the midline."""
    mask = template.mask.copy()
    body_rows = np.flatnonzero((template.front_regions == 0).any(axis=1))
    columns = np.flatnonzero(mask.any(axis=0))
    centre, width = columns.mean(), np.ptp(columns)
    band = body_rows[int(0.55 * body_rows.size) : int(0.7 * body_rows.size)]
    mask[band, int(centre + 0.1 * width) :] = False
    identity = Similarity(1.0, 0.0, 0.0, 0.0)
    assert abs(parallax_evidence(mask, template, identity).offset) < 0.02
    # Half the body cut away along its length: a gap wider than any turn makes, so no evidence either way.
    mask[body_rows[int(0.3 * body_rows.size) :], int(centre) :] = False
    assert parallax_evidence(mask, template, identity).offset == 0.0


def test_a_template_without_a_neck_gives_no_evidence(template):
    no_neck = TemplateRenders(template.center, template.half_width, template.mask, template.front_depth, template.back_depth,
                              template.front_normals, template.back_normals, np.where(template.mask, 0, -1),
                              np.where(template.mask, 0, -1), ("body",))
    evidence = parallax_evidence(np.roll(template.mask, 5, axis=1), no_neck, Similarity(1.0, 0.0, 0.0, 0.0))
    assert evidence.offset == 0.0


def test_parallax_test_does_not_judge_an_outline_a_person_beside_it_may_hide(guitar, template):
    margin = Plugins().settings("guitar")["parallax_margin"]
    mask = render_frontal(turned(guitar, "yaw", 45.0), RESOLUTION)[1]
    assert not _gate(template, mask, margin).accepted
    beside = strip_beside(mask)
    context = VisibleAgreementContext(image=np.zeros(mask.shape + (3,), np.uint8), object_mask=mask, family=FAMILY,
                                      renders={"classical": template}, settings=_settings(margin), view_hidden=beside)
    assert FrontalGate().classify(context).accepted


@pytest.mark.parametrize("necks_wide", [2.0, 3.0])
def test_an_outline_only_the_body_fits_has_no_neck_and_is_turned_down(guitar, template, necks_wide):
    """The slab guitar with a block ``necks_wide`` necks wide over the lower neck (a limousine's bonnet
    under a classical template): the body still fits, but the shipped ``neckless_margin`` turns it
    down, whether the template's neck lies on the block (too wide) or is laid off the object (nothing
    there). Every row of the guitar's own lower neck shows a neck, and a guitar cut 30 % of its
    length from the top still passes (a photo cropping the headstock and the upper neck)."""
    margin = Plugins().settings("guitar")["neckless_margin"]
    mask = render_frontal(guitar, RESOLUTION)[1]
    rows, columns = np.nonzero(mask)
    top, height = rows.min(), np.ptp(rows)
    neck_columns = columns[rows < top + 0.3 * height]
    centre, neck_width = neck_columns.mean(), np.ptp(neck_columns) + 1
    bonnet = mask.copy()
    bonnet[top + int((0.45 - 0.1 * necks_wide) * height):top + int(0.55 * height),
           int(centre - necks_wide / 2 * neck_width):int(centre + necks_wide / 2 * neck_width)] = True
    cropped = mask.copy()
    cropped[:top + int(0.3 * height)] = False

    def gate(object_mask: np.ndarray, neckless_margin: float):
        settings = {**_settings(1.0), "neckless_margin": neckless_margin}
        context = ClassifierContext(image=np.zeros(object_mask.shape + (3,), np.uint8), object_mask=object_mask,
                                    family=FAMILY, renders={"classical": template}, settings=settings)
        return FrontalGate().classify(context), context.neckless_share()

    accepted, guitar_share = gate(mask, margin)
    assert accepted.accepted and guitar_share == 0.0
    assert gate(cropped, margin)[0].accepted
    rejected, bonnet_share = gate(bonnet, margin)
    assert not rejected.accepted and "has no neck" in rejected.reason and bonnet_share > 0.5
    assert gate(bonnet, 1.0)[0].accepted  # the agreement alone lets it through

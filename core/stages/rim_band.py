"""Rim-band evidence for the frontal gate (issue #6): does the body show its side wall?

A guitar's body is a slab: seen straight on, only its face shows. Turned by an angle
``a`` about any axis in the image plane (yaw or pitch), the side wall comes into view as
a band of width ``thickness x sin a`` along the outline that faces the turn, and none
along the opposite outline. A stretch of the outline, which the silhouette tests cannot
tell from a pitch, shows no such band: this is the one cue here that sees a pitch.

The wall faces another way than the face, so it is shaded differently. From each
outline point of the body (next to the aligned template's body region, away from the
neck's junction) the lightness is read inward along the outline's normal; points whose
line leaves the object first (across a horn) are left out. The band is the run of
samples, from the edge, whose lightness differs from the face's (read further in along
the same line) by more than :data:`LIGHTNESS_STEP`, provided the run ends in a step (a
wall meets the face at an edge; a sunburst's dark rim fades out). Points are pooled by
the direction their outline faces, in the template's frame (right, left, down, up); the
evidence is the largest difference of mean band width between opposite directions, as
a share of the body's width. Comparing opposite sides cancels what a
frontal view puts all round the edge (binding, a sunburst's dark rim, rounded edges
under diffuse light), and reading the face along each line keeps a lighting gradient
across the face from counting.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from frontal3d.masks import within
from frontal3d.render import TemplateRenders
from frontal3d.stages.align import Similarity, warp_labels

#: The slab whose side wall shows, and the part whose junction with it is left out.
BODY_REGION = "body"
NECK_REGION = "neck"
#: Widest band measured, and the stretch of each inward line that gives the face's
#: lightness, as shares of the body's width.
BAND_DEPTH = 0.25
FACE_DEPTH = (0.25, 0.38)
#: Lab lightness difference (0-100) from the face that counts as another surface.
LIGHTNESS_STEP = 6.0
#: Samples either side of a band's end over which the lightness must change by LIGHTNESS_STEP.
EDGE_SPAN = 2
#: Outline left out around the neck (where it meets the body), as a share of the body's width.
NECK_CLEARANCE = 0.08
#: How far outside the template's body region an outline point may lie and still count, as a
#: share of the body's width (the object's outline is not the template's).
BODY_REACH = 0.05
#: Fewest outline points facing a direction for that direction to count.
MIN_POINTS = 5
#: Outline directions, as unit vectors in the template's frame (x right, y down).
DIRECTIONS = {"right": (1.0, 0.0), "left": (-1.0, 0.0), "down": (0.0, 1.0), "up": (0.0, -1.0)}
OPPOSITE = {"right": "left", "left": "right", "down": "up", "up": "down"}


@dataclass(frozen=True)
class RimEvidence:
    """Mean band width (share of the body's width) per outline direction, and the largest opposite-side gap."""

    bands: dict[str, float]

    @property
    def asymmetry(self) -> float:
        """How much wider the band along one side is than along the opposite side (0 without evidence)."""
        gaps = [self.bands[side] - self.bands[OPPOSITE[side]] for side in self.bands if OPPOSITE[side] in self.bands]
        return max(gaps, default=0.0)

    @property
    def side(self) -> str | None:
        """The outline direction with the widest band beyond its opposite (None without evidence)."""
        gaps = {side: self.bands[side] - self.bands[OPPOSITE[side]] for side in self.bands if OPPOSITE[side] in self.bands}
        return max(gaps, key=gaps.get) if gaps else None


def rim_evidence(image: np.ndarray, object_mask: np.ndarray, render: TemplateRenders, similarity: Similarity) -> RimEvidence:
    """Band widths along the body's outline, by direction (empty: no evidence, e.g. a template without a body)."""
    if BODY_REGION not in render.region_names:
        return RimEvidence({})
    body_label = render.region_names.index(BODY_REGION)
    template_columns = np.flatnonzero((render.front_regions == body_label).any(axis=0))
    # The template body's width placed on the image (a yaw narrows the object's, not this one).
    width = float(similarity.scale * (np.ptp(template_columns) + 1)) if template_columns.size else 0.0
    if width < 8:
        return RimEvidence({})
    regions = warp_labels(render.front_regions, similarity, object_mask.shape)
    body = regions == body_label
    points, inward = _body_outline(object_mask, body, regions, render, width)
    if len(points) < MIN_POINTS:
        return RimEvidence({})
    lightness = cv2.cvtColor(np.ascontiguousarray(image[..., :3], dtype=np.uint8), cv2.COLOR_RGB2LAB)[..., 0]
    lightness = lightness.astype(np.float32) * np.float32(100.0 / 255.0)
    bands, kept = _band_widths(lightness, object_mask, points, inward, width)
    # Outline directions in the template's frame: undo the alignment's in-plane turn.
    outward = -inward[kept]
    cos, sin = np.cos(-similarity.angle), np.sin(-similarity.angle)
    facing = np.stack([cos * outward[:, 0] - sin * outward[:, 1], sin * outward[:, 0] + cos * outward[:, 1]], axis=1)
    out = {}
    for name, direction in DIRECTIONS.items():
        chosen = facing @ np.array(direction) > np.sqrt(0.5)
        if chosen.sum() >= MIN_POINTS:
            out[name] = float(bands[chosen].mean() / width)
    return RimEvidence(out)


def _body_outline(mask: np.ndarray, body: np.ndarray, regions: np.ndarray, render: TemplateRenders,
                  width: float) -> tuple[np.ndarray, np.ndarray]:
    """Outline pixels (x, y) of the object next to the template's body and away from its neck, with unit inward normals."""
    mask_u8 = mask.astype(np.uint8)
    outline = mask & ~(cv2.erode(mask_u8, np.ones((3, 3), np.uint8)) > 0)
    near_body = within(body, max(1, round(BODY_REACH * width)))
    if NECK_REGION in render.region_names:
        near_body &= ~within(regions == render.region_names.index(NECK_REGION), max(1, round(NECK_CLEARANCE * width)))
    ys, xs = np.nonzero(outline & near_body)
    smooth = cv2.GaussianBlur(mask_u8.astype(np.float32), (0, 0), 1.5)
    gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3)[ys, xs]
    gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3)[ys, xs]
    length = np.hypot(gx, gy)
    keep = length > 1e-6
    inward = np.stack([gx[keep], gy[keep]], axis=1) / length[keep, None]
    return np.stack([xs[keep], ys[keep]], axis=1).astype(np.float32), inward.astype(np.float32)


def _band_widths(lightness: np.ndarray, mask: np.ndarray, points: np.ndarray, inward: np.ndarray,
                 width: float) -> tuple[np.ndarray, np.ndarray]:
    """Per outline point whose inward line stays on the object to the face's stretch: the run (pixels)
    of samples from the edge whose lightness differs from the face's, or 0 when the run does not end
    in a step (within :data:`EDGE_SPAN` samples either side); and which points those are."""
    depth = max(4, int(np.ceil(FACE_DEPTH[1] * width)))
    steps = np.arange(depth + 1, dtype=np.float32)
    xs = points[:, :1] + inward[:, :1] * steps
    ys = points[:, 1:] + inward[:, 1:] * steps
    profiles = cv2.remap(lightness, xs, ys, cv2.INTER_LINEAR)
    on_object = cv2.remap(mask.astype(np.float32), xs, ys, cv2.INTER_LINEAR) > 0.5
    kept = on_object.all(axis=1)
    profiles = profiles[kept]
    face = np.median(profiles[:, int(FACE_DEPTH[0] * width):], axis=1)
    band_depth = max(2, int(BAND_DEPTH * width))
    differs = np.abs(profiles[:, 1 : band_depth + 1] - face[:, None]) > LIGHTNESS_STEP
    # Samples 1..run differ from the face (sample 0 is the edge pixel itself, half background).
    runs = np.argmin(np.concatenate([differs, np.zeros((len(differs), 1), bool)], axis=1), axis=1)
    # A side wall ends at the face's edge; a sunburst or a shadow fades out.
    rows = np.arange(len(profiles))
    before, after = np.clip(runs + 1 - EDGE_SPAN, 0, depth), np.clip(runs + EDGE_SPAN, 0, depth)
    crisp = np.abs(profiles[rows, after] - profiles[rows, before]) >= LIGHTNESS_STEP
    return np.where(crisp, runs, 0).astype(np.float64), kept

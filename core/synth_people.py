"""Procedural people for `synth`: a head, a torso and arms, drawn behind and across the object.

Photos of guitars show the guitarist: a face beside the headstock, clothes behind the body,
an arm across it. A segmenter trained only on objects over abstract backgrounds takes skin
and faces for the object's wood (docs/results.md, "With no object mask"). We have no photos
of people to train on, so, as for the objects, we draw them: flat shapes in skin tones and
clothing colours, shaded as rounded, in the two arrangements photos show (a player behind
the object with arms across it, or someone standing in front of part of it). What stands in
front is cut from the object's mask, so the network learns that arms and faces are not the
object, whatever its colour.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: Skin tones from dark to light (RGB); a person's tone is a random blend of two neighbours.
SKIN_TONES = np.array([(60, 38, 26), (105, 66, 42), (150, 100, 66), (198, 140, 100), (228, 180, 145), (246, 214, 190)], np.float64)
#: Head radius as a share of the object's longest side.
HEAD_SIZE = (0.08, 0.22)
#: Share of people standing in front of part of the object (the rest play it: behind, arms across).
IN_FRONT_SHARE = 0.4
#: Share of people whose skin takes the object's own main colour: wood is skin-coloured, so the
#: network must tell them apart by shape (a face, an arm), not by colour.
OBJECT_COLOURED_SKIN = 0.5
#: Largest share of the object a person in front may hide (the object must stay the largest thing
#: seen); a person in front who would hide more is drawn smaller, up to this many times.
MAX_HIDDEN = 0.45
PLACEMENT_TRIES = 4
#: Share of players whose arms are in sleeves (the clothes' colour) rather than bare.
SLEEVED_ARMS = 0.4


@dataclass
class PersonLayers:
    """A person's colours and coverage: ``behind`` goes under the object, ``front`` over it (both 0-1)."""

    colour: np.ndarray
    behind: np.ndarray
    front: np.ndarray


def person_layers(mask: np.ndarray, object_rgb: np.ndarray, rng: np.random.Generator) -> PersonLayers:
    """A random person placed against the object ``mask`` (square image, colours ``object_rgb``), as a player or a passer-by."""
    resolution = mask.shape[0]
    rows, cols = np.nonzero(mask)
    size = max(int(np.ptp(rows)), int(np.ptp(cols)), 1)
    if rng.random() < OBJECT_COLOURED_SKIN:
        skin = np.clip(np.median(object_rgb[mask], axis=0) * rng.uniform(0.85, 1.15, size=3), 0, 255)
    else:
        skin = _skin_tone(rng)
    clothes = _cloth_colour(rng)
    head_radius = max(3.0, size * rng.uniform(*HEAD_SIZE))
    in_front = rng.random() < IN_FRONT_SHARE
    for _ in range(PLACEMENT_TRIES if in_front else 1):
        anchor = (rows[rng.integers(len(rows))], cols[rng.integers(len(cols))])  # a point over the object's box
        figure, skin_parts = _figure(resolution, anchor, head_radius, rng)
        if not in_front or (figure & mask).sum() <= MAX_HIDDEN * mask.sum():
            break
        head_radius *= 0.7
    colour = np.broadcast_to(clothes, (resolution, resolution, 3)).copy()
    colour[skin_parts] = skin
    colour = _textured(colour, figure & ~skin_parts, rng)
    if in_front:
        behind, front = np.zeros(mask.shape, bool), figure
    else:
        arms = _arms_across(mask, anchor=_shoulders(figure), radius=head_radius, rng=rng)
        colour[arms] = clothes if rng.random() < SLEEVED_ARMS else skin
        behind, front = figure, arms
    if (front & mask).sum() > MAX_HIDDEN * mask.sum():  # the object would no longer be the largest thing seen
        behind, front = behind | front, np.zeros(mask.shape, bool)
    shaded = np.clip(colour * _rounded_shading(behind | front, head_radius)[..., None], 0, 255)
    return PersonLayers(colour=shaded, behind=_soft(behind, resolution), front=_soft(front, resolution))


def _skin_tone(rng: np.random.Generator) -> np.ndarray:
    """A skin colour between two neighbouring tones of :data:`SKIN_TONES`, a little jittered."""
    index = rng.integers(len(SKIN_TONES) - 1)
    blend = rng.random()
    tone = SKIN_TONES[index] * (1 - blend) + SKIN_TONES[index + 1] * blend
    return np.clip(tone * rng.uniform(0.9, 1.1, size=3), 0, 255)


def _cloth_colour(rng: np.random.Generator) -> np.ndarray:
    """Clothes: dark half the time (stage black, suits), else any colour."""
    hue, saturation = rng.uniform(0, 180), rng.uniform(0, 255)
    value = rng.uniform(10, 70) if rng.random() < 0.5 else rng.uniform(70, 255)
    return cv2.cvtColor(np.array([[[hue, saturation, value]]], np.uint8), cv2.COLOR_HSV2RGB)[0, 0].astype(np.float64)


def _figure(resolution: int, anchor: tuple[int, int], head_radius: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Head, neck and torso of a person whose chest is near ``anchor`` (row, col), the torso running
    off the image's bottom; returns (figure, skin)."""
    chest_row = anchor[0] + rng.uniform(-2, 2) * head_radius
    centre_col = anchor[1] + rng.uniform(-1.5, 1.5) * head_radius
    head_centre = (int(centre_col), int(chest_row - rng.uniform(2.5, 4.0) * head_radius))
    head_axes = (int(head_radius * 0.8), int(head_radius))
    skin = np.zeros((resolution, resolution), np.uint8)
    cv2.ellipse(skin, head_centre, head_axes, float(rng.uniform(-15, 15)), 0, 360, 1, -1)
    neck_top = head_centre[1] + int(head_radius * 0.8)
    cv2.rectangle(skin, (head_centre[0] - int(head_radius * 0.4), neck_top), (head_centre[0] + int(head_radius * 0.4), neck_top + int(head_radius * 0.8)), 1, -1)
    shoulders_row = neck_top + int(head_radius * 0.7)
    half_width = head_radius * rng.uniform(2.4, 3.4)
    torso = np.array([
        (head_centre[0] - half_width, shoulders_row + head_radius * 0.4), (head_centre[0] - half_width * 0.7, shoulders_row),
        (head_centre[0] + half_width * 0.7, shoulders_row), (head_centre[0] + half_width, shoulders_row + head_radius * 0.4),
        (head_centre[0] + half_width * rng.uniform(0.8, 1.0), resolution * 2), (head_centre[0] - half_width * rng.uniform(0.8, 1.0), resolution * 2),
    ], np.int32)
    body = np.zeros((resolution, resolution), np.uint8)
    cv2.fillPoly(body, [torso], 1)
    hair = np.zeros((resolution, resolution), np.uint8)
    if rng.random() < 0.8:
        cv2.ellipse(hair, (head_centre[0], head_centre[1] - int(head_radius * 0.25)), (int(head_radius * 0.9), int(head_radius * 0.85)), 0, 180, 360, 1, -1)
    skin_parts = skin.astype(bool) & ~hair.astype(bool)
    figure = skin.astype(bool) | body.astype(bool) | hair.astype(bool)
    _draw_face(skin_parts, head_centre, head_radius)
    return figure, skin_parts


def _draw_face(skin: np.ndarray, centre: tuple[int, int], radius: float) -> None:
    """Eyes and mouth as holes in the skin, filled with the clothes' colour like the rest of the figure."""
    features = np.zeros(skin.shape, np.uint8)
    eye = max(1, int(radius * 0.12))
    for side in (-1, 1):
        cv2.circle(features, (centre[0] + side * int(radius * 0.35), centre[1] - int(radius * 0.05)), eye, 1, -1)
    cv2.ellipse(features, (centre[0], centre[1] + int(radius * 0.5)), (max(1, int(radius * 0.3)), max(1, int(radius * 0.08))), 0, 0, 360, 1, -1)
    skin &= ~features.astype(bool)


def _shoulders(figure: np.ndarray) -> tuple[int, int, int]:
    """(row, left col, right col) of the torso's widest row near its top."""
    rows = np.nonzero(figure.any(axis=1))[0]
    widths = figure.sum(axis=1)
    top = rows[0] if len(rows) else 0
    below_head = np.arange(top, min(top + figure.shape[0] // 2, figure.shape[0]))
    row = int(below_head[np.argmax(widths[below_head])]) if len(below_head) else top
    cols = np.nonzero(figure[row])[0]
    return row, int(cols.min()) if len(cols) else 0, int(cols.max()) if len(cols) else 0


def _arms_across(mask: np.ndarray, anchor: tuple[int, int, int], radius: float, rng: np.random.Generator) -> np.ndarray:
    """One or two arms from the shoulders, each ending in a hand on the object (a strumming or fretting hand)."""
    row, left, right = anchor
    rows, cols = np.nonzero(mask)
    arms = np.zeros(mask.shape, np.uint8)
    width = max(2, int(radius * rng.uniform(0.55, 0.8)))
    for shoulder_col in rng.permutation([left, right])[: int(rng.integers(1, 3))]:
        pick = rng.integers(len(rows))
        hand = (int(cols[pick]), int(rows[pick]))
        shoulder = (int(shoulder_col), int(row + radius * 0.3))
        elbow = (int((shoulder[0] + hand[0]) / 2 + rng.uniform(-2, 2) * radius), int(max(shoulder[1], hand[1]) + rng.uniform(0.5, 2.5) * radius))
        cv2.line(arms, shoulder, elbow, 1, width * 2)
        cv2.line(arms, elbow, hand, 1, int(width * 1.7))
        cv2.ellipse(arms, hand, (width, int(width * 1.3)), float(rng.uniform(0, 180)), 0, 360, 1, -1)
    return arms.astype(bool)


def _textured(colour: np.ndarray, cloth: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Clothes plain, striped or mottled."""
    pattern = rng.integers(3)
    if pattern == 0:
        return colour
    resolution = colour.shape[0]
    if pattern == 1:
        period = rng.uniform(4, 16)
        modulation = 1 + 0.3 * np.sign(np.sin(np.arange(resolution) / period * np.pi))[None, :].repeat(resolution, 0)
        if rng.random() < 0.5:
            modulation = modulation.T
    else:
        coarse = rng.uniform(-1, 1, size=(int(rng.integers(8, 40)),) * 2).astype(np.float32)
        modulation = 1 + 0.3 * cv2.resize(coarse, (resolution, resolution), interpolation=cv2.INTER_CUBIC).clip(-1, 1)
    textured = colour.copy()
    textured[cloth] *= modulation[cloth][:, None]
    return textured


def _rounded_shading(shape: np.ndarray, radius: float) -> np.ndarray:
    """Lighter inside, darker towards the edges, as a rounded body under soft light."""
    depth = cv2.distanceTransform(shape.astype(np.uint8), cv2.DIST_L2, 3)
    return 0.65 + 0.35 * np.sqrt(np.clip(depth / max(radius, 1.0), 0, 1))


def _soft(shape: np.ndarray, resolution: int) -> np.ndarray:
    """A 0-1 cover with an edge half a pixel soft (anti-aliased at 256 px)."""
    return cv2.GaussianBlur(shape.astype(np.float32), (0, 0), max(0.5, resolution / 512)).astype(np.float64)

"""Airplane templates: airliner, fighter and light aircraft seen from above.

Canonical frame: nose toward +Y, wingspan along X, height along Z (the fin points to
+Z). A round fuselage, thin wings with rounded leading and trailing edges, a tailplane,
the fin as a ridge along the rear centre line, and engines below the wings (airliner)
or at the nose (light aircraft) or as the intakes and nozzle (fighter).
"""

from __future__ import annotations

import numpy as np

from frontal3d.family import Template
from frontal3d.template_geometry import Canvas, height_field_template, rounded_profile, sd_box, sd_ellipse, sd_polygon, smooth_union

REGIONS = {subtype: ("fuselage", "wings", "tail", "engines") for subtype in ("airliner", "fighter", "light")}


def _wing(span: float, root_y: tuple[float, float], tip_y: tuple[float, float], x_root: float = 0.0) -> list[tuple[float, float]]:
    """A tapered, swept wing pair outline: root (leading y, trailing y) to tip (leading, trailing)."""
    half = span / 2
    return [
        (-x_root, root_y[0]), (-half, tip_y[0]), (-half, tip_y[1]), (-x_root, root_y[1]),
        (x_root, root_y[1]), (half, tip_y[1]), (half, tip_y[0]), (x_root, root_y[0]),
    ]


def _fuselage(c: Canvas, length: float, radius: float, nose: float, tail: float) -> np.ndarray:
    """Signed distance of a fuselage: a cylinder with an ogive nose and a tapering tail cone."""
    y = c.y
    half_width = np.full(c.shape, radius)
    nose_start, tail_end = length / 2 - nose, -length / 2 + tail
    in_nose = y > nose_start
    half_width = np.where(in_nose, radius * np.sqrt(np.clip(1 - ((y - nose_start) / nose) ** 2, 0, 1)), half_width)
    in_tail = y < tail_end
    half_width = np.where(in_tail, radius * (0.25 + 0.75 * np.clip((y + length / 2) / tail, 0, 1)), half_width)
    return np.maximum(np.abs(c.x) - half_width, np.abs(y) - length / 2)


def _assemble(subtype: str, c: Canvas, parts: dict[str, np.ndarray], radius: float, wing_half: float, wing_z: float, fin: tuple[float, float, float], engine_depth: tuple[float, float], landmarks: dict) -> Template:
    """Label the parts and give each its height profile."""
    fuselage_sd, wings_sd, tail_sd, engines_sd = parts["fuselage"], parts["wings"], parts["tail"], parts["engines"]
    shape = smooth_union(smooth_union(fuselage_sd, np.minimum(wings_sd, tail_sd), radius * 0.3), engines_sd, radius * 0.1) < 0
    labels = np.full(c.shape, -1, np.int32)
    labels[shape] = 1
    labels[shape & (tail_sd < 0)] = 2
    labels[shape & (engines_sd < 0)] = 3
    fuselage = shape & (fuselage_sd < radius * 0.05)
    labels[fuselage] = 0
    distance = c.distance_inside(shape)
    # Thin lifting surfaces: half-thickness rounded toward every edge.
    surface_half = rounded_profile(distance, wing_half, wing_half * 4)
    front, back = wing_z + surface_half, wing_z - surface_half
    # A round fuselage cross-section.
    across = np.clip(-fuselage_sd / radius, 0, 1)
    body_half = radius * np.sqrt(1 - (1 - across) ** 2)
    front = np.where(fuselage, np.maximum(front, body_half), front)
    back = np.where(fuselage, np.minimum(back, -body_half), back)
    engines = shape & (engines_sd < 0) & ~fuselage
    engine_top, engine_bottom = engine_depth
    front = np.where(engines, np.maximum(front, engine_top), front)
    back = np.where(engines, np.minimum(back, engine_bottom), back)
    fin_y0, fin_y1, fin_height = fin
    on_fin = fuselage & (np.abs(c.x) < 2.5 * c.pixel_size) & (c.y > fin_y0) & (c.y < fin_y1)
    rise = np.clip((c.y - fin_y0) / (fin_y1 - fin_y0), 0, 1)
    front = np.where(on_fin, np.maximum(front, radius + fin_height * np.sqrt(1 - rise)), front)
    labels[on_fin] = 2
    return height_field_template("airplane", subtype, c, labels, np.where(shape, front, 0), np.where(shape, back, 0), REGIONS[subtype], landmarks)


def build_airliner() -> Template:
    span, length, radius = 36.0, 38.0, 2.0
    c = Canvas((-span / 2, span / 2), (-length / 2, length / 2))
    wings = sd_polygon(c, _wing(span, (5.0, -3.5), (-6.5, -8.2), x_root=0.0), round_r=0.3)
    tail = sd_polygon(c, _wing(12.5, (-13.5, -18.0), (-17.8, -19.3)), round_r=0.2)
    engines = np.minimum(sd_box(c, -7.8, -5.0, -1.5, 4.0, round_r=1.2), sd_box(c, 5.0, 7.8, -1.5, 4.0, round_r=1.2))
    parts = {"fuselage": _fuselage(c, length, radius, 5.0, 8.0), "wings": wings, "tail": tail, "engines": engines}
    landmarks = {"nose": (0.0, 18.9, 0.0), "tail": (0.0, -18.9, 0.5), "wing_tip_left": (-17.8, -7.3, -0.9),
                 "wing_tip_right": (17.8, -7.3, -0.9), "fin_tip": (0.0, -18.0, 8.5)}
    return _assemble("airliner", c, parts, radius, 0.35, -0.9, (-18.5, -12.0, 7.0), (-0.3, -2.4), landmarks)


def build_fighter() -> Template:
    span, length, radius = 12.0, 19.0, 1.1
    c = Canvas((-span / 2, span / 2), (-length / 2, length / 2))
    wings = sd_polygon(c, _wing(span, (2.5, -5.5), (-4.2, -6.0)), round_r=0.15)
    tail = sd_polygon(c, _wing(8.0, (-6.5, -9.4), (-8.8, -9.6)), round_r=0.1)
    engines = np.minimum(sd_box(c, -1.9, -0.6, -1.0, 3.8, round_r=0.4), sd_box(c, 0.6, 1.9, -1.0, 3.8, round_r=0.4))
    parts = {"fuselage": _fuselage(c, length, radius, 5.5, 2.0), "wings": wings, "tail": tail, "engines": engines}
    landmarks = {"nose": (0.0, 9.4, 0.0), "tail": (0.0, -9.4, 0.0), "wing_tip_left": (-5.9, -5.0, -0.1),
                 "wing_tip_right": (5.9, -5.0, -0.1), "fin_tip": (0.0, -9.0, 4.0)}
    return _assemble("fighter", c, parts, radius, 0.12, -0.1, (-9.4, -4.5, 3.2), (0.9, -0.9), landmarks)


def build_light() -> Template:
    span, length, radius = 11.0, 8.2, 0.6
    c = Canvas((-span / 2, span / 2), (-length / 2, length / 2))
    wings = sd_polygon(c, _wing(span, (1.6, 0.1), (1.4, 0.3)), round_r=0.15)
    tail = sd_polygon(c, _wing(3.4, (-2.9, -4.0), (-3.3, -3.9)), round_r=0.1)
    engines = sd_ellipse(c, 0.0, 3.5, 0.55, 0.65)
    parts = {"fuselage": _fuselage(c, length, radius, 0.9, 3.0), "wings": wings, "tail": tail, "engines": engines}
    landmarks = {"nose": (0.0, 4.05, 0.0), "tail": (0.0, -4.05, 0.2), "wing_tip_left": (-5.45, 0.9, 0.55),
                 "wing_tip_right": (5.45, 0.9, 0.55), "fin_tip": (0.0, -3.9, 1.8)}
    return _assemble("light", c, parts, radius, 0.1, 0.55, (-4.1, -2.6, 1.3), (0.6, -0.6), landmarks)


BUILDERS = {"airliner": build_airliner, "fighter": build_fighter, "light": build_light}

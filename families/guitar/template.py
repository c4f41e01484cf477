"""Guitar templates: classical and electric, front view, neck up (+Y), face toward +Z.

Real proportions in metres. The classical body is a figure eight about 10 cm deep with
rounded edges and the sound hole as a shallow blind recess; the electric is a 4.5 cm
solid body with cutaways, its bridge, pickups and controls painted as regions.
"""

from __future__ import annotations

import numpy as np

from frontal3d.family import Template
from frontal3d.template_geometry import Canvas, height_field_template, rounded_profile, sd_box, sd_circle, sd_ellipse, smooth_union, surface_z

REGIONS = {
    "classical": ("body", "neck", "head", "bridge", "hole"),
    "electric": ("body", "neck", "head", "bridge", "pickups", "controls"),
}


def _neck_and_head(c: Canvas, neck_x: float, neck_y: tuple[float, float], head_x: float, head_y: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    neck = sd_box(c, -neck_x, neck_x, neck_y[0], neck_y[1]) < 0
    head = sd_box(c, -head_x, head_x, head_y[0], head_y[1], round_r=0.012) < 0
    return neck, head & ~neck


def _neck_depths(c: Canvas, neck: np.ndarray, head: np.ndarray, top: float, neck_half_width: float, neck_depth: float, head_depth: float, front: np.ndarray, back: np.ndarray) -> None:
    """A fretboard flush above the top, a half-round neck back, a flat headstock plate."""
    across = np.clip(np.abs(c.x) / neck_half_width, 0, 1)
    front[neck] = top + 0.004
    back[neck] = (top + 0.004 - neck_depth * np.sqrt(1 - 0.8 * across**2))[neck]
    front[head] = top - 0.004
    back[head] = top - 0.004 - head_depth


def build_classical() -> Template:
    c = Canvas((-0.2, 0.2), (-0.5, 0.5))
    body_sd = smooth_union(sd_circle(c, 0.0, -0.255, 0.187), sd_circle(c, 0.0, -0.035, 0.142), 0.09)
    body = body_sd < 0
    neck, head = _neck_and_head(c, 0.027, (0.06, 0.30), 0.037, (0.30, 0.495))
    neck &= ~body
    labels = np.full(c.shape, -1, np.int32)
    labels[body], labels[neck], labels[head] = 0, 1, 2
    bridge = (sd_box(c, -0.095, 0.095, -0.305, -0.27, round_r=0.008) < 0) & body
    hole = (sd_circle(c, 0.0, -0.075, 0.043) < 0) & body
    labels[bridge], labels[hole] = 3, 4
    half = rounded_profile(c.distance_inside(body), 0.05, 0.02)
    front, back = np.where(body, half, 0.0), np.where(body, -half, 0.0)
    front[hole] -= 0.006  # the sound hole: a shallow blind recess, so the template stays genus 0
    front[bridge] += 0.004
    _neck_depths(c, neck, head, 0.05, 0.027, 0.022, 0.016, front, back)
    landmarks = {
        "strap_pin_bottom": (0.0, -0.44, 0.0),
        "strap_pin_neck": (0.0, 0.075, 0.03),
        "nut": (0.0, 0.30, surface_z(c, front, 0.0, 0.295)),
        "bridge_center": (0.0, -0.288, surface_z(c, front, 0.0, -0.288)),
        "headstock_tip": (0.0, 0.49, 0.04),
    }
    return height_field_template("guitar", "classical", c, labels, front, back, REGIONS["classical"], landmarks)


def build_electric() -> Template:
    c = Canvas((-0.2, 0.2), (-0.5, 0.5))
    lower = sd_ellipse(c, 0.0, -0.235, 0.165, 0.15)
    upper = sd_ellipse(c, 0.0, -0.075, 0.142, 0.12)
    horns = np.minimum(sd_ellipse(c, -0.085, 0.03, 0.04, 0.095), sd_ellipse(c, 0.095, 0.0, 0.038, 0.07))
    body_sd = smooth_union(smooth_union(lower, upper, 0.06), horns, 0.05)
    cutaway = sd_ellipse(c, 0.005, 0.075, 0.048, 0.09)
    body = (np.maximum(body_sd, -cutaway) < 0) & (c.y < 0.13)
    neck, head = _neck_and_head(c, 0.027, (0.0, 0.36), 0.045, (0.36, 0.53))
    neck &= ~body
    labels = np.full(c.shape, -1, np.int32)
    labels[body], labels[neck], labels[head] = 0, 1, 2
    labels[(sd_box(c, -0.045, 0.045, -0.285, -0.25, round_r=0.005) < 0) & body] = 3
    for y in (-0.205, -0.145, -0.085):
        labels[(sd_box(c, -0.04, 0.04, y - 0.011, y + 0.011, round_r=0.008) < 0) & body] = 4
    for x, y in ((0.085, -0.27), (0.11, -0.225), (0.125, -0.18)):
        labels[(sd_circle(c, x, y, 0.013) < 0) & body] = 5
    half = rounded_profile(c.distance_inside(body), 0.0225, 0.012)
    front, back = np.where(body, half, 0.0), np.where(body, -half, 0.0)
    _neck_depths(c, neck, head, 0.0225, 0.027, 0.022, 0.014, front, back)
    landmarks = {
        "strap_pin_bottom": (0.0, -0.38, 0.0),
        "strap_pin_neck": (-0.085, 0.12, 0.0),
        "nut": (0.0, 0.36, surface_z(c, front, 0.0, 0.355)),
        "bridge_center": (0.0, -0.268, surface_z(c, front, 0.0, -0.268)),
        "headstock_tip": (0.0, 0.525, 0.015),
    }
    return height_field_template("guitar", "electric", c, labels, front, back, REGIONS["electric"], landmarks)


BUILDERS = {"classical": build_classical, "electric": build_electric}

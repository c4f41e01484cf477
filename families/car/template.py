"""Car templates: sedan, SUV and sports car seen from the side.

Canonical frame: front toward +X, wheels down (-Y), width along Z, mirror-symmetric
about Z = 0. Each is a lower body with wheels and a narrower glasshouse (the roof is
narrower than the body: tumblehome), all edges rounded in plan and section.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frontal3d.family import Template
from frontal3d.template_geometry import Canvas, height_field_template, rounded_profile, sd_box, sd_circle, sd_polygon, smooth_union

REGIONS = {subtype: ("body", "windows", "wheels", "lights") for subtype in ("sedan", "suv", "sports")}


@dataclass(frozen=True)
class CarShape:
    """Side-view proportions in metres (x from the rear bumper, y from the ground)."""

    length: float
    width: float
    sill: float  # bottom of the body between the wheels
    belt: float  # top of the lower body (bottom of the windows)
    roof: float
    wheel_radius: float
    wheelbase: float
    front_overhang: float
    glasshouse: tuple[tuple[float, float], ...]  # (x, y) outline of the cabin above the belt line
    nose_height: float  # top of the front bumper/bonnet edge
    tail_height: float  # top of the rear end


SHAPES = {
    "sedan": CarShape(4.75, 1.82, 0.22, 0.92, 1.45, 0.33, 2.80, 0.95,
                      ((1.00, 0.92), (1.55, 1.42), (2.85, 1.45), (3.55, 0.95)), 0.80, 0.95),
    "suv": CarShape(4.60, 1.88, 0.32, 1.08, 1.75, 0.38, 2.75, 0.90,
                    ((0.25, 1.08), (0.45, 1.72), (3.00, 1.75), (3.60, 1.10)), 0.95, 1.05),
    "sports": CarShape(4.40, 1.90, 0.14, 0.78, 1.22, 0.34, 2.55, 1.00,
                       ((1.15, 0.78), (1.85, 1.20), (2.55, 1.22), (3.35, 0.80)), 0.62, 0.82),
}


def build(subtype: str) -> Template:
    s = SHAPES[subtype]
    c = Canvas((0.0, s.length), (0.0, s.roof))
    rear_axle = s.length - s.front_overhang - s.wheelbase
    front_axle = s.length - s.front_overhang
    lower_outline = [
        (0.02, s.sill + 0.05), (0.0, s.tail_height * 0.7), (0.05, s.tail_height), (s.length * 0.25, s.belt),
        (s.length * 0.7, s.belt), (s.length - 0.05, s.nose_height), (s.length, s.nose_height * 0.6), (s.length - 0.03, s.sill + 0.05),
    ]
    lower = sd_polygon(c, lower_outline, round_r=0.12)
    lower = np.maximum(lower, s.sill - c.y) if s.sill > 0 else lower
    cabin_outline = [(x, y) for x, y in s.glasshouse]
    cabin_outline = [(cabin_outline[0][0] - 0.2, s.belt - 0.1)] + cabin_outline + [(cabin_outline[-1][0] + 0.2, s.belt - 0.1)]
    cabin = sd_polygon(c, cabin_outline, round_r=0.1)
    wheels_sd = np.minimum(sd_circle(c, rear_axle, s.wheel_radius, s.wheel_radius), sd_circle(c, front_axle, s.wheel_radius, s.wheel_radius))
    car = smooth_union(smooth_union(lower, cabin, 0.15), wheels_sd, 0.05) < 0
    labels = np.full(c.shape, -1, np.int32)
    labels[car] = 0
    windows = (sd_polygon(c, list(s.glasshouse), round_r=0.06) < -0.05) & (c.y > s.belt + 0.05) & car
    labels[windows] = 1
    wheels = (wheels_sd < 0) & car
    labels[wheels] = 2
    lights = car & (
        ((np.abs(c.x - (s.length - 0.12)) < 0.12) & (np.abs(c.y - (s.nose_height - 0.12)) < 0.07))
        | ((c.x < 0.15) & (np.abs(c.y - (s.tail_height - 0.15)) < 0.08))
    )
    labels[lights] = 3
    distance = c.distance_inside(car)
    # Half-width: full over the lower body, tapering up the glasshouse to ~78 % at the roof.
    taper = np.clip((c.y - s.belt) / (s.roof - s.belt), 0.0, 1.0)
    half_width = s.width / 2 * (1.0 - 0.22 * taper)
    half_width = np.where(wheels, s.width / 2 * 0.92, half_width)
    half = rounded_profile(distance, half_width, 0.28)
    front = np.where(car, half, 0.0)
    landmarks = {
        "wheel_rear_left": (rear_axle, s.wheel_radius, s.width * 0.46),
        "wheel_rear_right": (rear_axle, s.wheel_radius, -s.width * 0.46),
        "wheel_front_left": (front_axle, s.wheel_radius, s.width * 0.46),
        "wheel_front_right": (front_axle, s.wheel_radius, -s.width * 0.46),
        "front_bumper": (s.length - 0.02, s.nose_height * 0.6, 0.0),
        "rear_bumper": (0.03, s.tail_height * 0.6, 0.0),
        "roof": (float(np.mean([p[0] for p in s.glasshouse[1:3]])), s.roof - 0.05, 0.0),
    }
    return height_field_template("car", subtype, c, labels, front, -front, REGIONS[subtype], landmarks)


BUILDERS = {subtype: (lambda subtype=subtype: build(subtype)) for subtype in SHAPES}

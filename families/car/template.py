"""Car templates: sedan, suv (hatchback/SUV) and sports, side view, front toward +X, wheels down.

Real proportions in metres; width runs along Z and every part is symmetric about
Z = 0. A reconstruction takes its width profile from here, so it follows what real
car meshes show (measured on the shared meshes, longest side 1): a full-width
lower body whose ends and edges round off, a greenhouse about 80 % as wide
(the roof is narrower than the shoulders), and full-width wheels, so every ray
along -Z crosses the car once. Windows and lights are painted regions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frontal3d.family import Template
from frontal3d.template_geometry import centre_on_bounds, ellipse_outline, prism, rounded_polygon, rounded_slab, union_labelled

REGIONS = {subtype: ("body", "windows", "wheels", "lights") for subtype in ("sedan", "suv", "sports")}


@dataclass(frozen=True)
class CarShape:
    """A car's side profile (x from the rear bumper, y from the ground) and widths, in metres."""

    width: float
    greenhouse_width: float
    wheel_radius: float
    wheel_x: tuple[float, float]
    lower_body: tuple[tuple[float, float], ...]
    greenhouse: tuple[tuple[float, float], ...]
    window: tuple[tuple[float, float], ...]
    headlight: tuple[float, float, float, float]
    taillight: tuple[float, float, float, float]
    bumper_height: float = 0.45
    body_corner: float = 0.2


SHAPES = {
    "sedan": CarShape(
        width=1.84, greenhouse_width=1.46, wheel_radius=0.33, wheel_x=(0.95, 3.75),
        lower_body=((0.0, 0.38), (0.06, 0.2), (0.6, 0.16), (4.2, 0.16), (4.66, 0.24), (4.7, 0.5), (4.62, 0.72),
                    (3.4, 0.9), (1.1, 0.98), (0.06, 0.96), (0.0, 0.8)),
        greenhouse=((0.75, 0.8), (0.95, 0.97), (1.65, 1.4), (2.75, 1.42), (3.45, 0.92), (3.55, 0.8)),
        window=((1.2, 1.02), (1.75, 1.32), (2.7, 1.33), (3.2, 1.0)),
        headlight=(4.45, 4.8, 0.58, 0.74), taillight=(-0.1, 0.22, 0.72, 0.9),
    ),
    "suv": CarShape(
        width=1.84, greenhouse_width=1.5, wheel_radius=0.38, wheel_x=(0.85, 3.6),
        lower_body=((0.0, 0.45), (0.04, 0.26), (0.5, 0.22), (4.2, 0.22), (4.55, 0.3), (4.6, 0.6), (4.52, 0.95),
                    (3.5, 1.06), (0.06, 1.08), (0.0, 1.0)),
        greenhouse=((0.02, 0.95), (0.06, 1.68), (0.35, 1.75), (2.6, 1.76), (3.55, 1.06), (3.65, 0.95)),
        window=((0.3, 1.14), (0.38, 1.62), (2.55, 1.63), (3.25, 1.14)),
        headlight=(4.35, 4.7, 0.78, 0.95), taillight=(-0.1, 0.2, 0.85, 1.1),
    ),
    "sports": CarShape(
        width=1.74, greenhouse_width=1.34, wheel_radius=0.32, wheel_x=(0.85, 3.5),
        lower_body=((0.0, 0.4), (0.06, 0.16), (0.5, 0.12), (4.0, 0.12), (4.38, 0.2), (4.4, 0.46), (3.2, 0.8),
                    (1.2, 0.86), (0.04, 0.82)),
        greenhouse=((0.6, 0.72), (1.0, 0.9), (1.75, 1.18), (2.4, 1.2), (3.2, 0.8), (3.35, 0.72)),
        window=((1.25, 0.92), (1.85, 1.12), (2.35, 1.13), (2.95, 0.86)),
        headlight=(4.05, 4.5, 0.3, 0.48), taillight=(-0.1, 0.2, 0.55, 0.75),
        bumper_height=0.32, body_corner=0.16,
    ),
}


def _box(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])


def build(subtype: str) -> Template:
    """Build one car subtype from its :class:`CarShape`."""
    shape = SHAPES[subtype]
    regions = REGIONS[subtype]
    half_width = shape.width / 2
    lower = rounded_slab(
        rounded_polygon(shape.lower_body, shape.body_corner, count=320), -half_width, half_width,
        radius=shape.body_corner, floor=0.62, rings=8,
    )
    greenhouse = rounded_slab(
        rounded_polygon(shape.greenhouse, 0.12, count=256), -shape.greenhouse_width / 2, shape.greenhouse_width / 2,
        radius=0.12, floor=0.7, rings=6,
    )
    tyre_half_width = half_width - 0.03
    wheels = [
        rounded_slab(ellipse_outline((x, shape.wheel_radius), (shape.wheel_radius, shape.wheel_radius), count=96),
                     -tyre_half_width, tyre_half_width, radius=0.06, floor=0.85, rings=5)
        for x in shape.wheel_x
    ]
    through = (-shape.width, shape.width)
    decals = [(prism(np.array(shape.window), *through), regions.index("windows"))]
    decals += [(prism(_box(*light), *through), regions.index("lights")) for light in (shape.headlight, shape.taillight)]
    mesh, labels = union_labelled(
        [(lower, regions.index("body")), (greenhouse, regions.index("body"))] + [(w, regions.index("wheels")) for w in wheels],
        decals=decals,
    )
    length = max(x for x, _ in shape.lower_body)
    wheel_z = half_width - 0.15
    roof_points = sorted(shape.greenhouse, key=lambda point: point[1])[-2:]
    roof_x = 0.5 * (roof_points[0][0] + roof_points[1][0])
    roof_y = max(y for _, y in roof_points)
    rear_x, front_x = shape.wheel_x
    landmarks = {
        "wheel_front_left": (front_x, shape.wheel_radius, wheel_z),
        "wheel_front_right": (front_x, shape.wheel_radius, -wheel_z),
        "wheel_rear_left": (rear_x, shape.wheel_radius, wheel_z),
        "wheel_rear_right": (rear_x, shape.wheel_radius, -wheel_z),
        "front_bumper": (length - 0.03, shape.bumper_height, 0.0),
        "rear_bumper": (0.03, 0.55, 0.0),
        "roof": (roof_x, roof_y - 0.08, 0.0),
    }
    mesh, landmarks = centre_on_bounds(mesh, landmarks)
    return Template(family="car", subtype=subtype, mesh=mesh, face_regions=labels, region_names=regions, landmarks=landmarks)


BUILDERS = {subtype: (lambda subtype=subtype: build(subtype)) for subtype in SHAPES}

"""Guitar templates: classical and electric, front view, neck up (+Y), face toward +Z.

Real proportions in metres (overall length about 1 m). The Z profile is what a
reconstruction inherits, so it follows real guitars: a flat-topped, flat-backed
body (acoustic 10 cm deep at the neck and 12 cm at the tail, electric 4.5 cm),
edges rounded over a few centimetres, a neck whose fretboard stands just above the top and a thinner
headstock. The classical sound hole is a shallow blind recess (the template stays
one closed solid); the electric's bridge, pickups and controls are painted
regions on a flat face, as the paper asks for no small details (section 3.2.1).
"""

from __future__ import annotations

import numpy as np
from manifold3d import Manifold

from frontal3d.family import Template
from frontal3d.template_geometry import (
    centre_on_bounds,
    ellipse_outline,
    fit_outline,
    mirrored_outline,
    prism,
    rounded_polygon,
    rounded_slab,
    taper_depth,
    union_labelled,
)

REGIONS = {
    "classical": ("body", "neck", "head", "bridge", "hole"),
    "electric": ("body", "neck", "head", "bridge", "pickups", "controls"),
}

TOP_Y = 0.5
BOTTOM_Y = -0.5
#: Depth of the acoustic body at its tail end (it is 10 cm where the neck joins).
ACOUSTIC_TAIL_DEPTH = 0.12


def _neck(top_z: float, y_low: float, y_nut: float, width_low: float, width_nut: float) -> Manifold:
    """A tapered neck: flat fretboard just above the top, rounded back about 2.2 cm deep."""
    outline = rounded_polygon(
        [(-width_low / 2, y_low), (width_low / 2, y_low), (width_nut / 2, y_nut), (-width_nut / 2, y_nut)],
        corner_radius=0.008,
    )
    return rounded_slab(outline, top_z - 0.021, top_z + 0.006, radius=0.008, floor=0.45)


def _head(top_z: float, y_low: float, width: float, thickness: float) -> Manifold:
    """A flat headstock plate set back below the fretboard, flaring slightly to the tip."""
    outline = rounded_polygon(
        [(-0.42 * width, y_low), (0.42 * width, y_low), (0.5 * width, TOP_Y), (-0.5 * width, TOP_Y)],
        corner_radius=0.01,
    )
    return rounded_slab(outline, top_z - 0.004 - thickness, top_z - 0.004, radius=0.006, floor=0.5)


def build_classical() -> Template:
    """An acoustic guitar: 1.0 m long, figure-eight body 0.37 m wide, 10 cm deep at the neck, 12 at the tail.

    The depth covers both classical (about 10 cm) and steel-string guitars (dreadnoughts
    grow from 10 to 12.5 cm toward the tail), which a front view cannot tell apart.
    """
    regions = REGIONS["classical"]
    depth = 0.10
    top_z = depth / 2
    body_top_y = -0.02
    body_outline = fit_outline(
        mirrored_outline(
            [(0.0, -0.5), (0.12, -0.5), (0.185, -0.45), (0.19, -0.34), (0.15, -0.24), (0.12, -0.19),
             (0.14, -0.12), (0.14, -0.04), (0.09, -0.02), (0.0, -0.02)],
            count=320,
        ),
        (-0.185, 0.185),
        (BOTTOM_Y, body_top_y),
    )
    body = rounded_slab(body_outline, -top_z, top_z, radius=0.02, floor=0.55, rings=7)
    neck = _neck(top_z, body_top_y - 0.04, 0.30, 0.060, 0.052)
    head = _head(top_z, 0.295, 0.078, 0.018)
    bridge_y = -0.36
    bridge = rounded_slab(
        rounded_polygon([(-0.095, bridge_y - 0.016), (0.095, bridge_y - 0.016), (0.095, bridge_y + 0.016), (-0.095, bridge_y + 0.016)], 0.008),
        top_z - 0.004, top_z + 0.009, radius=0.004, floor=0.5,
    )
    hole_centre = (0.0, -0.14)
    recess = prism(ellipse_outline(hole_centre, (0.043, 0.043), count=96), top_z - 0.006, top_z + 0.01)
    mesh, labels = union_labelled(
        [(body, regions.index("body")), (neck, regions.index("neck")), (head, regions.index("head")), (bridge, regions.index("bridge"))],
        cutters=[(recess, regions.index("hole"))],
    )
    landmarks = {
        "strap_pin_bottom": (0.0, BOTTOM_Y + 0.002, 0.0),
        "strap_pin_neck": (0.0, body_top_y + 0.004, top_z - 0.02),
        "nut": (0.0, 0.29, top_z + 0.002),
        "bridge_center": (0.0, bridge_y, top_z + 0.008),
        "headstock_tip": (0.0, TOP_Y - 0.002, top_z - 0.013),
    }
    mesh, landmarks = taper_depth(mesh, landmarks, body_top_y, BOTTOM_Y, ACOUSTIC_TAIL_DEPTH / depth)
    mesh, landmarks = centre_on_bounds(mesh, landmarks)
    return Template(family="guitar", subtype="classical", mesh=mesh, face_regions=labels, region_names=regions, landmarks=landmarks)


def build_electric() -> Template:
    """A solid-body electric guitar: 0.99 m long, double-cutaway body 0.33 m wide, 4.5 cm deep."""
    regions = REGIONS["electric"]
    depth = 0.045
    top_z = depth / 2
    body_outline = fit_outline(
        mirrored_outline(
            [(0.0, -0.495), (0.12, -0.49), (0.165, -0.43), (0.16, -0.33), (0.125, -0.26), (0.13, -0.19),
             (0.155, -0.11), (0.15, -0.03), (0.125, -0.02), (0.09, -0.07), (0.05, -0.12), (0.0, -0.125)],
            count=360,
        ),
        (-0.165, 0.165),
        (BOTTOM_Y + 0.005, -0.03),
    )
    body = rounded_slab(body_outline, -top_z, top_z, radius=0.013, floor=0.35, rings=7)
    neck = _neck(top_z, -0.17, 0.30, 0.057, 0.043)
    head = _head(top_z, 0.295, 0.085, 0.014)
    bridge_y = -0.35

    def painted(polygon: np.ndarray) -> Manifold:
        return prism(polygon, top_z - 0.002, top_z + 0.002)

    decals = [(painted(_box(-0.045, 0.045, bridge_y - 0.035, bridge_y + 0.015)), regions.index("bridge"))]
    decals += [(painted(_box(-0.04, 0.04, y - 0.011, y + 0.011)), regions.index("pickups")) for y in (-0.305, -0.255, -0.205)]
    decals += [(painted(rounded_polygon(_box(0.06, 0.125, -0.43, -0.33), 0.015, count=64)), regions.index("controls"))]
    mesh, labels = union_labelled([(body, regions.index("body")), (neck, regions.index("neck")), (head, regions.index("head"))], decals=decals)
    landmarks = {
        "strap_pin_bottom": (0.0, BOTTOM_Y + 0.007, 0.0),
        "strap_pin_neck": (0.13, -0.035, 0.0),
        "nut": (0.0, 0.29, top_z + 0.002),
        "bridge_center": (0.0, bridge_y, top_z - 0.001),
        "headstock_tip": (0.0, TOP_Y - 0.002, top_z - 0.011),
    }
    mesh, landmarks = centre_on_bounds(mesh, landmarks)
    return Template(family="guitar", subtype="electric", mesh=mesh, face_regions=labels, region_names=regions, landmarks=landmarks)


def _box(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])


BUILDERS = {"classical": build_classical, "electric": build_electric}

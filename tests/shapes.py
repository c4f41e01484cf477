"""Small generated meshes shared by several test modules."""

from __future__ import annotations

import trimesh


def box_car() -> trimesh.Trimesh:
    """A car in the canonical frame (front to +X, up +Y, width along Z): a long body, a
    cabin set back, four wheels; the front and back ends differ."""
    body = trimesh.creation.box(extents=[4.2, 0.7, 1.8])
    body.apply_translation([0.0, 0.65, 0.0])
    cabin = trimesh.creation.box(extents=[2.0, 0.6, 1.5])
    cabin.apply_translation([-0.3, 1.3, 0.0])
    parts = [body, cabin]
    for x in (-1.4, 1.4):
        for z in (-0.75, 0.75):
            wheel = trimesh.creation.cylinder(radius=0.35, height=0.25, sections=24)
            wheel.apply_translation([x, 0.35, z])
            parts.append(wheel)
    return trimesh.util.concatenate(parts)

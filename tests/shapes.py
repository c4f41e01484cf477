"""Small generated meshes, and renders of the shipped templates, shared by several test modules."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from frontal3d.family import Family

#: The one-subtype guitar family :func:`slab_guitar` is judged in.
SLAB_GUITAR_FAMILY = Family(name="guitar", subtypes=("classical",), canonical_view="front",
                            regions={"classical": ("body", "neck")}, real_size={"classical": 1.0},
                            view_hint="a front view of the guitar's face")


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


def box_car_meshes(folder: Path) -> Path:
    """``folder`` holding the box car, scaled to unit length, as the only mesh (evaluate-gate input)."""
    folder.mkdir()
    car = box_car()
    car.apply_scale(1.0 / max(car.extents))
    car.export(folder / "boxcar.glb")
    return folder


def slab_guitar() -> tuple[trimesh.Trimesh, np.ndarray]:
    """A classical-guitar-like solid (neck +Y, face +Z): a 10 cm deep body of two bouts with
    square-cut edges, a neck lying on the face, a headstock; and each face's region (0 body, 1 neck)."""
    lower = trimesh.creation.cylinder(radius=0.19, height=0.1, sections=64)
    lower.apply_translation([0.0, -0.3, 0.0])
    upper = trimesh.creation.cylinder(radius=0.14, height=0.1, sections=64)
    upper.apply_translation([0.0, -0.08, 0.0])
    neck = trimesh.creation.box(extents=[0.055, 0.5, 0.05])
    neck.apply_translation([0.0, 0.3, 0.055])
    head = trimesh.creation.box(extents=[0.08, 0.16, 0.03])
    head.apply_translation([0.0, 0.62, 0.055])
    parts = [lower, upper, neck, head]
    labels = np.concatenate([np.full(len(part.faces), label) for part, label in zip(parts, (0, 0, 1, 1))])
    return trimesh.util.concatenate(parts), labels


def toy_airliner() -> trimesh.Trimesh:
    """An airliner in the canonical frame (nose +Y, fin +Z): fuselage, wing, tail, fin, two engines hung below."""
    fuselage = trimesh.creation.cylinder(radius=0.05, height=1.0, sections=24)
    fuselage.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    wing = trimesh.creation.box(extents=[1.0, 0.16, 0.02])
    wing.apply_translation([0, 0.05, 0])
    tail = trimesh.creation.box(extents=[0.3, 0.08, 0.015])
    tail.apply_translation([0, -0.42, 0])
    fin = trimesh.creation.box(extents=[0.015, 0.12, 0.3])
    fin.apply_translation([0, -0.41, 0.15])
    parts = [fuselage, wing, tail, fin]
    for x in (-0.28, 0.28):
        engine = trimesh.creation.cylinder(radius=0.035, height=0.16, sections=16)
        engine.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
        engine.apply_translation([x, 0.14, -0.09])
        pylon = trimesh.creation.box(extents=[0.01, 0.06, 0.09])
        pylon.apply_translation([x, 0.1, -0.045])
        parts += [engine, pylon]
    return trimesh.util.concatenate(parts)


def strip_beside(mask: np.ndarray, width: int = 5) -> np.ndarray:
    """A ``width``-column strip just right of ``mask``: where a person beside the object may stand
    (the pixels a gate test that judges whole outlines only must then leave alone)."""
    beside = np.zeros_like(mask)
    columns = np.flatnonzero(mask.any(axis=0))
    beside[:, columns[-1] + 1 : columns[-1] + 1 + width] = True
    return beside


def shipped_guitar_render(subtype: str) -> tuple[np.ndarray, np.ndarray]:
    """The shipped guitar template of ``subtype`` rendered from the front (RGBA, 384 px) and its mask."""
    from frontal3d.photo_render import frontal_camera, render_frontal
    from frontal3d.plugins import Plugins

    plugins = Plugins()
    mesh = plugins.hook.frontal3d_template(family=plugins.family("guitar"), subtype=subtype, settings=plugins.settings("guitar")).mesh
    rgba = render_frontal(mesh, frontal_camera(mesh, 384, 0.8))
    return rgba, rgba[..., 3] > 127

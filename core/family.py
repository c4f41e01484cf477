"""The data a family plugin hands to the core: families, templates and rules.

A family plugin is mostly data (this module's dataclasses) plus a few small rules;
everything two families would both need lives in the core.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import trimesh
import yaml

#: Where the camera looks from, in the family's canonical frame. The camera always
#: looks along -Z, image right = +X, image up = +Y; this names what that view shows.
CANONICAL_VIEWS = ("front", "side", "top")


@dataclass(frozen=True)
class Family:
    """A family of rigid objects the pipeline can reconstruct.

    ``regions`` maps each subtype to its ordered region names; label ``i`` in every
    region map of that subtype means ``regions[subtype][i]``.
    ``real_size`` maps each subtype to its typical longest bounding-box edge in
    metres, which gives outputs a metric scale when the user gives none.
    ``view_hint`` completes "this family needs ..." in error messages.
    ``settings`` holds the family's defaults; plugins.toml may override any key.
    """

    name: str
    subtypes: tuple[str, ...]
    canonical_view: str
    regions: dict[str, tuple[str, ...]]
    real_size: dict[str, float]
    description: str = ""
    settings: dict[str, Any] = field(default_factory=dict)
    view_hint: str = ""

    def __post_init__(self) -> None:
        if self.canonical_view not in CANONICAL_VIEWS:
            raise ValueError(f"family {self.name!r}: canonical_view must be one of {CANONICAL_VIEWS}")
        for what, table in (("region list", self.regions), ("real size", self.real_size)):
            missing = [s for s in self.subtypes if s not in table]
            if missing:
                raise ValueError(f"family {self.name!r}: no {what} for subtypes {missing}")

    def to_dict(self) -> dict[str, Any]:
        """The JSON shape ``frontal3d families --json`` prints."""
        return {
            "name": self.name,
            "description": self.description,
            "canonical_view": self.canonical_view,
            "subtypes": list(self.subtypes),
            "regions": {s: list(r) for s, r in self.regions.items()},
            "real_size_m": dict(self.real_size),
        }


@dataclass
class Template:
    """A family's 3D template for one subtype, in the canonical frame, in metres.

    ``face_regions[f]`` is the index into ``region_names`` of face ``f``;
    ``landmarks`` are named points (strap pins, wheel centres, wing tips) that follow
    the warp into the output so a scene can attach things to them.
    """

    family: str
    subtype: str
    mesh: trimesh.Trimesh
    face_regions: np.ndarray
    region_names: tuple[str, ...]
    landmarks: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.face_regions = np.asarray(self.face_regions, dtype=np.int32)
        self.landmarks = {k: np.asarray(v, dtype=np.float64).reshape(3) for k, v in self.landmarks.items()}


def load_family_yaml(path: Path, regions: dict[str, tuple[str, ...]]) -> Family:
    """Build a :class:`Family` from a plugin's family.yaml and its template regions.

    The yaml holds the family's data (name, view, sizes, settings); the region lists
    come from the template builders so the two can never disagree. Checkpoints its
    ``weights`` setting names are shipped with the plugin: relative to the yaml's folder
    (plugins.toml's, a user's own, stay relative to the working directory).
    """
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    settings = dict(data.get("settings", {}))
    if "weights" in settings:
        settings["weights"] = {task: str(path.parent / checkpoint) for task, checkpoint in settings["weights"].items()}
    return Family(
        name=data["name"],
        subtypes=tuple(regions),
        canonical_view=data["canonical_view"],
        regions={k: tuple(v) for k, v in regions.items()},
        real_size={k: float(v) for k, v in data["real_size"].items()},
        description=data.get("description", ""),
        settings=settings,
        view_hint=data.get("view_hint", ""),
    )


_BUILT: dict[tuple[str, str], Template] = {}


def template_for(family: Family, builders: dict[str, Callable[[], Template]], subtype: str, settings: dict[str, Any]) -> Template:
    """The template a family plugin returns: the user's mesh if configured, else the built-in.

    Built-in templates are built once per process: their builders are deterministic.
    """
    if settings.get("template_path"):
        from frontal3d.template_tools import template_from_mesh

        template, warnings = template_from_mesh(Path(settings["template_path"]), family, subtype)
        for warning in warnings:
            logging.getLogger("frontal3d.template").warning(warning)
        return template
    if subtype not in builders:
        from frontal3d.errors import UnknownFamilyError

        raise UnknownFamilyError(f"family {family.name!r} has no subtype {subtype!r} (subtypes: {', '.join(builders)})")
    key = (family.name, subtype)
    if key not in _BUILT:
        _BUILT[key] = builders[subtype]()
    return _BUILT[key]

"""Every hook a frontal3d plugin can implement, in one place.

A plugin is a module with functions decorated by :data:`frontal3d.hookimpl` whose
names match the specs below (pluggy checks the names and arguments: a misspelled
hook fails at start-up through ``check_pending()``). Plugins are found through the
``frontal3d`` entry-point group and through ``[plugins] modules`` in plugins.toml.

Hooks marked *first result wins* stop at the first implementation that returns
something other than ``None``; implementations run in reverse registration order,
and ``@hookimpl(tryfirst=True)`` / ``trylast=True`` move one to the front or back.
All other hooks collect every plugin's result in a list.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

import numpy as np
import pluggy

if TYPE_CHECKING:
    from frontal3d.family import Family, Template
    from frontal3d.stages.classify import Classifier

hookspec = pluggy.HookspecMarker("frontal3d")


@hookspec
def frontal3d_register_families() -> list[Family]:
    """Declare the families this plugin provides.

    Called once when the plugin manager starts. Return a list of
    :class:`frontal3d.family.Family`: name, subtypes, canonical view (``front``,
    ``side`` or ``top``), the ordered region names of each subtype, the real size
    in metres and default settings. Every plugin's families are collected; two
    plugins declaring the same family name is an error.
    """


@hookspec(firstresult=True)
def frontal3d_template(family: Family, subtype: str, settings: dict[str, Any]) -> Template | None:
    """Return the 3D template of ``family``/``subtype``. First result wins.

    Called once per reconstruction, after the classifier chain chose the subtype.
    Return ``None`` when this plugin does not provide that family, so the next
    plugin is asked. ``settings`` is the family's merged settings (defaults plus
    plugins.toml), e.g. a ``template_path`` a user points at their own mesh.
    """


@hookspec(firstresult=True)
def frontal3d_segment(image: np.ndarray, family: Family, settings: dict[str, Any], hints: dict[str, Any]) -> np.ndarray | None:
    """Return the object's mask (bool, same height and width as ``image``). First result wins.

    ``image`` is H x W x 3 (RGB) or H x W x 4 (RGBA) uint8 at full resolution.
    ``hints`` carries what the user gave: ``mask`` (the ``--mask`` array, or
    None). The core's chain is,
    in order: the user's mask, the alpha channel, a learned segmenter when weights
    are configured, the classical segmenter. Return ``None`` to pass.
    """


@hookspec
def frontal3d_classifiers(family: Family) -> list[Classifier]:
    """Return weak classifiers for ``family`` (every plugin's are collected).

    The chain runs them sorted by their ``order`` attribute (frontal gate first,
    then subtype). Each returns a :class:`frontal3d.stages.classify.Decision`; a
    decision with ``accepted=False`` stops the reconstruction with its ``reason``.
    The decision named ``subtype`` chooses the template.
    """


@hookspec(firstresult=True)
def frontal3d_segment_regions(image: np.ndarray, object_mask: np.ndarray, transferred_regions: np.ndarray, family: Family, subtype: str, settings: dict[str, Any]) -> np.ndarray | None:
    """Return the object's inner-region map (int, -1 outside). First result wins.

    ``transferred_regions`` is the aligned template's region map on the image grid,
    a strong prior. Labels index ``family.regions[subtype]``. The core's default
    refines the transferred map with per-region colour models and a graph cut.
    """


@hookspec
def frontal3d_back_texture_rules() -> dict[str, Callable[..., np.ndarray]]:
    """Return named back-texture rules this plugin adds (all plugins' are merged).

    A rule is ``rule(front_texture, mask, region_map, region_names, params) ->
    back_texture``. A family chooses its rule by name in its settings
    (``back_texture``), e.g. the guitar's ``synthesize_from_region`` (the back
    takes the body's wood) or the car's ``mirror_front``.
    """


@hookspec
def frontal3d_symmetry_rules() -> dict[str, Callable[..., tuple[np.ndarray, np.ndarray]]]:
    """Return named symmetry rules this plugin adds (all plugins' are merged).

    A rule is ``rule(front_z, back_z, mask, region_map, params) -> (front_z,
    back_z)`` and constrains the hidden depth, e.g. ``mirror_z`` for a car seen
    from the side. A family chooses its rule by name in its settings (``symmetry``).
    """


@hookspec
def frontal3d_occluders(image: np.ndarray, object_mask: np.ndarray, settings: dict[str, Any]) -> np.ndarray | None:
    """Return a mask of things in front of the object (bool, image-sized), or None.

    Every plugin's masks are OR-ed together: the core's default finds people's
    arms and hands; a plugin may add e.g. microphone stands.
    """

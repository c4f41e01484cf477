"""frontal3d: one frontal photo in, a textured watertight 3D mesh out.

Public API: :func:`reconstruct`, :func:`reconstruct_all`, :class:`Reconstruction`, :data:`hookimpl`.
"""

from typing import Any

import pluggy

__version__ = "0.1.0"

#: Mark a function in a plugin module as an implementation of a frontal3d hook.
hookimpl = pluggy.HookimplMarker("frontal3d")

__all__ = ["__version__", "hookimpl", "reconstruct", "reconstruct_all", "Reconstruction"]


def __getattr__(name: str) -> Any:
    # The pipeline imports every stage; load it only when asked, so a plugin that
    # imports ``frontal3d.hookimpl`` stays cheap and free of import cycles.
    if name in ("reconstruct", "reconstruct_all", "Reconstruction"):
        from frontal3d import pipeline

        return getattr(pipeline, name)
    raise AttributeError(f"module 'frontal3d' has no attribute {name!r}")

"""Errors a user can act on.

Every failure the pipeline can foresee is a :class:`Frontal3DError`; the CLI prints
its message on one line and exits non-zero, so the message must name the cause.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np


class Frontal3DError(Exception):
    """Base class: a foreseen failure with a one-line, user-facing message."""

    exit_code = 2


class InputError(Frontal3DError):
    """The input image or mask is unreadable, empty or unusable."""


class NoObjectError(Frontal3DError):
    """No object of the family was found in the image."""


class NotFrontalError(Frontal3DError):
    """The classifier chain rejected the view (not the family's canonical view).

    ``outlines`` maps each family that turned the image down to the object mask it judged,
    so the CLI can picture the verdict (``reconstruct -v``): a wrong outline explains most
    wrong verdicts, and it is easier to see than to describe.
    """

    def __init__(self, message: str, outlines: dict[str, np.ndarray] | None = None):
        super().__init__(message)
        self.outlines = dict(outlines or {})


class ConfigError(Frontal3DError):
    """plugins.toml or a setting is wrong; the message names the file and key."""


class PluginError(Frontal3DError):
    """A plugin failed to load or implements a hook wrongly."""


class UnknownFamilyError(Frontal3DError):
    """The asked-for family or subtype is not provided by any installed plugin."""


class TemplateError(Frontal3DError):
    """A template mesh or its cached renders are unusable."""


class NotImplementedStageError(Frontal3DError):
    """A pipeline stage has no implementation yet; never fake its output."""

    def __init__(self, stage: str):
        super().__init__(f"not implemented yet: {stage}")
        self.stage = stage

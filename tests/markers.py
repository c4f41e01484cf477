"""Markers shared by the test modules."""

from __future__ import annotations

import importlib.util

import pytest

#: People detection needs mediapipe, which scripts/setup.sh installs without its GUI OpenCV.
needs_mediapipe = pytest.mark.skipif(importlib.util.find_spec("mediapipe") is None, reason="mediapipe is not installed (scripts/setup.sh installs it)")

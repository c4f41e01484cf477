"""The bundled example inputs (CC0; see examples/SOURCES.md)."""

from pathlib import Path

from frontal3d.errors import InputError

EXAMPLES_DIR = Path(__file__).resolve().parents[1] / "examples"


def example_image(name: str = "sportscar.png") -> Path:
    """Path of a bundled example image (only in a source checkout, not in a wheel)."""
    path = EXAMPLES_DIR / name
    if not path.is_file():
        raise InputError(f"bundled example {name} not found in {EXAMPLES_DIR}: pass an IMAGE")
    return path

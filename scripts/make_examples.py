"""Re-create the bundled example inputs in examples/ from the CC0 meshes there.

    python3 scripts/make_examples.py

Each mesh is rendered along -Z (its family's canonical view) at 640x480 over a soft
studio gradient and saved as RGBA PNG (alpha = the exact silhouette, so the example
needs no segmenter) and as a plain RGB JPEG (for trying the segmenters).
"""

from pathlib import Path

import cv2
import numpy as np

from frontal3d.photo_render import composite, frontal_camera, load_coloured_mesh, render_frontal

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def studio_background(height: int, width: int) -> np.ndarray:
    """A light grey vertical gradient, like a photo studio's sweep."""
    ramp = np.linspace(235, 180, height)[:, None, None]
    return np.broadcast_to(ramp, (height, width, 3)).astype(np.uint8)


def make(name: str) -> None:
    mesh = load_coloured_mesh(EXAMPLES / f"{name}.glb")
    camera = frontal_camera(mesh, resolution=640, fill=0.8)
    rgba = render_frontal(mesh, camera)[80:560]  # 640x480: crop the empty top and bottom
    cv2.imwrite(str(EXAMPLES / f"{name}.png"), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
    photo = composite(rgba, studio_background(*rgba.shape[:2]))
    cv2.imwrite(str(EXAMPLES / f"{name}.jpg"), cv2.cvtColor(photo, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 92])


if __name__ == "__main__":
    for example in ("sportscar", "private_plane"):
        make(example)
        print(f"wrote examples/{example}.png and .jpg")

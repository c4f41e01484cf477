"""Progress on long work: one bar over the images, the running stage as its label."""

from __future__ import annotations

import sys
from types import TracebackType

from tqdm import tqdm


class StageProgress:
    """A progress bar over images whose label names the image and the running stage.

    Shown only when stderr is a terminal, so logs and CI output stay clean.
    """

    def __init__(self, total: int):
        self._bar = tqdm(total=total, unit="image", file=sys.stderr, disable=not sys.stderr.isatty(), leave=False)
        self._image = ""
        self._started = False

    def __enter__(self) -> "StageProgress":
        return self

    def __exit__(self, exc_type: type | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self._bar.close()

    def start(self, image: str) -> None:
        """A new image begins: count the previous one as done."""
        if self._started:
            self._bar.update(1)
        self._started = True
        self._image = image
        self._bar.set_description(image)

    def stage(self, name: str) -> None:
        self._bar.set_description(f"{self._image}: {name}")

    def write(self, line: str) -> None:
        """Print a line above the bar (or plainly when there is no bar)."""
        tqdm.write(line, file=sys.stdout)

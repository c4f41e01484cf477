"""Progress on long work: bars on stderr, shown only when stderr is a terminal (logs and CI stay clean)."""

from __future__ import annotations

import sys
from types import TracebackType

from tqdm import tqdm


def counter(total: int | None, unit: str, desc: str | None = None, enabled: bool | None = None) -> tqdm:
    """A counting bar for batch commands (evaluate, synth, training epochs); `enabled` None means "stderr is a terminal"."""
    show = sys.stderr.isatty() if enabled is None else enabled
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, disable=not show, leave=False)


class StageProgress:
    """A progress bar over images whose label names the image and the running stage.

    Shown only when stderr is a terminal, so logs and CI output stay clean.
    """

    def __init__(self, total: int):
        self._bar = counter(total, "image")
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

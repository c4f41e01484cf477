"""``python -m frontal3d``: the same as the ``frontal3d`` command."""

import sys

from frontal3d.cli import main

sys.exit(main())

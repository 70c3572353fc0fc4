"""``python -m twin.sweep SPEC.toml ...``: the ``twin sweep`` command on its own."""

from __future__ import annotations

import sys

from twin.sweep.cli import main

if __name__ == "__main__":  # worker processes spawned by Dask import this module again
    sys.exit(main())

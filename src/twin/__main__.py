"""``python -m twin``: the ``twin`` command (through :mod:`twin.entry`, so a Ctrl-C while it
imports is one line and exit code 130, as for the console script)."""

import sys

from twin.entry import main

sys.exit(main())

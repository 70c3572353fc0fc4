"""``python -m twin``: the ``twin`` command (:func:`twin.cli.console`)."""

import sys

from twin.cli import console

sys.exit(console())

"""``python -m chiptwin`` is the ``chiptwin`` command."""

from chiptwin.cli import entry

entry()

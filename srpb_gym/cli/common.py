"""What every subcommand of the ``srpb-gym`` command line shares: its name, and how it
says one line on stderr."""

from __future__ import annotations

import sys

PROG = "srpb-gym"


def stderr(line: str) -> None:
    """Print one ``srpb-gym: <line>`` to stderr."""
    print(f"{PROG}: {line}", file=sys.stderr)

"""How every command ends: one JSON line for machines, one line for people."""

from __future__ import annotations

import json
import sys


def report(summary: dict, human: str, quiet: bool) -> None:
    """Print `summary` as one JSON line on stdout and `human` on stderr (not when `quiet`)."""
    print(json.dumps(summary, default=str))
    if not quiet:
        print(human, file=sys.stderr)

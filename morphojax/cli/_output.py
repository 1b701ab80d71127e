"""How every command ends: one JSON line for machines, one line for people."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from morphojax._render import png_path  # the one place a picture's path gets its .png


def report(summary: dict, human: str, quiet: bool) -> None:
    """Print `summary` as one JSON line on stdout and `human` on stderr (not when `quiet`)."""
    print(json.dumps(summary, default=str))
    if not quiet:
        print(human, file=sys.stderr)


def picture_path(path) -> Path:
    """`path` ending in .png, its folder created."""
    out = png_path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    return out

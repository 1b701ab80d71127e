"""How every command ends: one JSON line for machines, one line for people."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from morphojax._render import png_path  # the one place a picture's path gets its .png
from morphojax._files import check_output_path, make_folder_of  # refused before the work, not after it


def report(summary: dict, human: str, quiet: bool) -> None:
    """Print `summary` as one JSON line on stdout and `human` on stderr (not when `quiet`)."""
    print(json.dumps(summary, default=str))
    if not quiet:
        print(human, file=sys.stderr)


class FolderPath(type(Path())):
    """An `--out` that names a folder: it ends in `/` (or is a folder already)."""


def out_arg(text: str) -> Path:
    """The argparse type of `--out`: a Path, or a FolderPath when `text` names a folder (a
    trailing `/`, which `Path` itself would drop)."""
    if not text:
        raise argparse.ArgumentTypeError("--out needs a path")
    folder = text.endswith(("/", os.sep)) or Path(text).is_dir()
    return FolderPath(text) if folder else Path(text)


def picture_path(path, name: str = "out") -> Path:
    """`path` ending in .png (inside it, as NAME.png, when it names a folder), its folder
    created; a path that cannot be written (a parent that is a file, a folder without write
    permission) is refused before any work."""
    if isinstance(path, FolderPath) or Path(path).is_dir():
        path = Path(path) / f"{name}.png"
    out = png_path(path)
    check_output_path(out)
    make_folder_of(out)
    return out

"""`morphojax listing FILE`: run one of the thesis's experiment files (its own language,
thesis 4.8) on the cell simulator; write a picture, the cells as .npz and an SVG.

    morphojax listing A.18 --out leopard.png --seed 0
    morphojax listing my_experiment.txt --steps 2000 --texture --out pattern.png

FILE is a listing file or the name of a shipped one (A.1 ... A.18, fig5.1, fig5.2,
listing4.1, listing5.1; `--list` shows them). The picture shows the first chemical (or
`--chemical`) through the listing's colour map: the cells as discs, or with `--texture`
the interpolated texture of `texture size` (thesis 4.6). The .npz beside it holds the
final cells, the listing's text, the seed and the iterations (`mj.load_cells`). The same
seed gives the same cells.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from morphojax.cells import LISTINGS, load_listing
from morphojax.presets._cells import write_outputs

from ._output import out_arg, picture_path, report

QUICK_STEPS = 100  # --quick: at most this many iterations


def register(subparsers) -> None:
    """Add the `listing` subcommand."""
    p = subparsers.add_parser("listing", help="run a thesis experiment file on the cell simulator",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", nargs="?", help="a listing file, or a shipped listing's name (A.1 ... A.18)")
    p.add_argument("--out", type=out_arg, default=None, help="picture (default out/NAME.png); .npz and .svg beside it")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: the listing's `use seed`, else 0)")
    p.add_argument("--steps", type=int, default=None, help="iterations (default: the listing's `stop at`)")
    p.add_argument("--quick", action="store_true", help=f"at most {QUICK_STEPS} iterations (a check, in seconds)")
    p.add_argument("--chemical", default=None, help="the chemical shown (default: the first declared)")
    p.add_argument("--texture", action="store_true", help="draw the interpolated texture instead of discs")
    p.add_argument("--list", action="store_true", help="list the shipped listings and exit")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--quiet", action="store_true", help="print only the JSON line")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.list:
        for name, path in LISTINGS.items():
            print(f"{name:<12} {path.name}")
        return 0
    if args.file is None:
        raise ValueError("give a listing file or name (or --list)")
    listing = load_listing(args.file)
    steps = args.steps if args.steps is not None else listing.steps
    if steps is None:
        raise ValueError(f"{listing.name} has no 'stop at' line: pass --steps")
    if args.quick:
        steps = min(steps, QUICK_STEPS)
    seed = args.seed if args.seed is not None else (listing.seed or 0)
    out = picture_path(args.out if args.out is not None else Path("out") / f"{listing.name}.png", listing.name)
    t0 = time.perf_counter()
    cells = listing.run(seed=seed, steps=steps, progress=not args.no_progress)
    seconds = time.perf_counter() - t0
    _, npz, svg = write_outputs(listing, [cells], [steps], out, texture=args.texture, reagent=args.chemical,
                                metadata={"seed": seed, "steps": steps})
    for warning in listing.warnings:
        print(f"{listing.name}: warning: {warning}", file=sys.stderr)
    report({"listing": listing.name, "seed": seed, "steps": steps, "cells": int(cells.count),
            "seconds_run": round(seconds, 3), "image": str(out), "npz": str(npz), "svg": str(svg)},
           f"{listing.name}: {int(cells.count)} cells after {steps} iterations; wrote {out} ({seconds:.1f} s)",
           args.quiet)
    return 0

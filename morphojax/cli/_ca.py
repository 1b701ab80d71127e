"""`morphojax ca`: a custom cellular automaton (Young activator-inhibitor or life-like) run
from the command line; the automaton presets run through `morphojax run NAME`."""

from __future__ import annotations

import argparse
from pathlib import Path

import morphojax as mj
from morphojax._checks import STEP_COUNTER_MAX, check_range, check_run_size  # the library's checks, for the flags
from morphojax.presets import run_automaton, run_life_like

from ._output import out_arg, picture_path, report

DEFAULT_SPECIES = (3.2, 6.0, 1.0, -0.2)  # Dur's (2023) two-species example (section 4.2)


def _species(text: str):
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 4:
        raise argparse.ArgumentTypeError(f"a species is r_act,r_inh,w_act,w_inh (got {text!r})")
    return values


def register(subparsers) -> argparse.ArgumentParser:
    """Add the `ca` subcommand (a custom Young automaton or life-like run)."""
    p = subparsers.add_parser(
        "ca", help="run a custom cellular automaton (Young activator-inhibitor or life-like)",
        description="Young's activator-inhibitor automaton with K species (radii in lattice cells), or a "
                    "life-like B/S rule. Writes OUT.png, OUT.npz (cells + JSON metadata) and, in 3D, a mesh per species.",
    )
    p.add_argument("--species", type=_species, action="append", metavar="R_ACT,R_INH,W_ACT,W_INH",
                   help="one species (repeat for K species); default 3.2,6,1,-0.2")
    p.add_argument("--rule", default=None, help="a life-like rule instead, e.g. B3/S23 (0/1 cells, p = alive fraction)")
    p.add_argument("--neighbourhood", choices=["disc", "box"], default="disc",
                   help="disc: the radii as Euclidean distances (default); box: as Chebyshev distances, Young's "
                        "square boxes")
    p.add_argument("--include-self", action="store_true", help="count the cell itself in its activator disc")
    p.add_argument("--dim", type=int, default=2, help="lattice dimension (default 2)")
    p.add_argument("--size", type=int, default=128, help="cells per side (default 128)")
    p.add_argument("--p", type=float, default=None,
                   help="probability a cell starts differentiated (Young: 0.015); default uniform over the K+1 states")
    p.add_argument("--steps", type=int, default=50, help="synchronous updates to run (default 50)")
    p.add_argument("--stop-at-convergence", action="store_true", help="stop once < --threshold of the cells change")
    p.add_argument("--threshold", type=float, default=0.01, help="convergence threshold (fraction, default 0.01)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the starting cells (default 0)")
    p.add_argument("--frames", action="store_true", help="also write intermediate snapshots (Young automata)")
    p.add_argument("--out", type=out_arg, default=Path("out") / "ca.png", help="output PNG (default out/ca.png)")
    p.add_argument("--quiet", action="store_true", help="print only the JSON line")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (--quiet has none either)")
    p.set_defaults(func=run_ca_command)
    return p


def run_ca_command(args) -> int:
    if args.dim not in (2, 3):  # the library takes any dimension; pictures and meshes need 2 or 3
        raise ValueError(f"--dim must be 2 or 3 (got {args.dim})")
    check_range(args.size, "--size (cells per side)", low=1)
    check_range(args.steps, "--steps", low=0, high=STEP_COUNTER_MAX)
    species = 2 if args.rule else len(args.species or [DEFAULT_SPECIES]) + 1
    check_run_size((int(args.size),) * int(args.dim), species,
                   what=f"this automaton ({args.size}^{args.dim} cells, {species} states)")
    if args.p is not None:
        check_range(args.p, "--p (probability)", low=0.0, high=1.0)
    out = picture_path(args.out, "ca")
    shape = (int(args.size),) * int(args.dim)
    run = dict(p=args.p, steps=args.steps, stop=args.stop_at_convergence, seed=args.seed, out=out,
               threshold=args.threshold, progress=False if args.no_progress or args.quiet else "ca")
    if args.rule:
        summary = run_life_like(mj.LifeLike(args.rule), shape, **run)
    else:
        ca = mj.YoungCA(args.species or [DEFAULT_SPECIES], args.neighbourhood, args.include_self)
        summary = run_automaton(ca, shape, frames=args.frames, **run)
    t = summary.get("seconds_run", 0.0)
    report(summary, f"ca: {summary['steps']} steps on {'x'.join(map(str, shape))}, {t:.2f} s; "
                    f"wrote {', '.join(summary.get('files', [str(out)]))}", args.quiet)
    return 0

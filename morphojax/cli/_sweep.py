"""`morphojax sweep`: a parameter map from the command line.

    morphojax sweep --model turing --vary ratio=4:40:9 --vary upper_a=4:6.5:6 --fixed scale=3 --out map.png

writes map.png (the labelled montage), map.csv and map.json (the descriptor table, one row
per member) and map.npz (final states and every parameter as JSON metadata). `A:B:N` is N
values from A to B inclusive; `A,B,C` is a list. Without --dt, 0.8 x the smallest
explicit-Euler limit of the diffusion over the swept values is used (a margin for the
reaction, which the limit ignores: Gray-Scott blows up at 0.9 x); without --steps the run
lasts --time (default 100, the paper's Fig. 4). Members that blow up anyway are recorded in
the table (pattern "unstable", with the step), not raised.
"""

from __future__ import annotations

import argparse
import math
import re
from collections import Counter

import numpy as np

import morphojax as mj
from morphojax._checks import STEP_COUNTER_MAX, check_run_size, check_scale, check_shape  # sizes before a run

from ._output import out_arg, picture_path, report

_RANGE = re.compile(r"^\s*([^:]+):([^:]+):([^:]+)\s*$")
DEFAULT_TIME = 100.0  # the leopard paper's Fig. 4 runs to t = 100
MAX_MEMBERS = 10**6  # members of one sweep: its table, montage and files stay readable
DT_SAFETY = 0.8  # default dt = DT_SAFETY x the explicit-Euler limit of the diffusion


def register(subparsers) -> None:
    """Add the `sweep` subcommand to an argparse subparsers object."""
    p = subparsers.add_parser(
        "sweep", help="run a model over a grid of parameter values; write a montage, a table and an .npz",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", required=True, help="turing, bard, gray-scott or reinforcement")
    p.add_argument("--vary", action="append", required=True, metavar="NAME=A:B:N|V1,V2,...",
                   help="a swept parameter (repeat for a 2D or larger grid, in row-major order)")
    p.add_argument("--fixed", action="append", default=[], metavar="NAME=VALUE",
                   help="a fixed parameter of the base model (repeatable), e.g. scale=3 or upper_b=inf")
    p.add_argument("--steps", type=int, default=None, help="steps per member (default: --time / dt)")
    p.add_argument("--time", type=float, default=None, help=f"simulated time when --steps is not given "
                   f"(default {DEFAULT_TIME:g})")
    p.add_argument("--dt", type=float, default=None,
                   help="time step (default: 0.8 x the diffusion's stable limit over the sweep)")
    p.add_argument("--shape", type=int, nargs=2, default=(50, 50), metavar=("ROWS", "COLS"),
                   help="lattice size (default 50 50, as the paper's Fig. 4)")
    p.add_argument("--boundary", default="wrap", help="wrap (toroidal) or no-flux")
    p.add_argument("--stencil", default="nine-point", help="nine-point or five-point")
    p.add_argument("--growth", type=float, default=None, metavar="RATE",
                   help="grow the lattice at RATE expansions per unit time (then growth_rate can vary)")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same result)")
    p.add_argument("--own-starts", action="store_true",
                   help="a different random start per member (default: one shared start, as in the paper)")
    p.add_argument("--batch-size", type=int, default=None, help="members per compiled chunk (default: automatic)")
    p.add_argument("--devices", type=int, default=None, help="number of local devices to use (default: all)")
    p.add_argument("--species", default=None, help="species shown and described (default: the last)")
    p.add_argument("--cmap", default="inferno", help="colour map of the montage")
    p.add_argument("--scale", type=int, default=None, help="pixels per cell in the montage (default: automatic)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--quiet", action="store_true", help="print only the JSON line")
    p.add_argument("--out", type=out_arg, required=True, help="the montage PNG; .csv, .json and .npz go next to it")
    p.set_defaults(func=run_sweep_command)


def parse_values(name: str, text: str) -> list[float]:
    """`A:B:N` (N values from A to B inclusive), `A,B,...` or one number."""
    hint = "use START:STOP:COUNT (COUNT values from START to STOP inclusive) or a comma list V1,V2,..."
    text = text.strip()
    if not text:
        raise ValueError(f"--vary {name}: no values given; {hint}")
    m = _RANGE.match(text)
    try:
        if m:
            a, b = float(m.group(1)), float(m.group(2))
            count = float(m.group(3))
            if count != int(count) or count < 1:
                raise ValueError
            if count > MAX_MEMBERS:  # refused before the values are made
                raise ValueError(f"--vary {name}: {int(count)} values; a sweep has at most {MAX_MEMBERS} members")
            values = np.linspace(a, b, int(count)).tolist()
        elif ":" in text:
            raise ValueError
        else:
            parts = [t for t in (s.strip() for s in text.split(",")) if t]
            if not parts:
                raise ValueError
            values = [float(t) for t in parts]
    except ValueError as err:
        if str(err).startswith("--vary"):  # the count check's own message
            raise
        raise ValueError(f"--vary {name}: bad values {text!r}; {hint}") from None
    if len(values) > MAX_MEMBERS:
        raise ValueError(f"--vary {name}: {len(values)} values; a sweep has at most {MAX_MEMBERS} members")
    return values


def _split(option: str, item: str):
    name, sep, text = item.partition("=")
    if not sep or not name.strip():
        raise ValueError(f"{option} {item!r}: expected NAME=VALUES, e.g. {option} ratio=4:40:9")
    return name.strip(), text


def build_sweep(args):
    """(model, vary, kwargs for `sweep`) from parsed arguments; bad input raises ValueError."""
    # the sweep's own name and value checks, so bad input is reported before any run
    from morphojax._sweep_members import DT, GROWTH_RATE, _check_name, _check_values

    fixed = {}
    for item in args.fixed:
        name, text = _split("--fixed", item)
        try:
            fixed[name] = float(text)
        except ValueError:
            raise ValueError(f"--fixed {name}: {text!r} is not a number") from None
        if math.isnan(fixed[name]):
            raise ValueError(f"--fixed {name}: NaN is not a parameter value")
    model = mj.model_from_name(args.model, **fixed)
    growth = None if args.growth is None else mj.Growth(rate=args.growth)
    vary = {}
    for item in args.vary:
        name, text = _split("--vary", item)
        if name in vary:
            raise ValueError(f"--vary {name} is given twice")
        if name in fixed:
            raise ValueError(f"{name} is both --fixed and --vary")
        if name == GROWTH_RATE and growth is None:
            growth = mj.Growth(rate=1.0)  # the rate is swept; the schedule needs a Growth
        _check_name(model, growth, name)
        vary[name] = _check_values(name, parse_values(name, text)).tolist()
    members = math.prod(len(v) for v in vary.values())
    if members > MAX_MEMBERS:
        raise ValueError(f"--vary: {' x '.join(str(len(v)) for v in vary.values())} = {members} members; a sweep "
                         f"has at most {MAX_MEMBERS}")
    check_shape(args.shape, "--shape", ndim=2)
    check_run_size(args.shape, model.n_species, members=members,
                   what=f"this sweep ({members} members of {args.shape[0]}x{args.shape[1]} cells)")
    if args.scale is not None:
        check_scale(args.scale, "--scale")
    lattice = mj.Lattice(stencil=args.stencil, boundary=args.boundary)
    stencil = lattice.stencil
    if args.dt is None:
        if DT in vary:
            dt = None
        else:
            limit = min(lattice.max_stable_dt(model.replace(**{k: v for k, v in c.items() if k != GROWTH_RATE})
                                              .max_diffusion()) for c in _combos(vary))
            if not math.isfinite(limit):
                raise ValueError("--dt is required: the model has no diffusion, so there is no stable limit "
                                 "to pick from")
            dt = float(f"{DT_SAFETY * limit:.3g}")
    else:
        dt = args.dt
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"--dt must be a finite number > 0 (got {dt})")
        if DT in vary:
            raise ValueError("give either --dt or --vary dt=..., not both")
    if args.steps is not None and args.time is not None:
        raise ValueError("give --steps or --time, not both")
    if args.steps is not None:
        steps = args.steps
    else:
        time = DEFAULT_TIME if args.time is None else args.time
        if not (math.isfinite(time) and time >= 0):
            raise ValueError(f"--time must be a finite non-negative number (got {time!r})")
        largest_dt = max(vary[DT]) if DT in vary else dt
        steps = int(math.ceil(time / largest_dt - 1e-9))
    if not 0 <= steps <= STEP_COUNTER_MAX:
        raise ValueError(f"--steps must lie in [0, {STEP_COUNTER_MAX}], what the step counter holds (got {steps}"
                         f"{'' if args.steps is not None else ' from --time / dt'})")
    rows, cols = args.shape
    capacity = None
    if growth is not None:
        rates = vary.get(GROWTH_RATE, [float(np.asarray(growth.rate))])
        dts = vary.get(DT, [dt])
        n_exp = max(mj.Growth(rate=r).expansions(steps, d) for r in rates for d in dts)
        capacity = (rows + n_exp, cols + n_exp)
        check_run_size(capacity, model.n_species, members=members,
                       what=f"this sweep ({members} members growing to {capacity[0]}x{capacity[1]} cells)")
    kwargs = dict(steps=steps, dt=dt if dt is not None else min(vary[DT]), boundary=args.boundary, stencil=stencil,
                  growth=growth, batch_size=args.batch_size, devices=args.devices, key=args.seed,
                  species=args.species if args.species is not None else -1, progress=not args.no_progress)
    # one shared start (and growth noise) for every member, as the paper compares parameters,
    # or each member its own (--own-starts); see `sweep` for how the keys are derived
    kwargs |= dict(state=None, shape=(rows, cols), capacity=capacity,
                   keys="per-member" if args.own_starts else "shared")
    return model, vary, kwargs


def _combos(vary):
    names = list(vary)
    for values in np.array(np.meshgrid(*vary.values(), indexing="ij")).reshape(len(names), -1).T:
        yield dict(zip(names, values.tolist()))


def run_sweep_command(args) -> int:
    model, vary, kwargs = build_sweep(args)
    args.out = picture_path(args.out, "sweep")  # a path that cannot be written is refused before the run
    result = mj.sweep(model, vary, **kwargs)
    written = result.save(args.out, species=kwargs["species"], cmap=args.cmap, scale=args.scale)
    patterns = Counter(row.get("pattern", "") for row in result.table)
    unstable = int((result.blowup_step >= 0).sum())
    report({"written": [str(p) for p in written.values()], "members": len(result), "shape": list(result.shape),
            "steps": kwargs["steps"], "dt": kwargs["dt"], "patterns": dict(patterns), "unstable": unstable,
            "seconds": round(result.seconds, 2)},
           f"sweep: {len(result)} members ({unstable} unstable) in {result.seconds:.1f} s; "
           f"wrote {', '.join(str(p) for p in written.values())}", args.quiet)
    return 0

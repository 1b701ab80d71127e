"""`morphojax fit PHOTO ...`: fit a model to a photo from the command line.

`register` is the entry point `fit` of the group `morphojax.commands` (pyproject.toml):
`morphojax` finds it through the installed metadata, so the core never imports `fitting`."""

from __future__ import annotations

import json
from pathlib import Path


def _floats(text: str, n: int, what: str):
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(f"{what} must be {n} comma-separated numbers (got {text!r})") from None
    if len(vals) != n:
        raise ValueError(f"{what} must be {n} comma-separated numbers (got {text!r})")
    return vals


def _pairs(items, what: str) -> dict:
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise ValueError(f"{what} takes NAME=VALUE (got {item!r})")
        out[name.strip()] = value.strip()
    return out


def register(subparsers) -> None:
    """Add the `fit` subcommand to an argparse subparsers object (its defaults are `fitting.DEFAULTS`)."""
    from ._pipeline import DEFAULTS as D
    from ._families import FAMILIES

    p = subparsers.add_parser("fit", help="fit model parameters to a photo's texture statistics",
                              description="Fit parameters of a model so that its simulated texture matches a photo. "
                                          "Writes a JSON report (top-level 'params') and a preview picture.")
    p.add_argument("photo", type=Path, help="image file (any format pillow reads)")
    p.add_argument("--model", default=D["model"],
                   help=f"auto (screen every family, fit the best), {', '.join(FAMILIES)} or another model name "
                        f"(default {D['model']})")
    p.add_argument("--fit", default=D["fit"], help="comma-separated parameters to fit (default: the family's own)")
    p.add_argument("--fixed", action="append", metavar="NAME=VALUE", help="hold a parameter at a value")
    p.add_argument("--bounds", action="append", metavar="NAME=LOW:HIGH", help="bounds of a fitted parameter")
    p.add_argument("--crop", default=None, metavar="X0,Y0,X1,Y1", help="pixel box of the coat region")
    p.add_argument("--channel", default="luminance", help="luminance, red, green, blue, alpha, saturation, value")
    p.add_argument("--invert", action="store_true", help="dark pigment as high values (e.g. black spots = high B)")
    p.add_argument("--cell-pixels", type=float, default=None,
                   help="photo pixels per lattice cell (default: estimated, 10 cells per pattern wavelength)")
    p.add_argument("--no-binarise", dest="binarise", action="store_false", default=D["binarise"],
                   help="compare raw intensities instead of soft pigment maps (the default)")
    p.add_argument("--orientation", dest="orientation", action="store_true", default=D["orientation"],
                   help="compare the structure-tensor orientation of stripes (the default)")
    p.add_argument("--no-orientation", dest="orientation", action="store_false",
                   help="leave the orientation out of the statistics")
    p.add_argument("--shape", type=int, nargs=2, default=D["shape"], metavar=("ROWS", "COLS"),
                   help=f"the simulated lattice (default {' '.join(map(str, D['shape']))})")
    p.add_argument("--steps", type=int, default=D["steps"], help="steps per simulation (default: the family's)")
    p.add_argument("--window", type=int, default=D["window"],
                   help="steps differentiated at the end of each run (default: the family's)")
    p.add_argument("--seeds", type=int, default=D["seeds"], help="simulations averaged per evaluation")
    p.add_argument("--design-seeds", type=int, default=D["design_seeds"],
                   help="simulations averaged per point of the global design (at most --seeds)")
    p.add_argument("--design", type=int, default=D["n_design"], help="points per design round (default 12 per parameter)")
    p.add_argument("--rounds", type=int, default=D["rounds"], help="refinement rounds of the design")
    p.add_argument("--keep", type=int, default=D["keep"], help="local searches from the best design points")
    p.add_argument("--method", default=D["method"], help="bfgs, lm, nelder-mead or gd")
    p.add_argument("--max-steps", type=int, default=D["max_steps"],
                   help=f"iteration budget of each local search (default {D['max_steps']})")
    p.add_argument("--seed", type=int, default=D["seed"],
                   help=f"the fit's random seed: design, simulation noise (default {D['seed']})")
    p.add_argument("--screen", default=D["screen"], choices=("heldout", "loss"),
                   help="with --model auto, order the screened families by their samples' distance to the held-out "
                        "tile (heldout, the default) or by the penalised training loss (loss)")
    p.add_argument("--no-refine", dest="refine", action="store_false", default=D["refine"],
                   help="return the fit of the training half of a split photo as it was judged, without refining "
                        "it on the whole photo (faster; wider intervals)")
    p.add_argument("--json", type=Path, required=True, help="output JSON report")
    p.add_argument("--preview", type=Path, default=None,
                   help="output picture: target | fit | loss curve | fit in the photo's colours")
    p.add_argument("--sample", type=Path, default=None,
                   help="output grey PNG: one simulated field of the fit at lattice resolution, pigment bright")
    p.add_argument("--render", type=Path, default=None, help="output picture: the fitted coat at 1024 px, photo colours")
    p.add_argument("--progress", dest="progress", action="store_const", const=True, default=D["progress"],
                   help="show the progress bar (default: a bar in a terminal, one log line per stage on stderr "
                        "otherwise)")
    p.add_argument("--no-progress", dest="progress", action="store_const", const=False,
                   help="print nothing while fitting")
    p.set_defaults(func=run)


def _check_before_fitting(args, fixed: dict) -> None:
    """What can be checked before minutes of fitting: the outputs can be written and differ,
    the sizes fit in memory and the step counter, and the fixed values are ones the model takes."""
    from morphojax._files import check_output_path  # a private helper of the core, as `cli` uses it

    from ._pipeline import check_fit_inputs

    outputs = [p for p in (args.json, args.preview, args.sample, args.render) if p is not None]
    for path in outputs:
        check_output_path(path)
    resolved = [p.resolve() for p in outputs]
    if len(set(resolved)) != len(resolved):
        raise ValueError(f"two outputs have the same path: {', '.join(str(p) for p in outputs)}")
    check_fit_inputs(args.model, args.shape, args.seeds, args.steps, args.window, fixed, flag="--{}")


# argparse destination -> `fitting.fit` keyword (the names that differ)
CLI_TO_API = {"design": "n_design"}


def run(args) -> int:
    import time

    import fitting
    import morphojax as mj

    t_wall = time.perf_counter()

    crop = _floats(args.crop, 4, "--crop") if args.crop else None
    fixed = {}
    for name, text in _pairs(args.fixed, "--fixed").items():
        try:
            fixed[name] = float(text)
        except ValueError:
            raise ValueError(f"--fixed {name}: {text!r} is not a number") from None
    _check_before_fitting(args, fixed)
    bounds = {}
    for name, text in _pairs(args.bounds, "--bounds").items():
        lo, sep, hi = text.partition(":")
        if not sep:
            raise ValueError(f"--bounds takes NAME=LOW:HIGH (got {name}={text})")
        bounds[name] = (float(lo), float(hi))
    target = fitting.load_target(args.photo, crop=crop, channel=args.channel, invert=args.invert,
                                 cell_pixels=args.cell_pixels)
    result = fitting.fit(target, model=args.model, fit=args.fit, fixed=fixed, bounds=bounds, shape=tuple(args.shape),
                         steps=args.steps, window=args.window, seeds=args.seeds, design_seeds=args.design_seeds,
                         seed=args.seed, n_design=args.design,
                         rounds=args.rounds, keep=args.keep, method=args.method, max_steps=args.max_steps,
                         stats=fitting.StatsConfig(binarise=args.binarise, orientation=args.orientation),
                         progress=args.progress, screen=args.screen, refine=args.refine)
    result.save_json(args.json)
    for path, write in ((args.preview, result.preview), (args.sample, result.save_sample),
                        (args.render, lambda f: result.render(f, size=1024))):
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            write(path)
    stages = {k: round(v, 1) for k, v in result.timings.items() if k != "total"}
    line = {"family": result.family, "convincing": result.convincing, "verdict": result.verdict,
            "heldout": {k: result.heldout.get(k) for k in ("distance", "floor", "noise", "held_out")},
            "params": result.params, "intervals": result.intervals, "undetermined": result.undetermined,
            "correlated": result.correlated, "loss": result.loss, "noise_floor": result.noise_floor,
            "cell_pixels": target.cell_pixels, "seconds": round(time.perf_counter() - t_wall, 1), "stages": stages,
            "json": str(args.json), "preview": str(args.preview) if args.preview else None}
    print(json.dumps(mj.to_jsonable(line), allow_nan=False))  # strict JSON: a NaN is written as "nan"
    print(result.describe())
    return 0

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
    """Add the `fit` subcommand to an argparse subparsers object."""
    p = subparsers.add_parser("fit", help="fit model parameters to a photo's texture statistics",
                              description="Fit parameters of a model so that its simulated texture matches a photo. "
                                          "Writes a JSON report (top-level 'params') and a preview picture.")
    p.add_argument("photo", type=Path, help="image file (any format pillow reads)")
    p.add_argument("--model", default="turing", help="turing, bard, gray-scott or reinforcement (default turing)")
    p.add_argument("--fit", default="ratio,scale", help="comma-separated parameters to fit (default ratio,scale)")
    p.add_argument("--fixed", action="append", metavar="NAME=VALUE", help="hold a parameter at a value")
    p.add_argument("--bounds", action="append", metavar="NAME=LOW:HIGH", help="bounds of a fitted parameter")
    p.add_argument("--crop", default=None, metavar="X0,Y0,X1,Y1", help="pixel box of the coat region")
    p.add_argument("--channel", default="luminance", help="luminance, red, green, blue, alpha, saturation, value")
    p.add_argument("--invert", action="store_true", help="dark pigment as high values (e.g. black spots = high B)")
    p.add_argument("--cell-pixels", type=float, default=None, help="photo pixels per lattice cell (default: estimated)")
    p.add_argument("--no-binarise", action="store_true",
                   help="compare raw intensities instead of soft pigment maps (the default for photos)")
    p.add_argument("--orientation", action="store_true", help="add the structure-tensor orientation (stripes)")
    p.add_argument("--shape", type=int, nargs=2, default=(64, 64), metavar=("ROWS", "COLS"))
    p.add_argument("--steps", type=int, default=8000)
    p.add_argument("--window", type=int, default=1000, help="steps differentiated at the end of each run")
    p.add_argument("--seeds", type=int, default=4, help="simulations averaged per evaluation")
    p.add_argument("--design", type=int, default=None, help="points per design round (default 12 per parameter)")
    p.add_argument("--rounds", type=int, default=2, help="refinement rounds of the design")
    p.add_argument("--keep", type=int, default=2, help="local searches from the best design points")
    p.add_argument("--method", default="bfgs", help="bfgs, lm, nelder-mead or gd")
    p.add_argument("--max-steps", type=int, default=40)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", type=Path, required=True, help="output JSON report")
    p.add_argument("--preview", type=Path, default=None, help="output picture: target | fit | loss curve")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    import fitting

    crop = _floats(args.crop, 4, "--crop") if args.crop else None
    fixed = {k: float(v) for k, v in _pairs(args.fixed, "--fixed").items()}
    bounds = {}
    for name, text in _pairs(args.bounds, "--bounds").items():
        lo, sep, hi = text.partition(":")
        if not sep:
            raise ValueError(f"--bounds takes NAME=LOW:HIGH (got {name}={text})")
        bounds[name] = (float(lo), float(hi))
    target = fitting.load_target(args.photo, crop=crop, channel=args.channel, invert=args.invert,
                                 cell_pixels=args.cell_pixels)
    result = fitting.fit(target, model=args.model, fit=args.fit, fixed=fixed, bounds=bounds, shape=tuple(args.shape),
                         steps=args.steps, window=args.window, seeds=args.seeds, seed=args.seed, n_design=args.design,
                         rounds=args.rounds, keep=args.keep, method=args.method, max_steps=args.max_steps,
                         stats=fitting.StatsConfig(binarise=not args.no_binarise, orientation=args.orientation),
                         progress=not args.no_progress)
    result.save_json(args.json)
    if args.preview is not None:
        args.preview.parent.mkdir(parents=True, exist_ok=True)
        result.preview(args.preview)
    print(json.dumps({"params": result.params, "loss": result.loss, "noise_floor": result.noise_floor,
                      "seconds": round(result.timings["total"], 1), "json": str(args.json),
                      "preview": str(args.preview) if args.preview else None}))
    return 0

"""How `auto`'s screen orders the families on the photo-like suite: the held-out rule against
the training loss, on the same screens.

The screen runs each family's global design on the training half of a photo and keeps its
best point's samples (`fitting._auto.screen`). Two rules order the families from one run:
`heldout`, the samples' texture distance to the held-out half (`fitting._verdict`), and
`loss`, the penalised training loss (the rule before). The `top` families go on to full
fits, so what matters is the rank of the family that made the coat: recorded per case with
the right family's rank under each rule and whether it is among the `TOP` fitted in full.

The cases, their coats and their camera faults are `fit_photolike.py`'s. Developers decide
on the tuning seeds (the default here); `--report` runs the report seeds, which are only
reported.

    python benchmarks/screen_photolike.py [--report] [--degradations all none] [--only CASE ...]
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import time
from functools import partial
from pathlib import Path

import numpy as np

import fitting
from fitting._auto import TOP, families_for, screen
from fitting._stats import StatsConfig
from fitting._verdict import heldout_distance, split_target

import fit_photolike as suite

HERE = Path(__file__).resolve().parent
OPTIONS = ("fixed", "bounds", "shape", "steps", "window", "seeds", "seed", "design_seeds", "design", "n_design",
           "rounds", "keep", "method", "max_steps", "fallback", "boundary", "species", "batch_size", "noise_seeds",
           "learning_rate", "length_scale", "intervals")


def fit_options() -> dict:
    """`fitting.fit`'s own defaults for the options the screen passes on."""
    params = inspect.signature(fitting.fit).parameters
    return {**{k: params[k].default for k in OPTIONS}, "stats": StatsConfig()}


def screen_case(name: str, which: str, tuning: bool) -> dict:
    family = suite.CASES[name][0]
    try:  # a coat that forms no pattern on its seed, or a photo the loader refuses: recorded
        seed, _, wavelength, photo = suite.coat(name, tuning)
        target = fitting.load_target(suite.degrade(photo, which, seed), cell_pixels=None, invert=True)
    except ValueError as err:
        return {"case": name, "degradation": which, "family": family, "error": str(err), "ranks": {}, "rows": []}
    train, heldout, apart = split_target(target.field)
    training = dataclasses.replace(target, field=train) if apart else target
    score = partial(heldout_distance, whole=target.field, heldout=heldout)
    t0 = time.perf_counter()
    rows = screen(training, None, families_for(training.field), fit_options(), score, "heldout")
    seconds = time.perf_counter() - t0
    ranks = {}
    for rule, key in (("heldout", "heldout"), ("loss", "penalised")):
        order = sorted(rows, key=lambda r: (r["rejected"] is not None, r[key] if np.isfinite(r[key]) else np.inf))
        names = [r["family"] for r in order]
        ranks[rule] = names.index(family) + 1 if family in names else None
    return {"case": name, "degradation": which, "seed": seed, "family": family, "held_out": apart,
            "ranks": ranks, "rows": rows, "seconds": seconds}


def table(results: list, tuning: bool) -> list[str]:
    lines = ["| case | degradation | family | rank, held-out rule | rank, training loss | screened |",
             "|---|---|---|---|---|---|"]
    errors = [r for r in results if r.get("error")]
    results = [r for r in results if not r.get("error")]
    for r in results:
        lines.append(f"| {r['case']} | {r['degradation']} | {r['family']} | {r['ranks']['heldout']} | "
                     f"{r['ranks']['loss']} | {len(r['rows'])} families, {r['seconds']:.0f} s |")
    n = len(results)
    fitted = {rule: sum(1 for r in results if r["ranks"][rule] is not None and r["ranks"][rule] <= TOP)
              for rule in ("heldout", "loss")}
    first = {rule: sum(1 for r in results if r["ranks"][rule] == 1) for rule in ("heldout", "loss")}
    seeds = "tuning" if tuning else "report"
    skipped = [f"{r['case']} ({r['error']})" for r in errors]
    return lines + [""] + ([f"Not screened: {'; '.join(skipped)}.", ""] if skipped else []) + [f"On the {seeds} seeds: the right family first on {first['heldout']} of {n} with the "
                        f"held-out rule and {first['loss']} of {n} with the training loss; among the {TOP} fitted in "
                        f"full on {fitted['heldout']} and {fitted['loss']} of {n}.", ""]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--report", action="store_true", help="the report seeds (default: the tuning seeds)")
    parser.add_argument("--degradations", nargs="+", default=["all"], choices=suite.CHOICES)
    parser.add_argument("--only", nargs="+", default=list(suite.CASES), choices=list(suite.CASES))
    args = parser.parse_args(argv)
    tuning = not args.report
    name = "screen_photolike" + ("-tuning" if tuning else "")
    out = HERE / "results" / f"{name}.md"
    results = []
    for which in args.degradations:
        for case in args.only:
            results.append(screen_case(case, which, tuning))
            print(json.dumps({k: v for k, v in results[-1].items() if k != "rows"}), flush=True)
            out.with_suffix(".json").write_text(json.dumps(results, indent=1, default=float))
    lines = ["# The screen's order on the photo-like suite", "",
             f"`python benchmarks/screen_photolike.py{' --report' if args.report else ''} --degradations "
             f"{' '.join(args.degradations)}` ({time.strftime('%Y-%m-%d')}); see the script's docstring.", ""]
    out.write_text("\n".join(lines + table(results, tuning)))
    print("\n".join(table(results, tuning)))


if __name__ == "__main__":
    main()

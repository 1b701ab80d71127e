"""Where linear stability places the fit's design points (`fitting._predicted`), against the
family's scaling law: which families may use the prediction (`Family.predicted`).

For every family, Latin-hypercube points are drawn in its default fitted bounds (seed
`DESIGN_SEED`, not the fit's) for each target wavelength in `TARGETS` (cells; photos are
resampled to about 10 cells per wavelength). Each point is simulated as the fit's design
simulates it (`fitting.Simulator`: the family's lattice, steps, time step and solver; the
design's 2 seeds) and its wavelength measured as the verdict measures it (the spectrum's peak
of each seed's field, median over seeds: `fitting._verdict.wavelength_of`). Two ways to bring
a point to the target's wavelength along the family's length parameter:

- `law`: simulate the drawn point, then move it by the family's law (wavelength ~ length **
  `length_power`, from the measured wavelength) and simulate again: two runs a point;
- `placed`: where the prediction is valid at the point, place it at the target's predicted
  wavelength (`fitting._predicted.place`) and simulate once; where it then settled more than
  `LANDED` (5%) away, or formed no measurable pattern, move it by the law and simulate again
  (the fit's rule).

Reported over the points whose prediction is valid (elsewhere the fit moves by the law as
before): how many (and how many distinct drawn points: every target draws the same ones), the
share within 10% and 20% of the target's wavelength after the placed point's first run (a run
with no measurable pattern counts as a miss, and is counted), after each way's last run, and
the runs a placed point took. A family is declared
`predicted` when its placed points land within 10% at least as often after one run as the
law's after two.

    python benchmarks/fit_placement.py [--families turing bard gray-scott] [--points 16]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from fitting._families import FAMILIES
from fitting._predicted import LANDED, applies, place
from fitting._scale import moved_length
from fitting._simulator import Simulator
from fitting._space import ParamSpace
from fitting._verdict import wavelength_of

HERE = Path(__file__).resolve().parent
SHAPE = (64, 64)
TARGETS = (8.0, 10.0, 13.0)
DESIGN_SEED = 11
SEEDS = 2
MODEL_FAMILIES = ["turing", "bard", "gray-scott", "reinforcement"]  # the others: no model template (Young, leopard) or a polarised lattice


def family_simulator(name: str) -> tuple[Simulator, list, ParamSpace]:
    fam = FAMILIES[name]
    names = list(fam.fit)
    sim = fam.simulator(SHAPE)
    return sim, names, ParamSpace.build(names, {n: fam.bounds[n] for n in names})


def measure(name: str, points: int) -> dict:
    fam = FAMILIES[name]
    sim, names, space = family_simulator(name)
    length = names.index(fam.length)
    low, high = space.low[length], space.high[length]
    keys = jax.random.split(jax.random.key(DESIGN_SEED), SEEDS)
    run = jax.jit(jax.vmap(jax.vmap(lambda t, k: sim.run({n: t[i] for i, n in enumerate(names)}, k),
                                    in_axes=(None, 0)), in_axes=(0, None)))

    def wavelengths(thetas):
        fields = np.asarray(run(jnp.asarray(thetas, jnp.float32), keys))
        return np.array([np.nanmedian([wavelength_of(f) for f in seeds]) if np.isfinite(fields).all() else np.nan
                         for seeds in fields])

    # every target starts from the same drawn points, run once
    drawn = np.asarray(space.from_unit(space.design(points, "lhs", DESIGN_SEED)), np.float64)
    first = wavelengths(drawn)
    rows = []
    for target in TARGETS:
        t0 = time.perf_counter()
        moved = drawn.copy()
        moved[:, length] = moved_length(drawn[:, length], first, target, fam.length_power, low, high)
        law = wavelengths(moved)
        placed, valid = place(sim, names, drawn, length, target, low, high) if applies(sim) else (
            drawn, np.zeros(points, bool))
        once = wavelengths(placed)
        again = placed.copy()
        again[:, length] = moved_length(placed[:, length], once, target, fam.length_power, low, high)
        redo = ~(np.abs(once / target - 1) <= LANDED)  # off, or no measurable pattern (NaN)
        twice = np.where(redo, wavelengths(again), once)
        for i in range(points):
            rows.append({"target": target, "point": i, "theta": drawn[i].tolist(), "valid": bool(valid[i]),
                         "placed": placed[i].tolist(), "first": first[i], "law": law[i], "once": once[i],
                         "twice": twice[i], "redo": bool(redo[i])})
        print(f"{name} target {target}: {valid.sum()} valid, {time.perf_counter() - t0:.0f} s", flush=True)
    return {"family": name, "names": names, "rows": rows}


def share(values, targets, tol: float) -> float:
    values, targets = np.asarray(values, float), np.asarray(targets, float)
    return float(np.mean(np.abs(values / targets - 1) <= tol)) if len(values) else float("nan")


def summarise(result: dict) -> list[str]:
    rows = [r for r in result["rows"] if r["valid"]]
    n_all = len(result["rows"])
    if not rows:
        return [f"| {result['family']} | 0 of {n_all} | - | - | - | - | - | - | no (never valid) |"]
    t = [r["target"] for r in rows]
    once10, law10 = share([r["once"] for r in rows], t, 0.1), share([r["law"] for r in rows], t, 0.1)
    runs = 1 + np.mean([r["redo"] for r in rows])
    flat = sum(not np.isfinite(r["once"]) for r in rows)
    distinct = len({r["point"] for r in rows})
    verdict = "yes" if once10 >= law10 else "no"
    return [f"| {result['family']} | {len(rows)} of {n_all} ({distinct} distinct) | {flat} "
            f"| {once10:.0%} / {share([r['once'] for r in rows], t, 0.2):.0%} "
            f"| {share([r['twice'] for r in rows], t, 0.1):.0%} | {law10:.0%} / {share([r['law'] for r in rows], t, 0.2):.0%} "
            f"| {runs:.2f} | 2 | {verdict} |"]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--families", nargs="+", default=MODEL_FAMILIES, choices=MODEL_FAMILIES)
    parser.add_argument("--points", type=int, default=16)
    parser.add_argument("--out", default=str(HERE / "results" / "fit_placement.md"))
    args = parser.parse_args(argv)
    out = Path(args.out)
    results = [measure(name, args.points) for name in args.families]
    out.with_suffix(".json").write_text(json.dumps(results, indent=1, default=float))
    lines = ["# Placing the fit's design by linear stability", "",
             f"`python benchmarks/fit_placement.py --families {' '.join(args.families)} --points {args.points}` "
             f"({time.strftime('%Y-%m-%d')}, {jax.devices()[0].platform}): {SHAPE[0]}x{SHAPE[1]}, targets "
             f"{', '.join(f'{t:g}' for t in TARGETS)} cells, {args.points} points each, {SEEDS} seeds; see the "
             "script's docstring. Shares are of the points whose prediction is valid.", "",
             "| family | valid points | placed runs with no measurable pattern | placed, one run: within 10% / 20% "
             "| placed, then moved where off: within 10% | law (two runs): within 10% / 20% "
             "| runs a placed point | runs a point, law | predicted |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        lines += summarise(r)
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

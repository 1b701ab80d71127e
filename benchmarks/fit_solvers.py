"""Which solver a fit's family may use: the fit's own statistics under each candidate solver
against forward Euler's, in units of the seed-to-seed spread, and the time each takes.

For every family, points are drawn in its default fitted bounds (a Latin hypercube, fixed
seed) and moved along the family's length parameter to a wavelength of `WAVELENGTH` cells,
as the fit's design moves its points to the target's (photos are resampled to 10 cells per
wavelength); points whose Euler pattern is then uniform or grid-scale (the fit rejects
those) are left out. Each point is simulated as the fit simulates it (`fitting.Simulator`: the family's
lattice, steps and adaptive Euler time step) for the same seeds with Euler and with each
candidate (a solver taking one step of `stride` Euler steps, the same simulated time), and
the fit's distance (`fitting._stats.distance`, in units of the noise scales) is measured:

- `solver`: the candidate's mean statistics against Euler's, the same seeds (the initial
  states are the same: the difference is the time stepping's);
- `seeds`: Euler's mean statistics on one set of seeds against another (the fit cannot
  resolve differences below this).

A candidate is accepted for a family when its median `solver` distance is below the median
`seeds` distance, and no point is more than 2x its `seeds` distance. The fastest accepted
candidate is the family's (`fitting.FAMILIES`). Times are compiled runs of one point's
seeds, interleaved per point, so the ratio holds on a shared machine.

    python benchmarks/fit_solvers.py [--families turing bard] [--points 12] [--out benchmarks/results/fit_solvers.md]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import morphojax as mj
from fitting._families import FAMILIES
from fitting._space import ParamSpace
from fitting._stats import StatsConfig, distance, texture_stats

HERE = Path(__file__).resolve().parent
SHAPE = (64, 64)  # the fit's default lattice
SEEDS = 4  # the fit's seeds per evaluation
WAVELENGTH = 10.0  # cells: a photo's resolution in a fit (`fitting.load_target`)

# (label, solver, stride): a solver step spans `stride` Euler steps
CANDIDATES = {
    "turing": [("etdrk1 x5", mj.ETDRK(order=1), 5), ("etdrk1 x20", mj.ETDRK(order=1), 20),
               ("etdrk2 x5", mj.ETDRK(order=2), 5), ("etdrk2 x10", mj.ETDRK(order=2), 10),
               ("etdrk2 x40", mj.ETDRK(order=2), 40), ("etdrk4 x10", mj.ETDRK(order=4), 10),
               ("etdrk4 x40", mj.ETDRK(order=4), 40), ("imex2 x10", mj.IMEX(order=2), 10)],
    "bard": [("etdrk1 x2", mj.ETDRK(order=1), 2), ("etdrk2 x5", mj.ETDRK(order=2), 5),
             ("etdrk4 x5", mj.ETDRK(order=4), 5)],
    "gray-scott": [("etdrk1 x2", mj.ETDRK(order=1), 2), ("etdrk2 x5", mj.ETDRK(order=2), 5),
                   ("etdrk4 x5", mj.ETDRK(order=4), 5)],
    "reinforcement": [("etdrk1 x5", mj.ETDRK(order=1), 5), ("etdrk2 x10", mj.ETDRK(order=2), 10),
                      ("etdrk4 x10", mj.ETDRK(order=4), 10)],
}


@eqx.filter_jit
def _stats(sim, space, cfg, theta, keys):
    fields = jax.vmap(lambda k: sim.run(space.as_dict(theta), k))(keys)
    return jax.vmap(lambda f: texture_stats(f, cfg))(fields)


def _mean(per_seed):
    return jax.tree_util.tree_map(lambda v: jnp.mean(v, axis=0), per_seed)


def _timed(sim, space, cfg, theta, keys):
    out = _stats(sim, space, cfg, theta, keys)  # compiled already: the first call of each is not timed
    jax.block_until_ready(out)
    t0 = time.perf_counter()
    out = _stats(sim, space, cfg, theta, keys)
    jax.block_until_ready(out)
    return out, time.perf_counter() - t0


def _moved(fam, space, sim, cfg, theta, keys):
    """theta moved along the family's length parameter to WAVELENGTH cells (the fit's design
    rule, wavelength ~ length ** length_power), or None when its pattern is then uniform or
    grid-scale (under 4 cells, `fitting._verdict`)."""
    theta = np.array(theta, np.float32)
    if fam.length in fam.fit:
        i = list(fam.fit).index(fam.length)
        lam = float(_mean(_stats(sim, space, cfg, jnp.asarray(theta), keys))["wavelength"])
        if np.isfinite(lam) and lam > 0:
            theta[i] = np.clip(theta[i] * (WAVELENGTH / lam) ** (1.0 / fam.length_power), space.low[i], space.high[i])
    lam = float(_mean(_stats(sim, space, cfg, jnp.asarray(theta), keys))["wavelength"])
    if not np.isfinite(lam) or lam < 4.0:  # a uniform field measures the lattice's scale too
        return None
    return jnp.asarray(theta)


def measure(name: str, n_points: int, seed: int = 0) -> dict:
    fam = FAMILIES[name]
    cfg = StatsConfig()
    space = ParamSpace.build(fam.fit, {n: fam.bounds[n] for n in fam.fit})
    thetas = np.asarray(space.from_unit(jnp.asarray(space.design(n_points, "lhs", seed), jnp.float32)))
    base = fam.simulator(SHAPE, solver=None, stride=1)  # forward Euler, the reference
    keys_a = jax.random.split(jax.random.key(1), SEEDS)
    keys_b = jax.random.split(jax.random.key(2), SEEDS)
    sims = {label: fam.simulator(SHAPE, solver=solver, stride=stride)
            for label, solver, stride in CANDIDATES[name]}
    for s in [base, *sims.values()]:  # compile every program once before any timing
        jax.block_until_ready(_stats(s, space, cfg, jnp.asarray(thetas[0]), keys_a))
    rows = []
    for theta in thetas:
        theta = _moved(fam, space, base, cfg, theta, keys_a)
        if theta is None:
            continue
        euler_a, t_euler = _timed(base, space, cfg, theta, keys_a)
        euler_b = _stats(base, space, cfg, theta, keys_b)
        mean_a = _mean(euler_a)
        row = {"params": {n: float(v) for n, v in zip(fam.fit, theta)}, "euler_seconds": t_euler,
               "wavelength": float(mean_a["wavelength"]),
               "seeds": float(distance(_mean(euler_b), mean_a, cfg)), "candidates": {}}
        for label, sim in sims.items():
            cand, t = _timed(sim, space, cfg, theta, keys_a)
            mean_c = _mean(cand)
            row["candidates"][label] = {"solver": float(distance(mean_c, mean_a, cfg)), "seconds": t,
                                        "wavelength": float(mean_c["wavelength"])}
        rows.append(row)
        print(json.dumps(row), flush=True)
    return {"family": name, "points": rows}


def summarise(result: dict) -> list[str]:
    rows = result["points"]
    seeds = np.array([r["seeds"] for r in rows])
    euler = np.median([r["euler_seconds"] for r in rows])
    lines = [f"### {result['family']}", "",
             f"{len(rows)} points; Euler's seed-to-seed distance: median {np.median(seeds):.1f} "
             f"(range {seeds.min():.1f}-{seeds.max():.1f}); Euler {euler * 1e3:.0f} ms per point ({SEEDS} seeds)", "",
             "| candidate | distance to Euler, median | worst / seeds | wavelength change, worst | speed-up (median) | accepted |",
             "|---|---|---|---|---|---|"]
    chosen = None
    for label in rows[0]["candidates"]:
        d = np.array([r["candidates"][label]["solver"] for r in rows])
        worst = float(np.max(d / np.maximum(seeds, 1e-9)))
        lam = max(abs(r["candidates"][label]["wavelength"] / r["wavelength"] - 1.0) for r in rows)
        speed = np.median([r["euler_seconds"] / r["candidates"][label]["seconds"] for r in rows])
        ok = bool(np.median(d) < np.median(seeds) and worst <= 2.0)
        if ok and speed > 1.0 and (chosen is None or speed > chosen[1]):
            chosen = (label, speed)
        lines.append(f"| {label} | {np.median(d):.1f} | {worst:.2f} | {100 * lam:.1f}% | {speed:.1f}x | "
                     f"{'yes' if ok else 'no'} |")
    decision = (f"the family steps with {chosen[0]} ({chosen[1]:.1f}x)" if chosen is not None else
                "forward Euler: no accepted candidate is faster")
    return lines + ["", f"Decision: {decision}.", ""]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--families", nargs="+", default=list(CANDIDATES), choices=list(CANDIDATES))
    parser.add_argument("--points", type=int, default=12)
    parser.add_argument("--out", default=str(HERE / "results" / "fit_solvers.md"))
    parser.add_argument("--from-json", action="store_true", help="write the table from the saved rows (no runs)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    results = json.loads(out.with_suffix(".json").read_text()) if args.from_json else []
    for name in [] if args.from_json else args.families:  # each family's rows are kept once measured
        results.append(measure(name, args.points))
        out.with_suffix(".json").write_text(json.dumps(results, indent=1))
    lines = ["# Solvers for the fit's families", "",
             f"`python benchmarks/fit_solvers.py --families {' '.join(r['family'] for r in results)}` "
             f"({time.strftime('%Y-%m-%d')}, {jax.devices()[0].platform}). "
             "Distances are the fit's loss (`fitting._stats.distance`, noise scales of `StatsConfig`) between "
             f"mean statistics of {SEEDS} seeds on {SHAPE[0]}x{SHAPE[1]}; see the script's docstring. "
             "The speed-ups are one compiled run per point and candidate: on a busy machine they are rough.", ""]
    for r in results:
        lines += summarise(r)
    out.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()

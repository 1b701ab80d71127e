"""The off-lattice cell simulator (thesis ch. 4) against the thesis's C++ and a NumPy port.

The thesis's Table A.1 times its C++ simulator on one core of a 1.8 GHz Core i7-4500U:
- the leopard (Fig. 7.21, Listing A.18): a 50 x 58 hex grid (2,900 cells) growing to
  6,228 in 14,000 iterations (dt 0.1, packed domain, division limit 6, division with
  probability 1e-4 from iteration 4,000): 22.298 s;
- the moray eel (Fig. 7.18, Listing A.17): a 200 x 100 square grid (20,000 cells), 5,000
  iterations, no division: 21.122 s.
morphojax runs the shipped listings with `Listing.run` (compiled; the compile time, the
first run less the median of three re-runs, is reported apart) and at `Listing.run`'s
default capacity, which follows the tissue (a piece of the run that outgrows it runs
again with 1.5x the room; every iteration pays for the buffers' size, so a guess of
4 x 2,900 = 11,600 cost the leopard twice its time; `--leopard-capacity` fixes one). Listing A.18 as printed
sets only 9 of its 32 seed cells (the other 23 are named in a comment, "omitted for
brevity"); the benchmark restores them (`set cell N chemical V conc 10` lines), as a
preset would, and runs it with seed 0. The moray runs as published (`use seed 1`).

Every speed is also a ratio against the NumPy port in benchmarks/cells_numpy.py (cKDTree
pairs, np.add.at, rebuilt every iteration), timed in the same process on the same cells:
`--numpy-steps` iterations from the listing's prepattern, and for the growing leopard from
snapshots at 0, 1/4, 1/2, 3/4 and the end of the run (the NumPy run's seconds are then
estimated from the per-iteration times at the snapshots, trapezoid rule). Before timing,
the script checks once that the port and morphojax agree after 10 iterations of a small
run (and 4 iterations with divisions) to 1e-4, so the baseline is the same computation.
The speed-up over the thesis compares seconds per iteration (for the full runs, the same
as comparing the runs' seconds).

Then, per-iteration times against the number of cells (hex grids of ~1k to 100k cells):
a static reaction-diffusion run (Bard's reaction, no division, no domain: the neighbour
list is never rebuilt) and a growing one (the leopard's rules, a domain packed at the hex
grid's own 2 sqrt 3 per cell, division by chance 4 / cells: the list is rebuilt on the
~98% of iterations with a division; capacity
for 1.5 times the expected divisions); and a profile of one growing iteration at the
leopard's size (6,240 cells, capacity 6,600): each part of `_step.step` jitted and timed
alone (median of 20 calls; every figure includes the cost of calling a jitted function,
timed apart). Medians over fresh processes (_harness.py).

    python benchmarks/bench_cells.py [--repeats 5] [--quick] [--only leopard moray scaling profile]
                                     [--max-cells 100000] [--numpy-steps 200] [--numpy-max-cells 30000]
                                     [--leopard-capacity N]

`--quick` runs tiny sizes (seconds; for testing) and writes nothing; otherwise the tables
go to stdout and to benchmarks/results/bench_cells.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time

import numpy as np

from _harness import HERE, in_fresh_processes, machine, markdown_table, median

RESULTS = HERE / "results" / "bench_cells.md"
THESIS_SECONDS = {"leopard": 22.298, "moray": 21.122}  # Table A.1, Figs. 7.21 and 7.18
THESIS_ITERATIONS = {"leopard": 14_000, "moray": 5_000}
HEX_AREA = 2 * math.sqrt(3)  # area per cell of a hexagonal grid of spacing 2
THESIS_CELLS = {"leopard": "2,900 -> 6,228", "moray": "20,000"}
LISTING = {"leopard": "A.18", "moray": "A.17"}
# Listing A.18's seed cells left in a comment ("other seed cells omitted for brevity")
LEOPARD_OMITTED_SEEDS = (1005, 1015, 1025, 1035, 1045, 1410, 1420, 1430, 1440, 1805, 1815, 1825, 1835, 1845,
                         2210, 2220, 2230, 2240, 2605, 2615, 2625, 2635, 2645)
SCALING_CELLS = (1_000, 3_000, 10_000, 30_000, 100_000)
QUICK_SCALING_CELLS = (300, 1_000)
SCALING_STEPS = 200  # iterations per timed call of morphojax
DIVISIONS_PER_ITERATION = 4  # the growing runs' expected divisions (Chance(4 / cells))
PROFILE_GRID, PROFILE_CAPACITY = (80, 78), 6_600  # (rows, cols): 6,240 cells, the leopard's final size
QUICK_PROFILE_GRID, QUICK_PROFILE_CAPACITY = (20, 18), 400
QUICK_LISTING_STEPS = 40
RERUNS = 3


# ---- the experiments --------------------------------------------------------------------------
def leopard_listing():
    """Listing A.18 with its 23 commented-out seed cells restored (32 seeds in all)."""
    import morphojax as mj

    text = mj.cells.listing_path("A.18").read_text()
    restored = "".join(f"set cell {n} chemical V conc 10\n" for n in LEOPARD_OMITTED_SEEDS)
    marker = "// ----- rules"
    if marker not in text:
        raise RuntimeError("Listing A.18 changed: no '// ----- rules' line to put the restored seeds before")
    return mj.load_listing(text.replace(marker, restored + "\n" + marker), name="A18_fig7.21 (32 seeds)")


def listing_for(name: str):
    import morphojax as mj

    return leopard_listing() if name == "leopard" else mj.load_listing(LISTING[name])


def leopard_rules(growth_probability=None):
    """The leopard's rules (Listing A.18), dividing with `growth_probability` from the start
    (None: no division)."""
    import morphojax as mj
    import morphojax.cells as mc

    rules = [mc.Rule(mc.React(mj.Bard(alpha=16.0, beta=12.0, sp=1.0), ("U", "V"), scale=0.025))]
    if growth_probability is not None:
        rules.append(mc.Rule(mc.Divide(0.0, math.pi), when=mc.Chance(growth_probability)))
    return tuple(rules)


def leopard_cells(shape, capacity=None, *, key_seed=0, jitter=0.0):
    """A hex grid of `shape` = (rows, cols) with the leopard's reagents (U 4, V 4 +- 1)."""
    import jax

    import morphojax.cells as mc

    return mc.cell_grid(shape, ("U", "V"), lattice="hex", concentration=(4.0, 4.0), spread=(0.0, 1.0),
                        diffusion=(0.40, 0.01), upper=(4.05, None), jitter=jitter, capacity=capacity,
                        key=jax.random.key(key_seed))


def hex_shape(cells: int) -> tuple[int, int]:
    """(rows, cols) of a roughly square hex grid of about `cells` cells."""
    cols = max(2, round(math.sqrt(cells * math.sqrt(3) / 2)))
    return max(2, round(cells / cols)), cols


# ---- the honesty check: the port computes what morphojax computes --------------------------------
def check_port() -> str:
    """Run a small leopard-like run in morphojax and the NumPy port; raise if they differ."""
    import jax

    import morphojax as mj
    import morphojax.cells as mc
    import cells_numpy

    base = mc.cell_grid((10, 12), ("U", "V", "P"), lattice="hex", concentration=(4.0, 4.0, 0.0),
                        spread=(0.5, 1.0, 0.0), diffusion=(0.40, 0.01, 0.01), upper=(4.05, None, None), jitter=0.4,
                        key=jax.random.key(3))
    seeded = np.array(base.concentration)
    seeded[2, [17, 64]] = 8.0  # two sources of P: Change fires where P > 0.5
    seeded[1, [30, 90]] = 10.0  # two seeds of V: Divide fires where V > 8
    reaction = mc.Rule(mc.React(mj.Bard(alpha=16.0, beta=12.0, sp=1.0), ("U", "V"), scale=0.025))
    change = mc.Rule(mc.Change(mc.conc("V"), 1.0), when=mc.Compare(mc.conc("P"), ">", 0.5))
    divide = mc.Rule(mc.Divide(0.3), when=mc.Compare(mc.conc("V"), ">", 8.0))
    lines = []
    for label, rules, steps, capacity, limit in (("static", (reaction, change), 10, 120, 6),
                                                 ("dividing", (reaction, divide), 4, 400, 9)):
        cells = base.replace(concentration=jax.numpy.asarray(seeded)).with_capacity(capacity)
        settings = dict(domain=mc.Packed(), division_limit=limit)
        out = mj.simulate_cells(None, cells, steps, 0.1, rules=rules, **settings)
        ref = cells_numpy.run(cells_numpy.from_cells(cells), rules, steps, 0.1, np.random.default_rng(0), **settings)
        got = out.live()
        if got["position"].shape[0] != ref.count:
            raise AssertionError(f"NumPy port check ({label}): {ref.count} cells, morphojax {got['position'].shape[0]}")
        for field, mine in (("position", ref.position), ("concentration", ref.concentration),
                            ("diffusion", ref.diffusion), ("polarity", ref.polarity), ("birth", ref.birth)):
            if not np.allclose(got[field], mine, rtol=1e-4, atol=1e-4):
                worst = float(np.max(np.abs(got[field].astype(float) - mine)))
                raise AssertionError(f"NumPy port check ({label}): {field} differs from morphojax by up to {worst:.3g}")
        worst = max(float(np.max(np.abs(got[f].astype(float) - m)))
                    for f, m in (("position", ref.position), ("concentration", ref.concentration)))
        lines.append(f"{label}: {steps} iterations, {int(cells.count)} -> {ref.count} cells, "
                     f"largest difference {worst:.1e}")
    return "; ".join(lines)


# ---- workers ------------------------------------------------------------------------------------
def numpy_seconds_per_iteration(state, rules, steps, dt, **settings) -> float:
    import cells_numpy

    rng = np.random.default_rng(0)
    warm = cells_numpy.step(state, rules, dt, rng, **settings)  # first-call costs (imports, caches) untimed
    del warm
    t0 = time.perf_counter()
    cells_numpy.run(state, rules, steps, dt, rng, **settings)
    return (time.perf_counter() - t0) / steps


def listing_worker(name: str, quick: bool, numpy_steps: int, capacity: int | None = None) -> dict:
    import jax

    import cells_numpy
    import morphojax.cells as mc

    listing = listing_for(name)
    steps = QUICK_LISTING_STEPS if quick else listing.steps
    seed = 0 if name == "leopard" else None  # the moray keeps its own `use seed 1`

    def run():
        out = listing.run(seed=seed, steps=steps, capacity=capacity)  # syncs: it reads out.ok
        jax.block_until_ready(out.concentration)
        return out

    t0 = time.perf_counter()
    out = run()  # compiles
    first = time.perf_counter() - t0
    runs = []
    for _ in range(1 if quick else RERUNS):
        t0 = time.perf_counter()
        out = run()
        runs.append(time.perf_counter() - t0)
    jax_s = statistics.median(runs)

    # the NumPy port from the same cells: the prepattern, and for a growing run snapshots
    # spread over it (equal segments: one more compilation of morphojax's loop, untimed)
    divides = any(isinstance(rule.action, mc.Divide) for rule in listing.rules)
    marks = [round(k * steps / 4) for k in range(5)] if divides else [0]
    shots = listing.snapshots(marks, seed=seed, capacity=capacity)
    settings = dict(domain=listing.domain, division_limit=listing.division_limit)
    per_iteration = [numpy_seconds_per_iteration(cells_numpy.from_cells(s), listing.rules, numpy_steps, listing.dt,
                                                 **settings) for s in shots]
    if len(per_iteration) == 1:
        numpy_run = steps * per_iteration[0]
    else:  # trapezoid rule over the equally spaced marks
        numpy_run = steps * (sum(per_iteration) - (per_iteration[0] + per_iteration[-1]) / 2) / (len(per_iteration) - 1)
    return {
        "name": name, "steps": steps, "jax": jax_s, "jax_runs": runs, "compile": first - jax_s,
        "cells_start": int(shots[0].count), "cells_end": int(out.count), "capacity": int(out.capacity),
        "numpy_marks": marks, "numpy_marks_cells": [int(s.count) for s in shots],
        "numpy_per_iteration": per_iteration, "numpy_run": numpy_run, "platform": jax.devices()[0].platform,
    }


def scaling_worker(sizes, quick: bool, numpy_steps: int, numpy_max_cells: int) -> dict:
    import jax

    import cells_numpy
    import morphojax as mj
    from _harness import timeit

    steps = 20 if quick else SCALING_STEPS
    rows = []
    for target in sizes:
        shape = hex_shape(target)
        n = shape[0] * shape[1]
        for kind in ("static", "growing"):
            growing = kind == "growing"
            # room for the divisions of one run (Poisson, mean 4 an iteration) and no more:
            # every buffer, and so every iteration's cost, grows with the capacity
            capacity = n + round(1.5 * DIVISIONS_PER_ITERATION * steps) + 64 if growing else n
            cells = leopard_cells(shape, capacity)
            rules = leopard_rules(DIVISIONS_PER_ITERATION / n if growing else None)
            # the packed square at the hexagonal grid's own area per cell (2 sqrt 3), so the
            # run measures growth, not the grid's first squeeze into the thesis's 3.2
            settings = dict(domain=mj.cells.Packed(HEX_AREA) if growing else None,
                            division_limit=6 if growing else None)
            key = jax.random.key(1)

            def run():
                return jax.block_until_ready(mj.simulate_cells(None, cells, steps, 0.1, rules=rules, key=key,
                                                               **settings))

            t0 = time.perf_counter()
            out = run()
            first = time.perf_counter() - t0
            jax_s = timeit(run, min_time=1.0, min_runs=2 if quick else 3) / steps
            row = {"cells": n, "capacity": capacity, "kind": kind, "jax": jax_s, "compile": first - jax_s * steps,
                   "divisions": int(out.count) - n}
            if n <= numpy_max_cells:
                np_settings = dict(domain=mj.cells.Packed(HEX_AREA) if growing else None,
                                   division_limit=settings["division_limit"])
                row["numpy"] = numpy_seconds_per_iteration(cells_numpy.from_cells(cells), rules, numpy_steps, 0.1,
                                                           **np_settings)
            rows.append(row)
    return {"rows": rows, "steps": steps}


def profile_worker(quick: bool) -> dict:
    import equinox as eqx
    import jax

    from morphojax.cells import _step
    from morphojax.cells._neighbours import Search, find_neighbours, table_size_for
    from morphojax.cells._simulate import BUCKET_SIZE, INFLUENCE_RADIUS, MAX_NEIGHBOURS, SKIN
    from morphojax.cells._space import as_domain

    shape, capacity = (QUICK_PROFILE_GRID, QUICK_PROFILE_CAPACITY) if quick else (PROFILE_GRID, PROFILE_CAPACITY)
    cells = leopard_cells(shape, capacity)
    rules = leopard_rules(6 / int(cells.count))  # ~6 divisions: the list is rebuilt
    search = Search(radius=INFLUENCE_RADIUS + SKIN, skin=SKIN, max_neighbours=MAX_NEIGHBOURS,
                    bucket_size=BUCKET_SIZE, table_size=table_size_for(capacity))
    settings = _step.Settings(dt=jax.numpy.asarray(0.1), domain=as_domain("packed"),
                              influence_radius=INFLUENCE_RADIUS, division_limit=6, search=search)
    key = jax.random.key(2)
    neighbours = search.build(cells.position, cells.count)
    iteration = cells.step

    find = eqx.filter_jit(find_neighbours)
    contacts = eqx.filter_jit(_step.contacts)
    rules_fn = eqx.filter_jit(_step.apply_rules)
    diffusion = eqx.filter_jit(_step.diffusion_change)
    collision = eqx.filter_jit(_step.collision_offset)
    divide = eqx.filter_jit(_step.divide)
    whole = eqx.filter_jit(_step.step)
    nothing = eqx.filter_jit(lambda cells, *rest: cells.count)  # the cost of calling, in every figure

    touch = contacts(cells, neighbours, INFLUENCE_RADIUS)
    fx = rules_fn(rules, cells, touch, iteration, settings.dt, key)
    wants = fx.divide & cells.alive & (touch.count <= 6)
    parts = {
        "neighbour rebuild (find_neighbours)": lambda: find(cells.position, cells.count, search.radius,
                                                            search.max_neighbours, search.bucket_size,
                                                            search.table_size),
        "contacts": lambda: contacts(cells, neighbours, INFLUENCE_RADIUS),
        "rules (apply_rules)": lambda: rules_fn(rules, cells, touch, iteration, settings.dt, key),
        "diffusion (diffusion_change)": lambda: diffusion(cells, touch, settings.dt),
        "collision (collision_offset)": lambda: collision(cells, touch),
        "division (divide)": lambda: divide(cells, cells, wants, fx.direction, iteration),
        "whole step (_step.step)": lambda: whole(cells, neighbours, touch, rules, settings, key),
        "(a jitted call doing nothing: dispatch)": lambda: nothing(cells, neighbours, rules, settings, key),
    }
    out = {"cells": int(cells.count), "capacity": capacity, "times": {}}
    for label, fn in parts.items():
        jax.block_until_ready(fn())  # compile
        times = []
        for _ in range(20):
            t0 = time.perf_counter()
            jax.block_until_ready(fn())
            times.append(time.perf_counter() - t0)
        out["times"][label] = statistics.median(times)
    nxt, _, _ = whole(cells, neighbours, touch, rules, settings, key)
    out["divisions"] = int(nxt.count) - int(cells.count)  # > 0: the profiled step rebuilt the list
    return out


# ---- the report -----------------------------------------------------------------------------------
def listing_table(results: dict) -> str:
    rows = []
    for name, res in results.items():
        jax_s = [r["jax"] for r in res]
        steps = res[0]["steps"]
        per_np = [r["numpy_run"] / r["steps"] for r in res]
        cells_end = median([r["cells_end"] for r in res])
        rows.append([
            f"{name} (Listing {LISTING[name]}), {steps:,} iterations",
            f"{res[0]['cells_start']:,} -> {cells_end:,.0f} (capacity {res[0]['capacity']:,})",
            f"{median(jax_s):.2f}", f"{median([r['compile'] for r in res]):.1f}",
            f"{median(jax_s) / steps * 1e3:.3f}", f"{median(per_np) * 1e3:.2f}",
            f"{median([r['numpy_run'] / r['jax'] for r in res]):.1f}x",
            f"{THESIS_SECONDS[name]:.1f} ({THESIS_CELLS[name]} cells)",
            f"{median([THESIS_SECONDS[name] / THESIS_ITERATIONS[name] / (r['jax'] / r['steps']) for r in res]):.2f}x",
        ])
    return markdown_table(["run", "cells", "morphojax (s, compiled)", "compile (s)", "morphojax ms / iteration",
                           "NumPy port ms / iteration", "speed-up over NumPy", "thesis C++ (s, i7-4500U, 1 core)",
                           "speed-up over thesis (per iteration)"], rows)


def scaling_table(res: list[dict]) -> str:
    rows = []
    for i, first in enumerate(res[0]["rows"]):
        per = [r["rows"][i] for r in res]
        jax_ms = median([p["jax"] for p in per]) * 1e3
        numpy = [p for p in per if "numpy" in p]
        row = [f"{first['cells']:,}", first["kind"], f"{first['capacity']:,}", f"{jax_ms:.3f}",
               f"{jax_ms * 1e3 / first['cells']:.3f}",
               f"{median([p['compile'] for p in per]):.1f}", f"{median([p['divisions'] for p in per]):.0f}"]
        if numpy:
            row += [f"{median([p['numpy'] for p in numpy]) * 1e3:.2f}",
                    f"{median([p['numpy'] / p['jax'] for p in numpy]):.1f}x"]
        else:
            row += ["(skipped)", ""]
        rows.append(row)
    return markdown_table(["cells (hex grid)", "run", "capacity", "morphojax ms / iteration", "us / cell / iteration",
                           "compile (s)", f"divisions in {res[0]['steps']} iterations", "NumPy port ms / iteration",
                           "speed-up over NumPy"], rows)


def profile_table(res: list[dict]) -> str:
    labels = list(res[0]["times"])
    whole = median([r["times"]["whole step (_step.step)"] for r in res])
    rows = []
    for label in labels:
        t = median([r["times"][label] for r in res])
        rows.append([label, f"{t * 1e3:.3f}", f"{100 * t / whole:.0f}%"])
    six = [label for label in labels if not label.startswith(("whole", "("))]
    parts = sum(median([r["times"][label] for r in res]) for label in six)
    rows.append(["sum of the six parts (each paying the dispatch)", f"{parts * 1e3:.3f}",
                 f"{100 * parts / whole:.0f}%"])
    return markdown_table(["part of one growing iteration", "ms (median of 20 calls)", "of the whole step"], rows)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("task", nargs="*", help=argparse.SUPPRESS)  # a worker's task: listing NAME, scaling N..., profile
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--quick", action="store_true", help="tiny sizes, one process each; writes no results file")
    p.add_argument("--only", nargs="+", choices=("leopard", "moray", "scaling", "profile"),
                   default=["leopard", "moray", "scaling", "profile"])
    p.add_argument("--max-cells", type=int, default=100_000, help="largest grid of the scaling runs")
    p.add_argument("--numpy-steps", type=int, default=200, help="iterations per timing of the NumPy port")
    p.add_argument("--numpy-max-cells", type=int, default=30_000, help="no NumPy baseline above this many cells")
    p.add_argument("--leopard-capacity", type=int, default=None,
                   help="a fixed cell capacity for the leopard's run (default: Listing.run's, which grows "
                        "with the tissue; every iteration costs in proportion to it)")
    args = p.parse_args()
    numpy_steps = 5 if args.quick else args.numpy_steps
    quick = ["--quick"] if args.quick else []
    if args.worker:
        task, *rest = args.task
        if task == "listing":
            capacity = args.leopard_capacity if rest[0] == "leopard" else None
            out = listing_worker(rest[0], args.quick, numpy_steps, capacity)
        elif task == "scaling":
            out = scaling_worker([int(n) for n in rest], args.quick, numpy_steps, args.numpy_max_cells)
        else:
            out = profile_worker(args.quick)
        print(json.dumps(out))
        return

    started = time.perf_counter()
    repeats = 1 if args.quick else args.repeats
    script = HERE / "bench_cells.py"
    common = [*quick, "--numpy-steps", str(numpy_steps), "--numpy-max-cells", str(args.numpy_max_cells)]
    if args.leopard_capacity is not None:
        common += ["--leopard-capacity", str(args.leopard_capacity)]
    load_before = os.getloadavg()
    check = check_port()
    print(f"NumPy port check: {check}", file=sys.stderr)
    sections = []
    listings = {}
    for name in ("leopard", "moray"):
        if name in args.only:
            listings[name] = in_fresh_processes(script, [*common, "listing", name], repeats)
            print(f"{name}: {listings[name]}", file=sys.stderr)
    if listings:
        sections.append("## The thesis's timed listings (Table A.1)\n\n" + listing_table(listings))
    if "scaling" in args.only:
        sizes = [n for n in (QUICK_SCALING_CELLS if args.quick else SCALING_CELLS) if n <= args.max_cells]
        res = in_fresh_processes(script, [*common, "scaling", *map(str, sizes)], repeats)
        print(f"scaling: {res}", file=sys.stderr)
        sections.append("## Time per iteration against the number of cells\n\n" + scaling_table(res))
    if "profile" in args.only:
        res = in_fresh_processes(script, [*common, "profile"], repeats)
        print(f"profile: {res}", file=sys.stderr)
        sections.append(f"## One growing iteration, {res[0]['cells']:,} cells in a capacity of "
                        f"{res[0]['capacity']:,} ({median([r['divisions'] for r in res]):.0f} divisions)\n\n"
                        + profile_table(res))
    load_after = os.getloadavg()
    footer = (f"machine: {machine()}; load average before {load_before[0]:.1f}, after {load_after[0]:.1f}; "
              f"medians of {repeats} fresh processes; NumPy port check: {check}; "
              f"benchmark wall time {time.perf_counter() - started:.0f} s")
    report = "\n\n".join(sections + [footer])
    print(report)
    if not args.quick:
        command = "python benchmarks/bench_cells.py " + " ".join(sys.argv[1:])
        RESULTS.write_text(f"# The off-lattice cell simulator: speed\n\n`{command.strip()}`\n\n{report}\n")


if __name__ == "__main__":
    main()

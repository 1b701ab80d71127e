"""The off-lattice cell simulator (thesis ch. 4) against the thesis's C++ and a NumPy port.

The thesis's Table A.1 times its C++ simulator on one core of a 1.8 GHz Core i7-4500U. Every
row with a shipped listing runs here (`--only rows`, or `leopard` / `moray` alone) with
`Listing.run` (compiled; the compile time, the first run less the median of the re-runs, is
reported apart) for the thesis's own number of iterations, at `Listing.run`'s default
capacity, which follows the tissue (a piece of the run that outgrows it runs again with
1.5x the room). The rows without a listing (5.3, 5.11-5.13, 7.1, 7.4: lattice experiments,
automata, or listings the thesis does not print) are named and skipped; 7.13 (giraffe) and
7.15 (nudibranch) run their listings printed in section 7.3 on a torus (`create sqr_grid
100 100 wrap`).
Table A.1 swaps the cell-count and iteration columns of rows 5.1, 5.2, 5.3, 5.11, 5.12 and
5.13 (Fig. 5.1 is 225 cells for 1,000 iterations, as its listing places them); the table
here quotes them the right way round. Listing A.18 as printed sets only 9 of its 32 seed
cells (the other 23 are named in a comment, "omitted for brevity"); the benchmark restores
them (`set cell N chemical V conc 10` lines), as a preset would, and runs it with seed 0.
The moray runs as published (`use seed 1`). The speed-up over the thesis compares seconds
for the same number of iterations.

The NumPy port in benchmarks/cells_numpy.py (cKDTree pairs, np.add.at, rebuilt every
iteration) is checked once to agree with morphojax after 10 iterations of a small run (and
4 with divisions) to 1e-4, and timed in the scaling runs up to `--numpy-max-cells`.

Then, per-iteration times against the number of cells (hex grids of ~1k to 100k cells):
a static reaction-diffusion run (Bard's reaction, no division, no domain: the neighbour
list is never touched) and a growing one (the leopard's rules, a domain packed at the hex
grid's own 2 sqrt 3 per cell, division by chance 4 / cells: children are patched into the
list and their pushed neighbours with them; capacity for 1.5 times the expected divisions),
plotted as the cost per cell and iteration (bench_cells_scaling.svg); and a profile of one
growing iteration at the leopard's size (6,240 cells, capacity 6,600): each part of
`_step.step` jitted and timed alone (median of 20 calls; every figure includes the cost of
calling a jitted function, timed apart), with `--baseline-tree DIR` the same worker also on
an older morphojax (DIR holds its `morphojax/`; `git archive REV morphojax | tar -x -C DIR`)
for a before / after table. Medians over fresh processes (_harness.py).

    python benchmarks/bench_cells.py [--repeats 3] [--quick] [--only rows leopard moray scaling profile]
                                     [--rows 5.14 6.6 ...] [--row-repeats 1] [--max-cells 100000]
                                     [--numpy-steps 200] [--numpy-max-cells 30000] [--baseline-tree DIR]

`--quick` runs tiny sizes (seconds; for testing) and writes nothing; otherwise the tables
go to stdout and to benchmarks/results/bench_cells.md (sections not run keep their text;
the rows' measurements are kept in bench_cells_rows.json, so rows run in separate calls
share one table).
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
PLOT = HERE / "results" / "bench_cells_scaling.svg"
ROWS_JSON = HERE / "results" / "bench_cells_rows.json"  # every row's processes, kept between calls
HEX_AREA = 2 * math.sqrt(3)  # area per cell of a hexagonal grid of spacing 2
# Table A.1: figure -> (listing, cells, iterations, seconds), cells and iterations of rows
# 5.1 and 5.2 the right way round (the table swaps them)
TABLE_A1 = {
    "5.1": ("fig5.1", "225", 1_000, 0.627), "5.2": ("fig5.2", "961", 4_000, 1.586),
    "5.14": ("A.1", "10,000", 10_000, 71.918), "5.15": ("A.2", "10,000", 18_000, 125.158),
    "6.1": ("A.3", "10,400", 26_000, 86.066), "6.2": ("A.4", "2,500", 30_000, 25.427),
    "6.3": ("A.5", "5,001", 10_000, 22.159), "6.4": ("A.6", "4,064", 16_000, 28.392),
    "6.5": ("A.7", "6,432", 18_000, 29.709), "6.6": ("A.8", "2,058", 10_000, 5.502),
    "6.7": ("A.9", "5,248", 15_000, 37.292), "6.8": ("A.10", "5,248", 15_000, 36.159),
    "6.10": ("A.11", "5,248", 15_000, 38.599), "7.2": ("A.12", "225", 72, 0.985),
    "7.3": ("A.13", "10,000", 3_200, 2.919), "7.7": ("A.14", "10,000", 2_000, 3.072),
    "7.8": ("A.15", "10,000", 2_000, 3.094), "7.13": ("fig7.13", "10,000", 38_000, 54.722),
    "7.15": ("fig7.15", "10,000", 3_000, 4.801), "7.16": ("A.16", "10,000", 8_000, 8.135),
    "7.18": ("A.17", "20,000", 5_000, 21.122), "7.21": ("A.18", "2,900 -> 6,228", 14_000, 22.298),
}
NO_LISTING = {  # Table A.1 rows that run on no shipped listing, and why
    "5.3": "Turing test on a square grid: the thesis prints no listing",
    "5.11": "spots: no listing printed; the lattice presets run it",
    "5.12": "transition: no listing printed; the lattice presets run it",
    "5.13": "anisotropy: no listing printed; the lattice presets run it",
    "7.1": "Game of Life: an automaton (morphojax.automata), not the cell simulator",
    "7.4": "cow: Young's automaton on a lattice (morphojax.automata)",
}
NAMED = {"leopard": "7.21", "moray": "7.18"}
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


def listing_for(row: str):
    """The listing of a Table A.1 row (the leopard's with its seeds restored)."""
    import morphojax as mj

    return leopard_listing() if row == "7.21" else mj.load_listing(TABLE_A1[row][0])


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


def listing_worker(row: str, quick: bool, reruns: int) -> dict:
    """One Table A.1 row: the listing run for the thesis's iterations, compiled, `reruns` times."""
    import jax

    listing = listing_for(row)
    steps = QUICK_LISTING_STEPS if quick else TABLE_A1[row][2]
    seed = 0 if row == "7.21" else None  # the others keep their own `use seed` (else 0)

    def run():
        out = listing.run(seed=seed, steps=steps)  # syncs: it reads out.ok
        jax.block_until_ready(out.concentration)
        return out

    t0, c0 = time.perf_counter(), time.process_time()
    first_out = run()  # compiles (every capacity and room the run grows through)
    first, first_cpu = time.perf_counter() - t0, time.process_time() - c0
    runs, cpu = [], []
    for _ in range(reruns):
        t0, c0 = time.perf_counter(), time.process_time()
        out = run()
        runs.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    jax_s = statistics.median(runs)
    return {
        "row": row, "steps": steps, "jax": jax_s, "jax_runs": runs, "cpu": statistics.median(cpu),
        "compile": first - jax_s, "first": first, "first_cpu": first_cpu,
        "cells_start": int(listing.prepattern(jax.random.split(jax.random.key(seed if seed is not None else
                                                                                 (listing.seed or 0)))[0]).count),
        "cells_end": int(out.count), "cells_end_first": int(first_out.count), "capacity": int(out.capacity),
        "platform": jax.devices()[0].platform,
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
    from morphojax.cells._neighbours import Search, find_neighbours, patch, table_size_for
    from morphojax.cells._simulate import BUCKET_SIZE, INFLUENCE_RADIUS, MAX_NEIGHBOURS, SKIN
    from morphojax.cells._space import as_domain

    shape, capacity = (QUICK_PROFILE_GRID, QUICK_PROFILE_CAPACITY) if quick else (PROFILE_GRID, PROFILE_CAPACITY)
    cells = leopard_cells(shape, capacity)
    rules = leopard_rules(6 / int(cells.count))  # ~6 divisions: the list must take them in
    search = Search(radius=INFLUENCE_RADIUS + SKIN, skin=SKIN, max_neighbours=MAX_NEIGHBOURS,
                    bucket_size=BUCKET_SIZE, table_size=table_size_for(capacity))
    settings = _step.Settings(dt=jax.numpy.asarray(0.1), domain=as_domain("packed"),
                              influence_radius=INFLUENCE_RADIUS, division_limit=6, search=search)
    key = jax.random.key(2)
    neighbours = search.build(cells.position, cells.count)
    iteration = cells.step

    find = eqx.filter_jit(find_neighbours)
    update = eqx.filter_jit(lambda search, *args: search.update(*args))
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
    # the cells after one iteration with its divisions, before their neighbour list follows
    born = divide(cells, cells, wants, fx.direction, iteration)
    # 64 cells spread over the tissue pushed 0.2 (more than half the skin): a patch of the
    # largest size, the most common one in a growing leopard (33-64 movers in a third of
    # its iterations)
    count = int(cells.count)
    pushed = jax.numpy.zeros(capacity, bool).at[jax.numpy.arange(64) * (count // 64)].set(True)
    moved = cells.position.at[:, 0].add(jax.numpy.where(pushed, 0.2, 0.0))
    patch64 = eqx.filter_jit(patch)
    parts = {
        "neighbour update after the divisions (Search.update)": lambda: update(search, neighbours, born.position,
                                                                               born.count),
        "patch of 64 movers (patch)": lambda: patch64(neighbours, pushed, moved, cells.count, search.radius, 64),
        "full rebuild (find_neighbours)": lambda: find(cells.position, cells.count, search.radius,
                                                       search.max_neighbours, search.bucket_size,
                                                       search.table_size),
        "contacts (round 5 on: with the collisions' sums)": lambda: contacts(cells, neighbours, INFLUENCE_RADIUS),
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
    out["divisions"] = int(born.count) - int(cells.count)  # > 0: the list had children to take in
    return out


# ---- the report -----------------------------------------------------------------------------------
def rows_table(results: dict) -> str:
    rows = []
    for row, res in results.items():
        listing, cells, iterations, seconds = TABLE_A1[row]
        jax_s = median([r["jax"] for r in res])
        steps = res[0]["steps"]
        rows.append([
            f"{row} (Listing {listing})", cells, f"{iterations:,}", f"{seconds:.3f}",
            f"{res[0]['cells_start']:,} -> {median([r['cells_end'] for r in res]):,.0f}", f"{steps:,}",
            f"{jax_s:.2f}", f"{median([r['cpu'] for r in res]):.2f}", f"{median([r['compile'] for r in res]):.1f}",
            f"{seconds / iterations / (jax_s / steps):.2f}x", str(len(res)),
        ])
    for row, why in NO_LISTING.items():
        rows.append([row, "", "", "", "", "", "", "", "", f"no cell run: {why}", ""])
    return markdown_table(["Table A.1 row", "thesis cells", "thesis iterations", "thesis C++ (s, i7-4500U, 1 core)",
                           "morphojax cells", "iterations", "morphojax (s, compiled)", "CPU (s, both cores)",
                           "compile (s)", "speed-up over thesis", "processes"], rows)


def scaling_table(res: list[dict]) -> str:
    rows = []
    for i, first in enumerate(res[0]["rows"]):
        per = [r["rows"][i] for r in res]
        jax_ms = median([p["jax"] for p in per]) * 1e3
        numpy = [p for p in per if "numpy" in p]
        row = [f"{first['cells']:,}", first["kind"], f"{first['capacity']:,}", f"{jax_ms:.3f}",
               f"{jax_ms * 1e3 / first['cells']:.3f}",
               f"{median([p['compile'] for p in per]):.1f}", f"{median([p['divisions'] for p in per]):.0f}"]
        if first["kind"] == "growing":
            static = median([r["rows"][i - 1]["jax"] for r in res])
            row.append(f"{median([p['jax'] for p in per]) / static:.2f}x")
        else:
            row.append("")
        if numpy:
            row += [f"{median([p['numpy'] for p in numpy]) * 1e3:.2f}",
                    f"{median([p['numpy'] / p['jax'] for p in numpy]):.1f}x"]
        else:
            row += ["(skipped)", ""]
        rows.append(row)
    return markdown_table(["cells (hex grid)", "run", "capacity", "morphojax ms / iteration", "us / cell / iteration",
                           "compile (s)", f"divisions in {res[0]['steps']} iterations", "growing / static",
                           "NumPy port ms / iteration", "speed-up over NumPy"], rows)


def scaling_plot(res: list[dict]) -> str:
    """An SVG of us per cell and iteration against cells (log-log), static and growing."""
    series = {}
    for i, first in enumerate(res[0]["rows"]):
        us = median([r["rows"][i]["jax"] for r in res]) * 1e6 / first["cells"]
        series.setdefault(first["kind"], []).append((first["cells"], us))
    width, height, pad = 560, 360, 60
    xs = [x for pts in series.values() for x, _ in pts]
    ys = [y for pts in series.values() for _, y in pts]
    lx0, lx1 = math.log10(min(xs)) - 0.1, math.log10(max(xs)) + 0.1
    ly0, ly1 = math.log10(min(ys)) - 0.15, math.log10(max(ys)) + 0.15

    def at(x, y):
        return (pad + (math.log10(x) - lx0) / (lx1 - lx0) * (width - 1.5 * pad),
                height - pad - (math.log10(y) - ly0) / (ly1 - ly0) * (height - 1.5 * pad))

    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" '
             f'font-size="12"><rect width="100%" height="100%" fill="white"/>',
             f'<line x1="{pad}" y1="{height - pad}" x2="{width - pad / 2}" y2="{height - pad}" stroke="black"/>',
             f'<line x1="{pad}" y1="{pad / 2}" x2="{pad}" y2="{height - pad}" stroke="black"/>',
             f'<text x="{width / 2}" y="{height - 15}" text-anchor="middle">cells (log)</text>',
             f'<text x="15" y="{height / 2}" transform="rotate(-90 15 {height / 2})" text-anchor="middle">'
             'us per cell and iteration (log)</text>']
    for x in sorted(set(xs)):
        px, _ = at(x, 10 ** ly0)
        parts.append(f'<text x="{px:.1f}" y="{height - pad + 16}" text-anchor="middle">{x:,}</text>')
    for e in range(math.floor(ly0 * 4), math.ceil(ly1 * 4) + 1):
        y = 10 ** (e / 4)
        if ly0 <= math.log10(y) <= ly1:
            _, py = at(10 ** lx0, y)
            parts.append(f'<text x="{pad - 5}" y="{py + 4:.1f}" text-anchor="end">{y:.3g}</text>')
            parts.append(f'<line x1="{pad}" y1="{py:.1f}" x2="{width - pad / 2}" y2="{py:.1f}" stroke="#ddd"/>')
    for (kind, pts), colour in zip(sorted(series.items()), ("#c0392b", "#2c3e50")):
        path = " ".join(f"{a:.1f},{b:.1f}" for a, b in (at(x, y) for x, y in pts))
        parts.append(f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="2"/>')
        for x, y in pts:
            px, py = at(x, y)
            parts.append(f'<circle cx="{px:.1f}" cy="{py:.1f}" r="3" fill="{colour}"/>')
        px, py = at(*pts[-1])
        parts.append(f'<text x="{px - 5:.1f}" y="{py - 8:.1f}" text-anchor="end" fill="{colour}">{kind}</text>')
    return "\n".join(parts + ["</svg>"]) + "\n"


def profile_table(res: list[dict], before: list[dict] | None = None) -> str:
    labels = list(res[0]["times"])
    if before:
        labels += [label for label in before[0]["times"] if label not in labels]

    def figure(results, label):
        got = [r["times"][label] for r in results if label in r["times"]]
        return median(got) if got else None

    rows = []
    for label in labels:
        row = [label]
        for results in ([before] if before else []) + [res]:
            t = figure(results, label)
            whole = figure(results, "whole step (_step.step)")
            row += ["" if t is None else f"{t * 1e3:.3f}", "" if t is None else f"{100 * t / whole:.0f}%"]
        rows.append(row)
    headers = ["part of one growing iteration"]
    if before:
        headers += ["before: ms (median of 20 calls)", "before: of the whole step"]
    headers += ["ms (median of 20 calls)", "of the whole step"]
    return markdown_table(headers, rows)


def in_processes_with(tree, script, args, repeats) -> list[dict]:
    """`in_fresh_processes`, importing morphojax from `tree` (an older copy) when given."""
    return in_fresh_processes(script, args, repeats, tree)


def _replace_section(text: str, title: str, body: str) -> str:
    """`text` (a results file) with the section `## title...` replaced by `body` (appended if absent)."""
    lines = text.split("\n## ")
    for i, chunk in enumerate(lines):
        if chunk.startswith(title):
            lines[i] = body[3:] if body.startswith("## ") else body
            return "\n## ".join(lines)
    return text.rstrip("\n") + "\n\n" + body


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("task", nargs="*", help=argparse.SUPPRESS)  # a worker's task: row FIG, scaling N..., profile
    p.add_argument("--repeats", type=int, default=3, help="processes for the leopard, the moray, scaling, profile")
    p.add_argument("--row-repeats", type=int, default=1, help="processes for the other rows of Table A.1")
    p.add_argument("--reruns", type=int, default=RERUNS, help="compiled re-runs per process (leopard, moray)")
    p.add_argument("--quick", action="store_true", help="tiny sizes, one process each; writes no results file")
    p.add_argument("--only", nargs="+", choices=("rows", "leopard", "moray", "scaling", "profile"),
                   default=["rows", "scaling", "profile"])
    p.add_argument("--rows", nargs="+", default=None, help="Table A.1 rows to run (default: every one with a listing)")
    p.add_argument("--max-cells", type=int, default=100_000, help="largest grid of the scaling runs")
    p.add_argument("--numpy-steps", type=int, default=200, help="iterations per timing of the NumPy port")
    p.add_argument("--numpy-max-cells", type=int, default=30_000, help="no NumPy baseline above this many cells")
    p.add_argument("--baseline-tree", default=None, help="a folder holding an older morphojax/ to profile too")
    args = p.parse_args()
    numpy_steps = 5 if args.quick else args.numpy_steps
    quick = ["--quick"] if args.quick else []
    if args.worker:
        task, *rest = args.task
        if task == "row":
            out = listing_worker(rest[0], args.quick, 1 if args.quick else int(rest[1]))
        elif task == "scaling":
            out = scaling_worker([int(n) for n in rest], args.quick, numpy_steps, args.numpy_max_cells)
        else:
            out = profile_worker(args.quick)
        print(json.dumps(out))
        return

    started = time.perf_counter()
    script = HERE / "bench_cells.py"
    common = [*quick, "--numpy-steps", str(numpy_steps), "--numpy-max-cells", str(args.numpy_max_cells)]
    load_before = os.getloadavg()
    check = check_port()
    print(f"NumPy port check: {check}", file=sys.stderr)
    sections = []
    wanted = list(args.rows or (TABLE_A1 if "rows" in args.only else []))
    wanted += [NAMED[n] for n in ("leopard", "moray") if n in args.only and NAMED[n] not in wanted]
    rows = {}
    for row in wanted:
        if row not in TABLE_A1:
            raise SystemExit(f"--rows: {row!r} is not a Table A.1 row with a listing ({', '.join(TABLE_A1)})")
        named = row in NAMED.values()
        repeats = 1 if args.quick else (args.repeats if named else args.row_repeats)
        reruns = args.reruns if named else 1
        rows[row] = in_fresh_processes(script, [*common, "row", row, str(reruns)], repeats)
        print(f"{row}: {rows[row]}", file=sys.stderr)
    if rows and not args.quick:  # rows measured before (other rows, other calls) stay in the table
        kept = json.loads(ROWS_JSON.read_text()) if ROWS_JSON.exists() else {}
        kept.update(rows)
        ROWS_JSON.write_text(json.dumps(kept, indent=1) + "\n")
        rows = {row: kept[row] for row in TABLE_A1 if row in kept}
    if rows:
        sections.append(("The thesis's timed listings (Table A.1)",
                         "## The thesis's timed listings (Table A.1)\n\n" + rows_table(rows)))
    if "scaling" in args.only:
        sizes = [n for n in (QUICK_SCALING_CELLS if args.quick else SCALING_CELLS) if n <= args.max_cells]
        res = in_fresh_processes(script, [*common, "scaling", *map(str, sizes)], 1 if args.quick else args.repeats)
        print(f"scaling: {res}", file=sys.stderr)
        if not args.quick:
            PLOT.write_text(scaling_plot(res))
        sections.append(("Time per iteration against the number of cells",
                         "## Time per iteration against the number of cells\n\n"
                         f"![cost per cell and iteration]({PLOT.name})\n\n" + scaling_table(res)))
    if "profile" in args.only:
        repeats = 1 if args.quick else args.repeats
        res = in_fresh_processes(script, [*common, "profile"], repeats)
        before = (in_processes_with(args.baseline_tree, script, [*common, "profile"], repeats)
                  if args.baseline_tree else None)
        print(f"profile: {res} before: {before}", file=sys.stderr)
        title = "One growing iteration"
        sections.append((title, f"## {title}, {res[0]['cells']:,} cells in a capacity of {res[0]['capacity']:,} "
                         f"({median([r['divisions'] for r in res]):.0f} divisions)\n\n"
                         + (f"before: morphojax from {args.baseline_tree}\n\n" if before else "")
                         + profile_table(res, before)))
    load_after = os.getloadavg()
    footer = (f"machine: {machine()}; load average before {load_before[0]:.1f}, after {load_after[0]:.1f} "
              f"(the 2 cores are shared: CPU seconds are steadier than wall seconds); NumPy port check: {check}; "
              f"benchmark wall time {time.perf_counter() - started:.0f} s")
    command = "python benchmarks/bench_cells.py " + " ".join(sys.argv[1:])
    report = "\n\n".join([body for _, body in sections] + [f"`{command.strip()}`: {footer}"])
    print(report)
    if not args.quick:
        text = RESULTS.read_text() if RESULTS.exists() else "# The off-lattice cell simulator: speed\n"
        for title, body in sections:
            text = _replace_section(text, title, body + f"\n\n`{command.strip()}`: {footer}\n")
        RESULTS.write_text(text)


if __name__ == "__main__":
    main()

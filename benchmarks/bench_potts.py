"""Copy attempts per second of the cellular Potts model against a straightforward NumPy port.

Paper 003's runs (section III.B): the 100x100 blob of radius 40 cut into cells 5 wide,
`Potts.paper003(j_like)` (T 10, V 25, lambda 2, order 2). morphojax runs its compiled
parallel sub-lattice sweeps (`Potts.run`, 300 MCS per timed call, compilation excluded);
the baseline is tests/potts_oracle.py's sequential Metropolis (random site, random
neighbour, the energy change from the site's neighbourhood, a Python loop with NumPy
arrays: the straightforward port), 2 MCS per timed call, started from the same blob in the
same process. One MCS is 10,000 attempts for both. Every figure is the median over fresh
processes (_harness.py); the full paper run (3,000 MCS) is timed once per process too.

    python benchmarks/bench_potts.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from _harness import HERE, in_fresh_processes, machine, markdown_table, median, timeit

SIZE, RADIUS, WIDTH = 100, 40, 5
J_VALUES = (3.0, 15.0)  # paper 003 Fig. 11: stripes, spots


def worker() -> dict:
    import jax
    import numpy as np

    import morphojax as mj
    import potts_oracle as oracle

    state = mj.potts_blob((SIZE, SIZE), RADIUS, WIDTH, key=jax.random.key(0))
    ids, types, _ = state.arrays()
    sites = SIZE * SIZE
    out = {}
    for j in J_VALUES:
        model = mj.Potts.paper003(j)
        warm = model.run(state, 300, jax.random.key(1))  # compile; start the timed runs from a relaxed lattice
        jax.block_until_ready(warm.ids)
        run = lambda: jax.block_until_ready(model.run(warm, 300, jax.random.key(2)).ids)  # noqa: E731
        out[f"jax {j:g}"] = 300 * sites / timeit(run, min_time=2.0)
        warm_ids = np.asarray(warm.ids)
        rng = np.random.default_rng(0)
        numpy_run = lambda: oracle.metropolis(warm_ids, types, np.asarray(model.J), 10.0, 25.0, 2.0, 2, rng)  # noqa: E731
        out[f"numpy {j:g}"] = 2 * sites / timeit(numpy_run, min_time=2.0, min_runs=2)
        t0 = time.perf_counter()
        full = model.run(state, 3000, jax.random.key(3))
        jax.block_until_ready(full.ids)
        out[f"paper run {j:g}"] = time.perf_counter() - t0  # the loop compiled above serves every MCS count
    return out


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--worker", action="store_true")
    p.add_argument("--repeats", type=int, default=5)
    args = p.parse_args()
    if args.worker:
        print(json.dumps(worker()))
        return
    import os

    load_before = os.getloadavg()
    res = in_fresh_processes(HERE / "bench_potts.py", [], args.repeats)
    load_after = os.getloadavg()
    print(res, file=sys.stderr)
    rows = []
    for j in J_VALUES:
        fast = [r[f"jax {j:g}"] for r in res]
        slow = [r[f"numpy {j:g}"] for r in res]
        ratio = [a / b for a, b in zip(fast, slow)]
        rows.append([f"J(like) = {j:g}", f"{median(fast) / 1e6:.2f}", f"{median(slow) / 1e3:.1f}",
                     f"{median(ratio):.0f}x", f"{median([r[f'paper run {j:g}'] for r in res]):.1f}"])
    table = markdown_table(["paper 003 model, 100x100 blob", "morphojax (M attempts/s)", "NumPy port (k attempts/s)",
                            "speed-up", "paper run, 3,000 MCS (s)"], rows)
    print(table)
    print(f"machine: {machine()}; load average before {load_before[0]:.1f}, after {load_after[0]:.1f}; "
          f"{args.repeats} fresh processes")


if __name__ == "__main__":
    main()

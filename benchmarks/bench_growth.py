"""Growing domains: morphojax against a straightforward NumPy port of the same experiment.

Two experiments of the leopard paper, timed in the same worker process:
- `whipray` (Fig. 9): 4,000 static steps at 100x100 (r = 30), then 10,000 steps growing to
  200x200 at 2.5 expansions per unit time (r = 8);
- the leopard's development phase (Figs. 15-16): A, B (Turing r = 40, s = 5, Lb = 2) and C
  (reinforcement) on 130x130 growing to 370x370 in 12,000 steps (no-flux).
The NumPy ports (benchmarks/numpy_port.py) are vectorised NumPy with arrays sized to the
current lattice and `take_along_axis` for the expansions; the Laplacian either by `np.roll`
(the straightforward form) or from slices of a padded copy (hand-vectorised, faster).
morphojax is timed compiled (the figure a user re-running an experiment sees: the median of
three re-runs in the process) and the compile time is reported apart; each NumPy port runs
once. Medians over fresh processes.

    python benchmarks/bench_growth.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import numpy as np

from _harness import HERE, in_fresh_processes, machine, markdown_table, median

PAPER_SECONDS = {"whipray": 14.45, "leopard-development": 45.52 + 15.17}  # Table 1: Figs. 9, 15 + 16


def _whipray_jax():
    import jax

    import morphojax as mj

    exp = mj.preset("whipray")
    return lambda: jax.block_until_ready(mj.run_experiment(exp, seed=0).state.fields)


def _leopard_dev_jax():
    import jax

    import morphojax as mj

    dev = mj.preset("leopard").phases[1]
    start = mj.paper_state(jax.random.key(0), (130, 130))
    start = mj.State.from_arrays(start.arrays(), names=("a", "b"))
    exp = mj.Experiment("leopard-development", mj.Initial("paper", (130, 130)), phases=(dev,), show="b")
    return lambda: jax.block_until_ready(mj.run_experiment(exp, seed=0).state.fields)


def worker(name: str) -> dict:
    import numpy_port

    run = {"whipray": _whipray_jax, "leopard-development": _leopard_dev_jax}[name]()
    t0 = time.perf_counter()
    run()  # includes compilation
    first = time.perf_counter() - t0
    runs = []
    for _ in range(3):  # re-runs of the compiled experiment: the first is often slower (warm-up)
        t0 = time.perf_counter()
        run()
        runs.append(time.perf_counter() - t0)
    jax_s = statistics.median(runs)
    out = {"name": name, "jax": jax_s, "jax_runs": runs, "compile": first - jax_s}
    for kind, lap in numpy_port.LAPLACIANS.items():
        t0 = time.perf_counter()
        if name == "whipray":
            numpy_port.whipray(lap=lap)
        else:
            rng = np.random.default_rng(0)
            a = np.full((130, 130), 4.0, np.float32)
            b = rng.uniform(4.0, 5.0, (130, 130)).astype(np.float32)
            numpy_port.leopard_development(a, b, lap=lap)
        out[f"numpy_{kind}"] = time.perf_counter() - t0
    return out


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--worker", action="store_true")
    p.add_argument("name", nargs="?")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--only", nargs="*", default=["whipray", "leopard-development"])
    args = p.parse_args()
    if args.worker:
        print(json.dumps(worker(args.name)))
        return
    rows = []
    for name in args.only:
        res = in_fresh_processes(HERE / "bench_growth.py", [name], args.repeats)
        print(f"{name}: {res}", file=sys.stderr)
        row = [name, f"{median([r['jax'] for r in res]):.2f}", f"{median([r['compile'] for r in res]):.1f}"]
        for kind in ("roll", "slices"):
            ratios = [r[f"numpy_{kind}"] / r["jax"] for r in res]
            row += [f"{median([r[f'numpy_{kind}'] for r in res]):.1f}", f"{median(ratios):.1f}x (min {min(ratios):.1f}x)"]
        row.append(f"{PAPER_SECONDS[name]:.1f}")
        rows.append(row)
    print(f"medians of {args.repeats} processes; {machine()}\n")
    print(markdown_table(["experiment", "morphojax (s, compiled)", "compile (s)", "NumPy np.roll port (s)", "ratio",
                          "NumPy padded-slices port (s)", "ratio", "paper Table 1 (s, their NumPy/SciPy, i3-9100F)"],
                         rows))


if __name__ == "__main__":
    main()

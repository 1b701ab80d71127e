"""Single-run speed of the bounded Turing model: morphojax against NumPy, in the same process.

Reports Mcell-steps/s (cells x steps / s) for square lattices (128, 250, 256, 512) and the
ratio against two NumPy baselines timed in the same worker process:
- the test oracle (tests/oracle.py: scipy.ndimage.correlate does the stencil), and
- a hand-vectorised NumPy step (benchmarks/numpy_port.py: slices of a padded copy).
Each figure is the median over several fresh processes (see _harness.py).

    python benchmarks/bench_core.py [--repeats 5] [--sizes 128 250 256 512]
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from _harness import HERE, in_fresh_processes, machine, markdown_table, median, timeit

R, S, DT = 12.0, 3.0, 0.008  # a labyrinth (Fig. 4, r = 12) with B >= 0


def worker(n: int, steps: int) -> dict:
    import jax

    import morphojax as mj
    import numpy_port
    import oracle

    state = mj.paper_state(jax.random.key(0), (n, n))
    model = mj.Turing(R, S)
    a0, b0 = (np.asarray(x) for x in state.arrays())

    run = lambda: jax.block_until_ready(mj.simulate(model, state, steps=steps, dt=DT).fields)  # noqa: E731
    run()  # compile
    t_jax = timeit(run, min_time=1.0) / steps

    def oracle_steps(k):
        a, b = a0.astype(np.float32), b0.astype(np.float32)
        for _ in range(k):
            da, db = oracle.turing_rates(a, b, R, S, dtype=np.float32)  # the run's dtype
            a, b = np.maximum(a + DT * da, 0), np.maximum(b + DT * db, 0)

    k_np = max(3, min(200, int(2e6 / (n * n))))
    t_oracle = timeit(lambda: oracle_steps(k_np), min_time=1.0) / k_np

    def port_steps(k):
        a, b = a0, b0
        for _ in range(k):
            a, b = numpy_port.turing_step(a, b, R, S, DT, (0.0, 0.0), (np.inf, np.inf), "wrap")

    t_port = timeit(lambda: port_steps(k_np), min_time=1.0) / k_np
    cells = n * n
    return {"n": n, "jax": cells / t_jax / 1e6, "oracle": cells / t_oracle / 1e6, "numpy": cells / t_port / 1e6}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--worker", action="store_true")
    p.add_argument("--sizes", type=int, nargs="*", default=[128, 250, 256, 512])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("n", nargs="?", type=int)
    args = p.parse_args()
    if args.worker:
        steps = 4000 if args.n <= 256 else 1000
        print(json.dumps(worker(args.n, steps)))
        return
    rows = []
    for n in args.sizes:
        res = in_fresh_processes(HERE / "bench_core.py", [str(n)], args.repeats)
        jx = median([r["jax"] for r in res])
        orc = median([r["oracle"] for r in res])
        npy = median([r["numpy"] for r in res])
        ratios_o = [r["jax"] / r["oracle"] for r in res]
        ratios_n = [r["jax"] / r["numpy"] for r in res]
        rows.append([f"{n}x{n}", f"{jx:.0f}", f"{orc:.1f}", f"{npy:.0f}",
                     f"{median(ratios_o):.0f}x", f"{median(ratios_n):.1f}x (min {min(ratios_n):.1f}x)"])
        print(f"{n}: {res}", file=sys.stderr)
    print(f"Turing r={R:g} s={S:g} dt={DT}, float32, one run; medians of {args.repeats} processes; {machine()}\n")
    print(markdown_table(["lattice", "morphojax Mcell-steps/s", "oracle (SciPy) Mcell-steps/s",
                          "NumPy slices Mcell-steps/s", "vs oracle", "vs NumPy slices"], rows))


if __name__ == "__main__":
    main()

"""Batched sweeps against a loop of single runs: throughput in Mcell-steps/s.

For batches of 16, 64 and 256 members (the bounded Turing model, ratio varying from 4 to 12,
one shared paper start) on 64x64 and 128x128 lattices, this times

- `sweep`: the whole batch through `mj.sweep` (vmapped, chunked, sharded over the local
  devices; descriptors off, so only the simulation and the transfer back are timed), and
- a loop of `mj.simulate`, once per member, one call after the other (one compiled program,
  since parameters are traced arrays; blocked on at the end): what a user would write, and
- a lean loop: one `jax.jit`-compiled single run (`run_status` of `Turing(r, s)`), called
  once per member: the same kernel without `simulate`'s per-call checks,

each figure the median over several fresh processes (see _harness.py); cell-steps count
members x cells x steps, the same work in both columns.

    python benchmarks/bench_sweep.py [--repeats 3] [--sizes 64 128] [--batches 16 64 256]
"""

from __future__ import annotations

import argparse
import json
import sys

from _harness import HERE, in_fresh_processes, machine, markdown_table, median, timeit

S, DT = 3.0, 0.008  # ratio 4..12 with s = 3 is stable at dt = 0.008 (limit 0.0104 at r = 12)
WORK = 1.6e6  # cell-steps per member: 400 steps at 64x64, 100 steps at 128x128


def worker(n: int, batch: int, batch_size: int | None) -> dict:
    import jax
    import numpy as np

    import morphojax as mj
    from morphojax import sweep

    steps = max(10, int(WORK / (n * n)))
    ratios = np.linspace(4.0, 12.0, batch)
    model = mj.Turing(4.0, S)
    state = mj.paper_state(jax.random.key(0), (n, n))

    def batched():
        return sweep(model, {"ratio": ratios}, state=state, steps=steps, dt=DT, batch_size=batch_size,
                        describe_members=False).fields

    members = [model.replace(ratio=float(r)) for r in ratios]

    def loop():
        out = [mj.simulate(m, state, steps=steps, dt=DT).fields for m in members]
        return jax.block_until_ready(out)

    one = jax.jit(lambda r: mj.run_status(mj.Turing(r, S), state, steps, DT, check_dt=False)[0].fields)
    rs = [jax.numpy.float32(r) for r in ratios]

    def lean():
        return jax.block_until_ready([one(r) for r in rs])

    batched(), loop(), lean()  # compile all three
    t_batch = timeit(batched, min_time=0.0, min_runs=2)
    t_loop = timeit(loop, min_time=0.0, min_runs=2)
    t_lean = timeit(lean, min_time=0.0, min_runs=2)
    work = batch * n * n * steps
    return {"n": n, "batch": batch, "steps": steps, "sweep": work / t_batch / 1e6, "loop": work / t_loop / 1e6,
            "lean": work / t_lean / 1e6, "devices": len(jax.devices()), "backend": jax.default_backend()}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--worker", action="store_true")
    p.add_argument("--sizes", type=int, nargs="*", default=[64, 128])
    p.add_argument("--batches", type=int, nargs="*", default=[16, 64, 256])
    p.add_argument("--batch-size", type=int, default=None, help="sweep chunk size (default: automatic)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("n", nargs="?", type=int)
    p.add_argument("batch", nargs="?", type=int)
    args = p.parse_args()
    if args.worker:
        print(json.dumps(worker(args.n, args.batch, args.batch_size)))
        return
    rows = []
    extra = [] if args.batch_size is None else ["--batch-size", str(args.batch_size)]
    for n in args.sizes:
        for b in args.batches:
            res = in_fresh_processes(HERE / "bench_sweep.py", [*extra, str(n), str(b)], args.repeats)
            sw, lp, ln = (median([r[k] for r in res]) for k in ("sweep", "loop", "lean"))
            vs_loop = [r["sweep"] / r["loop"] for r in res]
            vs_lean = [r["sweep"] / r["lean"] for r in res]
            rows.append([f"{n}x{n}", b, res[0]["steps"], f"{sw:.0f}", f"{lp:.0f}", f"{ln:.0f}",
                         f"{median(vs_loop):.1f}x (min {min(vs_loop):.1f}x)",
                         f"{median(vs_lean):.1f}x (min {min(vs_lean):.1f}x)"])
            print(f"{n} {b}: {res}", file=sys.stderr)
    print(f"Machine: {machine()}; medians over {args.repeats} fresh processes.\n")
    print(markdown_table(["lattice", "members", "steps/member", "sweep", "loop of simulate", "lean jit loop",
                          "sweep / simulate loop", "sweep / lean loop"], rows))
    print("\nThroughputs in Mcell-steps/s (members x cells x steps per second).")


if __name__ == "__main__":
    main()

"""Batched sweeps against a loop of single runs and one large lattice: Mcell-steps/s.

For batches of 16, 64 and 256 members (the bounded Turing model, ratio varying from 4 to 12,
one shared paper start) on 60x60 and 120x120 lattices, this times

- `sweep`: the whole batch through `mj.sweep` with its defaults (on one CPU device: groups
  of members in lanes, see morphojax/_lanes.py; descriptors off, so only the simulation and
  the transfer back are timed),
- `sweep 1x1`: the same sweep member by member (`vmap_size=1`, the path before lanes),
- a loop of `mj.simulate`, once per member, one call after the other (one compiled program,
  since parameters are traced arrays; blocked on at the end): what a user would write,
- a lean loop: one `jax.jit`-compiled single run (`run_status` of `Turing(r, s)`), called
  once per member: the same kernel without `simulate`'s per-call checks, and
- one large lattice: `mj.simulate` on 480x480 (as many cells as 64 members of 60x60), the
  per-cell throughput a small-lattice sweep is measured against,

all five interleaved round by round (`time_interleaved`: a slow spell of the shared
machine falls on all of them alike), each figure the median over several fresh processes
(see _harness.py); cell-steps count members x cells x steps, the same work in every column.

    python benchmarks/bench_sweep.py [--repeats 3] [--sizes 60 120] [--batches 16 64 256]
"""

from __future__ import annotations

import argparse
import json
import sys

from _harness import HERE, in_fresh_processes, machine, markdown_table, median, time_interleaved

S, DT = 3.0, 0.008  # ratio 4..12 with s = 3 is stable at dt = 0.008 (limit 0.0104 at r = 12)
WORK = 1.8e6  # cell-steps per member: 500 steps at 60x60, 125 steps at 120x120
LARGE = 480  # the large lattice's side


def worker(n: int, batch: int, batch_size: int | None) -> dict:
    import jax
    import numpy as np

    import morphojax as mj
    from morphojax import sweep

    steps = max(10, int(WORK / (n * n)))
    ratios = np.linspace(4.0, 12.0, batch)
    model = mj.Turing(4.0, S)
    state = mj.paper_state(jax.random.key(0), (n, n))

    def batched(vmap_size=None):
        return sweep(model, {"ratio": ratios}, state=state, steps=steps, dt=DT, batch_size=batch_size,
                     vmap_size=vmap_size, describe_members=False).fields

    members = [model.replace(ratio=float(r)) for r in ratios]

    def loop():
        out = [mj.simulate(m, state, steps=steps, dt=DT).fields for m in members]
        return jax.block_until_ready(out)

    one = jax.jit(lambda r: mj.run_status(mj.Turing(r, S), state, steps, DT, check_dt=False)[0].fields)
    rs = [jax.numpy.float32(r) for r in ratios]

    def lean():
        return jax.block_until_ready([one(r) for r in rs])

    big = mj.paper_state(jax.random.key(0), (LARGE, LARGE))
    big_steps = max(10, int(WORK * 16 / LARGE**2))

    def large():
        return mj.simulate(model.replace(ratio=8.0), big, steps=big_steps, dt=DT).fields.block_until_ready()

    fns = {"sweep": batched, "one": lambda: batched(1), "loop": loop, "lean": lean, "large": large}
    for fn in fns.values():
        fn()  # compile
    t = time_interleaved(fns)
    work = batch * n * n * steps
    cell_steps = {k: work for k in fns} | {"large": LARGE**2 * big_steps}
    return {"n": n, "batch": batch, "steps": steps, **{k: cell_steps[k] / v / 1e6 for k, v in t.items()},
            "devices": len(jax.devices()), "backend": jax.default_backend()}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--worker", action="store_true")
    p.add_argument("--sizes", type=int, nargs="*", default=[60, 120])
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
            sw, one, lp, ln, lg = (median([r[k] for r in res]) for k in ("sweep", "one", "loop", "lean", "large"))

            def ratio(key):
                x = [r["sweep"] / r[key] for r in res]
                return f"{median(x):.1f}x (min {min(x):.1f}x)"

            rows.append([f"{n}x{n}", b, res[0]["steps"], f"{sw:.0f}", f"{one:.0f}", f"{lp:.0f}", f"{ln:.0f}",
                         f"{lg:.0f}", ratio("loop"), ratio("lean"), ratio("large")])
            print(f"{n} {b}: {res}", file=sys.stderr)
    print(f"Machine: {machine()}; medians over {args.repeats} fresh processes.\n")
    print(markdown_table(["lattice", "members", "steps/member", "sweep", "sweep 1x1", "loop of simulate",
                          "lean jit loop", f"one {LARGE}x{LARGE}", "sweep / simulate loop", "sweep / lean loop",
                          "sweep / large lattice"], rows))
    print("\nThroughputs in Mcell-steps/s (members x cells x steps per second).")


if __name__ == "__main__":
    main()

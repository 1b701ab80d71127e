"""Where the time of a compiled run goes: XLA:CPU's ops (thunks), with calls and time per call.

Traces one run of an already compiled experiment with `jax.profiler` and sums the trace
events by op name (fusions, FFTs, copies). The profiler adds a few microseconds to every op,
so small ops look dearer than they are; the large ones are close to their real cost.

    python benchmarks/profile_ops.py leopard-development   # the leopard's development phase
    python benchmarks/profile_ops.py whipray
    python benchmarks/profile_ops.py young-3d-l30           # paper 002 Table 1: 100 iterations

Op names are XLA's (e.g. `minimum_concatenate_fusion.6` is the update of one block size,
`select_dynamic-update-slice_fusion.*` the in-place writes of a growing run); dump the
optimised HLO with XLA_FLAGS=--xla_dump_to=DIR to see what each contains.
"""

from __future__ import annotations

import argparse
import collections
import glob
import tempfile

import jax

import bench_growth


def _young_3d_l30():
    from morphojax.automata import YoungCA, random_cells

    ca = YoungCA(species=[(3.2, 6.0, 1.0, -0.2)])
    cells = random_cells(jax.random.key(0), (30, 30, 30), 1)
    return lambda: jax.block_until_ready(ca.run(cells, 100))


RUNS = {"leopard-development": bench_growth._leopard_dev_jax, "whipray": bench_growth._whipray_jax,
        "young-3d-l30": _young_3d_l30}
SKIP = ("ThunkExecutor", "Threadpool", "end: ", "H2D")


def profile(run) -> dict[str, list]:
    """{op name: [calls, total ns]} for one call of `run` (compiled beforehand)."""
    from jax.profiler import ProfileData

    run()
    run()
    with tempfile.TemporaryDirectory() as tmp:
        jax.profiler.start_trace(tmp)
        run()
        jax.profiler.stop_trace()
        data = ProfileData.from_file(sorted(glob.glob(f"{tmp}/**/*.xplane.pb", recursive=True))[-1])
    ops = collections.defaultdict(lambda: [0, 0])
    for plane in data.planes:
        for line in plane.lines:
            if "python" in line.name:
                continue
            for ev in line.events:
                # while / conditional events enclose the ops of their bodies: not counted twice
                if ev.name.startswith(SKIP) or ev.name.startswith(("while", "conditional")):
                    continue
                ops[ev.name][0] += 1
                ops[ev.name][1] += ev.duration_ns
    return ops


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("name", choices=sorted(RUNS))
    p.add_argument("--top", type=int, default=25)
    args = p.parse_args()
    ops = profile(RUNS[args.name]())
    total = sum(t for _, t in ops.values())
    print(f"{args.name}: {total / 1e6:.1f} ms in {sum(n for n, _ in ops.values())} op calls\n")
    print("| op | calls | total (ms) | per call (us) | share |\n|---|---|---|---|---|")
    for name, (n, t) in sorted(ops.items(), key=lambda kv: -kv[1][1])[: args.top]:
        print(f"| {name} | {n} | {t / 1e6:.1f} | {t / n / 1e3:.1f} | {100 * t / total:.1f}% |")


if __name__ == "__main__":
    main()

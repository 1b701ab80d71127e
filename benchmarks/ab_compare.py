"""Before/after speed of two checkouts, interleaved process by process.

A refactor must not slow anything down, and this machine's speed drifts by tens of percent
from minute to minute; so the two trees' benchmark workers run alternately (A B B A A B ...),
each in a fresh process, and every figure is the ratio against the NumPy baseline timed in
the same process. Reports medians and ranges over the processes.

    git worktree add /tmp/before <rev>
    python benchmarks/ab_compare.py /tmp/before . [--repeats 5] [--out benchmarks/results/ab.md]

Cases: bench_core (128x128, 250x250), bench_growth (whipray, leopard development),
bench_sweep (64x64 with 16 and 64 members), bench_automata --quick (its three cases).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

CASES = [
    # (label, script, worker args, metric name, how to read the metric from the worker's JSON)
    ("core 128x128", "bench_core.py", ["128"], "x NumPy slices", lambda r: r["jax"] / r["numpy"]),
    ("core 250x250", "bench_core.py", ["250"], "x NumPy slices", lambda r: r["jax"] / r["numpy"]),
    ("growth whipray", "bench_growth.py", ["whipray"], "x np.roll port", lambda r: r["numpy_roll"] / r["jax"]),
    ("growth leopard development", "bench_growth.py", ["leopard-development"], "x np.roll port",
     lambda r: r["numpy_roll"] / r["jax"]),
    ("sweep 64x64, 16 members", "bench_sweep.py", ["64", "16"], "x loop of simulate", lambda r: r["sweep"] / r["loop"]),
    ("sweep 64x64, 64 members", "bench_sweep.py", ["64", "64"], "x loop of simulate", lambda r: r["sweep"] / r["loop"]),
]
AUTOMATA = ["Young L=30 3D K=1, 100 iterations", "Young L=100 3D K=2, to convergence", "Young 2D 1024x1024, 30 steps"]


def _env(tree: Path) -> dict:
    return dict(os.environ, PYTHONPATH=os.pathsep.join(str(tree / p) for p in ("", "tests", "benchmarks")))


def _worker(tree: Path, script: str, args: list[str]) -> dict:
    res = subprocess.run([sys.executable, str(tree / "benchmarks" / script), "--worker", *args], capture_output=True,
                         text=True, env=_env(tree), cwd=tree, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"{tree}: {script} {args} failed:\n{res.stderr[-2000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def _seconds(text: str) -> float:
    value, unit = re.match(r"\s*([\d.]+)\s*(ms|s)", text).groups()
    return float(value) / (1e3 if unit == "ms" else 1.0)


def _automata(tree: Path) -> list[float]:
    """The three cases of bench_automata --quick: morphojax against the NumPy FFT port."""
    res = subprocess.run([sys.executable, str(tree / "benchmarks" / "bench_automata.py"), "--quick"],
                         capture_output=True, text=True, env=_env(tree), cwd=tree, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"{tree}: bench_automata failed:\n{res.stderr[-2000:]}")
    rows = [line.split("|") for line in res.stdout.splitlines() if line.startswith("| paper") or
            line.startswith("| Young")]
    return [_seconds(cols[10]) / _seconds(cols[4]) for cols in rows]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before", type=Path)
    p.add_argument("after", type=Path)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--out", type=Path)
    args = p.parse_args()
    trees = {"before": args.before.resolve(), "after": args.after.resolve()}
    results = {label: {"before": [], "after": []} for label in [c[0] for c in CASES] + AUTOMATA}
    for i in range(args.repeats):
        order = ("before", "after") if i % 2 == 0 else ("after", "before")
        for label, script, wargs, _, metric in CASES:
            for side in order:
                results[label][side].append(metric(_worker(trees[side], script, wargs)))
        for side in order:
            for label, ratio in zip(AUTOMATA, _automata(trees[side])):
                results[label][side].append(ratio)
        print(f"round {i + 1} of {args.repeats} done", file=sys.stderr)
    units = {c[0]: c[3] for c in CASES} | {label: "x NumPy FFT port" for label in AUTOMATA}
    lines = [f"Interleaved before/after, {args.repeats} fresh processes per tree and case "
             f"(before: {trees['before']}, after: {trees['after']}).", "",
             "| case | ratio | before: median (range) | after: median (range) | after / before |",
             "|---|---|---|---|---|"]
    for label, sides in results.items():
        b, a = sides["before"], sides["after"]
        lines.append(f"| {label} | {units[label]} | {statistics.median(b):.2f} ({min(b):.2f}-{max(b):.2f}) "
                     f"| {statistics.median(a):.2f} ({min(a):.2f}-{max(a):.2f}) "
                     f"| {statistics.median(a) / statistics.median(b):.2f} |")
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text + "\n\nRaw ratios:\n\n```\n" + json.dumps(results, indent=1) + "\n```\n")


if __name__ == "__main__":
    main()

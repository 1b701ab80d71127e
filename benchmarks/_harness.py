"""Shared benchmark plumbing: repeated runs in fresh processes, medians, markdown tables.

This machine is shared and noisy, and power-of-two lattices run at two different speeds
from one process to the next, so every figure is the median over several *process* runs,
and every speed is reported next to a NumPy baseline timed in the same process.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def timeit(fn, *, min_time=0.5, min_runs=3, max_runs=50):
    """Best-of timing of `fn()` (already warmed up by the caller), in seconds per call."""
    times = []
    start = time.perf_counter()
    while len(times) < min_runs or (time.perf_counter() - start < min_time and len(times) < max_runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def time_interleaved(fns: dict, rounds: int = 4) -> dict:
    """Best time of each of `fns` ({name: fn}, already warmed up), in seconds per call. Each
    round calls every function once, in turn, so that a slow spell of a shared machine falls
    on all of them alike and their ratios hold."""
    best = {name: float("inf") for name in fns}
    for _ in range(rounds):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            best[name] = min(best[name], time.perf_counter() - t0)
    return best


def in_fresh_processes(script: Path, args: list[str], repeats: int, tree: Path | None = None) -> list[dict]:
    """Run `script --worker ARGS` `repeats` times, each in a new Python process; collect JSON.
    `tree`: import morphojax from that copy of the repository (default this one)."""
    out = []
    source = ROOT if tree is None else tree
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(source), str(ROOT / "tests"), str(HERE)]))
    for _ in range(repeats):
        res = subprocess.run([sys.executable, str(script), "--worker", *args], capture_output=True, text=True,
                             env=env, check=False)
        if res.returncode != 0:
            raise RuntimeError(f"benchmark worker failed:\n{res.stderr[-3000:]}")
        out.append(json.loads(res.stdout.strip().splitlines()[-1]))
    return out


def median(values):
    return statistics.median(values)


def markdown_table(headers, rows) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def machine() -> str:
    import platform

    try:
        import jax

        backend = f"jax {jax.__version__} on {jax.default_backend()} ({len(jax.devices())} device(s))"
    except Exception:  # pragma: no cover
        backend = "jax unavailable"
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, {backend}"

"""How long a fit takes, by stage: the README's cheetah fit (`--model turing`, three
parameters, intervals and verdict included) and `auto`, each in its own process.

Three conditions, each repeated `--repeats` times, medians reported:
- `cold`: a new process with an empty compilation cache (a first fit on a new machine);
- `disk`: a new process whose compilation cache holds the cold run's programs (every later
  fit from the command line, or from Python after `mj.use_compilation_cache()`);
- `memory`: a second fit in the same process as a `disk` one (a notebook's second fit).
Wall and CPU seconds are both reported, with the load average: on a shared machine the wall
time grows with the load and the CPU time does not.

    python benchmarks/fit_speed.py [--repeats 3] [--auto] [--out benchmarks/results/fit_speed.md]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

# The README's fit (the crop and the fitted names are the README's own)
FIT = """
import json, os, resource, sys, time
t0 = time.perf_counter()
import morphojax as mj
mj.use_compilation_cache()
import fitting
target = fitting.load_target("targets/cheetah-01.jpg", crop=(760, 230, 960, 430), invert=True)
rows = []
for k in range(int(sys.argv[2])):
    c0, w0 = time.process_time(), time.perf_counter()
    if sys.argv[1] == "auto":
        fit = fitting.fit(target, model="auto", progress=False)
    else:
        fit = fitting.fit(target, model="turing", fit=["ratio", "scale", "lower_b"], progress=False)
    rows.append({"timings": fit.timings, "cpu": time.process_time() - c0, "wall": time.perf_counter() - w0,
                 "family": fit.family, "convincing": fit.convincing, "loss": fit.loss, "params": fit.params})
rows[0]["process_wall"] = time.perf_counter() - t0
print("RESULT " + json.dumps(rows))
"""


def run_once(kind: str, cache: Path, fits: int) -> list[dict]:
    env = {**os.environ, "MORPHOJAX_CACHE_DIR": str(cache)}
    load = os.getloadavg()[0]
    out = subprocess.run([sys.executable, "-c", FIT, kind, str(fits)], cwd=ROOT, env=env, capture_output=True,
                         text=True, check=True)
    line = next(ln for ln in out.stdout.splitlines() if ln.startswith("RESULT "))
    rows = json.loads(line[len("RESULT "):])
    for row in rows:
        row["load"] = (load + os.getloadavg()[0]) / 2
    return rows


def measure(kind: str, repeats: int) -> dict:
    conditions = {"cold": [], "disk": [], "memory": []}
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as folder:
            cache = Path(folder) / "jax"
            conditions["cold"] += run_once(kind, cache, 1)
            disk, memory = run_once(kind, cache, 2)
            conditions["disk"].append(disk)
            conditions["memory"].append(memory)
        print(json.dumps({k: [r["wall"] for r in v] for k, v in conditions.items()}), flush=True)
    return conditions


def table(kind: str, conditions: dict) -> list[str]:
    stages = ["design", "noise", "local", "report", "intervals", "restart", "refine", "verdict", "auto_screen",
              "auto_fits"]
    present = [s for s in stages if any(s in r["timings"] for rows in conditions.values() for r in rows)]
    lines = [f"### {kind}", "",
             "| condition | wall s | CPU s | load | " + " | ".join(present) + " |",
             "|---|---|---|---|" + "---|" * len(present)]
    for name, rows in conditions.items():
        med = lambda f: float(np.median([f(r) for r in rows]))  # noqa: E731
        cells = [f"{med(lambda r: r['timings'].get(s, float('nan'))):.1f}" for s in present]
        lines.append(f"| {name} | {med(lambda r: r['wall']):.1f} | {med(lambda r: r['cpu']):.1f} | "
                     f"{med(lambda r: r['load']):.1f} | " + " | ".join(cells) + " |")
    fam = sorted({r["family"] for rows in conditions.values() for r in rows})
    return lines + ["", f"Family returned: {', '.join(fam)}; {len(conditions['cold'])} repeats (medians).", ""]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--auto", action="store_true", help="also time model='auto'")
    parser.add_argument("--out", default=str(HERE / "results" / "fit_speed.md"))
    args = parser.parse_args(argv)
    kinds = ["turing"] + (["auto"] if args.auto else [])
    results = {kind: measure(kind, args.repeats) for kind in kinds}
    lines = ["# How long a fit takes", "",
             f"`python benchmarks/fit_speed.py --repeats {args.repeats}{' --auto' if args.auto else ''}` "
             f"({time.strftime('%Y-%m-%d')}, {os.cpu_count()} CPUs). Stage columns are wall seconds; "
             "see the script's docstring for the conditions.", ""]
    for kind, conditions in results.items():
        lines += table(kind, conditions)
    out = Path(args.out)
    out.write_text("\n".join(lines))
    out.with_suffix(".json").write_text(json.dumps(results, indent=1))
    print("\n".join(lines))


if __name__ == "__main__":
    main()

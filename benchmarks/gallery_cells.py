"""Run the thesis's cell experiments (the `cells` presets, from its own listings) at full
size with seed 0 and write the README gallery's cell images and a table of what each run
made (cells, iterations, seconds).

    python benchmarks/gallery_cells.py [--only thesis-fig6.3 ...] [--quick]

Images go to benchmarks/results/gallery/NAME.png (the .npz and .svg beside them are not
kept); the table to benchmarks/results/gallery_cells.md, and what the presets that measure their
figure found (the summary entries named in MEASURED: `transition`, `spots`, ...) to
benchmarks/results/gallery_cells_measured.md.
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

import morphojax as mj

HERE = Path(__file__).resolve().parent
# Listings A.5, A.7 and A.8 grow from one cell whose random concentrations decide whether V
# survives (V = 0 is absorbing under the clamp at 0); seed 0 loses it in all three, and in
# the variants of Figs. 6.3 and 6.5
SEEDS = {"thesis-fig6.3": 1, "thesis-fig6.5": 1, "thesis-fig6.6": 1, "thesis-fig6.3-closeup": 1,
         "thesis-fig6.3-anisotropic-u": 1, "thesis-fig6.3-anisotropic-v": 1, "thesis-fig6.5-directed": 1}
MEASURED = ("transition", "spots", "cubic", "saturation")  # the summary entries that measure a figure


def main():
    names = list(mj.presets.of_kind("cells"))
    p = argparse.ArgumentParser()
    p.add_argument("--only", nargs="*", default=names)
    p.add_argument("--quick", action="store_true")
    args = p.parse_args()
    out = HERE / "results" / "gallery"
    out.mkdir(parents=True, exist_ok=True)
    rows, measured = [], {}
    for name in args.only:
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            seed = SEEDS.get(name, 0)
            summary = mj.PRESETS[name].run(seed=seed, quick=args.quick, out=Path(tmp) / f"{name}.png")
            shutil.copy(Path(tmp) / f"{name}.png", out / f"{name}.png")
        seconds = time.perf_counter() - t0
        rows.append((name, mj.PRESETS[name].figure, seed, summary["iterations"], summary["cells"], seconds))
        found = {k: summary[k] for k in MEASURED if summary.get(k) is not None}
        if found:
            measured[name] = found
        print(f"{name}: {summary['cells']} cells at {summary['iterations']} ({seconds:.1f} s)"
              f"{', ' + json.dumps(found) if found else ''}", flush=True)
    if args.quick:
        return
    lines = ["# The thesis's cell experiments at full size", "",
             "`python benchmarks/gallery_cells.py` (2-core CPU, other work running; seconds include compilation).", "",
             "| preset | figure | seed | iterations | cells | seconds |", "|---|---|---|---|---|---|"]
    table = HERE / "results" / "gallery_cells.md"
    kept = {}
    if table.exists() and len(args.only) < len(names):  # a partial run updates its rows only
        for line in table.read_text().splitlines():
            if line.startswith("| `"):
                kept[line.split("`")[1]] = line
    for name, figure, seed, iterations, cells, seconds in rows:
        kept[name] = (f"| `{name}` | {figure} | {seed} | {', '.join(map(str, iterations))} | "
                      f"{', '.join(map(str, cells))} | {seconds:.0f} |")
    lines += [kept[n] for n in names if n in kept]
    table.write_text("\n".join(lines) + "\n")
    _write_measured(measured, names, len(args.only) < len(names))


def _write_measured(measured: dict, names: list, partial: bool) -> None:
    """One line of JSON per preset that measures its figure (a partial run updates its own)."""
    path = HERE / "results" / "gallery_cells_measured.md"
    kept = {}
    if path.exists() and partial:
        for line in path.read_text().splitlines():
            if line.startswith("- `"):
                kept[line.split("`")[1]] = line
    for name, found in measured.items():
        kept[name] = f"- `{name}`: `{json.dumps(found)}`"
    lines = ["# What the cell presets that measure their figure found", "",
             ("`python benchmarks/gallery_cells.py` with the seeds of gallery_cells.md; each preset's summary entries "
              "(see its module's notes for what they mean)."), ""]
    path.write_text("\n".join(lines + [kept[n] for n in names if n in kept]) + "\n")


if __name__ == "__main__":
    main()

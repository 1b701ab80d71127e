"""Run the paper's presets at full size and write the README gallery and its statistics.

For every preset: the final image (benchmarks/results/gallery/NAME.png), the final lattice
size, and simple statistics of the shown species (pattern class, dominant wavelength, number
and mean area of spots, dark fraction), to compare with the paper's figure.

    python benchmarks/gallery.py [--only leopard whipray ...] [--quick]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import morphojax as mj
from morphojax import montage, render_experiment

HERE = Path(__file__).resolve().parent
NAMES = ["whipray", "honeycomb-whipray", "frog", "squirrel", "leopard", "reinforcement-growth", "giraffe",
         "nudibranch", "gray-scott-mitosis", "gray-scott-coral", "gray-scott-worms", "gray-scott-holes",
         "fitzhugh-nagumo", "gierer-meinhardt", "schnakenberg", "brusselator", "thesis-fig5.10-square",
         "thesis-fig5.10-hex"]
GROUPS = ["fig4", "development"]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--only", nargs="*", default=NAMES + GROUPS)
    p.add_argument("--quick", action="store_true")
    args = p.parse_args()
    out = HERE / "results" / "gallery"
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in args.only:
        preset = mj.PRESETS[name]
        t0 = time.perf_counter()
        if preset.members:
            images, labels = [], []
            for member in preset.members:
                res = mj.run_experiment(mj.PRESETS[member].experiment(args.quick), seed=0,
                                        frames=name == "development")
                shots = [s for _, s in res.frames] if name == "development" else []
                images += [render_experiment(s, res.experiment, scale=2) for s in shots] or [res.image(scale=2)]
                labels.append(member)
            if name == "fig4":
                from morphojax.presets import FIG4_RATIOS

                sheet = montage(images, 5, col_labels=[f"r = {r:g}" for r in FIG4_RATIOS],
                                row_labels=["B >= 0", "Ua", "Lb"])
            else:
                ncols = max(1, len(images) // len(preset.members))
                sheet = montage(images, ncols, row_labels=[m.split("-")[-1] for m in preset.members],
                                col_labels=["prepattern", "1 expansion", "10 expansions", "final"][:ncols])
            sheet.save(out / f"{name}.png")
            rows.append({"preset": name, "figure": preset.figure, "seconds": time.perf_counter() - t0})
            continue
        res = mj.run_experiment(preset.experiment(args.quick), seed=0)
        seconds = time.perf_counter() - t0
        res.image(scale=2 if max(res.state.shape) < 200 else 1).save(out / f"{name}.png")
        d = res.describe()
        rows.append({"preset": name, "figure": preset.figure, "size": list(res.state.shape), "pattern": d.pattern,
                     "wavelength": d.wavelength, "spots": d.spots, "spot_area": d.spot_area, "holes": d.holes,
                     "dark_fraction": d.dark_fraction, "seconds": seconds})
        print(json.dumps(rows[-1]), flush=True)
    # a run of some presets updates their rows and keeps the others'
    table = HERE / "results" / "gallery.json"
    kept = {r["preset"]: r for r in (json.loads(table.read_text()) if table.exists() else [])}
    kept.update({r["preset"]: r for r in rows})
    rows = [kept[n] for n in NAMES + GROUPS if n in kept] + [r for n, r in kept.items() if n not in NAMES + GROUPS]
    table.write_text(json.dumps(rows, indent=1))
    lines = ["| preset | paper figure | final size | pattern (shown species) | wavelength | spots / holes | time (s) |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        if "size" not in r:
            lines.append(f"| {r['preset']} | {r['figure']} | | | | | {r['seconds']:.0f} |")
            continue
        lines.append(f"| {r['preset']} | {r['figure']} | {r['size'][0]}x{r['size'][1]} | {r['pattern']} | "
                     f"{r['wavelength']:.1f} | {r['spots']} / {r['holes']} | {r['seconds']:.0f} |")
    (HERE / "results" / "gallery.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

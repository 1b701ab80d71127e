"""Fit the model to the real photos in targets/ and write previews for the README.

Each entry: the photo, the crop of its coat, whether dark pigment is the high species, and
which parameters to fit. Results go to benchmarks/results/photos/ (JSON + preview PNG) and a
markdown table to benchmarks/results/fit_photos.md.

    python benchmarks/fit_photos.py [--only cheetah giraffe]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import fitting

HERE = Path(__file__).resolve().parent
TARGETS = HERE.parent / "targets"

PHOTOS = {
    # name: (file, crop x0,y0,x1,y1, invert, fit, bounds)
    "cheetah": ("cheetah-01.jpg", (760, 230, 960, 430), True, ["ratio", "scale", "lower_b"], {}),
    "leopard": ("leopard-01.jpg", (340, 55, 580, 200), True, ["ratio", "scale", "lower_b"], {}),
    # the reticulated family of Fig. 4 (low ratio, A saturated) and the labyrinth family
    "giraffe": ("giraffe-01.jpg", (100, 265, 420, 420), False, ["ratio", "scale", "upper_a"],
                {"ratio": (3.0, 15.0), "upper_a": (4.5, 8.0)}),
    "zebra": ("zebra-01.jpg", (0, 380, 300, 640), False, ["ratio", "scale"], {"ratio": (4.0, 20.0)}),
    "pufferfish": ("pufferfish-01.jpg", (150, 230, 380, 400), False, ["ratio", "scale", "lower_b"], {}),
}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--only", nargs="*", default=list(PHOTOS))
    p.add_argument("--out", type=Path, default=HERE / "results" / "photos")
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in args.only:
        file, crop, invert, names, bounds = PHOTOS[name]
        target = fitting.load_target(TARGETS / file, crop=crop, invert=invert)
        t0 = time.perf_counter()
        # photos are compared as soft pigment maps (see fitting.StatsConfig.binarise)
        result = fitting.fit(target, model="turing", fit=names, bounds=bounds,
                             stats=fitting.StatsConfig(binarise=True))
        seconds = time.perf_counter() - t0
        result.save_json(args.out / f"{name}.json")
        result.preview(args.out / f"{name}.png")
        row = {"photo": name, "file": file, "crop": crop, "invert": invert, "params": result.params,
               "loss": result.loss, "noise_floor": result.noise_floor, "cell_pixels": target.cell_pixels,
               "seconds": seconds, "method": result.config["method"]}
        rows.append(row)
        print(json.dumps(row), file=sys.stderr)
    lines = ["| photo | crop | fitted | loss / noise floor | pixels per cell | time (s) |", "|---|---|---|---|---|---|"]
    for r in rows:
        fitted = ", ".join(f"{k} {v:.3g}" for k, v in r["params"].items())
        lines.append(f"| {r['photo']} | {r['crop']} | {fitted} | {r['loss']:.0f} / {r['noise_floor']:.0f} | "
                     f"{r['cell_pixels']:.2f} | {r['seconds']:.0f} |")
    table = "\n".join(lines)
    print(table)
    (HERE / "results" / "fit_photos.md").write_text(table + "\n")


if __name__ == "__main__":
    main()

"""The classic reactions against the linear theory: how far the settled pattern's wavelength
moves from the predicted one.

    python benchmarks/stability_classic.py     # rewrites its section of benchmarks/results/stability.md

For each classic reaction with a linear-regime test (`tests/test_stability.py`:
FitzHugh-Nagumo, Gierer-Meinhardt, Schnakenberg, the Brusselator, Thomas; each model's
defaults, the test's dt) on a wrapping 64 x 64 nine-point lattice (the test's):
- predicted: `mj.dispersion(model, mj.Lattice(), (64, 64))`'s fastest-growing mode;
- linear: from the steady state with uniform noise of 1e-4 (relative, as the test), run
  until the fastest mode has grown about e^7, then the dominant wavelength of u's deviation
  (1 / the power-weighted mean |frequency|, the test's measure);
- settled: the same run continued in blocks of `BLOCK` time units until u changes by less
  than `SETTLED` of its range over a block (or `LIMIT` is reached: then "no" in the table),
  then the same measure, the peak mode (the torus's waves of one |frequency| with the
  largest mean power per wave, as `stability_fig4.py`'s) and `mj.describe`'s wavelength
  (the peak of the radial power spectrum). `SEEDS` noise draws; the table gives their mean
  (and the mean measure's range). The mean measure counts a spot pattern's harmonics, so
  it reads shorter than the peak mode once the spots are sharp.

float32, as the test (noise of 1e-4 is resolved there). A few seconds per reaction on a CPU.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import jax
import numpy as np

import morphojax as mj
from stability_fig4 import peak_mode  # the waves of one |frequency| with the most power per wave

HERE = Path(__file__).resolve().parent
OUT = HERE / "results" / "stability.md"
MARK = "<!-- stability_classic.py: the classic reactions; stability_fig4.py keeps this section -->"
SHAPE = (64, 64)
MODELS = {  # name: (model, dt): the linear-regime test's
    "FitzHugh-Nagumo": (mj.FitzHughNagumo(), 0.15),
    "Gierer-Meinhardt": (mj.GiererMeinhardt(), 0.035),
    "Schnakenberg": (mj.Schnakenberg(), 0.02),
    "Brusselator": (mj.Brusselator(), 0.02),
    "Thomas": (mj.Thomas(), 0.015),
}
NOISE = 1e-4
GROWTH = 7.0  # e-folds of the fastest mode at the linear measurement
BLOCK = 25.0  # time units between checks of the settling
SETTLED = 0.005  # largest change of u over a block, as a share of u's range
LIMIT = 3000.0  # the longest run (time units)
EARLY = 1000.0  # where a run still changing at LIMIT is measured too, to show its wavelength has settled
SEEDS = 3


def dominant_wavelength(u) -> float:
    """1 / the power-weighted mean |frequency| (cycles per cell) of u's deviation."""
    p = np.abs(np.fft.fft2(u - u.mean())) ** 2
    fr, fc = np.meshgrid(np.fft.fftfreq(u.shape[0]), np.fft.fftfreq(u.shape[1]), indexing="ij")
    return 1.0 / float((p * np.hypot(fr, fc)).sum() / p.sum())


def one_run(model, dt, d, seed):
    x = np.asarray(d.steady_state, float)
    amp = NOISE * np.maximum(np.abs(x), 1.0)
    rng = np.random.default_rng(seed)
    state = mj.State.from_arrays([x[i] + amp[i] * rng.uniform(-1, 1, SHAPE) for i in range(2)], names=model.species)
    steps = int(round(GROWTH / float(d.fastest_rate) / dt))
    state = mj.simulate(model, state, steps, dt)
    linear = dominant_wavelength(np.asarray(state.arrays()[0], float))
    t, block = steps * dt, int(round(BLOCK / dt))
    u = np.asarray(state.arrays()[0], float)
    settled, early = False, None
    while t < LIMIT:
        state = mj.simulate(model, state, block, dt)
        t += block * dt
        new = np.asarray(state.arrays()[0], float)
        if early is None and t >= EARLY:
            early = dominant_wavelength(new)
        change = float(np.abs(new - u).max() / max(np.ptp(new), 1e-12))
        u = new
        if change < SETTLED:
            settled = True
            break
    described = mj.describe(u)
    late = dominant_wavelength(u)
    drift = abs(late - early) if early is not None and not settled else 0.0
    return linear, late, peak_mode(u), float(described.wavelength), t, settled, described.pattern, drift


def row(name):
    model, dt = MODELS[name]
    d = mj.dispersion(model, mj.Lattice(), SHAPE)
    t0 = time.perf_counter()
    runs = [one_run(model, dt, d, seed) for seed in range(SEEDS)]
    linear, settled, peak, described, t, ok, pattern, drift = zip(*runs)
    return {"name": name, "predicted": float(d.fastest_wavelength), "rate": float(d.fastest_rate), "dt": dt,
            "linear": float(np.mean(linear)), "settled": np.array(settled), "peak": float(np.mean(peak)), "described": float(np.mean(described)),
            "time": max(t), "all_settled": all(ok), "pattern": max(set(pattern), key=pattern.count),
            "drift": max(drift), "seconds": time.perf_counter() - t0}


def section(rows) -> list[str]:
    lines = [
        MARK,
        "",
        "## The classic reactions: linear and settled",
        "",
        f"`python benchmarks/stability_classic.py` (float32 on {jax.devices()[0].platform.upper()}, morphojax "
        f"{mj.__version__}); see the script's docstring. Each model's defaults on a wrapping {SHAPE[0]} x {SHAPE[1]}",
        f"nine-point lattice, from the steady state with noise of {NOISE:g} (relative), {SEEDS} noise draws; "
        "wavelengths in cells.",
        "",
        "| model | dt | predicted | rate | linear run | settled | its range | change | settled peak mode | change "
        "| describe | pattern | settled by t |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        s = r["settled"]
        change = (s.mean() - r["predicted"]) / r["predicted"]
        peak_change = (r["peak"] - r["predicted"]) / r["predicted"]
        when = f"{r['time']:g}" if r["all_settled"] else f"no ({r['time']:g})"
        lines.append(f"| {r['name']} | {r['dt']:g} | {r['predicted']:.2f} | {r['rate']:.3f} | {r['linear']:.2f} | "
                     f"{s.mean():.2f} | {s.min():.2f}-{s.max():.2f} | {change:+.0%} | {r['peak']:.2f} | {peak_change:+.0%} | "
                     f"{r['described']:.2f} | "
                     f"{r['pattern']} | {when} |")
    moved = np.array([(r["settled"].mean() - r["predicted"]) / r["predicted"] for r in rows])
    peaks = np.array([(r["peak"] - r["predicted"]) / r["predicted"] for r in rows])
    lines += [
        "",
        f"- The settled pattern's wavelength (mean measure) moves by {moved.min():+.0%} to {moved.max():+.0%} from the "
        f"prediction (median {np.median(moved):+.0%}); its peak mode by {peaks.min():+.0%} to {peaks.max():+.0%} "
        f"(median {np.median(peaks):+.0%}).",
        f"- Runs still changing at t = {LIMIT:g} (spots drifting) kept their wavelength: the mean measure moved by at "
        f"most {max(r['drift'] for r in rows):.2f} cells between t = {EARLY:g} and {LIMIT:g}.",
        "",
        f"`linear run`: the dominant wavelength (1 / the power-weighted mean frequency of u's deviation) once the "
        f"fastest mode grew about e^{GROWTH:g};",
        f"`settled`: the same measure once u changes by less than {SETTLED:.1%} of its range over {BLOCK:g} time "
        f"units (`settled by t`: the latest time over the draws; \"no\": still changing at t = {LIMIT:g});",
        "`settled peak mode`: the torus's waves of one |frequency| with the largest mean power per wave (mean over "
        "the draws); `change`: each against predicted; `describe`: `mj.describe`'s wavelength of the settled u (the peak "
        "of its radial power spectrum), mean over the draws.",
        "",
    ]
    return lines


def main():
    rows = []
    for name in MODELS:
        rows.append(row(name))
        r = rows[-1]
        print(f"{name}: predicted {r['predicted']:.2f}, linear {r['linear']:.2f}, settled {r['settled'].round(2)} "
              f"by t = {r['time']:g} ({r['seconds']:.0f} s)", file=sys.stderr)
    text = OUT.read_text() if OUT.exists() else ""
    head = text.split(MARK)[0].rstrip("\n")
    OUT.write_text(head + "\n\n" + "\n".join(section(rows)))
    print(OUT)


if __name__ == "__main__":
    main()

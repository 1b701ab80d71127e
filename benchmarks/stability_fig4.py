"""The leopard paper's Fig. 4 presets against the linear theory: predicted and simulated
wavelengths, while the perturbation is linear and once the pattern has settled.

    python benchmarks/stability_fig4.py            # writes benchmarks/results/stability.md

(its first part: `stability_classic.py` writes the classic reactions' section after it)

For each `fig4-*` preset (Turing r, s = 3 on a wrapping 50 x 50 nine-point lattice, with
the row's limits):
- predicted: `mj.dispersion(model, mj.Lattice(), (50, 50))`, the fastest-growing mode of
  that lattice (its wavelengths are those of the torus's waves, so they come in steps);
- linear: the preset's model and dt run from the steady state (4, 4) with uniform noise
  of amplitude 1e-8 until the fastest mode has grown by e^14, then the dominant wavelength
  of b's deviation (1 / the power-weighted mean frequency, as `tests/test_stability.py`
  measures it, over four noise draws), the peak mode (the waves of one |frequency| with
  the largest mean power per wave) and the growth rate between half time and the end;
- settled: the preset as published (A = 4, B uniform in [4, 5), a large perturbation) run
  to its T = 100, then the same measure and `mj.describe`'s wavelength (the peak of the
  radial power spectrum).

Everything runs in float64 (`jax_enable_x64`): in float32, forward Euler drops an increment
below half an ulp of the state, and near the threshold (r = 4.2: rate 0.06, dt = 0.01) a
perturbation of 1e-4 around 4 changes by about 6e-8 per step, below float32's 2.4e-7 there,
so it stops moving altogether.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import morphojax as mj

HERE = Path(__file__).resolve().parent
OUT = HERE / "results" / "stability.md"
GROWTH = 14.0  # e-folds of the fastest mode in the linear run
NOISE = 1e-8  # float64 resolves it: the run ends at about 1e-8 e^14 = 0.012, still linear
SEEDS = 4  # noise draws per linear run
CLASSIC_MARK = "<!-- stability_classic.py"  # where benchmarks/stability_classic.py's section begins


def dominant_wavelength(*fields) -> float:
    """1 / the power-weighted mean |frequency| (cycles per cell) of the fields' deviations,
    their power spectra summed."""
    p = sum(np.abs(np.fft.fft2(u - u.mean())) ** 2 for u in fields)
    fr, fc = np.meshgrid(np.fft.fftfreq(fields[0].shape[0]), np.fft.fftfreq(fields[0].shape[1]), indexing="ij")
    return 1.0 / float((p * np.hypot(fr, fc)).sum() / p.sum())


def peak_mode(*fields) -> float:
    """The wavelength of the modes with the largest mean power per mode (the waves of equal
    |frequency| of the torus taken together, their spectra summed over the fields): the
    run's own fastest mode, without the pull of rings that hold more modes."""
    p = sum(np.abs(np.fft.fft2(u - u.mean())) ** 2 for u in fields)
    fr, fc = np.meshgrid(np.fft.fftfreq(fields[0].shape[0]), np.fft.fftfreq(fields[0].shape[1]), indexing="ij")
    ring = np.round(np.hypot(fr, fc) * 1e9).astype(np.int64).ravel()
    keys, inverse = np.unique(ring, return_inverse=True)
    mean = np.bincount(inverse, p.ravel()) / np.bincount(inverse)
    mean[keys == 0] = 0.0
    return 1e9 / float(keys[np.argmax(mean)])


def linear_run(model, shape, dt, d):
    """(wavelength, growth rate, largest deviation of b) of runs from the steady state with
    noise, over `SEEDS` noise draws (their spectra summed: one draw's few modes per ring
    make its estimate wander by several per cent)."""
    x = np.asarray(d.steady_state, float)
    half = max(1, int(round(GROWTH / 2 / float(d.fastest_rate) / dt)))
    ends, rates, devs = [], [], []
    for seed in range(SEEDS):
        rng = np.random.default_rng(seed)
        state = mj.State.from_arrays([x[i] + NOISE * rng.uniform(-1, 1, shape) for i in range(2)],
                                     names=model.species)
        middle = mj.simulate(model, state, half, dt)
        end = mj.simulate(model, middle, half, dt)
        b_mid, b_end = (np.asarray(s.arrays()[1], float) for s in (middle, end))
        ends.append(b_end)
        rates.append(math.log(np.std(b_end) / np.std(b_mid)) / (half * dt))
        devs.append(float(np.abs(b_end - x[1]).max()))
    return dominant_wavelength(*ends), peak_mode(*ends), float(np.mean(rates)), max(devs)


def row(name):
    experiment = mj.preset(name)
    phase = experiment.phases[0]
    model, dt = phase.model, float(phase.dt)
    shape = tuple(experiment.initial.shape)
    d = mj.dispersion(model, mj.Lattice(), shape)
    t0 = time.perf_counter()
    lin_wl, lin_peak, lin_rate, lin_dev = linear_run(model, shape, dt, d)
    result = mj.run_experiment(experiment, seed=0)
    b = np.asarray(result.state.arrays()[1], float)
    settled, described = dominant_wavelength(b), float(mj.describe(b).wavelength)
    limits = [f"{k}={float(v):g}" for k, v in model.parameters().items()
              if k.startswith(("upper", "lower")) and math.isfinite(float(v)) and float(v) != 0.0]
    return {"preset": name, "ratio": float(model.ratio), "limits": ", ".join(limits) or "-",
            "at_limit": "".join(s for s, on in zip(model.species, np.asarray(d.at_limit)) if on) or "-",
            "predicted": float(d.fastest_wavelength), "rate": float(d.fastest_rate), "linear": lin_wl, "peak": lin_peak,
            "peak_rate": float(np.max(np.asarray(d.rates)[np.isclose(np.asarray(d.wavelengths), lin_peak, rtol=1e-6)])),
            "linear_rate": lin_rate, "linear_dev": lin_dev, "settled": settled, "described": described,
            "seconds": time.perf_counter() - t0}


def main():
    names = [n for n in mj.PRESETS if n.startswith("fig4-")]
    rows = []
    for name in names:
        rows.append(row(name))
        r = rows[-1]
        print(f"{name}: predicted {r['predicted']:.2f}, linear {r['linear']:.2f}, settled {r['settled']:.2f} "
              f"({r['seconds']:.0f} s)", file=sys.stderr)
    lines = [
        "# Fig. 4 against the linear theory",
        "",
        f"`python benchmarks/stability_fig4.py` (float64 on {jax.devices()[0].platform.upper()}, morphojax "
        f"{mj.__version__}); see the script's docstring for each column.",
        "Wavelengths in cells; rates per unit time. `at limit`: the species whose limit the steady state",
        "(4, 4) sits on (there the clamp cuts half of every growing wave, and the linearisation leaves it out).",
        "",
        "| preset | r | limits | at limit | predicted | rate | linear run | its peak mode | peak's predicted rate "
        "| its rate | settled | change | describe |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        change = (r["settled"] - r["predicted"]) / r["predicted"]
        lines.append(f"| `{r['preset']}` | {r['ratio']:g} | {r['limits']} | {r['at_limit']} | {r['predicted']:.2f} | "
                     f"{r['rate']:.3f} | {r['linear']:.2f} | {r['peak']:.2f} | {r['peak_rate']:.3f} | {r['linear_rate']:.3f} | {r['settled']:.2f} | "
                     f"{change:+.0%} | {r['described']:.2f} |")
    lin = np.array([abs(r["linear"] - r["predicted"]) / r["predicted"] for r in rows])
    free = np.array([r["at_limit"] == "-" for r in rows])
    moved = np.array([(r["settled"] - r["predicted"]) / r["predicted"] for r in rows])
    lines += [
        "",
        f"- Linear runs against the prediction: largest difference {lin[free].max():.1%} over the "
        f"{int(free.sum())} presets whose state is off the limits, {lin[~free].max() if (~free).any() else 0:.1%} "
        "over those on a limit.",
        f"- The settled pattern's wavelength (T = 100 from the paper's start) moves by {moved.min():+.0%} to "
        f"{moved.max():+.0%} from the prediction (median {np.median(moved):+.0%}).",
        "",
        "`linear run`: 1 / the power-weighted mean frequency of b's deviation once the fastest mode grew e^14 from",
        "noise of 1e-8 at the steady state (four noise draws, spectra summed); `its peak mode`: the wavelength of the",
        "torus's waves of one |frequency| with the largest mean power per wave (where two rings' predicted rates",
        "differ by less than the noise can show in e^14, either may win), and that ring's predicted rate; `its rate`: the deviation's growth",
        "rate over the second half of that run; `settled`: the same measure after the preset's own run; `change`: settled against predicted;",
        "`describe`: `mj.describe`'s wavelength of the settled pattern (the peak of its radial power spectrum).",
        "",
    ]
    # the classic reactions' section, written by stability_classic.py, stays as it is
    previous = OUT.read_text() if OUT.exists() else ""
    keep = previous[previous.index(CLASSIC_MARK):] if CLASSIC_MARK in previous else ""
    OUT.write_text("\n".join(lines) + ("\n" + keep if keep else ""))
    print(OUT)


if __name__ == "__main__":
    main()

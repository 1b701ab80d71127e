"""Speed of a step on each domain against the square nine-point step, in the same process.

The bounded Turing model (r = 12, s = 3, B >= 0) on a square lattice with the nine-point
stencil (the reference), the thesis's Moore sum (`Lattice("moore")`), and the hexagonal
lattice (`HexLattice`: the Laplacian and the neighbour sum on a torus, the Laplacian with
no-flux), and the square lattice's link form: a diffusion map (`scale` as an (n, n) array)
in the flux form and the pointwise form, and species b anisotropic with one polarity angle
or one per cell (wrap; Moore with no-flux) or following a's gradient (`Polarize`), and the
scale set every step from a (`Modulated`). Reports Mcell-steps/s (cells x steps / s) and
each domain's speed as a ratio of the nine-point step's timed in the same worker; every
figure is the median over several fresh processes (see _harness.py). dt is the nine-point
run's; every domain is stable at it.

    python benchmarks/bench_domains.py [--repeats 5] [--sizes 250]
"""

from __future__ import annotations

import argparse
import json
import sys

from _harness import HERE, in_fresh_processes, machine, markdown_table, median, timeit

R, S, DT = 12.0, 3.0, 0.004
DOMAINS = {  # name: constructor source (evaluated in the worker, after importing morphojax)
    "square nine-point (wrap)": "mj.Lattice('nine-point', 'wrap')",
    "square moore (wrap)": "mj.Lattice('moore', 'wrap')",
    "hex laplacian (wrap)": "mj.HexLattice('wrap', 'laplacian')",
    "hex sum (wrap)": "mj.HexLattice('wrap', 'sum')",
    "hex laplacian (no-flux)": "mj.HexLattice('no-flux', 'laplacian')",
    # per-cell rates and anisotropy on the links (domains/_links): `scale` as a (n, n) map
    # (constant, so every case runs the same pattern), polarity one angle or one per cell
    "square nine-point, rate map, flux form (wrap)": "mj.Lattice('nine-point', 'wrap')",
    "square nine-point, rate map, pointwise (wrap)": "mj.Lattice('nine-point', 'wrap', maps='pointwise')",
    "square nine-point, b anisotropic, one angle (wrap)": "mj.Lattice('nine-point', 'wrap', anisotropic='b', "
                                                          "polarity=0.3)",
    "square nine-point, b anisotropic, angle per cell (wrap)": "mj.Lattice('nine-point', 'wrap', anisotropic='b', "
                                                               "polarity=ANGLES)",
    "square moore, b anisotropic, angle per cell (no-flux)": "mj.Lattice('moore', 'no-flux', anisotropic='b', "
                                                              "polarity=ANGLES)",
    "hex laplacian, b anisotropic, angle per cell (wrap)": "mj.HexLattice('wrap', anisotropic='b', polarity=ANGLES)",
    # a polarity that follows a's gradient, recomputed every step (Polarize, eq. 4.10)
    "square moore, b anisotropic, Polarize(a) (no-flux)": "mj.Lattice('moore', 'no-flux', anisotropic='b', "
                                                          "polarity=mj.Polarize('a'))",
    "hex sum, b anisotropic, Polarize(a) (no-flux)": "mj.HexLattice('no-flux', 'sum', anisotropic='b', "
                                                     "polarity=mj.Polarize('a'))",
    # the scale set every step from a's concentration (Modulated; a map that gives s everywhere)
    "square nine-point, scale modulated by a (wrap)": "mj.Lattice('nine-point', 'wrap')",
}
MAPS = {"square nine-point, rate map, flux form (wrap)", "square nine-point, rate map, pointwise (wrap)"}
MODULATED = {"square nine-point, scale modulated by a (wrap)"}


def worker(n: int, steps: int) -> dict:
    import jax
    import numpy as np

    import morphojax as mj

    state = mj.paper_state(jax.random.key(0), (n, n))
    angles = np.random.default_rng(0).uniform(-np.pi, np.pi, (n, n))
    out = {"n": n}
    for name, source in DOMAINS.items():
        domain = eval(source, {"mj": mj, "ANGLES": angles})  # noqa: S307 (our own table above)
        model = mj.Turing(R, np.full((n, n), S) if name in MAPS else S)
        if name in MODULATED:
            model = mj.Modulated(model, mj.Modulation("scale", by="a", low=0.0, high=8.0, out_low=S, out_high=S))
        run = lambda: jax.block_until_ready(mj.simulate(model, state, steps=steps, dt=DT, domain=domain).fields)  # noqa: E731
        run()  # compile
        out[name] = n * n / (timeit(run, min_time=1.0) / steps) / 1e6
    return out


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--worker", action="store_true")
    p.add_argument("--sizes", type=int, nargs="*", default=[250])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("n", nargs="?", type=int)
    args = p.parse_args()
    if args.worker:
        print(json.dumps(worker(args.n, 2000 if args.n <= 256 else 500)))
        return
    rows = []
    reference = next(iter(DOMAINS))
    for n in args.sizes:
        res = in_fresh_processes(HERE / "bench_domains.py", [str(n)], args.repeats)
        print(f"{n}: {res}", file=sys.stderr)
        for name in DOMAINS:
            speeds = [r[name] for r in res]
            ratios = [r[name] / r[reference] for r in res]
            rows.append([f"{n}x{n}", name, f"{median(speeds):.0f}",
                         f"{median(ratios):.2f} (range {min(ratios):.2f}-{max(ratios):.2f})"])
    print(f"Turing r={R:g} s={S:g} dt={DT}, float32, one run; medians of {args.repeats} processes; {machine()}\n")
    print(markdown_table(["lattice", "domain", "Mcell-steps/s", "speed / nine-point (same process)"], rows))


if __name__ == "__main__":
    main()

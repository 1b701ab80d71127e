"""Speed of Young's automaton (morphojax.YoungCA) against NumPy, printed as a markdown table.

    python benchmarks/bench_automata.py [--repeats 7] [--quick]
    python benchmarks/bench_automata.py --methods      # the counting methods side by side

Cases:
1. paper 002 Table 1: L = 30, K = 1, 3D, (R_act, w_act, R_inh, w_inh) = (3.2, 1, 6, -0.2),
   100 iterations (paper: 1.233 s on its GPU, 275 s on its CPU; target here <= 20 ms);
2. paper 002 section 4.2: L = 100, K = 2, 3D, both species as above, run to convergence
   (< 1% of the cells changed);
3. a 1024 x 1024 2D run of Young's automaton (r1 = 2.30, r2 = 6.01, w1 = 1, w2 = -0.2,
   p = 0.015) for 30 steps (paper 003's run length).

`--methods` times the three exact counting methods (direct sums, FFT, matrix-product
transforms) on the same runs, interleaved in one process, over 3D and 2D lattice sizes,
with the method `method="auto"` picks: the measurements behind the cost model.

Every time is end to end (the `ca.run` call until its result is ready, compiled code
reused), the median of several runs; compile time is reported apart. Two NumPy
references run in the same process: the test oracle `tests/ca_oracle.py` (one np.roll
per neighbour offset, exact integers) and a vectorised NumPy FFT port (FFT convolution
rounded to integers: how one would write it in NumPy). Both compute in morphojax's dtypes,
int32 counts and float32 transforms (NumPy 2 transforms float32 in single precision): in
int64 the oracle ran 1.3-3.6x slower and in float64 the port about 1.3-1.5x, which flattered
the ratios (benchmarks/results/bench_automata.md). Slow references
are timed over fewer steps and scaled, as marked in the table; their results are
checked equal to morphojax's over the steps they ran.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import ca_oracle  # noqa: E402

from morphojax.automata import YoungCA, random_cells, volume_fractions  # noqa: E402


# ---- a plain vectorised NumPy port (the "how you would write it in NumPy" baseline) -------
COUNTS = np.int32  # morphojax's counts; the port and the oracle count in it too


class NumpyFFT:
    def __init__(self, species, shape):
        self.k = len(species)
        grids = np.meshgrid(*[np.minimum(np.arange(n), n - np.arange(n)) for n in shape], indexing="ij")
        d2 = sum(g.astype(np.int64) ** 2 for g in grids)
        self.spectra, self.weights = [], []
        for r_act, r_inh, w_act, w_inh in species:
            act = (d2 <= r_act**2 * (1 + 1e-6)) & (d2 > 0)
            ring = (d2 <= r_inh**2 * (1 + 1e-6)) & ~(d2 <= r_act**2 * (1 + 1e-6))
            self.spectra.append((np.fft.rfftn(act.astype(np.float32)), np.fft.rfftn(ring.astype(np.float32))))
            self.weights.append((w_act, w_inh))
        self.shape = shape
        # exact comparison: weights over their common decimal denominator
        from fractions import Fraction
        import math

        den = 1
        for w in self.weights:
            for v in w:
                den = math.lcm(den, Fraction(str(v)).denominator)
        self.int_weights = [(round(a * den), round(b * den)) for a, b in self.weights]

    def step(self, cells):
        fields = []
        for j, ((s_act, s_ring), (a, b)) in enumerate(zip(self.spectra, self.int_weights)):
            f = np.fft.rfftn((cells == j).astype(np.float32))
            axes = tuple(range(len(self.shape)))
            n_act = np.rint(np.fft.irfftn(f * s_act, s=self.shape, axes=axes)).astype(COUNTS)
            n_ring = np.rint(np.fft.irfftn(f * s_ring, s=self.shape, axes=axes)).astype(COUNTS)
            fields.append(a * n_act + b * n_ring)
        fields = np.stack(fields)
        best = fields.max(0)
        return np.where(best > 0, fields.argmax(0), np.where(best < 0, self.k, cells)).astype(cells.dtype)

    def run(self, cells, steps, stop=False, threshold=0.01):
        for i in range(steps):
            new = self.step(cells)
            converged = stop and np.mean(new != cells) < threshold
            cells = new
            if converged:
                return cells, i + 1
        return cells, steps


def _median_time(fn, repeats):
    """Median wall time, the wall times, and the median process CPU time (all threads):
    on a shared machine the CPU time is what the run costs without waiting for a core."""
    times, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(times), times, statistics.median(cpu)


def _run_jax(ca, cells, steps, stop):
    out = ca.run(cells, steps, stop_at_convergence=stop)
    jax.block_until_ready(out.cells)
    return out


def bench_case(name, species, shape, steps, stop, p, repeats, oracle_steps, numpy_steps, seed=0):
    ca = YoungCA(species)
    plan = ca._plan(shape)
    cells = random_cells(jax.random.key(seed), shape, len(species), p)
    t0 = time.perf_counter()
    out = _run_jax(ca, cells, steps, stop)
    first = time.perf_counter() - t0
    steps_run = int(out.steps)
    med, times, cpu = _median_time(lambda: _run_jax(ca, cells, steps, stop), repeats)
    compile_s = max(first - med, 0.0)

    cells_np = np.asarray(cells)
    # the oracle over `oracle_steps` (scaled to steps_run when fewer), checked equal
    n_or = min(oracle_steps, steps_run)
    t0 = time.perf_counter()
    ref = cells_np
    for _ in range(n_or):
        ref = ca_oracle.young_step(ref, [tuple(s) for s in species], counts=COUNTS)
    oracle_s = (time.perf_counter() - t0) * steps_run / max(n_or, 1)
    check = np.array_equal(ref, np.asarray(_run_jax(ca, cells, n_or, False).cells)) if n_or else True

    port = NumpyFFT(species, shape)
    n_np = min(numpy_steps, steps_run)
    t0 = time.perf_counter()
    ref2, _ = port.run(cells_np, n_np)
    numpy_s = (time.perf_counter() - t0) * steps_run / max(n_np, 1)
    check &= np.array_equal(ref2, np.asarray(_run_jax(ca, cells, n_np, False).cells))

    fractions = np.asarray(volume_fractions(out.cells, len(species)))
    return {
        "name": name, "stop": stop, "shape": shape, "K": len(species), "method": plan.method, "steps": steps_run,
        "converged": bool(out.converged), "median_s": med, "cpu_s": cpu, "min_s": min(times), "max_s": max(times),
        "repeats": repeats, "compile_s": compile_s, "oracle_s": oracle_s, "oracle_scaled": n_or < steps_run,
        "oracle_steps": n_or, "numpy_s": numpy_s, "numpy_scaled": n_np < steps_run, "numpy_steps": n_np,
        "equal": bool(check), "fractions": fractions,
    }


def compare_methods(repeats):
    """ms per step of each counting method, interleaved, and what `auto` picks."""
    cases = [((n,) * 3, [(3.2, 6.0, 1.0, -0.2)]) for n in (16, 20, 24, 30, 32, 36, 40, 48, 64)]
    cases += [((n,) * 3, [(3.2, 6.0, 1.0, -0.2)] * 2) for n in (30, 48, 64, 100)]
    cases += [((25, 40, 30), [(3.2, 6.0, 1.0, -0.2)])]
    cases += [((n, n), [(2.30, 6.01, 1.0, -0.2)]) for n in (64, 128, 250, 256, 1024)]
    cases += [((250, 250), [(2.30, 6.01, 1.0, -0.2), (2.0, 5.0, 1.0, -0.25), (1.5, 4.0, 1.0, -0.3)])]
    # larger inhibitor radii: where XLA:CPU stops vectorising the direct sums' last fusion
    cases += [((256, 256), [(2.30, r, 1.0, -0.02)]) for r in (12.0, 15.0)]
    cases += [((48,) * 3, [(3.2, r, 1.0, -0.05)]) for r in (7.5, 8.0)]
    methods = ("direct", "fft", "matmul")
    print("| lattice | K | r_inh | " + " | ".join(methods) + " | auto picks | fastest |")
    print("|---|---|---|" + "---|" * (len(methods) + 2))
    for shape, species in cases:
        steps = max(5, min(100, int(3e6 / np.prod(shape))))
        cells = random_cells(jax.random.key(0), shape, len(species), None if len(shape) == 3 else 0.015)
        models = {m: YoungCA(species, method=m) for m in methods}
        for m in methods:
            try:
                models[m]._plan(shape)
            except ValueError:  # matmul: fields too large for its float32 error bound
                del models[m]
        results = {m: np.asarray(_run_jax(ca, cells, steps, False).cells) for m, ca in models.items()}
        assert all(np.array_equal(results["fft"], r) for r in results.values()), shape
        times = {m: [] for m in models}
        for _ in range(repeats):
            for m, ca in models.items():
                t0 = time.perf_counter()
                _run_jax(ca, cells, steps, False)
                times[m].append((time.perf_counter() - t0) / steps)
        med = {m: statistics.median(t) for m, t in times.items()}
        auto = YoungCA(species)._plan(shape).method
        r_inh = f"{species[0][1]:g}" if len(set(species)) == 1 else "mixed"
        print(f"| {'x'.join(map(str, shape))} | {len(species)} | {r_inh} | "
              + " | ".join(f"{med[m] * 1e3:.3f} ms" if m in med else "n/a" for m in methods)
              + f" | {auto} | {min(med, key=med.get)} |")


def fmt_s(s):
    return f"{s * 1e3:.1f} ms" if s < 1 else f"{s:.2f} s"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--quick", action="store_true", help="smaller repeats and oracle steps (smoke test)")
    parser.add_argument("--methods", action="store_true", help="time the counting methods side by side")
    args = parser.parse_args(argv)
    if args.methods:
        return compare_methods(args.repeats)
    r = 3 if args.quick else args.repeats
    dur = (3.2, 6.0, 1.0, -0.2)
    cases = [
        bench_case("paper 002 Table 1: L=30 3D K=1, 100 iterations", [dur], (30, 30, 30), 100, False, None,
                   3 * r, oracle_steps=5 if args.quick else 100, numpy_steps=100),
        bench_case("paper 002 sec. 4.2: L=100 3D K=2, to convergence", [dur, dur], (100,) * 3, 100, True, None,
                   max(1, r // 2), oracle_steps=1, numpy_steps=2 if args.quick else 100),
        bench_case("Young 2D 1024x1024 K=1, 30 steps", [(2.30, 6.01, 1.0, -0.2)], (1024, 1024), 30, False, 0.015,
                   r, oracle_steps=1 if args.quick else 3, numpy_steps=3 if args.quick else 30),
    ]
    load = os.getloadavg()
    print(f"\nmachine: {os.cpu_count()} CPU cores, jax {jax.__version__} on {jax.devices()[0].platform}, "
          f"load average {load[0]:.2f} / {load[1]:.2f} (1 / 5 min)\n")
    print("| case | method | steps | morphojax wall (median of n, range) | CPU time (median) | per step | compile "
          "| NumPy oracle | ratio | NumPy FFT port | ratio | equal |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for c in cases:
        star = lambda scaled, n: f" (scaled from {n} steps)" if scaled else ""
        print(f"| {c['name']} | {c['method']} | {c['steps']}{' (converged)' if c['stop'] and c['converged'] else ''} "
              f"| {fmt_s(c['median_s'])} (n={c['repeats']}, {fmt_s(c['min_s'])}-{fmt_s(c['max_s'])}) "
              f"| {fmt_s(c['cpu_s'])} | {fmt_s(c['median_s'] / c['steps'])} | {fmt_s(c['compile_s'])} "
              f"| {fmt_s(c['oracle_s'])}{star(c['oracle_scaled'], c['oracle_steps'])} | {c['oracle_s'] / c['median_s']:.0f}x "
              f"| {fmt_s(c['numpy_s'])}{star(c['numpy_scaled'], c['numpy_steps'])} | {c['numpy_s'] / c['median_s']:.0f}x "
              f"| {'yes' if c['equal'] else 'NO'} |")
    t1 = cases[0]
    verdict = "met" if t1["median_s"] <= 0.020 else "NOT met"
    print(f"\nTable 1 target, 100 iterations of L=30, K=1 in <= 20 ms: {verdict}, median {fmt_s(t1['median_s'])} "
          f"wall, {fmt_s(t1['cpu_s'])} CPU, best {fmt_s(t1['min_s'])} "
          f"(paper 002: 1.233 s on its GPU, {1.233 / t1['median_s']:.0f}x longer; 275 s on its CPU).")
    k2 = cases[1]
    print(f"L=100 K=2: converged after {k2['steps']} iterations, volume fractions "
          f"{', '.join(f'{100 * f:.2f}%' for f in k2['fractions'])} (paper 002: 20 iterations, 42.86%, 42.88%, 14.26%).")


if __name__ == "__main__":
    main()

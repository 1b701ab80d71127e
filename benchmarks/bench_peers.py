"""morphojax against py-pde and exponax: the same problem and initial state, timed in one process.

The peers are not dependencies: run this with a Python that has them, e.g.

    python -m venv .peers && .peers/bin/pip install -e . py-pde exponax
    .peers/bin/python benchmarks/bench_peers.py --repeats 3

Problem: Gray-Scott (F 0.037, k 0.06, Du 0.2, Dv 0.1), periodic, a smooth start made of a
few low Fourier modes (the same continuum field on every grid). Four comparisons:

1. Same grid, matched time-step error: the five-point stencil on 100x100 cells (py-pde's
   finite differences are the same operator), to t = 100. The error is the largest
   difference from the semi-discrete solution (morphojax ETDRK4 in float64 at dt 1/16);
   each solver's time at the largest dt of its ladder whose error is below 1e-3.
2. Matched continuum error: against exponax (spectral, dealiased) on 200x200 points of the
   same domain at t = 25; morphojax's stencil error is O(dx^2), exponax's spectral: how
   much that wins.
3. Gradients: d mean(v) / d feed at t = 50.
4. vmap: eight feed values in one batch, per member.

Times are the best of interleaved rounds after warm-up (compilation and numba's JIT
excluded), medians over `--repeats` processes. Written to benchmarks/results/bench_peers.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE)]
from _harness import in_fresh_processes, machine, markdown_table, median, time_interleaved  # noqa: E402

F, K, DU, DV = 0.037, 0.06, 0.2, 0.1
L, N, T = 100.0, 100, 100.0
T_CONTINUUM = 25.0  # while the pattern is still smooth (by t = 100 every 100x100 run is 4e-2 off)
TOL = 1e-3


def smooth_start(n: int):
    """u, v on an n x n grid of the domain [0, L)^2: a few low modes, the same field for every n."""
    x = np.arange(n) * L / n
    X, Y = np.meshgrid(x, x, indexing="ij")
    rng = np.random.default_rng(0)
    blob = np.zeros((n, n))
    for kx in range(-3, 4):
        for ky in range(-3, 4):
            a, phase = rng.normal(), rng.uniform(0, 2 * np.pi)
            blob += a * np.cos(2 * np.pi * (kx * X + ky * Y) / L + phase)
    blob = (blob - blob.min()) / np.ptp(blob)
    return 1.0 - 0.5 * blob, 0.25 * blob


def morphojax_run(solver, dt, t_end, n=N, dtype="float32"):
    import jax
    import jax.numpy as jnp
    import morphojax as mj
    u, v = smooth_start(n)
    state = mj.State.from_arrays([jnp.asarray(u, dtype), jnp.asarray(v, dtype)])
    model = mj.GrayScott(F, K, DU, DV)
    steps = int(round(t_end / dt))
    return lambda: jax.block_until_ready(mj.simulate(model, state, steps, dt, "wrap", stencil="five-point",
                                                     solver=solver).fields)


def pypde_run(dt, t_end, n=N):
    import pde
    grid = pde.CartesianGrid([[0, L], [0, L]], [n, n], periodic=True)
    eq = pde.PDE({"u": f"{DU}*laplace(u) - u*v**2 + {F}*(1-u)", "v": f"{DV}*laplace(v) + u*v**2 - {F + K}*v"})
    u, v = smooth_start(n)
    start = pde.FieldCollection([pde.ScalarField(grid, u), pde.ScalarField(grid, v)])
    # the stepper is made (and numba-compiled) once; each call then advances a copy in place
    stepper = pde.EulerSolver(eq, backend="numba").make_stepper(start.copy(), dt=dt)

    def run():
        state = start.copy()
        stepper(state, 0.0, t_end)
        return np.stack([state[0].data, state[1].data])

    return run


def exponax_stepper(n, dt, feed=F):
    import exponax as ex
    return ex.stepper.reaction.GrayScott(2, L, n, dt, diffusivity_1=DU, diffusivity_2=DV, feed_rate=feed,
                                         kill_rate=K, order=2)


def exponax_run(n, dt, t_end):
    import jax
    import jax.numpy as jnp
    import exponax as ex
    u, v = smooth_start(n)
    start = jnp.asarray(np.stack([u, v]), jnp.float32)
    stepper = exponax_stepper(n, dt)
    go = jax.jit(ex.repeat(stepper, int(round(t_end / dt))))
    return lambda: jax.block_until_ready(go(start))


def worker():
    import jax
    import morphojax as mj
    out = {"versions": {}}
    import pde, exponax  # noqa: E401
    out["versions"] = {"py-pde": pde.__version__, "exponax": getattr(exponax, "__version__", "0.2"),
                       "jax": jax.__version__}
    # 1. same grid, matched time-step error
    with jax.enable_x64(True):
        ref = np.asarray(morphojax_run(mj.ETDRK(4), 1 / 16, T, dtype="float64")())
        check = np.asarray(morphojax_run(mj.ETDRK(4), 1 / 8, T, dtype="float64")())
    out["reference_change"] = float(np.abs(ref - check).max())
    euler_ladder = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625)
    ladders = {"morphojax Euler": (lambda dt: morphojax_run(mj.Euler(), dt, T), euler_ladder),
               "morphojax ETDRK2": (lambda dt: morphojax_run(mj.ETDRK(2), dt, T), (4.0, 2.0, 1.0, 0.5)),
               "morphojax ETDRK4": (lambda dt: morphojax_run(mj.ETDRK(4), dt, T), (8.0, 4.0, 2.0, 1.0)),
               "py-pde Euler (numba)": (lambda dt: pypde_run(dt, T), euler_ladder)}
    chosen, rows = {}, []
    for name, (make, ladder) in ladders.items():
        for dt in ladder:
            run = make(dt)
            err = float(np.abs(np.asarray(run()) - ref).max())
            rows.append({"solver": name, "dt": dt, "error": err})
            if err < TOL:
                chosen[name] = (dt, err, run)
                break
    best = time_interleaved({k: v[2] for k, v in chosen.items()}, rounds=3)
    out["same_grid"] = {"ladder": rows, "chosen": {k: {"dt": v[0], "error": v[1], "seconds": best[k]}
                                                   for k, v in chosen.items()}}
    # 2. continuum error: exponax on 200x200 as the reference, sampled at the 100x100 points
    # every run at dt 0.25 (ETDRK2's time error, ~6e-5, is then far below the spatial errors)
    fine = np.asarray(exponax_run(2 * N, 0.25, T_CONTINUUM)())[:, ::2, ::2]
    runs = {"morphojax ETDRK2 five-point": morphojax_run(mj.ETDRK(2), 0.25, T_CONTINUUM),
            "morphojax ETDRK2 nine-point": None,
            "exponax ETDRK2": exponax_run(N, 0.25, T_CONTINUUM)}
    import jax.numpy as jnp
    u, v = smooth_start(N)
    state = mj.State.from_arrays([jnp.asarray(u, "float32"), jnp.asarray(v, "float32")])
    runs["morphojax ETDRK2 nine-point"] = lambda: jax.block_until_ready(
        mj.simulate(mj.GrayScott(F, K, DU, DV), state, int(4 * T_CONTINUUM), 0.25, "wrap", solver=mj.ETDRK(2)).fields)
    errs = {k: float(np.abs(np.asarray(r()) - fine).max()) for k, r in runs.items()}
    best = time_interleaved(runs, rounds=3)
    out["continuum"] = {k: {"error": errs[k], "seconds": best[k]} for k in runs}
    # 3. gradients and 4. vmap
    import exponax as ex
    start = jnp.asarray(np.stack(smooth_start(N)), jnp.float32)

    def mj_v(feed):
        model = mj.GrayScott(feed, K, DU, DV)
        return mj.simulate(model, mj.State.from_arrays([start[0], start[1]]), 50, 1.0, "wrap", stencil="five-point",
                           solver=mj.ETDRK(2)).fields[1].mean()

    def ex_v(feed):
        return ex.repeat(exponax_stepper(N, 1.0, feed), 50)(start)[1].mean()

    feeds = jnp.linspace(0.03, 0.045, 8)
    fns = {"morphojax grad": jax.jit(jax.grad(mj_v)), "exponax grad": jax.jit(jax.grad(ex_v)),
           "morphojax vmap 8": jax.jit(jax.vmap(mj_v)), "exponax vmap 8": jax.jit(jax.vmap(ex_v)),
           "morphojax one": jax.jit(mj_v), "exponax one": jax.jit(ex_v)}
    calls = {k: (lambda f=f, k=k: jax.block_until_ready(f(feeds) if "vmap" in k else f(jnp.float32(F))))
             for k, f in fns.items()}
    for c in calls.values():
        c()
    out["grad_vmap"] = time_interleaved(calls, rounds=3)
    print(json.dumps(out))


def report(repeats):
    runs = in_fresh_processes(Path(__file__), [], repeats)
    first = runs[0]
    lines = [f"# morphojax, py-pde and exponax\n\n{machine()}; py-pde {first['versions']['py-pde']} (numba), "
             f"exponax {first['versions']['exponax']}; medians over {repeats} processes "
             "(`python benchmarks/bench_peers.py`, in an environment with the peers installed).\n"]
    ladder = markdown_table(["solver", "dt", "max error at t = 100"],
                            [[r["solver"], f"{r['dt']:g}", f"{r['error']:.2e}"] for r in first["same_grid"]["ladder"]])
    chosen = first["same_grid"]["chosen"]
    if "py-pde Euler (numba)" not in chosen:
        raise SystemExit(f"py-pde's Euler did not reach an error below {TOL:g} on its ladder: extend it")
    base = median([r["same_grid"]["chosen"]["py-pde Euler (numba)"]["seconds"] for r in runs])
    rows = []
    for k in chosen:
        sec = median([r["same_grid"]["chosen"][k]["seconds"] for r in runs])
        rows.append([k, f"{chosen[k]['dt']:g}", f"{chosen[k]['error']:.1e}", f"{sec:.3f}", f"{base / sec:.1f}x"])
    lines += ["## Same grid, matched time-step error\n",
              "Five-point stencil, 100x100 cells, wrap, t = 100. Reference: morphojax ETDRK4 in float64 at dt 1/16 "
              f"(it moves by {first['reference_change']:.1e} from dt 1/8). Each solver's largest dt of its ladder with "
              f"error < {TOL:g}:\n", ladder, "", markdown_table(
                  ["solver", "dt", "error", "seconds", "speed-up vs py-pde"], rows), ""]
    cont = first["continuum"]
    rows = [[k, f"{v['error']:.2e}", f"{median([r['continuum'][k]['seconds'] for r in runs]):.3f}"]
            for k, v in cont.items()]
    lines += ["## Matched continuum error\n", "Against exponax on 200x200 points of the same domain (dt 0.25, "
              f"ETDRK2, dealiased), sampled at the 100x100 points, t = {T_CONTINUUM:g}, every run at dt 0.25:\n",
              markdown_table(["run on 100x100", "max error vs the continuum", "seconds"], rows), ""]
    gv = {k: median([r["grad_vmap"][k] for r in runs]) for k in first["grad_vmap"]}
    rows = [[k, f"{v:.3f}"] for k, v in gv.items()]
    lines += ["## Gradients and vmap\n", "d mean(v) / d feed at t = 50 (ETDRK2, dt 1, 100x100), and a vmap over "
              "8 feed values; seconds per call:\n", markdown_table(["call", "seconds"], rows), ""]
    (HERE / "results" / "bench_peers.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker()
    else:
        ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
        ap.add_argument("--repeats", type=int, default=3)
        report(ap.parse_args().repeats)

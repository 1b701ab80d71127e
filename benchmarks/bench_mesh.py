"""Speed of Gray-Scott on a triangle mesh: morphojax's compiled step against a NumPy/SciPy port.

The same forward-Euler step (Gray-Scott, Pearson's F = 0.0545, k = 0.062, Du = 0.2097,
Dv = 0.105, clamped at 0, dt = 1) on icospheres whose edge is about one unit: morphojax's
`simulate(..., domain=mj.Mesh)` (the cotangent operator as a gather and row sum, fused with
the reaction in one `lax.scan`) and tests/mesh_oracle.py's `gray_scott_run` (two SciPy CSR
products per step, the operator assembled from the same mesh arrays, all in float32 like
the run: a float64 port runs 24-36% slower and flatter the ratio). Reports vertex-steps
per second and the ratio, timed in the same worker; every figure is the median over several
fresh processes (see _harness.py). For context, paper 004 (Lundelius) reports 0.127 s per
iteration of its NumPy Gray-Scott on a 100 x 100 grid (10,000 cells: 7.9e4 cell-steps/s).

    python benchmarks/bench_mesh.py [--repeats 5] [--subdivisions 4 5 6]
"""

from __future__ import annotations

import argparse
import json
import sys

from _harness import HERE, in_fresh_processes, machine, markdown_table, median, timeit

FEED, KILL, DU, DV, DT = 0.0545, 0.062, 0.2097, 0.105, 1.0
EDGE = 0.0377  # mean edge of the unit icosphere with 5 subdivisions; halves per subdivision


def worker(subdivisions: int, steps: int) -> dict:
    import jax
    import numpy as np
    import scipy.sparse as sp

    import morphojax as mj
    from mesh_oracle import gray_scott_run
    from morphojax.domains._mesh_build import weight_matrix
    from morphojax.presets._meshes import seed_patches

    radius = 1.0 / (EDGE * 2.0 ** (5 - subdivisions))
    mesh = mj.Mesh.icosphere(subdivisions, radius)
    n = mesh.n_vertices
    state = mj.gray_scott_state(jax.random.key(0), (n,), seeded=seed_patches(mesh))
    model = mj.GrayScott(FEED, KILL, DU, DV)
    run = lambda: jax.block_until_ready(mj.simulate(model, state, steps=steps, dt=DT, domain=mesh).fields)  # noqa: E731
    run()  # compile
    t_jax = timeit(run, min_time=1.0) / steps
    wm = weight_matrix(np.asarray(mesh.neighbours), np.asarray(mesh.weights, np.float32))
    lap = (sp.diags(np.asarray(mesh.inverse_mass)) @ (wm - sp.diags(np.asarray(wm.sum(1)).ravel()))).tocsr()
    u0, v0 = (np.asarray(a) for a in state.arrays())
    lap = lap.astype(u0.dtype)  # cast once here, not inside every timed call of the port
    np_steps = max(10, steps // 10)
    # the port computes in the run's dtype (float32), as morphojax does
    port = lambda: gray_scott_run(lap, u0, v0, FEED, KILL, DU, DV, DT, np_steps, dtype=u0.dtype)  # noqa: E731
    assert all(a.dtype == u0.dtype == np.float32 for a in port())
    t_np = timeit(port, min_time=1.0) / np_steps
    return {"subdivisions": subdivisions, "vertices": n, "jax": n / t_jax, "numpy": n / t_np}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--worker", action="store_true")
    p.add_argument("--subdivisions", type=int, nargs="*", default=[4, 5, 6])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("n", nargs="?", type=int)
    args = p.parse_args()
    if args.worker:
        print(json.dumps(worker(args.n, 2000 if args.n <= 5 else 500)))
        return
    rows = []
    for k in args.subdivisions:
        res = in_fresh_processes(HERE / "bench_mesh.py", [str(k)], args.repeats)
        print(f"{k}: {res}", file=sys.stderr)
        ratios = [r["jax"] / r["numpy"] for r in res]
        rows.append([f"icosphere({k})", res[0]["vertices"], f"{median([r['jax'] for r in res]) / 1e6:.1f}",
                     f"{median([r['numpy'] for r in res]) / 1e6:.2f}",
                     f"{median(ratios):.1f} (range {min(ratios):.1f}-{max(ratios):.1f})"])
    print(f"Gray-Scott F={FEED} k={KILL} dt={DT}, float32; medians of {args.repeats} processes; {machine()}\n")
    print(markdown_table(["mesh", "vertices", "morphojax Mvertex-steps/s", "NumPy/SciPy Mvertex-steps/s",
                          "speed-up (same process)"], rows))


if __name__ == "__main__":
    main()

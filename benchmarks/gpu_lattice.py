"""The lattice step on a GPU: Euler's bandwidth against the card's memory roofline, and the
solvers' throughput next to Euler's (the solvers issue's GPU figures).

Each run is `simulate` on `fig4`'s Turing model (r = 12, s = 3, wrap, nine-point) from
`paper_state(key(0))`, compiled (the second of two calls), float32. Euler's traffic is
counted as the issue counts it: 16 bytes per cell-step (two float32 species read and
written once), so its bandwidth is 16 x cell-steps/s against the card's peak (H100 SXM
3.35 TB/s, H200 4.8 TB/s; another card: no fraction). `--unroll` re-times Euler with the
scan body repeated k times per loop iteration (`_loop._scan` replaced for the run), which
separates the step's own cost from the loop's per-iteration overhead; `--barrier` also times
k steps per iteration separated by `lax.optimization_barrier`, so that XLA cannot fuse one step
into the next, while the second step may still write into the first one's dead input (the
copy that the scan's body makes of the whole state each step, bench_gpu.md, is what it tests). The solvers run at
16x Euler's dt (the largest multiple that kept `fig4-r12`'s pattern for all five in
`solvers.md`), so their simulated time per second is the figure a user sees.

    python benchmarks/gpu_lattice.py [--sizes 1024 2048] [--steps 400] [--unroll 1 8] [--barrier 2 4]
"""

from __future__ import annotations

import argparse
import time

import jax
from _harness import machine, markdown_table

R, S, DT, SOLVER_FACTOR = 12.0, 3.0, 0.008, 16
BYTES_PER_CELL_STEP = 16
PEAK_BYTES_PER_S = {"H100": 3.35e12, "H200": 4.8e12}


def peak_bandwidth() -> tuple[str, float | None]:
    kind = jax.devices()[0].device_kind
    return kind, next((v for k, v in PEAK_BYTES_PER_S.items() if k in kind), None)


def run_seconds(model, state, steps, dt, solver=None) -> float:
    """Seconds of the compiled run: the best of three calls after a first that compiles."""
    import morphojax as mj
    call = lambda: jax.block_until_ready(
        mj.simulate(model, state, steps, dt, solver=solver, throw=False, check_dt=False).fields)
    call()
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - t0)
    return best


def use_loop(k: int, original, barrier: bool = False):
    """`_loop._scan` taking `k` steps per loop iteration (`original` for 1): by `unroll`, or
    with `barrier` as k steps separated by `lax.optimization_barrier`. The compiled programs
    are dropped so the next run traces the new loop."""
    from morphojax import _loop

    def unrolled(step, carry, n):
        if n == 0:
            return carry
        return jax.lax.scan(lambda c, _: (step(c), None), carry, None, length=n, unroll=k)[0]

    def separated(step, carry, n):
        def body(c, _):
            for _ in range(k):
                c = jax.lax.optimization_barrier(step(c))
            return c, None

        full, rest = divmod(n, k)
        carry = jax.lax.scan(body, carry, None, length=full)[0] if full else carry
        return original(step, carry, rest)

    _loop._scan = original if k == 1 else separated if barrier else unrolled
    jax.clear_caches()


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=[1024, 2048])
    p.add_argument("--steps", type=int, default=400)
    p.add_argument("--unroll", type=int, nargs="+", default=[1, 8])
    p.add_argument("--barrier", type=int, nargs="*", default=[2], help="steps per iteration, barriers between")
    p.add_argument("--solvers-at", type=int, default=1024, help="lattice size of the solver rows")
    args = p.parse_args()
    import morphojax as mj
    from morphojax import _loop

    kind, peak = peak_bandwidth()
    model, original = mj.Turing(R, S), _loop._scan
    euler_rows, solver_rows = [], []
    for n in args.sizes:
        state = mj.paper_state(jax.random.key(0), (n, n))
        loops = [(k, False) for k in args.unroll] + [(k, True) for k in args.barrier]
        for k, barrier in loops:
            use_loop(k, original, barrier)
            sec = run_seconds(model, state, args.steps, DT)
            rate = n * n * args.steps / sec
            gbs = rate * BYTES_PER_CELL_STEP
            euler_rows.append([f"{n}x{n}", f"{k}, barriers" if barrier else k, f"{sec / args.steps * 1e6:.1f}",
                               f"{rate / 1e9:.2f}",
                               f"{gbs / 1e9:.0f}", f"{gbs / peak:.0%}" if peak else "n/a"])
            print(euler_rows[-1], flush=True)
    use_loop(1, original)
    n = args.solvers_at
    state = mj.paper_state(jax.random.key(0), (n, n))
    solvers = {"Euler": (None, DT), **{name: (solver, DT * SOLVER_FACTOR) for name, solver in {
        "ETDRK1": mj.ETDRK(1), "ETDRK2": mj.ETDRK(2), "ETDRK4": mj.ETDRK(4), "IMEX1": mj.IMEX(1),
        "IMEX2": mj.IMEX(2)}.items()}}
    euler_time = None
    for name, (solver, dt) in solvers.items():
        steps = args.steps if solver is None else max(1, args.steps // 4)  # 4x Euler's simulated time
        sec = run_seconds(model, state, steps, dt, solver)
        per_time = steps * dt / sec
        euler_time = euler_time or per_time
        solver_rows.append([name, f"{dt:g}", f"{sec / steps * 1e6:.1f}", f"{n * n * steps / sec / 1e9:.2f}",
                            f"{per_time:.0f}", f"{per_time / euler_time:.1f}x"])
        print(solver_rows[-1], flush=True)
    print(f"\n{machine()}; {kind}; peak {peak / 1e12:.2f} TB/s" if peak else f"\n{machine()}; {kind}")
    print("\nEuler, 16 bytes per cell-step:\n")
    print(markdown_table(["lattice", "steps per iteration", "us / step", "Gcell-steps/s", "GB/s", "of peak"], euler_rows))
    print(f"\nSolvers at {n}x{n} (Euler at dt {DT}, the others at {SOLVER_FACTOR}x):\n")
    print(markdown_table(["solver", "dt", "us / step", "Gcell-steps/s", "simulated time / s", "vs Euler"],
                         solver_rows))


if __name__ == "__main__":
    main()

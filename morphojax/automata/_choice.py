"""How Young's automaton counts neighbours: the plan worked out before compiling.

A plan is static, hashable configuration: the counting method (`auto` picks the cheapest
exact one from a cost model), the integer neighbourhood thresholds, the dtypes the counts
fit in, and whether the float transforms may take one weighted kernel per species. It is
a function of a model's concrete parameters, the lattice shape and the backend only, so
`_caches` keeps plans of concrete models.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .._checks import is_concrete
from ._direct import direct_adds, vector_width
from ._geometry import ball_size, half_width

INT32_MAX = 2**31 - 1
# float32 transforms (FFT or matrix products): the kernel may carry integer weights (one
# transform pair per species) while the sum of their magnitudes keeps the worst-case
# rounding error far below 1/2; otherwise the activator and ring counts are transformed
# separately (each exact).
FFT_ERROR_SCALE = 4.0 * float(np.finfo(np.float32).eps)

# Cost model of `method="auto"`, microseconds a step for N cells. Its constants are fitted
# to the tables of `benchmarks/bench_automata.py --methods` in
# benchmarks/results/bench_automata.md (XLA:CPU); the model's form is:
# - direct: US_DIRECT + N x adds x max(NS_ADD, NS_ADD_SMALL (4096 / N)^(1/3)) ns (byte adds
#   over whole vectors, cheaper per add on larger lattices, whose loops XLA:CPU splits
#   over the cores), x SCALAR_PENALTY once a species' last fused sum (its adds beyond the
#   runs along the first axis) exceeds FUSED_ADDS_2D adds in 2D or FUSED_ADDS in 3D and
#   more: XLA:CPU then emits that fusion as scalar code;
# - fft: US_FFT + NS_FFT x N log2 N per transform pair (1.5 pairs a species when the
#   activator and ring counts are transformed separately);
# - matmul (K = 1, CPU only): US_MATMUL + N x max(NS_MATMUL, NS_MAC x multiply-adds per cell) ns.
US_DIRECT, NS_ADD, NS_ADD_SMALL, SCALAR_PENALTY = 10.0, 0.035, 0.1, 13.0
FUSED_ADDS_2D, FUSED_ADDS = 30, 130  # (1D: nothing is fused beyond the runs)
US_FFT, NS_FFT = 25.0, 0.4
US_MATMUL, NS_MATMUL, NS_MAC = 5.0, 6.5, 0.013


class YoungPlan(NamedTuple):
    """Static configuration of the counting, worked out before compiling."""

    method: str  # "direct", "fft" or "matmul"
    combined: bool  # fft / matmul: one weighted kernel per species (else separate counts)
    thresholds: tuple | None  # direct: ((T_act, T_inh), ...) per species
    count_dtype: str
    extent: int = 0  # matmul: the kernels' half-width along the first axis
    keys: bool = False  # K > 1: the update picks the largest packed key W_j (K + 1) + K - j (int32)
    width: int = 0  # direct: the carried lattice's last axis, widened periodically to whole vectors


def make_plan(ca, shape: tuple, backend: str) -> YoungPlan:
    """The plan of YoungCA `ca` on a periodic lattice of `shape` on `backend`; raises a
    ValueError for a lattice too small for the radii, fields that overflow int32, or an
    explicit method that cannot count this model exactly."""
    dim = len(shape)
    n = int(np.prod(shape))
    if not is_concrete(ca.r_act, ca.r_inh):
        if ca.method == "direct":
            raise ValueError("YoungCA.method 'direct' needs concrete radii (the radii are traced); use 'fft'")
        return YoungPlan("fft", False, None, "int32")
    thresholds = ca._thresholds()
    extent = max(half_width(t, ca.neighbourhood) for _, t in thresholds)
    if min(shape) < 2 * extent + 1:
        raise ValueError(
            f"YoungCA cells: every side of the periodic lattice must be at least 2 floor(r_inh) + 1 = "
            f"{2 * extent + 1} cells so that no neighbour counts twice (got shape {tuple(shape)})"
        )
    counts = ca.neighbour_counts(dim)
    ball = max(ball_size(t, dim, ca.neighbourhood) for _, t in thresholds)
    count_dtype = "int16" if ball < 2**15 else "int32"
    combined = keys = False
    if is_concrete(ca.w_act, ca.w_inh, ca.denominator):
        a, b = (np.abs(x) for x in ca._host_integer_weights())
        bound = int(np.max(a * counts[:, 0] + b * counts[:, 1]))
        if bound > INT32_MAX:
            raise ValueError(
                f"YoungCA: weights x denominator ({int(ca.denominator)}) x neighbour counts overflow "
                "32-bit integers; use weights with fewer decimals or smaller radii"
            )
        combined = bound * FFT_ERROR_SCALE * max(1.0, math.log2(n)) < 0.1
        keys = ca.n_species > 1 and bound * (ca.n_species + 1) + ca.n_species <= INT32_MAX
        # matrix-product transforms: float32 sums as long as the transformed sides allow
        # (worst-case error growth, far above the errors measured; bench_automata.md)
        exact_matmul = bound * FFT_ERROR_SCALE * max(1, sum(shape[1:])) < 0.1
    else:
        exact_matmul = False
    method = ca.method
    if method == "matmul" and not exact_matmul:
        raise ValueError(
            "YoungCA.method 'matmul' needs concrete weights whose fields (weights x denominator x neighbour "
            "counts) stay small enough for exact float32 transforms; use 'fft' or 'direct'"
        )
    if method == "auto":
        costs = {"fft": fft_cost(n, ca.n_species, combined)}
        # the model is fitted on CPU; on GPUs 3D lattices keep the FFT, which the GPU
        # timings (benchmarks/results/bench_gpu.md) favour there
        if dim <= 2 or backend == "cpu":
            costs["direct"] = direct_cost(shape, thresholds, ca.neighbourhood)
        # matrix products only on CPU and for one species (K > 1: slower than the FFT's
        # batched transforms at most sizes)
        if exact_matmul and dim >= 2 and ca.n_species == 1 and backend == "cpu":
            costs["matmul"] = matmul_cost(shape, extent)
        method = min(costs, key=costs.get)
    direct = method == "direct"
    return YoungPlan(method, combined or method == "matmul", thresholds if direct else None, count_dtype,
                     extent if method == "matmul" else 0, keys, vector_width(shape[-1]) if direct else 0)


def direct_cost(shape, thresholds, neighbourhood: str) -> float:
    """Estimated microseconds a step of the direct sums for every species."""
    dim, n = len(shape), int(np.prod(shape))
    per_add = max(NS_ADD, NS_ADD_SMALL * (4096 / n) ** (1 / 3))
    total = US_DIRECT
    for t in thresholds:
        adds = direct_adds(t, dim, neighbourhood)
        fused = adds - 2 * max(half_width(x, neighbourhood) for x in t)
        scalar = fused > (FUSED_ADDS_2D if dim == 2 else FUSED_ADDS)
        total += 1e-3 * n * adds * per_add * (SCALAR_PENALTY if scalar else 1.0)
    return total


def fft_cost(n: int, n_species: int, combined: bool) -> float:
    """Estimated microseconds a step of the FFT counting of `n_species` on `n` cells."""
    return US_FFT + 1e-3 * NS_FFT * n * math.log2(max(n, 2)) * n_species * (1.0 if combined else 1.5)


def matmul_cost(shape, extent: int) -> float:
    """Estimated microseconds a step of one species' convolution by matrix products."""
    n = int(np.prod(shape))
    return US_MATMUL + 1e-3 * n * max(NS_MATMUL, NS_MAC * (2 * sum(shape[1:]) + 2 * extent + 1))

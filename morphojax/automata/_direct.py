"""Direct counting: exact neighbour counts as byte sums of shifted slices.

The lattice is padded periodically and each neighbourhood summed from shifted slices of
the padded copy, sharing partial sums between neighbourhoods. Partial sums stay in bytes
while their bound allows (four times the lanes of int32), and the last axis is computed
over whole vectors: the lattice is carried widened periodically to `vector_width` along
its last axis (XLA:CPU finishes a row's remainder one element at a time, so a lattice
whose rows are not whole vectors would run its sums and update in scalar code).
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from ._geometry import cross_section, half_width

LANE_BYTES = 32  # one AVX2 vector: the last axis of the direct sums is computed in whole vectors
NARROW = jnp.uint8  # partial sums stay in bytes while their bound allows (4x the lanes of int32)


def vector_width(n: int) -> int:
    """`n` rounded up to whole vectors of byte sums (the direct method's carried width)."""
    lane = max(1, LANE_BYTES // jnp.dtype(NARROW).itemsize)
    return -(-n // lane) * lane


def widen(cells: Array, width: int) -> Array:
    """`cells` with its last axis extended periodically to `width`."""
    pad = width - cells.shape[-1]
    return jnp.pad(cells, [(0, 0)] * (cells.ndim - 1) + [(0, pad)], mode="wrap") if pad else cells


def ball_sums(ind: Array, thresholds, extent: int, neighbourhood: str, dtype=jnp.int32) -> dict:
    """Exact neighbour counts of `ind` (0/1) over balls {o : dist(o) <= T} for each threshold
    T, by sums of shifted slices of a periodically padded copy; results in `dtype`.

    A ball is the sum over its last-axis offsets of lower-dimensional balls (shifted),
    down to runs along the first axis (shifted slices there are contiguous blocks, which
    sum faster than runs along the rows), built incrementally; sub-results are shared
    between thresholds, so a disc costs about (number of distinct cross-sections) x
    (width) adds. Partial sums are kept in bytes while their largest value (the number of
    offsets they cover) fits, and the last axis is computed over whole vectors: the
    results' last axis is `vector_width` of the lattice's (the extra entries repeat the
    lattice periodically).
    """
    d, shape = ind.ndim, ind.shape
    width = vector_width(shape[-1])
    pads = [(extent, extent)] * (d - 1) + [(extent, extent + width - shape[-1])]
    xp = jnp.pad(ind.astype(NARROW), pads, mode="wrap")
    memo: dict = {}
    limit = int(jnp.iinfo(NARROW).max)

    def add(a, b):  # (array, bound) pairs; widened before the bound could overflow bytes
        (x, bx), (y, by) = a, b
        if bx + by > limit:
            x, y = x.astype(dtype), y.astype(dtype)
        return x + y, bx + by

    size = list(shape[:-1]) + [width]  # each axis once cropped

    def run(h):  # sums along the first axis, width 2h + 1; other axes still padded
        if ("run", h) not in memo:
            sl = lambda o: (xp[extent + o: extent + o + size[0]], 1)
            memo[("run", h)] = sl(0) if h == 0 else add(add(run(h - 1), sl(-h)), sl(h))
        return memo[("run", h)]

    def ball(axis, res):  # axes <= axis cropped, axes > axis padded
        if (axis, res) not in memo:
            m = half_width(res, neighbourhood)
            if axis == 0:
                memo[(axis, res)] = run(m)
            else:
                total = None
                for o in range(-m, m + 1):
                    sub, bound = ball(axis - 1, cross_section(res, o, neighbourhood))
                    idx = (slice(None),) * axis + (slice(extent + o, extent + o + size[axis]),)
                    total = (sub[idx], bound) if total is None else add(total, (sub[idx], bound))
                memo[(axis, res)] = total
        return memo[(axis, res)]

    return {t: ball(d - 1, t)[0].astype(dtype) for t in thresholds}


def direct_adds(thresholds, dim: int, neighbourhood: str) -> int:
    """Number of array additions `ball_sums` performs (for the cost model)."""
    seen: set = set()

    def walk(axis, res):
        if (axis, res) in seen:
            return 0
        seen.add((axis, res))
        m = half_width(res, neighbourhood)
        if axis == dim - 1:
            return 0
        return 2 * m + sum(walk(axis + 1, cross_section(res, o, neighbourhood)) for o in range(-m, m + 1))

    runs = max((half_width(t, neighbourhood) for t in thresholds), default=0) * 2
    return runs + sum(walk(0, t) for t in thresholds)


def direct_fields(cells: Array, n: int, thresholds, a, b, neighbourhood: str, include_self: bool,
                  count_dtype) -> Array:
    """Exact integer fields a_j n_act + b_j n_ring, shape (K, *carried lattice), of the
    lattice carried widened to whole vectors (`n`: the lattice's last side), for the
    per-species ((T_act, T_inh), ...) `thresholds` and integer weights `a`, `b`. The
    sums and the update run over the widened rows too, so that they stay vector code."""
    dtype = jnp.dtype(count_dtype)
    extent = max(half_width(t, neighbourhood) for _, t in thresholds)
    out = []
    for j, (t_act, t_inh) in enumerate(thresholds):
        sums = ball_sums(cells[..., :n] == j, sorted({t_act, t_inh}), extent, neighbourhood, dtype)
        n_act = sums[t_act].astype(jnp.int32)
        n_ring = sums[t_inh].astype(jnp.int32) - n_act
        if not include_self:
            n_act = n_act - (cells == j).astype(jnp.int32)
        out.append(a[j] * n_act + b[j] * n_ring)
    return jnp.stack(out)

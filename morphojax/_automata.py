"""Young's activator-inhibitor cellular automaton in any dimension, with K species.

Cells hold an integer state: 0 .. K-1 are the K differentiated species and K is the
undifferentiated state (for Young's original K = 1: 0 = differentiated, 1 = not; note
that this is the reverse of the 0/1 coding in the Python code of paper 003, use
`1 - cells` to convert). Species j has an activator neighbourhood of radius r_act[j]
with weight w_act[j] > 0 and an inhibitor ring r_act[j] < d <= r_inh[j] with weight
w_inh[j] < 0. Its net field at a cell is

    W_j = w_act[j] * (# cells of species j in the activator disc)
        + w_inh[j] * (# cells of species j in the inhibitor ring)

and the synchronous update (paper 002, eqs. 1-4) is: the species with the largest W_j
wins when that maximum is > 0 (the lowest index on a tie between species), the cell
becomes undifferentiated when the maximum is < 0, and keeps its state when it is 0.

Units and conventions:
- radii are in lattice cells (Euclidean distance for `neighbourhood="disc"`, the
  Chebyshev distance max|dx_i| for Young's square boxes, `"box"`); an offset at squared
  distance d2 belongs to the disc of radius r when d2 <= r^2 (1 + 1e-6), so a radius
  typed as 3 or 1.4142135 includes the shell at exactly that distance;
- the cell itself is not a neighbour unless `include_self=True` (then it counts in the
  activator disc, as in Young's code);
- boundaries are periodic and every side of the lattice must be at least
  2 floor(r_inh) + 1 cells, so that no neighbour is counted twice;
- weights are compared exactly: they are read as fractions over a common `denominator`
  (by default the smallest one that makes every weight's shortest decimal form an
  integer, e.g. 5 for 1 and -0.2) and the fields are computed as integers, so a tie such
  as 3 x 1 + 15 x (-0.2) = 0 is an exact zero and keeps the state.

Neighbour counts are exact integers, computed by sums of shifted slices of a
periodically padded copy (`method="direct"`, fastest for Young's radii in 2D and in 3D
from 30^3: byte sums over whole vectors, the lattice carried widened periodically to a
multiple of 32 cells along its last axis), by FFT convolution with kernel spectra computed
once per run (`method="fft"`, fastest for large radii, and the only method for traced
radii), or by real separable Fourier transforms as matrix products on every
axis but the first, with the kernel's few offsets along the first axis summed directly
(`method="matmul"`, fast for small 3D lattices on CPU, where matrix products run near the
core's peak and the FFT does not); the last two are rounded to integers. `method="auto"`
picks the cheapest from a cost model; all give identical results.
"""

from __future__ import annotations

import abc
import functools
import math
from fractions import Fraction
from typing import Callable, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._checks import check_choice, check_count, check_range, is_concrete

YOUNG_P = 0.015  # Young's probability that a cell starts differentiated
NEIGHBOURHOODS = ("disc", "box")
METHODS = ("auto", "direct", "fft", "matmul")
_SLACK = 1e-6  # relative slack on the radii, see the module docstring
_MAX_DENOMINATOR = 10**6
_INT32_MAX = 2**31 - 1
# float32 FFT convolution: the kernel may carry integer weights (one transform pair per
# species) while the sum of their magnitudes keeps the rounding error far below 1/2;
# otherwise the activator and ring counts are transformed separately (each exact).
_FFT_ERROR_SCALE = 4.0 * float(np.finfo(np.float32).eps)
# Cost model of `method="auto"`, microseconds a step for N cells, fitted on a 2-core x86
# CPU (AVX2, XLA:CPU; benchmarks/bench_automata.py --methods, results/bench_automata.md):
# - direct: 10 us + N x adds x max(0.035, 0.1 (4096 / N)^(1/3)) ns (byte adds over whole
#   vectors; the cost of an add falls with N as XLA:CPU splits larger loops over both
#   cores), x13 once a species' last fused sum (its adds beyond the runs along the first
#   axis) exceeds 30 adds in 2D or 130 in 3D and more: XLA:CPU then emits that fusion as
#   scalar code (measured from r_inh = 15 in 2D, 8 in 3D; the lattice's width rounding
#   measured as no extra cost);
# - fft: 25 us + 0.4 ns x N log2 N per transform pair (1.5 pairs a species when the
#   activator and ring counts are transformed separately);
# - matmul (K = 1, CPU only): 5 us + N x max(6.5, 0.013 x multiply-adds per cell) ns.
_US_DIRECT, _NS_ADD, _NS_ADD_SMALL, _SCALAR_PENALTY = 10.0, 0.035, 0.1, 13.0
_FUSED_ADDS_2D, _FUSED_ADDS = 30, 130  # (1D: nothing is fused beyond the runs)
_US_FFT, _NS_FFT = 25.0, 0.4
_US_MATMUL, _NS_MATMUL, _NS_MAC = 5.0, 6.5, 0.013


# ---- small public helpers ----------------------------------------------------------------
def random_cells(key, shape, k: int = 1, p=None, dtype=jnp.int8) -> Array:
    """A random initial lattice of states 0..k (k = undifferentiated).

    With `p` (Young: p = 0.015, `YOUNG_P`) each cell is differentiated with probability p
    and then of a species drawn uniformly among the k; with `p=None` every cell is
    uniform over the k + 1 states (the well-mixed start of paper 002). `key` is a
    `jax.random` key; `p` may be traced (vmap over keys and p works).
    """
    shape = tuple(int(s) for s in shape)
    check_range(k, "random_cells.k (number of species)", low=1, high=int(jnp.iinfo(dtype).max) - 1)
    k = int(k)
    if p is None:
        return jax.random.randint(key, shape, 0, k + 1).astype(dtype)
    check_range(p, "random_cells.p (probability of a differentiated cell)", low=0.0, high=1.0)
    k_diff, k_species = jax.random.split(key)
    differentiated = jax.random.uniform(k_diff, shape) < p
    species = jax.random.randint(k_species, shape, 0, k)
    return jnp.where(differentiated, species, k).astype(dtype)


@functools.partial(jax.jit, static_argnames="k")
def volume_fractions(cells, k: int) -> Array:
    """Fraction of the lattice in each state 0..k: shape (k + 1,), summing to 1."""
    cells = jnp.asarray(cells)
    return jnp.stack([jnp.mean(cells == j) for j in range(int(k) + 1)])


@functools.partial(jax.jit, static_argnames="k")
def order_parameter(cells, k: int) -> Array:
    """Paper 002's order parameter (eq. 5), one entry per state 0..k, for any dimension.

    eps_j = | sum_c sum_{n in N(c)} s_j(c) s_j(n) | / (2 d N), with s_j = +1 on state j
    and -1 elsewhere, N(c) the 2d direct (von Neumann) neighbours on the periodic lattice
    and N the number of cells. It is 1 for a lattice fully taken by one state and near
    (2 f - 1)^2 for independent random cells with state fraction f (so near 0 for a
    50/50 mix); well-segregated patterns lie in between.
    """
    cells = jnp.asarray(cells)
    out = []
    for j in range(int(k) + 1):
        s = jnp.where(cells == j, 1, -1).astype(jnp.int32)
        # exact integer sums; each unordered neighbour pair appears twice in the double sum
        total = sum(jnp.sum(s * jnp.roll(s, 1, axis=a)) for a in range(cells.ndim))
        out.append(jnp.abs(total).astype(jnp.result_type(float)) / (cells.ndim * cells.size))
    return jnp.stack(out)


def changed_fraction(old, new) -> Array:
    """Fraction of cells whose state differs between two lattices (of the same shape)."""
    old, new = jnp.asarray(old), jnp.asarray(new)
    if old.shape != new.shape:
        raise ValueError(f"changed_fraction: the lattices must have the same shape (got {old.shape} and {new.shape})")
    return jnp.mean(old != new)


def has_converged(old, new, threshold=0.01) -> Array:
    """Paper 002's convergence test: fewer than `threshold` (1%) of the cells changed."""
    return changed_fraction(old, new) < threshold


def one_hot_cells(cells, k: int, dtype=None) -> Array:
    """Integer cells as state probabilities of shape (k + 1, *lattice) for the soft step."""
    cells = jnp.asarray(cells)
    dtype = jnp.result_type(float) if dtype is None else dtype
    return jnp.moveaxis(jax.nn.one_hot(cells, int(k) + 1, dtype=dtype), -1, 0)


def hard_cells(probs, dtype=jnp.int8) -> Array:
    """The most probable state of each cell (inverse of `one_hot_cells`)."""
    return jnp.argmax(probs, axis=0).astype(dtype)


def _call(obj, name: str, *args):
    """`obj.name(*args)` without the equinox bound-method module that attribute access
    builds (~40 us each: a third of a small run's Python overhead)."""
    return getattr(type(obj), name)(obj, *args)


# ---- the shared loop ---------------------------------------------------------------------
class AutomatonRun(eqx.Module):
    """What `run` returns.

    cells: the final lattice. steps: the number of updates applied. converged: whether
    the last update changed fewer than `threshold` of the cells. changes (with
    `history=True`, else None): the fraction of cells changed by each update, shape
    (steps requested,), NaN after an early stop. frames / frame_steps (with `save_every`,
    else None): the lattice every `save_every` updates (frame 0 is the start) and the
    update count of each frame (-1 for frames not reached before an early stop).
    """

    cells: Array
    steps: Array
    converged: Array
    changes: Array | None = None
    frames: Array | None = None
    frame_steps: Array | None = None


class _Codec(NamedTuple):
    """How a stepper carries the lattice through the loop: `encode` maps integer cells
    to the carried form (which may be wider than the lattice) and `decode` maps it back
    to the cells, of `dtype` (decode(encode(c)) == c; changed cells are counted on the
    decoded lattice)."""

    encode: Callable
    decode: Callable


def _identity_codec(dtype) -> _Codec:
    return _Codec(lambda c: c, lambda c: c.astype(dtype))


def _iterate(step_fn: Callable, cells, steps: int, stop: bool, threshold, save_every: int | None,
             history: bool, codec: _Codec | None = None) -> AutomatonRun:
    """Apply `step_fn` `steps` times in one compiled loop: a `lax.scan`, or a
    `lax.while_loop` that stops at convergence when `stop`. `step_fn` works on the
    carried form of `codec` (default: the integer cells themselves)."""
    codec = _identity_codec(cells.dtype) if codec is None else codec
    dtype, shape, cells = cells.dtype, cells.shape, codec.encode(cells)
    # "last": the changed fraction of the latest update. A plain run counts it in its final
    # update only (the first steps - 1 run in a lean scan: no count, no copy of the lattice)
    carry = {"i": jnp.int32(0), "cells": cells, "last": jnp.float32(1.0)}
    if history:
        carry["changes"] = jnp.full((steps,), jnp.nan, jnp.float32)
    if save_every:
        n_frames = steps // save_every + 1
        carry["frames"] = jnp.zeros((n_frames,) + shape, dtype).at[0].set(codec.decode(cells))
        carry["frame_steps"] = jnp.full((n_frames,), -1, jnp.int32).at[0].set(0)

    def body(carry, count=True):
        carry = dict(carry)
        i, c = carry["i"], carry["cells"]
        new = step_fn(c)
        if count:
            carry["last"] = frac = jnp.mean(codec.decode(new) != codec.decode(c)).astype(jnp.float32)
            if history:
                carry["changes"] = carry["changes"].at[i].set(frac)
        i = i + 1
        if save_every:
            slot, save = i // save_every, (i % save_every) == 0
            carry["frames"] = carry["frames"].at[slot].set(jnp.where(save, codec.decode(new), carry["frames"][slot]))
            carry["frame_steps"] = carry["frame_steps"].at[slot].set(jnp.where(save, i, carry["frame_steps"][slot]))
        carry.update(i=i, cells=new)
        return carry

    if steps > 0 and stop:
        carry = jax.lax.while_loop(lambda c: (c["i"] < steps) & (c["last"] >= threshold), body, carry)
    elif steps > 0:
        lean = steps - 1 if not history else 0
        if lean:
            carry = jax.lax.scan(lambda c, _: (body(c, count=False), None), carry, None, length=lean)[0]
        carry = jax.lax.scan(lambda c, _: (body(c), None), carry, None, length=steps - lean)[0]
    converged = (carry["last"] < threshold) & (carry["i"] > 0)
    return AutomatonRun(codec.decode(carry["cells"]), carry["i"], converged, carry.get("changes"),
                        carry.get("frames"), carry.get("frame_steps"))


class AbstractAutomaton(eqx.Module):
    """A synchronous cellular automaton on a periodic integer lattice of any dimension.

    Subclasses provide `n_states`, `_plan(shape)` (static, hashable configuration worked
    out from concrete parameters before compiling) and `_stepper(plan, shape)` (called
    inside the compiled function once per run, so precomputation such as kernel spectra
    happens once, and returning the one-step function; given `_precomputed(plan, shape)`
    it uses those arrays instead). The step works on the form of the lattice that
    `_codec(plan, shape, dtype)` gives (by default the integer cells).
    """

    @property
    @abc.abstractmethod
    def n_states(self) -> int:
        """Number of cell states (values 0 .. n_states - 1)."""

    @abc.abstractmethod
    def _plan(self, shape: tuple[int, ...]):
        ...

    @abc.abstractmethod
    def _stepper(self, plan, shape: tuple[int, ...], pre=None) -> Callable[[Array], Array]:
        ...

    def _codec(self, plan, shape, dtype) -> _Codec:
        return _identity_codec(dtype)

    def _precomputed(self, plan, shape):
        """Arrays the step needs that depend only on concrete parameters and the lattice
        (kernel spectra), computed once and reused across calls; None: `_stepper`
        computes them inside the compiled function (traced parameters)."""
        return None

    def _check_cells(self, cells) -> Array:
        name = f"{type(self).__name__} cells"
        if isinstance(cells, (list, tuple)):
            cells = np.asarray(cells)
        dtype = getattr(cells, "dtype", None)
        if dtype is None or dtype == bool or not jnp.issubdtype(dtype, jnp.integer):
            raise ValueError(f"{name} must be an integer array of states 0..{self.n_states - 1} (got dtype {dtype})")
        if cells.ndim < 1:
            raise ValueError(f"{name} must have at least one dimension (got a scalar)")
        if is_concrete(cells):
            arr = np.asarray(cells)
            if arr.size and (arr.min() < 0 or arr.max() > self.n_states - 1):
                raise ValueError(
                    f"{name} must hold states in [0, {self.n_states - 1}] (got min {arr.min()}, max {arr.max()})"
                )
        return jnp.asarray(cells)

    def step(self, cells) -> Array:
        """One synchronous update of an integer lattice; returns the same dtype."""
        cells = _call(self, "_check_cells", cells)
        plan = _call(self, "_plan", cells.shape)
        return _jit_step(self, cells, _call(self, "_precomputed", plan, cells.shape), plan=plan)

    def run(self, cells, steps: int, *, stop_at_convergence: bool = False, threshold=0.01,
            save_every: int | None = None, history: bool = False) -> AutomatonRun:
        """`steps` synchronous updates in one compiled loop, or fewer with
        `stop_at_convergence=True`: then the loop stops after the first update that
        changed fewer than `threshold` (paper 002: 1%) of the cells. `save_every` keeps a
        snapshot every that many updates (`AutomatonRun.frames`); `history` records the
        fraction of changed cells of every update (`AutomatonRun.changes`)."""
        cells = _call(self, "_check_cells", cells)
        check_count(steps, "run.steps", "updates")
        check_range(threshold, "run.threshold (fraction of changed cells)", low=0.0, high=1.0)
        if save_every is not None:
            check_count(save_every, "run.save_every", "updates", low=1)
            save_every = int(save_every)
        plan = _call(self, "_plan", cells.shape)
        threshold = np.float32(threshold) if is_concrete(threshold) else jnp.asarray(threshold, jnp.float32)
        pre = _call(self, "_precomputed", plan, cells.shape)
        return _jit_run(self, cells, pre, threshold, steps=int(steps), plan=plan, stop=bool(stop_at_convergence),
                        save_every=save_every, history=bool(history))


# plain jax.jit (the automaton is a pytree of arrays, its configuration static in the
# treedef): ~0.2 ms a call against ~1 ms through filter_jit, 5% of 100 steps at L = 30
@functools.partial(jax.jit, static_argnames=("plan",))
def _jit_step(automaton, cells, pre, *, plan):
    codec = automaton._codec(plan, cells.shape, cells.dtype)
    return codec.decode(automaton._stepper(plan, cells.shape, pre)(codec.encode(cells)))


@functools.partial(jax.jit, static_argnames=("steps", "plan", "stop", "save_every", "history"))
def _jit_run(automaton, cells, pre, threshold, *, steps, plan, stop, save_every, history):
    return _iterate(automaton._stepper(plan, cells.shape, pre), cells, steps, stop, threshold, save_every, history,
                    automaton._codec(plan, cells.shape, cells.dtype))


# ---- exact weights -----------------------------------------------------------------------
def _decimal_fraction(value) -> Fraction:
    """The shortest decimal that rounds to `value` in its own precision, as a Fraction."""
    return Fraction(np.format_float_positional(value, unique=True, trim="0"))


def _common_denominator(values) -> int:
    den = 1
    for v in np.asarray(values).ravel():
        den = math.lcm(den, _decimal_fraction(v).denominator)
    return den


# ---- neighbourhood geometry --------------------------------------------------------------
def _threshold(r, neighbourhood: str):
    """Largest squared distance (disc) or Chebyshev distance (box) inside radius r; works
    on NumPy and on (traced) JAX values in the array's own precision."""
    xp = jnp if isinstance(r, jax.Array) else np
    one = r.dtype.type(1.0 + _SLACK) if hasattr(r, "dtype") else 1.0 + _SLACK
    return xp.floor(r * r * one) if neighbourhood == "disc" else xp.floor(r * one)


def _half_width(res: int, neighbourhood: str) -> int:
    return math.isqrt(res) if neighbourhood == "disc" else res


def _lattice_distance(shape, neighbourhood: str) -> np.ndarray:
    """Minimal-image squared distance (disc) or Chebyshev distance (box) of every lattice
    offset from the origin, as a float32 array of the lattice shape."""
    grids = np.meshgrid(*[np.minimum(np.arange(n), n - np.arange(n)) for n in shape], indexing="ij")
    if neighbourhood == "disc":
        dist = sum(g.astype(np.int64) ** 2 for g in grids)
    else:
        dist = np.max(np.stack(grids), axis=0)
    return dist.astype(np.float32)


def _ball_size(res: int, dim: int, neighbourhood: str) -> int:
    """Number of lattice offsets (origin included) within threshold `res` in `dim` dims."""
    return (2 * res + 1) ** dim if neighbourhood == "box" else _disc_size(dim, res)


@functools.lru_cache(maxsize=None)
def _disc_size(dim: int, r2: int) -> int:
    m = math.isqrt(r2)
    if dim == 1:
        return 2 * m + 1
    return sum(_disc_size(dim - 1, r2 - o * o) for o in range(-m, m + 1))


_LANE_BYTES = 32  # one AVX2 vector: the last axis of the direct sums is computed in whole vectors
_NARROW = jnp.uint8  # partial sums stay in bytes while their bound allows (4x the lanes of int32)


def _vector_width(n: int) -> int:
    """`n` rounded up to whole vectors of byte sums (the direct method's carried width)."""
    lane = max(1, _LANE_BYTES // jnp.dtype(_NARROW).itemsize)
    return -(-n // lane) * lane


def _widen(cells: Array, width: int) -> Array:
    """`cells` with its last axis extended periodically to `width`."""
    pad = width - cells.shape[-1]
    return jnp.pad(cells, [(0, 0)] * (cells.ndim - 1) + [(0, pad)], mode="wrap") if pad else cells


def _ball_sums(ind: Array, thresholds, extent: int, neighbourhood: str, dtype=jnp.int32) -> dict:
    """Exact neighbour counts of `ind` (0/1) over balls {o : dist(o) <= T} for each threshold
    T, by sums of shifted slices of a periodically padded copy; results in `dtype`.

    A ball is the sum over its last-axis offsets of lower-dimensional balls (shifted),
    down to runs along the first axis (shifted slices there are contiguous blocks: ~10%
    faster than runs along the rows at 30^3), built incrementally; sub-results are shared
    between thresholds, so a disc costs about (number of distinct cross-sections) x
    (width) adds. Partial sums are kept in bytes while their largest value (the number of
    offsets they cover) fits, and the last axis is computed over whole vectors: the
    results' last axis is `_vector_width` of the lattice's (the extra entries repeat the
    lattice periodically). XLA:CPU finishes a row's remainder one element at a time, which
    made a 30^3 lattice cost twice 32^3.
    """
    d, shape = ind.ndim, ind.shape
    width = _vector_width(shape[-1])
    pads = [(extent, extent)] * (d - 1) + [(extent, extent + width - shape[-1])]
    xp = jnp.pad(ind.astype(_NARROW), pads, mode="wrap")
    memo: dict = {}
    limit = int(jnp.iinfo(_NARROW).max)

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
            m = _half_width(res, neighbourhood)
            if axis == 0:
                memo[(axis, res)] = run(m)
            else:
                total = None
                for o in range(-m, m + 1):
                    sub, bound = ball(axis - 1, res - o * o if neighbourhood == "disc" else res)
                    idx = (slice(None),) * axis + (slice(extent + o, extent + o + size[axis]),)
                    total = (sub[idx], bound) if total is None else add(total, (sub[idx], bound))
                memo[(axis, res)] = total
        return memo[(axis, res)]

    return {t: ball(d - 1, t)[0].astype(dtype) for t in thresholds}


def _direct_adds(thresholds, dim: int, neighbourhood: str) -> int:
    """Number of array additions `_ball_sums` performs (for the cost model)."""
    seen: set = set()

    def walk(axis, res):
        if (axis, res) in seen:
            return 0
        seen.add((axis, res))
        m = _half_width(res, neighbourhood)
        if axis == dim - 1:
            return 0
        return 2 * m + sum(walk(axis + 1, res - o * o if neighbourhood == "disc" else res) for o in range(-m, m + 1))

    runs = max((_half_width(t, neighbourhood) for t in thresholds), default=0) * 2
    return runs + sum(walk(0, t) for t in thresholds)


class _YoungPlan(NamedTuple):
    """Static configuration of the counting, worked out before compiling."""

    method: str  # "direct", "fft" or "matmul"
    combined: bool  # fft / matmul: one weighted kernel per species (else separate counts)
    thresholds: tuple | None  # direct: ((T_act, T_inh), ...) per species
    count_dtype: str
    extent: int = 0  # matmul: the kernels' half-width along the first axis
    keys: bool = False  # K > 1: the update picks the largest packed key W_j (K + 1) + K - j (int32)
    width: int = 0  # direct: the carried lattice's last axis, widened periodically to whole vectors


# ---- the automaton -----------------------------------------------------------------------
class YoungCA(AbstractAutomaton):
    """Young's activator-inhibitor automaton with K species (paper 002 eqs. 1-4).

        ca = YoungCA(species=[(3.2, 6.0, 1.0, -0.2)])        # (r_act, r_inh, w_act, w_inh)
        cells = random_cells(jax.random.key(0), (30, 30, 30), k=1, p=None)
        out = ca.run(cells, 100, stop_at_convergence=True)   # out.cells, out.steps

    Radii are in lattice cells; weights are the net activation (> 0) and inhibition (< 0)
    field of one differentiated cell. `neighbourhood` is "disc" (Euclidean, paper 002) or
    "box" (Young's square boxes as in paper 003's code); `include_self` counts the cell
    itself in its activator disc. Paper 003's code, which sums the inhibitor over the
    whole box (self included) and writes WS = Na wa - Ni wi, is
    `YoungCA([(Ra, Ri, wa - wi, -wi)], "box", include_self=True)`.

    The radii and weights are float array leaves of shape (K,), so a model can be
    vmapped over (stack several models, or build it inside vmap with an explicit
    `denominator`), and the soft relaxation `soft_step` is differentiable in all of them.
    `denominator` (an integer leaf) is the common denominator the weights are compared
    over, exactly, as the integers round(w x denominator); by default the smallest one for
    the weights' decimal forms (at most 10^6). `method` picks the counting ("auto",
    "direct", "fft" or "matmul"; all exact and identical).
    """

    r_act: Array
    r_inh: Array
    w_act: Array
    w_inh: Array
    denominator: Array
    neighbourhood: str = eqx.field(static=True)
    include_self: bool = eqx.field(static=True)
    method: str = eqx.field(static=True)

    def __init__(self, species, neighbourhood: str = "disc", include_self: bool = False, *,
                 denominator=None, method: str = "auto"):
        dtype = jnp.result_type(float)
        # Python or NumPy numbers are read on the host, so that the default denominator can
        # be worked out even when the model is built inside jit / vmap
        host = not any(isinstance(leaf, jax.Array) for leaf in jax.tree_util.tree_leaves(species))
        xp = np if host else jnp
        if isinstance(species, (list, tuple)):
            if len(species) == 0:
                raise ValueError("YoungCA.species needs at least one (r_act, r_inh, w_act, w_inh) tuple")
            rows = []
            for i, sp in enumerate(species):
                if not isinstance(sp, (list, tuple, np.ndarray, jax.Array)) or len(sp) != 4:
                    raise ValueError(f"YoungCA.species[{i}] must be a tuple (r_act, r_inh, w_act, w_inh) (got {sp!r})")
                rows.append(xp.stack([xp.asarray(v, dtype=dtype) for v in sp]))
            table = xp.stack(rows)
        else:
            table = xp.asarray(species, dtype=dtype)
            if table.ndim != 2 or table.shape[1] != 4:
                raise ValueError(f"YoungCA.species must have shape (K, 4) (got {table.shape})")
        self.r_act, self.r_inh, self.w_act, self.w_inh = (jnp.asarray(table[:, i]) for i in range(4))
        check_choice(neighbourhood, "YoungCA.neighbourhood", NEIGHBOURHOODS)
        check_choice(method, "YoungCA.method", METHODS)
        self.neighbourhood = neighbourhood
        self.include_self = bool(include_self)
        self.method = method
        if denominator is None:
            if not (host or is_concrete(table)):
                raise ValueError(
                    "YoungCA.denominator must be given when the weights are traced (inside jit/vmap): "
                    "weights are compared exactly as integers over it, e.g. denominator=100 for two decimals"
                )
            denominator = _common_denominator(np.asarray(table)[:, 2:])
            if denominator > _MAX_DENOMINATOR:
                raise ValueError(
                    f"YoungCA weights must be decimals with a common denominator <= {_MAX_DENOMINATOR} "
                    f"(at most 6 decimal places; got common denominator {denominator}); round them or "
                    "pass an explicit denominator="
                )
        if is_concrete(denominator) and np.any(np.asarray(denominator) != np.round(np.asarray(denominator, float))):
            raise ValueError(f"YoungCA.denominator must be a whole number (got {denominator!r})")
        self.denominator = jnp.asarray(denominator, dtype=jnp.int32)

    def __check_init__(self):
        k = self.r_act.shape[0]
        if k > 126:
            raise ValueError(f"YoungCA.species: at most 126 species (got {k})")
        for name in ("r_act", "r_inh", "w_act", "w_inh"):
            v = getattr(self, name)
            if is_concrete(v) and not np.isfinite(np.asarray(v)).all():
                raise ValueError(f"YoungCA.{name} must be finite (got {np.asarray(v)})")
        check_range(self.r_act, "YoungCA.r_act (activator radius, lattice cells)", low=0.0)
        check_range(self.w_act, "YoungCA.w_act (activator weight)", low=0.0, low_open=True)
        check_range(self.w_inh, "YoungCA.w_inh (inhibitor weight)", high=0.0, high_open=True)
        if is_concrete(self.r_act, self.r_inh):
            ra, ri = np.asarray(self.r_act), np.asarray(self.r_inh)
            if (ri < ra).any():
                j = int(np.argmax(ri < ra))
                raise ValueError(
                    f"YoungCA.r_inh (inhibitor radius, lattice cells) must lie in [r_act, +inf) for every "
                    f"species; species {j} has r_inh {ri[j]:g} < r_act {ra[j]:g}"
                )
        check_range(self.denominator, "YoungCA.denominator", low=1, high=_MAX_DENOMINATOR)
        if is_concrete(self.w_act, self.w_inh, self.denominator):
            den = int(self.denominator)
            for name in ("w_act", "w_inh"):
                value = np.asarray(getattr(self, name))
                scaled = value.astype(np.float64) * den
                if (np.abs(scaled) >= 2**24).any():
                    raise ValueError(
                        f"YoungCA.{name} x denominator must stay below 2^24 in magnitude (exact in float32); "
                        f"got {value} x {den}"
                    )
                # a multiple of 1/den stored in the weights' precision is within a few of its
                # ulps of one (a looser test would round a weight such as 1000.004 to 1000)
                tol = 4.0 * float(np.finfo(value.dtype).eps) * np.maximum(1.0, np.abs(scaled))
                if (np.abs(scaled - np.round(scaled)) > tol).any():
                    raise ValueError(
                        f"YoungCA.{name} must be multiples of 1/denominator = 1/{den} (got {np.asarray(getattr(self, name))})"
                    )

    # ---- description ------------------------------------------------------------------
    @property
    def n_species(self) -> int:
        return int(self.r_act.shape[0])

    @property
    def n_states(self) -> int:
        return self.n_species + 1

    @property
    def species(self) -> list[tuple[float, float, float, float]]:
        """The (r_act, r_inh, w_act, w_inh) tuples (concrete models only)."""
        cols = [np.asarray(getattr(self, n)) for n in ("r_act", "r_inh", "w_act", "w_inh")]
        return [tuple(float(_decimal_fraction(c[j])) for c in cols) for j in range(self.n_species)]

    def to_dict(self) -> dict:
        """Plain data to rebuild the model: `YoungCA(**ca.to_dict())`."""
        return {"species": [list(s) for s in self.species], "neighbourhood": self.neighbourhood,
                "include_self": self.include_self, "denominator": int(self.denominator), "method": self.method}

    def _thresholds(self) -> tuple:
        ra, ri = np.asarray(self.r_act), np.asarray(self.r_inh)
        return tuple((int(_threshold(a, self.neighbourhood)), int(_threshold(b, self.neighbourhood)))
                     for a, b in zip(ra, ri))

    def neighbour_counts(self, dim: int) -> np.ndarray:
        """Cells in each species' activator disc and inhibitor ring in `dim` dimensions,
        shape (K, 2) (the self cell counted in the disc only with include_self)."""
        out = []
        for t_act, t_inh in self._thresholds():
            n_act = _ball_size(t_act, dim, self.neighbourhood) - (0 if self.include_self else 1)
            out.append((n_act, _ball_size(t_inh, dim, self.neighbourhood) - _ball_size(t_act, dim, self.neighbourhood)))
        return np.array(out, dtype=np.int64)

    def _integer_weights(self):
        den = self.denominator.astype(self.w_act.dtype)
        a = jnp.round(self.w_act * den).astype(jnp.int32)
        b = jnp.round(self.w_inh * den).astype(jnp.int32)
        return a, b

    def _host_integer_weights(self) -> tuple[np.ndarray, np.ndarray]:
        """`_integer_weights` of a concrete model in NumPy (also while a jit traces a
        function that closes over the model, where jnp operations would give tracers)."""
        den = int(self.denominator)
        return tuple(np.round(np.asarray(w, np.float64) * den).astype(np.int64) for w in (self.w_act, self.w_inh))

    # ---- planning -----------------------------------------------------------------------
    def _key(self, shape):
        """What a plan and the kernel spectra depend on (None for traced parameters)."""
        if not is_concrete(self.r_act, self.r_inh, self.w_act, self.w_inh, self.denominator):
            return None
        return (type(self), self.neighbourhood, self.include_self, self.method, tuple(shape), int(self.denominator),
                *(np.asarray(getattr(self, n)).tobytes() for n in ("r_act", "r_inh", "w_act", "w_inh")),
                jax.default_backend())

    def _plan(self, shape) -> _YoungPlan:
        key = _call(self, "_key", shape)
        return self._make_plan(tuple(shape)) if key is None else _cached_plan(key, self)

    def _precomputed(self, plan, shape):
        size = (1 if plan.combined else 2) * self.n_species * math.prod(shape[:-1]) * (shape[-1] // 2 + 1)
        key = _call(self, "_key", shape) if plan.method != "direct" and size <= _SPECTRA_MAX_SIZE else None
        if key is None:  # traced, direct, or large (computing them in each run then costs little)
            return None
        if key not in _SPECTRA:
            # computed now even while a jit traces a function that closes over the model:
            # the cache must only ever hold concrete arrays
            with jax.ensure_compile_time_eval():
                spectra = _jit_spectra(self, plan=plan, shape=tuple(shape))
            if not is_concrete(spectra):  # pragma: no cover - defensive
                return None
            if len(_SPECTRA) >= 32:
                _SPECTRA.clear()
            _SPECTRA[key] = spectra
        return _SPECTRA[key]

    def _make_plan(self, shape) -> _YoungPlan:
        dim = len(shape)
        n = int(np.prod(shape))
        if not is_concrete(self.r_act, self.r_inh):
            if self.method == "direct":
                raise ValueError("YoungCA.method 'direct' needs concrete radii (the radii are traced); use 'fft'")
            return _YoungPlan("fft", False, None, "int32")
        thresholds = self._thresholds()
        extent = max(_half_width(t, self.neighbourhood) for _, t in thresholds)
        if min(shape) < 2 * extent + 1:
            raise ValueError(
                f"YoungCA cells: every side of the periodic lattice must be at least 2 floor(r_inh) + 1 = "
                f"{2 * extent + 1} cells so that no neighbour counts twice (got shape {tuple(shape)})"
            )
        counts = self.neighbour_counts(dim)
        ball = max(_ball_size(t, dim, self.neighbourhood) for _, t in thresholds)
        count_dtype = "int16" if ball < 2**15 else "int32"
        combined = keys = False
        if is_concrete(self.w_act, self.w_inh, self.denominator):
            a, b = (np.abs(x) for x in self._host_integer_weights())
            bound = int(np.max(a * counts[:, 0] + b * counts[:, 1]))
            if bound > _INT32_MAX:
                raise ValueError(
                    f"YoungCA: weights x denominator ({int(self.denominator)}) x neighbour counts overflow "
                    "32-bit integers; use weights with fewer decimals or smaller radii"
                )
            combined = bound * _FFT_ERROR_SCALE * max(1.0, math.log2(n)) < 0.1
            keys = self.n_species > 1 and bound * (self.n_species + 1) + self.n_species <= _INT32_MAX
            # matrix-product transforms: float32 sums as long as the transformed sides
            # (worst-case error growth; measured errors are ~1e-4, 400x below at 64^3)
            exact_matmul = bound * _FFT_ERROR_SCALE * max(1, sum(shape[1:])) < 0.1
        else:
            exact_matmul = False
        method = self.method
        if method == "matmul" and not exact_matmul:
            raise ValueError(
                "YoungCA.method 'matmul' needs concrete weights whose fields (weights x denominator x neighbour "
                "counts) stay small enough for exact float32 transforms; use 'fft' or 'direct'"
            )
        if method == "auto":
            costs = {"fft": _US_FFT + 1e-3 * _NS_FFT * n * math.log2(max(n, 2)) * self.n_species * (
                1.0 if combined else 1.5)}
            # the model is fitted on CPU; on GPUs 3D lattices keep the FFT, as measured on
            # an H100 (benchmarks/results/bench_gpu.md), until direct sums are timed there
            if dim <= 2 or jax.default_backend() == "cpu":
                costs["direct"] = self._direct_cost(shape, thresholds)
            # matrix products only pay on CPU, and only for one species (K > 1 measured
            # slower than the FFT's batched transforms at most sizes)
            if exact_matmul and dim >= 2 and self.n_species == 1 and jax.default_backend() == "cpu":
                costs["matmul"] = _matmul_cost(shape, extent)
            method = min(costs, key=costs.get)
        direct = method == "direct"
        return _YoungPlan(method, combined or method == "matmul", thresholds if direct else None, count_dtype,
                          extent if method == "matmul" else 0, keys, _vector_width(shape[-1]) if direct else 0)

    def _direct_cost(self, shape, thresholds) -> float:
        """Estimated microseconds a step of `_ball_sums` for every species (cost model)."""
        dim, n = len(shape), int(np.prod(shape))
        per_add = max(_NS_ADD, _NS_ADD_SMALL * (4096 / n) ** (1 / 3))
        total = _US_DIRECT
        for t in thresholds:
            adds = _direct_adds(t, dim, self.neighbourhood)
            fused = adds - 2 * max(_half_width(x, self.neighbourhood) for x in t)
            scalar = fused > (_FUSED_ADDS_2D if dim == 2 else _FUSED_ADDS)
            total += 1e-3 * n * adds * per_add * (_SCALAR_PENALTY if scalar else 1.0)
        return total

    # ---- counting -----------------------------------------------------------------------
    def _kernels(self, shape, edge=None):
        """Activator and ring kernels of shape (K, *shape) on the periodic lattice, from the
        (possibly traced) radii. `edge` > 0 gives a smooth membership (soft step)."""
        dist = jnp.asarray(_lattice_distance(shape, self.neighbourhood))
        bcast = (slice(None),) + (None,) * len(shape)
        centre = jnp.zeros(shape, bool).at[(0,) * len(shape)].set(True)
        if edge is None:
            t_act = _threshold(self.r_act, self.neighbourhood)[bcast]
            t_inh = _threshold(self.r_inh, self.neighbourhood)[bcast]
            in_act = (dist <= t_act).astype(dist.dtype)
            in_inh = (dist <= t_inh).astype(dist.dtype)
        else:
            d = jnp.sqrt(dist) if self.neighbourhood == "disc" else dist
            in_act = jax.nn.sigmoid((self.r_act[bcast] - d) / edge)
            in_inh = jax.nn.sigmoid((self.r_inh[bcast] - d) / edge)
        ring = jnp.maximum(in_inh - in_act, 0.0)
        act = in_act if self.include_self else jnp.where(centre, 0.0, in_act)
        return act, ring

    def _fields(self, cells, plan: _YoungPlan, spectra, n: int) -> Array:
        """Exact integer fields W_j x denominator, shape (K, *carried lattice), from the
        carried form of the cells (`_codec`); `n` is the lattice's last side."""
        k = self.n_species
        a, b = self._integer_weights()
        if plan.method == "direct":
            # the carried lattice is widened periodically to whole vectors along its last
            # axis, and so are the sums and the update: over rows of 30 XLA:CPU ran the
            # update, into which it fuses the last sums, element by element (0.24 against
            # 0.13 ms a step at 30^3, K = 1)
            dtype = jnp.dtype(plan.count_dtype)
            extent = max(_half_width(t, self.neighbourhood) for _, t in plan.thresholds)
            out = []
            for j, (t_act, t_inh) in enumerate(plan.thresholds):
                sums = _ball_sums(cells[..., :n] == j, sorted({t_act, t_inh}), extent, self.neighbourhood, dtype)
                n_act = sums[t_act].astype(jnp.int32)
                n_ring = sums[t_inh].astype(jnp.int32) - n_act
                if not self.include_self:
                    n_act = n_act - (cells == j).astype(jnp.int32)
                out.append(a[j] * n_act + b[j] * n_ring)
            return jnp.stack(out)
        ind = jnp.stack([(cells == j) for j in range(k)]).astype(jnp.float32)
        if plan.combined:
            return jnp.round(_convolve(ind, spectra, plan)).astype(jnp.int32)
        axes = tuple(range(1, cells.ndim + 1))
        f = jnp.fft.rfftn(ind, axes=axes)
        fs = jnp.concatenate([f, f])
        counts = jnp.round(jnp.fft.irfftn(_times_real(fs, spectra), s=cells.shape, axes=axes)).astype(jnp.int32)
        bc = (slice(None),) + (None,) * cells.ndim
        return a[bc] * counts[:k] + b[bc] * counts[k:]

    def _spectra(self, plan: _YoungPlan, shape):
        if plan.method == "direct":
            return None
        act, ring = self._kernels(shape)
        if plan.combined:
            a, b = self._integer_weights()
            bc = (slice(None),) + (None,) * len(shape)
            kernel = a[bc].astype(act.dtype) * act + b[bc].astype(act.dtype) * ring
        else:
            kernel = jnp.concatenate([act, ring])
        if plan.method == "matmul":
            return _matmul_spectra(kernel, plan.extent)
        axes = tuple(range(1, len(shape) + 1))
        return jnp.fft.rfftn(kernel, axes=axes).real  # even kernel: real spectrum

    def _binary(self, plan) -> bool:
        """One species with one weighted kernel: the loop carries the float indicator of
        species 0 straight into the transform (no conversions; ~10% of the step)."""
        return plan.method in ("fft", "matmul") and plan.combined and self.n_species == 1

    def _codec(self, plan, shape, dtype) -> _Codec:
        if plan.width > shape[-1]:  # direct counting: the lattice widened periodically
            return _Codec(lambda c: _widen(c, plan.width), lambda c: c[..., :shape[-1]].astype(dtype))
        if not self._binary(plan):
            return _identity_codec(dtype)
        return _Codec(lambda c: (c == 0).astype(jnp.float32),
                      lambda x: jnp.where(x > 0.5, 0, 1).astype(dtype))

    def _stepper(self, plan, shape, pre=None):
        spectra = self._spectra(plan, shape) if pre is None else pre
        k = self.n_species
        if self._binary(plan):
            def binary_step(ind):
                # W x denominator is an integer and the transform error is < 0.1 (plan):
                # W > 0 <=> w > 1/2 and W < 0 <=> w < -1/2, exactly
                w = _convolve(ind[None], spectra, plan)[0]
                return jnp.where(w > 0.5, 1.0, jnp.where(w < -0.5, 0.0, ind)).astype(ind.dtype)

            return binary_step

        def step(cells):
            w = self._fields(cells, plan, spectra, shape[-1])
            if plan.keys:
                # one packed key per species, W_j (K + 1) + K - j, and their maximum: the
                # largest field, the lowest species on a tie (as argmax). Made from the
                # stacked fields, XLA:CPU computes the direct sums once, in the stacking op;
                # argmax, or a best/winner chain over the species' fields, took 6-8x the
                # step (K = 3 at 250^2: the sums fused into the update, once per use)
                tags = (k - jnp.arange(k, dtype=w.dtype)).reshape((k,) + (1,) * cells.ndim)
                keys = w * (k + 1) + tags
                key = functools.reduce(jnp.maximum, [keys[j] for j in range(k)])
                best = jnp.floor_divide(key, k + 1)
                winner = (k - (key - best * (k + 1))).astype(cells.dtype)
            else:
                best, winner = w[0], jnp.zeros((), cells.dtype)
                for j in range(1, k):
                    winner = jnp.where(w[j] > best, jnp.asarray(j, cells.dtype), winner)
                    best = jnp.maximum(best, w[j])
            undiff = jnp.asarray(k, cells.dtype)
            return jnp.where(best > 0, winner, jnp.where(best < 0, undiff, cells))

        return step

    def fields(self, cells) -> Array:
        """The net fields W_j (K, *lattice) as exact multiples of 1/denominator (float)."""
        cells = _call(self, "_check_cells", cells)
        plan = _call(self, "_plan", cells.shape)
        w = _jit_fields(self, cells, _call(self, "_precomputed", plan, cells.shape), plan=plan)
        return w.astype(jnp.result_type(float)) / self.denominator.astype(jnp.result_type(float))

    # ---- differentiable relaxation ------------------------------------------------------
    def soft_step(self, probs, temperature, *, edge=None) -> Array:
        """A differentiable relaxation of `step` on state probabilities (K + 1, *lattice).

        The fields W_j are computed from the probabilities of species j; the hard argmax
        over (W_0, ..., W_{K-1}, 0) becomes softmax(. / temperature) and the keep-on-tie
        rule a gate g = 1 - exp(-(max_j W_j / temperature)^2) between that softmax and the
        current probabilities. As temperature -> 0 this is the hard step on one-hot input
        (except on ties between species, split evenly here); a tie at W = 0 keeps the state
        at any temperature, because neighbour counts within 1e-3 of an integer are taken
        as that integer (in value; their gradients are kept). `temperature` is in units of
        the weights; `edge` (lattice cells) smooths the disc boundaries with a sigmoid so
        that the radii get gradients too (None: hard discs).
        """
        probs = jnp.asarray(probs)
        k, shape = self.n_species, probs.shape[1:]
        if probs.shape[0] != k + 1:
            raise ValueError(f"YoungCA.soft_step probs must have shape (K + 1, *lattice) = ({k + 1}, ...) (got {probs.shape})")
        check_range(temperature, "YoungCA.soft_step temperature", low=0.0, low_open=True)
        if edge is not None:
            check_range(edge, "YoungCA.soft_step edge (lattice cells)", low=0.0, low_open=True)
        act, ring = self._kernels(shape, edge)
        axes = tuple(range(1, len(shape) + 1))
        f = jnp.fft.rfftn(probs[:k], axes=axes)
        spec = jnp.fft.rfftn(jnp.concatenate([act, ring]), axes=axes).real
        counts = jnp.fft.irfftn(_times_real(jnp.concatenate([f, f]), spec), s=shape, axes=axes)
        # On one-hot input the counts are integers, and W x denominator is then a sum of
        # integer products (w x denominator is an integer in float), so a tie is an exact
        # zero: the counts' values (not their gradients) are snapped to the nearest integer
        # when within 1e-3 of it, so that the transforms' float error (~1e-6) cannot open
        # the keep-on-tie gate as the temperature goes to 0.
        near = jnp.round(counts) - counts
        counts = counts + jax.lax.stop_gradient(jnp.where(jnp.abs(near) < 1e-3, near, 0.0))
        den = self.denominator.astype(counts.dtype)
        bc = (slice(None),) + (None,) * len(shape)
        w = ((self.w_act * den)[bc] * counts[:k] + (self.w_inh * den)[bc] * counts[k:]) / den
        scores = jnp.concatenate([w, jnp.zeros((1,) + shape, w.dtype)])
        q = jax.nn.softmax(scores / temperature, axis=0)
        gate = 1.0 - jnp.exp(-jnp.square(jnp.max(w, axis=0) / temperature))
        return gate * q + (1.0 - gate) * probs

    def soft_run(self, probs, steps: int, temperature, *, edge=None) -> Array:
        """`steps` soft steps in a `lax.scan` (reverse-mode differentiable)."""
        def body(p, _):
            return self.soft_step(p, temperature, edge=edge), None

        return jax.lax.scan(body, jnp.asarray(probs), None, length=int(steps))[0]


_PLANS: dict = {}
_SPECTRA: dict = {}  # kernel spectra of concrete models, by the plan key
_SPECTRA_MAX_SIZE = 2**18  # values kept per entry (1 MiB of float32)


def _cached_plan(key, ca) -> _YoungPlan:
    """Plans depend only on concrete parameters and the lattice shape: cache them (the
    Python work is ~1 ms, comparable to 100 steps of a small 3D lattice)."""
    if key not in _PLANS:
        if len(_PLANS) > 256:
            _PLANS.clear()
        _PLANS[key] = ca._make_plan(key[4])
    return _PLANS[key]


@functools.partial(jax.jit, static_argnames=("plan",))
def _jit_fields(ca, cells, pre, *, plan):
    n = cells.shape[-1]
    wide = _widen(cells, max(plan.width, n))
    return ca._fields(wide, plan, ca._spectra(plan, cells.shape) if pre is None else pre, n)[..., :n]


@functools.partial(jax.jit, static_argnames=("plan", "shape"))
def _jit_spectra(ca, *, plan, shape):
    return ca._spectra(plan, shape)


def _times_real(f, s):
    """Complex spectrum times a real one (cheaper than promoting `s` to complex)."""
    return jax.lax.complex(jnp.real(f) * s, jnp.imag(f) * s)


# ---- convolution by matrix-product transforms ---------------------------------------------
# The kernels are even in every axis (a function of |offset_i| on the periodic lattice), so
# the real separable transform with cas(t) = cos(t) + sin(t) along each axis diagonalises
# the convolution like the FFT does, with the kernel's real spectrum as eigenvalues; cas
# matrices are symmetric and their own inverse up to 1/n. Along the first lattice axis the
# kernel spans only 2 extent + 1 offsets, which are summed directly in the transformed
# space of the other axes.
def _cas_matrix(n: int) -> np.ndarray:
    t = 2.0 * np.pi * np.outer(np.arange(n), np.arange(n)) / n
    return (np.cos(t) + np.sin(t)).astype(np.float32)


def _matmul_cost(shape, extent: int) -> float:
    """Estimated microseconds a step of one species' `_convolve` by matrix products."""
    n = int(np.prod(shape))
    return _US_MATMUL + 1e-3 * n * max(_NS_MATMUL, _NS_MAC * (2 * sum(shape[1:]) + 2 * extent + 1))


def _cas_transform(y: Array, mats: dict) -> Array:
    """The cas transform of y (B, n0, n1, ..., nm) over the axes after n0, each one matrix
    product that drops the axis and appends its transform (so the last axis stays in
    place), leaving those axes in reverse order: applied twice it gives y x prod(n_i)
    back in the original order. (Measured: plain products with XLA's layout copies beat
    products that avoid the copies with transposed operands.)"""
    for axis in range(y.ndim - 1, 1, -1):
        y = jax.lax.dot_general(y, mats[y.shape[axis]], (((axis,), (0,)), ((), ())),
                                precision=jax.lax.Precision.HIGHEST)  # no TF32 on GPUs
    return y


def _matmul_spectra(kernel: Array, extent: int) -> dict:
    """What `_convolve` needs for kernels (B, n0, ...): the cas matrices, and the cas
    spectra over the other axes of the kernels' slices at first-axis offsets 0..extent,
    in `_cas_transform`'s layout and divided by the size of those axes ("taps")."""
    rest = kernel.shape[2:]
    mats = {n: jnp.asarray(_cas_matrix(n)) for n in sorted(set(rest))}
    taps = _cas_transform(kernel[:, :extent + 1].astype(jnp.float32), mats) / math.prod(rest)
    return {"taps": taps, "mats": mats}


def _convolve(ind: Array, spectra, plan: _YoungPlan) -> Array:
    """Periodic convolution of each of ind (B, *lattice) with its combined kernel."""
    if plan.method == "fft":
        axes = tuple(range(1, ind.ndim))
        return jnp.fft.irfftn(_times_real(jnp.fft.rfftn(ind, axes=axes), spectra), s=ind.shape[1:], axes=axes)
    taps, mats, e = spectra["taps"], spectra["mats"], plan.extent
    y = _cas_transform(ind, mats)
    b, n0 = y.shape[:2]
    y3, t3 = y.reshape(b, n0, -1), taps.reshape(b, e + 1, -1)  # first-axis shifts move whole rows
    padded = jnp.concatenate([y3[:, n0 - e:], y3, y3[:, :e]], axis=1) if e else y3
    w = t3[:, :1] * y3
    for t in range(1, e + 1):
        w = w + t3[:, t:t + 1] * (padded[:, e + t:e + t + n0] + padded[:, e - t:e - t + n0])
    return _cas_transform(w.reshape(y.shape), mats)


def weighted_volume_difference(ca: YoungCA, dim: int = 3, *, discrete: bool = False) -> Array:
    """Paper 002's weighted volume difference (eq. 6) of every species, shape (K,).

    WVD_j = V(r_act) w_act + (V(r_inh) - V(r_act)) w_inh with V the volume of a
    `dim`-dimensional ball (4/3 pi r^3 in 3D), in lattice cells^dim x weight. With
    `discrete=True` the lattice counts are used instead (the field W_j at a cell whose
    whole neighbourhood is species j), which moves in steps as the radii grow.
    """
    if discrete:
        counts = jnp.asarray(ca.neighbour_counts(dim), ca.w_act.dtype)
        return ca.w_act * counts[:, 0] + ca.w_inh * counts[:, 1]
    unit = math.pi ** (dim / 2) / math.gamma(dim / 2 + 1)
    v_act, v_inh = unit * ca.r_act**dim, unit * ca.r_inh**dim
    return v_act * ca.w_act + (v_inh - v_act) * ca.w_inh

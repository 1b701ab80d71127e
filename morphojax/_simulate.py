"""Stepping: forward Euler under `lax.scan`, with clamps, blow-up detection and snapshots.

One step, as in the leopard paper (section 7): integrate reaction + diffusion with forward
Euler, add any localised production (sources), clamp every species to [lower, upper], and
expand the lattice when the growth schedule says so.

`simulate` returns the final state; `rollout` also returns snapshots every n steps.
Both are pure functions of (model, state, dt, key): usable under `jax.jit`, `jax.vmap`
and `jax.grad`. Non-array configuration (steps, boundary, stencil, ...) is static.
"""

from __future__ import annotations

import bisect
import dataclasses
import functools
import itertools
import math
from typing import Any, Callable, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._bounds import Barrier, bounds_policy as _bounds_policy
from ._checks import as_float_array, check_finite, check_range, is_concrete
from ._growth import steps_done
from ._domain import Lattice
from ._lattice import active_mask, laplacian_padded, normalise_boundary, normalise_stencil, pad, repad
from ._models import AbstractModel, per_species
from ._state import State


class SimulationError(ValueError):
    """A run that went wrong: non-finite values (with the step), or growth past capacity."""


class _Carry(NamedTuple):
    p: Array  # ghost-padded fields (species, cap_rows + 2, cap_cols + 2)
    size: Array  # active (rows, cols)
    step: Array  # global step counter
    bad: Array  # first step whose result was non-finite, -1 if none
    overflow: Array  # growth wanted to pass the capacity


class _Config(NamedTuple):
    boundary: str
    stencil: str
    bounds: Any  # "clip" or Barrier
    dynamic: bool  # active region smaller than the array (growth)


def _slice_maps(model, block):
    """The model with its lattice maps (leaves with 2+ dims) cut to a (rows, cols) block."""
    def cut(leaf):
        if getattr(leaf, "ndim", 0) >= 2:
            return leaf[..., : min(block[0], leaf.shape[-2]), : min(block[1], leaf.shape[-1])]
        return leaf

    return jax.tree_util.tree_map(cut, model)


def _make_step(model: AbstractModel, dt, cfg: _Config, growth, sources, key, origin, block=None):
    """One step on the whole array, or on its top-left `block` (rows, cols) of the lattice."""
    if block is not None:
        model = _slice_maps(model, block)
    return _make_block_step(model, dt, cfg, growth, sources, key, origin)


def _make_block_step(model: AbstractModel, dt, cfg: _Config, growth, sources, key, origin):
    barrier = cfg.bounds if isinstance(cfg.bounds, Barrier) else None

    def update(m, x, lap, production, mask):
        """New values of the cells `x` (species, ...) given their Laplacian: reaction-diffusion,
        production, clamp. Species by species, stacked once at the end: XLA:CPU then computes
        the whole update in one loop (~20% faster than stacking the rates)."""
        lower, upper, diffusion = per_species(m.lower), per_species(m.upper), per_species(m.diffusion())
        rates = m.reaction(x)
        parts = []
        for i in range(x.shape[0]):
            rate = rates[i] + diffusion[i] * lap[i]
            if barrier is not None:
                rate = rate + barrier.terms(x[i], lower[i], upper[i])
            value = x[i] + dt * rate
            if i in production:
                value = value + production[i]
            if cfg.bounds == "clip":
                value = jnp.clip(value, lower[i], upper[i])
            parts.append(value)
        new = jnp.stack(parts)
        # the mask after stacking: XLA:CPU then computes the stack in one loop and fuses only
        # the select into the in-place write of `repad` (masking each species before the
        # stack made it fuse the whole update there, copying the buffer: 1.5x slower)
        return new if mask is None else jnp.where(mask, new, 0.0)

    def step(c: _Carry) -> _Carry:
        x = c.p[..., 1:-1, 1:-1]
        step_key = None if key is None else jax.random.fold_in(key, c.step)
        production = {}
        for j, src in enumerate(sources):
            amount = src.production(c.size, jax.random.fold_in(step_key, 1 + j), x[src.index])
            production[src.index] = production[src.index] + amount if src.index in production else amount
        mask = active_mask(x.shape[-2:], c.size) if cfg.dynamic else None
        new = update(model, x, laplacian_padded(c.p, cfg.stencil), production, mask)
        if cfg.dynamic:
            # an active region inside the array: the new values go back into the carried
            # buffer in place, with the ghost cells along the region's edges as four lines
            # (measured 5x slower for a fixed lattice: XLA:CPU then fuses the update
            # into the in-place write and copies the buffer)
            p = repad(c.p, new, c.size, cfg.boundary)
        else:  # the whole array is the lattice: ghost cells at its edges
            p = pad(new, cfg.boundary)
        size, overflow = c.size, c.overflow
        if growth is not None:
            p, size, overflow = growth.maybe_expand(
                p, size, c.step + 1 - origin, dt, jax.random.fold_in(step_key, 0), overflow,
                lambda p, x, size: repad(p, x, size, cfg.boundary),
            )
        return _Carry(p, size, c.step + 1, c.bad, overflow)

    return step


def _scan(step, carry, n: int):
    def body(c, _):
        return step(c), None

    if n == 0:
        return carry
    return jax.lax.scan(body, carry, None, length=n)[0]


def _locate_blowup(step, start: _Carry, n: int, needed) -> Array:
    """Re-run from `start` one step at a time to find the first non-finite step.

    Runs zero iterations unless `needed`, so it costs nothing on healthy runs (also under vmap).
    """
    start = jax.lax.stop_gradient(start)

    def cond(s):
        c, k, found = s
        return needed & ~found & (k < n)

    def body(s):
        c, k, _ = s
        c = step(c)
        return c, k + 1, ~jnp.all(jnp.isfinite(c.p))

    _, k, found = jax.lax.while_loop(cond, body, (start, jnp.asarray(0, jnp.int32), jnp.asarray(False)))
    return jnp.where(found, start.step + k, start.step + n)


def _steps(step, c: _Carry, n: int, checkpoint: bool) -> _Carry:
    """`n` steps in a scan, rematerialised in the backward pass when `checkpoint`."""
    run = functools.partial(_scan, step, n=n)
    return (jax.checkpoint(run) if checkpoint else run)(c)


def _chunk(step, c: _Carry, n: int, checkpoint: bool) -> _Carry:
    """`n` steps, then a finiteness check that pins down the first bad step if needed."""
    c1 = _steps(step, c, n, checkpoint)
    needed = (c1.bad < 0) & ~jnp.all(jnp.isfinite(c1.p))
    where = _locate_blowup(step, c, n, needed)
    return c1._replace(bad=jnp.where(needed, where, c1.bad))


def _chunk_lean(step, c: _Carry, n: int, checkpoint: bool) -> _Carry:
    """`n` steps, then a finiteness check that only marks the chunk: `bad` becomes the
    chunk's last step (an upper bound). Keeps no copy of the starting state, so a growing
    run's segments update their buffer in place; `_drive` re-runs a failed piece with
    `_chunk` to pin down the exact step."""
    c1 = _steps(step, c, n, checkpoint)
    marked = (c1.bad < 0) & ~jnp.all(jnp.isfinite(c1.p))
    return c1._replace(bad=jnp.where(marked, c1.step, c1.bad))


def _crop_state(c: _Carry, names, t0, step0, dt, growable, dynamic: bool) -> State:
    fields = c.p[..., 1:-1, 1:-1]
    if dynamic:  # drop the ghost cells written after the active region
        fields = jnp.where(active_mask(fields.shape[-2:], c.size), fields, 0.0)
    return State(fields, c.size, c.step, t0 + (c.step - step0) * dt, names, growable)


@eqx.filter_jit
def _integrate(model, fields, size, step0, time0, dt, key, origin, growth, sources, *, names, growable,
               steps: int, cfg: _Config, chunk: int, checkpoint: bool, save_every: int | None, save_fn,
               blocks=None, schedule=None, plan=None, clock=None):
    """The compiled core. Returns (final State, bad step, overflow flag, saved frames or None).

    With `blocks`, chunk j computes on the top-left block `blocks[schedule[j]]` (see
    `_block_schedule`); the chunk index comes from the scan, so it stays a real branch
    under vmap too. `clock` = (time, step) of the run's start when this is one of its
    pieces: times are then time + (step - that step) dt, as in one piece.
    """
    time0, step_t = (time0, step0) if clock is None else clock
    p = pad(fields, cfg.boundary)
    if cfg.dynamic:  # ghost cells along the active region's edges
        p = repad(p, fields, size, cfg.boundary)
    c = _Carry(p, size, step0, jnp.asarray(-1, jnp.int32), jnp.asarray(False))
    if plan is not None:
        return _integrate_plan(model, c, dt, key, origin, growth, sources, cfg, checkpoint, plan, names, growable,
                               time0, step_t)
    per = save_every if save_every is not None else chunk
    per = max(1, min(per, steps)) if steps else 1
    n_full, rem = divmod(steps, per)

    if blocks is None:
        step = _make_step(model, dt, cfg, growth, sources, key, origin)

        def run_chunk(c, j, n):
            return _chunk(step, c, n, checkpoint)
    else:
        steps_b = [_make_step(model, dt, cfg, growth, sources, key, origin, block=b) for b in blocks]

        def run_chunk(c, j, n):
            def branch(i):
                def run(c):
                    r, q = blocks[i]
                    sub = _chunk(steps_b[i], c._replace(p=c.p[..., : r + 2, : q + 2]), n, checkpoint)
                    return sub._replace(p=jax.lax.dynamic_update_slice(c.p, sub.p, (0,) * c.p.ndim))

                return run

            if len(blocks) == 1:
                return branch(0)(c)
            return jax.lax.switch(j, [branch(i) for i in range(len(blocks))], c)

    frames = None
    if n_full:
        def body(c, j):
            c = run_chunk(c, j, per)
            y = None if save_every is None else save_fn(_crop_state(c, names, time0, step_t, dt, growable, cfg.dynamic))
            return c, y

        index = jnp.asarray(schedule[:n_full] if schedule is not None else [0] * n_full, jnp.int32)
        c, frames = jax.lax.scan(body, c, index)
    if rem:
        c = run_chunk(c, jnp.asarray(schedule[-1] if schedule is not None else 0, jnp.int32), rem)
    final = _crop_state(c, names, time0, step_t, dt, growable, cfg.dynamic)
    return final, c.bad, c.overflow, frames


def _integrate_plan(model, c, dt, key, origin, growth, sources, cfg, checkpoint, plan, names, growable, time0,
                    step0):
    """Run a `_growth_plan`: per block, a scan over (steps without growth, then expand)."""
    blocks, groups = plan
    steps_b = {}

    def expand(sub):  # the plan knows the sizes: an expansion that would not fit is not planned
        k = jax.random.fold_in(jax.random.fold_in(key, sub.step - 1), 0)  # the key of the step it follows
        x, size = growth.expand(sub.p[..., 1:-1, 1:-1], sub.size, k)
        return sub._replace(p=repad(sub.p, x, size, cfg.boundary), size=size)

    for b, n, grow, repeat in groups:
        if b not in steps_b:
            steps_b[b] = _make_step(model, dt, cfg, None, sources, key, origin, block=blocks[b])
        r, q = blocks[b]

        def body(sub, _, b=b, n=n, grow=grow):
            sub = _chunk_lean(steps_b[b], sub, n, checkpoint)
            if grow == "overflow":  # due, but the capacity is full: recorded, as `maybe_expand` does
                return sub._replace(overflow=jnp.asarray(True)), None
            return (expand(sub) if grow else sub), None

        sub = jax.lax.scan(body, c._replace(p=c.p[..., : r + 2, : q + 2]), None, length=repeat)[0]
        c = sub._replace(p=jax.lax.dynamic_update_slice(c.p, sub.p, (0,) * c.p.ndim))
    final = _crop_state(c, names, time0, step0, dt, growable, cfg.dynamic)
    return final, c.bad, c.overflow, None


def _default_chunk(steps: int, checkpoint) -> int:
    if checkpoint is None or checkpoint is False:
        return 128
    if checkpoint is True:
        return max(1, int(math.sqrt(max(steps, 1))))
    return int(checkpoint)


def _check_inputs(model, state, steps, dt, cfg, growth, check_dt, bounds):
    # concrete values are checked eagerly, also while an outer jax.jit traces this call
    with jax.ensure_compile_time_eval():
        _check_inputs_eager(model, state, steps, dt, cfg, growth, check_dt, bounds)


def _check_inputs_eager(model, state, steps, dt, cfg, growth, check_dt, bounds):
    if not isinstance(model, AbstractModel):
        raise ValueError(f"model must be a morphojax model such as Turing(...) (got {type(model).__name__})")
    if not isinstance(state, State):
        raise ValueError(f"state must be a morphojax State (got {type(state).__name__})")
    if not isinstance(steps, (int, np.integer)) or isinstance(steps, bool) or steps < 0:
        raise ValueError(f"steps must be a non-negative integer (got {steps!r})")
    if model.n_species != state.n_species:
        raise ValueError(
            f"{type(model).__name__} evolves {model.n_species} species {model.species} but the state has "
            f"{state.n_species} ({', '.join(state.names)})"
        )
    check_finite(dt, "dt")
    check_range(dt, "dt", low=0.0, low_open=True)
    cap = state.capacity
    for name, leaf in _map_leaves(model):
        try:
            jnp.broadcast_shapes(leaf.shape[-2:], cap)
        except ValueError:
            raise ValueError(
                f"parameter map {name} has shape {leaf.shape[-2:]}, which does not broadcast to the lattice "
                f"{cap} (rows, cols)"
            ) from None
    if is_concrete(state.fields):
        if not np.isfinite(np.asarray(state.fields)).all():
            raise ValueError("state contains NaN or infinite values")
    if check_dt and is_concrete(model, dt):
        Lattice(cfg.stencil, cfg.boundary).check_dt(dt, model.max_diffusion())
    if isinstance(cfg.bounds, Barrier) and is_concrete(state.fields, model):
        x = np.asarray(state.fields)[:, : state.shape[0], : state.shape[1]]
        lo = np.asarray(per_species(model.lower))
        hi = np.asarray(per_species(model.upper))
        if (np.asarray(model.lower) < 0).any():
            raise ValueError("bounds='barrier' needs lower limits >= 0 (the rational terms use x^k - L^k)")
        lo_c = lo[..., : x.shape[-2], : x.shape[-1]] if lo.ndim == 3 and lo.shape[-2:] != (1, 1) else lo
        hi_c = hi[..., : x.shape[-2], : x.shape[-1]] if hi.ndim == 3 and hi.shape[-2:] != (1, 1) else hi
        if not ((x > lo_c) & (x < hi_c)).all():
            raise ValueError(
                "bounds='barrier' needs the initial state strictly inside (lower, upper) for every species; "
                "start from values inside the limits or use bounds='clip'"
            )


def _map_leaves(model):
    """(name, array) of the model's spatially varying parameters (arrays with 2+ dims)."""
    out = []
    for path, leaf in jax.tree_util.tree_leaves_with_path(model):
        if getattr(leaf, "ndim", 0) >= 2:
            out.append((f"{type(model).__name__}{jax.tree_util.keystr(path)}", leaf))
    return out


def _prepare(model, state, steps, dt, boundary, stencil, bounds, growth, sources, key, check_dt, origin=None):
    cfg = _Config(
        boundary=normalise_boundary(boundary),
        stencil=normalise_stencil(stencil),
        bounds=_bounds_policy(bounds),
        dynamic=bool(state.growable or growth is not None),
    )
    _check_inputs(model, state, steps, dt, cfg, growth, check_dt, bounds)
    sources = tuple(sources or ())
    if (growth is not None or sources) and key is None:
        raise ValueError("key is required when growth or sources are used (they draw random numbers)")
    if growth is not None:
        # no room is an error only if an expansion falls in this run (a resumed run's last
        # period, or rate 0, has none)
        if not state.growable and is_concrete(state.size) and growth.due(state, steps, dt, origin) != 0:
            raise SimulationError(
                "this state has no room to grow: build it with State.from_arrays(..., capacity=(rows, cols)) "
                "or use state.with_capacity((rows, cols))"
            )
        growth.check_capacity(state, steps, dt, origin)
    sources = tuple(s.check(state) for s in sources)
    dt = as_float_array(dt, "dt").astype(state.fields.dtype)
    return cfg, dt, sources


SMALL_LATTICE = 160 * 160  # at or below this capacity a growing run uses a single block


def _ladder(first: int, last: int, cap: int, ratio: float, multiple: int) -> list[int]:
    """Block rows from `first` to `last`, each about `ratio` times the previous, rounded up
    to a multiple of `multiple` and capped at `cap` (one block when ratio is infinite)."""
    ladder, r = [], first
    while True:
        r = min(-(-r // multiple) * multiple, cap)
        ladder.append(r)
        if r >= last:
            return ladder
        r = max(r + 1, int(r * ratio)) if math.isfinite(ratio) else last


def _placed_ladder(rows: list[int], weights: list[int], cap: int, ratio: float, multiple: int,
                   area: Callable[[int], int]) -> list[int]:
    """As many block sizes as `_ladder` gives (the number of compiled step bodies), placed
    to minimise the work: sum over chunks of weight x area(block) for the smallest block
    that holds each chunk's `rows` (dynamic programming over the candidate sizes).

    For the leopard's development phase (130 -> 370 rows, linear growth) six blocks then
    compute 15% more cells than the active regions instead of 21% for the geometric ladder.
    """
    geometric = _ladder(min(rows), max(rows), cap, ratio, multiple)
    k = len(geometric)
    cands = sorted({min(-(-r // multiple) * multiple, cap) for r in range(min(rows), max(rows) + 1)})
    if k <= 1 or len(cands) <= k:
        return geometric if len(cands) > k else cands
    load = [0] * len(cands)  # load[j]: total weight of the chunks needing at most cands[j] rows
    for r, wt in zip(rows, weights):
        load[bisect.bisect_left(cands, r)] += wt
    load = list(itertools.accumulate(load))

    def seg(i, j):  # chunks in (cands[i], cands[j]] computed on block cands[j]
        return (load[j] - (load[i] if i >= 0 else 0)) * area(cands[j])

    n = len(cands)
    best = [[math.inf] * n for _ in range(k + 1)]
    back = [[-1] * n for _ in range(k + 1)]
    for j in range(n):
        best[1][j] = seg(-1, j)
    for m in range(2, k + 1):
        for j in range(1, n):
            for i in range(j):
                v = best[m - 1][i] + seg(i, j)
                if v < best[m][j]:
                    best[m][j], back[m][j] = v, i
    m = min(range(1, k + 1), key=lambda m: best[m][n - 1])
    out, j = [], n - 1
    while j >= 0 and m >= 1:
        out.append(cands[j])
        j, m = back[m][j], m - 1
    return sorted(out)


def _blocks(rows, weights, shape, capacity, ratio, multiple, rungs):
    """(block rows, blocks as (rows, cols)) for a run whose chunks need `rows` rows with
    `weights` steps each, starting from the active `shape`: placed by `_placed_ladder`, or,
    given the `rungs` of a whole run split into progress pieces, the one rung that holds
    every size of this piece (pieces on the same rung then share one compiled program).
    Columns grow with the rows (one expansion adds one of each)."""
    (h, w), (cap_r, cap_c) = shape, capacity
    cols = lambda r: min(r - h + w, cap_c)
    if rungs is None:
        ladder = _placed_ladder(rows, weights, cap_r, ratio, multiple, lambda r: r * cols(r))
    else:
        ladder = [next(r for r in rungs if r >= max(rows))]
    return ladder, tuple((r, cols(r)) for r in ladder)


def _block_schedule(state, growth, steps: int, dt, origin, per: int, ratio: float = 1.25, multiple: int = 8,
                    rungs=None):
    """Blocks for a run on a dynamic active region, and which one each chunk uses.

    A chunk of `per` steps computes on the top-left block of the lattice that holds the
    active region as it will be at the chunk's end (expansions are on a fixed schedule),
    chosen from a ladder of block sizes (multiples of 8, as many as a ladder growing by
    `ratio` has, placed by `_placed_ladder` to minimise the cells computed). A growing run
    then costs about what its current size costs, still in one compiled program. Returns
    (blocks, schedule) or (None, None) when sizes are not known in advance (traced states
    or growth rates, e.g. inside vmap over growth rates): the whole capacity is used then.
    """
    if not is_concrete(state.size, state.step, origin) or (growth is not None and not is_concrete(growth.rate, dt)):
        return None, None
    if state.capacity[0] * state.capacity[1] <= SMALL_LATTICE:
        ratio = float("inf")  # small lattices: one block, one compiled step
    with jax.ensure_compile_time_eval():
        h, w = state.shape
        done = steps_done(state, origin)
        cap_r = state.capacity[0]
        ends = [min((j + 1) * per, steps) for j in range(-(-steps // per))] if steps else []
        need = [min(h + (growth.expansions(e, dt, done) if growth is not None else 0), cap_r) for e in ends]
    if not need:
        return None, None
    steps_per = [min((j + 1) * per, steps) - j * per for j in range(len(need))]
    ladder, blocks = _blocks(need, steps_per, (h, w), state.capacity, ratio, multiple, rungs)
    schedule = tuple(next(i for i, b in enumerate(ladder) if b >= n) for n in need)
    return blocks, schedule


def _growth_plan(state, growth, steps: int, dt, origin, check: int = 128, ratio: float = 1.25, multiple: int = 8,
                 rungs=None):
    """A growing run as segments: `n` steps without growth, then one expansion.

    Expansions fall on a fixed schedule (phase steps 1, 1 + p, 1 + 2p, ...), so an eager
    run can be laid out in advance: each block of the size ladder (see `_block_schedule`)
    runs a scan over identical segments, and the per-step growth test disappears from the
    stepping loop. Returns (blocks, groups) with groups of (block, steps, expand, repeat),
    expand being True, False or "overflow" (due but the capacity is full), or (None, None)
    when the sizes are not concrete.
    """
    if growth is None or not is_concrete(state.size, state.step, origin, growth.rate, dt) or not steps:
        return None, None
    if state.capacity[0] * state.capacity[1] <= SMALL_LATTICE:
        ratio = float("inf")  # small lattices: one block, one compiled step (compiling costs more)
    with jax.ensure_compile_time_eval():
        period = growth.period_steps(dt)
        done = steps_done(state, origin)
        h, w = state.shape
    cap_r, cap_c = state.capacity
    segments, t = [], 0
    while t < steps:
        nxt = t + 1 + ((period - (done + t) % period) % period) if period > 0 else steps + 1
        n, expand = (nxt - t, True) if nxt <= steps else (steps - t, False)
        t += n
        while n > 4 * check:  # long stretches: check for blow-ups every `check` steps
            segments.append((check, False))
            n -= check
        segments.append((n, expand))
    sizes, grown, kinds = [], (h, w), []
    for n, expand in segments:
        fits = grown[0] < cap_r and grown[1] < cap_c
        kinds.append(("overflow" if not fits else True) if expand else False)
        grown = (grown[0] + 1, grown[1] + 1) if expand and fits else grown
        sizes.append(grown[0])
    ladder, blocks = _blocks(sizes, [n for n, _ in segments], (h, w), state.capacity, ratio, multiple, rungs)
    groups = []
    for (n, _), expand, need in zip(segments, kinds, sizes):
        b = next(i for i, r in enumerate(ladder) if r >= need)
        if groups and groups[-1][:3] == (b, n, expand):
            groups[-1] = (b, n, expand, groups[-1][3] + 1)
        else:
            groups.append((b, n, expand, 1))
    return blocks, tuple(groups)


def _finish(final, bad, overflow, throw: bool):
    if not throw:
        return final
    if is_concrete(bad, overflow):
        if int(bad) >= 0:
            raise SimulationError(
                f"the state became non-finite (NaN or Inf) at step {int(bad)}: the run blew up. "
                "Reduce dt, check the parameters, or use throw=False to get the state anyway."
            )
        if bool(overflow):
            raise SimulationError("growth exceeded the state's capacity during the run")
        return final
    fields = eqx.error_if(final.fields, bad >= 0, "the state became non-finite (NaN or Inf) during the run; "
                          "run eagerly (outside jit) to get the step, or pass throw=False")
    fields = eqx.error_if(fields, overflow, "growth exceeded the state's capacity during the run")
    return eqx.tree_at(lambda s: s.fields, final, fields)


def _drive(model, state, steps, dt, cfg, growth, sources, key, origin, checkpoint, progress, save_every, save_fn,
           description):
    """Run `_integrate`, in pieces with a progress bar when asked (results are identical)."""
    chunk = _default_chunk(steps, checkpoint)
    ckpt = bool(checkpoint)
    origin = state.step if origin is None else jnp.asarray(origin, jnp.int32)
    pieces, rungs = [steps], None
    if progress and steps and is_concrete(state.fields, model, dt):
        unit = save_every or chunk
        planned = cfg.dynamic and save_every is None and growth is not None and is_concrete(growth.rate)
        if planned and growth.period_steps(dt) > 0:
            unit = growth.period_steps(dt)  # every piece then has the same segments
        per = max(unit, (steps // 50) // unit * unit) if steps >= 50 * unit else steps
        pieces = [per] * (steps // per) + ([steps % per] if steps % per else [])
        if len(pieces) > 1 and cfg.dynamic and growth is not None:
            # the block sizes of the whole run, one per piece: a growing run in pieces
            # compiles once per block size, not once per piece
            whole = (_growth_plan(state, growth, steps, dt, origin, chunk) if planned
                     else _block_schedule(state, growth, steps, dt, origin, max(1, min(unit, steps))))
            rungs = None if whole[0] is None else tuple(b[0] for b in whole[0])
    bar = None
    if len(pieces) > 1 or (progress and steps):
        from tqdm.auto import tqdm

        bar = tqdm(total=steps, desc=description, unit="step", leave=False)
    frames_all = []
    bad = jnp.asarray(-1, jnp.int32)
    overflow = jnp.asarray(False)
    current = state
    try:
        for n in pieces:
            blocks, schedule, plan = None, None, None
            if cfg.dynamic and save_every is None and growth is not None:
                plan = _growth_plan(current, growth, int(n), dt, origin, chunk, rungs=rungs)
                plan = plan if plan[0] is not None else None
            if cfg.dynamic and plan is None:
                per = max(1, min(save_every or chunk, int(n))) if n else 1
                blocks, schedule = _block_schedule(current, growth, int(n), dt, origin, per, rungs=rungs)
            run = functools.partial(
                _integrate, model, current.fields, current.size, current.step, current.time, dt, key, origin, growth,
                sources, names=current.names, growable=current.growable, steps=int(n), cfg=cfg, chunk=chunk,
                checkpoint=ckpt, save_every=save_every, save_fn=save_fn,
                clock=None if len(pieces) == 1 else (state.time, state.step))
            final, bad_i, over_i, frames = run(blocks=blocks, schedule=schedule, plan=plan)
            if plan is not None and is_concrete(bad_i) and int(bad_i) >= 0:
                # a planned run only marks the segment that blew up: the same piece again
                # (same key, same result) on the chunked path, which replays the bad chunk
                # one step at a time, pins down the step
                per = max(1, min(chunk, int(n)))
                blocks, schedule = _block_schedule(current, growth, int(n), dt, origin, per)
                final, bad_i, over_i, frames = run(blocks=blocks, schedule=schedule, plan=None)
            bad = jnp.where(bad >= 0, bad, bad_i)
            overflow = overflow | over_i
            if frames is not None:
                frames_all.append(frames)
            current = final
            if bar is not None:
                bar.update(n)
                if is_concrete(bad) and int(bad) >= 0:
                    break
    finally:
        if bar is not None:
            bar.close()
    frames = None
    if frames_all:
        frames = frames_all[0] if len(frames_all) == 1 else jax.tree_util.tree_map(
            lambda *xs: jnp.concatenate(xs), *frames_all)
    return current, bad, overflow, frames


def simulate(model: AbstractModel, state: State, steps: int, dt, boundary: str = "wrap", *,
             stencil: str = "nine-point", bounds="clip", growth=None, sources=(), key=None,
             check_dt: bool = True, throw: bool = True, progress: bool = False, checkpoint=None,
             origin=None) -> State:
    """Run `steps` forward-Euler steps of `model` from `state`; return the new State.

    Args:
        model: a model such as `Turing(ratio=4, scale=3)`.
        state: the initial `State` (species must match the model's).
        steps: number of steps (a Python int; simulated time is steps x dt).
        dt: time step (unit: simulated time). Checked against the explicit-Euler limit of the
            stencil for the largest diffusion rate unless `check_dt=False`.
        boundary: "wrap" (toroidal) or "no-flux" (ghost cell = edge cell).
        stencil: "nine-point" (the paper's isotropic stencil, default) or "five-point".
        bounds: "clip" (clamp to [lower, upper] after every step, the paper's method) or
            "barrier" / `Barrier(k)` (smooth rational terms, needs a ~20x smaller dt).
        growth: a `Growth` schedule (random matrix expansion); needs a state with capacity.
        sources: localised production, a sequence of `Source`.
        key: `jax.random` key, required with growth or sources. The same key gives the same run.
        throw: raise `SimulationError` if the state becomes NaN/Inf (with the first bad step)
            or growth overflows the capacity. With `throw=False` the state is returned as is.
        progress: show a progress bar (the run is split into pieces; the result is identical).
        checkpoint: None, True (checkpoint every ~sqrt(steps) steps) or an int chunk length:
            rematerialise inside chunks under `jax.grad`, so memory does not grow with steps.
        origin: the step at which the growth schedule started (default: `state.step`);
            set it when resuming inside a growing phase.

    Returns:
        The new `State`, with `step` and `time` advanced.
    """
    cfg, dt, sources = _prepare(model, state, steps, dt, boundary, stencil, bounds, growth, sources, key, check_dt,
                                origin)
    final, bad, overflow, _ = _drive(model, state, steps, dt, cfg, growth, sources, key, origin, checkpoint,
                                     progress, None, None, type(model).__name__)
    return _finish(final, bad, overflow, throw)


def _save_state(s: State):
    return s


def rollout(model: AbstractModel, state: State, steps: int, dt, every: int, boundary: str = "wrap", *,
            save: Callable[[State], Any] | None = None, **kwargs):
    """Like `simulate`, also saving a snapshot every `every` steps (for animations and figures).

    Returns `(final_state, frames)`. By default `frames` is a State whose leaves have a
    leading axis of length steps // every (`frames.frame(i)` is snapshot i, taken after
    (i + 1) * every steps). With `save=fn`, `fn(state)` is saved instead, e.g.
    `lambda s: s.fields[1].mean()`. Memory grows with the number of snapshots only.
    """
    if not isinstance(every, (int, np.integer)) or every < 1:
        raise ValueError(f"every must be a positive integer number of steps (got {every!r})")
    keys = ("stencil", "bounds", "growth", "sources", "key", "check_dt", "throw", "progress", "checkpoint", "origin")
    unknown = set(kwargs) - set(keys)
    if unknown:
        raise TypeError(f"rollout() got unexpected arguments {sorted(unknown)}")
    opts = dict(stencil="nine-point", bounds="clip", growth=None, sources=(), key=None, check_dt=True, throw=True,
                progress=False, checkpoint=None, origin=None)
    opts.update(kwargs)
    cfg, dt, sources = _prepare(model, state, steps, dt, boundary, opts["stencil"], opts["bounds"], opts["growth"],
                                opts["sources"], opts["key"], opts["check_dt"], opts["origin"])
    if every > steps:  # no snapshot would fall in the run
        raise ValueError(f"rollout.every must lie in [1, steps = {steps}] (got {every})")
    final, bad, overflow, frames = _drive(
        model, state, steps, dt, cfg, opts["growth"], sources, opts["key"], opts["origin"], opts["checkpoint"],
        opts["progress"], int(every), save or _save_state, type(model).__name__,
    )
    final = _finish(final, bad, overflow, opts["throw"])
    return final, frames


def run_status(model, state, steps, dt, boundary="wrap", **kwargs):
    """Like `simulate` with `throw=False`, also returning (first non-finite step or -1, overflow).

    For sweeps and fitting, where a failed member must be recorded rather than raised.
    """
    opts = dict(stencil="nine-point", bounds="clip", growth=None, sources=(), key=None, check_dt=True,
                checkpoint=None, origin=None)
    opts.update(kwargs)
    cfg, dt, sources = _prepare(model, state, steps, dt, boundary, opts["stencil"], opts["bounds"], opts["growth"],
                                opts["sources"], opts["key"], opts["check_dt"], opts["origin"])
    final, bad, overflow, _ = _drive(model, state, steps, dt, cfg, opts["growth"], sources, opts["key"],
                                     opts["origin"], opts["checkpoint"], False, None, None, "")
    return final, bad, overflow

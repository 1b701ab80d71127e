"""The loop: the step (`_step`) scanned in chunks, blow-ups located, progress in pieces.

A run is `steps` applications of one step under `lax.scan`, cut into chunks; after each
chunk a finiteness check records the first bad step (replaying the bad chunk one step at a
time, which costs nothing on healthy runs, also under vmap). `checkpoint` rematerialises
chunks under `jax.grad`. A growing lattice is run on blocks chosen by an execution plan
(`_plan`). With a progress bar the run goes in pieces, each one compiled call; the pieces
of a growing run share the block sizes of the whole run, so they share compiled programs.
An adaptive solver's run goes to its own controller (`_adaptive`).
"""

from __future__ import annotations

import functools
import math

import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
from jax import Array

from ._adaptive import integrate_adaptive
from ._checks import is_concrete
from ._progress import progress_bar
from ._repeat import repeat as _scan  # the loop's steps (benchmarks/gpu_lattice.py times others)
from ._state import State
from ._status import RunStatus
from ._step import Carry, Config, growth_key, make_step


def _locate_blowup(step, start: Carry, n: int, needed) -> Array:
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


def _steps(step, c: Carry, n: int, checkpoint: bool) -> Carry:
    """`n` steps in a scan, rematerialised in the backward pass when `checkpoint`."""
    run = functools.partial(_scan, step, n=n)
    return (jax.checkpoint(run) if checkpoint else run)(c)


def _chunk(step, c: Carry, n: int, checkpoint: bool) -> Carry:
    """`n` steps, then a finiteness check that pins down the first bad step if needed."""
    c1 = _steps(step, c, n, checkpoint)
    needed = (c1.bad < 0) & ~jnp.all(jnp.isfinite(c1.p))
    where = _locate_blowup(step, c, n, needed)
    return c1._replace(bad=jnp.where(needed, where, c1.bad))


def _chunk_lean(step, c: Carry, n: int, checkpoint: bool) -> Carry:
    """`n` steps, then a finiteness check that only marks the chunk: `bad` becomes the
    chunk's last step (an upper bound). Keeps no copy of the starting state, so a growing
    run's segments update their buffer in place; `drive` re-runs a failed piece with
    `_chunk` to pin down the exact step."""
    c1 = _steps(step, c, n, checkpoint)
    marked = (c1.bad < 0) & ~jnp.all(jnp.isfinite(c1.p))
    return c1._replace(bad=jnp.where(marked, c1.step, c1.bad))


def _crop_state(domain, c: Carry, names, t0, step0, dt, growable, dynamic: bool) -> State:
    fields = domain.interior(c.p)
    if dynamic:  # drop the ghost cells written after the active region
        fields = jnp.where(domain.active_mask(fields.shape[1:], c.size), fields, 0.0)
    return State(fields, c.size, c.step, t0 + (c.step - step0) * dt, names, growable)


@eqx.filter_jit
def _integrate(model, domain, fields, size, step0, time0, dt, key, origin, growth, sources, *, names, growable,
               steps: int, cfg: Config, chunk: int, checkpoint: bool, save_every: int | None, save_fn,
               blocks=None, schedule=None, segments=None, clock=None, solver=None, until=None):
    """The compiled core. Returns (final State, bad step, overflow flag, saved frames or
    None, the time a stopping rule ended the run or NaN, whether an adaptive run stopped
    short of its time, the steps it made): the whole status comes out of the compiled
    program, so an eager call does no device operation on it.

    With `blocks`, chunk j computes on the top-left block `blocks[schedule[j]]` (see
    `BlockLadder.chunk_blocks`); the chunk index comes from the scan, so it stays a real
    branch under vmap too. With `segments` (see `BlockLadder.segments`) the run follows
    that layout instead. `clock` = (time, step) of the run's start when this is one of its
    pieces: times are then time + (step - that step) dt, as in one piece. `solver`
    advances each step (default Euler); with a stopping rule `until`, steps after the stop
    leave the carry as it is and the chunks after it are skipped.
    """
    if solver is not None and solver.adaptive:  # steps * dt is the time to reach; pieces keep their own time
        out = integrate_adaptive(model, domain, fields, size, step0, time0, dt, steps, cfg, solver, until, names,
                                 growable)
        return out + (out[0].step - step0,)
    time0, step_t = (time0, step0) if clock is None else clock
    steady = None if until is None else jnp.asarray(jnp.nan, dt.dtype)
    c = Carry(domain.carry(fields, size, cfg.dynamic), size, step0, jnp.asarray(-1, jnp.int32), jnp.asarray(False),
              steady)
    if segments is not None:
        return _integrate_segments(model, domain, c, dt, key, origin, growth, sources, cfg, checkpoint, segments,
                                   names, growable, time0, step_t)
    per = save_every if save_every is not None else chunk
    per = max(1, min(per, steps)) if steps else 1
    n_full, rem = divmod(steps, per)

    def stopping(step):
        return step if until is None else _until_steady(step, domain, until.tol, dt, time0, step_t)

    if blocks is None:
        step = stopping(make_step(model, domain, dt, cfg, growth, sources, key, origin, solver=solver,
                                  shape=fields.shape[1:]))

        def run_chunk(c, j, n):
            return _chunk(step, c, n, checkpoint)
    else:
        steps_b = [stopping(make_step(model, domain, dt, cfg, growth, sources, key, origin, block=b))
                   for b in blocks]

        def run_chunk(c, j, n):
            def branch(i):
                def run(c):
                    sub = _chunk(steps_b[i], c._replace(p=domain.block(c.p, *blocks[i])), n, checkpoint)
                    return sub._replace(p=domain.unblock(c.p, sub.p))

                return run

            if len(blocks) == 1:
                return branch(0)(c)
            return jax.lax.switch(j, [branch(i) for i in range(len(blocks))], c)

    frames = None
    index = jnp.asarray(schedule[:n_full] if schedule is not None else [0] * n_full, jnp.int32)
    if n_full and until is not None and save_every is None:
        # chunks until every member has stopped (or blown up); reverse-mode differentiable
        def running(s):
            j, c = s
            return (j < n_full) & jnp.isnan(c.steady) & (c.bad < 0)

        def next_chunk(s):
            j, c = s
            return j + 1, run_chunk(c, index[j], per)

        c = eqxi.while_loop(running, next_chunk, (jnp.asarray(0, jnp.int32), c), max_steps=n_full,
                            kind="checkpointed")[1]
    elif n_full:
        def body(c, j):
            c = run_chunk(c, j, per)
            y = None if save_every is None else save_fn(
                _crop_state(domain, c, names, time0, step_t, dt, growable, cfg.dynamic))
            return c, y

        c, frames = jax.lax.scan(body, c, index)
    if rem:
        c = run_chunk(c, jnp.asarray(schedule[-1] if schedule is not None else 0, jnp.int32), rem)
    final = _crop_state(domain, c, names, time0, step_t, dt, growable, cfg.dynamic)
    return final, c.bad, c.overflow, frames, c.steady_time(dt), jnp.asarray(False), c.step - step0


def _until_steady(step, domain, tol: float, dt, time0, step0):
    """`step` that records when max |x_{n+1} - x_n| / dt first falls below `tol`, and from
    then on leaves the carry as it is (a frozen member of a vmapped batch)."""
    def stepped(c: Carry) -> Carry:
        new = step(c)
        change = jnp.max(jnp.abs(domain.interior(new.p) - domain.interior(c.p))) / dt
        settled = change < tol  # False for NaN: a blow-up is not a steady state
        new = new._replace(steady=jnp.where(settled, time0 + (new.step - step0) * dt, new.steady))
        done = ~jnp.isnan(c.steady)
        return jax.tree_util.tree_map(lambda old, fresh: jnp.where(done, old, fresh), c, new)

    return stepped


def _integrate_segments(model, domain, c, dt, key, origin, growth, sources, cfg, checkpoint, segments, names,
                        growable, time0, step0):
    """Run a plan's segments: per block, a scan over (steps without growth, then expand)."""
    blocks, groups = segments
    steps_b, start = {}, c.step

    def expand(sub):  # the plan knows the sizes: an expansion that would not fit is not planned
        x, size = growth.expand(domain.interior(sub.p), sub.size, growth_key(key, sub.step - 1))
        return sub._replace(p=domain.write(sub.p, x, size, True), size=size)

    for b, n, grow, repeat in groups:
        if b not in steps_b:
            steps_b[b] = make_step(model, domain, dt, cfg, None, sources, key, origin, block=blocks[b])

        def body(sub, _, b=b, n=n, grow=grow):
            sub = _chunk_lean(steps_b[b], sub, n, checkpoint)
            if grow == "overflow":  # due, but the capacity is full: recorded, as the per-step path does
                return sub._replace(overflow=jnp.asarray(True)), None
            return (expand(sub) if grow else sub), None

        sub = jax.lax.scan(body, c._replace(p=domain.block(c.p, *blocks[b])), None, length=repeat)[0]
        c = sub._replace(p=domain.unblock(c.p, sub.p))
    final = _crop_state(domain, c, names, time0, step0, dt, growable, cfg.dynamic)
    return final, c.bad, c.overflow, None, c.steady_time(dt), jnp.asarray(False), c.step - start


def default_chunk(steps: int, checkpoint) -> int:
    """Steps between finiteness checks: 128, or the checkpoint length when rematerialising."""
    if checkpoint is None or checkpoint is False:
        return 128
    if checkpoint is True:
        return max(1, int(math.sqrt(max(steps, 1))))
    return int(checkpoint)


def drive(model, domain, state, steps, dt, cfg, growth, sources, key, origin, checkpoint, progress, save_every,
          save_fn, description, plan, solver=None, until=None):
    """Run `_integrate`, in pieces with a progress bar when asked (results are identical).

    Returns (final State, RunStatus, frames or None).
    """
    chunk = default_chunk(steps, checkpoint)
    ckpt = bool(checkpoint)
    origin = state.step if origin is None else jnp.asarray(origin, jnp.int32)
    pieces, rungs = [steps], None
    planned = cfg.dynamic and save_every is None and growth is not None and until is None
    # an adaptive run is one piece: pieces would restart its step size at each cut
    if progress and steps and is_concrete(state.fields, model, dt) and not getattr(solver, "adaptive", False):
        unit = save_every or chunk
        if planned and is_concrete(growth.rate) and growth.period_steps(dt) > 0:
            unit = growth.period_steps(dt)  # every piece then has the same segments
        per = max(unit, (steps // 50) // unit * unit) if steps >= 50 * unit else steps
        pieces = [per] * (steps // per) + ([steps % per] if steps % per else [])
        if len(pieces) > 1 and cfg.dynamic and growth is not None:
            # the block sizes of the whole run, one per piece: a growing run in pieces
            # compiles once per block size, not once per piece
            whole = (plan.segments(state, growth, steps, dt, origin, chunk)
                     if planned and is_concrete(growth.rate)
                     else plan.chunk_blocks(state, growth, steps, dt, origin, max(1, min(unit, steps))))
            rungs = None if whole[0] is None else tuple(b[0] for b in whole[0])
    bar = None
    if len(pieces) > 1 or (progress and steps):
        bar = progress_bar(steps, description)
    frames_all, compiled = [], set()
    status = None
    current = state
    try:
        for n in pieces:
            blocks, schedule, segments = None, None, None
            if planned:
                segments = plan.segments(current, growth, int(n), dt, origin, chunk, rungs=rungs)
                segments = segments if segments[0] is not None else None
            if cfg.dynamic and segments is None:
                per = max(1, min(save_every or chunk, int(n))) if n else 1
                blocks, schedule = plan.chunk_blocks(current, growth, int(n), dt, origin, per, rungs=rungs)
            if bar is not None:  # a piece of a new shape compiles first: say so rather than show a rate
                shape = (int(n), segments[0] if segments is not None else blocks)
                bar.set_postfix_str("" if shape in compiled else "compiling")
                compiled.add(shape)
            run = functools.partial(
                _integrate, model, domain, current.fields, current.size, current.step, current.time, dt, key, origin,
                growth, sources, names=current.names, growable=current.growable, steps=int(n), cfg=cfg, chunk=chunk,
                checkpoint=ckpt, save_every=save_every, save_fn=save_fn,
                clock=None if len(pieces) == 1 else (state.time, state.step), solver=solver, until=until)
            final, bad_i, over_i, frames, steady_i, short_i, taken_i = run(blocks=blocks, schedule=schedule,
                                                                           segments=segments)
            if segments is not None and is_concrete(bad_i) and int(bad_i) >= 0:
                # a planned run only marks the segment that blew up: the same piece again
                # (same key, same result) on the chunked path, which replays the bad chunk
                # one step at a time, pins down the step
                per = max(1, min(chunk, int(n)))
                blocks, schedule = plan.chunk_blocks(current, growth, int(n), dt, origin, per)
                final, bad_i, over_i, frames, steady_i, short_i, taken_i = run(blocks=blocks, schedule=schedule,
                                                                               segments=None)
            piece = RunStatus(bad_i, over_i, steady_i, taken_i, short_i)
            status = piece if status is None else status.merge(piece)  # one piece: its own status, no device op
            if frames is not None:
                frames_all.append(frames)
            current = final
            if bar is not None:
                bar.update(n)
                if is_concrete(status.nonfinite_step) and int(status.nonfinite_step) >= 0:
                    break
                if is_concrete(status.steady_at) and not math.isnan(float(status.steady_at)):
                    break
                if is_concrete(status.incomplete) and bool(status.incomplete):
                    break
    finally:
        if bar is not None:
            bar.close()
    frames = None
    if frames_all:
        frames = frames_all[0] if len(frames_all) == 1 else jax.tree_util.tree_map(
            lambda *xs: jnp.concatenate(xs), *frames_all)
    return current, status, frames

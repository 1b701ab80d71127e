"""The adaptive solvers' run: an attempted step with its error estimate, and the controller
that keeps, retries and sizes the steps until the run's time is reached.

A solver with `adaptive` (`solvers`) supplies a step and its embedded lower-order estimate;
`make_attempt` turns them into one attempted step and an error norm, and
`integrate_adaptive` runs attempts under a bounded `while_loop`, keeping a step when its
norm is <= 1 and sizing the next from it. Fixed-step runs never come here (`_loop`).
"""

from __future__ import annotations

import equinox.internal as eqxi
import jax
import jax.numpy as jnp

from ._state import State
from ._step import Carry, Config, sources_and_limits
from .domains import AbstractDomain
from .models import AbstractModel


def make_attempt(model: AbstractModel, domain: AbstractDomain, dt, cfg: Config, solver, shape):
    """attempt(carry, h) -> (carry after a step of h, error norm), for an adaptive solver.

    The norm is max |high - low| / (atol + rtol max|x_i|) over species i and cells: high and
    low are the step and its embedded lower-order estimate, both clamped to the limits
    (where a limit binds both land on it, and the scheme's error there does not reach the
    solution), and the relative part is scaled by each species' largest magnitude, not
    cell by cell: a cell near 0 would otherwise hold the step to the transforms' float32
    rounding (measured: a cell-by-cell scale kept h at 1e-4 on the bounded Turing model,
    where the rounding of two transform round trips, about 2e-6, met atol 1e-6). A step is
    acceptable when the norm is <= 1.
    """
    advance = solver.make_advance(model, domain, dt, cfg.bounds, shape)

    def attempt(c: Carry, h):
        x = domain.interior(c.p)
        acting = model.at(x)
        high, low = (sources_and_limits(acting, y, {}, domain.ndim, cfg.bounds) for y in advance(acting, x, h))
        spatial = tuple(range(1, x.ndim))
        scale = solver.atol + solver.rtol * jnp.max(jnp.abs(x), axis=spatial, keepdims=True)
        error = jnp.max(jnp.abs(high - low) / scale)
        return c._replace(p=domain.write(c.p, high, c.size, False), step=c.step + 1), error

    return attempt


# Step-size control of the adaptive solvers: the next step is h (0.9 / error)^(1/2) (the
# embedded estimate's local error is O(h^2)), changed by at most 5x up and 5x down per
# attempt; a run whose step falls below 1e-9 of its span stops there, `incomplete`.
SAFETY, MAX_GROWTH, MAX_SHRINK, SMALLEST = 0.9, 5.0, 0.2, 1e-9


def integrate_adaptive(model, domain, fields, size, step0, time0, dt, steps, cfg, solver, until, names, growable):
    """Steps of varying size h until the time steps * dt is reached: each attempt is kept
    when its error norm is <= 1 and retried with a smaller h otherwise, inside the loop.
    The state's step counts the steps kept; its time is time0 + the time reached. A run
    whose `solver.max_steps` attempts do not reach the time, or whose step stalls, is
    `incomplete` (the last element returned)."""
    attempt = make_attempt(model, domain, dt, cfg, solver, fields.shape[1:])
    span = steps * dt
    steady = None if until is None else jnp.asarray(jnp.nan, dt.dtype)
    c = Carry(domain.carry(fields, size, False), size, step0, jnp.asarray(-1, jnp.int32), jnp.asarray(False), steady)
    zero = jnp.zeros((), dt.dtype)

    def short(t):
        return t < span * (1 - 1e-6)

    def running(s):
        c, t, h, stalled = s
        going = short(t) & (c.bad < 0) & ~stalled
        return going if until is None else going & jnp.isnan(c.steady)

    def one(s):
        c, t, h, stalled = s
        h_try = jnp.minimum(h, span - t)
        new, error = attempt(c, h_try)
        ok = error <= 1.0  # False for NaN: a non-finite step is retried smaller
        factor = jnp.where(error > 0, SAFETY * jnp.where(error > 0, error, 1.0) ** -0.5, MAX_GROWTH)
        h_next = h_try * jnp.clip(jnp.nan_to_num(factor, nan=MAX_SHRINK), MAX_SHRINK, MAX_GROWTH)
        if until is not None:
            change = jnp.max(jnp.abs(domain.interior(new.p) - domain.interior(c.p))) / h_try
            new = new._replace(steady=jnp.where(change < until.tol, time0 + t + h_try, c.steady))
        stalled = stalled | ((h_next < SMALLEST * span) & ~ok)
        c = jax.tree_util.tree_map(lambda a, b: jnp.where(ok, a, b), new, c)
        return c, jnp.where(ok, t + h_try, t), h_next, stalled

    c, t, _, _ = eqxi.while_loop(running, one, (c, zero, jnp.asarray(dt, dt.dtype), jnp.asarray(False)),
                                 max_steps=solver.max_steps, kind="checkpointed")
    final = State(domain.interior(c.p), c.size, c.step, time0 + t, names, growable)
    stopped = jnp.asarray(False) if until is None else ~jnp.isnan(c.steady)
    incomplete = short(t) & (c.bad < 0) & ~stopped
    return final, c.bad, c.overflow, None, c.steady_time(dt), incomplete

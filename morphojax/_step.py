"""One step: reaction + diffusion by the domain and the solver, sources, limits, growth.

As in the leopard paper (section 7): integrate reaction + diffusion (forward Euler by
default; the solver is a policy, see `solvers`), add any localised production (sources),
clamp every species to [lower, upper], and expand the lattice when the growth schedule
says so. The step is a function of the loop's carry; the
loop (`_loop`) scans it.

Random numbers follow one key schedule (`step_key`, `growth_key`, `source_key`): step n
of a run with key k draws from fold_in(k, n), its growth from fold_in(., 0) and source j
from fold_in(., 1 + j). Every number therefore depends on the run's key and the step
only, never on how the run is cut into chunks, blocks or pieces, so resumed runs draw
what the uninterrupted run draws.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from jax import Array

from ._bounds import Barrier
from .domains import AbstractDomain
from .models import AbstractModel, per_species
from .solvers import Euler


class Carry(NamedTuple):
    """What the loop carries from step to step."""

    p: Array  # the fields in the domain's carried layout (a lattice: ghost-padded)
    size: Array  # active (rows, cols)
    step: Array  # global step counter
    bad: Array  # first step whose result was non-finite, -1 if none
    overflow: Array  # growth wanted to pass the capacity
    steady: Array | None = None  # with a stopping rule: simulated time it stopped at, NaN before

    def steady_time(self, dt) -> Array:
        """The time a stopping rule stopped the run at; NaN before, or without a rule."""
        return jnp.asarray(jnp.nan, dt.dtype) if self.steady is None else self.steady


class Config(NamedTuple):
    """Static configuration of a run's step."""

    bounds: Any  # "clip" or Barrier
    dynamic: bool  # active region smaller than the array (growth)


# ---- the key schedule ----------------------------------------------------------------
def step_key(key, step):
    """The key of step `step` (None without a key)."""
    return None if key is None else jax.random.fold_in(key, step)


def growth_key(key, step):
    """The key of the expansion that follows step `step`."""
    return jax.random.fold_in(step_key(key, step), 0)


def source_key(key, step, j: int):
    """The key of source `j`'s production in step `step`."""
    return jax.random.fold_in(step_key(key, step), 1 + j)


# ---- the step ----------------------------------------------------------------------------
def slice_maps(model, block):
    """The model with its lattice maps (leaves with 2+ dims) cut to a (rows, cols) block."""
    def cut(leaf):
        if getattr(leaf, "ndim", 0) >= 2:
            return leaf[..., : min(block[0], leaf.shape[-2]), : min(block[1], leaf.shape[-1])]
        return leaf

    return jax.tree_util.tree_map(cut, model)


def make_step(model: AbstractModel, domain: AbstractDomain, dt, cfg: Config, growth, sources, key, origin,
              block=None, solver=None, shape=None):
    """One step on the whole array, or on its top-left `block` (rows, cols) of the lattice.

    `solver` (default `Euler()`) advances reaction + diffusion; a solver other than Euler
    steps the whole lattice of spatial `shape` (it was checked to run without growth)."""
    if block is not None:
        model = slice_maps(model, block)
    barrier = cfg.bounds if isinstance(cfg.bounds, Barrier) else None
    euler = solver is None or isinstance(solver, Euler)
    advance = None if euler else solver.make_advance(model, domain, dt, cfg.bounds, shape)

    def clamp(m, new, production):
        return sources_and_limits(m, new, production, domain.ndim, cfg.bounds)

    def update(m, x, diffusion_terms, production, mask):
        """New values of the cells `x` (species, ...) given their diffusion terms: reaction,
        diffusion, production, clamp. Species by species, stacked once at the end, so that
        XLA computes the whole update in one loop."""
        lower, upper = per_species(m.lower, domain.ndim), per_species(m.upper, domain.ndim)
        rates = m.reaction(x)
        parts = []
        for i in range(x.shape[0]):
            rate = rates[i] + diffusion_terms[i]
            if barrier is not None:
                rate = rate + barrier.terms(x[i], lower[i], upper[i])
            value = x[i] + dt * rate
            if i in production:
                value = value + production[i]
            if cfg.bounds == "clip":
                value = jnp.clip(value, lower[i], upper[i])
            parts.append(value)
        new = jnp.stack(parts)
        # the mask after stacking, so that only the select fuses into the domain's in-place
        # write (masking each species before the stack fuses the whole update into the
        # write, which then copies the buffer)
        return new if mask is None else jnp.where(mask, new, 0.0)

    def step(c: Carry) -> Carry:
        x = domain.interior(c.p)
        production = {}
        for j, src in enumerate(sources):
            amount = src.production(c.size, source_key(key, c.step, j), x[src.index])
            production[src.index] = production[src.index] + amount if src.index in production else amount
        mask = domain.active_mask(x.shape[1:], c.size) if cfg.dynamic else None
        acting = model.at(x)  # the model itself unless its parameters follow the state
        if euler:
            rates = per_species(acting.diffusion(), domain.ndim)
            terms = domain.active_diffusion(c.p, rates, c.size) if cfg.dynamic else domain.diffusion(c.p, rates)
            new = update(acting, x, terms, production, mask)
        else:
            new = clamp(acting, advance(acting, x, carried=c.p), production)  # the stencil from the ghost cells
        p = domain.write(c.p, new, c.size, cfg.dynamic)
        size, overflow = c.size, c.overflow
        if growth is not None:
            p, size, overflow = grow_if_due(growth, domain, p, size, c.step + 1 - origin, dt,
                                            growth_key(key, c.step), overflow)
        return Carry(p, size, c.step + 1, c.bad, overflow, c.steady)

    return step


def sources_and_limits(m, new, production: dict, ndim: int, bounds):
    """Sources and limits after a solver's step, species by species."""
    lower, upper = per_species(m.lower, ndim), per_species(m.upper, ndim)
    parts = []
    for i in range(new.shape[0]):
        value = new[i] + production[i] if i in production else new[i]
        parts.append(jnp.clip(value, lower[i], upper[i]) if bounds == "clip" else value)
    return jnp.stack(parts)


def grow_if_due(growth, domain: AbstractDomain, p, size, k, dt, key, overflow):
    """Expand the active region when phase step `k` (1-based) opens a growth period; a due
    expansion with no room left is recorded in `overflow` instead."""
    capacity = domain.interior(p).shape[-2:]
    copies = domain.expansion_copies
    due = growth.is_due(k, dt)
    room = (size[0] + copies <= capacity[0]) & (size[1] + copies <= capacity[1])

    def grow(args):
        p, size = args
        x, size = growth.expand(domain.interior(p), size, key, copies)
        return domain.write(p, x, size, True), size

    p, size = jax.lax.cond(due & room, grow, lambda a: a, (p, size))
    return p, size, overflow | (due & ~room)

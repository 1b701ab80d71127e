"""One iteration of the cell simulator, in the order of the thesis's loop (4.1):

1. the domain's size (a packed domain follows the number of cells, 4.2);
2. rules, on the current state, their effects accumulated (4.8.5, `_rules`);
3. neighbours within the influence radius (4.2, `_neighbours`);
4. diffusion between neighbours, dR_i = dt sum_j D_ij (R_j - R_i), with D_ij the
   harmonic mean of the two cells' rates, 2 D_i D_j / (D_i + D_j) (eq. 4.7), each rate
   first scaled by |d . p| / |d| for anisotropic reagents of polarised cells (eq. 4.8):
   the exchange is symmetric, so every reagent's total is conserved;
5. collisions: o_i = sum_j (0.25 - 0.5 / |d_j|) d_j over neighbours with 0 < |d_j| < 2
   (eq. 4.9; fixed cells never move);
6. limits: concentrations into [lower, upper] (0 and the saturation limit in the
   thesis), diffusion rates >= 0, positions into the domain;
7. newborn cells: each dividing cell (at most `division_limit` neighbours) gets a child
   one unit away at angle polarity + the rule's direction, a copy of the parent as the
   rules saw it (concentrations, rates; 4.4) with its polarity turned by the same angle,
   born next iteration;
8. the next state replaces the current one.

Polarization (eq. 4.10) sets p = sum_j (R_j - R_i) d_j / |d_j| for the next iteration.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from ._neighbours import NeighbourList, Search
from ._rules import Always, Chance, Change, Compare, Divide, Map, Polarize, React, Rule, Var, Within
from ._space import clamp_positions
from ._state import Cells

CONTACT = 2.0  # unit-radius cells overlap below this distance (eq. 4.9)


class Settings(eqx.Module):
    """What stays fixed during a run: dt, the domain, the division limit, the search."""

    dt: Array
    domain: object
    influence_radius: float = eqx.field(static=True)
    division_limit: int | None = eqx.field(static=True)
    search: Search


class Contacts(eqx.Module):
    """The neighbours of every cell this iteration, per slot of the neighbour list: the
    index, `near` (a live neighbour within the influence radius), the offset (dx, dy) to
    it, its distance and the unit direction (ux, uy). Coordinates are kept apart: (C, K)
    arrays reduce several times faster on a CPU than (C, K, 2) ones."""

    index: Array
    near: Array
    dx: Array
    dy: Array
    distance: Array
    ux: Array
    uy: Array

    @property
    def count(self) -> Array:
        return jnp.sum(self.near, axis=1)


def contacts(cells: Cells, neighbours: NeighbourList, radius: float) -> Contacts:
    index = neighbours.index
    capacity = cells.capacity
    safe = jnp.minimum(index, capacity - 1)
    x, y = cells.position[:, 0], cells.position[:, 1]
    dx = jnp.take(x, safe, mode="clip") - x[:, None]
    dy = jnp.take(y, safe, mode="clip") - y[:, None]
    squared = dx * dx + dy * dy
    near = (index < capacity) & (squared < radius * radius) & cells.alive[:, None]
    apart = near & (squared > 0)
    distance = jnp.sqrt(jnp.where(apart, squared, 1.0))
    ux, uy = jnp.where(apart, dx / distance, 0.0), jnp.where(apart, dy / distance, 0.0)
    return Contacts(safe, near, dx, dy, distance, ux, uy)


# ---- rules ------------------------------------------------------------------------
class _Effects(NamedTuple):
    """What the rules ask for this iteration, accumulated over the rules."""

    conc: Array
    rates: Array
    divide: Array
    direction: Array
    polarise: Array
    polarity: Array
    maps: dict


def _value(v, cells: Cells, near_count: Array, iteration: Array, maps: dict):
    if not isinstance(v, Var):
        return v
    if v.kind == "conc":
        return cells.concentration[cells.index(v.name)]
    if v.kind == "diff":
        return cells.diffusion[cells.index(v.name)]
    if v.kind == "AGE":
        return (iteration - cells.birth).astype(cells.position.dtype)
    if v.kind == "BIRTH":
        return cells.birth.astype(cells.position.dtype)
    if v.kind == "NEIGHBORS":
        return near_count.astype(cells.position.dtype)
    return maps[v.name]


_COMPARE = {
    "==": jnp.equal, "!=": jnp.not_equal, "<": jnp.less,
    "<=": jnp.less_equal, ">": jnp.greater, ">=": jnp.greater_equal,
}


def _holds(condition, value, key: Array, capacity: int) -> Array:
    if isinstance(condition, Always):
        return jnp.ones(capacity, bool)
    if isinstance(condition, Compare):
        return jnp.broadcast_to(_COMPARE[condition.op](value(condition.left), value(condition.right)), (capacity,))
    if isinstance(condition, Within):
        x = value(condition.value)
        return jnp.broadcast_to((x >= value(condition.low)) & (x <= value(condition.high)), (capacity,))
    assert isinstance(condition, Chance)
    return jax.random.uniform(key, (capacity,)) < value(condition.probability)


def _gradient(cells: Cells, touch: Contacts, name: str) -> Array:
    """Eq. 4.10: sum_j (R_j - R_i) d_j / |d_j|, per cell (C, 2)."""
    r = cells[name]
    rise = jnp.where(touch.near, jnp.take(r, touch.index, mode="clip") - r[:, None], 0.0)
    return jnp.stack([jnp.sum(rise * touch.ux, axis=1), jnp.sum(rise * touch.uy, axis=1)], axis=1)


def apply_rules(rules: tuple[Rule, ...], cells: Cells, touch: Contacts, iteration: Array, dt: Array,
                key: Array) -> _Effects:
    """The accumulated effects of every rule on the current state (thesis 4.8.5)."""
    capacity = cells.capacity
    near_count = touch.count
    fx = _Effects(
        conc=jnp.zeros_like(cells.concentration), rates=jnp.zeros_like(cells.diffusion),
        divide=jnp.zeros(capacity, bool), direction=jnp.zeros_like(cells.polarity),
        polarise=jnp.zeros(capacity, bool), polarity=cells.polarity, maps={},
    )
    alive = cells.alive
    for k, rule in enumerate(rules):
        rule_key = jax.random.fold_in(key, k)
        maps = dict(fx.maps)

        def value(v, maps=maps):
            return _value(v, cells, near_count, iteration, maps)

        mask = alive & rule.active(iteration)
        for c, condition in enumerate(rule.when):
            mask &= _holds(condition, value, jax.random.fold_in(rule_key, c), capacity)
        action_key = jax.random.fold_in(rule_key, len(rule.when))
        fx = _act(rule.action, fx, mask, value, cells, touch, dt, action_key, maps)
    return fx


def _uniform(key, shape, amplitude):
    return amplitude * jax.random.uniform(key, shape, minval=-1.0, maxval=1.0)


def _act(action, fx: _Effects, mask: Array, value, cells: Cells, touch: Contacts, dt, key, maps) -> _Effects:
    capacity = cells.capacity
    if isinstance(action, Change):
        amount = jnp.broadcast_to(value(action.amount), (capacity,)) + _uniform(key, (capacity,), action.spread)
        row = cells.index(action.target.name)
        delta = jnp.where(mask, amount, 0.0)
        if action.target.kind == "conc":
            return fx._replace(conc=fx.conc.at[row].add(delta))
        return fx._replace(rates=fx.rates.at[row].add(delta))
    if isinstance(action, React):
        rows = jnp.asarray([cells.index(name) for name in action.species])
        # cells the rule skips (and unused capacity, all zeros) react on a harmless 1, so a
        # reaction singular at 0 (Gierer-Meinhardt) leaves no NaN in the gradient
        x = jnp.where(mask, cells.concentration[rows], 1.0)
        rate = action.model.reaction(x) * (dt * value(action.scale))
        return fx._replace(conc=fx.conc.at[rows].add(jnp.where(mask, rate, 0.0)))
    if isinstance(action, Divide):
        first = mask & ~fx.divide  # the first divide rule that fires sets the direction
        angle = action.direction + _uniform(key, (capacity,), action.spread)
        return fx._replace(divide=fx.divide | mask, direction=jnp.where(first, angle, fx.direction))
    if isinstance(action, Map):
        low, high, a, b = (value(v) for v in (action.low, action.high, action.out_low, action.out_high))
        span = jnp.where(high != low, high - low, 1.0)
        out = jnp.clip(a + (value(action.source) - low) * (b - a) / span, jnp.minimum(a, b), jnp.maximum(a, b))
        previous = maps.get(action.name, jnp.zeros(capacity, cells.position.dtype))
        new_maps = dict(maps)
        new_maps[action.name] = jnp.where(mask, jnp.broadcast_to(out, (capacity,)), previous)
        return fx._replace(maps=new_maps)
    assert isinstance(action, Polarize)
    p = _gradient(cells, touch, action.reagent)
    steered = mask & (jnp.sum(p * p, axis=1) > 0)
    angle = jnp.arctan2(p[:, 1], jnp.where(steered, p[:, 0], 1.0))
    return fx._replace(polarise=fx.polarise | steered, polarity=jnp.where(steered, angle, fx.polarity))


# ---- diffusion and collision --------------------------------------------------------
def diffusion_change(cells: Cells, touch: Contacts, dt: Array) -> Array:
    """dt sum_j D_ij (R_j - R_i) per reagent and cell (eqs. 4.7-4.8), shape (species, C)."""
    idx = touch.index
    rate_i = jnp.broadcast_to(cells.diffusion[:, :, None], (cells.n_species,) + idx.shape)
    rate_j = jnp.take(cells.diffusion, idx, axis=1, mode="clip")
    if any(cells.anisotropic):
        px, py = jnp.cos(cells.polarity), jnp.sin(cells.polarity)
        align_i = jnp.abs(touch.ux * px[:, None] + touch.uy * py[:, None])
        align_j = jnp.abs(touch.ux * jnp.take(px, idx, mode="clip") + touch.uy * jnp.take(py, idx, mode="clip"))
        align_i = jnp.where(cells.polarised[:, None], align_i, 1.0)
        align_j = jnp.where(jnp.take(cells.polarised, idx, mode="clip"), align_j, 1.0)
        steer = jnp.asarray(cells.anisotropic)[:, None, None]
        rate_i = jnp.where(steer, rate_i * align_i, rate_i)
        rate_j = jnp.where(steer, rate_j * align_j, rate_j)
    total = rate_i + rate_j
    positive = total > 0
    combined = jnp.where(positive, 2 * rate_i * rate_j / jnp.where(positive, total, 1.0), 0.0)
    r = cells.concentration
    exchange = jnp.where(touch.near, combined * (jnp.take(r, idx, axis=1, mode="clip") - r[:, :, None]), 0.0)
    return dt * jnp.sum(exchange, axis=-1)


def collision_offset(cells: Cells, touch: Contacts) -> Array:
    """Eq. 4.9: o_i = sum_j (0.25 - 0.5 / |d_j|) d_j for 0 < |d_j| < 2; zero for fixed cells."""
    overlap = touch.near & (touch.distance < CONTACT) & ((touch.dx != 0) | (touch.dy != 0))
    weight = jnp.where(overlap, 0.25 - 0.5 / touch.distance, 0.0)
    offset = jnp.stack([jnp.sum(weight * touch.dx, axis=1), jnp.sum(weight * touch.dy, axis=1)], axis=1)
    return jnp.where((cells.fixed | ~cells.alive)[:, None], 0.0, offset)


# ---- division -------------------------------------------------------------------------
def divide(cells: Cells, parents: Cells, wants: Array, direction: Array, iteration: Array) -> Cells:
    """Append to `cells` a child for every cell in `wants`, in index order, while capacity
    lasts. A child is its parent as the rules saw it (`parents`, the iteration's current
    state: the thesis lists newborns while evaluating rules, 4.1 steps 2 and 7), one unit
    away at the parent's polarity + `direction`; so a child differs from its parent by the
    parent's update of this iteration, which is what lets a tissue grown from one cell
    (Fig. 6.3) break its symmetry."""
    capacity = cells.capacity
    rank = jnp.cumsum(wants) - 1
    seat = cells.count + rank
    fits = wants & (seat < capacity)
    target = jnp.where(fits, seat, capacity)
    angle = parents.polarity + direction
    child_position = parents.position + jnp.stack([jnp.cos(angle), jnp.sin(angle)], axis=1)

    def put(buffer, values, axis=0):
        if axis == 0:
            return buffer.at[target].set(values, mode="drop")
        return buffer.at[:, target].set(values, mode="drop")

    overflowed = jnp.any(wants & ~fits)
    return eqx.tree_at(
        lambda c: (c.position, c.polarity, c.polarised, c.concentration, c.diffusion, c.birth, c.fixed,
                   c.count, c.overflow_step),
        cells,
        (
            put(cells.position, child_position),
            put(cells.polarity, angle),
            put(cells.polarised, parents.polarised),
            put(cells.concentration, parents.concentration, axis=1),
            put(cells.diffusion, parents.diffusion, axis=1),
            put(cells.birth, jnp.full_like(cells.birth, iteration + 1)),
            put(cells.fixed, jnp.zeros_like(cells.fixed)),  # children always move (so they can make room)
            cells.count + jnp.sum(fits).astype(jnp.int32),
            jnp.where((cells.overflow_step < 0) & overflowed, iteration, cells.overflow_step),
        ),
    )


# ---- the iteration ----------------------------------------------------------------------
def step(cells: Cells, neighbours: NeighbourList, rules: tuple[Rule, ...], settings: Settings,
         key: Array) -> tuple[Cells, NeighbourList]:
    """One iteration (the thesis's loop, 4.1); returns the next cells and neighbour list."""
    iteration = cells.step
    dt = settings.dt
    touch = contacts(cells, neighbours, settings.influence_radius)
    fx = apply_rules(rules, cells, touch, iteration, dt, jax.random.fold_in(key, iteration))

    alive = cells.alive
    concentration = cells.concentration + fx.conc + diffusion_change(cells, touch, dt)
    concentration = jnp.where(alive, jnp.clip(concentration, cells.lower[:, None], cells.upper[:, None]), 0.0)
    rates = jnp.where(alive, jnp.maximum(cells.diffusion + fx.rates, 0.0), 0.0)
    position = clamp_positions(settings.domain, cells.position + collision_offset(cells, touch), cells.count)
    position = jnp.where(alive[:, None], position, 0.0)
    finite = jnp.all(jnp.isfinite(concentration)) & jnp.all(jnp.isfinite(position))

    nxt = eqx.tree_at(
        lambda c: (c.concentration, c.diffusion, c.position, c.polarity, c.polarised, c.nonfinite_step),
        cells,
        (concentration, rates, position, fx.polarity, cells.polarised | fx.polarise,
         jnp.where((cells.nonfinite_step < 0) & ~finite, iteration, cells.nonfinite_step)),
    )
    wants = fx.divide & alive
    if settings.division_limit is not None:
        wants &= touch.count <= settings.division_limit
    nxt = divide(nxt, cells, wants, fx.direction, iteration)
    if settings.domain is not None:  # newborns start inside the domain too
        nxt = eqx.tree_at(lambda c: c.position, nxt, clamp_positions(settings.domain, nxt.position, nxt.count))
    nxt = eqx.tree_at(lambda c: c.step, nxt, iteration + 1)

    neighbours = settings.search.update(neighbours, nxt.position, nxt.count)
    nxt = eqx.tree_at(
        lambda c: c.neighbour_overflow_step, nxt,
        jnp.where((nxt.neighbour_overflow_step < 0) & neighbours.overflow, iteration, nxt.neighbour_overflow_step),
    )
    return nxt, neighbours

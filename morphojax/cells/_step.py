"""One iteration of the cell simulator, in the order of the thesis's loop (4.1):

1. the domain's size (a packed domain follows the number of cells, 4.2);
2. rules, on the current state, their effects accumulated (4.8.5, `_evaluate`);
3. neighbours within the influence radius (4.2, `_neighbours`, `_contacts`);
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

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from ._contacts import Contacts, contacts
from ._evaluate import Directions, apply_rules
from ._neighbours import NeighbourList, Search
from ._rules import Rule
from ._space import clamp_positions
from ._state import Cells



class Settings(eqx.Module):
    """What stays fixed during a run: dt, the domain, the division limit, the search."""

    dt: Array
    domain: object
    influence_radius: float = eqx.field(static=True)
    division_limit: int | None = eqx.field(static=True)
    search: Search


# ---- diffusion and collision --------------------------------------------------------
def harmonic_rate(rate_i: Array, rate_j: Array) -> Array:
    """Eq. 4.7: the link's rate 2 D_i D_j / (D_i + D_j); 0 where both are 0 (with a
    gradient that stays finite there)."""
    total = rate_i + rate_j
    positive = total > 0
    return jnp.where(positive, 2 * rate_i * rate_j / jnp.where(positive, total, 1.0), 0.0)


def diffusion_change(cells: Cells, touch: Contacts, dt: Array) -> Array:
    """dt sum_j D_ij (R_j - R_i) per reagent and cell (eqs. 4.7-4.8), shape (species, C).

    One reagent at a time, with 1D takes: on a CPU several times faster than gathering
    the (species, C) arrays along their second axis."""
    idx = touch.index
    if any(cells.anisotropic):
        px, py = jnp.cos(cells.polarity), jnp.sin(cells.polarity)
        align_i = jnp.abs(touch.ux * px[:, None] + touch.uy * py[:, None])
        align_j = jnp.abs(touch.ux * jnp.take(px, idx, mode="clip") + touch.uy * jnp.take(py, idx, mode="clip"))
        align_i = jnp.where(cells.polarised[:, None], align_i, 1.0)
        align_j = jnp.where(jnp.take(cells.polarised, idx, mode="clip"), align_j, 1.0)
    change = []
    for s, steered in enumerate(cells.anisotropic):
        rate = cells.diffusion[s]
        rate_i, rate_j = rate[:, None], jnp.take(rate, idx, mode="clip")
        if steered:
            rate_i, rate_j = rate_i * align_i, rate_j * align_j
        combined = harmonic_rate(rate_i, rate_j)
        r = cells.concentration[s]
        exchange = jnp.where(touch.near, combined * (jnp.take(r, idx, mode="clip") - r[:, None]), 0.0)
        change.append(jnp.sum(exchange, axis=-1))
    return dt * jnp.stack(change)


def collision_offset(cells: Cells, touch: Contacts) -> Array:
    """Eq. 4.9: o_i = sum_j (0.25 - 0.5 / |d_j|) d_j for 0 < |d_j| < 2; zero for fixed cells
    (the sums are `touch.push`, made with the contacts)."""
    return jnp.where((cells.fixed | ~cells.alive)[:, None], 0.0, touch.push)


# ---- division -------------------------------------------------------------------------
def divide(cells: Cells, parents: Cells, wants: Array, direction: Array | Directions, iteration: Array) -> Cells:
    """Append to `cells` a child for every cell in `wants`, in index order, while capacity
    lasts. A child is its parent as the rules saw it (`parents`, the iteration's current
    state: the thesis lists newborns while evaluating rules, 4.1 steps 2 and 7), one unit
    away at the parent's polarity + `direction`; so a child differs from its parent by the
    parent's update of this iteration, which is what lets a tissue grown from one cell
    (Fig. 6.3) break its symmetry. `direction`: the angles the rules drew, per cell
    (capacity,) or as `Directions` (drawn then for the dividing cells only).

    An iteration without divisions writes nothing, and one with at most `FEW_DIVISIONS`
    writes only their seats; the children are the same either way."""
    wanted = jnp.sum(wants)
    branch = jnp.where(wanted == 0, 0, jnp.where(wanted <= FEW_DIVISIONS, 1, 2))
    return jax.lax.switch(branch, [lambda c: c,
                                   lambda c: _append(c, parents, wants, direction, iteration, FEW_DIVISIONS),
                                   lambda c: _append(c, parents, wants, direction, iteration, None)], cells)


FEW_DIVISIONS = 16  # divisions an iteration writes seat by seat; more: every buffer is written whole


def _append(cells: Cells, parents: Cells, wants: Array, direction: Array | Directions, iteration: Array,
            size: int | None) -> Cells:
    """`divide` for the first `size` cells in `wants` (all of them: None)."""
    capacity = cells.capacity
    if size is None:
        def pick(values, axis=0):
            return values
        wanting = wants
    else:
        source = jnp.nonzero(wants, size=size, fill_value=capacity)[0]

        def pick(values, axis=0):
            return jnp.take(values, source, axis=axis, mode="clip")
        wanting = source < capacity
    rank = jnp.cumsum(wanting) - 1
    seat = cells.count + rank
    fits = wanting & (seat < capacity)
    target = jnp.where(fits, seat, capacity)
    if isinstance(direction, Directions):
        drawn = direction.full() if size is None else direction.at(source)
    else:
        drawn = pick(direction)
    angle = pick(parents.polarity) + drawn
    child_position = pick(parents.position) + jnp.stack([jnp.cos(angle), jnp.sin(angle)], axis=1)

    def put(buffer, values, axis=0):
        if axis == 0:
            return buffer.at[target].set(values, mode="drop")
        return buffer.at[:, target].set(values, mode="drop")

    overflowed = jnp.any(wanting & ~fits)
    return eqx.tree_at(
        lambda c: (c.position, c.polarity, c.polarised, c.concentration, c.diffusion, c.birth, c.fixed,
                   c.count, c.overflow_step),
        cells,
        (
            put(cells.position, child_position),
            put(cells.polarity, angle),
            put(cells.polarised, pick(parents.polarised)),
            put(cells.concentration, pick(parents.concentration, 1), axis=1),
            put(cells.diffusion, pick(parents.diffusion, 1), axis=1),
            put(cells.birth, jnp.full(target.shape, iteration + 1, cells.birth.dtype)),
            put(cells.fixed, jnp.zeros(target.shape, bool)),  # children always move (so they can make room)
            cells.count + jnp.sum(fits).astype(jnp.int32),
            jnp.where((cells.overflow_step < 0) & overflowed, iteration, cells.overflow_step),
        ),
    )


# ---- the iteration ----------------------------------------------------------------------
def step(cells: Cells, neighbours: NeighbourList, touch: Contacts, rules: tuple[Rule, ...], settings: Settings,
         key: Array) -> tuple[Cells, NeighbourList, Contacts]:
    """One iteration (the thesis's loop, 4.1): the next cells, neighbour list and contacts.

    `touch` is `contacts(cells, neighbours, ...)`, carried from the iteration before: a
    tissue that did not move keeps its neighbours and contacts, and one without overlaps
    skips the collisions (on a static grid, most of an iteration's geometry)."""
    iteration = cells.step
    dt = settings.dt
    fx = apply_rules(rules, cells, touch, iteration, dt, jax.random.fold_in(key, iteration))

    alive = cells.alive
    concentration = cells.concentration + fx.conc + diffusion_change(cells, touch, dt)
    concentration = jnp.where(alive, jnp.clip(concentration, cells.lower[:, None], cells.upper[:, None]), 0.0)
    rates = jnp.where(alive, jnp.maximum(cells.diffusion + fx.rates, 0.0), 0.0)
    offset = jax.lax.cond(touch.overlapping, collision_offset, lambda c, t: jnp.zeros_like(c.position), cells, touch)
    position = clamp_positions(settings.domain, cells.position + offset, cells.count)
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

    moved = (nxt.count != cells.count) | jnp.any(nxt.position != cells.position)

    def follow(neighbours):
        neighbours = settings.search.update(neighbours, nxt.position, nxt.count)
        return neighbours, contacts(nxt, neighbours, settings.influence_radius)

    neighbours, touch = jax.lax.cond(moved, follow, lambda n: (n, touch), neighbours)
    nxt = eqx.tree_at(
        lambda c: c.neighbour_overflow_step, nxt,
        jnp.where((nxt.neighbour_overflow_step < 0) & neighbours.overflow, iteration, nxt.neighbour_overflow_step),
    )
    return nxt, neighbours, touch

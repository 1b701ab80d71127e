"""The cells each cell touches this iteration: from the neighbour list (cells within the
influence radius + skin), those strictly within the influence radius, with the offset,
distance and unit direction to each (thesis 4.2; the d and |d| of eqs. 4.8-4.10). On a
torus (the list's `period`) the offset is the neighbour's nearest periodic image."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from ._neighbours import NeighbourList
from ._space import minimum_image
from ._state import Cells


CONTACT = 2.0  # unit-radius cells overlap below this distance (eq. 4.9)


class Contacts(eqx.Module):
    """The neighbours of every cell this iteration, per slot of the neighbour list: the
    index (the list's own: empty slots hold the capacity, so read it with `mode="clip"`,
    which takes the last cell there, where `near` is False), `near` (a live neighbour
    within the influence radius), the offset (dx, dy) to it, its distance and the unit
    direction (ux, uy). Coordinates are kept apart: (C, K) arrays reduce several times
    faster on a CPU than (C, K, 2) ones.

    With them, what the collisions of eq. 4.9 make of them, summed as the geometry is
    computed (one pass over the slots instead of a second that reads dx, dy and the
    distance back): `push` (C, 2), o_i = sum_j (0.25 - 0.5 / |d_j|) d_j over the
    neighbours with 0 < |d_j| < 2 (fixed or not: the step leaves fixed cells where they
    are), and `overlapping`, whether any live pair is closer than 2."""

    index: Array
    near: Array
    dx: Array
    dy: Array
    distance: Array
    ux: Array
    uy: Array
    push: Array
    overlapping: Array

    @property
    def count(self) -> Array:
        return jnp.sum(self.near, axis=1)


def contacts(cells: Cells, neighbours: NeighbourList, radius: float) -> Contacts:
    index = neighbours.index
    capacity = cells.capacity
    x, y = cells.position[:, 0], cells.position[:, 1]
    dx = jnp.take(x, index, mode="clip") - x[:, None]  # empty slots (the capacity) read the last cell
    dy = jnp.take(y, index, mode="clip") - y[:, None]
    if neighbours.period is not None:
        dx, dy = minimum_image(dx, neighbours.period[0]), minimum_image(dy, neighbours.period[1])
    squared = dx * dx + dy * dy
    near = (index < capacity) & (squared < radius * radius) & cells.alive[:, None]
    apart = near & (squared > 0)
    distance = jnp.sqrt(jnp.where(apart, squared, 1.0))
    ux, uy = jnp.where(apart, dx / distance, 0.0), jnp.where(apart, dy / distance, 0.0)
    touching = near & (distance < CONTACT)
    overlap = touching & ((dx != 0) | (dy != 0))
    weight = jnp.where(overlap, 0.25 - 0.5 / distance, 0.0)
    push = jnp.stack([jnp.sum(weight * dx, axis=1), jnp.sum(weight * dy, axis=1)], axis=1)
    return Contacts(index, near, dx, dy, distance, ux, uy, push, jnp.any(touching.ravel()))

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
    if neighbours.period is not None:
        dx, dy = minimum_image(dx, neighbours.period[0]), minimum_image(dy, neighbours.period[1])
    squared = dx * dx + dy * dy
    near = (index < capacity) & (squared < radius * radius) & cells.alive[:, None]
    apart = near & (squared > 0)
    distance = jnp.sqrt(jnp.where(apart, squared, 1.0))
    ux, uy = jnp.where(apart, dx / distance, 0.0), jnp.where(apart, dy / distance, 0.0)
    return Contacts(safe, near, dx, dy, distance, ux, uy)

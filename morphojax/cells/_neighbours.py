"""Neighbours within the influence radius (thesis 4.2), from a hashed cell list, kept as a
Verlet list that is rebuilt only when cells were added or moved far enough.

Why not jax-md's `partition.neighbor_list`: jax-md 0.2.29 (the current release) imports
flax, e3nn-jax, optax, jraph and pymatgen on `import jax_md`, hundreds of megabytes for
one function; its list also needs a box that bounds every cell, while the thesis's
growth experiments (Figs. 6.3-6.6) grow without one. The search here is the same
algorithm in ~80 lines:

1. the live cells' bounding box is cut into at most `table_size` square buckets of side
   `radius` (wider when the cells spread too far for that, so unbounded growth needs no
   box), and the cells are sorted by bucket;
2. a cell's candidates are the cells of the 3 x 3 buckets around its own, at most
   `bucket_size` per bucket; a candidate counts if it lies strictly within `radius`;
3. the neighbours are packed into `max_neighbours` slots per cell (unused slots hold the
   capacity, an index past every cell).

Running out of room (a bucket with more than `bucket_size` cells, or a cell with more than
`max_neighbours` neighbours) sets `overflow`: the simulator records the iteration, so a
missed neighbour is never silent.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

_OFFSETS = np.array([(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1)], np.int32)


class NeighbourList(eqx.Module):
    """Per cell the indices of the cells within `radius` + skin at the last build.

    Attributes:
        index: (capacity, max_neighbours) int32; unused slots hold `capacity`.
        reference: (capacity, 2) the positions at the last build.
        built_count: the number of live cells at the last build.
        overflow: bool, the last build ran out of room.
    """

    index: Array
    reference: Array
    built_count: Array
    overflow: Array


class Search(eqx.Module):
    """How to search (static): the list radius (influence radius + skin), the Verlet skin,
    and the sizes of the buffers."""

    radius: float = eqx.field(static=True)
    skin: float = eqx.field(static=True)
    max_neighbours: int = eqx.field(static=True)
    bucket_size: int = eqx.field(static=True)
    table_size: int = eqx.field(static=True)

    def build(self, position: Array, count: Array) -> NeighbourList:
        index, overflow = find_neighbours(position, count, self.radius, self.max_neighbours,
                                          self.bucket_size, self.table_size)
        return NeighbourList(index, position, count, overflow)

    def update(self, neighbours: NeighbourList, position: Array, count: Array) -> NeighbourList:
        """The list, rebuilt when cells were added or one moved more than half the skin
        since the last build (then no pair can have come within the influence radius
        unseen)."""
        alive = jnp.arange(position.shape[0]) < count
        moved = jnp.max(jnp.where(alive, jnp.sum((position - neighbours.reference) ** 2, axis=1), 0.0))
        stale = (count != neighbours.built_count) | (moved > (self.skin / 2) ** 2)
        return jax.lax.cond(stale, lambda: self.build(position, count), lambda: neighbours)


def find_neighbours(position: Array, count: Array, radius: float, max_neighbours: int,
                    bucket_size: int, table_size: int) -> tuple[Array, Array]:
    """(index (capacity, max_neighbours), overflow) of the live cells within `radius`."""
    capacity = position.shape[0]
    alive = jnp.arange(capacity) < count
    side_count = int(np.floor(np.sqrt(table_size)))  # buckets per side, at most
    low = jnp.min(jnp.where(alive[:, None], position, jnp.inf), axis=0)
    high = jnp.max(jnp.where(alive[:, None], position, -jnp.inf), axis=0)
    # buckets are squares of side >= radius; wider only when the cells spread so far that
    # side_count buckets of side `radius` would not span them
    side = jnp.maximum(radius, jnp.max(high - low) / (side_count - 1))
    bucket = jnp.floor((position - low) / side).astype(jnp.int32)
    slot = jnp.where(alive, bucket[:, 0] + side_count * bucket[:, 1], table_size)
    order = jnp.argsort(slot)
    starts = jnp.searchsorted(slot[order], jnp.arange(table_size + 1), side="left").astype(jnp.int32)
    bucket_overflow = jnp.max(starts[1:] - starts[:-1]) > bucket_size

    wanted = bucket[:, None, :] + _OFFSETS[None]                      # (C, 9, 2)
    inside = jnp.all((wanted >= 0) & (wanted < side_count), axis=-1)
    wanted_slot = jnp.where(inside, wanted[..., 0] + side_count * wanted[..., 1], table_size)
    first, end = starts[wanted_slot], starts[jnp.minimum(wanted_slot + 1, table_size)]
    seat = first[..., None] + jnp.arange(bucket_size)                  # (C, 9, B)
    candidate = order[jnp.minimum(seat, capacity - 1)]
    gap = position[candidate] - position[:, None, None, :]
    near = jnp.sum(gap * gap, axis=-1) < radius * radius
    me = jnp.arange(capacity)[:, None, None]
    valid = (seat < end[..., None]) & inside[..., None] & near & (candidate != me) & alive[:, None, None]

    valid = valid.reshape(capacity, -1)
    candidate = candidate.reshape(capacity, -1)
    rank = jnp.cumsum(valid, axis=1) - 1
    target = jnp.where(valid & (rank < max_neighbours), rank, max_neighbours)
    rows = jnp.arange(capacity)[:, None]
    index = jnp.full((capacity, max_neighbours + 1), capacity, jnp.int32)
    index = index.at[rows, target].set(candidate.astype(jnp.int32))[:, :max_neighbours]
    overflow = bucket_overflow | jnp.any(jnp.sum(valid, axis=1) > max_neighbours)
    return index, overflow


def table_size_for(capacity: int) -> int:
    """Buckets: four per cell of capacity (at least 64), so a tissue at any density, and
    a sparse one spread over ~13 times its own area, keeps buckets of side `radius`."""
    return max(64, 4 * int(capacity))

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
2. a cell's candidates are the cells of the 3 x 3 buckets around its own: three runs of
   three buckets, each read up to 3 x `bucket_size` cells; a candidate counts if it lies
   strictly within `radius`;
3. the neighbours are packed into `max_neighbours` slots per cell (unused slots hold the
   capacity, an index past every cell).

Running out of room (three buckets in a row holding more than 3 x `bucket_size` cells, or a
cell with more than `max_neighbours` neighbours) sets `overflow`: the simulator records the iteration, so a
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
    buckets = side_count * side_count
    low = jnp.min(jnp.where(alive[:, None], position, jnp.inf), axis=0)
    high = jnp.max(jnp.where(alive[:, None], position, -jnp.inf), axis=0)
    # buckets are squares of side >= radius; wider only when the cells spread so far that
    # side_count buckets of side `radius` would not span them
    side = jnp.maximum(radius, jnp.max(high - low) / (side_count - 1))
    bucket = jnp.clip(jnp.floor((position - low) / side).astype(jnp.int32), 0, side_count - 1)
    slot = jnp.where(alive, bucket[:, 0] + side_count * bucket[:, 1], buckets)
    order = jnp.argsort(slot)
    # starts[k]: where the cells of bucket k begin in `order` (buckets row by row)
    starts = jnp.concatenate([jnp.zeros(1, jnp.int32),
                              jnp.cumsum(jnp.zeros(buckets + 1, jnp.int32).at[slot].add(1))])

    # the 3 x 3 buckets around a cell are three runs of consecutive buckets (one per row
    # of buckets), so three contiguous stretches of `order`, each read up to `run` cells
    run = 3 * bucket_size
    row = bucket[:, 1:2] + jnp.arange(-1, 2)[None, :]                  # (C, 3)
    row_inside = (row >= 0) & (row < side_count)
    row = jnp.clip(row, 0, side_count - 1)
    first = starts[jnp.maximum(bucket[:, 0:1] - 1, 0) + side_count * row]
    end = starts[jnp.minimum(bucket[:, 0:1] + 1, side_count - 1) + side_count * row + 1]
    end = jnp.where(row_inside, end, first)
    crowded = jnp.any(alive[:, None] & (end - first > run))
    seat = (first[..., None] + jnp.arange(run)).reshape(capacity, -1)  # (C, 3 run)
    # 1D takes in "clip" mode: several times faster on a CPU than gathering (x, y) rows
    candidate = jnp.take(order, seat, mode="clip")
    dx = jnp.take(position[:, 0], candidate, mode="clip") - position[:, 0:1]
    dy = jnp.take(position[:, 1], candidate, mode="clip") - position[:, 1:2]
    near = dx * dx + dy * dy < radius * radius
    me = jnp.arange(capacity)[:, None]
    valid = (seat < jnp.repeat(end, run, axis=1)) & near & (candidate != me) & alive[:, None]

    # pack the valid candidates into max_neighbours slots (one flat scatter: the fastest
    # compaction on a CPU, well ahead of a per-row sort or top_k)
    rank = _row_cumsum(valid) - 1
    column = jnp.where(valid & (rank < max_neighbours), rank, max_neighbours)
    flat = (jnp.arange(capacity)[:, None] * (max_neighbours + 1) + column).ravel()
    index = jnp.full(capacity * (max_neighbours + 1), capacity, jnp.int32)
    index = index.at[flat].set(candidate.astype(jnp.int32).ravel(), mode="promise_in_bounds")
    index = index.reshape(capacity, max_neighbours + 1)[:, :max_neighbours]
    overflow = crowded | jnp.any(rank[:, -1] >= max_neighbours)
    return index, overflow


def needed_room(position, count: int, radius: float, table_size: int) -> tuple[int, int]:
    """(max_neighbours, bucket_size) that a search of these cells needs (NumPy, on the
    host): the most cells any live cell has within `radius`, and the most cells in three
    consecutive buckets of a row, divided by three, rounded up (`find_neighbours`'s runs)."""
    xy = np.asarray(position)[: int(count)]
    if len(xy) == 0:
        return 0, 0
    side_count = int(np.floor(np.sqrt(table_size)))
    low = xy.min(axis=0)
    side = max(radius, float((xy.max(axis=0) - low).max()) / (side_count - 1))
    bucket = np.clip(np.floor((xy - low) / side).astype(np.int64), 0, side_count - 1)
    grid = np.zeros((side_count, side_count + 2), np.int64)
    np.add.at(grid, (bucket[:, 1], bucket[:, 0] + 1), 1)
    runs = grid[:, :-2] + grid[:, 1:-1] + grid[:, 2:]  # three buckets of a row around each
    from scipy.spatial import cKDTree

    pairs = cKDTree(xy).query_pairs(radius, output_type="ndarray")
    counts = np.bincount(pairs.ravel(), minlength=len(xy)) if len(pairs) else np.zeros(len(xy), np.int64)
    return int(counts.max()), int(-(-runs.max() // 3))


def _row_cumsum(flags: Array) -> Array:
    """Running count of True along each row, as a product with a triangular matrix: on a
    CPU, twice as fast as `jnp.cumsum` (a reduce-window there); exact in float32 while
    rows are shorter than 2**24."""
    width = flags.shape[1]
    triangle = jnp.triu(jnp.ones((width, width), jnp.float32))
    return jnp.round(flags.astype(jnp.float32) @ triangle).astype(jnp.int32)


def table_size_for(capacity: int) -> int:
    """Buckets: four per cell of capacity (at least 64), so a tissue at any density, and
    a sparse one spread over ~13 times its own area, keeps buckets of side `radius`."""
    return max(64, 4 * int(capacity))

"""Neighbours within the influence radius (thesis 4.2), from a hashed cell list, kept as a
Verlet list that is patched where cells were born or moved, and rebuilt only when too
many did at once.

Why not jax-md's `partition.neighbor_list`: jax-md 0.2.29 (the current release) imports
flax, e3nn-jax, optax, jraph and pymatgen on `import jax_md`, hundreds of megabytes for
one function; its list also needs a box that bounds every cell, while the thesis's
growth experiments (Figs. 6.3-6.6) grow without one.

The list keeps one rule: it holds every pair of live cells whose *reference* positions
lie within `radius` (the influence radius + the skin), both ways (j in i's row exactly
when i is in j's), and each cell is within half the skin of its own reference. Then every
pair now within the influence radius is in the list. Each iteration, the cells that broke
the rule (moved more than half the skin from their reference, or were born since) are
"movers": each takes its position as its reference, its row is recomputed by a brute
search over every live cell, and the rows of its old and new partners drop or gain it.
That costs (movers x capacity); a full build costs (capacity x 9 x bucket_size), so the list is
rebuilt only when more than `patch_sizes[-1]` cells moved at once.

The full build:
1. the live cells' bounding box is cut into at most `table_size` square buckets of side
   `radius` (wider when the cells spread too far for that, so unbounded growth needs no
   box), and the cells are sorted by bucket;
2. a cell's candidates are the cells of the 3 x 3 buckets around its own: three runs of
   three buckets, each read up to 3 x `bucket_size` cells; a candidate counts if it lies
   strictly within `radius`;
3. the neighbours are packed into `max_neighbours` slots per cell (unused slots hold the
   capacity, an index past every cell).

Running out of room (three buckets in a row holding more than 3 x `bucket_size` cells, or
a cell with more than `max_neighbours` partners) sets `overflow`: the simulator records the
iteration, so a missed neighbour is never silent; growing the room is done outside jit
(`Listing.run`, `needed_room`).

On a torus (`Torus`, a periodic domain), every offset is the shortest of its periodic
images (the minimum-image convention) and the buckets tile the torus: the run of three
buckets around a cell at a row's end goes on at the row's other end (two stretches of
`order` instead of one), and the rows above the top one are the bottom ones. Each side
holds floor(side / radius) buckets (capped by `table_size`), or one bucket when fewer
than three would fit, so that no bucket is read twice. A list carries its torus (`period`)
and serves no other domain.

A patched list holds the same pairs as a rebuilt one within the influence radius but in
other slots, and more pairs beyond it (its references are older), so the contacts' float
sums run in another order. The list is therefore part of the run's state: the cells carry
it from call to call (`Cells.neighbours`, saved in their files), and a resumed call
continues it, so that it is bit-identical to one uninterrupted call. A call
builds a list afresh only when the cells carry none, or one for another radius, skin,
capacity or `max_neighbours` (`Search.fits`).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._space import minimum_image

PATCH_SIZES = (4, 8, 16, 32, 64)  # movers a patch handles per branch; more than the last: a full build
HIT_BLOCK = 32  # columns a patch's search reads per block (`_first_hits`)


class NeighbourList(eqx.Module):
    """Per cell the indices of its partners: the cells whose reference position was within
    `radius` (influence radius + skin) of its own (a symmetric relation).

    Attributes:
        index: (capacity, max_neighbours) int32; unused slots (anywhere in a row: patches
            leave holes) hold `capacity`.
        reference: (capacity, 2) each cell's position when its row was last computed.
        built_count: the number of live cells the list covers (cells born later have no
            row yet).
        overflow: bool, a build or patch ran out of room (sticky until the next full build).
        builds: int32, full builds since the first one (patches are not counted).
        radius, skin, bucket_size, period: (static) the search that keeps it (`Search`'s);
            a call with another radius, skin or torus (`period`, (width, height), None for
            an open domain) builds its own list.
    """

    index: Array
    reference: Array
    built_count: Array
    overflow: Array
    builds: Array
    radius: float = eqx.field(static=True)
    skin: float = eqx.field(static=True)
    bucket_size: int = eqx.field(static=True)
    period: tuple[float, float] | None = eqx.field(static=True, default=None)

    @property
    def max_neighbours(self) -> int:
        return self.index.shape[-1]

    def resized(self, capacity: int) -> "NeighbourList":
        """The same list for buffers of `capacity` entries (at least the cells it covers):
        the empty slots' marker is the capacity, and the rows past the live cells are empty."""
        old, slots = self.index.shape[-2:]
        index = jnp.where(self.index >= old, capacity, self.index)[:capacity]
        reference = self.reference[:capacity]
        grow = capacity - index.shape[0]
        index = jnp.concatenate([index, jnp.full((grow, slots), capacity, index.dtype)])
        reference = jnp.concatenate([reference, jnp.zeros((grow, 2), reference.dtype)])
        return self.retagged(index=index, reference=reference)

    def retagged(self, **changes) -> "NeighbourList":
        """A copy with some fields replaced (static ones too)."""
        return dataclasses.replace(self, **changes)


class Search(eqx.Module):
    """How to search (static): the list radius (influence radius + skin), the Verlet skin,
    and the sizes of the buffers: `max_neighbours` slots per cell, `bucket_size` cells per
    bucket on average over three in a row (a full build reads 3 x `bucket_size` candidates
    from each of a cell's three rows of buckets), `table_size` buckets at most, the movers
    a patch handles, and the torus the cells live on (`period`, (width, height); None for
    an open domain)."""

    radius: float = eqx.field(static=True)
    skin: float = eqx.field(static=True)
    max_neighbours: int = eqx.field(static=True)
    bucket_size: int = eqx.field(static=True)
    table_size: int = eqx.field(static=True)
    patch_sizes: tuple[int, ...] = eqx.field(static=True, default=PATCH_SIZES)
    period: tuple[float, float] | None = eqx.field(static=True, default=None)

    def build(self, position: Array, count: Array, builds=0) -> NeighbourList:
        index, overflow = find_neighbours(position, count, self.radius, self.max_neighbours,
                                          self.bucket_size, self.table_size, self.period)
        return NeighbourList(index, position, jnp.asarray(count, jnp.int32), overflow,
                             jnp.asarray(builds, jnp.int32), self.radius, self.skin, self.bucket_size,
                             self.period)

    def fits(self, neighbours: NeighbourList | None, capacity: int) -> bool:
        """Whether a carried list can go on under this search (static): the same radius,
        skin, torus, capacity and slots per cell. (`bucket_size` and `table_size` only size a
        full build's reads: they change no list that did not overflow.)"""
        return (neighbours is not None and neighbours.radius == self.radius and neighbours.skin == self.skin
                and neighbours.period == self.period and neighbours.index.shape == (capacity, self.max_neighbours))

    def carry_on(self, neighbours: NeighbourList, position: Array, count: Array) -> NeighbourList:
        """A carried list (`fits`) as this search's, unchanged (so a resumed run goes on
        exactly as one that never stopped); built afresh only when it covers more cells
        than are live (cells were taken away: no simulation does that)."""
        carried = neighbours.retagged(bucket_size=self.bucket_size)
        return jax.lax.cond(carried.built_count <= count, lambda: carried,
                            lambda: self.build(position, count, carried.builds + 1))

    def movers(self, neighbours: NeighbourList, position: Array, count: Array) -> Array:
        """(capacity,) bool: the live cells that broke the list's rule, born since it was
        last updated or moved more than half the skin from their reference."""
        cell = jnp.arange(position.shape[0])
        moved = offsets(position - neighbours.reference, self.period)
        drift = moved[:, 0] ** 2 + moved[:, 1] ** 2  # as a row sum of two gives, without a reduction kernel
        return (cell < count) & ((cell >= neighbours.built_count) | (drift > (self.skin / 2) ** 2))

    def update(self, neighbours: NeighbourList, position: Array, count: Array) -> NeighbourList:
        """The list, keeping its rule for cells at `position` (the live ones, `count`):
        unchanged when no cell broke it, patched when a few did, rebuilt when more than
        `patch_sizes[-1]` did."""
        movers = self.movers(neighbours, position, count)
        n = jnp.sum(movers)
        sizes = self.patch_sizes
        branch = jnp.where(n == 0, 0, 1 + jnp.sum(jnp.asarray(sizes) < n))  # len(sizes) + 1: build
        keep = [lambda nb, m: nb]
        patches = [lambda nb, m, size=size: patch(nb, m, position, count, self.radius, size, self.period)
                   for size in sizes]
        rebuild = [lambda nb, m: self.build(position, count, nb.builds + 1)]
        return jax.lax.switch(branch, keep + patches + rebuild, neighbours, movers)


def offsets(offset: Array, period) -> Array:
    """(..., 2) offsets as they are (open domain), or their minimum images on a torus."""
    if period is None:
        return offset
    return jnp.stack([minimum_image(offset[..., 0], period[0]), minimum_image(offset[..., 1], period[1])], axis=-1)


def patch(neighbours: NeighbourList, movers: Array, position: Array, count: Array, radius: float,
          size: int, period=None) -> NeighbourList:
    """The list with the rows of `movers` (at most `size` of them) recomputed at their
    current positions, by a brute search over every live cell's reference, and each mover
    dropped from or added to the rows of the other cells it left or reached. The rows of
    cells that did not move change in those slots only."""
    index = neighbours.index
    capacity, slots = index.shape
    cell = jnp.arange(capacity)
    who = first_true(movers, size)                                        # (M,) movers, then capacity
    real = who < capacity
    at = jnp.minimum(who, capacity - 1)
    reference = neighbours.reference.at[who].set(position[at], mode="drop")

    # the movers' new rows: every live cell whose reference lies within `radius` of theirs;
    # the columns padded to whole blocks of `_first_hits` (no hit there), so that XLA fuses
    # the distances into its count of hits per block instead of writing a padded copy
    width = capacity + (-capacity % HIT_BLOCK)
    column = jnp.arange(width)
    xs, ys = (jnp.pad(reference[:, k], (0, width - capacity)) for k in (0, 1))
    dx = xs[None, :] - reference[at, 0][:, None]
    dy = ys[None, :] - reference[at, 1][:, None]
    if period is not None:
        dx, dy = minimum_image(dx, period[0]), minimum_image(dy, period[1])
    hit = (dx * dx + dy * dy < radius * radius) & (column[None, :] < count) & (column[None, :] != who[:, None])
    hit &= real[:, None]
    new, overflow = _first_hits(hit, slots)
    new = jnp.minimum(new, capacity)  # rows with fewer hits than slots: then the capacity

    # the partners that did not move themselves: drop the mover from the rows of those it
    # left, add it to the rows of those it reached (the movers' own rows are replaced)
    old = jnp.where(real[:, None], index[at], capacity)
    settled = (cell < capacity) & ~movers
    old_stays = settled[jnp.minimum(old, capacity - 1)] & (old < capacity)
    new_stays = settled[jnp.minimum(new, capacity - 1)] & (new < capacity)
    left = old_stays & ~jnp.any(old[:, :, None] == new[:, None, :], axis=2)
    reached = new_stays & ~jnp.any(new[:, :, None] == old[:, None, :], axis=2)
    mover = jnp.broadcast_to(who[:, None], old.shape).ravel()

    target = jnp.where(left, old, capacity).ravel()
    rows = index[jnp.minimum(target, capacity - 1)]
    holds = rows == mover[:, None]
    slot = jnp.argmax(holds, axis=1)
    index = index.at[jnp.where(jnp.any(holds, axis=1), target, capacity), slot].set(capacity, mode="drop")

    target = jnp.where(reached, new, capacity).ravel()
    rank = _rank_among_equals(target)
    rows = index[jnp.minimum(target, capacity - 1)]
    free = rows == capacity
    nth_free = _row_cumsum(free) - 1
    fits = free & (nth_free == rank[:, None])
    slot = jnp.argmax(fits, axis=1)
    placed = jnp.any(fits, axis=1)
    overflow |= jnp.any((target < capacity) & ~placed)
    index = index.at[jnp.where(placed, target, capacity), slot].set(mover.astype(jnp.int32), mode="drop")

    index = index.at[who].set(new, mode="drop")
    return neighbours.retagged(index=index, reference=reference, built_count=jnp.asarray(count, jnp.int32),
                               overflow=neighbours.overflow | overflow)


def _first_hits(hit: Array, slots: int, block: int = HIT_BLOCK) -> tuple[Array, Array]:
    """(index (rows, slots), overflow): per row of `hit` (rows, n), the columns of its
    first `slots` True entries in increasing order, then n; and whether a row had more.

    In two steps, because a row holds a few hits among thousands of columns: the first
    `slots` + 1 blocks of `block` columns that hold a hit (a partial sort, `top_k`, of
    the blocks), then the first `slots` + 1 hits among those blocks' columns (another);
    they hold the row's first `slots` + 1 hits, since each holds one at least, so the
    rows are exactly those of one partial sort of every column, and the last hit found
    says whether a row had more than `slots`. On a CPU, a partial sort costs about its
    columns: 64 rows of 6,144 columns took 0.6 ms in one sort, besides 0.25 ms to count
    the hits. Exact in float32 while n < 2**24."""
    rows, n = hit.shape
    k = slots + 1  # one hit more than the row holds: the overflow test
    if n <= 2 * k * block:  # short rows: one partial sort
        return _first_of(hit, jnp.arange(n), slots, n)
    pad = -n % block
    blocks = jnp.pad(hit, ((0, 0), (0, pad))).reshape(rows, -1, block)
    count = blocks.shape[1]
    _, chosen = _first_of(jnp.any(blocks, axis=2), jnp.arange(count), k - 1, count, keep_last=True)
    safe = jnp.minimum(chosen, count - 1)                                              # (rows, k) blocks
    within = jnp.take_along_axis(blocks, safe[:, :, None], axis=1) & (chosen < count)[:, :, None]
    column = (safe[:, :, None] * block + jnp.arange(block)).reshape(rows, -1)          # increasing in each row
    index, overflow = _first_of(within.reshape(rows, -1), column, slots, n)
    return index, overflow


def _first_of(hit: Array, column: Array, slots: int, fill: int, keep_last: bool = False):
    """(overflow, index) when `keep_last`, else (index, overflow): per row of `hit`, the
    `column`s (increasing along each row) of its first `slots` True entries, then `fill`
    (with `keep_last`, the first `slots` + 1); overflow: a row had more than `slots`."""
    n = hit.shape[1]
    k = min(slots + 1, n)
    score = jnp.where(hit, (n - jnp.arange(n)).astype(jnp.float32), 0.0)
    # rows with fewer hits: all of them, then zeros; the barrier keeps XLA from folding the
    # gather below into the sort's output, which turns its CPU TopK back into a full sort
    top, at = jax.lax.optimization_barrier(jax.lax.top_k(score, k))
    found = jnp.take_along_axis(jnp.broadcast_to(column, hit.shape), at, axis=1)
    index = jnp.where(top > 0, found, fill).astype(jnp.int32)
    width = slots + 1 if keep_last else slots
    index = jnp.pad(index, ((0, 0), (0, max(0, width - k))), constant_values=fill)[:, :width]
    overflow = jnp.any(top[:, slots] > 0) if k > slots else jnp.asarray(False)
    return (overflow, index) if keep_last else (index, overflow)


def first_true(flags: Array, size: int) -> Array:
    """The indices of the first `size` True entries of a 1D `flags`, in order, then
    len(flags) (`jnp.nonzero(flags, size=size, fill_value=len(flags))`, by `running_count`)."""
    n = flags.shape[0]
    rank = running_count(flags) - 1
    seat = jnp.where(flags & (rank < size), rank, size)
    return jnp.full(size + 1, n, jnp.int32).at[seat].set(jnp.arange(n, dtype=jnp.int32))[:size]


def running_count(flags: Array, block: int = 128) -> Array:
    """Running count of True along the last axis (an inclusive cumulative sum), for long
    rows: within blocks of `block` entries as a product with a triangular matrix, then the
    blocks' totals the same way (on a CPU, XLA's cumsum is several times slower); exact in
    float32 while rows are shorter than 2**24."""
    n = flags.shape[-1]
    if n <= block:
        return _row_cumsum(flags.reshape(-1, n)).reshape(flags.shape)
    pad = -n % block
    lead = flags.shape[:-1]
    blocks = jnp.pad(flags, [(0, 0)] * len(lead) + [(0, pad)]).reshape(*lead, -1, block).astype(jnp.float32)
    within = blocks @ jnp.triu(jnp.ones((block, block), jnp.float32))
    count = within.shape[-2]
    before = within[..., -1] @ jnp.triu(jnp.ones((count, count), jnp.float32), k=1)  # totals of earlier blocks
    total = jnp.round(within + before[..., None]).astype(jnp.int32)
    return total.reshape(*lead, n + pad)[..., :n]


def _rank_among_equals(values: Array) -> Array:
    """For each entry, how many earlier entries hold the same value."""
    order = jnp.argsort(values, stable=True)
    ordered = values[order]
    first = jnp.searchsorted(ordered, ordered, side="left", method="scan_unrolled")  # no loop to run
    rank = jnp.arange(values.shape[0]) - first
    return jnp.zeros_like(rank).at[order].set(rank)


def find_neighbours(position: Array, count: Array, radius: float, max_neighbours: int,
                    bucket_size: int, table_size: int, period=None) -> tuple[Array, Array]:
    """(index (capacity, max_neighbours), overflow) of the live cells within `radius`
    (of their minimum images on the torus `period`, when given)."""
    if period is not None:
        return _find_on_torus(position, count, radius, max_neighbours, bucket_size, table_size, period)
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
    index, full = _pack(valid, candidate, max_neighbours)
    return index, crowded | full


def torus_buckets(period, radius: float, table_size: int) -> tuple[int, int]:
    """(columns, rows) of buckets tiling the torus `period`: floor(side / radius) per side,
    so each bucket's sides are at least `radius`; at most floor(sqrt(table_size)); one
    where fewer than three would fit (three or more buckets a side: a cell's 3 x 3
    buckets are distinct, each read once)."""
    most = int(np.floor(np.sqrt(table_size)))
    counts = []
    for length in period:
        n = min(int(np.floor(length / radius)), most)
        while n > 1 and length / n < radius:  # float rounding: never a side below radius
            n -= 1
        counts.append(n if n >= 3 else 1)
    return counts[0], counts[1]


def _find_on_torus(position: Array, count: Array, radius: float, max_neighbours: int, bucket_size: int,
                   table_size: int, period) -> tuple[Array, Array]:
    """`find_neighbours` on a torus: buckets that tile it, runs that wrap at a row's ends,
    minimum-image distances."""
    capacity = position.shape[0]
    alive = jnp.arange(capacity) < count
    nx, ny = torus_buckets(period, radius, table_size)
    buckets = nx * ny
    size = jnp.asarray(period, position.dtype)
    cell_side = size / jnp.asarray([nx, ny], position.dtype)
    bucket = jnp.floor((position + size / 2) / cell_side).astype(jnp.int32) % jnp.asarray([nx, ny])
    slot = jnp.where(alive, bucket[:, 0] + nx * bucket[:, 1], buckets)
    order = jnp.argsort(slot)
    starts = jnp.concatenate([jnp.zeros(1, jnp.int32),
                              jnp.cumsum(jnp.zeros(buckets + 1, jnp.int32).at[slot].add(1))])

    # per row of buckets around a cell (three rows, or the one when a side holds one
    # bucket), its columns c-1, c, c+1 (mod nx) are stretch A, the columns inside the row,
    # and stretch B, the column past the row's end (c = 0: column nx-1; c = nx-1: column
    # 0); a row reads up to `run` cells from A, then B
    run = 3 * bucket_size
    shifts = jnp.arange(-1, 2) if ny >= 3 else jnp.zeros(1, jnp.int32)
    row = (bucket[:, 1:2] + shifts[None, :]) % ny                       # (C, R)
    column = bucket[:, 0:1]
    first_a = starts[jnp.maximum(column - 1, 0) + nx * row]
    end_a = starts[jnp.minimum(column + 1, nx - 1) + nx * row + 1]
    wraps = (nx >= 3) & ((column == 0) | (column == nx - 1))
    column_b = jnp.where(column == 0, nx - 1, 0)
    first_b = starts[column_b + nx * row]
    end_b = jnp.where(wraps, starts[column_b + nx * row + 1], first_b)
    length_a, length = end_a - first_a, (end_a - first_a) + (end_b - first_b)
    crowded = jnp.any(alive[:, None] & (length > run))
    k = jnp.arange(run)
    seat = jnp.where(k < length_a[..., None], first_a[..., None] + k, first_b[..., None] + k - length_a[..., None])
    inside = (k < length[..., None]).reshape(capacity, -1)
    candidate = jnp.take(order, seat.reshape(capacity, -1), mode="clip")
    dx = minimum_image(jnp.take(position[:, 0], candidate, mode="clip") - position[:, 0:1], period[0])
    dy = minimum_image(jnp.take(position[:, 1], candidate, mode="clip") - position[:, 1:2], period[1])
    near = dx * dx + dy * dy < radius * radius
    me = jnp.arange(capacity)[:, None]
    valid = inside & near & (candidate != me) & alive[:, None]
    index, full = _pack(valid, candidate, max_neighbours)
    return index, crowded | full


def _pack(valid: Array, candidate: Array, max_neighbours: int) -> tuple[Array, Array]:
    """(index, full): each row's valid candidates packed into `max_neighbours` slots
    (the rest hold the capacity), and whether a row had more."""
    # one flat scatter: the fastest compaction on a CPU, well ahead of a per-row sort or top_k
    capacity = valid.shape[0]
    rank = _row_cumsum(valid) - 1
    column = jnp.where(valid & (rank < max_neighbours), rank, max_neighbours)
    flat = (jnp.arange(capacity)[:, None] * (max_neighbours + 1) + column).ravel()
    index = jnp.full(capacity * (max_neighbours + 1), capacity, jnp.int32)
    index = index.at[flat].set(candidate.astype(jnp.int32).ravel(), mode="promise_in_bounds")
    index = index.reshape(capacity, max_neighbours + 1)[:, :max_neighbours]
    return index, jnp.any(rank[:, -1] >= max_neighbours)


def needed_room(position, count: int, radius: float, table_size: int, period=None) -> tuple[int, int]:
    """(max_neighbours, bucket_size) that a search of these cells needs (NumPy, on the
    host): the most cells any live cell has within `radius` (minimum images on the torus
    `period`), and the most cells in three consecutive buckets of a row, divided by three,
    rounded up (`find_neighbours`'s runs)."""
    xy = np.asarray(position)[: int(count)]
    if len(xy) == 0:
        return 0, 0
    if period is not None:
        return _needed_room_on_torus(xy.astype(np.float64), radius, table_size, period)
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


def _needed_room_on_torus(xy: np.ndarray, radius: float, table_size: int, period) -> tuple[int, int]:
    """`needed_room` on a torus: its buckets (`torus_buckets`), runs wrapping at a row's end."""
    from scipy.spatial import cKDTree

    size = np.asarray(period, np.float64)
    nx, ny = torus_buckets(period, radius, table_size)
    shifted = np.mod(xy + size / 2, size)
    shifted = np.where(shifted >= size, 0.0, shifted)  # np.mod can round up to the period
    bucket = np.floor(shifted / (size / [nx, ny])).astype(np.int64) % [nx, ny]
    grid = np.zeros((ny, nx), np.int64)
    np.add.at(grid, (bucket[:, 1], bucket[:, 0]), 1)
    runs = grid + np.roll(grid, 1, axis=1) + np.roll(grid, -1, axis=1) if nx >= 3 else grid
    pairs = cKDTree(shifted, boxsize=size).query_pairs(radius, output_type="ndarray")
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

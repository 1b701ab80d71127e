"""Execution plans for growing lattices: which block of the lattice each stretch computes on.

A growing run's active region starts small and fills its capacity. Computing every step
on the whole capacity is correct but wastes the cells not yet grown; the plans here make a
growing run cost about what its current size costs, still in one compiled program:

- `BlockLadder` (the default): a few block sizes (a ladder, placed to minimise the cells
  computed); each stretch of steps computes on the smallest block that holds the active
  region at the stretch's end. When the sizes are known in advance (concrete rates and
  states), the run is laid out as segments (steps without growth, then one expansion), so
  the per-step growth test leaves the stepping loop.
- `WholeCapacity`: the reference; every step computes on the whole capacity and tests
  growth inside the step.

Both give identical results (every random number depends on the run's key and step only);
the loop (`_loop`) is given a plan and asks it for blocks.
"""

from __future__ import annotations

import bisect
import dataclasses
import itertools
import math
from typing import Callable

import jax

from ._checks import is_concrete
from ._growth import steps_done


@dataclasses.dataclass(frozen=True)
class BlockLadder:
    """The default plan: a ladder of block sizes, each stretch on the smallest that fits.

    Args:
        ratio: each block about `ratio` times the rows of the one before (sets how many
            compiled step bodies a run has).
        multiple: block rows are multiples of this (whole vectors along a row).
        small_lattice: at or below this capacity (cells) a run uses a single block: one
            compiled step, since compiling more costs more than the cells it saves.
    """

    ratio: float = 1.25
    multiple: int = 8
    small_lattice: int = 160 * 160

    def _ratio(self, state) -> float:
        """Small lattices: one block, one compiled step (compiling more costs more than it saves)."""
        return float("inf") if state.capacity[0] * state.capacity[1] <= self.small_lattice else self.ratio

    def chunk_blocks(self, state, growth, steps: int, dt, origin, per: int, rungs=None):
        """Blocks for a run on a dynamic active region, and which one each chunk uses.

        A chunk of `per` steps computes on the top-left block of the lattice that holds the
        active region as it will be at the chunk's end (expansions are on a fixed schedule),
        chosen from a ladder of block sizes (multiples of 8, as many as a ladder growing by
        `ratio` has, placed by `placed_ladder` to minimise the cells computed). A growing run
        then costs about what its current size costs, still in one compiled program. Returns
        (blocks, schedule) or (None, None) when sizes are not known in advance (traced states
        or growth rates, e.g. inside vmap over growth rates): the whole capacity is used then.
        """
        if not is_concrete(state.size, state.step, origin) or (growth is not None and not is_concrete(growth.rate, dt)):
            return None, None
        ratio = self._ratio(state)
        with jax.ensure_compile_time_eval():
            h, w = state.shape
            done = steps_done(state, origin)
            cap_r = state.capacity[0]
            ends = [min((j + 1) * per, steps) for j in range(-(-steps // per))] if steps else []
            need = [min(h + (growth.expansions(e, dt, done) if growth is not None else 0), cap_r) for e in ends]
        if not need:
            return None, None
        steps_per = [min((j + 1) * per, steps) - j * per for j in range(len(need))]
        ladder, blocks = blocks_for(need, steps_per, (h, w), state.capacity, ratio, self.multiple, rungs)
        schedule = tuple(next(i for i, b in enumerate(ladder) if b >= n) for n in need)
        return blocks, schedule

    def segments(self, state, growth, steps: int, dt, origin, check: int = 128, rungs=None):
        """A growing run as segments: `n` steps without growth, then one expansion.

        Expansions fall on a fixed schedule (phase steps 1, 1 + p, 1 + 2p, ...), so an eager
        run can be laid out in advance: each block of the size ladder (see `chunk_blocks`)
        runs a scan over identical segments, and the per-step growth test disappears from the
        stepping loop. Returns (blocks, groups) with groups of (block, steps, expand, repeat),
        expand being True, False or "overflow" (due but the capacity is full), or (None, None)
        when the sizes are not concrete.
        """
        if growth is None or not is_concrete(state.size, state.step, origin, growth.rate, dt) or not steps:
            return None, None
        ratio = self._ratio(state)
        with jax.ensure_compile_time_eval():
            period = growth.period_steps(dt)
            done = steps_done(state, origin)
            h, w = state.shape
        cap_r, cap_c = state.capacity
        segments, t = [], 0
        while t < steps:
            nxt = t + 1 + ((period - (done + t) % period) % period) if period > 0 else steps + 1
            n, expand = (nxt - t, True) if nxt <= steps else (steps - t, False)
            t += n
            while n > 4 * check:  # long stretches: check for blow-ups every `check` steps
                segments.append((check, False))
                n -= check
            segments.append((n, expand))
        sizes, grown, kinds = [], (h, w), []
        for n, expand in segments:
            fits = grown[0] < cap_r and grown[1] < cap_c
            kinds.append(("overflow" if not fits else True) if expand else False)
            grown = (grown[0] + 1, grown[1] + 1) if expand and fits else grown
            sizes.append(grown[0])
        ladder, blocks = blocks_for(sizes, [n for n, _ in segments], (h, w), state.capacity, ratio, self.multiple, rungs)
        groups = []
        for (n, _), expand, need in zip(segments, kinds, sizes):
            b = next(i for i, r in enumerate(ladder) if r >= need)
            if groups and groups[-1][:3] == (b, n, expand):
                groups[-1] = (b, n, expand, groups[-1][3] + 1)
            else:
                groups.append((b, n, expand, 1))
        return blocks, tuple(groups)


@dataclasses.dataclass(frozen=True)
class WholeCapacity:
    """The reference plan: every step on the whole capacity, growth tested in each step."""

    def chunk_blocks(self, state, growth, steps: int, dt, origin, per: int, rungs=None):
        return None, None

    def segments(self, state, growth, steps: int, dt, origin, check: int = 128, rungs=None):
        return None, None


def geometric_ladder(first: int, last: int, cap: int, ratio: float, multiple: int) -> list[int]:
    """Block rows from `first` to `last`, each about `ratio` times the previous, rounded up
    to a multiple of `multiple` and capped at `cap` (one block when ratio is infinite)."""
    ladder, r = [], first
    while True:
        r = min(-(-r // multiple) * multiple, cap)
        ladder.append(r)
        if r >= last:
            return ladder
        r = max(r + 1, int(r * ratio)) if math.isfinite(ratio) else last


def placed_ladder(rows: list[int], weights: list[int], cap: int, ratio: float, multiple: int,
                   area: Callable[[int], int]) -> list[int]:
    """As many block sizes as `geometric_ladder` gives (the number of compiled step bodies), placed
    to minimise the work: sum over chunks of weight x area(block) for the smallest block
    that holds each chunk's `rows` (dynamic programming over the candidate sizes).

    For the leopard's development phase (130 -> 370 rows, linear growth) six blocks then
    compute 15% more cells than the active regions instead of 21% for the geometric ladder.
    """
    geometric = geometric_ladder(min(rows), max(rows), cap, ratio, multiple)
    k = len(geometric)
    cands = sorted({min(-(-r // multiple) * multiple, cap) for r in range(min(rows), max(rows) + 1)})
    if k <= 1 or len(cands) <= k:
        return geometric if len(cands) > k else cands
    load = [0] * len(cands)  # load[j]: total weight of the chunks needing at most cands[j] rows
    for r, wt in zip(rows, weights):
        load[bisect.bisect_left(cands, r)] += wt
    load = list(itertools.accumulate(load))

    def seg(i, j):  # chunks in (cands[i], cands[j]] computed on block cands[j]
        return (load[j] - (load[i] if i >= 0 else 0)) * area(cands[j])

    n = len(cands)
    best = [[math.inf] * n for _ in range(k + 1)]
    back = [[-1] * n for _ in range(k + 1)]
    for j in range(n):
        best[1][j] = seg(-1, j)
    for m in range(2, k + 1):
        for j in range(1, n):
            for i in range(j):
                v = best[m - 1][i] + seg(i, j)
                if v < best[m][j]:
                    best[m][j], back[m][j] = v, i
    m = min(range(1, k + 1), key=lambda m: best[m][n - 1])
    out, j = [], n - 1
    while j >= 0 and m >= 1:
        out.append(cands[j])
        j, m = back[m][j], m - 1
    return sorted(out)


def blocks_for(rows, weights, shape, capacity, ratio, multiple, rungs):
    """(block rows, blocks as (rows, cols)) for a run whose chunks need `rows` rows with
    `weights` steps each, starting from the active `shape`: placed by `placed_ladder`, or,
    given the `rungs` of a whole run split into progress pieces, the one rung that holds
    every size of this piece (pieces on the same rung then share one compiled program).
    Columns grow with the rows (one expansion adds one of each)."""
    (h, w), (cap_r, cap_c) = shape, capacity
    cols = lambda r: min(r - h + w, cap_c)
    if rungs is None:
        ladder = placed_ladder(rows, weights, cap_r, ratio, multiple, lambda r: r * cols(r))
    else:
        ladder = [next(r for r in rungs if r >= max(rows))]
    return ladder, tuple((r, cols(r)) for r in ladder)

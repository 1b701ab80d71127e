"""Wireworld (Silverman's four-state automaton), thesis Fig. 7.2 and Listing A.12.

States as in Listing A.12: 0 empty, 1 electron head, 2 electron tail, 3 conductor. One
synchronous generation on the periodic lattice: empty stays empty, head -> tail, tail ->
conductor, and a conductor becomes a head when 1 or 2 of its Moore neighbours (the 3^d - 1
cells around it; 8 in 2D) are heads, otherwise it stays a conductor.

The thesis emulates the rule with three reagents and a three-iteration cycle (reagent C
counts 0, 1, 2; N diffuses at 0.01 so that a conductor sees 0.01 per neighbouring head):
one Wireworld generation is three of its iterations, so its 72 iterations are 24
generations. `wireworld_clock()` builds the listing's 15 x 15 prepattern.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jax import Array

from ._base import AbstractAutomaton
from ._loop import Codec, identity_codec

EMPTY, HEAD, TAIL, CONDUCTOR = 0, 1, 2, 3
# Listing A.12's colour map (Golly's): empty, head, tail, conductor
WIREWORLD_COLOURS = ("#303030", "#0080ff", "#ffffff", "#ff8000")


class Wireworld(AbstractAutomaton):
    """Wireworld on a periodic integer lattice of any dimension (thesis Fig. 7.2).

    `step(cells)` and `run(cells, steps, ...)` behave as for `LifeLike`; cells hold states
    0 (empty), 1 (electron head), 2 (electron tail), 3 (conductor).
    """

    @property
    def n_states(self) -> int:
        return 4

    def _plan(self, shape):
        if min(shape) < 3:
            raise ValueError(f"Wireworld cells: every side of the periodic lattice must be at least 3 "
                             f"(got shape {tuple(shape)})")
        return None

    def _codec(self, plan, shape, dtype) -> Codec:
        return identity_codec(dtype)

    def _precomputed(self, plan, shape):
        return None  # the rule needs no arrays

    def heads(self, cells) -> Array:
        """Electron heads among the Moore neighbours of every cell (periodic), exact integers."""
        cells = jnp.asarray(cells)
        x = (cells == HEAD).astype(jnp.int8 if cells.ndim <= 2 else jnp.int16)
        total = x
        for axis in range(x.ndim):  # separable 3 x 3 x ... box sum, self included
            total = jnp.roll(total, 1, axis) + total + jnp.roll(total, -1, axis)
        return total - x

    def _stepper(self, plan, shape, pre=None):
        def step(cells):
            n = self.heads(cells)
            fires = (cells == CONDUCTOR) & ((n == 1) | (n == 2))
            # head -> tail (1 -> 2), tail -> conductor (2 -> 3), conductor -> head when fired
            new = jnp.where((cells == HEAD) | (cells == TAIL), cells + 1, cells)
            return jnp.where(fires, HEAD, new).astype(cells.dtype)

        return step


def wireworld_clock(dtype=jnp.int8) -> Array:
    """Listing A.12's 15 x 15 prepattern: a ring of 12 conductor cells carrying one electron
    (head at cell 18, tail at 17) and a wire from the ring to column 13, a clock that
    sends an electron down the wire every 12 generations.

    The listing numbers cells row by row (cell i at row i // 15, column i % 15); its grid
    does not wrap, and nothing reaches the lattice's edge, so the periodic lattice runs it
    unchanged.
    """
    cells = np.zeros(15 * 15, np.int8)
    conductors = [*range(77, 80), 61, 65, 46, *range(50, 59), 31, 35, 19]
    cells[conductors] = CONDUCTOR
    cells[17], cells[18] = TAIL, HEAD
    return jnp.asarray(cells.reshape(15, 15), dtype)

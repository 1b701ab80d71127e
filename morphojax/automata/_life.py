"""Life-like (outer-totalistic) cellular automata in B/S notation, any dimension.

A cell is dead (0) or alive (1). Its neighbours are the 3^d - 1 cells of its Moore
neighbourhood on the periodic lattice; a dead cell is born when its number of live
neighbours is in the birth set B, a live cell survives when it is in the survival set S.
Conway's Game of Life is "B3/S23"; the notation also accepts "b3s23", "B3S23" and the
older "S/B" form "23/3".
"""

from __future__ import annotations

import re

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._base import AbstractAutomaton
from ._loop import Codec, identity_codec

RULES = {
    "life": "B3/S23",
    "highlife": "B36/S23",
    "seeds": "B2/S",
    "day-and-night": "B3678/S34678",
    "maze": "B3/S12345",
    "replicator": "B1357/S1357",
    "diamoeba": "B35678/S5678",
    "2x2": "B36/S125",
}


def parse_rule(rule: str) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """(birth, survive) neighbour counts from B/S notation or a name in `RULES`."""
    text = RULES.get(rule.lower(), rule) if isinstance(rule, str) else rule
    if not isinstance(text, str):
        raise ValueError(f"LifeLike.rule must be a string such as 'B3/S23' (got {rule!r})")
    compact = text.replace(" ", "").upper()
    m = re.fullmatch(r"B(\d*)/?S(\d*)", compact)
    if m:
        born, survive = m.group(1), m.group(2)
    else:
        m = re.fullmatch(r"(\d*)/(\d*)", compact)  # the older S/B form
        if not m:
            raise ValueError(
                f"LifeLike.rule must be in B/S notation such as 'B3/S23' or a name in {sorted(RULES)} (got {rule!r})"
            )
        survive, born = m.group(1), m.group(2)
    return tuple(sorted({int(c) for c in born})), tuple(sorted({int(c) for c in survive}))


class LifeLike(AbstractAutomaton):
    """A life-like rule, e.g. `LifeLike("B3/S23")` (Conway), on 0/1 integer lattices.

    Each digit of the notation is one neighbour count, so in 2D all counts 0..8 can be
    named (in 3D, with 26 neighbours, only 0..9 can).
    `step(cells)` and `run(cells, steps, ...)` behave as for `YoungCA`.
    """

    birth: tuple[int, ...] = eqx.field(static=True)
    survive: tuple[int, ...] = eqx.field(static=True)

    def __init__(self, rule: str = "B3/S23"):
        self.birth, self.survive = parse_rule(rule)

    @property
    def rule(self) -> str:
        return "B" + "".join(map(str, self.birth)) + "/S" + "".join(map(str, self.survive))

    @property
    def n_states(self) -> int:
        return 2

    def _plan(self, shape):
        if min(shape) < 3:
            raise ValueError(f"LifeLike cells: every side of the periodic lattice must be at least 3 (got shape {tuple(shape)})")
        most = 3 ** len(shape) - 1
        named = self.birth + self.survive
        if named and max(named) > most:
            raise ValueError(
                f"LifeLike.rule {self.rule}: neighbour counts must lie in [0, {most}] on a {len(shape)}D lattice "
                f"(got {max(named)})"
            )
        return None

    def _codec(self, plan, shape, dtype) -> Codec:
        return identity_codec(dtype)

    def _precomputed(self, plan, shape):
        return None  # the step needs no arrays beyond the rule's tables

    def neighbours(self, cells) -> Array:
        """Live Moore neighbours of every cell (periodic), exact integers."""
        cells = jnp.asarray(cells)
        x = cells.astype(jnp.int8 if cells.ndim <= 2 else jnp.int16)
        total = x
        for axis in range(x.ndim):  # separable 3 x 3 x ... box sum, self included
            total = jnp.roll(total, 1, axis) + total + jnp.roll(total, -1, axis)
        return total - x

    def _stepper(self, plan, shape, pre=None):
        n_max = 3 ** len(shape)
        born = jnp.asarray(np.isin(np.arange(n_max), self.birth))
        keep = jnp.asarray(np.isin(np.arange(n_max), self.survive))

        def step(cells):
            n = self.neighbours(cells).astype(jnp.int32)
            alive = jnp.where(cells == 1, keep[n], born[n])
            return alive.astype(cells.dtype)

        return step


def glider(shape=(16, 16), at=(1, 1), dtype=jnp.int8) -> Array:
    """A lattice with one Conway glider (moving +1 row and +1 column every 4 generations)."""
    cells = np.zeros(shape, np.int8)
    r, c = at
    for dr, dc in ((0, 1), (1, 2), (2, 0), (2, 1), (2, 2)):
        cells[(r + dr) % shape[0], (c + dc) % shape[1]] = 1
    return jnp.asarray(cells, dtype)

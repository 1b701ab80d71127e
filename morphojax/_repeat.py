"""`n` applications of a step in one compiled loop, with the same bits whatever `n`.

XLA inlines a loop of one trip and fuses its body with the code around it, which can round
differently from the same step inside a loop (by an ulp: seen with ETDRK steps on a lattice,
and in the positions and concentrations of cells). So one step runs as a loop of two trips
whose second does nothing, and a run cut into pieces of any length, one included (a
progress bar over few steps, resumed calls), gives the bits of one call.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def repeat(step, carry, n: int):
    """`step` applied `n` times (a Python int) to `carry` under `lax.scan`."""
    if n == 0:
        return carry
    if n == 1:
        skip = lambda c: c  # noqa: E731
        return jax.lax.scan(lambda c, i: (jax.lax.cond(i == 0, step, skip, c), None), carry, jnp.arange(2))[0]
    return jax.lax.scan(lambda c, _: (step(c), None), carry, None, length=n)[0]

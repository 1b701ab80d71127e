"""How the saturation limits are enforced: a clamp after every step, or a smooth barrier.

"clip" clamps every species to [lower, upper] after each forward-Euler step (the leopard
paper's method); `Barrier(k)` adds rational terms to the reaction instead (section 5.4).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp


@dataclasses.dataclass(frozen=True)
class Barrier:
    """Smooth bounds instead of clipping (leopard paper section 5.4).

    Adds 1 / (x^k - L^k) for a finite lower limit L >= 0 and -1 / (U^k - x^k) + 1 / U^k
    for a finite upper limit U to each species' reaction, so concentrations stay inside
    (L, U) without a clamp. The paper finds k = 2 gives patterns like clipping, with a
    time step about 20x smaller for stability. The initial state must lie strictly inside.
    """

    k: int = 2

    def terms(self, x, lower, upper):
        """The barrier rates added to the reaction for concentrations `x` and limits `lower`, `upper`."""
        k = self.k
        lo_ok = jnp.isfinite(lower)
        hi_ok = jnp.isfinite(upper)
        lo = jnp.where(lo_ok, lower, 0.0)
        hi = jnp.where(hi_ok, upper, 1.0)
        push_up = jnp.where(lo_ok, 1.0 / (x**k - lo**k), 0.0)
        push_down = jnp.where(hi_ok, -1.0 / (hi**k - x**k) + 1.0 / hi**k, 0.0)
        return push_up + push_down


def bounds_policy(bounds):
    if isinstance(bounds, Barrier):
        return bounds
    if bounds == "clip":
        return "clip"
    if bounds == "barrier":
        return Barrier()
    raise ValueError(f"unknown bounds {bounds!r}; allowed: 'clip', 'barrier' or Barrier(k=...)")

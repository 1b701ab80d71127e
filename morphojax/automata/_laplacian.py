"""Laplacian growth by the dielectric breakdown model as the thesis approximates it
(Fig. 7.3, Listing A.13): a two-state aggregate P coupled to a diffusing field G.

Listing A.13 runs its rules on three reagents of a 100 x 100 square grid (no wrap): P
(limit 1, diff 0.01) marks the aggregate, G (start 0.1, diff 0.1) is the probability
field, C (diff 0) a clock alternating 0, 1. `LaplacianGrowth.run` carries out that
listing iteration by iteration: each iteration every rule reads the current state, their
changes and the diffusion are added, and P is clamped to [0, 1] and G to [0, inf)
(thesis section 4.7), with

- C: +1 where C = 0, -1 where C = 1 (a period-2 clock);
- where C = 1: P - 1, and P + 2 where P > 0.9 (the aggregate stays), and P + 2 with
  probability G where window_low <= P <= window_high (an empty cell becomes part of the
  aggregate: after the diffusion of the previous iteration an empty cell holds
  0.01 x its number of aggregate neighbours, so the listing's window [0.03, 0.04] admits
  cells with 3 or 4 of them);
- where P = 0: G + g_gain; where P = 1: G - g_loss (the aggregate consumes the field,
  empty cells replenish it, so G is high far from the aggregate).

Diffusion is the thesis's sum over the neighbours, D sum_j (u_j - u) (section 4.3), and
the grid does not wrap: a cell at the edge has only the neighbours inside the grid (the
space outside does not diffuse). The random draws of iteration n come from
fold_in(key, n): same key, same aggregate.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._checks import as_float_array, check_count, check_finite, check_range


def moore_sum_open(u: Array) -> Array:
    """sum_j (u_j - u) over the Moore neighbours inside the grid (no neighbours beyond the
    edge), for the last two axes of `u`."""
    p = jnp.pad(u, [(0, 0)] * (u.ndim - 2) + [(1, 1), (1, 1)])
    inside = jnp.pad(jnp.ones(u.shape[-2:], u.dtype), 1)
    rows, cols = u.shape[-2:]
    total, count = jnp.zeros_like(u), jnp.zeros(u.shape[-2:], u.dtype)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr or dc:
                total = total + p[..., 1 + dr:1 + dr + rows, 1 + dc:1 + dc + cols]
                count = count + inside[1 + dr:1 + dr + rows, 1 + dc:1 + dc + cols]
    return total - count * u


class LaplacianRun(eqx.Module):
    """What `LaplacianGrowth.run` returns: the aggregate P (1 in the aggregate, 0 outside,
    after an even number of iterations), the field G, the clock C, and with `save_every`
    the P and G of every that many iterations (frame 0 the start)."""

    p: Array
    g: Array
    c: Array
    iterations: int = eqx.field(static=True)
    p_frames: Array | None = None
    g_frames: Array | None = None

    @property
    def aggregate(self) -> Array:
        """The aggregate as a boolean (rows, cols) mask (P > 0.9, the listing's test)."""
        return self.p > 0.9


class LaplacianGrowth(eqx.Module):
    """Thesis Listing A.13 (Fig. 7.3): diffusion-limited growth of an aggregate driven by a
    diffusing probability field. Defaults are the listing's.

    Args (all array leaves):
        p_diffusion: P's rate per neighbour per iteration (0.01).
        g_diffusion: G's rate per neighbour per iteration (0.1; at most 0.25 keeps the
            eight-neighbour sum stable).
        g_start: G's initial concentration (0.1).
        g_gain / g_loss: G's change per iteration in empty cells / aggregate cells.
        window_low / window_high: the listing's `P conc in 0.03 0.04`.
    """

    p_diffusion: Array
    g_diffusion: Array
    g_start: Array
    g_gain: Array
    g_loss: Array
    window_low: Array
    window_high: Array

    def __init__(self, p_diffusion=0.01, g_diffusion=0.1, g_start=0.1, g_gain=0.0001, g_loss=0.01,
                 window_low=0.03, window_high=0.04):
        name = type(self).__name__
        self.p_diffusion = as_float_array(p_diffusion, f"{name}.p_diffusion")
        self.g_diffusion = as_float_array(g_diffusion, f"{name}.g_diffusion")
        self.g_start = as_float_array(g_start, f"{name}.g_start")
        self.g_gain = as_float_array(g_gain, f"{name}.g_gain")
        self.g_loss = as_float_array(g_loss, f"{name}.g_loss")
        self.window_low = as_float_array(window_low, f"{name}.window_low")
        self.window_high = as_float_array(window_high, f"{name}.window_high")

    def __check_init__(self):
        name = type(self).__name__
        for field in ("p_diffusion", "g_diffusion"):  # the eight-neighbour sum's explicit limit, 12 D <= 2
            check_finite(getattr(self, field), f"{name}.{field}")
            check_range(getattr(self, field), f"{name}.{field} (rate per neighbour per iteration)", low=0.0,
                        high=1.0 / 6.0)
        for field in ("g_start", "g_gain", "g_loss", "window_low", "window_high"):
            check_finite(getattr(self, field), f"{name}.{field}")
            check_range(getattr(self, field), f"{name}.{field}", low=0.0)

    def initial(self, shape=(100, 100), seeds=((49, 49), (49, 50), (49, 51))):
        """The listing's start: P = 1 at the `seeds` cells (its cells 4949-4951, row by row
        on 100 x 100), 0 elsewhere; G = g_start; C = 0."""
        if len(shape) != 2 or min(shape) < 3:
            raise ValueError(f"LaplacianGrowth shape must be (rows, cols), each at least 3 (got {tuple(shape)})")
        p = np.zeros(shape, np.float32)
        for r, c in seeds:
            if not (0 <= r < shape[0] and 0 <= c < shape[1]):
                raise ValueError(f"LaplacianGrowth seeds must lie inside the grid {tuple(shape)} (got {(r, c)})")
            p[r, c] = 1.0
        dtype = jnp.result_type(float)
        return jnp.asarray(p, dtype), jnp.full(shape, self.g_start, dtype), jnp.zeros(shape, dtype)

    def iterate(self, p, g, c, u):
        """One iteration of the listing from (P, G, C) with the uniform draws `u`."""
        odd = c == 1
        dp = jnp.where(odd, -1.0, 0.0)
        window = (p >= self.window_low) & (p <= self.window_high)
        dp = dp + jnp.where(odd & (u < g) & window, 2.0, 0.0) + jnp.where(odd & (p > 0.9), 2.0, 0.0)
        dg = jnp.where(p == 0.0, self.g_gain, 0.0) - jnp.where(p == 1.0, self.g_loss, 0.0)
        dc = jnp.where(c == 0, 1.0, 0.0) - jnp.where(odd, 1.0, 0.0)
        p_new = jnp.clip(p + dp + self.p_diffusion * moore_sum_open(p), 0.0, 1.0)
        g_new = jnp.maximum(g + dg + self.g_diffusion * moore_sum_open(g), 0.0)
        return p_new, g_new, c + dc

    def run(self, key, iterations: int = 3200, shape=(100, 100), seeds=((49, 49), (49, 50), (49, 51)),
            save_every: int | None = None) -> LaplacianRun:
        """`iterations` of the listing (3,200: its `stop at`) from `initial(shape, seeds)`;
        one growth round takes two iterations. `save_every`: keep P and G every that
        many iterations."""
        check_count(iterations, "LaplacianGrowth.run iterations", "iterations")
        if save_every is not None:
            check_count(save_every, "LaplacianGrowth.run save_every", "iterations", low=1)
        p, g, c = self.initial(tuple(shape), tuple(tuple(s) for s in seeds))
        out = _run(self, key, p, g, c, iterations=int(iterations), save_every=save_every and int(save_every))
        (p, g, c), frames = out
        return LaplacianRun(p, g, c, int(iterations), *(frames if frames is not None else (None, None)))


@functools.partial(jax.jit, static_argnames=("iterations", "save_every"))
def _run(model, key, p, g, c, *, iterations, save_every):
    def body(carry, n):
        p, g, c = carry
        u = jax.random.uniform(jax.random.fold_in(key, n), p.shape, p.dtype)
        return model.iterate(p, g, c, u), None

    if not save_every:
        carry, _ = jax.lax.scan(body, (p, g, c), jnp.arange(iterations))
        return carry, None
    n_frames, rest = divmod(iterations, save_every)

    def chunk(carry, start):
        carry, _ = jax.lax.scan(body, carry, start + jnp.arange(save_every))
        return carry, (carry[0], carry[1])

    carry, (pf, gf) = jax.lax.scan(chunk, (p, g, c), save_every * jnp.arange(n_frames))
    carry, _ = jax.lax.scan(body, carry, n_frames * save_every + jnp.arange(rest))
    return carry, (jnp.concatenate([p[None], pf]), jnp.concatenate([g[None], gf]))

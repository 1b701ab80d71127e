"""Neighbourhood geometry of Young's automaton on a periodic lattice.

A neighbourhood of radius r is a disc (Euclidean: offsets at squared distance
d2 <= r^2 (1 + SLACK)), a box (Chebyshev, Moore's square: max|dx_i| <= r (1 + SLACK)) or a
diamond (Manhattan, von Neumann's: sum|dx_i| <= r (1 + SLACK)); the slack lets a radius
typed as 3 or 1.4142135 include the shell at exactly that distance. Radii are reduced to
integer thresholds on the squared (disc), Chebyshev (box) or Manhattan (diamond) distance.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

NEIGHBOURHOODS = ("disc", "box", "diamond")
SLACK = 1e-6  # relative slack on the radii, see the module docstring


def threshold(r, neighbourhood: str):
    """Largest squared distance (disc), or Chebyshev (box) or Manhattan (diamond) distance,
    inside radius r; works on NumPy and on (traced) JAX values in the array's own precision."""
    xp = jnp if isinstance(r, jax.Array) else np
    one = r.dtype.type(1.0 + SLACK) if hasattr(r, "dtype") else 1.0 + SLACK
    return xp.floor(r * r * one) if neighbourhood == "disc" else xp.floor(r * one)


def half_width(res: int, neighbourhood: str) -> int:
    """The largest offset along one axis within threshold `res`."""
    return math.isqrt(res) if neighbourhood == "disc" else res


def cross_section(res: int, offset: int, neighbourhood: str) -> int:
    """The threshold of the (one dimension lower) cross-section of the ball of threshold
    `res` at `offset` along one axis: what remains of the distance budget."""
    if neighbourhood == "disc":
        return res - offset * offset
    return res - abs(offset) if neighbourhood == "diamond" else res


def lattice_distance(shape, neighbourhood: str) -> np.ndarray:
    """Minimal-image squared distance (disc), Chebyshev distance (box) or Manhattan distance
    (diamond) of every lattice offset from the origin, as a float32 array of the lattice shape."""
    grids = np.meshgrid(*[np.minimum(np.arange(n), n - np.arange(n)) for n in shape], indexing="ij")
    if neighbourhood == "disc":
        dist = sum(g.astype(np.int64) ** 2 for g in grids)
    elif neighbourhood == "diamond":
        dist = sum(g.astype(np.int64) for g in grids)
    else:
        dist = np.max(np.stack(grids), axis=0)
    return dist.astype(np.float32)


def ball_size(res: int, dim: int, neighbourhood: str) -> int:
    """Number of lattice offsets (origin included) within threshold `res` in `dim` dims."""
    return (2 * res + 1) ** dim if neighbourhood == "box" else _ball_size(dim, res, neighbourhood)


@functools.lru_cache(maxsize=None)
def _ball_size(dim: int, res: int, neighbourhood: str) -> int:
    m = half_width(res, neighbourhood)
    if dim == 1:
        return 2 * m + 1
    return sum(_ball_size(dim - 1, cross_section(res, o, neighbourhood), neighbourhood) for o in range(-m, m + 1))


def neighbourhood_kernels(r_act, r_inh, neighbourhood: str, include_self: bool, shape, edge=None):
    """Activator and ring kernels of shape (K, *shape) on the periodic lattice, from the
    (possibly traced) radii of shape (K,). `edge` > 0 gives a smooth membership (a
    sigmoid of that width in lattice cells: the soft step's gradients in the radii)."""
    dist = jnp.asarray(lattice_distance(shape, neighbourhood))
    bcast = (slice(None),) + (None,) * len(shape)
    centre = jnp.zeros(shape, bool).at[(0,) * len(shape)].set(True)
    if edge is None:
        t_act = threshold(r_act, neighbourhood)[bcast]
        t_inh = threshold(r_inh, neighbourhood)[bcast]
        in_act = (dist <= t_act).astype(dist.dtype)
        in_inh = (dist <= t_inh).astype(dist.dtype)
    else:
        d = jnp.sqrt(dist) if neighbourhood == "disc" else dist
        in_act = jax.nn.sigmoid((r_act[bcast] - d) / edge)
        in_inh = jax.nn.sigmoid((r_inh[bcast] - d) / edge)
    ring = jnp.maximum(in_inh - in_act, 0.0)
    act = in_act if include_self else jnp.where(centre, 0.0, in_act)
    return act, ring

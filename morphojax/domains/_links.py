"""Diffusion on the links of the square lattice: per-cell rates, the harmonic mean, polarity.

The flux form of the thesis (section 4.3): every link between a cell i and a neighbour j
carries the exchange

    w_ij D_ij (u_j - u_i),   D_ij = 2 D_i D_j / (D_i + D_j)   (eq. 4.7; 0 when either is 0)

with w_ij the stencil's weight of that link (nine-point: 4/6 along the axes, 1/6 on the
diagonals; five-point: 1 along the axes; moore: 1 on all eight), in cells^-2, so the term
of cell i is sum_j w_ij D_ij (u_j - u_i), a discrete div(D grad u). The exchange is one
number per link, added to one end and subtracted from the other: mass is conserved.

Anisotropic species (eq. 4.8): before the mean, each cell's rate toward a neighbour is
scaled by |d . p| / |d|, d the direction of the link and p the cell's unit polarity (1 for
an unpolarised cell). The scale depends only on the link's axis (d and -d give the same),
so a cell has four factors: along a row (h), along a column (v), down-right (d) and
down-left (a).

Boundaries, as the stencils' ghost cells (see `_stencils`): "wrap" copies the opposite
edge; "no-flux" mirrors the lattice at its border (the ghost cell is the edge cell), so
links along the axes to a ghost carry nothing and a diagonal link to a ghost mirrors a
link along the edge. A mirrored cell's polarity is mirrored too (a row mirror turns the
angle t into -t, a column mirror into pi - t), which swaps its d and a factors in the
ghost rows and columns (twice, so not at all, in the corners): both ends of a mirrored
link then see the same pair of rates and the exchange stays symmetric.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

# (weight along the axes, weight on the diagonals) of each stencil, cells^-2
LINK_WEIGHTS = {"nine-point": (4.0 / 6.0, 1.0 / 6.0), "five-point": (1.0, 0.0), "moore": (1.0, 1.0)}
_ROOT_HALF = 1.0 / math.sqrt(2.0)


def harmonic_mean(a, b):
    """2 a b / (a + b) (thesis eq. 4.7), 0 where a + b is 0 (gradients stay finite there)."""
    s = a + b
    pos = s > 0
    return jnp.where(pos, 2.0 * a * b / jnp.where(pos, s, 1.0), 0.0)


def direction_factors(angle, polarised=None):
    """|d . p| / |d| for the four link axes (h, v, d, a) of cells with polarity `angle`
    (radians from +x = along a row toward increasing column, positive toward increasing
    row); `polarised` (1/0, same shape or None = all) gives 1 to unpolarised cells."""
    cx, sy = jnp.cos(angle), jnp.sin(angle)
    factors = (jnp.abs(cx), jnp.abs(sy), jnp.abs(cx + sy) * _ROOT_HALF, jnp.abs(sy - cx) * _ROOT_HALF)
    if polarised is None:
        return factors
    return tuple(polarised * f + (1.0 - polarised) for f in factors)


def pad_factors(factors, boundary: str, shape):
    """The four factors on the ghost-padded (rows + 2, cols + 2) layout of a (rows, cols)
    lattice: wrapped, or mirrored with the d and a factors swapped in the ghost rows and
    columns ("no-flux"). Scalars stay scalars on a wrapped lattice."""
    rows, cols = int(shape[-2]), int(shape[-1])
    if boundary == "wrap":
        return tuple(f if jnp.ndim(f) == 0 else jnp.pad(f, 1, mode="wrap") for f in factors)
    padded = tuple(jnp.pad(jnp.broadcast_to(f, (rows, cols)), 1, mode="edge") for f in factors)
    ghost_row = np.zeros((rows + 2, 1), bool)
    ghost_row[[0, -1]] = True
    ghost_col = np.zeros((1, cols + 2), bool)
    ghost_col[:, [0, -1]] = True
    swap = ghost_row ^ ghost_col  # static: a mirrored cell's diagonals trade places
    fh, fv, fd, fa = padded
    return fh, fv, jnp.where(swap, fa, fd), jnp.where(swap, fd, fa)


def link_divergence(p, rates, stencil: str):
    """sum_j w_ij D_ij (u_j - u_i) on the interior of a ghost-padded field `p` (rows + 2,
    cols + 2), given the padded per-cell rates toward each link axis `rates` = (h, v, d, a)
    (each a (rows + 2, cols + 2) array or a scalar). Each link's exchange is computed once
    and added to one end, subtracted from the other."""
    w_axis, w_diag = LINK_WEIGHTS[stencil]
    shape = p.shape
    rh, rv, rd, ra = (jnp.broadcast_to(r, shape) for r in rates)
    # along a row: (r, c) -- (r, c + 1) for the interior rows, c = 0 .. cols
    f = w_axis * harmonic_mean(rh[1:-1, :-1], rh[1:-1, 1:]) * (p[1:-1, 1:] - p[1:-1, :-1])
    out = f[:, 1:] - f[:, :-1]
    # along a column: (r, c) -- (r + 1, c)
    f = w_axis * harmonic_mean(rv[:-1, 1:-1], rv[1:, 1:-1]) * (p[1:, 1:-1] - p[:-1, 1:-1])
    out = out + (f[1:] - f[:-1])
    if w_diag:
        # down-right: (r, c) -- (r + 1, c + 1)
        f = w_diag * harmonic_mean(rd[:-1, :-1], rd[1:, 1:]) * (p[1:, 1:] - p[:-1, :-1])
        out = out + (f[1:, 1:] - f[:-1, :-1])
        # down-left: (r, c + 1) -- (r + 1, c)
        f = w_diag * harmonic_mean(ra[:-1, 1:], ra[1:, :-1]) * (p[1:, :-1] - p[:-1, 1:])
        out = out + (f[1:, :-1] - f[:-1, 1:])
    return out

"""Diffusion on a lattice's links: per-cell rates, the harmonic mean, polarity.

The square lattice's link form is here; the hexagonal lattice's (`_hex.hex_link_sum`) uses
the same mean and the same polarity leaves (`polarity_leaves`, `species_indices`).

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

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._checks import default_float, is_concrete

MAPS = ("flux", "pointwise")
LETTERS = "abcdefghijklmnopqrstuvwxyz"


def species_indices(anisotropic, who: str, field: str = "anisotropic") -> tuple:
    """The anisotropic species as sorted 0-based positions (from indices or letters)."""
    if isinstance(anisotropic, (str, int)):
        anisotropic = (anisotropic,)
    out = set()
    for s in anisotropic:
        if isinstance(s, str) and len(s) == 1 and s.lower() in LETTERS:
            out.add(LETTERS.index(s.lower()))
        elif isinstance(s, (int, np.integer)) and not isinstance(s, bool) and s >= 0:
            out.add(int(s))
        else:
            raise ValueError(f"{who}.{field} entries must be species positions: an index >= 0 or a letter "
                             f"'a'..'z' ('a' = first species) (got {s!r})")
    return tuple(sorted(out))


def polarity_leaves(polarity, polarised, who: str):
    """(angles with NaN replaced by 0, polarised mask or None) as array leaves."""
    if polarity is None:
        if polarised is not None:
            raise ValueError(f"{who}.polarised needs a polarity (an angle or a (rows, cols) array of angles)")
        return None, None
    angle = jnp.asarray(polarity, default_float())
    if angle.ndim not in (0, 2):
        raise ValueError(f"{who}.polarity must be an angle (radians) or a (rows, cols) array of angles "
                         f"(got shape {angle.shape})")
    mask = None if polarised is None else jnp.asarray(polarised, default_float())
    if mask is not None and mask.shape != angle.shape:
        raise ValueError(f"{who}.polarised must have the polarity's shape {angle.shape} (got {mask.shape})")
    if is_concrete(angle):
        values = np.asarray(angle)
        if np.isinf(values).any():
            raise ValueError(f"{who}.polarity must be finite angles in radians, or NaN for an unpolarised cell")
        nan = np.isnan(values)
        if nan.any():
            mask = jnp.asarray(~nan, default_float()) if mask is None else mask * jnp.asarray(~nan, mask.dtype)
            angle = jnp.where(jnp.asarray(nan), 0.0, angle)
    if mask is not None and is_concrete(mask) and not np.isin(np.asarray(mask), (0.0, 1.0)).all():
        raise ValueError(f"{who}.polarised must hold 1 (polarised) or 0 (unpolarised) per cell")
    return angle, mask


def polarity_fields(polarity, polarised, follow, who: str):
    """A lattice's (angles, polarised mask, followed species) from its `polarity` (an angle,
    an array of angles, None or a `Polarize`), `polarised` mask and saved `follow`."""
    if isinstance(polarity, Polarize) or follow is not None:
        if polarised is not None or (follow is not None and polarity is not None):
            raise ValueError(f"{who}.polarity: a Polarize polarity follows its reagent; give no polarised mask "
                             "and no other polarity with it")
        return None, None, polarity.reagent if follow is None else Polarize(follow).reagent
    return (*polarity_leaves(polarity, polarised, who), None)


def check_species(anisotropic, n: int, who: str, field: str = "anisotropic") -> None:
    """Raise a ValueError when an anisotropic species is beyond the model's `n` species."""
    if anisotropic and max(anisotropic) >= n:
        raise ValueError(f"{who}.{field} names species {max(anisotropic)} (0-based) but the model has {n} "
                         f"species; name species by position: 0..{n - 1} or 'a'..'{LETTERS[n - 1]}'")


# (weight along the axes, weight on the diagonals) of each stencil, cells^-2
LINK_WEIGHTS = {"nine-point": (4.0 / 6.0, 1.0 / 6.0), "five-point": (1.0, 0.0), "moore": (1.0, 1.0)}
_ROOT_HALF = 1.0 / math.sqrt(2.0)


def harmonic_mean(a, b):
    """2 a b / (a + b) (thesis eq. 4.7), 0 where a + b is 0 (gradients stay finite there)."""
    s = a + b
    pos = s > 0
    return jnp.where(pos, 2.0 * a * b / jnp.where(pos, s, 1.0), 0.0)


def unit_polarity(angle, polarised=None):
    """A polarity given by angles (radians from +x = along a row toward increasing column,
    positive toward increasing row) as (cos, sin, polarised): what the link factors take;
    None (no polarity) stays None."""
    return None if angle is None else (jnp.cos(angle), jnp.sin(angle), polarised)


def direction_factors(cx, sy, polarised=None):
    """|d . p| / |d| for the four link axes (h, v, d, a) of cells with unit polarity
    (cx, sy) (`unit_polarity`, or a normalised gradient); `polarised` (1/0, same shape or
    None = all) gives 1 to unpolarised cells."""
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


def gradient_vector(padded):
    """sum_j (R_j - R) d_j / |d_j| over the eight surrounding cells (thesis eq. 4.10,
    before normalising) of a ghost-padded reagent (..., rows + 2, cols + 2): (px, py), x
    along a row and y down the rows."""
    rows, cols = padded.shape[-2] - 2, padded.shape[-1] - 2
    r = padded[..., 1:-1, 1:-1]
    px = jnp.zeros_like(r)
    py = jnp.zeros_like(r)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr == dc == 0:
                continue
            diff = padded[..., 1 + dr: 1 + dr + rows, 1 + dc: 1 + dc + cols] - r
            norm = math.hypot(dr, dc)
            px = px + diff * (dc / norm)
            py = py + diff * (dr / norm)
    return px, py


def unit_gradient(px, py):
    """(cos, sin, polarised) of a gradient vector (px, py) normalised: a cell where it
    vanishes is unpolarised (mask 0), and the derivatives stay finite there. No angle is
    formed: arctan2, cos and sin per cell and step cost about 20x the step itself on CPU."""
    sq = px * px + py * py
    zero = sq == 0
    inv = jnp.where(zero, 0.0, jax.lax.rsqrt(jnp.where(zero, 1.0, sq)))
    return px * inv, py * inv, (~zero).astype(px.dtype)


def gradient_leaves(padded):
    """(cos, sin, polarised) of the polarity along a padded reagent's gradient (eq. 4.10)."""
    return unit_gradient(*gradient_vector(padded))


def gradient_polarity(reagent, boundary: str = "no-flux"):
    """Polarity angles from the local gradient of a reagent on the square lattice (thesis
    eq. 4.10): p = sum_j (R_j - R) d_j / |d_j| over the eight surrounding cells, as an
    angle in radians from +x (x along a row, y down the rows), NaN where p = 0 (an
    unpolarised cell). `reagent` is (rows, cols); `boundary` as the lattice's ghost cells.
    Pass the result as a `Lattice(polarity=...)` for a polarity set once from a reagent;
    `Lattice(polarity=Polarize(reagent))` makes the polarity follow the reagent as it runs."""
    from ._stencils import normalise_boundary, pad

    px, py = gradient_vector(pad(jnp.asarray(reagent), normalise_boundary(boundary)))
    zero = (px == 0) & (py == 0)
    return jnp.where(zero, jnp.nan, jnp.arctan2(py, px))


class Polarize(eqx.Module):
    """Chemically induced polarization (thesis eq. 4.10): `Lattice(polarity=Polarize("c"))`
    polarises every cell along the local gradient of a species, recomputed from the state at
    the start of every step, so a change of the reagent takes effect on the next step (as
    the thesis's `polarize` action). The polarity is a function of the state, so saved and
    resumed runs carry it with their fields; a cell where the gradient vanishes is
    unpolarised. `reagent` is a species position, like `anisotropic`: an index (0 = first)
    or a letter ("a" = first). On cells, the same action is the rule `mj.cells.Polarize`.
    """

    reagent: int = eqx.field(static=True)

    def __init__(self, reagent):
        (self.reagent,) = species_indices((reagent,), "Polarize", "reagent")

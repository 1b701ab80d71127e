"""The hexagonal lattice in the odd-r offset layout: six neighbours per cell, wrap or no-flux.

Fields have shape (species, rows, cols). Row r holds the cells at y = r sqrt(3)/2 and
x = c + (r mod 2) / 2: odd rows are shifted half a cell to the right, so every cell has
six neighbours at unit distance:

- (r, c - 1) and (r, c + 1) in its own row,
- for even r: (r - 1, c - 1), (r - 1, c), (r + 1, c - 1), (r + 1, c),
- for odd r:  (r - 1, c), (r - 1, c + 1), (r + 1, c), (r + 1, c + 1).

The carried layout is the fields with one ring of ghost cells copied from the opposite
edges (as on the square lattice). "wrap" uses them: a torus (the ghost row above row 0 is
the last row, so the row parity only stays consistent with an even number of rows).
"no-flux" ignores them: it sums only the neighbours that exist and subtracts u once per
neighbour, which drops every link that would leave the lattice (pure diffusion then
conserves mass exactly).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jax import Array

from .._checks import check_choice, is_concrete
from . import _links, _stencils
from ._base import AbstractDomain

OPERATORS = ("laplacian", "sum")
# Largest |eigenvalue| over all lattice sizes, in cells^-2. On the infinite lattice the
# neighbour sum sum_j (u_j - u) has the symbol 2 (cos a + cos b + cos(a + b)) - 6 (a, b the
# phases along two lattice directions); cos a + cos b + cos(a + b) >= -3/2, reached at
# a = b = 2 pi / 3, so the sum's spectrum is [-9, 0] and the Laplacian's (2/3 of it)
# [-6, 0]. A wrapped lattice attains it when its columns are a multiple of 3 (its rows are
# even); no-flux lattices stay below (dropping links lowers the quadratic form).
SPECTRAL_RADIUS = {"laplacian": 6.0, "sum": 9.0}
_OPERATOR_ALIASES = {"lap": "laplacian", "neighbour-sum": "sum", "neighbor-sum": "sum", "equal-weight": "sum"}
ROW_HEIGHT = math.sqrt(3.0) / 2.0  # distance between rows, in cells


def neighbour_sum(p, xp=jnp, links=None):
    """Sum over each interior cell's six neighbours in a ghost-padded odd-r array `p`
    (..., rows + 2, cols + 2). `xp` is jax.numpy or numpy. With `links` (see `links`) a
    neighbour counts only where its link exists (the ghost cells' values then do not matter)."""
    rows = p.shape[-2] - 2
    even = (np.arange(rows) % 2 == 0)[:, None]  # static: the layout's row parity
    up, down, mid = p[..., :-2, :], p[..., 2:, :], p[..., 1:-1, :]
    if links is None:
        same = mid[..., :-2] + mid[..., 2:] + up[..., 1:-1] + down[..., 1:-1]
        # even rows reach the column to the left in the rows above and below, odd rows the right
        return same + xp.where(even, up[..., :-2] + down[..., :-2], up[..., 2:] + down[..., 2:])
    has_up, has_down, has_left, has_right = links
    same = mid[..., :-2] * has_left + mid[..., 2:] * has_right + up[..., 1:-1] * has_up + down[..., 1:-1] * has_down
    return same + xp.where(even, (up[..., :-2] * has_up + down[..., :-2] * has_down) * has_left,
                           (up[..., 2:] * has_up + down[..., 2:] * has_down) * has_right)


def hex_direction_factors(cx, sy, polarised=None):
    """|d . p| / |d| for the three link axes of the odd-r layout (x along a row, y down the
    rows) of cells with unit polarity (cx, sy): along the row (1, 0); "up-left/down-right"
    (1/2, sqrt(3)/2); "up-right/down-left" (-1/2, sqrt(3)/2). `polarised` (1/0 or None = all)
    gives 1 to unpolarised cells."""
    h = math.sqrt(3.0) / 2.0
    factors = (jnp.abs(cx), jnp.abs(0.5 * cx + h * sy), jnp.abs(h * sy - 0.5 * cx))
    if polarised is None:
        return factors
    return tuple(polarised * f + (1.0 - polarised) for f in factors)


def hex_link_sum(p, rates, mask=None):
    """sum_j D_ij (u_j - u_i) over each interior cell's six links in a ghost-padded odd-r
    array `p` (rows + 2, cols + 2); `rates` = per-cell rates toward the three link axes
    (row, down-right, down-left; padded arrays or scalars), D_ij their harmonic mean (eq.
    4.7); `mask` (see `links`) drops the links that leave a no-flux lattice."""
    rows = p.shape[-2] - 2
    even = (np.arange(rows) % 2 == 0)[:, None]  # static: the layout's row parity
    r_row, r_dr, r_dl = (jnp.broadcast_to(r, p.shape) for r in rates)
    u = p[1:-1, 1:-1]

    def shifted(a, dr, dc):  # a at (r + dr, c + dc) of each interior cell
        return a[1 + dr: a.shape[0] - 1 + dr, 1 + dc: a.shape[1] - 1 + dc]

    def link(a, dr, dc):  # the exchange with the neighbour at (dr, dc), with rates `a`
        return _links.harmonic_mean(shifted(a, 0, 0), shifted(a, dr, dc)) * (shifted(p, dr, dc) - u)

    def parity(a, dr, even_dc, odd_dc):  # the diagonal neighbour by row parity
        return jnp.where(even, link(a, dr, even_dc), link(a, dr, odd_dc))

    left, right = link(r_row, 0, -1), link(r_row, 0, 1)
    up_left, down_right = parity(r_dr, -1, -1, 0), parity(r_dr, 1, 0, 1)
    up_right, down_left = parity(r_dl, -1, 0, 1), parity(r_dl, 1, -1, 0)
    if mask is None:
        return left + right + up_left + down_right + up_right + down_left
    has_up, has_down, has_left, has_right = mask
    # the diagonals of even rows reach the column to the left, of odd rows the right
    to_left, to_right = jnp.where(even, has_left, 1.0), jnp.where(even, 1.0, has_right)
    return (left * has_left + right * has_right + (up_left * to_left + up_right * to_right) * has_up
            + (down_left * to_left + down_right * to_right) * has_down)


def hex_gradient_leaves(p, mask=None):
    """(cos, sin, polarised) of the polarity along the local gradient of a ghost-padded odd-r reagent
    `p` (rows + 2, cols + 2): p = sum_j (R_j - R) d_j over the six links (thesis eq. 4.10;
    unit links), `mask` dropping those that leave a no-flux lattice; a cell where p = 0 is
    unpolarised."""
    rows = p.shape[-2] - 2
    even = (np.arange(rows) % 2 == 0)[:, None]  # static: the layout's row parity
    up, down, mid = p[:-2, :], p[2:, :], p[1:-1, :]
    u = mid[:, 1:-1]
    left, right = mid[:, :-2] - u, mid[:, 2:] - u
    up_left = jnp.where(even, up[:, :-2], up[:, 1:-1]) - u
    up_right = jnp.where(even, up[:, 1:-1], up[:, 2:]) - u
    down_left = jnp.where(even, down[:, :-2], down[:, 1:-1]) - u
    down_right = jnp.where(even, down[:, 1:-1], down[:, 2:]) - u
    if mask is not None:
        has_up, has_down, has_left, has_right = mask
        to_left, to_right = jnp.where(even, has_left, 1.0), jnp.where(even, 1.0, has_right)
        left, right = left * has_left, right * has_right
        up_left, up_right = up_left * has_up * to_left, up_right * has_up * to_right
        down_left, down_right = down_left * has_down * to_left, down_right * has_down * to_right
    px = right - left + 0.5 * (up_right - up_left + down_right - down_left)
    py = ROW_HEIGHT * (down_left + down_right - up_left - up_right)
    return _links.unit_gradient(px, py)


def links(shape):
    """1.0 where a (rows, cols) lattice has a neighbour above, below, left and right of a
    cell (as a column, a column, a row and a row vector): the no-flux lattice's links."""
    rows, cols = int(shape[-2]), int(shape[-1])
    r, c = np.arange(rows)[:, None], np.arange(cols)[None, :]
    return (r > 0).astype(float), (r < rows - 1).astype(float), (c > 0).astype(float), (c < cols - 1).astype(float)


def neighbour_count(shape, boundary: str):
    """Number of neighbours of each cell of a (rows, cols) lattice (6 everywhere on a torus)."""
    if boundary == "wrap":
        return 6.0
    rows, cols = int(shape[-2]), int(shape[-1])
    return neighbour_sum(np.ones((rows + 2, cols + 2)), np, links(shape))


class HexLattice(AbstractDomain):
    """The hexagonal lattice (odd-r offset layout, unit spacing between cell centres).

    Args:
        boundary: "wrap" (a torus: needs an even number of rows) or "no-flux" (links that
            leave the lattice are dropped: an edge cell has fewer than six neighbours).
        operator: "laplacian" (default): (2/3) sum_j (u_j - u), the six-neighbour
            Laplacian in cells^-2 (second order: the six unit neighbours give
            sum_j (u_j - u) = (3/2) lap u + O(h^4)), spectral radius 6; or "sum": the
            thesis's unnormalised equal-weight sum over the six neighbours, sum_j (u_j - u)
            (section 4.3, its hexagonal listings), which approximates (3/2) x the
            Laplacian in the same units (a rate D with "sum" diffuses as 1.5 D with
            "laplacian"), spectral radius 9.

        maps, anisotropic, polarity, polarised, follow: as on `Lattice` (a `Polarize`
            polarity follows its reagent's gradient over the six links, with the links
            that leave a no-flux lattice dropped): a diffusion map diffuses in
            the flux form by default (each link carries the operator's weight (2/3 or 1)
            times the harmonic mean of its two cells' rates, eq. 4.7), or "pointwise"
            D(x) lap(u); the anisotropic species scale each cell's rate toward a neighbour
            by |d . p| / |d| (eq. 4.8) with the six directions of the odd-r layout: along
            the row (1, 0), and (+-1/2, sqrt(3)/2) to the rows above and below (y grows
            with the row index, as the angle's sign). No-flux drops the links that leave.
            Every link's rate is at most D_max (a harmonic mean lies between its rates,
            |d . p| / |d| <= 1), so the operator stays below D_max times the isotropic one
            in the order of symmetric matrices: the spectral radius above bounds it.

    Growth (`growth=mj.Growth(...)`, matrix expansion with the square lattice's four laws)
    keeps the layout: each dividing cell is duplicated twice, so the cells below it move
    down two rows and keep their row parity (one row down would move them half a cell
    sideways), and the cells after it along a row move two whole cells; one expansion adds
    two rows and two columns (`Growth.expand`). A wrapped lattice's rows stay even. The
    active region grows in the top-left corner of the capacity, its ghost cells along its
    edges (as on the square lattice); no-flux drops the links that leave the active region.
    Not with a polarity; a rate map's links across the active region's edge use the rates
    as laid out in the capacity array. The division method only (no interpolation), and
    every step on the whole capacity (`WholeCapacity`; the block ladder is the square
    lattice's). Pictures: `mj.hex_image` draws the cells as hexagons.
    """

    boundary: str = eqx.field(static=True)
    operator: str = eqx.field(static=True)
    maps: str = eqx.field(static=True)
    anisotropic: tuple = eqx.field(static=True)
    polarity: Array | None
    polarised: Array | None
    follow: int | None = eqx.field(static=True)

    def __init__(self, boundary: str = "wrap", operator: str = "laplacian", *, maps: str = "flux",
                 anisotropic=(), polarity=None, polarised=None, follow=None):
        self.boundary = _stencils.normalise_boundary(boundary)
        key = str(operator).lower()
        key = _OPERATOR_ALIASES.get(key, key)
        check_choice(key, "operator", OPERATORS)
        self.operator = key
        check_choice(str(maps), "maps", _links.MAPS)
        self.maps = str(maps)
        self.anisotropic = _links.species_indices(anisotropic, "HexLattice")
        self.polarity, self.polarised, self.follow = _links.polarity_fields(polarity, polarised, follow,
                                                                            "HexLattice")

    @property
    def spectral_radius(self) -> float:
        return SPECTRAL_RADIUS[self.operator]

    @property
    def supports_growth(self) -> bool:
        return not self.polarised_cells

    @property
    def expansion_copies(self) -> int:
        return 2  # a cell moved by two rows keeps its row parity, so its place across the lattice

    @property
    def ndim(self) -> int:
        return 2

    @property
    def description(self) -> str:
        what = "Laplacian" if self.operator == "laplacian" else "neighbour sum"
        aniso = ", anisotropic" if self.anisotropic and self.polarised_cells else ""
        return f"hexagonal lattice {what} ({self.boundary}{aniso})"

    def check_shape(self, shape) -> None:
        """Raise a ValueError when a (rows, cols) lattice cannot hold this domain."""
        rows, cols = int(shape[-2]), int(shape[-1])
        if self.boundary == "wrap" and rows % 2:
            raise ValueError(f"HexLattice(boundary='wrap') needs an even number of rows (got {rows}): the odd-r "
                             "layout shifts odd rows, so a torus must pair them; use an even number of rows or "
                             "boundary='no-flux'")
        if rows < 2 or cols < 2:
            raise ValueError(f"HexLattice needs at least 2 rows and 2 columns (got {rows} x {cols})")

    def _pad(self, x):
        # both boundaries carry wrapped ghost cells; no-flux masks the links to them, which
        # keeps the step one fused loop on XLA:CPU as on the torus (zero ghosts make XLA fuse
        # the whole step into the padding, about 3x slower: benchmarks/results/bench_domains.md)
        self.check_shape(x.shape)
        widths = [(0, 0)] * (x.ndim - 2) + [(1, 1), (1, 1)]
        return jnp.pad(x, widths, mode="wrap")

    def _operator_padded(self, p, mask=None):
        """The operator on a padded array; `mask` (see `active_links`): the no-flux links
        of a growing lattice's active region (default: those of the whole array)."""
        x = p[..., 1:-1, 1:-1]
        if self.boundary == "wrap":
            s = neighbour_sum(p) - 6.0 * x
        elif mask is None:
            mask = tuple(jnp.asarray(v, x.dtype) for v in links(x.shape))
            count = jnp.asarray(neighbour_count(x.shape, self.boundary), x.dtype)
            s = neighbour_sum(p, jnp, mask) - count * x
        else:
            count = neighbour_sum(jnp.ones(p.shape[-2:], x.dtype), jnp, mask)
            s = neighbour_sum(p, jnp, mask) - count * x
        return s * (2.0 / 3.0) if self.operator == "laplacian" else s

    @staticmethod
    def active_links(shape, size, dtype):
        """`links` of the active region `size` (may be traced) of a (rows, cols) array: a
        cell has a neighbour above unless it is in row 0, below unless in row size[0] - 1,
        and so on."""
        r, c = jnp.arange(shape[-2])[:, None], jnp.arange(shape[-1])[None, :]
        return tuple(v.astype(dtype) for v in (r > 0, r < size[0] - 1, c > 0, c < size[1] - 1))

    # ---- what the stepping loop uses ---------------------------------------------------
    def carry(self, fields, size, dynamic):
        if dynamic:  # wrapped ghost cells along the active region's edges (no-flux masks them)
            if is_concrete(size):
                self.check_shape(np.asarray(size))
            return _stencils.repad(_stencils.pad(fields, "wrap"), fields, size, "wrap")
        return self._pad(fields)

    def interior(self, carried):
        return carried[..., 1:-1, 1:-1]

    def active_diffusion(self, carried, rates, size):
        if self.boundary == "wrap":
            return self.diffusion(carried, rates)
        shape = (carried.shape[-2] - 2, carried.shape[-1] - 2)
        return self.diffusion(carried, rates, self.active_links(shape, size, carried.dtype))

    def diffusion(self, carried, rates, mask=None):
        n = carried.shape[0]
        _links.check_species(self.anisotropic, n, "HexLattice")
        if self.follow is not None:
            _links.check_species((self.follow,), n, "Polarize", "reagent")
        on_links = [self._on_links(i, rates[i]) for i in range(n)]
        op = None if all(on_links) else self._operator_padded(carried, mask)
        shape = carried.shape[-2:]
        if mask is None and self.boundary != "wrap":
            mask = tuple(jnp.asarray(v, carried.dtype) for v in links((shape[0] - 2, shape[1] - 2)))
        # a polarity that follows a reagent: from the fields this step starts from
        polarity = (hex_gradient_leaves(carried[self.follow], mask) if self.follow is not None else
                    _links.unit_polarity(self.polarity, self.polarised))
        return [self._link_term(carried[i], rates[i], i, polarity, mask) if on_links[i] else rates[i] * op[i]
                for i in range(n)]

    @property
    def polarised_cells(self) -> bool:
        """Whether any polarity is set (fixed angles or one that follows a reagent)."""
        return self.polarity is not None or self.follow is not None

    def _on_links(self, i: int, rate) -> bool:
        """Whether species i diffuses on the links (flux form or anisotropic): static."""
        if i in self.anisotropic and self.polarised_cells:
            return True
        return self.maps == "flux" and tuple(jnp.shape(rate))[-2:] not in ((), (1,), (1, 1))

    def _link_term(self, p, rate, i: int, polarity, mask):
        """sum_j w D_ij (u_j - u_i) for one species' padded field `p` (eqs. 4.7-4.8), given
        the cells' unit polarity (cos, sin, polarised mask) or None and the no-flux link
        mask: each link's exchange is computed from both ends with the same operands (the
        harmonic mean is symmetric in them), so what one cell gains its neighbour loses."""
        shape = (p.shape[-2] - 2, p.shape[-1] - 2)
        d = jnp.pad(jnp.broadcast_to(jnp.asarray(rate, p.dtype), shape), 1, mode="wrap")
        if i in self.anisotropic and polarity is not None:
            cx = polarity[0]
            if cx.ndim == 2 and tuple(cx.shape) != shape:
                raise ValueError(f"HexLattice.polarity has shape {tuple(cx.shape)}; the lattice is {shape}")
            factors = hex_direction_factors(*polarity)
            if cx.ndim == 2:
                factors = tuple(jnp.pad(f, 1, mode="wrap") for f in factors)
            rates = tuple(d * f for f in factors)
        else:
            rates = (d,) * 3
        s = hex_link_sum(p, rates, mask)
        return s * (2.0 / 3.0) if self.operator == "laplacian" else s

    def write(self, carried, new, size, dynamic):
        if dynamic:
            return _stencils.repad(carried, new, size, "wrap")
        return self._pad(new)

    def active_mask(self, shape, size):
        return _stencils.active_mask(shape, size)

    def apply(self, fields):
        return self._operator_padded(self._pad(jnp.asarray(fields)))

    # ---- geometry ------------------------------------------------------------------------
    @staticmethod
    def centres(shape) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of the cell centres of a (rows, cols) lattice, in cells: x along a row
        (odd rows shifted by 1/2), y down the rows (sqrt(3)/2 apart)."""
        rows, cols = int(shape[0]), int(shape[1])
        r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
        return c + 0.5 * (r % 2), r * ROW_HEIGHT

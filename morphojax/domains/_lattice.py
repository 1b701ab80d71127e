"""The square lattice: a 3x3 stencil (a Laplacian, or the thesis's neighbour sum) with ghost-cell
boundaries; per-cell diffusion rates in flux form and anisotropic diffusion on its links (`_links`)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from .._checks import check_choice, check_range
from . import _links, _stencils
from ._base import AbstractDomain


class Lattice(AbstractDomain):
    """The square lattice: a 3x3 stencil with ghost-cell boundaries.

    Args:
        stencil: "nine-point" (the leopard paper's isotropic [[1,4,1],[4,-20,4],[1,4,1]]/6,
            spectral radius 16/3) or "five-point" ([[0,1,0],[1,-4,1],[0,1,0]], radius 8):
            both approximate the Laplacian, in cells^-2; or "moore", the thesis's
            equal-weight sum over the eight neighbours sum_j (u_j - u) (section 4.3,
            [[1,1,1],[1,-8,1],[1,1,1]]): in the same units it approximates 3 x the
            Laplacian (a rate D with "moore" diffuses as 3 D with "nine-point"), spectral
            radius 12 (the stripe mode, alternating along one axis; the checkerboard gives
            8). The thesis's diffusion rates are used with "moore" as printed.
            Other dimensions: "three-point" ([1, -2, 1], 1D, radius 4), "seven-point" (the
            3D five-point, radius 12) and "nineteen-point" (the isotropic 3D stencil: faces
            2/6, edges 1/6, centre -4; radius 16/3; the 3D default). 1D and 3D lattices take
            one diffusion rate per species (no maps, anisotropy or growth).
        boundary: "wrap" (toroidal) or "no-flux" (ghost cell = edge cell, as scipy's
            mode="reflect": pure diffusion conserves mass).
        maps: how a diffusion map (a model whose rates are (rows, cols) arrays) diffuses:
            "flux" (default), the conservative div(D grad u): each link of the stencil
            carries w_ij D_ij (u_j - u_i) with D_ij the harmonic mean of the two cells'
            rates (thesis eq. 4.7; 0 when either is 0), so mass is conserved and a cell of
            rate 0 is impermeable; or "pointwise", D(x) lap(u) (not conservative; the
            behaviour before the flux form). Scalar rates are unaffected by this choice.
        anisotropic: the species whose diffusion follows the polarity (thesis eq. 4.8), by
            position: an index (0 = first species) or a letter ("a" = first, "b" = second,
            as in `lower_a`/`upper_b`; letters are positions, not the model's own names).
            Each cell's rate toward neighbour j is scaled by |d_j . p| / |d_j| (d_j the
            direction to the neighbour, p the cell's unit polarity; 1 for an unpolarised
            cell) and the two scaled rates meet on the link by the harmonic mean (eq. 4.7):
            the exchange is symmetric and mass is conserved where polarity varies.
        polarity: None (no cell polarised: anisotropic species diffuse isotropically), an
            angle in radians from the +x axis (0 = along a row toward increasing column,
            pi/2 = along a column toward increasing row), or a (rows, cols) array of angles,
            NaN = unpolarised (turned into the `polarised` mask here, so gradients stay
            finite). An array leaf: differentiable and vmappable.
            Or `Polarize(reagent)`: each cell polarised along the local gradient of that
            species (eq. 4.10), recomputed from the state at the start of every step, so
            the polarity follows the reagent through the run (see `Polarize`).
        polarised: 1 where a cell is polarised, 0 where not (default: where `polarity` is
            not NaN); what a saved domain holds beside its NaN-free angles.
        follow: the species position a `Polarize` polarity follows (what a saved domain
            holds in its place).

    Stability: every link rate is at most D_max times the stencil's weight (a harmonic mean
    lies between its two rates, and |d . p| / |d| <= 1), so the operator is bounded by
    D_max times the stencil's in the order of symmetric matrices and the stencil's spectral
    radius bounds every map and polarity: dt * D_max * rho <= 2 stays the limit.

    Fields have shape (species, rows, cols); a growing lattice keeps its active region in
    the top-left corner of a fixed-capacity array, its ghost cells right after it (growth
    is refused with a polarity; on a growing lattice a rate map's links across the active
    region's edge use the rates as laid out in the capacity array).
    """

    stencil: str = eqx.field(static=True)
    boundary: str = eqx.field(static=True)
    maps: str = eqx.field(static=True)
    anisotropic: tuple = eqx.field(static=True)
    polarity: Array | None
    polarised: Array | None
    follow: int | None = eqx.field(static=True)

    def __init__(self, stencil: str = "nine-point", boundary: str = "wrap", *, maps: str = "flux",
                 anisotropic=(), polarity=None, polarised=None, follow=None):
        self.stencil = _stencils.normalise_stencil(stencil)
        self.boundary = _stencils.normalise_boundary(boundary)
        check_choice(str(maps), "maps", _links.MAPS)
        self.maps = str(maps)
        self.anisotropic = _links.species_indices(anisotropic, "Lattice")
        self.polarity, self.polarised, self.follow = _links.polarity_fields(polarity, polarised, follow, "Lattice")
        if self.ndim != 2 and (self.anisotropic or self.polarity is not None or self.follow is not None):
            raise ValueError(f"Lattice: anisotropic diffusion and polarity are defined on 2D lattices; the "
                             f"{self.stencil} stencil is {self.ndim}D")

    @property
    def polarised_cells(self) -> bool:
        """Whether any polarity is set (fixed angles or one that follows a reagent)."""
        return self.polarity is not None or self.follow is not None

    @property
    def spectral_radius(self) -> float:
        return _stencils.SPECTRAL_RADIUS[self.stencil]

    @property
    def ndim(self) -> int:
        """Spatial axes: 1 for "three-point", 3 for "seven-point" and "nineteen-point", else 2."""
        return _stencils.STENCIL_NDIM[self.stencil]

    @property
    def supports_growth(self) -> bool:
        return self.ndim == 2 and not self.polarised_cells

    @property
    def description(self) -> str:
        if self.anisotropic and self.follow is not None:
            return f"{self.stencil} stencil (anisotropic, polarity along species {self.follow}'s gradient)"
        if self.anisotropic and self.polarity is not None:
            return f"{self.stencil} stencil (anisotropic)"
        return f"{self.stencil} stencil"

    def carry(self, fields, size, dynamic):
        if self.ndim != 2:
            return _stencils.pad_nd(fields, self.boundary, self.ndim)
        p = _stencils.pad(fields, self.boundary)
        if dynamic:  # ghost cells along the active region's edges
            p = _stencils.repad(p, fields, size, self.boundary)
        return p

    def interior(self, carried):
        return carried[(Ellipsis,) + (slice(1, -1),) * self.ndim]

    def diffusion(self, carried, rates):
        n = carried.shape[0]
        if self.ndim != 2:  # 1D and 3D: the stencil with one rate per species
            for i in range(n):
                if jnp.ndim(rates[i]) > 0 and jnp.size(rates[i]) > 1:
                    raise ValueError(f"Lattice: diffusion rate maps are supported on 2D lattices; species {i} "
                                     f"has rates of shape {jnp.shape(rates[i])} on the {self.ndim}D {self.stencil} "
                                     "stencil")
            lap = _stencils.laplacian_padded_nd(carried, self.stencil)
            return [rates[i] * lap[i] for i in range(n)]
        _links.check_species(self.anisotropic, n, "Lattice")
        if self.follow is not None:
            _links.check_species((self.follow,), n, "Polarize", "reagent")
        links = [self._on_links(i, rates[i]) for i in range(n)]
        lap = None
        if not all(links):  # scalar rates, pointwise maps: the stencil, as before the flux form
            lap = _stencils.laplacian_padded(carried, self.stencil)
        # a polarity that follows a reagent: from the fields this step starts from
        polarity = (_links.gradient_leaves(carried[self.follow]) if self.follow is not None else
                    _links.unit_polarity(self.polarity, self.polarised))
        return [self._link_term(carried[i], rates[i], i, polarity) if links[i] else rates[i] * lap[i]
                for i in range(n)]

    def _on_links(self, i: int, rate) -> bool:
        """Whether species i diffuses on the links (flux form or anisotropic): static."""
        if i in self.anisotropic and self.polarised_cells:
            return True
        return self.maps == "flux" and tuple(jnp.shape(rate))[-2:] not in ((), (1,), (1, 1))

    def _link_term(self, p, rate, i: int, polarity):
        """sum_j w_ij D_ij (u_j - u_i) for one species' padded field `p` (eqs. 4.7-4.8),
        given the cells' unit polarity (cos, sin, polarised mask), or None."""
        shape = (p.shape[-2] - 2, p.shape[-1] - 2)
        rate = jnp.broadcast_to(jnp.asarray(rate, p.dtype), shape)
        padded = _stencils.pad(rate, self.boundary)
        if i in self.anisotropic and polarity is not None:
            cx = polarity[0]
            if cx.ndim == 2 and tuple(cx.shape) != shape:
                raise ValueError(f"Lattice.polarity has shape {tuple(cx.shape)}; the lattice is {shape}")
            factors = _links.direction_factors(*polarity)
            if cx.ndim == 2 or self.boundary != "wrap":
                factors = tuple(jnp.broadcast_to(f, shape) for f in factors)
            factors = _links.pad_factors(factors, self.boundary, shape)
            rates = tuple(padded * f for f in factors)
        else:
            rates = (padded,) * 4
        return _links.link_divergence(p, rates, self.stencil)

    def write(self, carried, new, size, dynamic):
        if dynamic:
            # an active region inside the array: the new values go back into the carried
            # buffer in place, with the ghost cells along the region's edges as four lines
            # (a fresh padded copy here makes XLA:CPU fuse the update into the copy)
            return _stencils.repad(carried, new, size, self.boundary)
        if self.ndim != 2:
            return _stencils.pad_nd(new, self.boundary, self.ndim)
        return _stencils.pad(new, self.boundary)  # the whole array is the lattice

    def active_mask(self, shape, size):
        return _stencils.active_mask(shape, size)

    def apply(self, fields):
        if self.ndim != 2:
            padded = _stencils.pad_nd(jnp.asarray(fields), self.boundary, self.ndim)
            return _stencils.laplacian_padded_nd(padded, self.stencil)
        return _stencils.laplacian_padded(_stencils.pad(jnp.asarray(fields), self.boundary), self.stencil)

    # ---- the operator's eigenbasis (exponential and implicit solvers, linear stability) --
    def eigenvalues(self, shape):
        """The stencil's eigenvalues on a lattice of `shape` with this boundary (float64,
        cells^-2), laid out as the coefficients of `transform`: exact for the lattice, not
        the continuum Laplacian's -|k|^2 (see `_stencils.eigenvalues`)."""
        return _stencils.eigenvalues(self.stencil, self.boundary, shape)

    def transform(self, fields):
        """Coefficients of `fields` (..., *spatial) in the stencil's eigenbasis: the real FFT
        for "wrap", the orthonormal DCT-II for "no-flux"."""
        return _stencils.forward_transform(fields, self.boundary, self.ndim)

    def inverse_transform(self, coefficients, shape):
        """The fields (..., *shape) whose `transform` is `coefficients`."""
        return _stencils.inverse_transform(coefficients, self.boundary, shape)

    # ---- blocks of a growing lattice (the execution plans of `_plan`) --------------------
    def block(self, carried, rows: int, cols: int):
        """The carried layout of the top-left (rows, cols) block of the lattice."""
        return carried[..., : rows + 2, : cols + 2]

    def unblock(self, carried, block):
        """`carried` with a block computed by `block` written back into its corner."""
        return jax.lax.dynamic_update_slice(carried, block, (0,) * carried.ndim)


def as_domain(domain=None, *, stencil=None, boundary=None, ndim: int = 2) -> AbstractDomain:
    """The domain of a run: `domain`, or a `Lattice` (the default domain) from the
    `stencil`/`boundary` shorthands; without a stencil, the default of fields with `ndim`
    spatial axes ("three-point", "nine-point", "nineteen-point").

    Giving both a domain and a shorthand is an error (they could disagree).
    """
    if domain is not None:
        if stencil is not None or boundary is not None:
            given = ", ".join(n for n, v in (("stencil", stencil), ("boundary", boundary)) if v is not None)
            raise ValueError(f"pass either domain= or the lattice shorthands ({given}), not both; "
                             f"e.g. domain=mj.Lattice(stencil=..., boundary=...)")
        if not isinstance(domain, AbstractDomain):
            raise ValueError(f"domain must be a morphojax domain such as mj.Lattice(...) (got {domain!r})")
        return domain
    default = _stencils.DEFAULT_STENCIL.get(ndim, "nine-point")
    return Lattice(default if stencil is None else stencil, "wrap" if boundary is None else boundary)


def max_stable_dt(max_diffusion: float, stencil: str = "nine-point") -> float:
    """Largest dt for which explicit Euler on pure diffusion is stable on a square lattice
    with this stencil: dt * D * rho <= 2 (see `AbstractDomain.max_stable_dt`)."""
    check_range(max_diffusion, "max_diffusion", low=0.0)
    return Lattice(stencil).max_stable_dt(max_diffusion)


def laplacian(x, boundary: str = "wrap", stencil: str = "nine-point"):
    """The stencil's operator on `x` (..., rows, cols) with the given boundary: a discrete
    Laplacian (cells^-2), or for "moore" the neighbour sum (about 3 x the Laplacian)."""
    return Lattice(stencil, boundary).apply(x)

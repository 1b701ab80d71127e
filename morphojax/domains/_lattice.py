"""The square lattice: a 3x3 stencil (a Laplacian, or the thesis's neighbour sum) with ghost-cell boundaries."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._checks import check_range
from . import _stencils
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
        boundary: "wrap" (toroidal) or "no-flux" (ghost cell = edge cell, as scipy's
            mode="reflect": pure diffusion conserves mass).

    Fields have shape (species, rows, cols); a growing lattice keeps its active region in
    the top-left corner of a fixed-capacity array, its ghost cells right after it.
    """

    stencil: str = eqx.field(static=True)
    boundary: str = eqx.field(static=True)

    def __init__(self, stencil: str = "nine-point", boundary: str = "wrap"):
        self.stencil = _stencils.normalise_stencil(stencil)
        self.boundary = _stencils.normalise_boundary(boundary)

    @property
    def spectral_radius(self) -> float:
        return _stencils.SPECTRAL_RADIUS[self.stencil]

    @property
    def ndim(self) -> int:
        return 2

    @property
    def supports_growth(self) -> bool:
        return True

    @property
    def description(self) -> str:
        return f"{self.stencil} stencil"

    def carry(self, fields, size, dynamic):
        p = _stencils.pad(fields, self.boundary)
        if dynamic:  # ghost cells along the active region's edges
            p = _stencils.repad(p, fields, size, self.boundary)
        return p

    def interior(self, carried):
        return carried[..., 1:-1, 1:-1]

    def diffusion(self, carried, rates):
        lap = _stencils.laplacian_padded(carried, self.stencil)
        return [rates[i] * lap[i] for i in range(lap.shape[0])]

    def write(self, carried, new, size, dynamic):
        if dynamic:
            # an active region inside the array: the new values go back into the carried
            # buffer in place, with the ghost cells along the region's edges as four lines
            # (a fresh padded copy here makes XLA:CPU fuse the update into the copy)
            return _stencils.repad(carried, new, size, self.boundary)
        return _stencils.pad(new, self.boundary)  # the whole array is the lattice

    def active_mask(self, shape, size):
        return _stencils.active_mask(shape, size)

    def apply(self, fields):
        return _stencils.laplacian_padded(_stencils.pad(jnp.asarray(fields), self.boundary), self.stencil)

    # ---- blocks of a growing lattice (the execution plans of `_plan`) --------------------
    def block(self, carried, rows: int, cols: int):
        """The carried layout of the top-left (rows, cols) block of the lattice."""
        return carried[..., : rows + 2, : cols + 2]

    def unblock(self, carried, block):
        """`carried` with a block computed by `block` written back into its corner."""
        return jax.lax.dynamic_update_slice(carried, block, (0,) * carried.ndim)


def as_domain(domain=None, *, stencil=None, boundary=None) -> AbstractDomain:
    """The domain of a run: `domain`, or a `Lattice` (the default domain) from the
    `stencil`/`boundary` shorthands.

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
    return Lattice("nine-point" if stencil is None else stencil, "wrap" if boundary is None else boundary)


def max_stable_dt(max_diffusion: float, stencil: str = "nine-point") -> float:
    """Largest dt for which explicit Euler on pure diffusion is stable on a square lattice
    with this stencil: dt * D * rho <= 2 (see `AbstractDomain.max_stable_dt`)."""
    check_range(max_diffusion, "max_diffusion", low=0.0)
    return Lattice(stencil).max_stable_dt(max_diffusion)


def laplacian(x, boundary: str = "wrap", stencil: str = "nine-point"):
    """The stencil's operator on `x` (..., rows, cols) with the given boundary: a discrete
    Laplacian (cells^-2), or for "moore" the neighbour sum (about 3 x the Laplacian)."""
    return Lattice(stencil, boundary).apply(x)

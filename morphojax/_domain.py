"""Domains: where the species diffuse, and the explicit-Euler limit that follows from it.

A model is its reaction; a domain is the space it runs on. The domain owns

- its diffusion operator (the Laplacian of a stencil on a lattice, and later anisotropic
  weights, a mesh's Laplace-Beltrami operator, the links between point cells),
- its stability limit: forward Euler on pure diffusion is stable while
  dt * D_max * rho <= 2, rho the spectral radius of the operator (the one place this
  limit is computed),
- its boundary handling and the layout the stepping loop carries (a lattice carries its
  fields with one ring of ghost cells).

A domain is an equinox Module, so a pytree: only its topology (stencil, boundary) is
static; numbers it may hold later (polarity, rate maps, a mesh's operator) are array
leaves that can be swept, vmapped and differentiated. The stepping loop talks to a domain
only through the methods of `AbstractDomain`.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from . import _lattice
from ._checks import check_range, is_concrete


class AbstractDomain(eqx.Module):
    """Base of every domain: a diffusion operator with its stability limit and its layout."""

    @property
    @abc.abstractmethod
    def spectral_radius(self) -> float:
        """Largest |eigenvalue| of the diffusion operator at unit rate (cells^-2)."""

    @property
    @abc.abstractmethod
    def ndim(self) -> int:
        """Number of spatial axes of the fields on this domain (2 for a lattice)."""

    @property
    @abc.abstractmethod
    def description(self) -> str:
        """A few words naming the operator, for messages ("nine-point stencil")."""

    # ---- what the stepping loop uses -------------------------------------------------
    @abc.abstractmethod
    def carry(self, fields: Array, size: Array, dynamic: bool) -> Array:
        """The layout carried through the loop for `fields` (species, *spatial) with the
        active region `size` (`dynamic`: the active region may be smaller than the array)."""

    @abc.abstractmethod
    def interior(self, carried: Array) -> Array:
        """The fields (species, *spatial) held in a carried layout."""

    @abc.abstractmethod
    def diffusion(self, carried: Array, rates) -> list:
        """Per species i, the diffusion term rates[i] * (operator applied to species i)."""

    @abc.abstractmethod
    def write(self, carried: Array, new: Array, size: Array, dynamic: bool) -> Array:
        """The carried layout holding `new` fields on the active region `size`."""

    @abc.abstractmethod
    def active_mask(self, shape, size) -> Array:
        """Boolean mask (of the spatial `shape`) of the active region `size`."""

    @abc.abstractmethod
    def apply(self, fields) -> Array:
        """The operator applied to plain fields (..., *spatial), the whole array active."""

    # ---- stability (final) ---------------------------------------------------------------
    def max_stable_dt(self, max_diffusion):
        """Largest dt for which forward Euler on pure diffusion is stable: dt * D * rho <= 2.

        A Python float for a concrete rate (inf for no diffusion); a JAX array for a traced
        one (inside `jit` or `grad`, e.g. a fit's time step that follows its parameters).
        """
        if not is_concrete(max_diffusion):
            d = jnp.asarray(max_diffusion)
            return jnp.where(d > 0, 2.0 / (self.spectral_radius * jnp.where(d > 0, d, 1.0)), jnp.inf)
        d = float(max_diffusion)
        return float("inf") if d <= 0 else 2.0 / (self.spectral_radius * d)

    def check_dt(self, dt: float, max_diffusion: float, *, who: str = "") -> None:
        """Raise a ValueError naming the largest stable dt when `dt` is beyond the limit."""
        limit = self.max_stable_dt(max_diffusion)
        if float(dt) > limit:
            raise ValueError(
                f"{who}dt = {float(dt):g} is beyond the explicit-Euler stability limit of the {self.description} "
                f"for the largest diffusion rate {float(max_diffusion):g}: the largest stable dt is {limit:.6g}. "
                "Use a smaller dt, or pass check_dt=False to run anyway."
            )


class Lattice(AbstractDomain):
    """The square lattice: a 3x3 stencil Laplacian with ghost-cell boundaries.

    Args:
        stencil: "nine-point" (the leopard paper's isotropic [[1,4,1],[4,-20,4],[1,4,1]]/6,
            spectral radius 16/3) or "five-point" ([[0,1,0],[1,-4,1],[0,1,0]], radius 8);
            both approximate the Laplacian in cells^-2.
        boundary: "wrap" (toroidal) or "no-flux" (ghost cell = edge cell, as scipy's
            mode="reflect": pure diffusion conserves mass).

    Fields have shape (species, rows, cols); a growing lattice keeps its active region in
    the top-left corner of a fixed-capacity array, its ghost cells right after it.
    """

    stencil: str = eqx.field(static=True)
    boundary: str = eqx.field(static=True)

    def __init__(self, stencil: str = "nine-point", boundary: str = "wrap"):
        self.stencil = _lattice.normalise_stencil(stencil)
        self.boundary = _lattice.normalise_boundary(boundary)

    @property
    def spectral_radius(self) -> float:
        return _lattice.SPECTRAL_RADIUS[self.stencil]

    @property
    def ndim(self) -> int:
        return 2

    @property
    def description(self) -> str:
        return f"{self.stencil} stencil"

    def carry(self, fields, size, dynamic):
        p = _lattice.pad(fields, self.boundary)
        if dynamic:  # ghost cells along the active region's edges
            p = _lattice.repad(p, fields, size, self.boundary)
        return p

    def interior(self, carried):
        return carried[..., 1:-1, 1:-1]

    def diffusion(self, carried, rates):
        lap = _lattice.laplacian_padded(carried, self.stencil)
        return [rates[i] * lap[i] for i in range(lap.shape[0])]

    def write(self, carried, new, size, dynamic):
        if dynamic:
            # an active region inside the array: the new values go back into the carried
            # buffer in place, with the ghost cells along the region's edges as four lines
            # (a fresh padded copy here makes XLA:CPU fuse the update into the copy)
            return _lattice.repad(carried, new, size, self.boundary)
        return _lattice.pad(new, self.boundary)  # the whole array is the lattice

    def active_mask(self, shape, size):
        return _lattice.active_mask(shape, size)

    def apply(self, fields):
        return _lattice.laplacian_padded(_lattice.pad(jnp.asarray(fields), self.boundary), self.stencil)

    # ---- blocks of a growing lattice (the execution plans of `_plan`) --------------------
    def block(self, carried, rows: int, cols: int):
        """The carried layout of the top-left (rows, cols) block of the lattice."""
        return carried[..., : rows + 2, : cols + 2]

    def unblock(self, carried, block):
        """`carried` with a block computed by `block` written back into its corner."""
        import jax

        return jax.lax.dynamic_update_slice(carried, block, (0,) * carried.ndim)


def as_domain(domain=None, *, stencil=None, boundary=None) -> AbstractDomain:
    """The domain of a run: `domain`, or a `Lattice` from the `stencil`/`boundary` shorthands.

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
    """Discrete Laplacian of `x` (..., rows, cols) with the given boundary and stencil."""
    return Lattice(stencil, boundary).apply(x)

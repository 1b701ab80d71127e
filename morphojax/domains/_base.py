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

from .._checks import is_concrete


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

    @property
    @abc.abstractmethod
    def supports_growth(self) -> bool:
        """Whether a growing state (matrix expansion, `growth=`) may run on this domain."""

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

    @property
    def expansion_copies(self) -> int:
        """Rows and columns one matrix expansion adds (each dividing cell's copies): 1 on
        the square lattice; a domain whose layout needs more says so (the hexagonal lattice)."""
        return 1

    def active_diffusion(self, carried: Array, rates, size: Array) -> list:
        """`diffusion` on a growing domain whose active region is `size`: the same, unless
        the operator depends on where the region ends (the hexagonal lattice's no-flux links)."""
        return self.diffusion(carried, rates)

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

"""Domains: where species diffuse. Each owns its operator, stability limit and layout.

`AbstractDomain` is the interface the stepping loop uses; `Lattice` is the square lattice
(nine- or five-point stencil, wrap or no-flux). New domains (hexagonal lattices,
anisotropic diffusion, triangle meshes, point cells) subclass `AbstractDomain` here.
"""

from ._base import AbstractDomain
from ._lattice import Lattice, as_domain, laplacian, max_stable_dt
from ._stencils import BOUNDARIES, STENCILS

__all__ = ["AbstractDomain", "as_domain", "BOUNDARIES", "laplacian", "Lattice", "max_stable_dt", "STENCILS"]

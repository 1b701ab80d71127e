"""Domains: where species diffuse. Each owns its operator, stability limit and layout.

`AbstractDomain` is the interface the stepping loop uses; `Lattice` is the square lattice
(nine- or five-point stencil or the thesis's Moore sum, wrap or no-flux), `HexLattice` the
hexagonal one (odd-r offset layout); on both, diffusion maps diffuse in the conservative
flux form and declared species anisotropically along a cell polarity (`_links`, thesis eqs.
4.7-4.8). New domains (anisotropic diffusion, triangle meshes,
point cells) subclass `AbstractDomain` here.
"""

from ._base import AbstractDomain
from ._hex import HexLattice
from ._lattice import Lattice, as_domain, laplacian, max_stable_dt
from ._links import Polarize, gradient_polarity
from ._mesh import Mesh
from ._stencils import BOUNDARIES, STENCILS

__all__ = ["AbstractDomain", "as_domain", "BOUNDARIES", "gradient_polarity", "HexLattice", "laplacian", "Lattice", "max_stable_dt", "Mesh", "Polarize", "STENCILS"]

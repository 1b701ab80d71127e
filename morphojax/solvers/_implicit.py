"""Implicit diffusion by conjugate gradients, where no transform diagonalises the operator.

IMEX on the hexagonal lattice, on meshes, and on square lattices whose rates are maps
(flux form) or follow fixed polarities, solves (I - a D L) u = r for each step's implicit
stages. These operators are symmetric in a weighted inner product: the identity on
lattices (the link form's w_ij D_ij is symmetric, eqs. 4.7-4.8 of the thesis), the lumped
mass on a mesh (L = M^-1 K, K symmetric). So the system is solved as the symmetric
positive-definite W (I - a D L) u = W r with `jax.scipy.sparse.linalg.cg`, matrix-free,
the domain's own operator applied once per iteration; its condition number is about
1 + a D rho, so the iterations grow like sqrt(a D rho). Gradients go through the solve by
implicit differentiation (JAX's `custom_linear_solve`). JAX's `cg` reports no
convergence flag: the solve stops at a relative residual of CG_TOL or after CG_MAXITER
iterations. CG's error falls about as exp(-2 k / sqrt(1 + a D rho)) in k iterations, so
CG_MAXITER reaches the tolerance up to a D rho of about 10^4 and loses digits beyond. The
residual is therefore measured once more after the solve (one operator application), and a
solve whose relative residual is above the square root of its tolerance (half its digits
lost: 1e-3 in float32, 1e-6 in float64) returns NaN: the run's status then names the step
where it happened, as for any blow-up, and its message says an implicit solve may be the
cause.
"""

from __future__ import annotations

import jax.numpy as jnp
import jax.scipy.sparse.linalg

from ..domains import HexLattice, Lattice, Mesh
from ..models import per_species
from ._base import reaction_and_limit

CG_TOL = 1e-6  # relative residual in float32, about its rounding (1e-12 in float64)
CG_MAXITER = 1000

# Ascher, Ruuth and Spiteri's IMEX (2,2,2) scheme (Appl. Numer. Math. 25, 1997): L-stable,
# stiffly accurate, second order, two implicit stages (here and on the transforms, `IMEX`).
ARS_GAMMA = 1.0 - 2.0 ** -0.5
ARS_DELTA = 1.0 - 1.0 / (2.0 * ARS_GAMMA)


def why_not_symmetric(domain, rates_shape: tuple) -> str | None:
    """None where the conjugate-gradient solve applies (for rates of `rates_shape`), else the reason."""
    if not isinstance(domain, (Lattice, HexLattice, Mesh)):
        return f"the {domain.description} is not a lattice or mesh"
    if getattr(domain, "follow", None) is not None:
        return ("a polarity that follows a reagent changes the operator within a step; give fixed angles, or use "
                "solver=mj.Euler()")
    if getattr(domain, "maps", "flux") == "pointwise" and any(n != 1 for n in rates_shape[1:]):
        return "pointwise rate maps D(x) lap u are not symmetric: use maps='flux' or solver=mj.Euler()"
    return None


def weights(domain, dtype):
    """The weights W that make the operator symmetric: the lumped masses on a mesh, else 1."""
    if isinstance(domain, Mesh):
        return (1.0 / domain.inverse_mass).astype(dtype)
    return jnp.ones((), dtype)


def make_solver(domain, shape):
    """solve(acting model, rhs, a, x0) -> u with (I - a D L) u = rhs, and apply(acting, u) -> D L u."""

    def apply(acting, u):
        size = jnp.asarray(shape, jnp.int32)
        rates = per_species(jnp.asarray(acting.diffusion()), domain.ndim)
        return jnp.stack(domain.diffusion(domain.carry(u, size, False), rates))

    def solve(acting, rhs, a, x0):
        w = weights(domain, rhs.dtype)

        def operator(u):
            return w * (u - a * apply(acting, u))

        tol = CG_TOL if rhs.dtype == jnp.float32 else 1e-12
        b = w * rhs
        u, _ = jax.scipy.sparse.linalg.cg(operator, b, x0=x0, tol=tol, maxiter=CG_MAXITER)
        residual = jnp.linalg.norm(jax.lax.stop_gradient(operator(u) - b))
        converged = residual <= tol**0.5 * jnp.linalg.norm(jax.lax.stop_gradient(b)) + jnp.finfo(b.dtype).tiny
        return jnp.where(converged, u, jnp.nan)  # a solve that did not converge blows the run up here

    return solve, apply


def make_advance(order: int, domain, dt, bounds, shape):
    """advance(acting model, x, h=dt, carried=None) -> x after one IMEX step of `order` (1:
    SBDF1, 2: ARS (2,2,2)) in cell space, each implicit stage solved by conjugate gradients
    (`carried` is not needed: the operator is applied to x as the solves apply it)."""
    solve, apply = make_solver(domain, shape)

    def advance(acting, x, h=dt, carried=None):
        reaction, limit = reaction_and_limit(acting, bounds, domain.ndim)
        nx = reaction(x)
        if order == 1:  # (1 - h L) x1 = x + h N(x)
            return solve(acting, x + h * nx, h, x)
        g, d = ARS_GAMMA, ARS_DELTA
        u1 = solve(acting, x + h * g * nx, g * h, x)
        n1 = reaction(limit(u1))
        rhs = x + (1.0 - g) * h * apply(acting, u1) + h * (d * nx + (1.0 - d) * n1)
        return solve(acting, rhs, g * h, u1)

    return advance

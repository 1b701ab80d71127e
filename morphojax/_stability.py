"""Linear stability of a model's homogeneous state on a domain's own operator: the
dispersion relation, mode by mode.

    d = mj.dispersion(mj.Turing(ratio=12, scale=3), mj.Lattice(), (64, 64))
    d.turing_unstable, d.fastest_wavelength      # True, about 14 cells
    d.rates                                      # one growth rate per mode of the 64 x 64 torus

Around a homogeneous steady state x* a small perturbation p obeys dp/dt = J p + D L p, J the
reaction's Jacobian at x*, D = diag(diffusion rates) and L the domain's operator. Every
eigenvector of L (eigenvalue mu <= 0) is a mode whose species' amplitudes evolve by the
small matrix J + mu D: its growth rate is the largest real part of that matrix's
eigenvalues. The modes are the domain's own, so a prediction is about the lattice that is
simulated, not the continuum:

- on a `Lattice`, the stencil's exact eigenvalues (`Lattice.eigenvalues`: the FFT's waves for
  "wrap", the DCT-II's cosines for "no-flux"), laid out as the coefficients of
  `Lattice.transform`; a mode's wavelength is that of its wave, in cells;
- on a `Mesh`, the lowest `modes` eigenvalues of the Laplace-Beltrami operator, from the
  generalised problem (D - W) phi = mu M phi with the lumped masses M (scipy's shift-invert
  Lanczos, in NumPy outside `jit`); a mode's wavelength is 2 pi / sqrt(-mu), the
  continuum's relation, in the mesh's length unit (exact for plane waves, about the
  circumference over l for the sphere's degree-l harmonics);
- on a `HexLattice`, every eigenvalue of its operator from the dense matrix (NumPy, at most
  `HEX_CELLS` cells), with the wavelength 2 pi / sqrt(-mu) in cell spacings.

The operator's modes are computed once in NumPy from the domain's static layout; the rest
(steady state, Jacobian, rates) is JAX, so `jax.vmap` over model parameters works (the
fields of `Dispersion` are arrays) and `turing_space` maps whole parameter planes.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .domains import AbstractDomain, HexLattice, Lattice, Mesh
from .domains import _stencils
from .models import AbstractModel
from .models._steady import local_jacobian, solve, tolerance

MESH_MODES = 64  # lowest Laplace-Beltrami modes a mesh's dispersion uses by default
HEX_CELLS = 4096  # largest hexagonal lattice whose operator is diagonalised densely


class Dispersion(eqx.Module):
    """The linear stability of a model's homogeneous state on a domain (see `dispersion`).

    Every field is an array, so a `Dispersion` passes through `jax.jit` and `jax.vmap`
    (a vmapped one has a leading member axis on each field).

    Attributes:
        steady_state: (species,) the homogeneous steady state within the limits
            (`AbstractModel.homogeneous_state`; NaN-free even where `converged` is False:
            then it is where Newton's method stopped, and nothing below is valid).
        converged: () whether Newton's method found that state; where it did not, the rates
            and the fastest wavelength are NaN and `turing_unstable` is False.
        at_limit: (species,) whether the state sits on (or beyond) a species' saturation
            limit. The linearisation leaves the limits out: see `dispersion` for what the
            rates mean then.
        jacobian: (species, species) d reaction_i / d x_j at the state.
        diffusion: (species,) the diffusion rates at the state.
        eigenvalues: (*modes) the operator's eigenvalue of each mode (<= 0, length^-2).
        wavelengths: (*modes) each mode's wavelength (cells on lattices, the mesh's unit on
            meshes; inf for the uniform mode).
        rates: (*modes) each mode's growth rate: the largest real part of the eigenvalues
            of jacobian + eigenvalue x diag(diffusion) (per unit time).
        kinetic_rate: () the uniform mode's rate without diffusion: the largest real part of
            the Jacobian's eigenvalues (< 0: stable without diffusion).
        fastest_rate: () the largest of `rates`.
        fastest_wavelength: () the wavelength of the fastest-growing mode, NaN when every
            mode decays (inf when the uniform mode grows fastest).
        turing_unstable: () True when the state is stable without diffusion
            (kinetic_rate < 0) and some mode grows with it (fastest_rate > 0).
    """

    steady_state: Array
    converged: Array
    at_limit: Array
    jacobian: Array
    diffusion: Array
    eigenvalues: Array
    wavelengths: Array
    rates: Array
    kinetic_rate: Array
    fastest_rate: Array
    fastest_wavelength: Array
    turing_unstable: Array

    def curve(self, wavenumbers) -> Array:
        """Growth rates for the continuum Laplacian's modes exp(i k x) of these angular
        wavenumbers (radians per cell, or per mesh unit): the dispersion curve to plot
        beside the domain's own `rates` (which a coarse lattice bends away from it: the
        nine-point stencil's eigenvalue is -k^2 + O(k^4))."""
        k = jnp.asarray(wavenumbers, self.jacobian.dtype)
        return largest_real_part(self.jacobian, self.diffusion, -(k * k))

    def python(self) -> dict:
        """The scalar results as plain Python values (for one, not vmapped, dispersion)."""
        return {"steady_state": [float(v) for v in np.asarray(self.steady_state)],
                "converged": bool(self.converged), "at_limit": [bool(v) for v in np.asarray(self.at_limit)],
                "kinetic_rate": float(self.kinetic_rate), "fastest_rate": float(self.fastest_rate),
                "fastest_wavelength": float(self.fastest_wavelength), "turing_unstable": bool(self.turing_unstable)}


def largest_real_part(jacobian, diffusion, mu) -> Array:
    """The largest real part of the eigenvalues of jacobian + mu diag(diffusion), for every
    operator eigenvalue in `mu` (any shape): closed forms for one and two species (the
    trace and determinant of the 2 x 2 matrix), `jnp.linalg.eigvals` beyond."""
    n = jacobian.shape[-1]
    mu = jnp.asarray(mu, jacobian.dtype)
    if n == 1:
        return jacobian[0, 0] + mu * diffusion[0]
    if n == 2:
        a = jacobian[0, 0] + mu * diffusion[0]
        d = jacobian[1, 1] + mu * diffusion[1]
        half = 0.5 * (a + d)
        disc = half * half - (a * d - jacobian[0, 1] * jacobian[1, 0])
        # complex roots: the real part is half the trace (a finite square root on both
        # branches keeps gradients finite where disc <= 0)
        return half + jnp.where(disc > 0, jnp.sqrt(jnp.where(disc > 0, disc, 1.0)), 0.0)
    m = jacobian + mu[..., None, None] * jnp.diag(diffusion)
    return jnp.max(jnp.real(jnp.linalg.eigvals(m)), axis=-1)


# ---- the domain's modes (NumPy, outside jit) -------------------------------------------------
def operator_modes(domain: AbstractDomain, shape=None, modes: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(eigenvalues, wavelengths) of the domain's operator, one per mode (float64 NumPy):
    see the module docstring for each kind of domain. `shape` is the lattice's (rows, cols)
    (one length per axis); `modes` the number of a mesh's lowest modes."""
    if modes is not None and not isinstance(domain, Mesh):
        raise ValueError(f"dispersion: modes= counts a Mesh's lowest modes; a {type(domain).__name__} uses every mode "
                         "of its shape")
    if isinstance(domain, Lattice):
        return _lattice_modes(domain, shape)
    if isinstance(domain, Mesh):
        if shape is not None and tuple(np.atleast_1d(shape)) != (domain.n_vertices,):
            raise ValueError(f"dispersion: a Mesh's modes live on its {domain.n_vertices} vertices; leave shape out "
                             f"(got {shape!r})")
        return _mesh_modes(domain, MESH_MODES if modes is None else modes)
    if isinstance(domain, HexLattice):
        return _hex_modes(domain, shape)
    raise ValueError(f"dispersion: no modes for a {type(domain).__name__}; domains: Lattice, Mesh, HexLattice")


def _lattice_shape(domain, shape, who="Lattice"):
    if shape is None:
        raise ValueError(f"dispersion on a {who} needs its shape: dispersion(model, domain, shape=(rows, cols)), "
                         "the lattice the model runs on (the modes are that lattice's own)")
    shape = tuple(int(n) for n in np.atleast_1d(shape))
    if len(shape) != domain.ndim or min(shape) < 1:
        raise ValueError(f"dispersion: the {domain.description} needs a shape of {domain.ndim} positive lengths "
                         f"(got {shape})")
    return shape


def _lattice_modes(domain: Lattice, shape):
    if domain.anisotropic and domain.polarised_cells:
        raise ValueError("dispersion: an anisotropic (polarised) Lattice is not diagonalised by its stencil's "
                         "waves; give the isotropic Lattice(stencil=..., boundary=...)")
    shape = _lattice_shape(domain, shape)
    eig = np.asarray(_stencils.eigenvalues(domain.stencil, domain.boundary, shape), float)
    freq2 = np.zeros(eig.shape)
    for axis, n in enumerate(shape):  # cycles per cell along each axis, laid out as the eigenvalues
        if domain.boundary == "wrap":
            f = np.fft.rfftfreq(n) if axis == len(shape) - 1 else np.fft.fftfreq(n)
        else:
            f = np.arange(n) / (2.0 * n)  # cos(pi k (x + 1/2) / n): period 2 n / k cells
        freq2 = freq2 + f.reshape([-1 if a == axis else 1 for a in range(len(shape))]) ** 2
    with np.errstate(divide="ignore"):
        return eig, np.where(freq2 > 0, 1.0 / np.sqrt(freq2), np.inf)


def _continuum_wavelengths(eig, scale):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(-eig > 1e-9 * scale, 2.0 * np.pi / np.sqrt(np.maximum(-eig, 0.0)), np.inf)


def _mesh_modes(domain: Mesh, modes: int):
    import scipy.sparse as sp
    from scipy.sparse.linalg import eigsh

    from .domains._mesh_build import weight_matrix

    modes = int(modes)
    if not 1 <= modes < domain.n_vertices:
        raise ValueError(f"dispersion: modes must lie in [1, {domain.n_vertices - 1}] for this mesh (got {modes})")
    w = weight_matrix(np.asarray(domain.neighbours), _combined_weights(domain))
    degree = np.asarray(w.sum(1)).ravel()
    root = sp.diags(np.sqrt(np.asarray(domain.inverse_mass, np.float64)))
    sym = (root @ (sp.diags(degree) - w) @ root).tocsc()  # similar to -L = M^-1 (D - W): same eigenvalues
    sym = 0.5 * (sym + sym.T)
    shift = -1e-6 * domain.rho  # just below the zero eigenvalue: sym - shift is positive definite
    values = eigsh(sym, k=modes, sigma=shift, which="LM", return_eigenvectors=False)
    eig = -np.sort(np.maximum(values, 0.0))  # the uniform mode (0) first, then ever faster decay
    return eig, _continuum_wavelengths(eig, domain.rho)


def _combined_weights(domain: Mesh) -> np.ndarray:
    """The operator's weights (K, V) in float64, the anisotropy's parts combined as the step
    combines them."""
    w = np.asarray(domain.weights, np.float64)
    if domain.directional is not None:
        w = float(domain.across) * w + (float(domain.along) - float(domain.across)) * np.asarray(domain.directional,
                                                                                                   np.float64)
    return w


def _hex_modes(domain: HexLattice, shape):
    shape = _lattice_shape(domain, shape, "HexLattice")
    domain.check_shape(shape)
    cells = math.prod(shape)
    if cells > HEX_CELLS:
        raise ValueError(f"dispersion on a HexLattice diagonalises its operator densely: at most {HEX_CELLS} cells "
                         f"(got {shape[0]} x {shape[1]} = {cells}); the modes of a smaller lattice give the same "
                         "curve")
    with jax.ensure_compile_time_eval():
        impulses = jnp.eye(cells, dtype=jnp.float32).reshape((cells,) + shape)
        matrix = np.asarray(domain.apply(impulses), np.float64).reshape(cells, cells).T
    eig = np.sort(np.real(np.linalg.eigvals(matrix)))[::-1]  # descending: the uniform mode (0) first
    eig = np.minimum(eig, 0.0)
    return eig, _continuum_wavelengths(eig, domain.spectral_radius)


# ---- the dispersion relation (JAX: jit, vmap) -----------------------------------------------
def dispersion(model: AbstractModel, domain: AbstractDomain | None = None, shape=None, *, modes: int | None = None,
               guess=None) -> Dispersion:
    """The linear stability of `model`'s homogeneous state on `domain`'s own modes.

    Args:
        model: any model with one diffusion rate per species (no parameter or rate maps).
        domain: a `Lattice` (default `Lattice()`: nine-point, wrap; isotropic), a `Mesh` or
            a `HexLattice` (at most `HEX_CELLS` cells).
        shape: the lattice's (rows, cols) (one length per axis on 1D and 3D lattices):
            the modes are those of that lattice. Not given for a mesh.
        modes: a mesh's number of lowest Laplace-Beltrami modes (default `MESH_MODES`).
        guess: a starting point for the steady state (one value per species), for models
            with several (see `AbstractModel.homogeneous_state`).

    Returns a `Dispersion` (arrays only: works under `jax.jit` and `jax.vmap` over the
    model's parameters; the domain's modes are computed once, in NumPy, from its layout).

    Saturation limits are left out of the linearisation: the Jacobian is the reaction's,
    and the clamp, which is not differentiable, is not in it. The steady state itself
    respects them (a species may be held on a limit by a reaction pushing past it), and
    `at_limit` says where it sits on one. There the rates are an upper bound of what the
    run does: a species held strictly (its reaction pushes past the limit) does not move
    at all for small perturbations; one on a limit where its reaction vanishes (the
    leopard paper's Fig. 4 rows with Ua = 4 or Lb = 4, whose limit is the state itself)
    follows the linear rates on one side of the limit and is cut on the other, so half of
    every growing wave is clipped flat from the first step. Away from the limits (every
    other Fig. 4 row) the clamp is inactive near the state and the rates are exact for
    small perturbations.

    Gradients: `jax.grad` of `rates`, `fastest_rate` or `curve(k)` with respect to the
    model's parameters works (the steady state differentiates by the implicit function
    theorem, see `models/_steady.py`); `fastest_wavelength` is piecewise constant on a
    lattice's discrete modes, so its gradient is zero: differentiate `curve` for a smooth
    one.

    Forward Euler adds its own factor: a mode of rate r grows by 1 + dt r per step, which is
    exp(r dt) to first order in dt; the fastest mode is the same.
    """
    domain = Lattice() if domain is None else domain
    if not isinstance(model, AbstractModel):
        raise ValueError(f"dispersion: model must be a morphojax model such as mj.Turing(...) (got {model!r})")
    if not isinstance(domain, AbstractDomain):
        raise ValueError(f"dispersion: domain must be a morphojax domain such as mj.Lattice() (got {domain!r})")
    eig, wavelengths = operator_modes(domain, shape, modes)
    return linear_stability(model, eig, wavelengths, guess)


def linear_stability(model: AbstractModel, eig, wavelengths, guess=None) -> Dispersion:
    """The `Dispersion` of `model` for the operator eigenvalues `eig` and their modes'
    `wavelengths` (NumPy arrays of one shape; from `operator_modes`). JAX throughout."""
    x, ok, _ = solve(model, guess)
    if x.size != model.n_species:
        raise ValueError(f"dispersion: {type(model).__name__} has parameter maps (its steady state has shape "
                         f"{tuple(x.shape)}); the dispersion relation is for one homogeneous state: use scalar "
                         "parameters")
    x = x.reshape(model.n_species)
    ok = ok.reshape(())
    here = model.at(x.reshape((-1, 1, 1)))
    rates_d = jnp.asarray(here.diffusion())
    if rates_d.shape != (model.n_species,):
        raise ValueError(f"dispersion: {type(model).__name__} has diffusion maps (rates of shape "
                         f"{tuple(rates_d.shape)}); the modes need one rate per species")
    rates_d = rates_d.astype(x.dtype)
    jac = local_jacobian(model.reaction, x.reshape((-1, 1, 1))).reshape(model.n_species, model.n_species)
    lo, hi = (jnp.broadcast_to(jnp.asarray(v, x.dtype).reshape(-1), x.shape) for v in (model.lower, model.upper))
    near = tolerance(x.dtype) * (1.0 + jnp.abs(x))
    at_limit = (x <= lo + near) | (x >= hi - near)
    mu = jnp.asarray(eig, x.dtype)
    lengths = jnp.asarray(wavelengths, x.dtype)
    nan = jnp.asarray(jnp.nan, x.dtype)
    rates = jnp.where(ok, largest_real_part(jac, rates_d, mu), nan)
    kinetic = jnp.where(ok, largest_real_part(jac, rates_d, jnp.zeros((), x.dtype)), nan)
    fastest = jnp.argmax(jnp.where(jnp.isnan(rates), -jnp.inf, rates))
    top = rates.reshape(-1)[fastest]
    wavelength = jnp.where(top > 0, lengths.reshape(-1)[fastest], nan)
    return Dispersion(steady_state=x, converged=ok, at_limit=at_limit, jacobian=jac, diffusion=rates_d,
                      eigenvalues=mu, wavelengths=lengths, rates=rates, kinetic_rate=kinetic, fastest_rate=top,
                      fastest_wavelength=wavelength, turing_unstable=ok & (kinetic < 0) & (top > 0))

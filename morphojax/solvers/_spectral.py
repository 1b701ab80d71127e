"""Exponential (ETDRK) and implicit-explicit (IMEX) steps on the stencil's own eigenbasis.

On a lattice (1D, 2D or 3D) with uniform rates, diffusion is the linear operator L = D_i S for
species i, S the stencil, and S is diagonal in a known basis: the FFT for "wrap" (one
complex FFT per pair of species, see `_basis`) and the DCT-II for "no-flux"
(`Lattice.eigenvalues`, exact for the stencil). There each mode
evolves by its eigenvalue z / dt with z = dt D_i lambda <= 0, so diffusion can be taken
exactly (exponential time differencing, Cox and Matthews, J. Comput. Phys. 176, 2002) or
implicitly, and only the reaction N is explicit. dt is then bounded by the reaction's
accuracy and stability, not by dt D rho <= 2.

Every step reads the reaction in cell space and the diffusion in the eigenbasis, so its
cost is a few transforms (counted per solver below); a transform costs several Euler
steps on a CPU, which is why a larger step must pay for them.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._bounds import Barrier
from .._checks import check_count, check_finite, check_range
from ..domains import Lattice
from ..models import AbstractModel, per_species
from . import _implicit
from ._base import AbstractSolver, rate_shape, reaction_and_limit
from ._basis import Eigenbasis
from ._phi import phi


def _state_dependent(model) -> bool:
    """Whether the model's parameters (and so perhaps its rates) follow the state."""
    return type(model).at is not AbstractModel.at


def _diagonal(domain, model, fields=None) -> bool:
    """Whether the transforms diagonalise the operator: a Lattice, isotropic, one rate per species."""
    if not isinstance(domain, Lattice) or (domain.polarised_cells and domain.anisotropic):
        return False
    return all(n == 1 for n in rate_shape(model, fields)[1:])


def _fields_like(model, shape, dtype):
    """A stand-in for the fields a step advances (their shape and dtype only)."""
    return jax.ShapeDtypeStruct((model.n_species,) + tuple(shape), dtype)


def _rate_vector(model):
    """The per-species diffusion rates as a (species,) vector (uniform rates only)."""
    rates = jnp.asarray(model.diffusion())
    return rates.reshape(rates.shape[0])


class _TransformSolver(AbstractSolver):
    """Shared by ETDRK and IMEX: their settings, where they run, and the step's plumbing."""

    order: int = eqx.field(static=True)
    rtol: float | None = eqx.field(static=True)  # None: a fixed step
    atol: float | None = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)  # attempts of an adaptive run, at most

    def _configure(self, orders: tuple, order, rtol, atol, max_steps) -> None:
        """Check and set the settings (from a subclass's __init__); only order 2 has an
        embedded estimate for adaptive steps."""
        if isinstance(order, bool) or order not in orders:
            allowed = ", ".join(map(str, orders[:-1])) + f" or {orders[-1]}"
            raise ValueError(f"{self.name}.order must be {allowed} (got {order!r})")
        self.order = int(order)
        self.rtol, self.atol = _check_tolerances(self.name, self.order, (2,), rtol, atol)
        check_count(max_steps, f"{self.name}.max_steps", "attempted steps", low=1)
        self.max_steps = int(max_steps)

    def check(self, domain, model, *, dynamic: bool, sources: tuple, fields=None, bounds="clip") -> None:
        who = f"solver={self.name}(order={self.order})"
        _check_run(who, dynamic, sources, bounds)
        if not isinstance(domain, Lattice):
            raise ValueError(f"{who} runs on the Lattice (1D, 2D or 3D), whose stencil the FFT or DCT diagonalises; the "
                             f"{domain.description} has no such basis: use solver=mj.Euler() there")
        if domain.polarised_cells and domain.anisotropic:
            raise ValueError(f"{who} needs isotropic diffusion: anisotropic links are not diagonal in the FFT/DCT "
                             "basis; use solver=mj.Euler()")
        shape = rate_shape(model, fields)
        if any(n != 1 for n in shape[1:]):
            raise ValueError(f"{who} needs one diffusion rate per species; {type(model).__name__} diffuses with a "
                             f"rate map of shape {shape}, which the FFT/DCT basis does not diagonalise: use "
                             "solver=mj.Euler()")

    def to_dict(self) -> dict:
        data = {"solver": self.name, "order": self.order}
        return {**data, "rtol": self.rtol, "atol": self.atol, "max_steps": self.max_steps} if self.adaptive else data

    def check_dt(self, domain, dt, model) -> None:
        # diffusion is exact (ETDRK) or implicit (IMEX): no diffusion limit. The reaction's
        # own limit depends on the state and is not checked; a blow-up is reported with its step.
        return None

    @property
    def adaptive(self) -> bool:
        """Whether the step size follows an embedded error estimate (`rtol` given)."""
        return self.rtol is not None

    @property
    def packs(self) -> bool:
        """Whether pairs of species share one complex FFT on "wrap" (`_basis`): where the
        step multiplies once per transform."""
        return False

    def make_advance(self, model, domain: Lattice, dt, bounds, shape):
        """advance(acting model, x, h=dt, carried=None) -> x after one step of h, before
        sources and the clamp; with `adaptive`, (x after the step, the embedded lower-order
        estimate). `carried`, the step's carried (ghost-padded) layout of x, gives the
        stencil at x from the ghost cells the loop already holds, as Euler reads it: without
        it x is padded again (measured on fig4-r40 50x50: three more kernels a step)."""
        basis = Eigenbasis(domain, shape, model.n_species, pack=self.packs)
        lam = jnp.asarray(basis.eigenvalues, dt.dtype)
        ndim = domain.ndim

        def coefficients(m, h):
            z = h * _rate_vector(m).reshape((-1,) + (1,) * ndim) * lam
            return basis.multipliers(self.coefficients(z, h))

        # a fixed step's coefficients are computed once, outside the loop
        fixed = None if self.adaptive or _state_dependent(model) else coefficients(model, dt)

        def advance(acting, x, h=dt, carried=None):
            reaction, limit = reaction_and_limit(acting, bounds, ndim)
            rates = per_species(_rate_vector(acting), ndim)

            def euler_rate():  # reaction + diffusion at x, the stencil applied in cell space
                if carried is None:
                    return reaction(x) + rates * domain.apply(x)
                return reaction(x) + jnp.stack(domain.diffusion(carried, rates))

            co = fixed if fixed is not None else coefficients(acting, h)
            high, low = self.advance(co, x, reaction, euler_rate, basis.fwd, basis.inv, limit)
            return (high, low) if self.adaptive else high

        return advance


def _check_run(who: str, dynamic: bool, sources: tuple, bounds) -> None:
    """What no transform or conjugate-gradient step supports, whatever the domain."""
    if dynamic:
        raise ValueError(f"{who} steps a fixed lattice: a growing state's active region changes size, which a "
                         "fixed operator solve cannot follow. Run growing phases with solver=mj.Euler() (an "
                         "Experiment can give each phase its own solver)")
    if sources:
        raise ValueError(f"{who}: sources add a fixed amount per step, so their total would change with dt; "
                         "run phases with sources with solver=mj.Euler()")
    if isinstance(bounds, Barrier):
        raise ValueError(f"{who}: the barrier's rational terms are stiff and explicit in every solver, so they allow "
                         "only Euler's barrier step (about 20x below clip's, leopard paper section 5.4), and a larger "
                         "step can cross a limit without a NaN; use bounds='clip' or solver=mj.Euler()")


def _check_tolerances(who: str, order: int, embedded: tuple, rtol, atol):
    """(rtol, atol) as floats or (None, None); an error where the order has no embedded pair."""
    if rtol is None and atol is None:
        return None, None
    if order not in embedded:
        raise ValueError(f"{who}(order={order}) has no embedded error estimate for adaptive steps; adaptive "
                         f"stepping needs order {' or '.join(map(str, embedded))}")
    rtol = 1e-3 if rtol is None else rtol
    atol = 1e-6 if atol is None else atol
    for name, value in (("rtol", rtol), ("atol", atol)):
        check_finite(value, f"{who}.{name}")
        check_range(value, f"{who}.{name}", low=0.0, low_open=True)  # atol 0 divides 0 by 0 on a zero species
    return float(rtol), float(atol)


class ETDRK(_TransformSolver):
    """Exponential time differencing with Runge-Kutta stages (Cox and Matthews 2002),
    diffusion exact on the stencil's eigenvalues, the reaction explicit.

    order=1: x + F^-1[dt phi_1(z) F(R(x))], R the Euler rate (2 transforms a step);
    order=2: Cox-Matthews ETD2RK (4 transforms); order=4: ETDRK4 in Kassam and
    Trefethen's form (9 transforms). The phi-functions (`_phi`) are accurate to float32
    rounding at the zero mode and every other eigenvalue. Exact for pure diffusion at any dt, and with the reaction
    accurate to the given order in dt. Runs on the `Lattice` (1D, 2D or 3D) with one
    diffusion rate per species, isotropic, without growth or sources (use `Euler` there).

    Adaptive steps (order 2): with `rtol` (and `atol`, default 1e-6) the step size follows
    the embedded ETD1 estimate, which is the scheme's own first stage and costs nothing:
    `steps * dt` is then the simulated time to reach and `dt` the first step, a step whose
    error norm exceeds 1 is retried smaller inside the compiled loop (see
    `_adaptive.make_attempt` for the norm), and at most `max_steps` attempts are made.
    """

    def __init__(self, order: int = 2, *, rtol: float | None = None, atol: float | None = None,
                 max_steps: int = 100_000):
        self._configure((1, 2, 4), order, rtol, atol, max_steps)

    @property
    def packs(self) -> bool:
        return self.order <= 2

    def coefficients(self, z, dt):
        if self.order == 1:
            return {"p1": dt * phi(z, 1)}
        if self.order == 2:
            return {"p1": dt * phi(z, 1), "p2": dt * phi(z, 2)}
        p1, p2, p3 = phi(z, 1), phi(z, 2), phi(z, 3)
        return {"E": jnp.exp(z), "E2": jnp.exp(z / 2), "Q": dt / 2 * phi(z / 2, 1),
                "f1": dt * (p1 - 3 * p2 + 4 * p3), "f2": dt * (p2 - 2 * p3), "f3": dt * (4 * p3 - p2)}

    def advance(self, co, x, reaction, euler_rate, fwd, inv, limit):
        """(the step, its embedded lower-order estimate or None); `euler_rate()` is reaction
        + diffusion at x, `limit` clamps a stage before the reaction is evaluated on it."""
        if self.order == 1:
            return x + inv(co["p1"] * fwd(euler_rate())), None
        if self.order == 2:  # the first stage is ETD1: the embedded estimate comes free
            nx = reaction(x)
            a = x + inv(co["p1"] * fwd(euler_rate()))
            return a + inv(co["p2"] * fwd(reaction(limit(a)) - nx)), a
        v = fwd(x)
        nv = fwd(reaction(x))
        a = co["E2"] * v + co["Q"] * nv
        na = fwd(reaction(limit(inv(a))))
        b = co["E2"] * v + co["Q"] * na
        nb = fwd(reaction(limit(inv(b))))
        c = co["E2"] * a + co["Q"] * (2 * nb - nv)
        nc = fwd(reaction(limit(inv(c))))
        return inv(co["E"] * v + co["f1"] * nv + 2 * co["f2"] * (na + nb) + co["f3"] * nc), None




class IMEX(_TransformSolver):
    """Implicit diffusion, explicit reaction, solved exactly on the stencil's eigenbasis.

    order=1: backward Euler for diffusion, forward Euler for the reaction (SBDF1):
    x + F^-1[dt / (1 - z) F(R(x))] (2 transforms a step); order=2: the L-stable IMEX
    (2,2,2) Runge-Kutta scheme of Ascher, Ruuth and Spiteri (5 transforms). Unconditionally
    stable in diffusion; damps the fastest modes where ETDRK is exact. Runs where `ETDRK`
    runs by the transforms, and by conjugate gradients on the other symmetric operators:
    the hexagonal lattice, meshes, flux-form rate maps and fixed polarities (`_implicit`).

    Adaptive steps (order 2): with `rtol` (and `atol`, default 1e-6) the step size follows
    the difference from an IMEX1 step from the same state (two transforms more a step),
    as for `ETDRK`.
    """

    def __init__(self, order: int = 2, *, rtol: float | None = None, atol: float | None = None,
                 max_steps: int = 100_000):
        self._configure((1, 2), order, rtol, atol, max_steps)

    def check(self, domain, model, *, dynamic: bool, sources: tuple, fields=None, bounds="clip") -> None:
        """The transforms where they apply; conjugate gradients on other symmetric operators."""
        if _diagonal(domain, model, fields):
            return super().check(domain, model, dynamic=dynamic, sources=sources, fields=fields, bounds=bounds)
        who = f"solver=IMEX(order={self.order})"
        _check_run(who, dynamic, sources, bounds)
        reason = _implicit.why_not_symmetric(domain, rate_shape(model, fields))
        if reason is not None:
            raise ValueError(f"{who}: {reason}")
        if self.adaptive:
            raise ValueError(f"{who}: adaptive steps use the transforms (a Lattice with one rate per species); on "
                             f"the {domain.description} give a fixed dt")

    def make_advance(self, model, domain, dt, bounds, shape):
        if _diagonal(domain, model, _fields_like(model, shape, dt.dtype)):
            return super().make_advance(model, domain, dt, bounds, shape)
        return _implicit.make_advance(self.order, domain, dt, bounds, shape)

    @property
    def packs(self) -> bool:
        return self.order == 1

    def coefficients(self, z, dt):
        if self.order == 1:
            return {"h": dt / (1.0 - z)}
        co = {"z": z, "solve": 1.0 / (1.0 - _implicit.ARS_GAMMA * z), "dt": dt}
        return {**co, "h": dt / (1.0 - z)} if self.adaptive else co

    def advance(self, co, x, reaction, euler_rate, fwd, inv, limit):
        """(the step, its embedded lower-order estimate or None), as `ETDRK.advance`."""
        if self.order == 1:
            return x + inv(co["h"] * fwd(euler_rate())), None
        g, d, h = _implicit.ARS_GAMMA, _implicit.ARS_DELTA, co["dt"]
        v = fwd(x)
        nx = reaction(x)
        u1 = co["solve"] * (v + h * g * fwd(nx))
        n1 = reaction(limit(inv(u1)))
        u2 = co["solve"] * (v + (1.0 - g) * co["z"] * u1 + h * fwd(d * nx + (1.0 - d) * n1))
        # the embedded estimate, when asked for: IMEX1 (SBDF1) from the same x, two transforms more
        low = x + inv(co["h"] * fwd(euler_rate())) if self.adaptive else None
        return inv(u2), low

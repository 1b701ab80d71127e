"""Solvers as policies: how a step advances the reaction and the diffusion over dt.

As in diffrax, the solver is a small object passed in (`simulate(..., solver=...)`); the
model stays its reaction and the domain its operator. `Euler` is the default and the
reference: forward Euler on reaction + diffusion, the leopard paper's method (section 7),
whose step is bounded by the diffusion limit dt * D_max * rho <= 2. The exponential and
implicit solvers of `_spectral` lift that limit by treating diffusion exactly or
implicitly on the stencil's own eigenbasis.

Whatever the solver, the saturation limits are a clamp after every step, sources add
their amount after it, and a growth expansion follows it: those stay the paper's
per-iteration rules.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._bounds import Barrier
from ..models import AbstractModel, per_species


class AbstractSolver(eqx.Module):
    """Base of the time-stepping policies. Each has an `order`: its order of accuracy in dt
    with the limits not binding."""

    order: eqx.AbstractVar[int]

    @property
    def name(self) -> str:
        return type(self).__name__

    @property
    def adaptive(self) -> bool:
        """Whether the step size follows an error estimate (then `steps * dt` is the time to
        reach and `dt` the first step)."""
        return False

    @abc.abstractmethod
    def check(self, domain, model, *, dynamic: bool, sources: tuple, fields=None, bounds="clip") -> None:
        """Raise a ValueError, saying what to use instead, where this solver cannot run
        (`fields`, or anything with their shape and dtype: the state it will step)."""

    @abc.abstractmethod
    def check_dt(self, domain, dt, model) -> None:
        """Raise a ValueError when `dt` is beyond this solver's own stability criterion."""

    def to_dict(self) -> dict:
        return {"solver": self.name, "order": self.order}


class Euler(AbstractSolver):
    """Forward Euler: x + dt (reaction + D lap x), the papers' method and the default.

    Stable while dt * D_max * rho <= 2 (rho the operator's spectral radius, e.g. 16/3 for
    the nine-point stencil); `simulate` checks this unless `check_dt=False`. Runs on every
    domain, with growth, sources, diffusion maps and anisotropy. First order.
    """

    order: int = eqx.field(static=True, default=1, init=False)

    def check(self, domain, model, *, dynamic: bool, sources: tuple, fields=None, bounds="clip") -> None:
        return None

    def check_dt(self, domain, dt, model) -> None:
        domain.check_dt(dt, _max_diffusion(model))


_MAX_DIFFUSION: dict = {}  # model.max_diffusion() by the model's structure and parameter values
_KEYED_VALUES = 65_536  # parameters a key may hold; larger models are not kept


def _max_diffusion(model) -> float:
    """`model.max_diffusion()`, worked out once for each structure and parameter values:
    it evaluates the rates eagerly, which cost more than the rest of a short run's checks.
    A model with a traced or unhashable leaf, or more than `_KEYED_VALUES` values, is
    evaluated each time."""
    leaves, treedef = jax.tree_util.tree_flatten(model)
    if any(isinstance(leaf, jax.core.Tracer) for leaf in leaves) or sum(
            int(np.size(leaf)) for leaf in leaves) > _KEYED_VALUES:
        return model.max_diffusion()
    try:
        key = (treedef, tuple(_value_key(leaf) for leaf in leaves))
        value = _MAX_DIFFUSION.get(key)
    except (TypeError, ValueError):  # a leaf or static field that cannot be read or hashed
        return model.max_diffusion()
    if value is None:
        if len(_MAX_DIFFUSION) >= 256:
            _MAX_DIFFUSION.clear()
        value = _MAX_DIFFUSION[key] = model.max_diffusion()
    return value


def _value_key(leaf):
    if not isinstance(leaf, (jax.Array, np.ndarray, np.generic)):
        return leaf
    values = np.asarray(leaf)
    return values.shape, values.dtype.str, values.tobytes()


def reaction_and_limit(acting, bounds, ndim: int):
    """(reaction(y), limit(y)) of a step's stages: the model's reaction with a `Barrier`'s
    terms, and the clamp to the limits with "clip". Stages are clamped as a step would be,
    so the reaction is only ever evaluated inside the limits (measured on fig4-r40 at dt
    0.3: unclamped stages gave labyrinths where Euler gives spots)."""
    lower, upper = per_species(acting.lower, ndim), per_species(acting.upper, ndim)
    barrier = bounds if isinstance(bounds, Barrier) else None

    def reaction(y):
        r = acting.reaction(y)
        return jnp.stack([r[i] + (barrier.terms(y[i], lower[i], upper[i]) if barrier is not None else 0.0)
                          for i in range(y.shape[0])])

    def limit(y):
        return jnp.clip(y, lower, upper) if bounds == "clip" else y

    return reaction, limit


_RATE_SHAPES: dict = {}  # rate_shape's answers by the model's structure and leaf shapes (and the fields')


def rate_shape(model, fields=None) -> tuple:
    """The shape of the diffusion rates a step uses: `model.diffusion()`'s, or, for a model
    whose parameters follow the state (`Modulated`), that of `model.at(fields).diffusion()`,
    worked out from `fields`' shape alone (a state-set rate may be a map where the model's
    own is a number).

    A shape depends on the model's tree structure and its leaves' shapes and dtypes only,
    so it is worked out once for each of those (each run checks it: computing the rates
    eagerly cost more than the rest of a short run's checks)."""
    follows = fields is not None and type(model).at is not AbstractModel.at
    leaves, treedef = jax.tree_util.tree_flatten(model)
    key = (treedef, tuple((leaf.shape, leaf.dtype) if hasattr(leaf, "shape") and hasattr(leaf, "dtype") else leaf
                          for leaf in leaves),
           (tuple(jnp.shape(fields)), jnp.result_type(fields)) if follows else None)
    try:
        return _RATE_SHAPES[key]
    except TypeError:  # a leaf or static field that cannot be hashed: not kept
        return _rate_shape(model, fields, follows)
    except KeyError:
        pass
    if len(_RATE_SHAPES) >= 256:
        _RATE_SHAPES.clear()
    shape = _RATE_SHAPES[key] = _rate_shape(model, fields, follows)
    return shape


def _rate_shape(model, fields, follows: bool) -> tuple:
    if not follows:
        return tuple(jnp.shape(model.diffusion()))
    struct = jax.ShapeDtypeStruct(tuple(jnp.shape(fields)), jnp.result_type(fields))
    return tuple(jax.eval_shape(lambda x: model.at(x).diffusion(), struct).shape)


def as_solver(solver) -> AbstractSolver:
    """`solver`, or `Euler()` for None; anything else is refused by name."""
    if solver is None:
        return Euler()
    if not isinstance(solver, AbstractSolver):
        raise ValueError(f"solver must be mj.Euler(), mj.ETDRK(order=1|2|4) or mj.IMEX(order=1|2) (got {solver!r})")
    return solver

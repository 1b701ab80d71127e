"""A user's own reaction: `Reaction(fn, params, diffusion, species=...)`, any number of species.

    def schnakenberg(x, p):
        u, v = x
        return jnp.stack([p["a"] - u + u * u * v, p["b"] - u * u * v])

    model = mj.Reaction(schnakenberg, {"a": 0.1, "b": 0.9}, diffusion=(0.5, 10.0), species=("u", "v"))

`fn(x, params)` gets the stacked state `x` of shape (species, rows, cols) and the dict of
parameters (JAX arrays) and returns the reaction part of dx/dt: an array of x's shape, or a
sequence with one array per species. It must be written with `jax.numpy`, so that the run
compiles and `jax.jit`, `jax.vmap` and `jax.grad` go through it and its parameters like
through a built-in model's.

Files: the function is code, not data. A result, phase or sweep saved with a `Reaction`
is written (its arrays and its model's numbers: "params", "rates", "lower", "upper"), with,
in place of the function, {"function": "module.qualname", "species": [...], "resumable":
false}; reading the model back from such a file (`mj.model_from_dict`, resuming an
experiment, `mj.load_sweep`) raises a ValueError that says so. To go on, rebuild
`Reaction(fn, saved["params"], saved["rates"], species=..., lower=..., upper=...)` with the
same function and run it from the saved arrays (`mj.load_npz`).
"""

from __future__ import annotations

import math
from typing import Callable, ClassVar, Mapping

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from .._checks import as_float_array, check_finite, check_range
from ._base import LETTERS, AbstractModel, check_limits, species_stack

_LIMIT_KINDS = ("diffusion", "lower", "upper")  # per-species parameters: diffusion_a, lower_b, ...


class ReactionFunction:
    """A user's reaction function and the species it acts on, callable as `fn(x, params)`.
    Two are equal when they wrap the same function for the same species, which is what a
    compiled run is cached by. `describe()` is what files hold in its place."""

    def __init__(self, fn: Callable, species: tuple[str, ...]):
        self.fn = fn
        self.species = tuple(species)
        self.name = f"{getattr(fn, '__module__', None) or '?'}.{getattr(fn, '__qualname__', None) or repr(fn)}"

    def describe(self) -> dict:
        """The plain-data stand-in for the function: it cannot be rebuilt from a file."""
        return {"function": self.name, "species": list(self.species), "resumable": False,
                "why": "a user-written reaction function is code, not data: rebuild the model "
                       "with mj.Reaction(fn, params, ...) to rerun or resume"}

    def __call__(self, x, params):
        return self.fn(x, params)

    def __eq__(self, other):
        return isinstance(other, ReactionFunction) and other.fn == self.fn and other.species == self.species

    def __hash__(self):
        return hash((self.fn, self.species))


class Reaction(AbstractModel):
    """A reaction-diffusion model from a user-written reaction function (see the module
    docstring for `fn`'s form and for files).

        dx_i/dt = fn(x, params)_i + D_i lap(x_i)      for each species i

    params: a dict of name -> number or array (a scalar, or a (rows, cols) parameter map);
        they become JAX array leaves, so `parameters()`, `replace()`, sweeps, fits, `vmap`
        and `grad` see them by these names.
    diffusion: one rate per species (cells^2 per unit time; scalars or maps), or a single
        rate for all; its parameters are named `diffusion_a`, `diffusion_b`, ...
    species: the species' names (default "a", "b", ... as many as `diffusion` has rates).
    lower, upper: the saturation limits per species (`lower_a`, `upper_b`, ...), clamped
        after every step; the default [0, +inf) keeps concentrations non-negative (give
        -inf for species whose values go negative).
    """

    # The species are per instance, held with the function (static: they fix the shapes);
    # a ClassVar annotation keeps this property out of the dataclass fields.
    species: ClassVar[tuple[str, ...]] = property(lambda self: self.fn.species)  # type: ignore[assignment]
    fn: ReactionFunction = eqx.field(static=True)
    params: dict[str, Array]
    rates: Array
    lower: Array
    upper: Array

    def __init__(self, fn, params=None, diffusion=None, species=None, lower=0.0, upper=math.inf, *, rates=None):
        # `rates` is the field's own name (what a saved model holds)
        if not callable(fn):
            raise ValueError(f"Reaction.fn must be a function fn(x, params) -> dx/dt (got {fn!r})")
        diffusion = rates if rates is not None else diffusion
        if species is None and isinstance(fn, ReactionFunction):
            species = fn.species
        if diffusion is None:
            raise ValueError("Reaction.diffusion is required: one diffusion rate per species (cells^2 per unit time)")
        if species is None:
            if not isinstance(diffusion, (tuple, list)) and jnp.ndim(diffusion) != 1:
                raise ValueError("Reaction needs species=(names...) or one diffusion rate per species")
            species = LETTERS[: len(diffusion)]
        species = tuple(str(s) for s in species)
        if not species or len(set(species)) != len(species):
            raise ValueError(f"Reaction.species must be distinct names, at least one (got {species!r})")
        n = len(species)
        if n > len(LETTERS):
            raise ValueError(f"Reaction.species: at most {len(LETTERS)} species (got {n})")
        params = {} if params is None else params
        if not isinstance(params, Mapping):
            raise ValueError(f"Reaction.params must be a dict of name -> number or array (got {type(params).__name__})")
        out = {}
        for key, value in params.items():
            if not isinstance(key, str) or not key.isidentifier():
                raise ValueError(f"Reaction.params: names must be identifiers (got {key!r})")
            if key in _LIMIT_KINDS or key.partition("_")[0] in _LIMIT_KINDS:
                raise ValueError(f"Reaction.params: the name {key!r} is taken by the per-species "
                                 "parameters (diffusion_a, lower_a, upper_a, ...); choose another")
            out[key] = as_float_array(value, f"Reaction.params[{key!r}]")
        self.fn = ReactionFunction(fn.fn if isinstance(fn, ReactionFunction) else fn, species)
        self.params = out
        self.rates = species_stack(diffusion, n, "Reaction.diffusion")
        self.lower = species_stack(lower, n, "Reaction.lower")
        self.upper = species_stack(upper, n, "Reaction.upper")

    def __check_init__(self):
        for key, value in self.params.items():
            check_finite(value, f"Reaction.params[{key!r}]")
        check_finite(self.rates, "Reaction.diffusion")
        check_range(self.rates, "Reaction.diffusion (a diffusion rate)", low=0.0)
        check_limits(self)
        n = len(self.species)
        probe = jax.ShapeDtypeStruct((n, 1, 1), self.rates.dtype)
        try:
            shape = jax.eval_shape(self.reaction, probe).shape
        except Exception as err:  # the user's function failed on a state of the right layout
            raise ValueError(f"Reaction.fn failed on a state of shape (species={n}, rows, cols): "
                             f"{type(err).__name__}: {err}") from err
        if len(shape) != 3 or shape[0] != n:
            raise ValueError(f"Reaction.fn must return dx/dt of the state's shape (species={n}, rows, cols); "
                             f"for a state of shape {(n, 1, 1)} it returned shape {shape}")

    def reaction(self, x):
        out = self.fn(x, self.params)
        if isinstance(out, (tuple, list)):
            out = jnp.stack(jnp.broadcast_arrays(*out))
        return out

    def diffusion(self):
        return self.rates

    def parameters(self) -> dict[str, Array]:
        """The user's parameters by their names, then `diffusion_a`, ..., `lower_a`, ...,
        `upper_a`, ... (a = first species)."""
        out = dict(self.params)
        for kind, arr in (("diffusion", self.rates), ("lower", self.lower), ("upper", self.upper)):
            out.update({f"{kind}_{LETTERS[i]}": arr[i] for i in range(len(self.species))})
        return out

    def replace(self, **changes) -> "Reaction":
        """A copy with some parameters changed, by the names of `parameters()`; per-species
        ones also by species name (`lower_v`) or whole (`diffusion=(1, 20)`). Works with
        traced values (inside vmap/grad)."""
        params = dict(self.params)
        per = {"diffusion": list(self.rates), "lower": list(self.lower), "upper": list(self.upper)}
        for key, value in changes.items():
            if key in params:
                params[key] = value
            elif key in per:
                per[key] = list(species_stack(value, len(self.species), f"Reaction.{key}"))
            else:
                kind, _, who = key.partition("_")
                idx = self._species_index(who) if kind in per and who else None
                if idx is None:
                    raise ValueError(f"Reaction has no parameter {key!r}; parameters: {', '.join(self.parameters())}")
                per[kind][idx] = value
        return Reaction(self.fn, params, tuple(per["diffusion"]), species=self.species,
                        lower=tuple(per["lower"]), upper=tuple(per["upper"]))

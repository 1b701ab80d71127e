"""The bases of every model: `AbstractModel` (a reaction, per-species diffusion rates and
saturation limits) and `AbstractReaction` (the single models: parameters by field name,
limits per species), with the per-species helpers they share and the two that every single
model's `__init__` and `__check_init__` are made of (`set_parameters`, `check_parameters`).

Every model is a final equinox Module whose numeric parameters are JAX array leaves, so
`jax.jit`, `jax.vmap` and `jax.grad` see them as ordinary inputs. A parameter may be a
scalar or an array broadcastable to the lattice (rows, cols): a spatial "parameter map".

A model acts on a stacked array `x` of shape (species, rows, cols) and provides

- `reaction(x)`: the reaction part of d x / dt, same shape as `x`;
- `diffusion()`: the diffusion rate of each species, shape (species,) or (species, rows, cols);
- `lower`, `upper`: the saturation limits, same layout as `diffusion()`.

Units: time is simulated time (steps x dt); lengths are lattice cells, so a diffusion rate
D means d x / dt = D * laplacian(x) with the Laplacian in cells^-2.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._checks import as_float_array, check_finite, check_range, is_concrete
from ._steady import homogeneous_values

LETTERS = "abcdefghijklmnopqrstuvwxyz"


def species_stack(values, n: int, name: str):
    """Stack per-species values (scalars or maps) into one array with a leading species axis.

    A single value (scalar or map) is used for every species. The result has shape
    (n,) for scalars or (n, rows, cols) when any entry is a map.
    """
    if isinstance(values, (tuple, list)):
        if len(values) != n:
            raise ValueError(f"{name} needs {n} values, one per species (got {len(values)})")
        arrays = [as_float_array(v, f"{name}[{i}]") for i, v in enumerate(values)]
    else:
        arr = as_float_array(values, name)
        if arr.ndim >= 1 and arr.shape[0] == n and arr.ndim in (1, 3):
            return arr
        arrays = [arr] * n
    try:
        shape = jnp.broadcast_shapes(*(a.shape for a in arrays))
    except ValueError as err:
        raise ValueError(f"{name}: the per-species maps have incompatible shapes {[a.shape for a in arrays]}") from err
    if len(shape) not in (0, 2):
        raise ValueError(f"{name} entries must be scalars or (rows, cols) maps (got shape {shape})")
    return jnp.stack([jnp.broadcast_to(a, shape) for a in arrays])


def per_species(arr: Array, ndim: int = 2) -> Array:
    """Reshape a (species,) parameter so it broadcasts against (species, rows, cols)."""
    return arr.reshape(arr.shape + (1,) * ndim) if arr.ndim == 1 else arr


def check_limits(model) -> None:
    check_finite(model.lower, f"{type(model).__name__}.lower", allow_inf="-")
    check_finite(model.upper, f"{type(model).__name__}.upper", allow_inf="+")
    if is_concrete(model.lower, model.upper):
        lower, upper = np.asarray(model.lower), np.asarray(model.upper)
        lo = lower.reshape(lower.shape + (1, 1)) if lower.ndim == 1 else lower
        hi = upper.reshape(upper.shape + (1, 1)) if upper.ndim == 1 else upper
        shape = np.broadcast_shapes(lo.shape, hi.shape)
        lo, hi = np.broadcast_to(lo, shape), np.broadcast_to(hi, shape)
        bad = (lo > hi).reshape(shape[0], -1)
        if bad.any():
            idx, cell = (int(v) for v in np.argwhere(bad)[0])
            raise ValueError(
                f"{type(model).__name__}: lower must be <= upper for every species; species "
                f"{model.species[idx]!r} has lower {lo.reshape(shape[0], -1)[idx, cell]:g} "
                f"> upper {hi.reshape(shape[0], -1)[idx, cell]:g}"
            )


def set_parameters(model, lower, upper, **values) -> None:
    """In a single model's `__init__`: each parameter field named in `values` set to its
    value as a float array, and `lower`, `upper` to one limit per species. Errors name
    `Class.name`, an aliased field by its public name (`Reinforcement.diffusion`)."""
    who = type(model).__name__
    public = {field: name for name, field in model.ALIASES.items()}
    for field, value in values.items():
        setattr(model, field, as_float_array(value, f"{who}.{public.get(field, field)}"))
    model.lower = species_stack(lower, len(model.species), f"{who}.lower")
    model.upper = species_stack(upper, len(model.species), f"{who}.upper")


def check_parameters(model, *fields: str, low: float | None = None, low_open: bool = False, note: str = "",
                     allow_inf: str | None = None) -> None:
    """In a single model's `__check_init__`: each named parameter field, one after the other,
    finite (infinities as `allow_inf` lets, see `check_finite`) and, with `low`, >= low (>
    low with `low_open`). Errors name `Class.name` (an aliased field by its public name),
    the range's followed by " (note)" where a note is given."""
    who = type(model).__name__
    public = {field: name for name, field in model.ALIASES.items()}
    for field in fields:
        name, value = f"{who}.{public.get(field, field)}", getattr(model, field)
        check_finite(value, name, allow_inf=allow_inf)
        if low is not None:
            check_range(value, f"{name} ({note})" if note else name, low=low, low_open=low_open)


class AbstractModel(eqx.Module):
    """Base of every model: a reaction, per-species diffusion rates and saturation limits."""

    species: eqx.AbstractClassVar[tuple[str, ...]]
    lower: eqx.AbstractVar[Array]
    upper: eqx.AbstractVar[Array]

    @abc.abstractmethod
    def reaction(self, x: Array) -> Array:
        """Reaction part of dx/dt for a stacked state `x` of shape (species, ...)."""

    @abc.abstractmethod
    def diffusion(self) -> Array:
        """Diffusion rate per species (cells^2 per unit time), shape (species,) or (species, rows, cols)."""

    def at(self, x: Array) -> "AbstractModel":
        """The model as it acts on the stacked state `x` (species, ...): itself, unless its
        parameters follow the state (`Modulated`). A step takes its reaction, rates and
        limits from it."""
        return self

    @property
    def n_species(self) -> int:
        return len(self.species)

    def _species_index(self, who: str):
        """The index of a species named by its name (`u`) or its letter (`a` = first), else None."""
        if who in self.species:
            return self.species.index(who)
        if len(who) == 1 and who in LETTERS[: self.n_species]:
            return LETTERS.index(who)
        return None

    # ---- the homogeneous steady state (linear stability, steady starts) ----------------
    def unclamped_state(self) -> tuple | None:
        """A homogeneous state where the reaction alone vanishes, limits left out, in
        closed form (one value per species), or None where the model has none (then
        `homogeneous_state` starts Newton's method from 1 per species, or a guess)."""
        return None

    def homogeneous_state(self, guess=None) -> tuple:
        """The homogeneous steady state within the saturation limits, one value per species
        (scalars; one per cell for a model with parameter maps).

        A state is steady under the clamped step when, for each species, the reaction
        vanishes strictly inside the limits, or the species sits on a limit and the
        reaction pushes past it (so the clamp holds it there). Where the model has a
        closed form (`unclamped_state`) inside the limits, that is the answer; otherwise a
        damped semismooth Newton method finds one (under `jit` and `vmap` too), starting
        from `guess` (one value per species), the closed form or 1 per species, clipped
        into the limits (see `morphojax/models/_steady.py`). Several states may exist:
        `guess` picks the nearest one Newton's method reaches. Differentiable in the
        parameters (by the implicit function theorem).

        Raises a ValueError (an equinox runtime error inside `jit`) when no steady state
        within the limits was found, for example when the reaction's own state lies beyond
        a limit and pushes back inside it: the clamp then holds nothing still.
        """
        return homogeneous_values(self, guess)

    # ---- parameters by name (sweeps, fitting, saving) -------------------------------
    @abc.abstractmethod
    def parameters(self) -> dict[str, Array]:
        """All numeric parameters by name (the names sweeps, fits and files use)."""

    @abc.abstractmethod
    def replace(self, **changes) -> "AbstractModel":
        """A copy with some parameters changed, by the names of `parameters()`; works with
        traced values (inside vmap/grad)."""

    def max_diffusion(self):
        """Largest diffusion rate anywhere on the lattice (concrete values only; evaluated
        eagerly even while tracing, so the stability check also runs inside `jax.jit`)."""
        with jax.ensure_compile_time_eval():
            return float(np.max(np.asarray(self.diffusion())))


class AbstractReaction(AbstractModel):
    """Base of the single models: every non-static field is a parameter, under its own
    name or an alias (`ALIASES`, for a field whose natural name is taken by a method), and
    the limits are named per species: `lower_a`, `upper_b`, ... (a = first species)."""

    ALIASES: ClassVar[dict[str, str]] = {}  # public name -> field name

    def parameters(self) -> dict[str, Array]:
        """All numeric parameters by name; limits as `lower_a`, `upper_b`, ... (a = first species)."""
        public = {field: name for name, field in self.ALIASES.items()}
        out = {public.get(name, name): getattr(self, name) for name in self._scalar_fields()}
        for kind in ("lower", "upper"):
            arr = getattr(self, kind)
            for i in range(self.n_species):
                out[f"{kind}_{LETTERS[i]}"] = arr[i]
        return out

    def replace(self, **changes) -> "AbstractModel":
        """A copy with some parameters changed, by the names of `parameters()`.

        Limits can be given per species (`lower_b=2.0`, or by species name, `upper_u=...`)
        or whole (`lower=(0, 2)`). Works with traced values (inside vmap/grad).
        """
        fields = {name: getattr(self, name) for name in self._scalar_fields()}
        limits = {"lower": list(self.lower), "upper": list(self.upper)}
        for key, value in changes.items():
            key = self.ALIASES.get(key, key)
            if key in fields:
                fields[key] = value
            elif key in limits:
                limits[key] = value
            else:
                kind, _, who = key.partition("_")
                idx = self._species_index(who) if kind in limits and who else None
                if idx is None:
                    raise ValueError(
                        f"{type(self).__name__} has no parameter {key!r}; "
                        f"parameters: {', '.join(self.parameters())}"
                    )
                if not isinstance(limits[kind], list):
                    limits[kind] = list(species_stack(limits[kind], self.n_species, kind))
                limits[kind][idx] = value
        return type(self)(**fields, lower=_as_tuple(limits["lower"]), upper=_as_tuple(limits["upper"]))

    @classmethod
    def _scalar_fields(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls)
                     if f.name not in ("lower", "upper") and not f.metadata.get("static"))


def _as_tuple(values):
    return tuple(values) if isinstance(values, list) else values

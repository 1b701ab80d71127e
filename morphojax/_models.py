"""Reaction-diffusion models: the reaction terms, diffusion rates and saturation limits.

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
import math
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._checks import as_float_array, check_finite, check_range, is_concrete

_LETTERS = "abcdefghijklmnopqrstuvwxyz"


def _species_stack(values, n: int, name: str):
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


def _check_limits(model) -> None:
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

    @property
    def n_species(self) -> int:
        return len(self.species)

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
                out[f"{kind}_{_LETTERS[i]}"] = arr[i]
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
                    limits[kind] = list(_species_stack(limits[kind], self.n_species, kind))
                limits[kind][idx] = value
        return type(self)(**fields, lower=_as_tuple(limits["lower"]), upper=_as_tuple(limits["upper"]))

    def _species_index(self, who: str):
        if who in self.species:
            return self.species.index(who)
        if len(who) == 1 and who in _LETTERS[: self.n_species]:
            return _LETTERS.index(who)
        return None

    @classmethod
    def _scalar_fields(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls)
                     if f.name not in ("lower", "upper") and not f.metadata.get("static"))


def _as_tuple(values):
    return tuple(values) if isinstance(values, list) else values


def bard_reaction(x: Array, alpha, beta, sp) -> Array:
    """Turing's reaction as written by Bard and Lauder: sp(alpha - ab), sp(ab - b - beta)."""
    a, b = x[0], x[1]
    ab = a * b
    return jnp.stack([sp * (alpha - ab), sp * (ab - b - beta)])


class Bard(AbstractReaction):
    """Bard-Lauder / Turk form of Turing's reaction (thesis eqs. 4.5-4.6):

        da/dt = sp (alpha - a b) + Da lap(a)
        db/dt = sp (a b - b - beta) + Db lap(b)

    `sp` scales the reaction speed (the thesis's `s`), `da`/`db` are diffusion rates in
    cells^2 per unit time. `lower`/`upper` clamp (a, b) after every step.
    """

    species: ClassVar[tuple[str, ...]] = ("a", "b")
    alpha: Array
    beta: Array
    sp: Array
    da: Array
    db: Array
    lower: Array
    upper: Array

    def __init__(self, alpha=16.0, beta=12.0, sp=1.0, da=0.04, db=0.01, lower=0.0, upper=math.inf):
        self.alpha = as_float_array(alpha, "Bard.alpha")
        self.beta = as_float_array(beta, "Bard.beta")
        self.sp = as_float_array(sp, "Bard.sp")
        self.da = as_float_array(da, "Bard.da")
        self.db = as_float_array(db, "Bard.db")
        self.lower = _species_stack(lower, 2, "Bard.lower")
        self.upper = _species_stack(upper, 2, "Bard.upper")

    def __check_init__(self):
        for name in ("alpha", "beta", "sp"):
            check_finite(getattr(self, name), f"Bard.{name}")
        for name in ("da", "db"):
            check_finite(getattr(self, name), f"Bard.{name}")
            check_range(getattr(self, name), f"Bard.{name} (a diffusion rate)", low=0.0)
        _check_limits(self)

    def reaction(self, x):
        return bard_reaction(x, self.alpha, self.beta, self.sp)

    def diffusion(self):
        return _species_stack((self.da, self.db), 2, "Bard diffusion")


class Turing(AbstractReaction):
    """The leopard paper's bounded Turing model (eqs. 3-4):

        da/dt = 16 - a b + r s lap(a)
        db/dt = a b - b - 12 + s lap(b)

    i.e. `Bard(alpha=16, beta=12, sp=1, da=r*s, db=s)`: see `as_bard`. `ratio` r = Da/Db
    sets the kind of pattern, `scale` s = Db its size. `lower`/`upper` are (La, Lb) and
    (Ua, Ub); the defaults 0 and +inf give the paper's b >= 0 requirement.
    """

    species: ClassVar[tuple[str, ...]] = ("a", "b")
    ratio: Array
    scale: Array
    lower: Array
    upper: Array

    ALPHA: ClassVar[float] = 16.0
    BETA: ClassVar[float] = 12.0

    def __init__(self, ratio=4.0, scale=3.0, lower=0.0, upper=math.inf):
        self.ratio = as_float_array(ratio, "Turing.ratio")
        self.scale = as_float_array(scale, "Turing.scale")
        self.lower = _species_stack(lower, 2, "Turing.lower")
        self.upper = _species_stack(upper, 2, "Turing.upper")

    def __check_init__(self):
        check_finite(self.ratio, "Turing.ratio")
        check_finite(self.scale, "Turing.scale")
        check_range(self.ratio, "Turing.ratio (Da/Db, a diffusion ratio)", low=0.0)
        check_range(self.scale, "Turing.scale (Db, a diffusion rate)", low=0.0)
        _check_limits(self)

    def as_bard(self) -> Bard:
        """The same model in the general Bard form: sp = 1, Da = r s, Db = s."""
        return Bard(
            alpha=self.ALPHA, beta=self.BETA, sp=1.0, da=self.ratio * self.scale, db=self.scale,
            lower=self.lower, upper=self.upper,
        )

    def reaction(self, x):  # Bard's reaction with alpha = 16, beta = 12, sp = 1
        return bard_reaction(x, self.ALPHA, self.BETA, 1.0)

    def diffusion(self):  # Bard's (Da, Db) = (r s, s)
        return _species_stack((self.ratio * self.scale, self.scale), 2, "Turing diffusion")


class GrayScott(AbstractReaction):
    """Gray-Scott model (Pearson 1993):

        du/dt = Du lap(u) - u v^2 + F (1 - u)
        dv/dt = Dv lap(v) + u v^2 - (F + k) v
    """

    species: ClassVar[tuple[str, ...]] = ("u", "v")
    feed: Array
    kill: Array
    du: Array
    dv: Array
    lower: Array
    upper: Array

    def __init__(self, feed=0.0367, kill=0.0649, du=0.2097, dv=0.105, lower=0.0, upper=math.inf):
        self.feed = as_float_array(feed, "GrayScott.feed")
        self.kill = as_float_array(kill, "GrayScott.kill")
        self.du = as_float_array(du, "GrayScott.du")
        self.dv = as_float_array(dv, "GrayScott.dv")
        self.lower = _species_stack(lower, 2, "GrayScott.lower")
        self.upper = _species_stack(upper, 2, "GrayScott.upper")

    def __check_init__(self):
        for name in ("feed", "kill", "du", "dv"):
            check_finite(getattr(self, name), f"GrayScott.{name}")
            check_range(getattr(self, name), f"GrayScott.{name}", low=0.0)
        _check_limits(self)

    def reaction(self, x):
        u, v = x[0], x[1]
        uvv = u * v * v
        return jnp.stack([-uvv + self.feed * (1.0 - u), uvv - (self.feed + self.kill) * v])

    def diffusion(self):
        return _species_stack((self.du, self.dv), 2, "GrayScott diffusion")


class Reinforcement(AbstractReaction):
    """Single-reagent reinforcement (leopard paper eq. 6):

        dc/dt = gamma (t - w - c)(t - c)(t + w - c) + Dc lap(c),  gamma = 3 sqrt(3) / (2 w^2)

    Concentrations in (t - w, t) are pushed down towards t - w and those in (t, t + w) up
    towards t + w, with -w and +w as the extreme rates: borders stay sharp while the
    regions keep their shape under growth.
    """

    species: ClassVar[tuple[str, ...]] = ("c",)
    ALIASES: ClassVar[dict[str, str]] = {"diffusion": "diffusion_rate"}  # `diffusion()` is the method
    threshold: Array
    width: Array
    diffusion_rate: Array
    lower: Array
    upper: Array

    def __init__(self, threshold=5.0, width=5.0, diffusion=1.0, lower=0.0, upper=math.inf, *, diffusion_rate=None):
        if diffusion_rate is not None:  # the field's own name, used by `replace`
            diffusion = diffusion_rate
        self.threshold = as_float_array(threshold, "Reinforcement.threshold")
        self.width = as_float_array(width, "Reinforcement.width")
        self.diffusion_rate = as_float_array(diffusion, "Reinforcement.diffusion")
        self.lower = _species_stack(lower, 1, "Reinforcement.lower")
        self.upper = _species_stack(upper, 1, "Reinforcement.upper")

    def __check_init__(self):
        check_finite(self.threshold, "Reinforcement.threshold")
        check_finite(self.width, "Reinforcement.width")
        check_range(self.width, "Reinforcement.width", low=0.0, low_open=True)
        check_finite(self.diffusion_rate, "Reinforcement.diffusion")
        check_range(self.diffusion_rate, "Reinforcement.diffusion (a diffusion rate)", low=0.0)
        _check_limits(self)

    @property
    def gamma(self):
        return 3.0 * math.sqrt(3.0) / (2.0 * self.width**2)

    def reaction(self, x):
        c = x[0]
        t, w = self.threshold, self.width
        return (self.gamma * (t - w - c) * (t - c) * (t + w - c))[None]

    def diffusion(self):
        return _species_stack(self.diffusion_rate, 1, "Reinforcement diffusion")



class Composite(AbstractModel):
    """Several models acting side by side on consecutive species of one state.

    `Composite((Turing(...), Reinforcement(...)))` evolves species (a, b) by the Turing
    model and species c by reinforcement, as in the leopard's development phase. Species
    names are the parts' names unless `species` is given.
    """

    parts: tuple[AbstractModel, ...]
    names: tuple[str, ...] = eqx.field(static=True)

    def __init__(self, parts, species=None):
        parts = tuple(parts)
        if not parts or not all(isinstance(p, AbstractModel) for p in parts):
            raise ValueError("Composite.parts must be a non-empty sequence of models")
        self.parts = parts
        names = tuple(species) if species is not None else tuple(n for p in parts for n in p.species)
        if len(names) != sum(p.n_species for p in parts):
            raise ValueError(f"Composite.species needs {sum(p.n_species for p in parts)} names (got {len(names)})")
        if len(set(names)) != len(names):
            names = tuple(f"{n}{i}" for i, n in enumerate(names))
        self.names = names

    @property
    def species(self):  # type: ignore[override]
        return self.names

    def _split(self, x):
        out, start = [], 0
        for p in self.parts:
            out.append(x[start : start + p.n_species])
            start += p.n_species
        return out

    @staticmethod
    def _cat(arrays):
        shape = jnp.broadcast_shapes(*(a.shape[1:] for a in arrays))
        return jnp.concatenate([jnp.broadcast_to(a, a.shape[:1] + shape) for a in arrays])

    def reaction(self, x):
        return jnp.concatenate([p.reaction(xi) for p, xi in zip(self.parts, self._split(x))])

    def diffusion(self):
        return self._cat([p.diffusion() for p in self.parts])

    @property
    def lower(self):  # type: ignore[override]
        return self._cat([p.lower for p in self.parts])

    @property
    def upper(self):  # type: ignore[override]
        return self._cat([p.upper for p in self.parts])

    def parameters(self):
        return {f"{i}.{k}": v for i, p in enumerate(self.parts) for k, v in p.parameters().items()}

    def replace(self, **changes):
        per_part: dict[int, dict] = {}
        for key, value in changes.items():
            head, _, rest = key.partition(".")
            if not head.isdigit() or int(head) >= len(self.parts):
                raise ValueError(f"Composite parameters are named 'PART.NAME' (got {key!r}); see parameters()")
            per_part.setdefault(int(head), {})[rest] = value
        parts = tuple(p.replace(**per_part[i]) if i in per_part else p for i, p in enumerate(self.parts))
        return Composite(parts, species=self.names)


MODELS = {"turing": Turing, "bard": Bard, "gray-scott": GrayScott, "reinforcement": Reinforcement}


def model_from_name(name: str, **params) -> AbstractModel:
    """Build a model from its command-line name (`turing`, `bard`, `gray-scott`, `reinforcement`)."""
    key = name.lower().replace("_", "-")
    if key == "grayscott":
        key = "gray-scott"
    if key not in MODELS:
        raise ValueError(f"unknown model {name!r}; allowed: {', '.join(MODELS)}")
    model = MODELS[key]()
    return model.replace(**params) if params else model

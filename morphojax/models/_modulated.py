"""Parameter modulation (thesis section 5.3): a model's parameter set, cell by cell, from a
reagent's concentration through a clamped linear map.

    signal = Morphogen(production=producer_cell, removal=0.001, diffusion=0.05)
    model = Modulated(Composite((Bard(...), signal)),
                      Modulation("0.sp", by="r", low=0.2, high=3.0, out_low=0.005, out_high=0.03))

Every step, each `Modulation` maps the current concentration of its reagent `by` from
[low, high] onto [out_low, out_high] (clamped at both ends, as the thesis's `map` action)
and the wrapped model runs with that (rows, cols) map as its parameter `parameter` (a name
of the wrapped model's `parameters()`). A reaction parameter (a scale) changes the
reaction; a diffusion rate changes the diffusion, in the flux form of per-cell rates
(harmonic mean per link); a limit (`lower_b`) changes the clamp. Both ends of every map
must be values the parameter accepts (checked when the model is built). A parameter set
once, at a given step, is a phase boundary: `modulated.at(state)` gives the wrapped model
with the maps of that state, to run the next phase with.

The explicit-Euler limit is checked against the largest rate a map can give
(max(out_low, out_high)), so a modulated diffusion never runs past its stable dt. The
limits a run reports before it starts (`lower`, `upper`) are the wrapped model's; a
modulated limit takes its map's values as the run goes.
"""

from __future__ import annotations

from typing import ClassVar, Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._checks import as_float_array, check_finite, is_concrete
from ._base import AbstractModel


class Modulation(eqx.Module):
    """`parameter` <- the clamped linear map of reagent `by` from [low, high] onto
    [out_low, out_high] (low != high; out_low > out_high maps a rising reagent to a
    falling parameter)."""

    FIELDS: ClassVar[tuple[str, ...]] = ("low", "high", "out_low", "out_high")  # its numbers, as in files
    parameter: str = eqx.field(static=True)
    by: str = eqx.field(static=True)
    low: Array
    high: Array
    out_low: Array
    out_high: Array

    def __init__(self, parameter: str, by: str, low, high, out_low, out_high):
        if not isinstance(parameter, str) or not isinstance(by, str):
            raise ValueError(f"Modulation.parameter and Modulation.by are names (got {parameter!r}, {by!r})")
        self.parameter, self.by = parameter, by
        self.low, self.high = (as_float_array(v, f"Modulation.{n}") for v, n in ((low, "low"), (high, "high")))
        self.out_low = as_float_array(out_low, "Modulation.out_low")
        self.out_high = as_float_array(out_high, "Modulation.out_high")

    def __check_init__(self):
        for name in ("low", "high", "out_low", "out_high"):
            check_finite(getattr(self, name), f"Modulation.{name}")
        if is_concrete(self.low, self.high) and np.any(np.asarray(self.low) == np.asarray(self.high)):
            raise ValueError(f"Modulation.low and Modulation.high must differ (both {float(self.low):g}): "
                             "the map divides by high - low")

    def __call__(self, concentration: Array) -> Array:
        t = jnp.clip((concentration - self.low) / (self.high - self.low), 0.0, 1.0)
        return self.out_low + t * (self.out_high - self.out_low)

    @property
    def largest(self) -> Array:
        """The largest value the map gives."""
        return jnp.maximum(self.out_low, self.out_high)


PREFIX = "modulation"  # a modulation's numbers are parameters "modulation{i}.low", ...


class Modulated(AbstractModel):
    """A model whose parameters are set every step from reagents' concentrations (see the
    module docstring). Its species, limits and parameters are the wrapped model's, plus
    each modulation's numbers as `modulation{i}.low`, `.high`, `.out_low`, `.out_high`."""

    model: AbstractModel
    modulations: tuple[Modulation, ...]

    def __init__(self, model: AbstractModel, modulations: Modulation | Sequence[Modulation]):
        if not isinstance(model, AbstractModel):
            raise ValueError(f"Modulated.model must be a morphojax model (got {model!r})")
        modulations = (modulations,) if isinstance(modulations, Modulation) else tuple(modulations)
        if not modulations or not all(isinstance(m, Modulation) for m in modulations):
            raise ValueError("Modulated.modulations must be one or more mj.Modulation(...)")
        names = model.parameters()
        for m in modulations:
            if m.parameter not in names:
                raise ValueError(f"Modulation.parameter {m.parameter!r} is not a parameter of "
                                 f"{type(model).__name__}; parameters: {', '.join(names)}")
            if m.by not in model.species:
                raise ValueError(f"Modulation.by {m.by!r} is not a species of {type(model).__name__}; "
                                 f"species: {', '.join(model.species)}")
        if len({m.parameter for m in modulations}) != len(modulations):
            raise ValueError("Modulated: each parameter can be modulated by one Modulation only")
        for m in modulations:  # both ends of the map must be values the parameter accepts
            if is_concrete(m.out_low, m.out_high):
                for end in ("out_low", "out_high"):
                    try:
                        model.replace(**{m.parameter: getattr(m, end)})
                    except ValueError as err:
                        raise ValueError(f"Modulation.{end} of {m.parameter!r} is not a value it accepts: {err}") \
                            from None
        self.model, self.modulations = model, modulations

    @property
    def species(self):  # type: ignore[override]
        return self.model.species

    @property
    def lower(self):  # type: ignore[override]
        return self.model.lower

    @property
    def upper(self):  # type: ignore[override]
        return self.model.upper

    def at(self, x) -> AbstractModel:
        """The wrapped model with every modulated parameter set from `x`: the stacked fields
        (species, rows, cols) or a `State`. A step runs with it, reaction, rates and limits."""
        x = jnp.stack([jnp.asarray(a) for a in x.arrays()]) if hasattr(x, "arrays") else jnp.asarray(x)
        return self.model.at(x).replace(**{m.parameter: m(x[self.species.index(m.by)]) for m in self.modulations})

    def reaction(self, x):
        return self.at(x).reaction(x)

    def homogeneous_state(self, guess=None):
        """A homogeneous steady state of the modulated reaction (its parameters set from
        the state itself), by Newton's method from `guess`, or from the wrapped model's
        homogeneous state when it has one, else 1 per species (see
        `AbstractModel.homogeneous_state`)."""
        if guess is None:
            guess = self.model.unclamped_state()
        return super().homogeneous_state(guess)

    def diffusion(self):
        # the largest rates the maps can give: what the explicit-Euler check needs (a
        # reaction parameter set to its bound leaves the diffusion as it is)
        return self.model.replace(**{m.parameter: m.largest for m in self.modulations}).diffusion()

    def parameters(self):
        out = dict(self.model.parameters())
        for i, m in enumerate(self.modulations):
            out.update({f"{PREFIX}{i}.{k}": getattr(m, k) for k in Modulation.FIELDS})
        return out

    def replace(self, **changes):
        mods = [{k: getattr(m, k) for k in Modulation.FIELDS} for m in self.modulations]
        inner = {}
        for key, value in changes.items():
            head, _, field = key.partition(".")
            index = head[len(PREFIX):] if head.startswith(PREFIX) else ""
            if index.isdigit() and int(index) < len(mods) and field in Modulation.FIELDS:
                mods[int(index)][field] = value
            else:
                inner[key] = value
        model = self.model.replace(**inner) if inner else self.model
        return Modulated(model, [Modulation(m.parameter, m.by, **v) for m, v in zip(self.modulations, mods)])

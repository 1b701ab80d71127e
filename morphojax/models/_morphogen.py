"""A signal reagent that only diffuses, is produced and is removed: the gradients of the
thesis's chapter 5 (a producer cell or row, removal elsewhere), which modulate other
parameters (`Modulated`)."""

from __future__ import annotations

import math
from typing import ClassVar

import jax.numpy as jnp
from jax import Array

from ._base import AbstractReaction, check_limits, check_parameters, set_parameters, species_stack


class Morphogen(AbstractReaction):
    """One reagent r with production, removal and diffusion, no reaction with others:

        dr/dt = production - removal - decay r + D lap(r)

    production: per unit time, a scalar or a (rows, cols) map (a producer cell is a map
        that is zero but there).
    removal: zero-order loss per unit time (the thesis's "change R conc -0.001" every
        iteration is removal 0.001 at dt 1); with the lower limit 0 the signal stays
        non-negative, so removal empties a cell and stops there.
    decay: first-order loss rate (per unit time).
    All of them, like the limits, may be maps.
    """

    species: ClassVar[tuple[str, ...]] = ("r",)
    ALIASES: ClassVar[dict[str, str]] = {"diffusion": "diffusion_rate"}  # `diffusion()` is the method
    production: Array
    removal: Array
    decay: Array
    diffusion_rate: Array
    lower: Array
    upper: Array

    def __init__(self, production=0.0, removal=0.0, decay=0.0, diffusion=0.1, lower=0.0, upper=math.inf, *,
                 diffusion_rate=None):
        # diffusion_rate: the field's own name, which `replace` gives
        set_parameters(self, lower, upper, production=production, removal=removal, decay=decay,
                       diffusion_rate=diffusion if diffusion_rate is None else diffusion_rate)

    def __check_init__(self):
        check_parameters(self, "production", "removal", "decay", low=0.0, note="per unit time")
        check_parameters(self, "diffusion_rate", low=0.0, note="a diffusion rate")
        check_limits(self)

    def reaction(self, x):
        r = x[0]
        return (self.production - self.removal - self.decay * r)[None]

    def diffusion(self):
        return species_stack(self.diffusion_rate, 1, "Morphogen diffusion")

    def unclamped_state(self):
        """(r,) = ((production - removal) / decay,) for decay > 0; without decay, the lower
        limit when removal outweighs production (the clamp holds it there), the upper one
        when production does (no steady state below an infinite limit), 0 when they
        balance."""
        net = self.production - self.removal
        safe = jnp.where(self.decay > 0, self.decay, 1.0)
        none = jnp.where(net < 0, self.lower[0], jnp.where(net > 0, self.upper[0], 0.0))
        return (jnp.where(self.decay > 0, net / safe, none),)

"""Single-reagent reinforcement (leopard paper eq. 6): a cubic that pushes a concentration
away from a threshold, keeping borders sharp under growth."""

from __future__ import annotations

import math
from typing import ClassVar

from jax import Array

from ._base import AbstractReaction, check_limits, check_parameters, set_parameters, species_stack


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
        # diffusion_rate: the field's own name, which `replace` gives
        set_parameters(self, lower, upper, threshold=threshold, width=width,
                       diffusion_rate=diffusion if diffusion_rate is None else diffusion_rate)

    def __check_init__(self):
        check_parameters(self, "threshold")
        check_parameters(self, "width", low=0.0, low_open=True)
        check_parameters(self, "diffusion_rate", low=0.0, note="a diffusion rate")
        check_limits(self)

    @property
    def gamma(self):
        return 3.0 * math.sqrt(3.0) / (2.0 * self.width**2)

    def reaction(self, x):
        c = x[0]
        t, w = self.threshold, self.width
        return (self.gamma * (t - w - c) * (t - c) * (t + w - c))[None]

    def diffusion(self):
        return species_stack(self.diffusion_rate, 1, "Reinforcement diffusion")

    def unclamped_state(self):
        """(t,): the threshold, the middle root of the cubic, which the reaction pushes away
        from (its rate there is +w); t - w and t + w are the stable roots (rate -2w each),
        `homogeneous_state(guess=...)` near one gives it. One species has no Turing
        instability: diffusion only damps its modes."""
        return (self.threshold,)

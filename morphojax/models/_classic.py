from __future__ import annotations

import math
from typing import ClassVar

import jax.numpy as jnp
from jax import Array

from .._checks import as_float_array, check_finite, check_range
from ._base import AbstractReaction, check_limits, species_stack


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
        self.lower = species_stack(lower, 2, "GrayScott.lower")
        self.upper = species_stack(upper, 2, "GrayScott.upper")

    def __check_init__(self):
        for name in ("feed", "kill", "du", "dv"):
            check_finite(getattr(self, name), f"GrayScott.{name}")
            check_range(getattr(self, name), f"GrayScott.{name}", low=0.0)
        check_limits(self)

    def reaction(self, x):
        u, v = x[0], x[1]
        uvv = u * v * v
        return jnp.stack([-uvv + self.feed * (1.0 - u), uvv - (self.feed + self.kill) * v])

    def diffusion(self):
        return species_stack((self.du, self.dv), 2, "GrayScott diffusion")

"""Turing's reaction in the Bard-Lauder form (`Bard`) and the leopard paper's bounded
Turing model (`Turing`), which is `Bard` with alpha = 16, beta = 12, sp = 1."""

from __future__ import annotations

import math
from typing import ClassVar

import jax.numpy as jnp
from jax import Array

from ._base import AbstractReaction, check_limits, check_parameters, set_parameters, species_stack


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
        set_parameters(self, lower, upper, alpha=alpha, beta=beta, sp=sp, da=da, db=db)

    def __check_init__(self):
        check_parameters(self, "alpha", "beta", "sp")
        check_parameters(self, "da", "db", low=0.0, note="a diffusion rate")
        check_limits(self)

    def reaction(self, x):
        return bard_reaction(x, self.alpha, self.beta, self.sp)

    def diffusion(self):
        return species_stack((self.da, self.db), 2, "Bard diffusion")

    def unclamped_state(self):
        """(a, b) = (alpha / (alpha - beta), alpha - beta), where the reaction vanishes
        (sp != 0; it needs alpha != beta, and alpha > beta for b > 0)."""
        b = self.alpha - self.beta
        return self.alpha / b, b


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
        set_parameters(self, lower, upper, ratio=ratio, scale=scale)

    def __check_init__(self):
        check_parameters(self, "ratio", low=0.0, note="Da/Db, a diffusion ratio")
        check_parameters(self, "scale", low=0.0, note="Db, a diffusion rate")
        check_limits(self)

    def as_bard(self) -> Bard:
        """The same model in the general Bard form: sp = 1, Da = r s, Db = s."""
        return Bard(
            alpha=self.ALPHA, beta=self.BETA, sp=1.0, da=self.ratio * self.scale, db=self.scale,
            lower=self.lower, upper=self.upper,
        )

    def reaction(self, x):  # Bard's reaction with alpha = 16, beta = 12, sp = 1
        return bard_reaction(x, self.ALPHA, self.BETA, 1.0)

    def diffusion(self):  # Bard's (Da, Db) = (r s, s)
        return species_stack((self.ratio * self.scale, self.scale), 2, "Turing diffusion")

    def unclamped_state(self):
        """(a, b) = (4, 4): Bard's alpha / (alpha - beta) and alpha - beta for 16 and 12.
        The leopard paper's Fig. 4 rows with Ua = 4 or Lb = 4 put a limit right on it."""
        four = jnp.full_like(self.ratio * self.scale, self.ALPHA / (self.ALPHA - self.BETA))
        return four, jnp.full_like(four, self.ALPHA - self.BETA)

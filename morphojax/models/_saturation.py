"""Single-reagent saturation patterns of the thesis, chapter 7: its cubic reaction
(eq. 7.1) and its rule-based reinforcement (sections 6.6 and 7.2).

Both act on one reagent `r` and are meant to run with saturation limits (the thesis's
`define chemical P limit L`: lower 0, upper L) on its own Moore stencil
(`Lattice(stencil="moore")`, rates as printed) at dt = 1, where one step is one of the
thesis's iterations: next r = clip(r + rule(r) + D sum_j (r_j - r), 0, L) (thesis section
4.7, steps 2, 4 and 6: the rules and diffusion both read the current state).
"""

from __future__ import annotations

import math
from typing import ClassVar

import jax
import jax.numpy as jnp
from jax import Array

from ._base import AbstractReaction, check_limits, check_parameters, set_parameters, species_stack


class ThesisReinforcement(AbstractReaction):
    """The thesis's single-reagent reaction, eq. 7.1, with its sign as printed:

        dr/dt = s (r - a)(r - b)(r - c) + D lap(r)

    For s > 0 and a < b < c the middle root b attracts (the cubic is negative just above
    it and positive just below) and a, c repel, so a value below a falls to the lower
    limit and one above c rises to the upper limit: with the thesis's saturation limits
    [0, 1] there are three stable values, 0, b and 1, and most cells end at 0 or 1, as
    the thesis's text intends (low values to 0, high ones to the limit). s < 0 makes a and
    c attract instead (a bistable cubic between a and c that never reaches the limits).
    Defaults: Fig. 7.9's s = 0.35, a = 0.3, b = 0.5, c = 0.7, with Fig. 7.4's diffusion
    rate 0.01 and limits [0, 1]. Units: r a concentration, s per unit time per
    concentration^2, D in cells^2 per unit time (or, on the Moore stencil, the thesis's
    rate per neighbour per iteration).
    """

    species: ClassVar[tuple[str, ...]] = ("r",)
    ALIASES: ClassVar[dict[str, str]] = {"diffusion": "diffusion_rate"}  # `diffusion()` is the method
    s: Array
    a: Array
    b: Array
    c: Array
    diffusion_rate: Array
    lower: Array
    upper: Array

    def __init__(self, s=0.35, a=0.3, b=0.5, c=0.7, diffusion=0.01, lower=0.0, upper=1.0, *, diffusion_rate=None):
        # diffusion_rate: the field's own name, which `replace` gives
        set_parameters(self, lower, upper, s=s, a=a, b=b, c=c,
                       diffusion_rate=diffusion if diffusion_rate is None else diffusion_rate)

    def __check_init__(self):
        check_parameters(self, "s", "a", "b", "c")
        check_parameters(self, "diffusion_rate", low=0.0, note="a diffusion rate")
        check_limits(self)

    def reaction(self, x):
        r = x[0]
        return (self.s * (r - self.a) * (r - self.b) * (r - self.c))[None]

    def diffusion(self):
        return species_stack(self.diffusion_rate, 1, f"{type(self).__name__} diffusion")

    def unclamped_state(self):
        """(b,): the middle root, which attracts for s > 0 (see the class docstring); a and
        c are the other roots, `homogeneous_state(guess=...)` near one gives it."""
        return (self.b,)


def _window(r, above, below, width):
    """1 where above < r < below, else 0; with width > 0 the product of two logistic
    steps of that width (concentration units) instead. Infinite ends give exact 1s."""
    hard = ((r > above) & (r < below)).astype(r.dtype)
    w = jnp.where(width > 0, width, 1.0)  # a finite divisor on both branches keeps gradients finite
    soft = jax.nn.sigmoid((r - above) / w) * jax.nn.sigmoid((below - r) / w)  # an infinite end gives 1
    return jnp.where(width > 0, soft, hard)


class RuleReinforcement(AbstractReaction):
    """The thesis's rule-based reinforcement (sections 6.6 and 7.2; Figs. 6.10, 7.4-7.8):
    add `gain` to r where it lies in the window (rise_above, rise_below), subtract `loss`
    where it lies in (fall_above, fall_below), clamped to [lower, upper] by the step:

        dr/dt = gain [rise_above < r < rise_below] - loss [fall_above < r < fall_below] + D lap(r)

    At dt = 1 a rate is the thesis's per-iteration change: `rule if P conc > 0.7 change P
    conc +0.01` is rise_above = 0.7 (rise_below = inf), gain = 0.01; `rule if R conc in 0.1
    0.9 change R conc -0.0004` is fall_above = 0.1, fall_below = 0.9, loss = 0.0004. The
    windows are open (a value exactly at a threshold gets no change; the thesis's `in`
    intervals are closed, which differs only on a set of measure zero).

    Differentiability: with `width = 0` (the default, the thesis's rule) the indicators
    are step functions, so the gradient of a run with respect to r and to the four
    thresholds is zero almost everywhere (only `gain`, `loss` and D get useful gradients).
    `width > 0` replaces each edge by a logistic step of that width (concentration
    units), a smooth rule whose gradients are nonzero near the thresholds; it tends to
    the hard rule as width -> 0.

    Defaults: thesis Fig. 7.4 (limit 1, D = 0.01: add 0.01 above 0.7, subtract 0.01 below
    0.3). Units: r a concentration, gain and loss concentration per unit time, D in cells^2
    per unit time (or the thesis's rate per neighbour per iteration on the Moore stencil).
    """

    species: ClassVar[tuple[str, ...]] = ("r",)
    ALIASES: ClassVar[dict[str, str]] = {"diffusion": "diffusion_rate"}  # `diffusion()` is the method
    rise_above: Array
    rise_below: Array
    gain: Array
    fall_above: Array
    fall_below: Array
    loss: Array
    width: Array
    diffusion_rate: Array
    lower: Array
    upper: Array

    def __init__(self, rise_above=0.7, gain=0.01, fall_below=0.3, loss=0.01, diffusion=0.01, lower=0.0, upper=1.0, *,
                 rise_below=math.inf, fall_above=-math.inf, width=0.0, diffusion_rate=None):
        # diffusion_rate: the field's own name, which `replace` gives
        set_parameters(self, lower, upper, rise_above=rise_above, rise_below=rise_below, gain=gain,
                       fall_above=fall_above, fall_below=fall_below, loss=loss, width=width,
                       diffusion_rate=diffusion if diffusion_rate is None else diffusion_rate)

    def __check_init__(self):
        check_parameters(self, "rise_above", allow_inf="-")
        check_parameters(self, "rise_below", allow_inf="+")
        check_parameters(self, "fall_above", allow_inf="-")
        check_parameters(self, "fall_below", allow_inf="+")
        check_parameters(self, "gain", "loss", "width", low=0.0)
        check_parameters(self, "diffusion_rate", low=0.0, note="a diffusion rate")
        check_limits(self)

    def unclamped_state(self):
        """(r,) in the band where neither rule acts: the midpoint of [fall_below, rise_above]
        when fall_below <= rise_above (every value of the band is steady; with width > 0
        the logistic tails make the midpoint one only approximately, and Newton's method in
        `homogeneous_state` moves it to where the two tails balance), else the midpoint of
        the limits."""
        band = (self.fall_below + self.rise_above) / 2
        limits = (self.lower[0] + self.upper[0]) / 2
        return (jnp.where(self.fall_below <= self.rise_above, band, limits),)

    def reaction(self, x):
        r = x[0]
        up = _window(r, self.rise_above, self.rise_below, self.width)
        down = _window(r, self.fall_above, self.fall_below, self.width)
        return (self.gain * up - self.loss * down)[None]

    def diffusion(self):
        return species_stack(self.diffusion_rate, 1, f"{type(self).__name__} diffusion")

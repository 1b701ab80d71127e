"""FFT counting: periodic convolutions with the neighbourhood kernels' spectra.

The kernels are even on the periodic lattice, so their spectra are real; products with
them are taken as a complex spectrum times a real one. Counts are float32 and rounded
to integers by the caller, which keeps the transforms' error bound (see `_choice`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array


def times_real(f, s):
    """Complex spectrum times a real one (cheaper than promoting `s` to complex)."""
    return jax.lax.complex(jnp.real(f) * s, jnp.imag(f) * s)


def fft_spectra(kernel: Array) -> Array:
    """Real spectra of even kernels (B, *lattice) over the lattice axes."""
    axes = tuple(range(1, kernel.ndim))
    return jnp.fft.rfftn(kernel, axes=axes).real  # even kernel: real spectrum


def fft_convolve(ind: Array, spectra: Array) -> Array:
    """Periodic convolution of each of ind (B, *lattice) with its kernel's spectrum."""
    axes = tuple(range(1, ind.ndim))
    return jnp.fft.irfftn(times_real(jnp.fft.rfftn(ind, axes=axes), spectra), s=ind.shape[1:], axes=axes)


def fft_counts(ind: Array, spectra: Array) -> Array:
    """Activator and ring counts (2K, *lattice) as exact int32 of the indicators
    ind (K, *lattice), from the spectra of the K activator then the K ring kernels: one
    forward transform per species serves both of its kernels."""
    axes = tuple(range(1, ind.ndim))
    f = jnp.fft.rfftn(ind, axes=axes)
    fs = jnp.concatenate([f, f])
    return jnp.round(jnp.fft.irfftn(times_real(fs, spectra), s=ind.shape[1:], axes=axes)).astype(jnp.int32)

"""Counting by matrix-product transforms (for small 3D lattices on CPU).

The kernels are even in every axis (a function of |offset_i| on the periodic lattice), so
the real separable transform with cas(t) = cos(t) + sin(t) along each axis diagonalises
the convolution like the FFT does, with the kernel's real spectrum as eigenvalues; cas
matrices are symmetric and their own inverse up to 1/n. Along the first lattice axis the
kernel spans only 2 extent + 1 offsets, which are summed directly in the transformed
space of the other axes. Sums are float32 and rounded by the caller (`_choice` only
plans this method where the error bound keeps them exact).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array


def cas_matrix(n: int) -> np.ndarray:
    """The n x n cas matrix cos(2 pi i j / n) + sin(2 pi i j / n), float32."""
    t = 2.0 * np.pi * np.outer(np.arange(n), np.arange(n)) / n
    return (np.cos(t) + np.sin(t)).astype(np.float32)


def cas_transform(y: Array, mats: dict) -> Array:
    """The cas transform of y (B, n0, n1, ..., nm) over the axes after n0, each one matrix
    product that drops the axis and appends its transform (so the last axis stays in
    place), leaving those axes in reverse order: applied twice it gives y x prod(n_i)
    back in the original order. The products are plain, leaving XLA its layout copies
    (faster than transposed operands that avoid them; bench_automata.md)."""
    for axis in range(y.ndim - 1, 1, -1):
        y = jax.lax.dot_general(y, mats[y.shape[axis]], (((axis,), (0,)), ((), ())),
                                precision=jax.lax.Precision.HIGHEST)  # no TF32 on GPUs
    return y


def matmul_spectra(kernel: Array, extent: int) -> dict:
    """What `matmul_convolve` needs for kernels (B, n0, ...): the cas matrices, and the cas
    spectra over the other axes of the kernels' slices at first-axis offsets 0..extent,
    in `cas_transform`'s layout and divided by the size of those axes ("taps")."""
    rest = kernel.shape[2:]
    mats = {n: jnp.asarray(cas_matrix(n)) for n in sorted(set(rest))}
    taps = cas_transform(kernel[:, :extent + 1].astype(jnp.float32), mats) / math.prod(rest)
    return {"taps": taps, "mats": mats}


def matmul_convolve(ind: Array, spectra: dict, extent: int) -> Array:
    """Periodic convolution of each of ind (B, *lattice) with its kernel, from
    `matmul_spectra` of kernels spanning offsets -extent..extent along the first axis."""
    taps, mats, e = spectra["taps"], spectra["mats"], extent
    y = cas_transform(ind, mats)
    b, n0 = y.shape[:2]
    y3, t3 = y.reshape(b, n0, -1), taps.reshape(b, e + 1, -1)  # first-axis shifts move whole rows
    padded = jnp.concatenate([y3[:, n0 - e:], y3, y3[:, :e]], axis=1) if e else y3
    w = t3[:, :1] * y3
    for t in range(1, e + 1):
        w = w + t3[:, t:t + 1] * (padded[:, e + t:e + t + n0] + padded[:, e - t:e - t + n0])
    return cas_transform(w.reshape(y.shape), mats)

"""The differentiable relaxation of Young's step on state probabilities.

Neighbour counts are FFT convolutions of the species' probabilities with the activator
and ring kernels (smoothed by a sigmoid of width `edge` so that the radii get gradients);
the hard update's argmax becomes a softmax and its keep-on-tie rule a gate. The public
entry points are `YoungCA.soft_step` and `YoungCA.soft_run`, which document the rule.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

from .._checks import check_range
from ._fft import times_real
from ._geometry import neighbourhood_kernels


def soft_step(ca, probs, temperature, edge=None) -> Array:
    """One soft step of YoungCA `ca` on probabilities (K + 1, *lattice) (`YoungCA.soft_step`)."""
    probs = jnp.asarray(probs)
    k, shape = ca.n_species, probs.shape[1:]
    if probs.shape[0] != k + 1:
        raise ValueError(f"YoungCA.soft_step probs must have shape (K + 1, *lattice) = ({k + 1}, ...) (got {probs.shape})")
    check_range(temperature, "YoungCA.soft_step temperature", low=0.0, low_open=True)
    if edge is not None:
        check_range(edge, "YoungCA.soft_step edge (lattice cells)", low=0.0, low_open=True)
    act, ring = neighbourhood_kernels(ca.r_act, ca.r_inh, ca.neighbourhood, ca.include_self, shape, edge)
    axes = tuple(range(1, len(shape) + 1))
    f = jnp.fft.rfftn(probs[:k], axes=axes)
    spec = jnp.fft.rfftn(jnp.concatenate([act, ring]), axes=axes).real
    counts = jnp.fft.irfftn(times_real(jnp.concatenate([f, f]), spec), s=shape, axes=axes)
    # On one-hot input the counts are integers, and W x denominator is then a sum of
    # integer products (w x denominator is an integer in float), so a tie is an exact
    # zero: the counts' values (not their gradients) are snapped to the nearest integer
    # when within 1e-3 of it, so that the transforms' float error cannot open the
    # keep-on-tie gate as the temperature goes to 0.
    near = jnp.round(counts) - counts
    counts = counts + jax.lax.stop_gradient(jnp.where(jnp.abs(near) < 1e-3, near, 0.0))
    den = ca.denominator.astype(counts.dtype)
    bc = (slice(None),) + (None,) * len(shape)
    w = ((ca.w_act * den)[bc] * counts[:k] + (ca.w_inh * den)[bc] * counts[k:]) / den
    scores = jnp.concatenate([w, jnp.zeros((1,) + shape, w.dtype)])
    q = jax.nn.softmax(scores / temperature, axis=0)
    gate = 1.0 - jnp.exp(-jnp.square(jnp.max(w, axis=0) / temperature))
    return gate * q + (1.0 - gate) * probs


def soft_run(ca, probs, steps: int, temperature, edge=None) -> Array:
    """`steps` soft steps of `ca` in a `lax.scan` (reverse-mode differentiable)."""
    def body(p, _):
        return soft_step(ca, p, temperature, edge), None

    return jax.lax.scan(body, jnp.asarray(probs), None, length=int(steps))[0]

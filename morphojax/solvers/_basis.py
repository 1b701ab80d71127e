"""The eigenbasis a spectral step runs in: the domain's transforms, or one complex FFT per
pair of species on a wrapped lattice.

A spectral step multiplies the coefficients of each species by real multipliers (dt
phi_1(z), 1 / (1 - z), ...) that depend on the wave only through the stencil's symbol,
which is even in the wave number: p(-k) = p(k). On a wrapped lattice two real species a
and b can then share one complex FFT, Z = F(a + i b). As F(a)(k) = (Z(k) + conj Z(-k)) / 2
and F(b)(k) = (Z(k) - conj Z(-k)) / 2i,

    p_a F(a) + i p_b F(b) = ((p_a + p_b) / 2) Z(k) + ((p_a - p_b) / 2) conj Z(-k),

which is again the packed transform of two real fields: sums and products of multipliers
stay in the packed form, and the inverse FFT's real and imaginary parts are the two
species.

The rule kept here: on "wrap" with an even number 2m of species, species j and m + j share
one complex FFT (contiguous halves, which XLA fuses into the step's other loops); "no-flux"
(the DCT) and an odd number of species use the domain's own transforms. Each packed
multiply reflects its coefficients (z(-k), read by the multiply's loop), so packing pays only where a
step multiplies once per transform: ETDRK1, ETDRK2 and IMEX1 pack (measured on fig4-r40's
50x50 lattice, interleaved in one process: 0.75-0.86x the step's time with the ghost-cell
stencil), ETDRK4 and IMEX2, which combine several multipliers per transform, do not (1.3x
slower packed); the solver says which (`packs`). The packed result differs from the
unpacked by float32 rounding of the larger species of the pair.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..domains import _stencils


def _reflect(z, ndim: int):
    """z(-k) on the FFT's layout of the last `ndim` axes (index -k mod n).

    A gather of constant indices along each axis, which XLA fuses into the multiply that
    reads it; a flip and a roll were two loops of their own each step (the same values)."""
    for axis in range(-ndim, 0):
        n = z.shape[axis]
        z = jnp.take(z, np.asarray(-np.arange(n) % n), axis=axis, unique_indices=True, mode="clip")
    return z


def _complex(dtype):
    return jnp.result_type(dtype, jnp.complex64)


class _PairMultiplier:
    """Real multipliers (p_a, p_b) of a species pair, acting on their packed coefficients."""

    __slots__ = ("minus", "ndim", "plus")

    def __init__(self, plus, minus, ndim: int):
        self.plus, self.minus, self.ndim = plus, minus, ndim

    def __mul__(self, other):
        if isinstance(other, _PairMultiplier):
            raise TypeError("packed multipliers act on coefficients, not on each other")
        if jnp.ndim(other) == 0:  # a number scales the multipliers
            return _PairMultiplier(other * self.plus, other * self.minus, self.ndim)
        return self.plus * other + self.minus * jnp.conj(_reflect(other, self.ndim))

    __rmul__ = __mul__


class Eigenbasis:
    """fwd(x) -> coefficients, inv(coefficients) -> x, the eigenvalues on the coefficients'
    layout, and `multipliers` to turn per-species multipliers on that layout into what
    multiplies the coefficients (`*`, as arrays do)."""

    def __init__(self, domain, shape, n_species: int, pack: bool = True):
        """`pack`: pairs of species where the rule above allows; False: the domain's transforms."""
        self.shape, self.ndim = tuple(int(n) for n in shape), len(shape)
        self.packed = pack and domain.boundary == "wrap" and n_species % 2 == 0
        if self.packed:
            self.eigenvalues = _stencils.eigenvalues(domain.stencil, domain.boundary, self.shape, full=True)
        else:
            self.eigenvalues = domain.eigenvalues(self.shape)
        self._domain = domain

    def fwd(self, x):
        if not self.packed:
            return self._domain.transform(x)
        # a + i b as a weighted sum over the halves rather than a slice of each: XLA then fuses
        # the species' stacks (reaction, stencil) into this loop instead of writing them first
        pairs = x.reshape((2, x.shape[0] // 2) + self.shape)
        weights = jnp.asarray([1.0, 1.0j], _complex(x.dtype)).reshape((2,) + (1,) * (self.ndim + 1))
        return jnp.fft.fftn(jnp.sum(pairs * weights, axis=0), axes=tuple(range(-self.ndim, 0)))

    def inv(self, coefficients):
        if not self.packed:
            return self._domain.inverse_transform(coefficients, self.shape)
        w = jnp.fft.ifftn(coefficients, axes=tuple(range(-self.ndim, 0)))
        # the real and imaginary parts as Re(w) and Re(-i w): a broadcast, not a concatenation,
        # so the clamp that follows reads them in its own loop
        weights = jnp.asarray([1.0, -1.0j], w.dtype).reshape((2,) + (1,) * w.ndim)
        return jnp.real(w[None] * weights).reshape((2 * w.shape[0],) + self.shape)

    def multipliers(self, values: dict) -> dict:
        """Each (species, *layout) array of `values` as the multiplier of the coefficients;
        numbers (a step size) stay as they are."""
        if not self.packed:
            return values
        out = {}
        for name, v in values.items():
            if np.ndim(v) == 0:
                out[name] = v
            else:
                a, b = v[: len(v) // 2], v[len(v) // 2:]
                out[name] = _PairMultiplier((a + b) / 2, (a - b) / 2, self.ndim)
        return out

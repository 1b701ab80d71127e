"""Applying a mesh's neighbour-table operator in JAX:

    (L x)_i = (1 / M_i) sum_k w_ik (x_{n_ik} - x_i)

over the slots k of the padded table (padding has w = 0 and points at the vertex itself).
Writing sum_k w_k (x_k - x) rather than sum_k w_k x_k - (sum_k w_k) x keeps a constant
field an exact fixed point. No scatter: every vertex reads its own neighbours.

Reading the neighbours is what the step spends its time on, and the two backends want it
done differently:
- on the CPU (`gathered_apart`), the neighbours are read by one gather of the whole (K, V)
  table, a loop of its own, and the arithmetic then streams through the gathered values,
  which XLA vectorises (with the gathers fused into the arithmetic, the fused loop reads
  element by element and is not vectorised). Species are read two at a time, packed as
  the real and imaginary parts of one complex number, so one 64-bit load fetches both;
  they are unpacked before any arithmetic, so nothing is computed in complex numbers, and
  the packing is exact and differentiable. The CPU step runs 1.15-1.5x faster this way
  (benchmarks/results/bench_mesh.md);
- elsewhere (`gathered_fused`), one gather per slot of the table, accumulated: XLA fuses
  these into the step's one loop, the form the GPU figures were measured with.
Both give the same numbers to rounding; the choice is made when the step is traced.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def gathered_fused(x, weights, neighbours, inverse_mass):
    """L x over the last axis of x (..., V), one gather per slot of the table."""
    slots = [x.at[..., neighbours[:, k]].get(mode="promise_in_bounds") for k in range(neighbours.shape[1])]
    return _neighbour_sum(slots, x, weights) * inverse_mass


def gathered_apart(x, weights, neighbours, inverse_mass):
    """L x over the last axis of x (..., V), one (K, V) gather per pair of species."""
    if x.ndim > 2:  # leading batch axes
        return jax.vmap(gathered_apart, in_axes=(0, None, None, None))(x, weights, neighbours, inverse_mass)
    species = [x] if x.ndim == 1 else list(x)
    width = 2 if x.dtype in (jnp.float32, jnp.float64) else 1  # the dtypes with a complex counterpart
    table = neighbours.T  # (K, V): each slot's gathered values are contiguous
    gathered = [g for i in range(0, len(species), width) for g in _read_neighbours(species[i: i + width], table)]
    out = [_neighbour_sum(g, s, weights) for g, s in zip(gathered, species)]
    return (out[0] if x.ndim == 1 else jnp.stack(out)) * inverse_mass


def _read_neighbours(group, table):
    """The neighbours' values (K, V) of one species, or of two read together as u + i v."""
    if len(group) == 1:
        return [group[0].at[table].get(mode="promise_in_bounds")]
    both = jax.lax.complex(*group).at[table].get(mode="promise_in_bounds")
    return [jnp.real(both), jnp.imag(both)]


def _neighbour_sum(gathered, x, weights):
    """sum_k w_k (x_{n_k} - x) from the neighbour values gathered per slot k: a (K, V) array
    or a sequence of K arrays shaped like x."""
    acc = jnp.zeros_like(x)
    for k in range(len(gathered)):
        acc = acc + weights[:, k] * (gathered[k] - x)
    return acc


def apply_operator(x, weights, neighbours, inverse_mass):
    """(L x) over the last axis of `x` (..., V), in the form that suits the backend."""
    form = gathered_apart if jax.default_backend() == "cpu" else gathered_fused
    return form(x, weights, neighbours, inverse_mass)

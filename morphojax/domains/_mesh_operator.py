"""Applying a mesh's neighbour-table operator in JAX:

    (L x)_i = (1 / M_i) sum_k w_ki (x_{n_ki} - x_i)

over the slots k of the padded, slot-major tables n and w (K, V) (padding has w = 0 and
points at the vertex itself). Writing sum_k w_k (x_k - x) rather than
sum_k w_k x_k - (sum_k w_k) x keeps a constant field an exact fixed point. No scatter:
every vertex reads its own neighbours.

Reading the neighbours is what the step spends its time on, and the two backends want it
done differently:
- on the CPU (`gathered_apart`), the neighbours are read by one gather of the whole (K, V)
  table, a loop of its own, and the arithmetic then streams through the gathered values and
  the weights, row by row, which XLA vectorises (with the gathers fused into the
  arithmetic, the fused loop reads element by element and is not vectorised). Species are
  read two at a time, packed as the real and imaginary parts of one complex number
  (`pack_pairs`), so that one gather fetches both; they are unpacked before any
  arithmetic, so nothing is computed in complex numbers, and the packing is exact and
  differentiable. A run on the CPU whose species pair up (an even number, float32 or
  float64) carries them packed so through the whole loop (`gathered_packed`; `Mesh.carry`):
  each step is then one gather and one loop for the weighted sums, the reaction and the
  packing of the new values, which writes in place. Under `jax.vmap` the packed carry is
  slower than a plain one would be: the vmapped gather reads a column of members per index;
- elsewhere (`gathered_fused`), one gather per slot of the table, accumulated: XLA fuses
  these into the step's one loop, the form the GPU figures were measured with.
All forms give the same numbers to rounding; the choice is made when the step is traced.
The speeds of each form are in benchmarks/results/bench_mesh.md.

The tables hold either operator a `Mesh` offers: the cotangent weights and lumped areas
(`_mesh_build`), or the umbrella operator of `umbrella_operator`, the same form with
w_ij = 1 on every edge and M_i = deg_i.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

PAIRABLE = (jnp.float32, jnp.float64)  # the real dtypes with a complex counterpart


def pack_pairs(fields):
    """(2P, V) real -> species 2i and 2i + 1 as the real and imaginary parts of row i of a
    (P, V) complex array; (V,) for one pair, so that a loop carrying it writes it in place
    (a (1, V) result is a reshape of the loop's output, which XLA copies each step)."""
    if fields.shape[0] == 2:
        return jax.lax.complex(fields[0], fields[1])
    return jax.lax.complex(fields[0::2], fields[1::2])


def unpack_pairs(packed):
    """The inverse of `pack_pairs`: (2P, V) real."""
    return jnp.stack(_unpacked_species(packed))


def _unpacked_species(packed):
    # The species one by one: a stack of these, rather than a reshape of whole real and
    # imaginary arrays, is what XLA folds away when the step reads a species back.
    return [part for pair in _pairs(packed) for part in _real_and_imaginary(pair)]


def _pairs(packed):
    """The packed pairs' rows (V,): the array itself for one pair."""
    return [packed] if packed.ndim == 1 else list(packed)


def gathered_fused(x, weights, neighbours, inverse_mass):
    """L x over the last axis of x (..., V), one gather per slot of the table."""
    slots = [x.at[..., neighbours[k]].get(mode="promise_in_bounds") for k in range(neighbours.shape[0])]
    return _neighbour_sum(slots, x, weights) * inverse_mass


def gathered_apart(x, weights, neighbours, inverse_mass):
    """L x over the last axis of x (..., V), one (K, V) gather per pair of species."""
    if x.ndim > 2:  # leading batch axes
        return jax.vmap(gathered_apart, in_axes=(0, None, None, None))(x, weights, neighbours, inverse_mass)
    species = x[None] if x.ndim == 1 else x
    paired = 2 * (len(species) // 2) if x.dtype in PAIRABLE else 0
    out = gathered_packed(pack_pairs(species[:paired]), weights, neighbours, inverse_mass) if paired else []
    out += [_neighbour_sum(_gather(s, neighbours), s, weights) * inverse_mass for s in species[paired:]]
    return out[0] if x.ndim == 1 else jnp.stack(out)


def gathered_packed(packed, weights, neighbours, inverse_mass):
    """L x of the species packed by `pack_pairs`, read pair by pair: a list of 2P arrays (V,),
    one per species (the step takes its diffusion terms species by species)."""
    reads = [g for pair in _pairs(packed) for g in _real_and_imaginary(_gather(pair, neighbours))]
    return [_neighbour_sum(g, s, weights) * inverse_mass for g, s in zip(reads, _unpacked_species(packed))]


def _gather(values, neighbours):
    """The neighbours' values (K, V) of one array (V,)."""
    return values.at[neighbours].get(mode="promise_in_bounds")


def _real_and_imaginary(z):
    return jnp.real(z), jnp.imag(z)


def _neighbour_sum(gathered, x, weights):
    """sum_k w_k (x_{n_k} - x) from the neighbour values gathered per slot k (a (K, V) array
    or a sequence of K arrays shaped like x) and the weights (K, V)."""
    acc = jnp.zeros_like(x)
    for k in range(len(gathered)):
        acc = acc + weights[k] * (gathered[k] - x)
    return acc


def apply_operator(x, weights, neighbours, inverse_mass):
    """(L x) over the last axis of `x` (..., V), in the form that suits the backend."""
    form = gathered_apart if jax.default_backend() == "cpu" else gathered_fused
    return form(x, weights, neighbours, inverse_mass)


def umbrella_operator(n: int, faces):
    """(rows, cols, weights, masses) of the uniform "umbrella" Laplacian in the form of
    `_mesh_build.cotangent_operator`: each edge of `faces` once in each direction with
    weight 1, and M_i = deg_i, the number of vertices joined to i by an edge, so that

        (L u)_i = (1 / deg_i) sum_j (u_j - u_i),

    the mean of the neighbours' values less the vertex's own (Lundelius's "equally
    weighted" Laplacian). It ignores the geometry: no lengths, so L and the rates are per
    edge, not per length^2. L = D^-1 (A - D) with A symmetric, so it is symmetric in the
    inner product weighted by the degrees, and pure diffusion conserves sum_i deg_i u_i;
    its eigenvalues lie in [-2, 0]."""
    f = np.asarray(faces, np.int64)
    edges = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0)
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([edges[:, 1], edges[:, 0]])
    degree = np.bincount(rows, minlength=n).astype(np.float64)
    return rows, cols, np.ones(len(rows)), degree

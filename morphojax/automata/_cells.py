"""Lattices of cell states: random starts, and the one-hot form of the soft step.

A lattice is an integer array of states 0..k, where 0..k-1 are the differentiated
species and k the undifferentiated state.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

from .._checks import check_range, check_run_size, check_shape

YOUNG_P = 0.015  # Young's probability that a cell starts differentiated


def random_cells(key, shape, k: int = 1, p=None, dtype=jnp.int8) -> Array:
    """A random initial lattice of states 0..k (k = undifferentiated).

    With `p` (Young: p = 0.015, `YOUNG_P`) each cell is differentiated with probability p
    and then of a species drawn uniformly among the k; with `p=None` every cell is
    uniform over the k + 1 states (the well-mixed start of Dur 2023). `key` is a
    `jax.random` key; `p` may be traced (vmap over keys and p works).
    """
    shape = check_shape(shape, "random_cells.shape")
    check_run_size(shape, int(k) + 1, what=f"a lattice of {'x'.join(map(str, shape))} cells and its run")
    check_range(k, "random_cells.k (number of species)", low=1, high=int(jnp.iinfo(dtype).max) - 1)
    k = int(k)
    if p is None:
        return jax.random.randint(key, shape, 0, k + 1).astype(dtype)
    check_range(p, "random_cells.p (probability of a differentiated cell)", low=0.0, high=1.0)
    k_diff, k_species = jax.random.split(key)
    differentiated = jax.random.uniform(k_diff, shape) < p
    species = jax.random.randint(k_species, shape, 0, k)
    return jnp.where(differentiated, species, k).astype(dtype)


def one_hot_cells(cells, k: int, dtype=None) -> Array:
    """Integer cells as state probabilities of shape (k + 1, *lattice) for the soft step."""
    cells = jnp.asarray(cells)
    dtype = jnp.result_type(float) if dtype is None else dtype
    return jnp.moveaxis(jax.nn.one_hot(cells, int(k) + 1, dtype=dtype), -1, 0)


def hard_cells(probs, dtype=jnp.int8) -> Array:
    """The most probable state of each cell (inverse of `one_hot_cells`)."""
    return jnp.argmax(probs, axis=0).astype(dtype)

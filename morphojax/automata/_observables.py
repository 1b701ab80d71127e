"""What is measured on automata: state fractions, Dur's (2023) order parameter (eq. 5),
changed cells and convergence, and the weighted volume difference of a rule (eq. 6)."""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
from jax import Array

if TYPE_CHECKING:
    from ._young import YoungCA


@functools.partial(jax.jit, static_argnames="k")
def volume_fractions(cells, k: int) -> Array:
    """Fraction of the lattice in each state 0..k: shape (k + 1,), summing to 1."""
    cells = jnp.asarray(cells)
    return jnp.stack([jnp.mean(cells == j) for j in range(int(k) + 1)])


@functools.partial(jax.jit, static_argnames="k")
def order_parameter(cells, k: int) -> Array:
    """Dur's (2023) order parameter (eq. 5), one entry per state 0..k, for any dimension.

    eps_j = | sum_c sum_{n in N(c)} s_j(c) s_j(n) | / (2 d N), with s_j = +1 on state j
    and -1 elsewhere, N(c) the 2d direct (von Neumann) neighbours on the periodic lattice
    and N the number of cells. It is 1 for a lattice fully taken by one state and near
    (2 f - 1)^2 for independent random cells with state fraction f (so near 0 for a
    50/50 mix); well-segregated patterns lie in between.
    """
    cells = jnp.asarray(cells)
    out = []
    for j in range(int(k) + 1):
        s = jnp.where(cells == j, 1, -1).astype(jnp.int32)
        # exact integer sums; each unordered neighbour pair appears twice in the double sum
        total = sum(jnp.sum(s * jnp.roll(s, 1, axis=a)) for a in range(cells.ndim))
        out.append(jnp.abs(total).astype(jnp.result_type(float)) / (cells.ndim * cells.size))
    return jnp.stack(out)


def changed_fraction(old, new) -> Array:
    """Fraction of cells whose state differs between two lattices (of the same shape)."""
    old, new = jnp.asarray(old), jnp.asarray(new)
    if old.shape != new.shape:
        raise ValueError(f"changed_fraction: the lattices must have the same shape (got {old.shape} and {new.shape})")
    return jnp.mean(old != new)


def has_converged(old, new, threshold=0.01) -> Array:
    """Dur's (2023) convergence test: fewer than `threshold` (1%) of the cells changed."""
    return changed_fraction(old, new) < threshold


def weighted_volume_difference(ca: YoungCA, dim: int = 3, *, discrete: bool = False) -> Array:
    """Dur's (2023) weighted volume difference (eq. 6) of every species, shape (K,).

    WVD_j = V(r_act) w_act + (V(r_inh) - V(r_act)) w_inh with V the volume of a
    `dim`-dimensional ball (4/3 pi r^3 in 3D), in lattice cells^dim x weight. With
    `discrete=True` the lattice counts are used instead (the field W_j at a cell whose
    whole neighbourhood is species j), which moves in steps as the radii grow.
    """
    if discrete:
        counts = jnp.asarray(ca.neighbour_counts(dim), ca.w_act.dtype)
        return ca.w_act * counts[:, 0] + ca.w_inh * counts[:, 1]
    unit = math.pi ** (dim / 2) / math.gamma(dim / 2 + 1)
    v_act, v_inh = unit * ca.r_act**dim, unit * ca.r_inh**dim
    return v_act * ca.w_act + (v_inh - v_act) * ca.w_inh

"""Concrete automata as hashable keys, and the plans and kernel spectra cached by them.

`freeze` turns a model whose leaves are all concrete into a `Frozen` key: its treedef
(the class and the static fields) and every leaf's dtype, shape and bytes; `thaw` builds
an equal model back. Two models with the same key count neighbours identically on the
same lattice, so what is computed from one serves the other:

- `cached_plan`: the plan (`_choice.make_plan`), static configuration worked out in
  Python, whose cost is comparable to a small run's steps; keyed also by the lattice
  shape and the backend (the method choice depends on both);
- `cached_spectra`: the kernel spectra of the FFT and matrix-product methods, computed
  once instead of in every compiled run; keyed also by the plan.

Both are bounded `functools.lru_cache`s of pure functions of their arguments. A model
with a traced leaf is never frozen, and an exception (an invalid model or lattice) is
not cached, so it is raised on every call. Thawed leaves and the spectra are computed
eagerly (`jax.ensure_compile_time_eval`), also while a jit traces a function that closes
over the model, so the caches only ever hold concrete arrays, never tracers.
"""

from __future__ import annotations

import functools
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._checks import is_concrete
from ._choice import YoungPlan, make_plan

SPECTRA_MAX_SIZE = 2**18  # values kept per cached entry (1 MiB of float32); larger ones are recomputed per run


class Frozen(NamedTuple):
    """A pytree of concrete arrays as hashable host data."""

    treedef: Any
    leaves: tuple  # (dtype, shape, bytes) of each leaf


def freeze(tree) -> Frozen | None:
    """The hashable key of `tree`, or None when a leaf is traced."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    if not is_concrete(leaves):
        return None
    host = [np.asarray(leaf) for leaf in leaves]
    return Frozen(treedef, tuple((a.dtype, a.shape, a.tobytes()) for a in host))


def thaw(frozen: Frozen):
    """The pytree `frozen` was made from (equal leaves as concrete JAX arrays, also while
    a jit is tracing)."""
    with jax.ensure_compile_time_eval():
        leaves = [jnp.asarray(np.frombuffer(data, dtype).reshape(shape)) for dtype, shape, data in frozen.leaves]
    return jax.tree_util.tree_unflatten(frozen.treedef, leaves)


@functools.lru_cache(maxsize=256)
def cached_plan(frozen: Frozen, shape: tuple, backend: str) -> YoungPlan:
    """`make_plan` of the frozen model (see the module docstring)."""
    return make_plan(thaw(frozen), shape, backend)


@functools.lru_cache(maxsize=32)
def cached_spectra(frozen: Frozen, plan: YoungPlan, shape: tuple, backend: str):
    """The kernel spectra of the frozen model under `plan` (see the module docstring)."""
    with jax.ensure_compile_time_eval():
        return _jit_spectra(thaw(frozen), plan=plan, shape=shape)


@functools.partial(jax.jit, static_argnames=("plan", "shape"))
def _jit_spectra(ca, *, plan, shape):
    return ca._spectra(plan, shape)

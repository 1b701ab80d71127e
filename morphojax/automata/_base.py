"""The abstract automaton: input checks, `step` and `run`, and their compiled entry points.

A subclass says how many states a cell has and how one synchronous update is computed
(`_plan`, `_stepper`, optionally `_codec` and `_precomputed`); the base validates the
lattice and runs the update once (`step`) or in the shared loop of `_loop` (`run`).
"""

from __future__ import annotations

import abc
import functools
from typing import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._checks import check_count, check_range, is_concrete
from ._loop import AutomatonRun, Codec, iterate


def call(obj, name: str, *args):
    """`obj.name(*args)` without the bound-method module that equinox builds on every
    attribute access of a method: it is a large share of a small run's Python overhead
    (figures in benchmarks/results/bench_automata.md)."""
    return getattr(type(obj), name)(obj, *args)


class AbstractAutomaton(eqx.Module):
    """A synchronous cellular automaton on a periodic integer lattice of any dimension.

    Subclasses (final, in the equinox pattern) provide `n_states`, `_plan(shape)` (static,
    hashable configuration worked out from concrete parameters before compiling),
    `_stepper(plan, shape)` (called inside the compiled function once per run, so
    precomputation such as kernel spectra happens once, and returning the one-step
    function; given `_precomputed(plan, shape)` it uses those arrays instead) and
    `_codec(plan, shape, dtype)`, the form of the lattice the step works on
    (`identity_codec`: the integer cells).
    """

    @property
    @abc.abstractmethod
    def n_states(self) -> int:
        """Number of cell states (values 0 .. n_states - 1)."""

    @abc.abstractmethod
    def _plan(self, shape: tuple[int, ...]):
        ...

    @abc.abstractmethod
    def _stepper(self, plan, shape: tuple[int, ...], pre=None) -> Callable[[Array], Array]:
        ...

    @abc.abstractmethod
    def _codec(self, plan, shape, dtype) -> Codec:
        """How the loop carries the lattice (`identity_codec(dtype)`: as the cells)."""

    @abc.abstractmethod
    def _precomputed(self, plan, shape):
        """Arrays the step needs that depend only on concrete parameters and the lattice
        (kernel spectra), computed once and reused across calls; None: `_stepper`
        computes them inside the compiled function (or needs none)."""

    def _check_cells(self, cells) -> Array:
        name = f"{type(self).__name__} cells"
        if isinstance(cells, (list, tuple)):
            cells = np.asarray(cells)
        dtype = getattr(cells, "dtype", None)
        if dtype is None or dtype == bool or not jnp.issubdtype(dtype, jnp.integer):
            raise ValueError(f"{name} must be an integer array of states 0..{self.n_states - 1} (got dtype {dtype})")
        if cells.ndim < 1:
            raise ValueError(f"{name} must have at least one dimension (got a scalar)")
        if is_concrete(cells):
            arr = np.asarray(cells)
            if arr.size and (arr.min() < 0 or arr.max() > self.n_states - 1):
                raise ValueError(
                    f"{name} must hold states in [0, {self.n_states - 1}] (got min {arr.min()}, max {arr.max()})"
                )
        return jnp.asarray(cells)

    def step(self, cells) -> Array:
        """One synchronous update of an integer lattice; returns the same dtype."""
        cells = call(self, "_check_cells", cells)
        plan = call(self, "_plan", cells.shape)
        return jit_step(self, cells, call(self, "_precomputed", plan, cells.shape), plan=plan)

    def run(self, cells, steps: int, *, stop_at_convergence: bool = False, threshold=0.01,
            save_every: int | None = None, history: bool = False) -> AutomatonRun:
        """`steps` synchronous updates in one compiled loop, or fewer with
        `stop_at_convergence=True`: then the loop stops after the first update that
        changed fewer than `threshold` (paper 002: 1%) of the cells. `save_every` keeps a
        snapshot every that many updates (`AutomatonRun.frames`); `history` records the
        fraction of changed cells of every update (`AutomatonRun.changes`)."""
        cells = call(self, "_check_cells", cells)
        check_count(steps, "run.steps", "updates")
        check_range(threshold, "run.threshold (fraction of changed cells)", low=0.0, high=1.0)
        if save_every is not None:
            check_count(save_every, "run.save_every", "updates", low=1)
            save_every = int(save_every)
        plan = call(self, "_plan", cells.shape)
        threshold = np.float32(threshold) if is_concrete(threshold) else jnp.asarray(threshold, jnp.float32)
        pre = call(self, "_precomputed", plan, cells.shape)
        return jit_run(self, cells, pre, threshold, steps=int(steps), plan=plan, stop=bool(stop_at_convergence),
                       save_every=save_every, history=bool(history))


# Plain jax.jit, not eqx.filter_jit: the automaton is a pytree of arrays whose
# configuration is static in its treedef, and filter_jit's argument partitioning costs
# several times the dispatch of a call (figures in benchmarks/results/bench_automata.md).
@functools.partial(jax.jit, static_argnames=("plan",))
def jit_step(automaton, cells, pre, *, plan):
    """One update of `cells` by `automaton` under `plan` (`pre`: its precomputed arrays)."""
    codec = automaton._codec(plan, cells.shape, cells.dtype)
    return codec.decode(automaton._stepper(plan, cells.shape, pre)(codec.encode(cells)))


@functools.partial(jax.jit, static_argnames=("steps", "plan", "stop", "save_every", "history"))
def jit_run(automaton, cells, pre, threshold, *, steps, plan, stop, save_every, history):
    """`steps` updates of `cells` in the shared loop (see `AbstractAutomaton.run`)."""
    return iterate(automaton._stepper(plan, cells.shape, pre), cells, steps, stop, threshold, save_every, history,
                   automaton._codec(plan, cells.shape, cells.dtype))

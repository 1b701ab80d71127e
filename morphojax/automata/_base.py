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

from .._checks import check_count, check_range, check_run_size, is_concrete
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
            save_every: int | None = None, history: bool = False, progress=False) -> AutomatonRun:
        """`steps` synchronous updates in one compiled loop, or fewer with
        `stop_at_convergence=True`: then the loop stops after the first update that
        changed fewer than `threshold` (Dur 2023: 1%) of the cells. `save_every` keeps a
        snapshot every that many updates (`AutomatonRun.frames`); `history` records the
        fraction of changed cells of every update (`AutomatonRun.changes`). `progress`
        shows a bar (a string names it): the run goes in pieces of about a twentieth
        (whole multiples of `save_every`), with the same result as one loop."""
        cells = call(self, "_check_cells", cells)
        check_run_size(cells.shape, self.n_states,
                       what=f"this automaton run ({'x'.join(map(str, cells.shape))} cells, {self.n_states} states)")
        check_count(steps, "run.steps", "updates")
        check_range(threshold, "run.threshold (fraction of changed cells)", low=0.0, high=1.0)
        if save_every is not None:
            check_count(save_every, "run.save_every", "updates", low=1)
            save_every = int(save_every)
        plan = call(self, "_plan", cells.shape)
        threshold = np.float32(threshold) if is_concrete(threshold) else jnp.asarray(threshold, jnp.float32)
        pre = call(self, "_precomputed", plan, cells.shape)
        options = dict(plan=plan, stop=bool(stop_at_convergence), save_every=save_every, history=bool(history))
        if progress and int(steps) > 1:
            label = progress if isinstance(progress, str) else type(self).__name__
            return run_in_pieces(lambda c, n: jit_run(self, c, pre, threshold, steps=n, **options), cells,
                                 int(steps), save_every, bool(stop_at_convergence), label)
        return jit_run(self, cells, pre, threshold, steps=int(steps), **options)


def run_in_pieces(run_piece, cells, steps: int, save_every: int | None, stop: bool, label: str) -> AutomatonRun:
    """`steps` updates as `run_piece(cells, n)` calls of about steps / 20 updates each (two
    compiled lengths at most), behind a progress bar, joined into the AutomatonRun one loop
    gives: the same cells, count, convergence, changes and frames. With `stop`, a piece
    whose last update converged ends the run (inside the piece or at its end)."""
    from .._progress import progress_bar

    piece = max(1, steps // 20)
    if save_every:  # frames fall on the same updates: pieces are whole multiples of save_every
        piece = max(save_every, piece // save_every * save_every)
    done, changes, frames, frame_steps, last = 0, [], [], [], None
    with progress_bar(steps, label) as bar:
        while done < steps:
            n = min(piece, steps - done)
            last = run_piece(cells, n)
            applied = int(last.steps)
            if last.changes is not None:
                changes.append(np.asarray(last.changes))
            if save_every:
                keep = slice(0 if done == 0 else 1, None)  # a piece's frame 0 is the previous piece's end
                frames.append(np.asarray(last.frames)[keep])
                starts = np.asarray(last.frame_steps)[keep]
                frame_steps.append(np.where(starts >= 0, starts + done, -1))
            cells, done = last.cells, done + applied
            bar.update(applied)
            if stop and bool(last.converged):
                break
    joined_changes = joined_frames = joined_steps = None
    if changes:  # NaN after an early stop, as in one loop
        joined_changes = np.full((steps,), np.nan, np.float32)
        flat = np.concatenate(changes)
        joined_changes[: len(flat)] = flat
        joined_changes = jnp.asarray(joined_changes)
    if save_every:  # frames an early stop never reached: zeros at step -1, as in one loop
        n_frames = steps // save_every + 1
        joined_frames = np.concatenate(frames)[:n_frames]
        joined_steps = np.concatenate(frame_steps)[:n_frames]
        pad = n_frames - len(joined_frames)
        joined_frames = jnp.asarray(np.concatenate(
            [joined_frames, np.zeros((pad,) + joined_frames.shape[1:], joined_frames.dtype)]))
        joined_steps = jnp.asarray(np.concatenate([joined_steps, np.full(pad, -1, joined_steps.dtype)]))
    return AutomatonRun(last.cells, jnp.int32(done), last.converged, joined_changes, joined_frames, joined_steps)


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

"""Stepping entry points: `simulate`, `rollout` and `run_status`, and their input checks.

`simulate` returns the final state; `rollout` also returns snapshots every n steps;
`run_status` returns the state with how the run ended instead of raising. All three are
pure functions of (model, state, dt, key): usable under `jax.jit`, `jax.vmap` and
`jax.grad`. Non-array configuration (steps, the domain's topology, ...) is static.

The work is done by three rooms: the step (`_step`: reaction, diffusion by the domain,
sources, limits, growth), the loop (`_loop`: chunked scan, blow-up location, progress)
and the execution plan of a growing lattice (`_plan`), which the loop is given.
"""

from __future__ import annotations

from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np

from ._bounds import Barrier, bounds_policy
from ._checks import as_float_array, check_finite, check_range, check_step_counter, is_concrete
from .domains import as_domain
from ._growing_mesh import MeshGrowth, run_growing_mesh
from ._loop import drive
from .models import AbstractModel, per_species
from ._plan import BlockLadder, WholeCapacity
from ._state import State
from ._status import Run, SimulationError
from ._step import Config
from .solvers import SteadyState, as_solver


def _check_inputs(model, domain, state, steps, dt, cfg, growth, check_dt, solver):
    # concrete values are checked eagerly, also while an outer jax.jit traces this call
    with jax.ensure_compile_time_eval():
        _check_inputs_eager(model, domain, state, steps, dt, cfg, growth, check_dt, solver)


def _check_inputs_eager(model, domain, state, steps, dt, cfg, growth, check_dt, solver):
    if not isinstance(model, AbstractModel):
        raise ValueError(f"model must be a morphojax model such as Turing(...) (got {type(model).__name__})")
    if not isinstance(state, State):
        raise ValueError(f"state must be a morphojax State (got {type(state).__name__})")
    if not isinstance(steps, (int, np.integer)) or isinstance(steps, bool) or steps < 0:
        raise ValueError(f"steps must be a non-negative integer (got {steps!r})")
    # an adaptive run may keep up to max_steps steps, whatever `steps` is
    check_step_counter(state.step, max(steps, solver.max_steps) if solver.adaptive else steps)
    if model.n_species != state.n_species:
        raise ValueError(
            f"{type(model).__name__} evolves {model.n_species} species {model.species} but the state has "
            f"{state.n_species} ({', '.join(state.names)})"
        )
    if state.ndim != domain.ndim:
        raise ValueError(f"the domain ({domain.description}) needs fields with {domain.ndim} spatial axes; the state "
                         f"has {state.ndim} (capacity {state.capacity})")
    check_finite(dt, "dt")
    check_range(dt, "dt", low=0.0, low_open=True)
    cap = state.capacity
    for name, leaf in _map_leaves(model):
        try:
            jnp.broadcast_shapes(leaf.shape[-2:], cap)
        except ValueError:
            raise ValueError(
                f"parameter map {name} has shape {leaf.shape[-2:]}, which does not broadcast to the lattice "
                f"{cap} (rows, cols)"
            ) from None
    if is_concrete(state.fields):
        if not np.isfinite(np.asarray(state.fields)).all():
            raise ValueError("state contains NaN or infinite values")
    if check_dt and is_concrete(model, dt):
        solver.check_dt(domain, dt, model)
    if isinstance(cfg.bounds, Barrier) and is_concrete(state.fields, model):
        x = np.stack(state.arrays())
        lo = np.asarray(per_species(model.lower))
        hi = np.asarray(per_species(model.upper))
        if (np.asarray(model.lower) < 0).any():
            raise ValueError("bounds='barrier' needs lower limits >= 0 (the rational terms use x^k - L^k)")
        lo_c = lo[..., : x.shape[-2], : x.shape[-1]] if lo.ndim == 3 and lo.shape[-2:] != (1, 1) else lo
        hi_c = hi[..., : x.shape[-2], : x.shape[-1]] if hi.ndim == 3 and hi.shape[-2:] != (1, 1) else hi
        if not ((x > lo_c) & (x < hi_c)).all():
            raise ValueError(
                "bounds='barrier' needs the initial state strictly inside (lower, upper) for every species; "
                "start from values inside the limits or use bounds='clip'"
            )


def _map_leaves(model):
    """(name, array) of the model's spatially varying parameters (arrays with 2+ dims)."""
    out = []
    for path, leaf in jax.tree_util.tree_leaves_with_path(model):
        if getattr(leaf, "ndim", 0) >= 2:
            out.append((f"{type(model).__name__}{jax.tree_util.keystr(path)}", leaf))
    return out


def _prepare(model, state, steps, dt, domain, boundary, stencil, bounds, growth, sources, key, check_dt, origin, plan,
             solver, until):
    domain = as_domain(domain, stencil=stencil, boundary=boundary, ndim=getattr(state, "ndim", 2))
    cfg = Config(bounds=bounds_policy(bounds), dynamic=bool(state.growable or growth is not None))
    if cfg.dynamic and not domain.supports_growth:
        raise ValueError(f"growth is not supported on the {domain.description}: pass growth=None and a state without "
                         "room to grow (State.from_arrays without capacity=)")
    if cfg.dynamic and hasattr(domain, "check_shape") and is_concrete(state.size):
        domain.check_shape(state.shape)  # the active region's (a wrapped hexagonal lattice: even rows)
    solver = as_solver(solver)
    if until is not None and not isinstance(until, SteadyState):
        raise ValueError(f"until must be None or mj.SteadyState(tol=...) (got {until!r})")
    sources = tuple(sources or ())
    if isinstance(model, AbstractModel):
        solver.check(domain, model, dynamic=cfg.dynamic, sources=sources, fields=getattr(state, "fields", None),
                     bounds=cfg.bounds)
    _check_inputs(model, domain, state, steps, dt, cfg, growth, check_dt, solver)
    if (growth is not None or sources) and key is None:
        raise ValueError("key is required when growth or sources are used (they draw random numbers)")
    if growth is not None:
        # no room is an error only if an expansion falls in this run (a resumed run's last
        # period, or rate 0, has none)
        if not state.growable and is_concrete(state.size) and growth.due(state, steps, dt, origin) != 0:
            raise SimulationError(
                "this state has no room to grow: build it with State.from_arrays(..., capacity=(rows, cols)) "
                "or use state.with_capacity((rows, cols))"
            )
        growth.check_capacity(state, steps, dt, origin, domain.expansion_copies)
    sources = tuple(s.check(state) for s in sources)
    dt = as_float_array(dt, "dt", state.fields.dtype)
    if plan is not None and not isinstance(plan, (BlockLadder, WholeCapacity)):
        raise ValueError(f"plan must be mj.BlockLadder(...) or mj.WholeCapacity() (got {plan!r})")
    if cfg.dynamic and not hasattr(domain, "block"):  # the block ladder cuts square lattices only
        plan = WholeCapacity()
    return domain, cfg, dt, sources, BlockLadder() if plan is None else plan, solver


_OPTIONS = dict(domain=None, stencil=None, bounds="clip", growth=None, sources=(), key=None, check_dt=True,
                throw=True, progress=False, checkpoint=None, origin=None, plan=None, solver=None, until=None)


def _run(model, state, steps, dt, boundary, options, save_every=None, save_fn=None, description=None):
    """Check the inputs, drive the loop; (final State, RunStatus, frames)."""
    o = options
    if isinstance(o["growth"], MeshGrowth):  # its operator is rebuilt between compiled chunks
        return run_growing_mesh(model, state, steps, dt, boundary, o, save_every, description,
                                check_inputs=_check_inputs)
    domain, cfg, dt, sources, plan, solver = _prepare(
        model, state, steps, dt, o["domain"], boundary, o["stencil"], o["bounds"], o["growth"], o["sources"],
        o["key"], o["check_dt"], o["origin"], o["plan"], o["solver"], o["until"])
    if description is None:  # the progress bar's name: a phase's, or the model's
        description = o["progress"] if isinstance(o["progress"], str) else type(model).__name__
    return drive(model, domain, state, steps, dt, cfg, o["growth"], sources, o["key"], o["origin"], o["checkpoint"],
                 bool(o["progress"]), save_every, save_fn, description, plan, solver, o["until"])


def simulate(model: AbstractModel, state: State, steps: int, dt, boundary: str | None = None, *,
             domain=None, stencil: str | None = None, bounds="clip", growth=None, sources=(), key=None,
             check_dt: bool = True, throw: bool = True, progress: bool = False, checkpoint=None,
             origin=None, plan=None, solver=None, until=None) -> State:
    """Run `steps` steps of `model` from `state` (forward Euler unless `solver` says
    otherwise); return the new State.

    Args:
        model: a model such as `Turing(ratio=4, scale=3)`.
        state: the initial `State` (species must match the model's).
        steps: number of steps (a Python int; simulated time is steps x dt).
        dt: time step (unit: simulated time). Checked against the solver's own criterion
            unless `check_dt=False`: for Euler the domain's explicit limit for the largest
            diffusion rate; `ETDRK` and `IMEX` have no diffusion limit.
        boundary: shorthand for `domain=Lattice(boundary=...)`: "wrap" (toroidal, the
            default) or "no-flux" (ghost cell = edge cell).
        domain: where the species diffuse (default `Lattice()`: nine-point stencil, wrap).
            Passing it together with `boundary` or `stencil` is an error.
        stencil: shorthand for `domain=Lattice(stencil=...)`: "nine-point" (the paper's
            isotropic stencil, default), "five-point" or "moore" (the thesis's sum over the
            eight neighbours).
        bounds: "clip" (clamp to [lower, upper] after every step, the paper's method) or
            "barrier" / `Barrier(k)` (smooth rational terms, needs a ~20x smaller dt).
        growth: a `Growth` schedule (random matrix expansion, on square and hexagonal
            lattices) or, on a `Mesh`, a `MeshGrowth` (scaling and division, run in compiled
            chunks between its growth events; eager only); needs a state with capacity.
        sources: localised production, a sequence of `Source`.
        key: `jax.random` key, required with growth or sources. The same key gives the same run.
        throw: raise `SimulationError` if the state becomes NaN/Inf (with the first bad step)
            or growth overflows the capacity. With `throw=False` the state is returned as is.
        progress: show a progress bar (the run is split into pieces; the result is identical);
            a string shows it under that name (e.g. the phase's).
        checkpoint: None, True (checkpoint every ~sqrt(steps) steps) or an int chunk length:
            rematerialise inside chunks under `jax.grad`, so memory does not grow with steps.
        origin: the step at which the growth schedule started (default: `state.step`);
            set it when resuming inside a growing phase.
        plan: how a growing lattice is computed: `BlockLadder()` (default: blocks that
            follow the active region) or `WholeCapacity()` (the reference); same results.
        solver: how each step advances reaction + diffusion: `Euler()` (default, the
            papers' method, every domain), `ETDRK(order=1|2|4)` (diffusion exact on a
            lattice's own eigenbasis, 1D to 3D, one rate per species, isotropic) or
            `IMEX(order=1|2)` (diffusion implicit: by the same transforms, or by conjugate
            gradients on hexagonal lattices, meshes, flux-form maps and fixed polarities).
            Those two take dt from the reaction alone, and refuse growth, sources and
            bounds="barrier". The limits are still a clamp after every step.
        until: a stopping rule, `SteadyState(tol=...)`: stop when the largest change per
            unit time falls below `tol`; `steps` is then the most steps taken.

    Returns:
        The new `State`, with `step` and `time` advanced.
    """
    options = dict(domain=domain, stencil=stencil, bounds=bounds, growth=growth, sources=sources, key=key,
                   check_dt=check_dt, progress=progress, checkpoint=checkpoint, origin=origin, plan=plan,
                   solver=solver, until=until)
    final, status, _ = _run(model, state, steps, dt, boundary, options)
    return status.check(final, throw, start=state.step)


def _save_state(s: State):
    return s


def _options(kwargs, who: str, allowed=tuple(_OPTIONS)) -> dict:
    unknown = set(kwargs) - set(allowed)
    if unknown:
        raise TypeError(f"{who}() got unexpected arguments {sorted(unknown)}")
    return {**_OPTIONS, **kwargs}


def rollout(model: AbstractModel, state: State, steps: int, dt, every: int, boundary: str | None = None, *,
            save: Callable[[State], Any] | None = None, **kwargs):
    """Like `simulate`, also saving a snapshot every `every` steps (for animations and figures).

    Returns `(final_state, frames)`. By default `frames` is a State whose leaves have a
    leading axis of length steps // every (`frames.frame(i)` is snapshot i, taken after
    (i + 1) * every steps). With `save=fn`, `fn(state)` is saved instead, e.g.
    `lambda s: s.fields[1].mean()`. Memory grows with the number of snapshots only.
    Other keyword arguments as for `simulate`.
    """
    if not isinstance(every, (int, np.integer)) or every < 1:
        raise ValueError(f"every must be a positive integer number of steps (got {every!r})")
    options = _options(kwargs, "rollout")
    if getattr(options["solver"], "adaptive", False):
        raise ValueError("rollout takes snapshots every `every` steps, which an adaptive solver (rtol=...) does not "
                         "have: use a fixed step, or simulate in pieces of simulated time")
    if isinstance(steps, (int, np.integer)) and every > steps:  # no snapshot would fall in the run
        raise ValueError(f"rollout.every must lie in [1, steps = {steps}] (got {every})")
    final, status, frames = _run(model, state, steps, dt, boundary, options, int(every), save or _save_state)
    return status.check(final, options["throw"], start=state.step), frames


def run_status(model, state, steps, dt, boundary=None, **kwargs) -> Run:
    """Like `simulate` with `throw=False`, also saying how the run ended.

    Returns a `Run`, which unpacks as (final state, first non-finite step or -1, overflow
    flag); `run.steady_at` is when a stopping rule ended it (NaN if none did) and
    `run.status` the whole `RunStatus`. For sweeps and fitting, where a failed member
    must be recorded rather than raised.
    """
    options = _options(kwargs, "run_status", tuple(k for k in _OPTIONS if k not in ("throw", "progress")))
    final, status, _ = _run(model, state, steps, dt, boundary, options, description="")
    return Run(final, status.nonfinite_step, status.overflow, status.steady_at, status.steps_taken,
               status.incomplete)

"""Parameter sweeps: one model over a grid (or a list) of parameter sets, vmapped and sharded.

    result = mj.sweep(mj.Turing(scale=3.0), vary={"ratio": [4.2, 6, 12, 20, 40], "upper_a": [6.2, 4.4]},
                      state=mj.paper_state(jax.random.key(0), (50, 50)), steps=12_500, dt=0.003)
    result.arrays()      # NumPy (5, 2, species, rows, cols), axes in the order of `vary`
    result.table         # one dict per member: its parameter values and pattern descriptors
    result.save("map.png")   # montage + map.csv + map.json + map.npz

The sweep in four rooms: what varies and each member's model (`_sweep_members`), this entry
point (the members' starts and keys, checking every member before the run), the batched
execution over chunks, devices and hosts (`_batch`), and the result with its table and
files (`_sweep_result`). A member is `model.replace(**its_values)` (and `growth` with its
rate), built inside the compiled batch from traced values: the sweep is a vmap over
constructors of models. A member that blows up is recorded (class "unstable", with the
first non-finite step), never raised.

Randomness. With `state=` every member starts from that one state (the paper compares
parameters from identical initial conditions). With `state=None, shape=...` each member gets
its own start: member i uses the key k_i = fold_in(key, i) (or `key` itself for every
member with `keys="shared"`); its initial state is `initial_state(model, fold_in(k_i, 0),
shape, capacity)` and its run (growth, sources) uses `fold_in(k_i, 1)`. `result.member(i)`
gives back exactly these inputs, so `simulate(**result.member(i).kwargs())` reproduces it.

Several hosts: see `_batch` (call `jax.distributed.initialize()` first, then `sweep` with
the same arguments in every process; every process returns the full result).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ._batch import run_batched
from ._descriptors import SETTLE_TOL
from .domains import Lattice
from ._growth import Growth
from ._initial import initial_state
from .models import AbstractModel
from ._bounds import bounds_policy
from ._checks import check_finite, check_range, check_shape, check_step_counter
from .solvers import Euler, SteadyState, as_solver, until_to_dict
from ._serialise import bounds_to_data, growth_to_dict, key_to_data, model_to_dict, source_to_dict
from ._files import to_jsonable
from ._state import State
from ._sweep_members import DT, GROWTH_RATE, label, member_model, sweep_members, with_growth_rate
from ._sweep_result import SweepResult, member_table, species_index


def sweep(model: AbstractModel, vary, state: State | None = None, steps: int = 0, dt=None, boundary: str = "wrap",
          batch_size: int | None = None, devices=None, *, vmap_size: int | None = None, key=None, shape=None,
          capacity=None, keys: str = "per-member", stencil: str = "nine-point", bounds="clip",
          growth: Growth | None = None, sources=(), species=-1, settle_steps: int | None = None,
          settle_tol: float = SETTLE_TOL, describe_members: bool = True, check_dt: bool = True,
          progress: bool = False, solver=None, until=None) -> SweepResult:
    """Run `model` for every parameter set of `vary`, batched with `jax.vmap`; return a `SweepResult`.

    Args:
        model: the base model; every member is `model.replace(**its values)`.
        vary: a grid `{"ratio": [4, 8, 12], "upper_a": [6.2, 4.4]}` (the product of the lists,
            C order: the last name varies fastest) or an explicit list of parameter sets
            `[{"ratio": 4.2, "upper_a": 6.2}, {"ratio": 40}]` (names a set leaves out keep the
            base value). Names: the model's `parameters()` (limits as `lower_a`, `upper_b`,
            ...), `dt` (per-member time step, same `steps`) and `growth_rate` (with `growth`).
        state: one initial State shared by every member (identical initial conditions), or a
            State batched over the members (leading axis n), or None to give each member its
            own random start `initial_state(model, ..., shape, capacity)` (needs `key`, `shape`).
        steps, dt, boundary, stencil, bounds, growth, sources, solver, until: as in `simulate`
            (with `until`, each member stops on its own step, and no settle tail is run
            unless `settle_steps` asks for one);
            `dt` is checked against the solver's criterion (for Euler the explicit limit) for
            every member unless `check_dt=False`. A solver other than Euler runs the members
            vmapped, not in lanes.
        batch_size: members per compiled chunk (None: about 512K lattice values per device on
            CPU, e.g. 16 members of 2 x 128 x 128, and at most an equal share per core; 32M
            values per device on GPU/TPU).
            It is rounded up to a multiple of the number of devices; the last chunk is padded
            with copies of its last member, so every chunk reuses one compiled program.
        devices: None (all local devices), a number of local devices, or a list of devices: the
            batch axis of every chunk is sharded over a 1D `Mesh` of them ("batch").
        vmap_size: members advanced together by one vmapped step; the rest of a chunk runs
            sub-batch after sub-batch in the same program (`lax.map`). None: the whole chunk
            on accelerators and several devices; on a single CPU device, groups of 8 float32
            members in the vector lanes of one array (4 float64; built-in models without
            parameter maps, growth or sources), else one member at a time, with one thread per
            core running chunks side by side. Results do not depend on it (lanes agree with a
            lone run to float rounding; see `morphojax/_lanes.py`).
        key: a `jax.random` key or an int seed: member i uses fold_in(key, i) (see module docs),
            or `key` itself for every member with `keys="shared"`. Needed for per-member
            starts, growth and sources.
        species: the species described and shown (name or index; default the last).
        settle_steps: the run's last steps over which `change` (and `settled`) are measured
            (default steps // 10); `settle_tol`: settled when change < settle_tol.
        describe_members: compute the pattern descriptors (NumPy/scikit-image on the host).
        progress: a progress bar over chunks.
    """
    if not isinstance(model, AbstractModel):
        raise ValueError(f"sweep: model must be a morphojax model such as Turing(...) (got {type(model).__name__})")
    if not isinstance(steps, (int, np.integer)) or isinstance(steps, bool) or steps < 0:
        raise ValueError(f"sweep: steps must be a non-negative integer (got {steps!r})")
    if dt is None:
        raise ValueError("sweep: dt is required (see max_stable_dt for the largest stable value)")
    check_finite(dt, "sweep.dt")
    check_range(dt, "sweep.dt", low=0.0, low_open=True)
    if growth is not None and not isinstance(growth, Growth):
        raise ValueError(f"sweep: growth must be a Growth (got {type(growth).__name__})")
    if keys not in ("per-member", "shared"):
        raise ValueError(f"sweep: keys must be 'per-member' or 'shared' (got {keys!r})")
    lattice = Lattice(stencil, boundary)
    boundary, stencil = lattice.boundary, lattice.stencil
    steps = int(steps)
    # with a stopping rule the members stop on their own; a settle tail would restart them
    tail = (0 if until is not None else min(steps, max(1, steps // 10))) if settle_steps is None else int(settle_steps)
    if not 0 <= tail <= steps:
        raise ValueError(f"sweep: settle_steps must lie in [0, steps={steps}] (got {settle_steps!r})")
    # sizes before anything is built or compiled: the step counter (int32), the member count and
    # the memory of the run (`check_members`)
    check_step_counter(np.max(np.asarray(state.step)) if isinstance(state, State) else 0, steps, "sweep: steps")
    names, axes, values, _ = sweep_members(model, vary, growth, dt, shape=_member_lattice(state, shape, capacity),
                                           species=model.n_species)
    n = len(values[names[0]])
    sources = tuple(sources or ())
    seed = None
    if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
        seed, key = int(key), jax.random.key(int(key))
    if (growth is not None or sources) and key is None:
        raise ValueError("sweep: key is required with growth or sources (they draw random numbers)")
    starts = _Starts.make(model, state, n, key, keys, shape, capacity)
    probe = starts.probe
    if model.n_species != probe.n_species:
        raise ValueError(f"sweep: {type(model).__name__} evolves {model.n_species} species {model.species} but the "
                         f"state has {probe.n_species} ({', '.join(probe.names)})")
    if growth is not None and not probe.growable:
        raise ValueError("sweep: growth needs a state with room to grow: State.from_arrays(..., capacity=(rows, cols)) "
                         "or shape=..., capacity=... for per-member starts")
    solver = as_solver(solver)
    solver.check(lattice, model, dynamic=growth is not None or probe.growable, sources=tuple(sources or ()),
                 fields=probe.fields, bounds=bounds_policy(bounds))
    if until is not None and not isinstance(until, SteadyState):
        raise ValueError(f"sweep: until must be None or mj.SteadyState(tol=...) (got {until!r})")
    _validate_members(model, growth, dt, values, names, probe, steps, lattice, check_dt and isinstance(solver, Euler))
    spec = species_index(probe.names, species)

    member_keys = None
    if key is not None:
        member_keys = jax.vmap(lambda i: jax.random.fold_in(key, i))(jnp.arange(n)) if keys == "per-member" \
            else jax.vmap(lambda i: key)(jnp.arange(n))
    run = run_batched(model, growth, sources, starts, member_keys, values, dt, steps=steps, tail=tail,
                      boundary=boundary, stencil=stencil, bounds=bounds, batch_size=batch_size, devices=devices,
                      vmap_size=vmap_size, progress=progress, solver=solver, until=until)

    config = {
        "model": model_to_dict(model), "steps": steps, "dt": to_jsonable(dt), "boundary": boundary,
        "stencil": stencil, "bounds": bounds_to_data(bounds), "solver": solver.to_dict(),
        "until": until_to_dict(until),
        "growth": growth_to_dict(growth) if growth is not None else None,
        "sources": [source_to_dict(s) for s in sources], "settle_steps": tail, "settle_tol": settle_tol,
        "keys": keys, "seed": seed, "key_data": key_to_data(key), "shape": list(probe.shape),
        "capacity": list(probe.capacity) if probe.growable else None, "growable": probe.growable,
        "start_step": int(np.asarray(probe.step)), "start_time": float(np.asarray(probe.time)),
        "initial": starts.kind, "batch_size": run.chunk, "vmap_size": run.inner, "lanes": run.lanes,
        "devices": [str(d) for d in run.devices], "processes": jax.process_count(),
    }
    result = SweepResult(model=model, names=names, axes=axes, values=values, fields=run.fields, size=run.size,
                         blowup_step=run.blowup_step.astype(np.int64), overflow=run.overflow.astype(bool),
                         change=run.change.astype(float), table=[], config=config, species=probe.names,
                         member_devices=run.member_devices, sharding=run.sharding, seconds=run.seconds,
                         initial=starts.state, growth=growth, sources=sources, key=key, bounds=bounds)
    result.table = member_table(result, spec, boundary == "wrap", settle_tol, describe_members)
    return result


def _member_lattice(state, shape, capacity):
    """The lattice (its capacity) one member steps, from the arguments alone (nothing built);
    None when they give none (`_Starts.make` then refuses them)."""
    if state is None:
        if shape is None:
            return None
        if capacity is not None:
            return check_shape(capacity, "sweep: capacity")
        return check_shape(shape, "sweep: shape")
    if isinstance(state, State) and state.fields.ndim in (3, 4):
        return tuple(state.fields.shape[state.fields.ndim - 2:])
    return None


@dataclasses.dataclass
class _Starts:
    """Where the members' initial states come from: one shared State, a batched State (one per
    member), or per-member random starts built chunk by chunk from the member keys."""

    kind: str  # "given" (one State for all), "shared-key" (one start from the key), "batched" or "per-member"
    state: State | None  # the shared or batched State (None for per-member starts)
    probe: State  # one member's start (shapes, species, capacity)
    build: Any = None  # key -> State, for per-member starts

    @property
    def shared(self) -> bool:
        return self.kind in ("given", "shared-key")

    @classmethod
    def make(cls, model, state, n, key, keys, shape, capacity):
        if state is None:
            if shape is None or key is None:
                raise ValueError("sweep: give a shared initial `state`, or `shape` and `key` for per-member starts")
            if keys == "shared":
                shared = initial_state(model, jax.random.fold_in(key, 0), shape, capacity=capacity)
                return cls("shared-key", shared, shared)
            build = lambda k: initial_state(model, k, shape, capacity=capacity)  # noqa: E731
            return cls("per-member", None, build(jax.random.key(0)), build)
        if not isinstance(state, State):
            raise ValueError(f"sweep: state must be a morphojax State or None (got {type(state).__name__})")
        if state.fields.ndim == 3:
            return cls("given", state, state)
        if state.fields.ndim == 4:
            if state.fields.shape[0] != n:
                raise ValueError(f"sweep: the batched state has {state.fields.shape[0]} members; the sweep has {n}")
            return cls("batched", state, state.frame(0))
        raise ValueError("sweep: state.fields must be (species, rows, cols), or (n, species, rows, cols) for one "
                         "start per member")

    def chunk(self, idx, member_keys):
        """(states for the members `idx`, their vmap axis): None for a shared state."""
        if self.shared:
            return self.state, None
        if self.kind == "batched":
            return jax.tree_util.tree_map(lambda x: x[idx], self.state), 0
        init_keys = jax.vmap(lambda k: jax.random.fold_in(k, 0))(member_keys[idx])
        return jax.vmap(self.build)(init_keys), 0


# ---- checking every member before the run ------------------------------------------------------
def _validate_members(model, growth, dt, values, names, probe, steps, lattice, check_dt):
    """Check every member concretely: the models' own checks, dt stability, growth capacity.

    Fast path: one model whose varied parameters are (1, n) maps holds every member at once
    (the models' checks are elementwise); if that fails or cannot be built, each member is
    built alone, which also names the first bad member in the error.
    """
    n = len(values[names[0]])
    if n > 1:
        try:
            _validate_at_once(model, growth, dt, values, names, probe, steps, lattice, check_dt)
            return
        except (ValueError, TypeError):
            pass
    for i in range(n):
        vals = {k: float(values[k][i]) for k in names}
        try:
            m, g, dt_i = member_model(model, growth, dt, vals)
            if DT in vals and not dt_i > 0:
                raise ValueError(f"dt must be > 0 (got {dt_i:g})")
            if check_dt:
                lattice.check_dt(dt_i, m.max_diffusion())
            if g is not None:
                g.check_capacity(probe, steps, dt_i)
        except ValueError as err:
            raise ValueError(f"sweep member {i} ({label(vals)}): {err}") from None


def _validate_at_once(model, growth, dt, values, names, probe, steps, lattice, check_dt):
    n = len(values[names[0]])
    params = {k: v for k, v in values.items() if k not in (DT, GROWTH_RATE)}
    m = model.replace(**{k: np.asarray(v, float).reshape(1, n) for k, v in params.items()}) if params else model
    dts = np.broadcast_to(np.asarray(values.get(DT, dt), float), (n,))
    if not (dts > 0).all():
        raise ValueError("a dt is not positive")
    if check_dt:
        d = np.asarray(m.diffusion(), float)
        d = d.reshape(d.shape[0], -1)
        dmax = d.max(axis=0) if d.shape[1] == n else np.full(n, d.max())
        limits = np.array([lattice.max_stable_dt(float(x)) for x in np.unique(dmax)])
        limit = limits[np.searchsorted(np.unique(dmax), dmax)]
        if (dts > limit).any():
            raise ValueError("a dt is beyond the stability limit")
    if growth is not None:
        rates = np.broadcast_to(np.asarray(values.get(GROWTH_RATE, np.asarray(growth.rate)), float), (n,))
        for rate, dt_i in set(zip(rates.tolist(), dts.tolist())):
            with_growth_rate(growth, rate).check_capacity(probe, steps, dt_i)

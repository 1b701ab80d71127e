"""Multi-phase experiments as plain data, run, checkpointed and resumed.

An `Experiment` is an initial state (`Initial`) and a sequence of `Phase`s, each with its
model, dt, steps, boundary, growth and sources; the final state of one phase is the
initial state of the next, and species can be added (the leopard's C starts as a copy
of B) or dropped between phases. Everything converts to and from JSON, and is saved
with every result, so a run can be reproduced or resumed from its `.npz` checkpoint.

Randomness: one root key per run (`seed`); the initial state uses fold_in(root, 0) and
phase i uses fold_in(root, i + 1), whose per-step keys are fold_in(phase key, step).
A resumed run therefore draws exactly the numbers the uninterrupted run would have.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import Any

import jax

from . import _initial
from ._checks import check_count, check_range, is_concrete
from .domains import Lattice, as_domain
from ._colours import Gradient
from ._files import dumps, from_jsonable, to_jsonable
from ._growing_mesh import MeshGrowth
from ._serialise import (bounds_from_data, bounds_to_data, domain_from_dict, domain_to_dict, growth_from_dict,
                         growth_to_dict, key_from_data, key_to_data, load_npz, model_from_dict, model_to_dict,
                         save_npz, source_from_dict, source_to_dict)
from .models import AbstractModel
from ._simulate import rollout, simulate
from .solvers import SteadyState, as_solver, solver_from_dict, solver_to_dict, until_from_dict, until_to_dict
from ._state import State
from ._version import __version__


@dataclasses.dataclass(frozen=True)
class Initial:
    """How the starting state is made.

    kind: "paper" (A = 4, B ~ U[4, 5)), "thesis" (both ~ U[mean - dev, mean + dev), params
    (dev, mean)), "constant" (params: one value per species), "uniform" (params: a value or
    (low, high) per species), "gray-scott" (params: (square, noise) on a lattice; on a mesh
    (noise, seeded vertex indices), see `gray_scott_state`).
    shape: (rows, cols), or (vertices,) for a mesh; capacity: room to grow (lattices), or
    None for a fixed lattice.
    """

    kind: str
    shape: tuple
    capacity: tuple | None = None
    params: tuple = ()
    names: tuple | None = None

    def build(self, key) -> State:
        """The initial State for a `jax.random` key (same key, same state)."""
        shape, cap = tuple(self.shape), (tuple(self.capacity) if self.capacity else None)
        if self.kind == "paper":
            return _initial.paper_state(key, shape, capacity=cap)
        if self.kind == "thesis":
            dev, mean = (tuple(self.params) + (2.0, 4.0)[len(self.params):])[:2]
            return _initial.thesis_state(key, shape, dev=dev, mean=mean, capacity=cap)
        if self.kind == "constant":
            return _initial.constant_state(shape, *self.params, names=self.names, capacity=cap)
        if self.kind == "uniform":
            specs = [tuple(p) if isinstance(p, (list, tuple)) else p for p in self.params]
            return _initial.random_state(key, shape, *specs, names=self.names, capacity=cap)
        if self.kind == "gray-scott":
            if len(shape) == 1:  # a mesh: (noise, the seeded vertices)
                noise, seeded = (tuple(self.params) + (0.02, None)[len(self.params):])[:2]
                return _initial.gray_scott_state(key, shape, noise=noise, seeded=seeded)
            square, noise = (tuple(self.params) + (0.2, 0.02)[len(self.params):])[:2]
            return _initial.gray_scott_state(key, shape, square=square, noise=noise, capacity=cap)
        raise ValueError(f"unknown initial kind {self.kind!r}; allowed: paper, thesis, constant, uniform, gray-scott")

    def to_dict(self) -> dict:
        """Plain-data (JSON-ready) form of the initial condition; `Initial.from_dict` rebuilds it."""
        return to_jsonable(dataclasses.asdict(self))

    @classmethod
    def from_dict(cls, d: dict) -> "Initial":
        d = from_jsonable(dict(d))
        return cls(kind=d["kind"], shape=tuple(d["shape"]),
                   capacity=tuple(d["capacity"]) if d.get("capacity") else None,
                   params=tuple(tuple(p) if isinstance(p, list) else p for p in d.get("params", ())),
                   names=tuple(d["names"]) if d.get("names") else None)


@dataclasses.dataclass(frozen=True)
class Phase:
    """One stage of an experiment (model parameters fixed within it).

    add_species: species added before the phase, as (name, source) pairs where source is
        the name of an existing species to copy or a constant.
    keep: species kept (in this order) before the phase, after additions; None keeps all.
    frames: snapshots to save during the phase (for `--frames`): a number of evenly spaced
        ones, or a tuple of the phase steps after which to take them.
    capacity: reallocate the state to this (rows, cols) capacity before the phase, so a
        static phase runs on its own small lattice and only growing phases carry room.
    solver: how the phase steps (`mj.Euler()` by default; `mj.ETDRK(...)` or `mj.IMEX(...)`
        for a phase without growth or sources, see `simulate`).
    until: a stopping rule (`mj.SteadyState(tol)`): the phase's run, and each of its pieces
        between checkpoints and frames, stops once settled; the next phase starts from there.
    """

    model: AbstractModel
    steps: int
    dt: float
    boundary: str | None = None
    stencil: str | None = None
    bounds: Any = "clip"
    growth: Any = None
    sources: tuple = ()
    add_species: tuple = ()
    keep: tuple | None = None
    frames: Any = 0
    name: str = ""
    capacity: tuple | None = None
    domain: Any = None
    solver: Any = None
    until: Any = None

    def __post_init__(self):
        from ._growing_mesh import MeshGrowth
        from ._growth import Growth, Source

        if not isinstance(self.model, AbstractModel):
            raise ValueError(f"Phase.model must be a morphojax model such as mj.Turing(...) (got {self.model!r})")
        check_count(self.steps, "Phase.steps", "steps")
        check_range(self.dt, "Phase.dt", low=0.0, low_open=True)
        if self.growth is not None and not isinstance(self.growth, (Growth, MeshGrowth)):
            raise ValueError(f"Phase.growth must be None, a Growth(rate=...) or, on a mesh, a MeshGrowth(...) "
                             f"(got {self.growth!r})")
        sources = (self.sources,) if isinstance(self.sources, Source) else tuple(self.sources or ())
        for src in sources:
            if not isinstance(src, Source):
                raise ValueError(f"Phase.sources must be Source(...) objects (got {src!r})")
        object.__setattr__(self, "sources", sources)  # a single Source is accepted as (Source,)
        object.__setattr__(self, "domain", _phase_domain(self.domain, self.stencil, self.boundary))
        object.__setattr__(self, "solver", as_solver(self.solver))
        if self.until is not None and not isinstance(self.until, SteadyState):
            raise ValueError(f"Phase.until must be None or mj.SteadyState(tol=...) (got {self.until!r})")
        if isinstance(self.domain, Lattice):  # the shorthands stay readable as the lattice's
            object.__setattr__(self, "stencil", self.domain.stencil)
            object.__setattr__(self, "boundary", self.domain.boundary)

    def prepare(self, state: State) -> State:
        """Apply the changes that happen at the start of the phase: reallocation to
        `capacity` (outside compiled code), then species additions and selection."""
        if self.capacity is not None and tuple(self.capacity) != tuple(state.capacity):
            state = state.with_capacity(self.capacity)
        for name, source in self.add_species:
            if isinstance(source, str):
                state = state.with_species(name, copy_of=source)
            else:
                state = state.with_species(name, values=source)
        if self.keep is not None:
            state = state.select(self.keep)
        return state

    def to_dict(self) -> dict:
        """Plain-data (JSON-ready) form of the phase, with its model, domain, growth and
        sources; a lattice is also written as its `boundary`/`stencil` shorthands, which
        files from before domains existed hold alone. `Phase.from_dict` rebuilds it."""
        return to_jsonable({
            "name": self.name, "model": model_to_dict(self.model), "steps": self.steps, "dt": self.dt,
            "boundary": self.boundary, "stencil": self.stencil, "domain": domain_to_dict(self.domain),
            "bounds": bounds_to_data(self.bounds),
            "growth": growth_to_dict(self.growth) if self.growth is not None else None,
            "sources": [source_to_dict(s) for s in self.sources],
            "add_species": [list(p) for p in self.add_species],
            "keep": list(self.keep) if self.keep is not None else None, "frames": self.frames,
            "capacity": list(self.capacity) if self.capacity is not None else None,
            "solver": solver_to_dict(self.solver), "until": until_to_dict(self.until),
        })

    @classmethod
    def from_dict(cls, d: dict) -> "Phase":
        d = from_jsonable(dict(d))
        domain = domain_from_dict(d["domain"]) if d.get("domain") else None
        return cls(
            model=model_from_dict(d["model"]), steps=int(d["steps"]), dt=float(d["dt"]),
            boundary=None if domain else d.get("boundary"), stencil=None if domain else d.get("stencil"),
            domain=domain, bounds=bounds_from_data(d.get("bounds", "clip")),
            growth=growth_from_dict(d["growth"]) if d.get("growth") else None,
            sources=tuple(source_from_dict(s) for s in d.get("sources", [])),
            add_species=tuple(tuple(p) for p in d.get("add_species", [])),
            keep=tuple(d["keep"]) if d.get("keep") is not None else None,
            frames=tuple(d["frames"]) if isinstance(d.get("frames"), list) else int(d.get("frames", 0)),
            name=d.get("name", ""), capacity=tuple(d["capacity"]) if d.get("capacity") else None,
            solver=solver_from_dict(d.get("solver")), until=until_from_dict(d.get("until")),
        )


def _phase_domain(domain, stencil, boundary):
    """A phase's domain from `domain` or the lattice shorthands. A phase's fields are echoed
    by `dataclasses.replace`, so shorthands that agree with a given lattice are accepted;
    ones that disagree are an error."""
    if domain is None:
        return as_domain(stencil=stencil, boundary=boundary)
    if isinstance(domain, Lattice) and (stencil is not None or boundary is not None):
        # only the stencil and boundary are compared: a lattice's polarity or maps have no shorthand
        given = as_domain(stencil=domain.stencil if stencil is None else stencil,
                          boundary=domain.boundary if boundary is None else boundary)
        if (given.stencil, given.boundary) != (domain.stencil, domain.boundary):
            raise ValueError(f"Phase: domain {domain} and the shorthands stencil={stencil!r}, boundary={boundary!r} "
                             "disagree; give only domain=")
        return domain
    return as_domain(domain, stencil=stencil, boundary=boundary)


@dataclasses.dataclass(frozen=True)
class Experiment:
    """An initial state and a sequence of phases, with how to show the result.

    show: the species to render, or "melanin" for the leopard's combined B/C texture.
    """

    name: str
    initial: Initial
    phases: tuple
    description: str = ""
    figure: str = ""
    show: str = "b"
    cmap: Any = "inferno"

    def __post_init__(self):
        from ._growing_mesh import MeshGrowth

        grows = [i for i, p in enumerate(self.phases) if isinstance(p.growth, MeshGrowth)]
        if grows and grows[0] != len(self.phases) - 1:
            raise ValueError(f"Experiment {self.name!r}: phase {grows[0] + 1} grows its mesh (MeshGrowth) and is not "
                             "the last: a later phase would run on the mesh it started from; a growing mesh's "
                             "phase must be the experiment's last")

    @property
    def total_steps(self) -> int:
        return sum(p.steps for p in self.phases)

    def final_domain(self, state):
        """The domain the last phase leaves `state` on: its domain, or for a growing mesh
        (`MeshGrowth`) that mesh grown for the steps the state has done in the phase (the
        phases before it counted whole), rebuilt by replaying its events."""
        from ._growing_mesh import MeshGrowth

        last = self.phases[-1]
        if not isinstance(last.growth, MeshGrowth):
            return last.domain
        done = min(max(int(state.step) - sum(p.steps for p in self.phases[:-1]), 0), last.steps)
        mesh = last.growth.grown(last.domain, done, last.dt, capacity=state.capacity[0])
        if mesh.n_vertices != state.shape[0]:
            raise ValueError(f"{self.name}: the state has {state.shape[0]} vertices, the mesh grown for {done} steps "
                             f"of the last phase {mesh.n_vertices}: the state is not this experiment's")
        return mesh

    def to_dict(self) -> dict:
        """Plain-data (JSON-ready) form of the experiment: every phase, model, growth and
        source; `Experiment.from_dict` rebuilds it."""
        cmap = self.cmap if isinstance(self.cmap, str) else [list(s) for s in self.cmap.stops]
        return {"name": self.name, "description": self.description, "figure": self.figure,
                "show": self.show, "cmap": to_jsonable(cmap), "initial": self.initial.to_dict(),
                "phases": [p.to_dict() for p in self.phases]}

    @classmethod
    def from_dict(cls, d: dict) -> "Experiment":
        cmap = d.get("cmap", "inferno")
        if isinstance(cmap, list):
            cmap = Gradient([(p, tuple(c)) for p, c in cmap])
        return cls(name=d["name"], initial=Initial.from_dict(d["initial"]),
                   phases=tuple(Phase.from_dict(p) for p in d["phases"]), description=d.get("description", ""),
                   figure=d.get("figure", ""), show=d.get("show", "b"), cmap=cmap)


# Phases and experiments are pytrees: models, growth and sources are their leaves (so an
# experiment can be passed through jax.jit and vmapped over), the rest is static data.
jax.tree_util.register_dataclass(
    Phase, data_fields=["model", "growth", "sources", "domain"],
    meta_fields=["steps", "dt", "boundary", "stencil", "bounds", "add_species", "keep", "frames", "name", "capacity",
                 "solver", "until"])
jax.tree_util.register_dataclass(
    Experiment, data_fields=["phases"], meta_fields=["name", "initial", "description", "figure", "show", "cmap"])


@dataclasses.dataclass
class Result:
    """What `run_experiment` returns: the final state, the experiment, snapshots and timings.

    frames: list of (label, State) snapshots (when asked for), in order.
    metadata: everything saved next to the arrays (seed, phase, steps, timings...).
    """

    state: State
    experiment: Experiment
    frames: list
    metadata: dict

    def image(self, scale: int = 1):
        """The final picture as a PIL image, rendered as the experiment shows it; `scale` pixels per lattice cell."""
        from ._render import render_experiment

        return render_experiment(self.state, self.experiment, scale=scale)

    def save(self, path) -> Path:
        """Write the result `.npz` (final species cropped to the active lattice, state, metadata); returns the path."""
        return save_npz(path, self.state, self.metadata)

    def describe(self):
        """`describe` of the final pattern the experiment shows (B for the melanin texture),
        periodic when the last phase wraps: its class, spots, holes, wavelength."""
        from ._descriptors import describe

        exp = self.experiment
        shown = self.state.array("b" if exp.show == "melanin" else exp.show)
        return describe(shown, wrap=exp.phases[-1].boundary == "wrap")


def check_progress(experiment: Experiment, meta: dict) -> None:
    """Refuse a checkpoint of `experiment` whose step disagrees with where its run says it
    stands. Every phase takes exactly its `steps` unless it stops at a steady state or steps
    adaptively, so up to the first such phase the state's step is the steps of the phases
    done plus `phase_step`: a checkpoint claiming more phases done than its state ran
    (a tampered `phase`) is refused here instead of being written out as the final result."""
    run, step = meta.get("run") or {}, meta.get("step")
    if step is None:
        return
    phase, phase_step = int(run.get("phase", 0)), int(run.get("phase_step", 0))
    done = experiment.phases[:phase + 1] if phase < len(experiment.phases) else experiment.phases
    if any(p.until is not None or getattr(p.solver, "adaptive", False) for p in done):
        return
    expected = sum(p.steps for p in experiment.phases[:phase]) + phase_step
    if int(step) != expected:
        raise ValueError(f"run fields 'phase' ({phase}) and 'phase_step' ({phase_step}) put this checkpoint at step "
                         f"{expected} of its experiment, but metadata field 'step' is {step}: the file disagrees "
                         "with itself")


def run_experiment(experiment: Experiment, seed: int = 0, *, key=None, frames: bool = False,
                   progress: bool = False, checkpoint_path=None, checkpoint_every: int | None = None, resume=None,
                   stop_after: int | None = None, grad_window: int | None = None, throw: bool = True) -> Result:
    """Run every phase of `experiment` from its initial state (or resume a checkpoint).

    Pure in (experiment, key) like `simulate`: usable under `jax.jit`, `jax.vmap` and
    `jax.grad` (with frames, checkpoints and progress off).

    Args:
        seed: the run's random seed; the same seed gives the same result.
        key: a `jax.random` key to use instead of `seed` (e.g. a traced key under vmap).
        frames: keep each phase's snapshots (`Phase.frames` of them) in `Result.frames`.
        progress: progress bars (per phase).
        checkpoint_path / checkpoint_every: write an `.npz` checkpoint every N steps (and at
            phase ends) that `resume` accepts.
        resume: a checkpoint path (or (State, metadata) from `load_npz`) to continue from; the
            result equals that of an uninterrupted run with the same seed (or key: a run
            started with `key=` records it, and resumes with it unless given another).
        stop_after: stop after this many steps in total (for tests of resuming).
        grad_window: differentiate only through the last `grad_window` steps of the run; the
            state before them is treated as a constant (truncated backpropagation, see the
            fitting documentation for why long horizons need it).
        throw: raise `SimulationError` when a phase blows up or overflows its capacity (as
            `simulate`); False returns the state as it is (a fit scores such a point as bad
            instead of stopping).
    """
    if stop_after is not None:
        check_range(stop_after, "run_experiment.stop_after (steps)", low=1)
    if checkpoint_every is not None:
        check_range(checkpoint_every, "run_experiment.checkpoint_every (steps)", low=1)
    if resume is not None:
        state, meta = load_npz(resume) if not isinstance(resume, tuple) else resume
        saved = meta.get("experiment")
        if saved is not None and is_concrete([p.model for p in experiment.phases]) and \
                _what_runs(saved) != _what_runs(experiment.to_dict()):
            raise ValueError(
                f"run_experiment.resume: the checkpoint was written by another experiment "
                f"({saved.get('name')!r}, or the same one with other parameters) than {experiment.name!r}; "
                "resume it with mj.load_experiment(meta), as `morphojax resume` does"
            )
        check_progress(experiment, meta)
        run = meta.get("run", {})
        seed = int(run["seed"]) if run.get("seed") is not None else seed
        key = key_from_data(run.get("key")) if key is None else key
        start_phase, phase_step = int(run.get("phase", 0)), int(run.get("phase_step", 0))
        origin = run.get("phase_origin")
    else:
        start_phase, phase_step, origin = 0, 0, None
    root = jax.random.key(int(seed)) if key is None else key
    record = {"seed": int(seed)} if key is None else {"seed": None, "key": key_to_data(key)}
    if resume is None:
        state = experiment.initial.build(jax.random.fold_in(root, 0))
    steps_before = sum(p.steps for p in experiment.phases[:start_phase])
    window_start = None if grad_window is None else max(0, experiment.total_steps - int(grad_window))
    done_total = 0
    snapshots: list = []
    timings = []
    t_start = time.perf_counter()
    for i in range(start_phase, len(experiment.phases)):
        phase = experiment.phases[i]
        if phase_step == 0:
            state = phase.prepare(state)
            origin = int(state.step) if is_concrete(state.step) else state.step
        kwargs = dict(domain=phase.domain, bounds=phase.bounds, growth=phase.growth, solver=phase.solver,
                      until=phase.until,
                      sources=phase.sources, key=jax.random.fold_in(root, i + 1), origin=origin, throw=throw,
                      progress=(phase.name or f"phase {i + 1}") if progress else False)
        marks = set(_frame_steps(phase)) if frames and phase.frames else set()
        saves = set(range(phase_step + checkpoint_every, phase.steps, checkpoint_every)) if checkpoint_every else set()
        cuts = {phase.steps} | marks | saves
        if stop_after is not None:
            cuts.add(phase_step + max(0, stop_after - done_total))
        if window_start is not None and steps_before < window_start < steps_before + phase.steps:
            cuts.add(window_start - steps_before)
        t0 = time.perf_counter()
        simple = (phase_step == 0 and cuts == {phase.steps} | marks and checkpoint_path is None and stop_after is None
                  and window_start is None and phase.until is None and not getattr(phase.solver, "adaptive", False)
                  and not isinstance(phase.growth, MeshGrowth))  # a growing mesh's snapshots differ in shape
        every = _even_spacing(marks, phase.steps) if simple else None
        if every is not None:
            # evenly spaced snapshots and nothing else to stop for: one rollout takes them
            # all in one compiled call (simulating piece by piece compiles a growing phase's
            # every piece anew: its lattice, and so its plan, differs from piece to piece),
            # and the key schedule makes its states those of the pieces
            n = phase.steps // every
            state, taken = rollout(phase.model, state, n * every, phase.dt, every, **kwargs)
            snapshots += [(f"{phase.name or f'phase {i + 1}'} step {(j + 1) * every}", taken.frame(j))
                          for j in range(n)]
            done_total += n * every
            phase_step = n * every
        for cut in sorted(c for c in cuts if phase_step < c <= phase.steps):
            state = simulate(phase.model, state, cut - phase_step, phase.dt, **kwargs)
            done_total += cut - phase_step
            phase_step = cut
            if window_start is not None and steps_before + cut <= window_start:
                state = jax.lax.stop_gradient(state)
            if cut in marks:
                snapshots.append((f"{phase.name or f'phase {i + 1}'} step {cut}", state))
            at_end = cut == phase.steps
            if checkpoint_path is not None and (cut in saves or at_end):
                _write(checkpoint_path, state, experiment, record, i + 1 if at_end else i, 0 if at_end else cut,
                       origin, timings)
            if stop_after is not None and done_total >= stop_after and not at_end:
                timings.append({"phase": phase.name or str(i + 1), "steps": cut, "seconds": time.perf_counter() - t0})
                return Result(state, experiment, snapshots, _meta(experiment, record, i, cut, origin, timings))
        timings.append({"phase": phase.name or str(i + 1), "steps": phase.steps, "seconds": time.perf_counter() - t0})
        steps_before += phase.steps
        phase_step = 0
        if stop_after is not None and done_total >= stop_after and i + 1 < len(experiment.phases):
            return Result(state, experiment, snapshots, _meta(experiment, record, i + 1, 0, origin, timings))
    meta = _meta(experiment, record, len(experiment.phases), 0, origin, timings)
    meta["run"]["seconds"] = time.perf_counter() - t_start
    return Result(state, experiment, snapshots, meta)


def _what_runs(data: dict) -> dict:
    """The parts of an experiment's plain data that decide its result (its initial state and
    phases, less their names and snapshot settings), normalised through JSON."""
    # a lattice is said twice (its shorthands and its domain); files written before domains
    # existed have only the shorthands, so the shorthands decide
    def decides(p):
        lattice = (p.get("domain") or {}).get("type", "Lattice") == "Lattice"
        return {k: v for k, v in p.items() if k not in ("name", "frames") and not (k == "domain" and lattice)}

    phases = [decides(p) for p in data["phases"]]
    return json.loads(dumps({"initial": data["initial"], "phases": phases}))


def _even_spacing(marks: set, steps: int) -> int | None:
    """The spacing of snapshot steps that are every k-th step from k on (the rest of the
    phase, under k steps, after the last), else None."""
    if not marks:
        return None
    every = min(marks)
    return every if marks == set(range(every, steps + 1, every)) else None


def _frame_steps(phase: Phase) -> list[int]:
    """The phase steps after which snapshots are taken."""
    if isinstance(phase.frames, (tuple, list)):
        return sorted(int(m) for m in phase.frames if 0 < int(m) <= phase.steps)
    if phase.frames <= 0 or phase.steps <= 0:
        return []
    every = max(1, phase.steps // int(phase.frames))
    return list(range(every, phase.steps + 1, every))


def _meta(experiment, record, phase, phase_step, origin, timings):
    """`record`: {"seed": int} for a run from a seed, {"seed": None, "key": words} from a key."""
    # under jit/vmap/grad the parameters are tracers: there is nothing concrete to record
    concrete = is_concrete([p.model for p in experiment.phases], [p.growth for p in experiment.phases])
    return {
        "morphojax": __version__,
        "experiment": experiment.to_dict() if concrete else None,
        "run": {**record, "phase": int(phase), "phase_step": int(phase_step),
                "phase_origin": int(origin) if origin is not None and is_concrete(origin) else None,
                "timings": timings},
    }


def _write(path, state, experiment, record, phase, phase_step, origin, timings):
    save_npz(path, state, _meta(experiment, record, phase, phase_step, origin, timings))


def load_experiment(meta: dict) -> Experiment:
    """The experiment saved in a result's metadata."""
    if "experiment" not in meta:
        raise ValueError("this result file does not describe an experiment")
    return Experiment.from_dict(meta["experiment"])


def single_phase(name, model, initial: Initial, steps, dt, *, description="", figure="", show="b",
                 cmap="inferno", frames=4, **phase_kwargs) -> Experiment:
    """Shorthand for a one-phase experiment."""
    phase = Phase(model=model, steps=int(steps), dt=float(dt), frames=frames, name=name, **phase_kwargs)
    return Experiment(name=name, initial=initial, phases=(phase,), description=description, figure=figure,
                      show=show, cmap=cmap)

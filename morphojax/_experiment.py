"""Multi-phase experiments as plain data (running them: `morphojax._run_experiment`).

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
from typing import Any

import jax

from . import _initial
from ._checks import check_count, check_range
from .domains import Lattice, as_domain
from ._colours import Gradient
from ._files import from_jsonable, to_jsonable
from ._growing_mesh import MeshGrowth
from ._serialise import (bounds_from_data, bounds_to_data, domain_from_dict, domain_to_dict, growth_from_dict,
                         growth_to_dict, model_from_dict, model_to_dict, source_from_dict, source_to_dict)
from .models import AbstractModel
from .solvers import SteadyState, as_solver, solver_from_dict, solver_to_dict, until_from_dict, until_to_dict
from ._state import State


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

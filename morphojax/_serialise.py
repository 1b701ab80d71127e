"""The one serialiser: every object to and from plain data (JSON), and the `.npz` files.

Models, domains, bounds, growth, sources, keys, initial states, phases, experiments and
automata; the classes' own `to_dict`/`from_dict` methods call these functions.

Every result morphojax writes carries what is needed to reproduce or resume it: the
species arrays (cropped to the active lattice) plus a JSON `metadata` entry with the
model parameters, the run configuration, the key/seed and the step counter.
JSON here is strict: infinities are written as the strings "inf" / "-inf".
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
from pathlib import Path

import jax
import numpy as np

from ._bounds import Barrier
from ._checks import is_concrete
from .domains import AbstractDomain, HexLattice, Lattice, Mesh
from ._growth import Growth, Source
from .models import (AbstractModel, Bard, Brusselator, Composite, FitzHughNagumo, GiererMeinhardt, GrayScott,
                     Modulated, Modulation, Morphogen, Reaction, Reinforcement, RuleReinforcement, Schnakenberg,
                     ThesisReinforcement, Turing)
from ._state import State

# the models a file can rebuild (a Reaction's file cannot: its function is code)
MODEL_TYPES = {cls.__name__: cls for cls in (Turing, Bard, GrayScott, Reinforcement, FitzHughNagumo, GiererMeinhardt,
                                            Schnakenberg, Brusselator, ThesisReinforcement, RuleReinforcement,
                                            Morphogen)}


def to_jsonable(value):
    """Arrays and numbers to JSON-safe Python (lists, floats, 'inf' strings)."""
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        return to_jsonable(np.asarray(value).tolist())
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return to_jsonable(float(value))
    return value


def from_jsonable(value):
    """Inverse of `to_jsonable` for numbers: 'inf', '-inf', 'nan' strings back to floats."""
    if isinstance(value, dict):
        return {k: from_jsonable(v) for k, v in value.items()}
    if isinstance(value, list):
        return [from_jsonable(v) for v in value]
    if value in ("inf", "-inf", "nan"):
        return float(value)
    return value


def dumps(obj, **kwargs) -> str:
    return json.dumps(to_jsonable(obj), allow_nan=False, **kwargs)


def model_to_dict(model: AbstractModel) -> dict:
    """A model as plain data: {"type": "Turing", "params": {...}} (composites nest)."""
    if isinstance(model, Composite):
        return {"type": "Composite", "species": list(model.species), "parts": [model_to_dict(p) for p in model.parts]}
    if isinstance(model, Modulated):
        return {"type": "Modulated", "model": model_to_dict(model.model),
                "modulations": [{"parameter": m.parameter, "by": m.by,
                                 **{k: to_jsonable(getattr(m, k)) for k in Modulation.FIELDS}}
                                for m in model.modulations]}
    params = {f.name: getattr(model, f.name) for f in dataclasses.fields(model)}
    if isinstance(model, Reaction):  # its function is code: a description stands in for it
        params["fn"] = model.fn.describe()
    return {"type": type(model).__name__, "params": to_jsonable(params)}


def model_from_dict(data: dict) -> AbstractModel:
    kind = data.get("type")
    if kind == "Composite":
        return Composite([model_from_dict(p) for p in data["parts"]], species=data.get("species"))
    if kind == "Modulated":
        return Modulated(model_from_dict(data["model"]), [
            Modulation(m["parameter"], m["by"], *(from_jsonable(m[k]) for k in Modulation.FIELDS))
            for m in data["modulations"]])
    if kind == "Reaction":
        saved = data.get("params", {}).get("fn", {})
        raise ValueError(
            f"this model was saved from mj.Reaction with the function {saved.get('function')!r}; a function is "
            "code, not data, so the file alone cannot rebuild it: build mj.Reaction(fn, params, diffusion, "
            "species=...) with that function and apply the saved parameters with .replace(...)")
    if kind not in MODEL_TYPES:
        raise ValueError(f"unknown model type {kind!r} in saved data; allowed: {', '.join(MODEL_TYPES)}, "
                         "Composite, Modulated")
    params = from_jsonable(dict(data["params"]))
    for lim in ("lower", "upper"):
        if lim in params:
            params[lim] = tuple(np.asarray(v, float) for v in params[lim])
    params = {k: (np.asarray(v, float) if isinstance(v, list) else v) for k, v in params.items()}
    return MODEL_TYPES[kind](**params)


DOMAIN_TYPES = {cls.__name__: cls for cls in (Lattice, HexLattice, Mesh)}


def domain_to_dict(domain: AbstractDomain) -> dict:
    """A domain as plain data: {"type": "Lattice", "params": {...}}, its arrays as lists."""
    params = {f.name: getattr(domain, f.name) for f in dataclasses.fields(domain)}
    return {"type": type(domain).__name__, "params": to_jsonable(params)}


def domain_from_dict(data: dict) -> AbstractDomain:
    kind = data.get("type")
    if kind not in DOMAIN_TYPES:
        raise ValueError(f"unknown domain type {kind!r} in saved data; allowed: {', '.join(DOMAIN_TYPES)}")
    return DOMAIN_TYPES[kind](**from_jsonable(dict(data.get("params", {}))))


def growth_to_dict(g: Growth) -> dict:
    return to_jsonable({"rate": g.rate, "distribution": g.distribution, "row_weights": g.row_weights,
                        "col_weights": g.col_weights, "spread": g.spread, "method": g.method})


def growth_from_dict(d: dict) -> Growth:
    d = from_jsonable(dict(d))
    return Growth(rate=d["rate"], distribution=d.get("distribution", "uniform"),
                  row_weights=d.get("row_weights"), col_weights=d.get("col_weights"),
                  spread=d.get("spread", 1.0 / 6.0), method=d.get("method", "division"))


def source_to_dict(s: Source) -> dict:
    return to_jsonable({"species": s.species, "amplitude": s.amplitude,
                        "region": s.region if s.mask is None else s.mask})


def source_from_dict(d: dict) -> Source:
    region = d.get("region", "center-row")
    return Source(d["species"], d["amplitude"], region if isinstance(region, str) else np.asarray(region))


def bounds_to_data(bounds):
    """"clip" or "barrier" as themselves, `Barrier(k)` as {"barrier": k}."""
    return {"barrier": bounds.k} if isinstance(bounds, Barrier) else bounds


def bounds_from_data(data):
    return Barrier(int(data["barrier"])) if isinstance(data, dict) else data


def initial_to_dict(initial) -> dict:
    return to_jsonable(dataclasses.asdict(initial))


def initial_from_dict(d: dict):
    from ._experiment import Initial

    d = from_jsonable(dict(d))
    return Initial(kind=d["kind"], shape=tuple(d["shape"]),
                   capacity=tuple(d["capacity"]) if d.get("capacity") else None,
                   params=tuple(tuple(p) if isinstance(p, list) else p for p in d.get("params", ())),
                   names=tuple(d["names"]) if d.get("names") else None)


def phase_to_dict(phase) -> dict:
    """A phase with its model, domain, growth and sources; a lattice is also written as its
    `boundary`/`stencil` shorthands, which files from before domains existed hold alone."""
    return to_jsonable({
        "name": phase.name, "model": model_to_dict(phase.model), "steps": phase.steps, "dt": phase.dt,
        "boundary": phase.boundary, "stencil": phase.stencil, "domain": domain_to_dict(phase.domain),
        "bounds": bounds_to_data(phase.bounds),
        "growth": growth_to_dict(phase.growth) if phase.growth is not None else None,
        "sources": [source_to_dict(s) for s in phase.sources],
        "add_species": [list(p) for p in phase.add_species],
        "keep": list(phase.keep) if phase.keep is not None else None, "frames": phase.frames,
        "capacity": list(phase.capacity) if phase.capacity is not None else None,
    })


def phase_from_dict(d: dict):
    from ._experiment import Phase

    d = from_jsonable(dict(d))
    domain = domain_from_dict(d["domain"]) if d.get("domain") else None
    return Phase(
        model=model_from_dict(d["model"]), steps=int(d["steps"]), dt=float(d["dt"]),
        boundary=None if domain else d.get("boundary"), stencil=None if domain else d.get("stencil"),
        domain=domain, bounds=bounds_from_data(d.get("bounds", "clip")),
        growth=growth_from_dict(d["growth"]) if d.get("growth") else None,
        sources=tuple(source_from_dict(s) for s in d.get("sources", [])),
        add_species=tuple(tuple(p) for p in d.get("add_species", [])),
        keep=tuple(d["keep"]) if d.get("keep") is not None else None,
        frames=tuple(d["frames"]) if isinstance(d.get("frames"), list) else int(d.get("frames", 0)),
        name=d.get("name", ""), capacity=tuple(d["capacity"]) if d.get("capacity") else None,
    )


def experiment_to_dict(experiment) -> dict:
    cmap = experiment.cmap if isinstance(experiment.cmap, str) else [list(s) for s in experiment.cmap.stops]
    return {"name": experiment.name, "description": experiment.description, "figure": experiment.figure,
            "show": experiment.show, "cmap": to_jsonable(cmap), "initial": initial_to_dict(experiment.initial),
            "phases": [phase_to_dict(p) for p in experiment.phases]}


def experiment_from_dict(d: dict):
    from ._experiment import Experiment
    from ._render import Gradient

    cmap = d.get("cmap", "inferno")
    if isinstance(cmap, list):
        cmap = Gradient([(p, tuple(c)) for p, c in cmap])
    return Experiment(name=d["name"], initial=initial_from_dict(d["initial"]),
                      phases=tuple(phase_from_dict(p) for p in d["phases"]), description=d.get("description", ""),
                      figure=d.get("figure", ""), show=d.get("show", "b"), cmap=cmap)


def automaton_to_dict(automaton) -> dict:
    """A cellular automaton as the keyword arguments that rebuild it: `type(ca)(**data)`."""
    from .automata import LifeLike, YoungCA

    if isinstance(automaton, YoungCA):
        return {"species": [list(s) for s in automaton.species], "neighbourhood": automaton.neighbourhood,
                "include_self": automaton.include_self, "denominator": int(automaton.denominator),
                "method": automaton.method}
    if isinstance(automaton, LifeLike):
        return {"rule": automaton.rule}
    raise ValueError(f"no plain-data form for automaton {type(automaton).__name__}")


def key_to_data(key):
    """A `jax.random` key (typed or a raw uint32 array) as a JSON list of its words; None
    for no key or a traced one. `key_from_data` rebuilds it."""
    if key is None or not is_concrete(key):
        return None
    try:
        return np.asarray(jax.random.key_data(key)).tolist()
    except (TypeError, ValueError):
        return np.asarray(key).tolist()


def key_from_data(data):
    """The key written by `key_to_data` (a typed key; raw keys draw the same numbers)."""
    return None if data is None else jax.random.wrap_key_data(np.asarray(data, np.uint32))


def save_npz(path, state: State, metadata: dict) -> Path:
    """Write the species arrays (cropped, by name) and JSON metadata to `path`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {f"species_{n}": a for n, a in zip(state.names, state.arrays())}
    meta = dict(metadata)
    meta.setdefault("species", list(state.names))
    meta.setdefault("step", int(state.step))
    meta.setdefault("time", float(state.time))
    meta.setdefault("size", list(state.shape))
    meta.setdefault("capacity", list(state.capacity))
    meta.setdefault("growable", bool(state.growable))
    meta.setdefault("dtype", str(state.fields.dtype))
    return write_npz(path, metadata=np.asarray(dumps(meta)), **arrays)


def write_npz(path, **arrays) -> Path:
    """`np.savez_compressed` that never leaves a half-written file (see `write_atomically`).
    Like NumPy, adds `.npz` when `path` has no such suffix."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")

    def write(tmp):
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, **arrays)

    return write_atomically(path, write)


def write_atomically(path, write) -> Path:
    """Write a file so that a crash never destroys the last good one: `write(temporary)`
    fills a temporary beside `path` (same suffix), which is flushed to disk and then replaces
    `path` in one step; a temporary whose writing failed is removed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def read_npz(path, what: str, parse):
    """Open a morphojax `.npz` and return (metadata, parse(metadata, data)).

    `data` is the open archive; a missing file, or one that is not what `parse` expects
    (it raises KeyError or ValueError), is a ValueError naming `what` ("result", "sweep").
    """
    path = Path(path)
    if not path.exists():
        raise ValueError(f"no such {what} file: {path}")
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = from_jsonable(json.loads(str(data["metadata"])))
            return meta, parse(meta, data)
    except (KeyError, OSError, ValueError, json.JSONDecodeError) as err:
        raise ValueError(f"{path} is not a morphojax {what} file ({err})") from err


def load_npz(path) -> tuple[State, dict]:
    """Read a result written by `save_npz`: (State with its capacity, step and time; metadata)."""
    meta, arrays = read_npz(path, "result", lambda meta, data: [data[f"species_{n}"] for n in meta["species"]])
    capacity = tuple(meta.get("capacity") or arrays[0].shape)
    # a growing state saved once it filled its capacity is still a growing state
    grows = bool(meta.get("growable", False)) or capacity != tuple(arrays[0].shape)
    state = State.from_arrays(arrays, capacity=capacity if grows else None, names=meta["species"])
    state = State(state.fields, state.size, meta.get("step", 0), meta.get("time", 0.0), state.names,
                  growable=state.growable)
    return state, meta

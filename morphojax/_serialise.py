"""Plain-data (JSON) forms of the building blocks, and result files of a state.

Models, domains, bounds, growth, sources and keys to and from plain data; the types built
from them (initial states, phases, experiments, automata) write and read their own forms
(`to_dict`/`from_dict`) from these, so this module imports no simulator. Every result
morphojax writes carries what is needed to reproduce or resume it: the species arrays
(cropped to the active lattice) plus a JSON `metadata` entry with the model parameters, the
run configuration, the key/seed and the step counter (`save_npz`, `load_npz`, checked by
`check_result`). How files are written and read safely is `_files`'.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import jax
import numpy as np

from ._bounds import Barrier
from ._checks import STEP_COUNTER_MAX, is_concrete
from ._files import dumps, from_jsonable, read_npz, to_jsonable, write_npz
from .domains import AbstractDomain, HexLattice, Lattice, Mesh
from ._growing_mesh import MeshGrowth
from ._growth import Growth, Source
from .models import (AbstractModel, Bard, Brusselator, Composite, FitzHughNagumo, GiererMeinhardt, GrayScott,
                     Modulated, Modulation, Morphogen, Reaction, Reinforcement, RuleReinforcement, Schnakenberg,
                     ThesisReinforcement, Thomas, Turing)
from ._state import State

# the models a file can rebuild (a Reaction's file cannot: its function is code)
MODEL_TYPES = {cls.__name__: cls for cls in (Turing, Bard, GrayScott, Reinforcement, FitzHughNagumo, GiererMeinhardt,
                                            Schnakenberg, Brusselator, ThesisReinforcement, RuleReinforcement,
                                            Morphogen, Thomas)}


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
    """The model a plain-data dict describes (what `model_to_dict` and every result file
    write): its "type" names the class, the other entries its parameters; a `Composite`
    rebuilds its parts. A user's `Reaction` function cannot be rebuilt from data."""
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


def growth_to_dict(g) -> dict:
    """A `Growth` (no "type": files before meshes grew hold only these) or a `MeshGrowth`."""
    if isinstance(g, MeshGrowth):
        return to_jsonable({"type": "MeshGrowth", "rate": g.rate, "field": g.field, "divide_area": g.divide_area,
                            "every": g.every, "dilute": g.dilute, "edge": g.edge, "seed": g.seed})
    return to_jsonable({"rate": g.rate, "distribution": g.distribution, "row_weights": g.row_weights,
                        "col_weights": g.col_weights, "spread": g.spread, "method": g.method})


def growth_from_dict(d: dict):
    d = from_jsonable(dict(d))
    if d.get("type", "Growth") == "MeshGrowth":
        return MeshGrowth(d["rate"], field=None if d.get("field") is None else np.asarray(d["field"], float),
                          divide_area=d.get("divide_area"), every=int(d.get("every", 50)),
                          dilute=bool(d.get("dilute", False)), edge=d.get("edge", "random"),
                          seed=int(d.get("seed", 0)))
    if d.get("type", "Growth") != "Growth":
        raise ValueError(f"unknown growth type {d.get('type')!r} in saved data; allowed: Growth, MeshGrowth")
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


def load_npz(path) -> tuple[State, dict]:
    """Read a result written by `save_npz`: (State with its capacity, step and time; metadata).
    Metadata that disagrees with itself or with the arrays is refused, naming the field."""

    def parse(meta, data):
        names = meta.get("species")
        if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names) \
                or len(set(names)) != len(names):
            raise ValueError(f"metadata field 'species' must list distinct species names (got {names!r})")
        return [np.asarray(data[f"species_{n}"]) for n in names]

    meta, arrays = read_npz(path, "result", parse)
    try:
        check_result(meta, arrays)
    except ValueError as err:
        raise ValueError(f"{path} is not a valid morphojax result ({err})") from None
    capacity = tuple(meta.get("capacity") or arrays[0].shape)
    # a growing state saved once it filled its capacity is still a growing state
    grows = bool(meta.get("growable", False)) or capacity != tuple(arrays[0].shape)
    state = State.from_arrays(arrays, capacity=capacity if grows else None, names=meta["species"])
    state = State(state.fields, state.size, meta.get("step", 0), meta.get("time", 0.0), state.names,
                  growable=state.growable)
    return state, meta


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _int_field(meta, field, low=0, high=STEP_COUNTER_MAX, where="metadata field"):
    value = meta[field]
    if not _is_int(value) or not low <= value <= high:
        raise ValueError(f"{where} {field!r} must be a whole number in [{low}, {high}] (got {value!r})")
    return value


def check_result(meta: dict, arrays) -> None:
    """The one validator of a result's metadata: its fields against each other and against
    its species arrays (one per name in `species`). Raises ValueError naming the field."""
    shape = arrays[0].shape
    for name, a in zip(meta["species"], arrays):
        if a.shape != shape or a.ndim not in (1, 2, 3) or a.dtype.kind not in "fiu":
            raise ValueError(f"species {name!r} is a {a.ndim}D {a.dtype} array of shape {a.shape}; every species "
                             f"must be a real array of one shape, 1D to 3D (the first is {shape})")
    for field in ("size", "capacity"):
        if meta.get(field) is None:
            continue
        value = meta[field]
        if not isinstance(value, list) or len(value) != len(shape) or not all(_is_int(v) and v >= 1 for v in value):
            raise ValueError(f"metadata field {field!r} must list {len(shape)} positive whole numbers (got {value!r})")
    if meta.get("size") is not None and tuple(meta["size"]) != shape:
        raise ValueError(f"metadata field 'size' {meta['size']} disagrees with the arrays' shape {list(shape)}")
    if meta.get("capacity") is not None and any(c < s for c, s in zip(meta["capacity"], shape)):
        raise ValueError(f"metadata field 'capacity' {meta['capacity']} is smaller than the arrays {list(shape)}")
    if "step" in meta:
        _int_field(meta, "step")
    if "time" in meta and (isinstance(meta["time"], bool) or not isinstance(meta["time"], (int, float))
                           or not math.isfinite(meta["time"]) or meta["time"] < 0):
        raise ValueError(f"metadata field 'time' must be a finite number >= 0 (got {meta['time']!r})")
    experiment = meta.get("experiment")
    if experiment is None:
        return
    if not isinstance(experiment, dict) or not isinstance(experiment.get("phases"), list) or not experiment["phases"] \
            or not all(isinstance(p, dict) and _is_int(p.get("steps")) and p["steps"] >= 0 for p in experiment["phases"]):
        raise ValueError("metadata field 'experiment' must hold a list of phases, each with its whole number of steps")
    run = meta.get("run")
    if not isinstance(run, dict):
        raise ValueError(f"metadata field 'run' is missing or not an object (got {run!r}); a result of an "
                         "experiment records where its run stands")
    phases = experiment["phases"]
    phase = _int_field(run, "phase", 0, len(phases), "run field") if "phase" in run else 0
    high = phases[phase]["steps"] - 1 if phase < len(phases) else 0
    step_in = _int_field(run, "phase_step", 0, max(high, 0), "run field") if "phase_step" in run else 0
    origin = run.get("phase_origin")
    if origin is not None:
        _int_field(run, "phase_origin", 0, meta.get("step", STEP_COUNTER_MAX), "run field")
        if step_in and "step" in meta and origin + step_in != meta["step"]:
            raise ValueError(f"run fields 'phase_origin' ({origin}) + 'phase_step' ({step_in}) disagree with "
                             f"metadata field 'step' ({meta['step']})")
    seed, key = run.get("seed"), run.get("key")
    if seed is not None and not _is_int(seed):
        raise ValueError(f"run field 'seed' must be a whole number or null (got {seed!r})")
    if seed is None and key is not None and not (isinstance(key, list) and all(_is_int(k) and 0 <= k < 2**32
                                                                                for k in key)):
        raise ValueError(f"run field 'key' must list 32-bit words (got {key!r})")

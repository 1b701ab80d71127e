"""The one serialiser: every object to and from plain data (JSON), and the `.npz` files.

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
from .domains import AbstractDomain, Lattice
from ._growth import Growth, Source
from ._models import AbstractModel, Bard, Composite, GrayScott, Reinforcement, Turing
from ._state import State

MODEL_TYPES = {cls.__name__: cls for cls in (Turing, Bard, GrayScott, Reinforcement)}


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
    params = {f.name: getattr(model, f.name) for f in dataclasses.fields(model)}
    return {"type": type(model).__name__, "params": to_jsonable(params)}


def model_from_dict(data: dict) -> AbstractModel:
    kind = data.get("type")
    if kind == "Composite":
        return Composite([model_from_dict(p) for p in data["parts"]], species=data.get("species"))
    if kind not in MODEL_TYPES:
        raise ValueError(f"unknown model type {kind!r} in saved data; allowed: {', '.join(MODEL_TYPES)}, Composite")
    params = from_jsonable(dict(data["params"]))
    for lim in ("lower", "upper"):
        if lim in params:
            params[lim] = tuple(np.asarray(v, float) for v in params[lim])
    params = {k: (np.asarray(v, float) if isinstance(v, list) else v) for k, v in params.items()}
    return MODEL_TYPES[kind](**params)


DOMAIN_TYPES = {cls.__name__: cls for cls in (Lattice,)}


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
    """`np.savez_compressed` that never leaves a half-written file: the archive goes to a
    temporary file beside `path`, which then replaces `path` in one step, so a crash keeps
    the last good file. Like NumPy, adds `.npz` when `path` has no such suffix."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            np.savez_compressed(handle, **arrays)
            handle.flush()
            os.fsync(handle.fileno())
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

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
import stat
import struct
import tempfile
import tokenize
import warnings
import zipfile
import zlib
from contextlib import contextmanager
from pathlib import Path

import jax
import numpy as np
from numpy.lib import format as npformat

from ._bounds import Barrier
from ._checks import STEP_COUNTER_MAX, cells_of, check_memory, is_concrete
from .domains import AbstractDomain, HexLattice, Lattice, Mesh
from ._growing_mesh import MeshGrowth
from ._growth import Growth, Source
from .models import (AbstractModel, Bard, Brusselator, Composite, FitzHughNagumo, GiererMeinhardt, GrayScott,
                     Modulated, Modulation, Morphogen, Reaction, Reinforcement, RuleReinforcement, Schnakenberg,
                     ThesisReinforcement, Thomas, Turing)
from ._state import State
from .solvers import solver_from_dict, solver_to_dict, until_from_dict, until_to_dict
from ._version import __version__

# the models a file can rebuild (a Reaction's file cannot: its function is code)
MODEL_TYPES = {cls.__name__: cls for cls in (Turing, Bard, GrayScott, Reinforcement, FitzHughNagumo, GiererMeinhardt,
                                            Schnakenberg, Brusselator, ThesisReinforcement, RuleReinforcement,
                                            Morphogen, Thomas)}


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
        "solver": solver_to_dict(phase.solver), "until": until_to_dict(phase.until),
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
        solver=solver_from_dict(d.get("solver")), until=until_from_dict(d.get("until")),
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


FORMAT_VERSION = 1  # the format number every file's metadata records (with the morphojax version)


def stamp(meta: dict) -> dict:
    """`meta` with the morphojax version and the format number that wrote it."""
    return {**meta, "morphojax": meta.get("morphojax") or __version__,
            "format_version": meta.get("format_version", FORMAT_VERSION)}


def _version_tuple(text) -> tuple:
    parts = []
    for piece in str(text).split("."):
        digits = "".join(ch for ch in piece if ch.isdigit()) if piece[:1].isdigit() else ""
        if not digits:
            break
        parts.append(int(digits))
    return tuple(parts)


def check_file_version(meta: dict, path=None) -> None:
    """Warn when a file was written by a newer morphojax or format than this one reads."""
    where = f"{path} was" if path is not None else "this file was"
    written, fmt = meta.get("morphojax"), meta.get("format_version")
    if isinstance(fmt, int) and not isinstance(fmt, bool) and fmt > FORMAT_VERSION:
        warnings.warn(f"{where} written in file format {fmt} (morphojax {written}); this morphojax "
                      f"{__version__} reads format {FORMAT_VERSION}, and fields it does not know are ignored",
                      stacklevel=3)
    elif isinstance(written, str) and _version_tuple(written) > _version_tuple(__version__):
        warnings.warn(f"{where} written by morphojax {written}, newer than this morphojax {__version__}",
                      stacklevel=3)


def write_npz(path, **arrays) -> Path:
    """`np.savez_compressed` that never leaves a half-written file (see `write_atomically`).
    Like NumPy, adds `.npz` when `path` has no such suffix. A JSON `metadata` entry gets the
    morphojax version and the format number (`stamp`)."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    if "metadata" in arrays:
        meta = json.loads(str(np.asarray(arrays["metadata"])))
        if isinstance(meta, dict):
            arrays["metadata"] = np.asarray(json.dumps(stamp(meta)))

    def write(tmp):
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, **arrays)

    return write_atomically(path, write)


def write_atomically(path, write) -> Path:
    """Write a file so that a crash never destroys the last good one: `write(temporary)`
    fills a temporary beside `path` (same suffix), which is flushed to disk and then replaces
    `path` in one step; a temporary whose writing failed is removed."""
    path = Path(path)
    check_output_path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ValueError(f"cannot write {path}: {err.strerror or err}") from None
    remove_stale_temporaries(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.{os.getpid()}-", suffix=path.suffix, dir=path.parent)
    except OSError as err:
        raise ValueError(f"cannot write {path}: {err.strerror or err}") from None
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # the user's umask, like any file (mkstemp makes 0600)
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


# ---- reading: every archive checked before it is loaded, every failure one ValueError ---------
METADATA_LIMIT = 64 * 2**20  # bytes of JSON metadata a file may declare
BOMB_SIZE = 256 * 2**20  # a member declaring more than this ...
BOMB_RATIO = 200  # ... that expands more than this from its compressed size is refused
# what a broken archive raises inside zipfile, zlib and numpy (flipped bytes give "Bad CRC-32",
# a truncated member EOFError, a lying header TypeError / IndexError / struct.error)
READ_ERRORS = (KeyError, OSError, ValueError, EOFError, TypeError, IndexError, AttributeError, OverflowError,
               MemoryError, UnicodeError, SyntaxError, json.JSONDecodeError, zipfile.BadZipFile, zlib.error,
               struct.error, tokenize.TokenError)  # a garbled .npy header fails NumPy's literal parser


def check_regular_file(path, what: str) -> Path:
    """`path` as a Path when it names an existing regular file; a folder, a named pipe or a
    device (`/dev/zero`) is refused, so a read never blocks or runs forever."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise ValueError(f"no such {what} file: {path}") from None
    except OSError as err:
        raise ValueError(f"cannot read {what} file {path}: {err.strerror or err}") from None
    if not stat.S_ISREG(mode):
        kind = "a folder" if stat.S_ISDIR(mode) else "not a regular file (a pipe, a device or a socket)"
        raise ValueError(f"{what} file {path} is {kind}")
    return path


def npz_members(path, what: str = "npz") -> dict:
    """{member name: (shape, dtype)} of a `.npz`, read from each member's header without
    loading its data; refuses an archive whose members would need more memory than the limit
    (`_checks.memory_limit`), expand like a decompression bomb, or disagree with their headers."""
    path = check_regular_file(path, what)
    members, total = {}, 0
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                with archive.open(info) as handle:
                    version = npformat.read_magic(handle)
                    reader = {(1, 0): npformat.read_array_header_1_0, (2, 0): npformat.read_array_header_2_0,
                              (3, 0): getattr(npformat, "_read_array_header", None)}.get(version)
                    if reader is None:
                        raise ValueError(f"member {name!r} has an unknown .npy version {version}")
                    shape, _, dtype = (reader(handle) if version != (3, 0) else reader(handle, version))
                if dtype.hasobject:
                    raise ValueError(f"member {name!r} holds Python objects, which morphojax never writes")
                nbytes = cells_of(shape) * dtype.itemsize
                if nbytes > info.file_size:  # the header claims more data than the member holds
                    raise ValueError(f"member {name!r} declares {nbytes} bytes of data but holds {info.file_size}")
                if name == "metadata" and nbytes > METADATA_LIMIT:
                    raise ValueError(f"its metadata declares {nbytes / 2**20:.0f} MB; at most "
                                     f"{METADATA_LIMIT // 2**20} MB is read")
                if info.file_size > BOMB_SIZE and info.file_size > BOMB_RATIO * max(info.compress_size, 1):
                    raise ValueError(f"member {name!r} expands from {info.compress_size / 1e6:.3g} MB to "
                                     f"{info.file_size / 1e9:.3g} GB, more than {BOMB_RATIO} times (a decompression "
                                     "bomb?)")
                members[name] = (tuple(shape), dtype)
                total += nbytes
    except READ_ERRORS as err:
        raise ValueError(f"{path} is not a morphojax {what} file ({_why(err)})") from None
    check_memory(total, f"reading {path}")
    return members


@contextmanager
def open_npz(path, what: str = "npz"):
    """`np.load(path)` of a checked archive (`npz_members`); any error while it is read, in the
    archive or in what the caller does with its arrays, is a ValueError naming the file."""
    path = Path(path)
    npz_members(path, what)
    try:
        with np.load(path, allow_pickle=False) as data:
            yield data
    except READ_ERRORS as err:
        if isinstance(err, ValueError) and str(err).startswith(str(path)):
            raise
        raise ValueError(f"{path} is not a morphojax {what} file ({_why(err)})") from None


def read_metadata(data, path=None) -> dict:
    """The JSON `metadata` member of an open archive as a dict (infinities restored)."""
    if "metadata" not in data.files:
        raise KeyError("metadata")
    meta = json.loads(str(data["metadata"]))
    if not isinstance(meta, dict):
        raise ValueError(f"its metadata is a JSON {type(meta).__name__}, not an object")
    check_file_version(meta, path)
    return from_jsonable(meta)


def _why(err) -> str:
    """What went wrong, in words: the exception's message, or its kind when it has none."""
    if isinstance(err, KeyError):
        key = str(err.args[0]) if err.args else ""
        if key.endswith(" is not a file in the archive"):  # NumPy's words for a missing member
            return f"no member {key.split(' ')[0]!r}"
        return f"no {key!r} entry" if key else "a missing entry"
    text = str(err).strip()
    return f"{type(err).__name__}: {text}" if text and not isinstance(err, ValueError) else (text or type(err).__name__)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


STALE_SECONDS = 60  # a temporary without its writer's process id is stale after this long


def remove_stale_temporaries(path) -> list[Path]:
    """Remove the temporaries (`.NAME.PID-*SUFFIX`) that a killed write of `path` left beside
    it: those whose writing process is gone (older ones, without a process id, once older than
    STALE_SECONDS), so a write running in another live process keeps its own."""
    import time

    path = Path(path)
    removed = []
    try:
        candidates = list(path.parent.glob(f".{glob_escape(path.stem)}.*{glob_escape(path.suffix)}"))
    except OSError:
        return removed
    for tmp in candidates:
        try:
            info = tmp.lstat()
            if not stat.S_ISREG(info.st_mode) or info.st_uid != os.getuid():
                continue
            pid = tmp.name[len(path.stem) + 2:].split("-", 1)[0]
            if pid.isdigit() and int(pid) > 0:
                if int(pid) == os.getpid() or _alive(int(pid)):
                    continue
            elif time.time() - info.st_mtime <= STALE_SECONDS:
                continue
            tmp.unlink()
            removed.append(tmp)
        except OSError:
            continue
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def glob_escape(text: str) -> str:
    import glob

    return glob.escape(text)


def check_output_path(path) -> Path:
    """Refuse, before any work, an output path whose parent is a file, that is a folder, or
    whose folder cannot be written (ValueError naming the path)."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"output {path} is a folder; name a file inside it")
    for parent in (path.parent, *path.parent.parents):
        if parent.exists():
            if not parent.is_dir():
                raise ValueError(f"cannot write {path}: {parent} is a file, not a folder")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise ValueError(f"cannot write {path}: the folder {parent} is not writable")
            break
    return path


def read_npz(path, what: str, parse):
    """Open a morphojax `.npz` and return (metadata, parse(metadata, data)).

    `data` is the open archive; a missing file, or one that is not what `parse` expects
    (it raises KeyError or ValueError), is a ValueError naming `what` ("result", "sweep").
    """
    with open_npz(path, what) as data:
        meta = read_metadata(data, path)
        return meta, parse(meta, data)


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

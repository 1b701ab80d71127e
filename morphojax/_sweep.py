"""Parameter sweeps: one model over a grid (or a list) of parameter sets, vmapped and sharded.

    result = mj.sweep(mj.Turing(scale=3.0), vary={"ratio": [4.2, 6, 12, 20, 40], "upper_a": [6.2, 4.4]},
                      state=mj.paper_state(jax.random.key(0), (50, 50)), steps=12_500, dt=0.003)
    result.arrays()      # NumPy (5, 2, species, rows, cols), axes in the order of `vary`
    result.table         # one dict per member: its parameter values and pattern descriptors
    result.save("map.png")   # montage + map.csv + map.json + map.npz

How it runs. A member is `model.replace(**its_values)` (and `growth` with its rate), built
*inside* the compiled batch from traced parameter values: the sweep is a vmap over
constructors of models, so one compiled program serves every value. Members are processed in
chunks of `batch_size` (the last chunk is padded with copies of the last member, so every
chunk reuses the same program and memory stays bounded); each chunk's batch axis is sharded
over a `jax.sharding.Mesh` of devices (`devices=None`: all local devices), so the same call
uses one CPU, 8 GPUs or a TPU slice. On GPUs, TPUs and several devices a chunk is one vmap;
on a single CPU device the members of a chunk run one after another inside the program
(`lax.map`, so each lattice stays in cache) and the cores run chunks side by side (see
`_BUDGET` below and benchmarks/bench_sweep.py). A member that blows up is recorded (class
"unstable", with the first non-finite step), never raised.

Randomness. With `state=` every member starts from that one state (the paper compares
parameters from identical initial conditions). With `state=None, shape=...` each member gets
its own start: member i uses the key k_i = fold_in(key, i) (or `key` itself for every
member with `keys="shared"`); its initial state is `initial_state(model, fold_in(k_i, 0),
shape, capacity)` and its run (growth, sources) uses `fold_in(k_i, 1)`. `result.member(i)`
gives back exactly these inputs, so `simulate(**result.member(i).kwargs())` reproduces it.

Several hosts. Call `jax.distributed.initialize()` in every process first (it finds the
coordinator on Cloud TPU, SLURM and similar; elsewhere pass `coordinator_address`,
`num_processes` and `process_id`), then call `sweep` with the same arguments in every
process. Each process runs a contiguous block of the members on its own local devices,
and the final arrays are all-gathered (`multihost_utils.process_allgather`), so every
process returns the full result; write files from process 0 only.
"""

from __future__ import annotations

import csv
import dataclasses
import itertools
import math
import os
import time
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from ._checks import default_float
from ._descriptors import SETTLE_TOL, describe, relative_change
from ._growth import Growth
from ._initial import initial_state
from ._serialise import (bounds_from_data, bounds_to_data, dumps, growth_from_dict, growth_to_dict, key_from_data,
                         key_to_data, model_from_dict, model_to_dict, read_npz, source_from_dict, source_to_dict,
                         to_jsonable)
from ._domain import max_stable_dt
from ._lattice import normalise_boundary, normalise_stencil
from ._models import AbstractModel
from ._simulate import run_status
from ._state import State

GROWTH_RATE = "growth_rate"  # the growth schedule's rate (needs growth=Growth(...))
DT = "dt"  # the time step, per member (steps stay the same for every member)
# How chunks run (measured in benchmarks/bench_sweep.py). A step is memory-bound. On one CPU
# device the members of a chunk run one after another inside the compiled program (`lax.map`),
# so each member's lattice stays in cache, and the cores run different chunks side by side
# (one dispatching thread per core): coarse-grained parallelism with no per-step hand-off. A
# wide vmap instead streams the whole chunk through memory at every step and splits each fused
# loop over the cores, which is slower on CPU, most of all on a busy machine. On accelerators,
# and on several devices (a sharded batch), each chunk is one vmap. Chunk sizes (lattice values
# per device) bound memory.
_BUDGET = {"cpu": 1 << 19, "other": 1 << 25}
_MAX_WORKERS = 8
_TRACES = {"batch": 0}  # times the batched program was traced (tests guard against recompiles)


# ---- what varies ---------------------------------------------------------------------------
def allowed_names(model: AbstractModel, growth=None) -> list[str]:
    """Parameter names a sweep can vary: the model's `parameters()`, `dt`, and `growth_rate`."""
    return list(model.parameters()) + [DT, GROWTH_RATE]


def _describe_allowed(model, growth):
    names = list(model.parameters()) + [DT]
    names.append(GROWTH_RATE if growth is not None else f"{GROWTH_RATE} (with growth=Growth(...))")
    return ", ".join(names)


def _check_name(model, growth, name):
    if not isinstance(name, str) or name not in allowed_names(model, growth):
        raise ValueError(f"sweep: unknown parameter {name!r} for {type(model).__name__}; "
                         f"allowed: {_describe_allowed(model, growth)}")
    if name == GROWTH_RATE and growth is None:
        raise ValueError("sweep: varying 'growth_rate' needs a growth schedule (growth=Growth(rate=...)) "
                         "and a state with room to grow (capacity)")


def _check_values(name, values) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"sweep: the values of {name!r} must be numbers (got {values!r})") from err
    if arr.ndim == 0:
        arr = arr[None]
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"sweep: {name!r} needs a non-empty 1D list of values (got shape {arr.shape})")
    # +inf is a valid upper limit and -inf a valid lower limit ("no limit"), as in the models
    kind = name.rsplit(".", 1)[-1][:6]  # composites name parameters "PART.NAME"
    ok = np.isfinite(arr) | ((arr == np.inf) & (kind == "upper_")) | ((arr == -np.inf) & (kind == "lower_"))
    if not ok.all():
        allowed = {"upper_": "finite or +inf", "lower_": "finite or -inf"}.get(kind, "finite")
        raise ValueError(f"sweep: the values of {name!r} must be {allowed} (got {float(arr[~ok][0]):g})")
    return arr


def _base_value(model, growth, dt, name):
    if name == DT:
        return float(dt)
    if name == GROWTH_RATE:
        return float(np.asarray(growth.rate))
    value = np.asarray(model.parameters()[name])
    if value.ndim != 0:
        raise ValueError(f"sweep: {name!r} is a parameter map in the base model; give it in every member "
                         "of the list (or vary it on a grid)")
    return float(value)


def _members(model, vary, growth, dt):
    """(names, grid axes or None, per-member values {name: (n,) array}, result shape)."""
    if isinstance(vary, Mapping):
        if not vary:
            raise ValueError(f"sweep: vary is empty; name at least one parameter: {_describe_allowed(model, growth)}")
        names = tuple(vary)
        for name in names:
            _check_name(model, growth, name)
        axes = tuple(_check_values(name, vary[name]) for name in names)
        mesh = np.meshgrid(*axes, indexing="ij")
        values = {name: m.reshape(-1) for name, m in zip(names, mesh)}
        return names, axes, values, tuple(len(a) for a in axes)
    if isinstance(vary, Sequence) and not isinstance(vary, str):
        rows = list(vary)
        if not rows:
            raise ValueError("sweep: the list of parameter sets is empty")
        if not all(isinstance(r, Mapping) for r in rows):
            raise ValueError("sweep: vary must be a dict {name: values} (a grid) or a list of dicts (explicit sets)")
        names = tuple(dict.fromkeys(k for r in rows for k in r))
        if not names:
            raise ValueError("sweep: the parameter sets name no parameter; "
                             f"allowed: {_describe_allowed(model, growth)}")
        for name in names:
            _check_name(model, growth, name)
        values = {}
        for name in names:
            base = None if all(name in r for r in rows) else _base_value(model, growth, dt, name)
            col = [r.get(name, base) for r in rows]
            values[name] = _check_values(name, col)
        return names, None, values, (len(rows),)
    raise ValueError("sweep: vary must be a dict {name: values} (a grid) or a list of dicts (explicit sets)")


def _member_model(model, growth, dt, changes: dict):
    changes = dict(changes)
    dt = changes.pop(DT, dt)
    rate = changes.pop(GROWTH_RATE, None)
    m = model.replace(**changes) if changes else model
    if rate is not None:
        growth = eqx.tree_at(lambda g: g.rate, growth, jnp.asarray(rate, jnp.asarray(growth.rate).dtype))
    return m, growth, dt


def _label(values: dict) -> str:
    return ", ".join(f"{k}={v:g}" for k, v in values.items())


# ---- the batched program ---------------------------------------------------------------------
def _member_run(model, growth, sources, state, key, values, dt, *, steps, tail, boundary, stencil, bounds):
    """One member (traced; vmapped by `_batch`): build its model, run, measure the last steps."""
    m, g, dt = _member_model(model, growth, dt, values)
    kw = dict(stencil=stencil, bounds=bounds, growth=g, sources=sources, key=key, check_dt=False,
              origin=state.step)
    mid, bad, overflow = run_status(m, state, steps - tail, dt, boundary, **kw)
    if tail == 0:
        return mid, bad, overflow, jnp.asarray(jnp.nan, mid.fields.dtype)
    final, bad2, overflow2 = run_status(m, mid, tail, dt, boundary, **kw)
    change = relative_change(mid.fields, final.fields, xp=jnp)
    return final, jnp.where(bad >= 0, bad, bad2), overflow | overflow2, change


def _batch(model, growth, sources, state, keys, values, dt, *, state_axis, steps, tail, boundary, stencil, bounds,
           inner, out_sharding):
    """A chunk of members: vmapped `inner` at a time (`lax.map` runs the sub-batches in sequence)."""
    _TRACES["batch"] += 1  # runs at trace time only

    def one(state, key, values):
        return _member_run(model, growth, sources, state, key, values, dt, steps=steps, tail=tail,
                           boundary=boundary, stencil=stencil, bounds=bounds)

    size = len(next(iter(values.values())))
    if inner >= size:
        out = jax.vmap(one, in_axes=(state_axis, None if keys is None else 0, 0))(state, keys, values)
    else:
        xs = (state if state_axis == 0 else None, keys, values)

        def each(x):
            return one(state if state_axis is None else x[0], x[1], x[2])

        out = jax.lax.map(each, xs, batch_size=None if inner == 1 else inner)
    if out_sharding is not None:  # keep every output split along the batch axis
        out = jax.tree_util.tree_map(lambda x: jax.lax.with_sharding_constraint(x, out_sharding), out)
    return out


_run_batch = eqx.filter_jit(_batch)


# ---- devices and chunks -------------------------------------------------------------------
def _devices(devices):
    if devices is None:
        return list(jax.local_devices())
    if isinstance(devices, int):
        local = jax.local_devices()
        if not 1 <= devices <= len(local):
            raise ValueError(f"sweep: devices={devices} but this process has {len(local)} local device(s)")
        return list(local[:devices])
    devices = list(devices)
    if not devices:
        raise ValueError("sweep: devices is an empty list; pass None for all local devices")
    return devices


def _chunk_size(batch_size, n, per_member, devices):
    ndev = len(devices)
    if batch_size is None:
        budget = _BUDGET["cpu" if devices[0].platform == "cpu" else "other"]
        size = min(n, max(1, budget // max(per_member, 1)) * ndev)
        workers = _workers(devices, n)
        if workers > 1:  # one chunk per worker at least, so every core has members to run
            size = min(size, -(-n // workers))
    else:
        if not isinstance(batch_size, (int, np.integer)) or isinstance(batch_size, bool) or batch_size < 1:
            raise ValueError(f"sweep: batch_size must be a positive integer or None (got {batch_size!r})")
        size = min(int(batch_size), n)
    return -(-size // ndev) * ndev  # a multiple of the number of devices


def _workers(devices, n_members) -> int:
    """Threads dispatching chunks at once: the CPU cores for a single CPU device, else 1."""
    if len(devices) > 1 or devices[0].platform != "cpu":
        return 1
    return max(1, min(os.cpu_count() or 1, _MAX_WORKERS, n_members))


def _inner(vmap_size, devices, chunk) -> int:
    if vmap_size is not None:
        if not isinstance(vmap_size, (int, np.integer)) or isinstance(vmap_size, bool) or vmap_size < 1:
            raise ValueError(f"sweep: vmap_size must be a positive integer or None (got {vmap_size!r})")
        return min(int(vmap_size), chunk)
    if len(devices) == 1 and devices[0].platform == "cpu":
        return 1  # CPU: one member at a time stays in cache; the cores run chunks side by side
    return chunk


def _host_block(n, index, count):
    """The contiguous members [start, stop) that process `index` of `count` runs (equal padded blocks)."""
    per = -(-n // count)
    return min(index * per, n), min((index + 1) * per, n), per


# ---- the result ---------------------------------------------------------------------------
@dataclasses.dataclass
class Member:
    """Everything needed to re-run one member alone: `simulate(**member.kwargs())`."""

    index: int
    values: dict
    model: AbstractModel
    state: State
    dt: float
    key: Any
    growth: Any
    config: dict

    def kwargs(self) -> dict:
        """Keyword arguments of `simulate` that reproduce this member alone (model, state, steps, dt, ...)."""
        c = self.config
        return dict(model=self.model, state=self.state, steps=c["steps"], dt=self.dt, boundary=c["boundary"],
                    stencil=c["stencil"], bounds=c["bounds"], growth=self.growth, sources=c["sources"], key=self.key)


@dataclasses.dataclass
class SweepResult:
    """The outcome of `sweep`: final states, descriptors and everything needed to reproduce it.

    Attributes:
        model: the base model; `names`: the varied parameters, in the order of `vary`;
        axes: the values of each grid axis (None for an explicit list);
        values: per-member parameter values {name: (n,) array}, members in C order of the grid;
        fields: (n, species, rows, cols) final concentrations at capacity (host NumPy);
        size: (n, 2) active lattice; blowup_step: (n,) first non-finite step or -1;
        overflow: (n,) growth wanted more than the capacity; change: (n,) relative change
        over the last `settle_steps` steps (see `relative_change`);
        table: one dict per member (its index, parameter values, descriptors, settled, ...);
        config: steps, dt, boundary, key data, ... (JSON-ready; saved with the files);
        member_devices: (n,) id of the device that computed each member.
    """

    model: AbstractModel
    names: tuple
    axes: tuple | None
    values: dict
    fields: np.ndarray
    size: np.ndarray
    blowup_step: np.ndarray
    overflow: np.ndarray
    change: np.ndarray
    table: list
    config: dict
    species: tuple
    member_devices: np.ndarray | None = None
    sharding: str = ""
    seconds: float = float("nan")
    initial: State | None = None  # the shared (or batched) initial State; None for per-member starts
    growth: Any = None
    sources: tuple = ()
    key: Any = None
    bounds: Any = "clip"

    # ---- views ----
    @property
    def shape(self) -> tuple:
        """(len(v1), len(v2), ...) for a grid, (n,) for an explicit list."""
        return tuple(len(a) for a in self.axes) if self.axes is not None else (len(self.fields),)

    def __len__(self):
        return len(self.fields)

    def arrays(self) -> np.ndarray:
        """Final states as (*shape, species, rows, cols), cropped to the largest active lattice
        (members that grew less are zero beyond their own `size`)."""
        h, w = (int(v) for v in self.size.max(axis=0)) if len(self.size) else (0, 0)
        return self.fields[..., :h, :w].reshape(self.shape + self.fields.shape[1:2] + (h, w))

    def column(self, name) -> np.ndarray:
        """One table column (or parameter) shaped like the grid, e.g. `column("pattern")`."""
        if name in self.values:
            return self.values[name].reshape(self.shape)
        if not self.table or name not in self.table[0]:
            raise ValueError(f"no column {name!r}; columns: {', '.join(self.table[0]) if self.table else '(none)'}")
        return np.asarray([row[name] for row in self.table]).reshape(self.shape)

    def index(self, i) -> int:
        """A flat member index from a flat int or a grid tuple."""
        if isinstance(i, tuple):
            return int(np.ravel_multi_index(i, self.shape))
        i = int(i)
        if not -len(self) <= i < len(self):
            raise ValueError(f"member {i} out of range 0..{len(self) - 1}")
        return i % len(self)

    def state(self, i) -> State:
        """The final State of member `i` (flat index or grid tuple)."""
        i = self.index(i)
        dt = float(self.values[DT][i]) if DT in self.values else float(np.asarray(self.config["dt"]))
        c = self.config
        return State(self.fields[i], self.size[i], c["steps"] + c.get("start_step", 0),
                     c.get("start_time", 0.0) + c["steps"] * dt, names=self.species, growable=c.get("growable", False))

    def member(self, i) -> Member:
        """Model, initial state, dt, key and growth of member `i`, to run it alone."""
        i = self.index(i)
        vals = {k: float(v[i]) for k, v in self.values.items()}
        model, growth, dt = _member_model(self.model, self.growth, self.config["dt"], vals)
        k_i, key = None, None
        if self.key is not None:
            k_i = self.key if self.config["keys"] == "shared" else jax.random.fold_in(self.key, i)
            key = jax.random.fold_in(k_i, 1)
        kind = self.config["initial"]
        if kind == "per-member":
            state = initial_state(self.model, jax.random.fold_in(k_i, 0), tuple(self.config["shape"]),
                                  capacity=_capacity(self.config))
        elif self.initial is None:
            raise ValueError("this result does not hold its initial states (a loaded file with a given state)")
        else:
            state = self.initial.frame(i) if kind == "batched" else self.initial
        config = self.config | {"sources": self.sources, "bounds": self.bounds}
        return Member(i, vals, model, state, float(np.asarray(dt)), key, growth, config)

    # ---- pictures and files ----
    def montage(self, species=-1, cmap="inferno", scale: int | None = None, vmin=None, vmax=None, title=None):
        """The batch as one labelled image (pillow): a grid like the paper's Figs. 4 and 5.

        2D grids: rows = first parameter, columns = second; 1D: one row; more axes: the last
        is the columns and the others combine into rows; explicit lists: captioned tiles.
        Each tile is normalised on its own (as the papers do) unless vmin/vmax are given;
        unstable members are grey tiles marked "NaN".
        """
        from ._render import montage, to_image

        k = _species_index(self.species, species)
        data = self.arrays()[..., k, :, :].reshape((len(self),) + self.arrays().shape[-2:])
        if scale is None:
            scale = max(1, 80 // max(data.shape[-2:]))
        tiles = []
        for i in range(len(self)):
            x = data[i]
            if self.blowup_step[i] >= 0 or not np.isfinite(x).all():
                tiles.append(_nan_tile(x.shape, scale))
            else:
                tiles.append(to_image(x, cmap=cmap, vmin=vmin, vmax=vmax, scale=scale))
        title = title or self._title(species)
        if self.axes is None:
            ncols = max(1, math.ceil(math.sqrt(len(self))))
            tiles = [_captioned(t, _label({n: self.values[n][i] for n in self.names})) for i, t in enumerate(tiles)]
            return montage(tiles, ncols, title=title)
        last = self.names[-1]
        col_labels = [f"{last}={v:g}" for v in self.axes[-1]]
        if len(self.axes) == 1:
            return montage(tiles, len(col_labels), col_labels=col_labels, title=title)
        row_labels = [_label(dict(zip(self.names[:-1], combo))) for combo in itertools.product(*self.axes[:-1])]
        return montage(tiles, len(col_labels), row_labels=row_labels, col_labels=col_labels, title=title)

    def _title(self, species):
        c = self.config
        params = c["model"].get("params", {})
        fixed = {k: v for k, v in params.items() if k not in self.names and not isinstance(v, list)}
        parts = [c["model"]["type"], _label({k: float(v) for k, v in fixed.items() if isinstance(v, (int, float))})]
        name = self.species[_species_index(self.species, species)]
        parts.append(f"species {name}, {c['steps']} steps, dt={_fmt(c['dt'])}, {c['boundary']}")
        return " | ".join(p for p in parts if p)

    def save(self, path, species=-1, cmap="inferno", scale=None) -> dict:
        """Write the montage (`path`, PNG), the table (.csv, .json) and the states (.npz) next to it."""
        path = Path(path)
        if path.suffix.lower() != ".png":
            path = path.with_suffix(".png")
        path.parent.mkdir(parents=True, exist_ok=True)
        self.montage(species=species, cmap=cmap, scale=scale).save(path, format="PNG")
        written = {"png": path, "csv": path.with_suffix(".csv"), "json": path.with_suffix(".json"),
                   "npz": path.with_suffix(".npz")}
        self.save_table(written["csv"])
        written["json"].write_text(dumps(self._metadata() | {"table": self.table}, indent=1))
        self.save_npz(written["npz"])
        return written

    def save_table(self, path) -> Path:
        """The descriptor table as CSV (one row per member; NaN as 'nan', booleans as true/false)."""
        path = Path(path)
        columns = list(self.table[0]) if self.table else []
        with path.open("w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(columns)
            for row in self.table:
                writer.writerow([_csv_cell(row[c]) for c in columns])
        return path

    def save_npz(self, path) -> Path:
        """Final states per species as (*shape, rows, cols) arrays, plus every parameter as JSON metadata."""
        path = Path(path)
        arrays = self.arrays()
        out = {f"species_{n}": arrays[..., j, :, :] for j, n in enumerate(self.species)}
        out |= {f"value_{n}": v.reshape(self.shape) for n, v in self.values.items()}
        out |= {"size": self.size.reshape(self.shape + (2,)), "blowup_step": self.blowup_step.reshape(self.shape),
                "overflow": self.overflow.reshape(self.shape), "change": self.change.reshape(self.shape)}
        np.savez_compressed(path, metadata=np.asarray(dumps(self._metadata() | {"table": self.table})), **out)
        return path

    def _metadata(self) -> dict:
        return {"kind": "morphojax.sweep", "names": list(self.names),
                "axes": None if self.axes is None else {n: a for n, a in zip(self.names, self.axes)},
                "members": None if self.axes is not None else [
                    {n: self.values[n][i] for n in self.names} for i in range(len(self))],
                "config": self.config, "species": list(self.species), "seconds": self.seconds,
                "devices": sorted({int(d) for d in self.member_devices}) if self.member_devices is not None else None}


def _capacity(config):
    cap = config.get("capacity")
    return tuple(cap) if cap else None


def _fmt(v):
    return ", ".join(f"{x:g}" for x in v) if isinstance(v, (list, tuple)) else f"{v:g}"


def _csv_cell(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    return v


def _species_index(names, species) -> int:
    if isinstance(species, (int, np.integer)):
        if not -len(names) <= species < len(names):
            raise ValueError(f"species index {species} out of range for species {', '.join(names)}")
        return int(species) % len(names)
    if species not in names:
        raise ValueError(f"unknown species {species!r}; allowed: {', '.join(names)}")
    return names.index(species)


def _nan_tile(shape, scale):
    from PIL import Image, ImageDraw

    img = Image.new("RGB", (shape[1] * scale, shape[0] * scale), (128, 128, 128))
    ImageDraw.Draw(img).text((2, 2), "NaN", fill="white")
    return img


def _captioned(img, text):
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default()
    box = ImageDraw.Draw(img).textbbox((0, 0), text, font=font)
    w, h = max(img.width, box[2] - box[0] + 4), img.height + box[3] - box[1] + 6
    canvas = Image.new("RGB", (w, h), "white")
    ImageDraw.Draw(canvas).text((2, 1), text, fill="black", font=font)
    canvas.paste(img, (0, h - img.height))
    return canvas


def load_sweep(path) -> SweepResult:
    """Read the `.npz` written by `SweepResult.save` / `save_npz` back into a SweepResult."""
    def parse(meta, data):
        if meta.get("kind") != "morphojax.sweep":
            raise ValueError("not a sweep file")
        species, names = tuple(meta["species"]), tuple(meta["names"])
        return (species, names, np.stack([data[f"species_{n}"] for n in species], axis=-3),
                {n: np.asarray(data[f"value_{n}"], float).reshape(-1) for n in names},
                {k: np.asarray(data[k]) for k in ("size", "blowup_step", "overflow", "change")})

    meta, (species, names, stacked, values, extra) = read_npz(path, "sweep", parse)
    n = len(next(iter(values.values())))
    axes = None if meta["axes"] is None else tuple(np.asarray(meta["axes"][k], float) for k in names)
    config = meta["config"]
    growth = growth_from_dict(config["growth"]) if config.get("growth") else None
    key = key_from_data(config.get("key_data") or None)
    initial = None
    if config.get("initial") == "shared-key" and key is not None:
        initial = initial_state(model_from_dict(config["model"]), jax.random.fold_in(key, 0), tuple(config["shape"]),
                                capacity=_capacity(config))  # the start `sweep` built itself (shape + shared key)
    return SweepResult(
        model=model_from_dict(config["model"]), names=names, axes=axes, values=values, initial=initial,
        bounds=bounds_from_data(config.get("bounds", "clip")),
        sources=tuple(source_from_dict(d) for d in config.get("sources") or ()),
        fields=stacked.reshape((n,) + stacked.shape[-3:]), size=extra["size"].reshape(n, 2),
        blowup_step=extra["blowup_step"].reshape(n), overflow=extra["overflow"].reshape(n),
        change=extra["change"].reshape(n), table=meta["table"], config=config, species=species,
        seconds=meta.get("seconds", float("nan")), growth=growth, key=key)


# ---- the entry point ---------------------------------------------------------------------
def sweep(model: AbstractModel, vary, state: State | None = None, steps: int = 0, dt=None, boundary: str = "wrap",
          batch_size: int | None = None, devices=None, *, vmap_size: int | None = None, key=None, shape=None,
          capacity=None, keys: str = "per-member", stencil: str = "nine-point", bounds="clip",
          growth: Growth | None = None, sources=(), species=-1, settle_steps: int | None = None,
          settle_tol: float = SETTLE_TOL, describe_members: bool = True, check_dt: bool = True,
          progress: bool = False) -> SweepResult:
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
        steps, dt, boundary, stencil, bounds, growth, sources: as in `simulate`; `dt` is
            checked against the explicit-Euler limit for every member unless `check_dt=False`.
        batch_size: members per compiled chunk (None: about 512K lattice values per device on
            CPU, e.g. 16 members of 2 x 128 x 128, and at most an equal share per core; 32M
            values per device on GPU/TPU).
            It is rounded up to a multiple of the number of devices; the last chunk is padded
            with copies of its last member, so every chunk reuses one compiled program.
        devices: None (all local devices), a number of local devices, or a list of devices: the
            batch axis of every chunk is sharded over a 1D `Mesh` of them ("batch").
        vmap_size: members advanced together by one vmapped step; the rest of a chunk runs
            sub-batch after sub-batch in the same program (`lax.map`). None: 1 on a single CPU
            device (and one thread per core running chunks side by side), the whole chunk
            otherwise. Results do not depend on it.
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
    if growth is not None and not isinstance(growth, Growth):
        raise ValueError(f"sweep: growth must be a Growth (got {type(growth).__name__})")
    if keys not in ("per-member", "shared"):
        raise ValueError(f"sweep: keys must be 'per-member' or 'shared' (got {keys!r})")
    boundary, stencil = normalise_boundary(boundary), normalise_stencil(stencil)
    steps = int(steps)
    tail = min(steps, max(1, steps // 10)) if settle_steps is None else int(settle_steps)
    if not 0 <= tail <= steps:
        raise ValueError(f"sweep: settle_steps must lie in [0, steps={steps}] (got {settle_steps!r})")
    names, axes, values, _ = _members(model, vary, growth, dt)
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
    _validate_members(model, growth, dt, values, names, probe, steps, stencil, check_dt)
    spec = _species_index(probe.names, species)

    devs = _devices(devices)
    hosts = devices is None and jax.process_count() > 1  # split the members between processes
    lo, hi, per_host = _host_block(n, jax.process_index(), jax.process_count()) if hosts else (0, n, n)
    chunk = _chunk_size(batch_size, max(per_host, 1), int(np.prod(probe.fields.shape)), devs)
    inner = _inner(vmap_size, devs, chunk)
    member_keys = None
    if key is not None:
        member_keys = jax.vmap(lambda i: jax.random.fold_in(key, i))(jnp.arange(n)) if keys == "per-member" \
            else jax.vmap(lambda i: key)(jnp.arange(n))
    t0 = time.perf_counter()
    host, sharding = _run_chunks(
        model, growth, sources, starts, member_keys, values, jnp.asarray(dt, probe.fields.dtype), devs, chunk, lo, hi,
        dict(steps=steps, tail=tail, boundary=boundary, stencil=stencil, bounds=bounds, inner=inner), progress)
    if hosts:
        host = _gather_hosts(host, n, per_host)
    fields, size, bad, over, change, member_devices = host
    seconds = time.perf_counter() - t0

    config = {
        "model": model_to_dict(model), "steps": steps, "dt": to_jsonable(dt), "boundary": boundary,
        "stencil": stencil, "bounds": bounds_to_data(bounds),
        "growth": growth_to_dict(growth) if growth is not None else None,
        "sources": [source_to_dict(s) for s in sources], "settle_steps": tail, "settle_tol": settle_tol,
        "keys": keys, "seed": seed, "key_data": key_to_data(key), "shape": list(probe.shape),
        "capacity": list(probe.capacity) if probe.growable else None, "growable": probe.growable,
        "start_step": int(np.asarray(probe.step)), "start_time": float(np.asarray(probe.time)),
        "initial": starts.kind, "batch_size": chunk, "vmap_size": inner, "devices": [str(d) for d in devs],
        "processes": jax.process_count(),
    }
    result = SweepResult(model=model, names=names, axes=axes, values=values, fields=fields, size=size,
                         blowup_step=bad.astype(np.int64), overflow=over.astype(bool), change=change.astype(float),
                         table=[], config=config, species=probe.names, member_devices=member_devices,
                         sharding=sharding, seconds=seconds, initial=starts.state, growth=growth, sources=sources,
                         key=key, bounds=bounds)
    result.table = _table(result, spec, boundary == "wrap", settle_tol, describe_members)
    return result


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


def _run_chunks(model, growth, sources, starts, member_keys, values, dt, devs, chunk, lo, hi, static, progress):
    """Members lo..hi-1 in chunks of `chunk`, each sharded over `devs`; host arrays and the sharding.

    On a single CPU device, `_workers` threads run chunks side by side (the program is traced
    and compiled once beforehand, so the threads only find it in the cache; XLA:CPU runs a
    call in its caller's thread). Otherwise chunks are dispatched in order, each copied back
    to the host while the next one computes.
    """
    mesh = Mesh(np.asarray(devs), ("batch",))
    batch, replicated = NamedSharding(mesh, PartitionSpec("batch")), NamedSharding(mesh, PartitionSpec())
    dtype = starts.probe.fields.dtype
    values = {k: np.asarray(v, dtype) for k, v in values.items()}
    shared = (model, growth, sources, starts.state if starts.shared else None, dt)
    model, growth, sources, shared_state, dt = jax.device_put(shared, replicated)
    static = static | dict(out_sharding=batch if len(devs) > 1 else None)
    put = lambda tree: jax.device_put(tree, batch)  # noqa: E731

    def inputs(a):
        idx = np.minimum(np.arange(a, a + chunk), min(a + chunk, hi) - 1)  # the last chunk is padded
        state, axis = starts.chunk(idx, member_keys)
        state = shared_state if axis is None else put(state)
        keys = None if member_keys is None else put(jax.vmap(lambda k: jax.random.fold_in(k, 1))(member_keys[idx]))
        vals = put({k: v[idx] for k, v in values.items()})
        return (model, growth, sources, state, keys, vals, dt), dict(state_axis=axis, **static)

    def launch(a):
        args, kwargs = inputs(a)
        return _run_batch(*args, **kwargs), a, min(a + chunk, hi)

    def to_host(item):
        (final, bad, over, change), a, b = item
        arrays = (final.fields, final.size, bad, over, change)
        return a, tuple(np.asarray(x)[: b - a] for x in arrays) + (_owners(final.fields, b - a),)

    firsts = list(range(lo, hi, chunk))
    workers = min(_workers(devs, hi - lo), len(firsts))
    parts = []
    bar = None
    if progress and firsts:
        from tqdm.auto import tqdm

        bar = tqdm(total=hi - lo, desc="sweep", unit="member", leave=False)

    def done(part):
        parts.append(part)
        if bar is not None:
            bar.update(len(part[1][0]))

    try:
        if workers > 1:
            args, kwargs = inputs(firsts[0])
            _run_batch.lower(*args, **kwargs).compile()  # trace and compile once, before the threads
            with ThreadPoolExecutor(workers) as pool:
                for part in pool.map(lambda a: to_host(launch(a)), firsts):
                    done(part)
        else:
            pending = []
            for a in firsts:
                pending.append(launch(a))
                if len(pending) > 1:  # copy the previous chunk to the host while this one computes
                    done(to_host(pending.pop(0)))
            while pending:
                done(to_host(pending.pop(0)))
    finally:
        if bar is not None:
            bar.close()
    if parts:
        parts.sort(key=lambda p: p[0])
        host = tuple(np.concatenate(p) for p in zip(*(arrays for _, arrays in parts)))
    else:
        cap = starts.probe.fields.shape
        host = (np.zeros((0,) + cap, dtype), np.zeros((0, 2), np.int32), np.zeros(0, np.int32), np.zeros(0, bool),
                np.zeros(0, dtype), np.zeros(0, int))
    return host, (str(batch) if len(devs) > 1 else str(devs[0]))


def _validate_members(model, growth, dt, values, names, probe, steps, stencil, check_dt):
    """Check every member concretely: the models' own checks, dt stability, growth capacity.

    Fast path: one model whose varied parameters are (1, n) maps holds every member at once
    (the models' checks are elementwise); if that fails or cannot be built, each member is
    built alone, which also names the first bad member in the error.
    """
    n = len(values[names[0]])
    if n > 1:
        try:
            _validate_at_once(model, growth, dt, values, names, probe, steps, stencil, check_dt)
            return
        except (ValueError, TypeError):
            pass
    for i in range(n):
        vals = {k: float(values[k][i]) for k in names}
        try:
            m, g, dt_i = _member_model(model, growth, dt, vals)
            if DT in vals and not dt_i > 0:
                raise ValueError(f"dt must be > 0 (got {dt_i:g})")
            if check_dt:
                dmax = m.max_diffusion()
                limit = max_stable_dt(dmax, stencil)
                if float(dt_i) > limit:
                    raise ValueError(
                        f"dt = {float(dt_i):g} is beyond the explicit-Euler limit {limit:.6g} of the {stencil} "
                        f"stencil for the largest diffusion rate {dmax:g}; use a smaller dt (or check_dt=False)")
            if g is not None:
                g.check_capacity(probe, steps, dt_i)
        except ValueError as err:
            raise ValueError(f"sweep member {i} ({_label(vals)}): {err}") from None


def _validate_at_once(model, growth, dt, values, names, probe, steps, stencil, check_dt):
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
        limits = np.array([max_stable_dt(float(x), stencil) for x in np.unique(dmax)])
        limit = limits[np.searchsorted(np.unique(dmax), dmax)]
        if (dts > limit).any():
            raise ValueError("a dt is beyond the stability limit")
    if growth is not None:
        rates = np.broadcast_to(np.asarray(values.get(GROWTH_RATE, np.asarray(growth.rate)), float), (n,))
        for rate, dt_i in set(zip(rates.tolist(), dts.tolist())):
            eqx.tree_at(lambda g: g.rate, growth, jnp.asarray(rate, jnp.asarray(growth.rate).dtype)).check_capacity(
                probe, steps, dt_i)


def _owners(arr, count) -> np.ndarray:
    """Device id of each of the first `count` members of a batch-sharded array."""
    owner = np.full(arr.shape[0], -1)
    for shard in arr.addressable_shards:
        owner[shard.index[0]] = shard.device.id
    return owner[:count]


def _gather_hosts(parts, n, per_host):
    """All-gather every process's block of members (multi-host runs; equal padded blocks)."""
    from jax.experimental import multihost_utils

    out = []
    for x in parts:  # pad to equal blocks (a process may hold fewer members, or none)
        x = np.concatenate([x, np.zeros((per_host - len(x),) + x.shape[1:], x.dtype)])
        g = np.asarray(multihost_utils.process_allgather(x))
        out.append(g.reshape((-1,) + g.shape[2:])[:n])
    return out


def _table(result: SweepResult, spec: int, wrap: bool, settle_tol: float, describe_members: bool) -> list:
    rows = []
    grid_idx = list(np.ndindex(result.shape)) if result.axes is not None else None
    for i in range(len(result)):
        row: dict[str, Any] = {"member": i}
        if grid_idx is not None:
            row |= {f"i_{n}": int(j) for n, j in zip(result.names, grid_idx[i])}
        row |= {n: float(result.values[n][i]) for n in result.names}
        unstable = bool(result.blowup_step[i] >= 0)
        if describe_members:
            x = result.fields[i, spec, : int(result.size[i, 0]), : int(result.size[i, 1])]
            d = describe(x, wrap=wrap).as_dict()
            d.pop("change"), d.pop("settled")
            if unstable:
                d["pattern"], d["finite"] = "unstable", bool(np.isfinite(x).all())
            row |= d
        change = float(result.change[i])
        row |= {"change": change, "settled": bool(not unstable and change < settle_tol),
                "blowup_step": int(result.blowup_step[i]), "overflow": bool(result.overflow[i]),
                "rows": int(result.size[i, 0]), "cols": int(result.size[i, 1])}
        rows.append(row)
    return rows


# ---- spatial parameter maps (Ready-style) ---------------------------------------------------
def parameter_map(model: AbstractModel, shape, x=None, y=None) -> AbstractModel:
    """A model whose parameters vary continuously across one lattice (Ready, thesis Fig. 5.5).

    `x=("ratio", 4.0, 40.0)` makes `ratio` go linearly from 4 in the first column to 40 in the
    last; `y=("upper_a", 6.5, 4.0)` does the same from the first row to the last. Any name of
    `model.parameters()` works (limits included). Run it with `simulate` on a lattice of
    `shape`; `map_image` labels the picture with the ranges.
    """
    rows, cols = (int(s) for s in shape)
    changes = {}
    for axis, spec in (("x", x), ("y", y)):
        if spec is None:
            continue
        try:
            name, lo, hi = spec
        except (TypeError, ValueError):
            raise ValueError(f"parameter_map: {axis} must be (name, start, stop) (got {spec!r})") from None
        if name not in model.parameters():
            raise ValueError(f"parameter_map: unknown parameter {name!r} for {type(model).__name__}; "
                             f"allowed: {', '.join(model.parameters())}")
        if name in changes:
            raise ValueError(f"parameter_map: {name!r} is given for both x and y")
        lo, hi = _check_values(name, [lo, hi])
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise ValueError(f"parameter_map: the range of {name!r} must be finite (got {lo:g}, {hi:g})")
        n = cols if axis == "x" else rows
        ramp = np.linspace(lo, hi, n, dtype=np.dtype(default_float()))
        changes[name] = np.broadcast_to(ramp[None, :] if axis == "x" else ramp[:, None], (rows, cols)).copy()
    if not changes:
        raise ValueError("parameter_map: give x=(name, start, stop) and/or y=(name, start, stop)")
    return model.replace(**changes)


def map_image(array, x=None, y=None, cmap="inferno", scale: int = 2, title=None):
    """A picture of a parameter-map run, with the x range under it and the y range on the left."""
    from PIL import Image, ImageDraw, ImageFont

    from ._render import to_image

    img = to_image(np.asarray(array), cmap=cmap, scale=scale)
    font = ImageFont.load_default()
    probe = ImageDraw.Draw(img)

    def size(t):
        b = probe.textbbox((0, 0), t, font=font)
        return b[2] - b[0], b[3] - b[1]

    ylo = f"{y[1]:g}" if y else ""
    yhi = f"{y[2]:g}" if y else ""
    left = max(size(ylo)[0], size(yhi)[0], size(y[0])[0] if y else 0) + 8
    th = size("Ag")[1] + 6
    top = th if title else 0
    canvas = Image.new("RGB", (left + img.width + 4, top + img.height + 2 * th), "white")
    canvas.paste(img, (left, top))
    d = ImageDraw.Draw(canvas)
    if title:
        d.text((4, 2), title, fill="black", font=font)
    if x:
        d.text((left, top + img.height + 2), f"{x[1]:g}", fill="black", font=font)
        d.text((left + img.width - size(f"{x[2]:g}")[0], top + img.height + 2), f"{x[2]:g}", fill="black", font=font)
        d.text((left + (img.width - size(f"{x[0]} ->")[0]) // 2, top + img.height + th), f"{x[0]} ->", fill="black",
               font=font)
    if y:
        d.text((2, top), ylo, fill="black", font=font)
        d.text((2, top + img.height - size(yhi)[1] - 2), yhi, fill="black", font=font)
        d.text((2, top + img.height // 2 - th // 2), f"{y[0]}", fill="black", font=font)
        d.text((2, top + img.height // 2 + 2), "v", fill="black", font=font)
    return canvas

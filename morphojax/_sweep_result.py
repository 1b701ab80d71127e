"""The result of a sweep: final states, the descriptor table, the files, and re-running a member.

    result.arrays()        # NumPy (*grid shape, species, rows, cols)
    result.table           # one dict per member: its parameter values and pattern descriptors
    result.member(i)       # model, start, dt, key, growth of member i: simulate(**member.kwargs())
    result.save("map.png") # montage + map.csv + map.json + map.npz
    mj.load_sweep("map.npz")
"""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path
from typing import Any

import jax
import numpy as np

from ._descriptors import describe
from ._initial import initial_state
from .models import AbstractModel
from ._render import png_path, tile_montage
from ._serialise import bounds_from_data, growth_from_dict, key_from_data, model_from_dict, source_from_dict
from ._files import check_output_path, dumps, read_npz, stamp, write_npz
from ._state import State
from ._sweep_members import DT, grid_labels, label, member_model


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
        model, growth, dt = member_model(self.model, self.growth, self.config["dt"], vals)
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
    def montage(self, species=-1, cmap="inferno", scale: int | None = None, vmin=None, vmax=None, title=None,
                per_tile: bool = False):
        """The batch as one labelled image (pillow): a grid like the paper's Figs. 4 and 5.

        2D grids: rows = first parameter, columns = second; 1D: one row; more axes: the last
        is the columns and the others combine into rows; explicit lists: captioned tiles.
        All tiles share one colour range (that of the stable members, or vmin/vmax), so the
        picture agrees with the table; `per_tile=True` normalises each tile on its own (as
        the papers' figures do). Unstable members are grey tiles marked "NaN"; members the
        table calls uniform are marked so. Column values are shown to 3 significant digits.
        """
        k = species_index(self.species, species)
        data = self.arrays()[..., k, :, :].reshape((len(self),) + self.arrays().shape[-2:])
        unstable = self.blowup_step >= 0
        if not per_tile:
            stable = data[~unstable]
            finite = stable[np.isfinite(stable)]
            vmin = (float(finite.min()) if finite.size else None) if vmin is None else vmin
            vmax = (float(finite.max()) if finite.size else None) if vmax is None else vmax
        marks = [row.get("pattern", "") == "uniform" and "uniform" or "" for row in self.table] if self.table else None
        draw = dict(title=title or self._title(species), cmap=cmap, scale=scale, vmin=vmin, vmax=vmax, marks=marks)
        if self.axes is None:
            captions = [label({n: self.values[n][i] for n in self.names}) for i in range(len(self))]
            return tile_montage(data, unstable, captions=captions, **draw)
        draw["title"] = f"{draw['title']} | columns: {self.names[-1]}"
        row_labels, col_labels = grid_labels(self.names, self.axes)
        return tile_montage(data, unstable, row_labels=row_labels, col_labels=col_labels, **draw)

    def _title(self, species):
        c = self.config
        params = c["model"].get("params", {})
        fixed = {k: v for k, v in params.items() if k not in self.names and not isinstance(v, list)}
        parts = [c["model"]["type"], label({k: float(v) for k, v in fixed.items() if isinstance(v, (int, float))})]
        name = self.species[species_index(self.species, species)]
        parts.append(f"species {name}, {c['steps']} steps, dt={_fmt(c['dt'])}, {c['boundary']}")
        return " | ".join(p for p in parts if p)

    def save(self, path, species=-1, cmap="inferno", scale=None) -> dict:
        """Write the montage (`path`, PNG), the table (.csv, .json) and the states (.npz) next to it."""
        path = png_path(path)
        check_output_path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        self.montage(species=species, cmap=cmap, scale=scale).save(path, format="PNG")
        written = {"png": path, "csv": path.with_suffix(".csv"), "json": path.with_suffix(".json"),
                   "npz": path.with_suffix(".npz")}
        self.save_table(written["csv"])
        written["json"].write_text(dumps(stamp(self._metadata() | {"table": self.table}), indent=1))
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
        return write_npz(path, metadata=np.asarray(dumps(self._metadata() | {"table": self.table})), **out)

    def _metadata(self) -> dict:
        return {"kind": "morphojax.sweep", "names": list(self.names),
                "axes": None if self.axes is None else {n: a for n, a in zip(self.names, self.axes)},
                "members": None if self.axes is not None else [
                    {n: self.values[n][i] for n in self.names} for i in range(len(self))],
                "config": self.config, "species": list(self.species), "seconds": self.seconds,
                "devices": sorted({int(d) for d in self.member_devices}) if self.member_devices is not None else None}


def member_table(result: SweepResult, spec: int, wrap: bool, settle_tol: float, describe_members: bool) -> list:
    """One row per member: index (and grid position), values, descriptors of species `spec`, status."""
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


def species_index(names, species) -> int:
    """Position of a species among `names`, given by name or index (negative counts from the end)."""
    if isinstance(species, (int, np.integer)):
        if not -len(names) <= species < len(names):
            raise ValueError(f"species index {species} out of range for species {', '.join(names)}")
        return int(species) % len(names)
    if species not in names:
        raise ValueError(f"unknown species {species!r}; allowed: {', '.join(names)}")
    return names.index(species)


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


def load_sweep(path) -> SweepResult:
    """Read the `.npz` written by `SweepResult.save` / `save_npz` back into a SweepResult."""
    def parse(meta, data):
        if meta.get("kind") != "morphojax.sweep":
            raise ValueError("not a sweep file")
        species, names = meta.get("species"), meta.get("names")
        for field, value in (("species", species), ("names", names)):
            if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
                raise ValueError(f"metadata field {field!r} must list names (got {value!r})")
        species, names = tuple(species), tuple(names)
        return (species, names, np.stack([data[f"species_{n}"] for n in species], axis=-3),
                {n: np.asarray(data[f"value_{n}"], float).reshape(-1) for n in names},
                {k: np.asarray(data[k]) for k in ("size", "blowup_step", "overflow", "change")})

    meta, (species, names, stacked, values, extra) = read_npz(path, "sweep", parse)
    try:
        return _sweep_from(meta, species, names, stacked, values, extra)
    except (KeyError, TypeError, IndexError, ValueError, AttributeError, OverflowError) as err:
        why = f"no {err.args[0]!r} entry" if isinstance(err, KeyError) else str(err)
        raise ValueError(f"{path} is not a valid morphojax sweep file ({why})") from None


def check_sweep(meta, species, names, stacked, values, extra) -> int:
    """The one validator of a sweep file: its metadata against itself and its arrays; returns
    the number of members. Raises ValueError naming the field."""
    if not species or not all(isinstance(n, str) for n in species):
        raise ValueError(f"metadata field 'species' must list species names (got {list(species)!r})")
    if not names or not all(isinstance(n, str) for n in names) or len(set(names)) != len(names):
        raise ValueError(f"metadata field 'names' must list distinct parameter names (got {list(names)!r})")
    n = len(values[names[0]])
    if n < 1 or any(len(v) != n for v in values.values()):
        raise ValueError(f"the value arrays of {list(names)} must hold one value per member, all the same number")
    if stacked.ndim < 3 or stacked.dtype.kind not in "fiu" or stacked.size != n * math.prod(stacked.shape[-3:]):
        raise ValueError(f"the species arrays (shape {stacked.shape}) do not hold {n} members")
    for key, per in (("size", 2), ("blowup_step", 1), ("overflow", 1), ("change", 1)):
        if extra[key].size != n * per:
            raise ValueError(f"array {key!r} holds {extra[key].size} values for {n} members")
    if not isinstance(meta.get("table"), list) or len(meta["table"]) != n:
        raise ValueError(f"metadata field 'table' must have one row per member ({n})")
    if not isinstance(meta.get("config"), dict) or not isinstance(meta["config"].get("model"), dict):
        raise ValueError("metadata field 'config' must hold the sweep's model")
    axes = meta.get("axes")
    if axes is not None:
        if not isinstance(axes, dict) or set(axes) != set(names) or \
                math.prod(len(np.atleast_1d(axes[k])) for k in names) != n:
            raise ValueError(f"metadata field 'axes' must give each of {list(names)} its values, {n} members in all")
    return n


def _sweep_from(meta, species, names, stacked, values, extra) -> SweepResult:
    n = check_sweep(meta, species, names, stacked, values, extra)
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

"""Cells to and from `.npz` files: every buffer of the live cells, the reagents' names,
limits and anisotropy, the iteration count and the run's status, with JSON metadata
(what produced them: a listing's text, the seed, the steps), written atomically.

The neighbour list the cells carry is part of the run's state and is saved too (its live
rows, `neighbour_index` with -1 for an empty slot and `neighbour_reference`, and the
metadata entry `neighbour_list`), so a run resumed from the file goes on bit for bit as
the uninterrupted one. Files with a list are format "morphojax-cells/2" (a morphojax that
reads only /1 refuses them by their format instead of failing on an unknown array); /1
files, without a list (those written before it was saved), load as before, and a run
resumed from one builds its list afresh.

Cells on a torus (`Cells.period`) save its (width, height) as the metadata entry `period`
(and their list its own), so a run resumed from the file is periodic too. Files with the
entry are format "morphojax-cells/3" (every file is written so; /1 and /2 files, from
before tori, load as cells of an open domain).
"""

from __future__ import annotations

import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .._files import read_npz, write_npz
from ._neighbours import NeighbourList
from ._space import check_period
from ._state import STATUS_FIELDS, Cells, make_cells

FORMAT = "morphojax-cells/3"
READABLE = ("morphojax-cells/1", "morphojax-cells/2", FORMAT)  # /1: no saved neighbour list; /1, /2: no torus
PERIOD = "period"  # the metadata entry of the torus the cells (or their list) live on: [width, height] or null
LIST_ARRAYS = ("neighbour_index", "neighbour_reference")  # the saved neighbour list's live rows
LIST_META = "neighbour_list"  # its metadata: the search that keeps it and its counters


def save_cells(path, cells: Cells, metadata: dict | None = None) -> Path:
    """Write the live cells and `metadata` (JSON-able) to `path` (.npz added if missing);
    `load_cells` reads them back with the same capacity."""
    if not isinstance(cells, Cells):
        raise ValueError(f"cells must be a Cells state (got {type(cells).__name__})")
    meta = {
        "format": FORMAT,
        "species": list(cells.species),
        "anisotropic": list(cells.anisotropic),
        "capacity": cells.capacity,
        "step": int(cells.step),
        "status": cells.message(),
        **(metadata or {}),
        PERIOD: None if cells.period is None else list(cells.period),
    }
    live = cells.live()
    listed = _list_entries(cells)
    if listed:
        meta[LIST_META] = listed.pop(LIST_META)
    return write_npz(
        path, **live, lower=np.asarray(cells.lower), upper=np.asarray(cells.upper),
        status=np.asarray([int(getattr(cells, name)) for name in STATUS_FIELDS]),
        metadata=json.dumps(meta), **listed,
    )


def _list_entries(cells: Cells) -> dict:
    """The entries that save the neighbour list the cells carry (its metadata under
    LIST_META, its arrays): its live rows only, since a run leaves the rows past the live
    cells empty and their references zero (as the positions there). Nothing for cells
    without a list, or with one that covers cells no longer live (cells changed by hand:
    a resumed run builds its list afresh, as it would from them)."""
    nb, n = cells.neighbours, int(cells.count)
    if nb is None:
        return {}
    index, reference = np.asarray(nb.index), np.asarray(nb.reference)
    if int(nb.built_count) > n or (index[n:] != cells.capacity).any() or (reference[n:] != 0).any():
        return {}
    meta = {"radius": nb.radius, "skin": nb.skin, "bucket_size": nb.bucket_size,
            "built_count": int(nb.built_count), "builds": int(nb.builds), "overflow": bool(nb.overflow),
            PERIOD: None if nb.period is None else list(nb.period)}
    rows = np.where(index[:n] >= cells.capacity, -1, index[:n]).astype(np.int32)
    return {LIST_META: meta, "neighbour_index": rows, "neighbour_reference": reference[:n]}


def load_cells(path) -> tuple[Cells, dict]:
    """(cells, metadata) from a file written by `save_cells` (a run can resume from it)."""

    def parse(meta, data):
        if meta.get("format") not in READABLE:
            raise ValueError(f"format {meta.get('format')!r}, expected one of {', '.join(map(repr, READABLE))}")
        return {name: np.asarray(data[name]) for name in data.files if name != "metadata"}

    meta, arrays = read_npz(path, "cells", parse)
    try:
        return _cells_from(meta, arrays)
    except (KeyError, TypeError, IndexError, ValueError, OverflowError) as err:
        why = f"no {err.args[0]!r} entry" if isinstance(err, KeyError) else str(err)
        raise ValueError(f"{path} is not a valid morphojax cells file ({why})") from None


def _cells_from(meta, arrays):
    """Cells from the checked metadata and arrays of a cells file."""
    for field, kind in (("species", list), ("anisotropic", list), ("capacity", int), ("step", int)):
        if not isinstance(meta.get(field), kind) or isinstance(meta.get(field), bool):
            raise ValueError(f"metadata field {field!r} must be a JSON {kind.__name__} (got {meta.get(field)!r})")
    if not all(isinstance(n, str) for n in meta["species"]):
        raise ValueError(f"metadata field 'species' must list names (got {meta['species']!r})")
    if len(meta["anisotropic"]) != len(meta["species"]):
        raise ValueError(f"metadata field 'anisotropic' has {len(meta['anisotropic'])} entries for "
                         f"{len(meta['species'])} species")
    if meta["step"] < 0:
        raise ValueError(f"metadata field 'step' must be >= 0 (got {meta['step']})")
    listed = {name: arrays.pop(name) for name in LIST_ARRAYS if name in arrays}
    position = arrays.pop("position")
    if position.ndim != 2 or not np.issubdtype(position.dtype, np.floating):
        raise ValueError(f"its positions must be an (n, 2) float array (got {position.ndim}D {position.dtype})")
    if not np.isfinite(position).all():
        raise ValueError("its cell positions hold NaN or infinite values")
    if meta["capacity"] < len(position):
        raise ValueError(f"metadata field 'capacity' ({meta['capacity']}) is smaller than its {len(position)} cells")
    for name, values in arrays.items():
        if values.dtype.kind not in "biuf":
            raise ValueError(f"its array {name!r} holds {values.dtype}, not numbers")
        per_species = name in ("concentration", "diffusion")
        if name in ("lower", "upper", "status") or (per_species and values.ndim != 2):
            continue
        if values.shape[-1] != len(position) or (per_species and len(values) != len(meta["species"])):
            raise ValueError(f"its array {name!r} has shape {values.shape} for {len(position)} cells and "
                             f"{len(meta['species'])} species")
        if per_species and not np.isfinite(values).all():
            raise ValueError(f"its array {name!r} holds NaN or infinite values")
    status = arrays.pop("status")
    upper = [None if np.isinf(u) else float(u) for u in arrays.pop("upper")]
    lower = arrays.pop("lower", None)  # files written before lower limits existed: the thesis's 0
    cells = make_cells(
        meta["species"], position, **arrays, lower=lower, upper=upper,
        anisotropic=tuple(bool(a) for a in meta["anisotropic"]), capacity=int(meta["capacity"]), step=int(meta["step"]),
        period=_period(meta.get(PERIOD), PERIOD),
    )
    cells = cells.replace(**{name: jnp.asarray(int(v), jnp.int32) for name, v in zip(STATUS_FIELDS, status)})
    if listed or LIST_META in meta:
        cells = cells.with_neighbours(_list_from(meta.get(LIST_META), listed, cells))
    return cells, meta


def _period(value, field: str):
    """A saved torus: None, or [width, height] of numbers in (0, +inf)."""
    if value is None:
        return None
    if not isinstance(value, list) or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise ValueError(f"metadata field {field!r} must be null or [width, height] (got {value!r})")
    return check_period(value, f"metadata field {field!r}")


def _list_from(meta, arrays, cells: Cells) -> NeighbourList:
    """The saved neighbour list, checked against the cells, in their buffers."""
    if not isinstance(meta, dict) or set(arrays) != set(LIST_ARRAYS):
        raise ValueError(f"a neighbour list needs the metadata entry {LIST_META!r} and the arrays "
                         f"{' and '.join(map(repr, LIST_ARRAYS))} together")
    for field, kinds in (("radius", (int, float)), ("skin", (int, float)), ("bucket_size", int),
                         ("built_count", int), ("builds", int), ("overflow", bool)):
        value = meta.get(field)
        if not isinstance(value, kinds) or (field != "overflow" and isinstance(value, bool)):
            raise ValueError(f"metadata field {LIST_META}.{field} is {value!r}")
    n, capacity = int(cells.count), cells.capacity
    if not (meta["radius"] > 0 and meta["skin"] >= 0 and meta["bucket_size"] >= 1 and 0 <= meta["built_count"] <= n
            and meta["builds"] >= 0):
        raise ValueError(f"metadata field {LIST_META} holds values out of range ({meta})")
    period = _period(meta.get(PERIOD), f"{LIST_META}.{PERIOD}")
    if period != cells.period:
        raise ValueError(f"its neighbour list's torus {period} is not its cells' {cells.period}")
    index, reference = arrays["neighbour_index"], arrays["neighbour_reference"]
    if index.ndim != 2 or index.shape[0] != n or index.shape[1] < 1 or index.dtype.kind not in "iu":
        raise ValueError(f"its array 'neighbour_index' must hold integers, one row per cell (got {index.shape} "
                         f"{index.dtype} for {n} cells)")
    if ((index < -1) | (index >= n)).any():
        raise ValueError("its array 'neighbour_index' names cells that are not live")
    if reference.shape != (n, 2) or reference.dtype.kind != "f" or not np.isfinite(reference).all():
        raise ValueError(f"its array 'neighbour_reference' must hold finite (x, y) per cell (got {reference.shape} "
                         f"{reference.dtype})")
    rows = np.full((capacity, index.shape[1]), capacity, np.int32)
    rows[:n] = np.where(index < 0, capacity, index)
    where = np.zeros((capacity, 2), reference.dtype)
    where[:n] = reference
    return NeighbourList(
        index=jnp.asarray(rows), reference=jnp.asarray(where, cells.position.dtype),
        built_count=jnp.asarray(meta["built_count"], jnp.int32), overflow=jnp.asarray(meta["overflow"]),
        builds=jnp.asarray(meta["builds"], jnp.int32), radius=float(meta["radius"]), skin=float(meta["skin"]),
        bucket_size=int(meta["bucket_size"]), period=period)

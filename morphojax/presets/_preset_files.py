"""The files the automaton, Potts and solid presets write, read back and checked.

A run's result, a sweep and a cells file have their own loaders (`load_npz`, `load_sweep`,
`load_cells`); these are the other three kinds `morphojax render` draws. Each loader reads
its arrays and JSON metadata through `read_npz` and checks the fields against each other and
against the arrays before anything is drawn, so a tampered or damaged file is refused as a
ValueError that names the file and the field, never drawn wrong. Fields a file lacks are not
required (files from before a field existed still load); a field it has must be right.
"""

from __future__ import annotations

import math

import numpy as np

from .._files import read_npz
from .._serialise import _int_field
from .._serialise import _is_int as _is_whole

AUTOMATA = ("YoungCA", "LifeLike", "Wireworld")


def load_automaton(path) -> tuple[np.ndarray, dict]:
    """An automaton preset's (or `morphojax ca`'s) file: (its cells, metadata). The cells are
    one lattice (2D or 3D) or a stack of them, one per run; every state is a whole number >= 0."""

    def parse(meta, data):
        cells = np.asarray(data["cells"])
        lattice = _lattice(meta, cells, "cells")
        if cells.ndim not in (2, 3, 4) or not np.issubdtype(cells.dtype, np.integer):
            raise ValueError(f"its cells are a {cells.ndim}D {cells.dtype} array; an automaton's are 2D or 3D "
                             "whole numbers, or a stack of them")
        if lattice is None and cells.ndim == 4:
            raise ValueError(f"its cells are 4D {cells.shape} and no metadata field 'lattice' says which are runs")
        if cells.size and not 0 <= cells.min() <= cells.max() <= 255:
            raise ValueError(f"its cells hold states {int(cells.min())} to {int(cells.max())}; an automaton's "
                             "states are 0 to 255")
        name = meta.get("automaton")
        if name is not None and name not in AUTOMATA:
            raise ValueError(f"metadata field 'automaton' must be one of {', '.join(AUTOMATA)} (got {name!r})")
        params = meta.get("params")
        runs = params if isinstance(params, list) else [params]
        if params is not None and not (runs and all(isinstance(p, dict) and isinstance(p.get("species"), list)
                                                    and p["species"] for p in runs)):
            raise ValueError("metadata field 'params' must hold each run's automaton, with its list of species")
        _whole(meta, "steps")
        _whole(meta, "seed", low=None)
        return cells

    meta, cells = read_npz(path, "automaton", parse)
    return cells, meta


def load_potts(path) -> tuple[np.ndarray, np.ndarray, dict]:
    """A Potts preset's file: (cell ids, one lattice or a stack of runs; each cell's type;
    metadata). Every id indexes the types, and each run has its like-type energy `j_like`."""

    def parse(meta, data):
        ids, types = np.asarray(data["ids"]), np.asarray(data["types"])
        if ids.ndim not in (2, 3) or not np.issubdtype(ids.dtype, np.integer) or types.ndim != 1 \
                or not np.issubdtype(types.dtype, np.integer) \
                or (ids.size and not 0 <= ids.min() <= ids.max() < len(types)):
            raise ValueError(f"its ids ({ids.ndim}D {ids.dtype}) do not index its {len(types)} cell types "
                             f"({types.ndim}D {types.dtype})")
        _lattice(meta, ids, "ids")
        runs = 1 if ids.ndim == 2 else ids.shape[0]
        j_like = meta.get("j_like")
        if j_like is not None:
            if not isinstance(j_like, list) or len(j_like) != runs or not all(_finite(j) for j in j_like):
                raise ValueError(f"metadata field 'j_like' must list one finite energy per run ({runs}); "
                                 f"got {j_like!r}")
            if "j_like" in data.files and not np.array_equal(np.asarray(data["j_like"], float), j_like):
                raise ValueError("metadata field 'j_like' disagrees with the array 'j_like'")
        _whole(meta, "mcs")
        _whole(meta, "seed", low=None)
        return ids, types

    meta, (ids, types) = read_npz(path, "Potts", parse)
    return ids, types, meta


def load_solid(path, species: str = "v") -> tuple[np.ndarray, dict]:
    """A 3D lattice's file (`gray-scott-3d`): (the field of `species`, metadata). Its fields
    are finite 3D arrays of one shape, the lattice's."""

    def parse(meta, data):
        names = [n for n in data.files if n != "metadata"]
        if species not in names:
            raise ValueError(f"it holds no field {species!r} (its fields: {', '.join(names)})")
        fields = {n: np.asarray(data[n]) for n in names}
        shape = fields[species].shape
        for name, field in fields.items():
            if field.ndim != 3 or field.dtype.kind not in "fiu" or field.shape != shape:
                raise ValueError(f"its field {name!r} is a {field.ndim}D {field.dtype} array of shape {field.shape}; "
                                 f"a solid's fields are real 3D arrays of one shape ({shape})")
            if not np.all(np.isfinite(field)):
                raise ValueError(f"its field {name!r} holds NaN or infinite values")
        _lattice(meta, fields[species], species)
        _whole(meta, "steps")
        _whole(meta, "seed", low=None)
        if "dt" in meta and not (_finite(meta["dt"]) and meta["dt"] > 0):
            raise ValueError(f"metadata field 'dt' must be a finite number > 0 (got {meta['dt']!r})")
        return fields[species]

    meta, field = read_npz(path, "solid", parse)
    return field, meta


def _lattice(meta: dict, array: np.ndarray, name: str):
    """The metadata's `lattice`, which must be the array's shape or the shape of each run in it."""
    lattice = meta.get("lattice")
    if lattice is None:
        return None
    if not isinstance(lattice, list) or len(lattice) not in (2, 3) \
            or not all(_is_whole(n) and n >= 1 for n in lattice):
        raise ValueError(f"metadata field 'lattice' must list 2 or 3 positive whole numbers (got {lattice!r})")
    if tuple(array.shape[-len(lattice):]) != tuple(lattice) or array.ndim > len(lattice) + 1:
        raise ValueError(f"metadata field 'lattice' {lattice} disagrees with the array {name!r} of shape "
                         f"{list(array.shape)} (one lattice, or a stack of them)")
    return lattice


def _whole(meta: dict, field: str, low: int | None = 0) -> None:
    """A field that, when present, is a whole number (a count: in [low, the step counter's most])."""
    value = meta.get(field)
    if value is None:
        return
    if low is not None:
        _int_field(meta, field, low)
    elif not _is_whole(value):
        raise ValueError(f"metadata field {field!r} must be a whole number (got {value!r})")


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)

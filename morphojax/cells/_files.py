"""Cells to and from `.npz` files: every buffer of the live cells, the reagents' names,
limits and anisotropy, the iteration count and the run's status, with JSON metadata
(what produced them: a listing's text, the seed, the steps), written atomically."""

from __future__ import annotations

import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .._files import read_npz, write_npz
from ._state import STATUS_FIELDS, Cells, make_cells

FORMAT = "morphojax-cells/1"


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
    }
    live = cells.live()
    return write_npz(
        path, **live, lower=np.asarray(cells.lower), upper=np.asarray(cells.upper),
        status=np.asarray([int(getattr(cells, name)) for name in STATUS_FIELDS]),
        metadata=json.dumps(meta),
    )


def load_cells(path) -> tuple[Cells, dict]:
    """(cells, metadata) from a file written by `save_cells` (a run can resume from it)."""

    def parse(meta, data):
        if meta.get("format") != FORMAT:
            raise ValueError(f"format {meta.get('format')!r}, expected {FORMAT!r}")
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
    )
    return cells.replace(**{name: jnp.asarray(int(v), jnp.int32) for name, v in zip(STATUS_FIELDS, status)}), meta

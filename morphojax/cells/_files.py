"""Cells to and from `.npz` files: every buffer of the live cells, the reagents' names,
limits and anisotropy, the iteration count and the run's status, with JSON metadata
(what produced them: a listing's text, the seed, the steps), written atomically."""

from __future__ import annotations

import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .._serialise import read_npz, write_npz
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
    status = arrays.pop("status")
    upper = [None if np.isinf(u) else float(u) for u in arrays.pop("upper")]
    lower = arrays.pop("lower", None)  # files written before lower limits existed: the thesis's 0
    cells = make_cells(
        meta["species"], arrays.pop("position"), **arrays, lower=lower, upper=upper,
        anisotropic=tuple(bool(a) for a in meta["anisotropic"]), capacity=int(meta["capacity"]), step=int(meta["step"]),
    )
    return cells.replace(**{name: jnp.asarray(int(v), jnp.int32) for name, v in zip(STATUS_FIELDS, status)}), meta

"""Cells to and from `.npz` files: every buffer of the live cells, the reagents' names,
limits and anisotropy, the iteration count and the run's status, with JSON metadata
(what produced them: a listing's text, the seed, the steps), written atomically."""

from __future__ import annotations

import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .._serialise import write_npz
from ._state import Cells, make_cells

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
        status=np.asarray([int(cells.overflow_step), int(cells.neighbour_overflow_step), int(cells.nonfinite_step)]),
        metadata=json.dumps(meta),
    )


def load_cells(path) -> tuple[Cells, dict]:
    """(cells, metadata) from a file written by `save_cells` (a run can resume from it)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["metadata"]))
            if meta.get("format") != FORMAT:
                raise ValueError(f"{path} is not a cells file (format {meta.get('format')!r}, expected {FORMAT!r})")
            arrays = {k: np.asarray(data[k]) for k in data.files if k != "metadata"}
    except (OSError, KeyError) as err:
        raise ValueError(f"cannot read cells from {path}: {err}") from err
    upper = [None if np.isinf(u) else float(u) for u in arrays["upper"]]
    lower = arrays.get("lower")  # files written before lower limits existed: the thesis's 0
    cells = make_cells(
        meta["species"], arrays["position"], concentration=arrays["concentration"], diffusion=arrays["diffusion"],
        polarity=arrays["polarity"], polarised=arrays["polarised"], birth=arrays["birth"], fixed=arrays["fixed"],
        lower=lower, upper=upper, anisotropic=tuple(bool(a) for a in meta["anisotropic"]), capacity=int(meta["capacity"]),
        step=int(meta["step"]),
    )
    overflow, neighbour_overflow, nonfinite = (int(v) for v in arrays["status"])
    cells = cells.replace(overflow_step=jnp.asarray(overflow, jnp.int32),
                          neighbour_overflow_step=jnp.asarray(neighbour_overflow, jnp.int32),
                          nonfinite_step=jnp.asarray(nonfinite, jnp.int32))
    return cells, meta

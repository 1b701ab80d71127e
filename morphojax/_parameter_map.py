"""Spatial parameter maps (Ready-style): one model whose parameters vary across the lattice.

A parameter map is a model transform, not a sweep: every cell of one lattice gets its own
value of a parameter (a linear ramp along x and/or y), and the model runs once with
`simulate`. `map_image` (in `_render`) labels the picture with the ranges.
"""

from __future__ import annotations

import numpy as np

from ._checks import check_run_size, check_shape, default_float
from .models import AbstractModel
from ._sweep_members import _check_values


def parameter_map(model: AbstractModel, shape, x=None, y=None) -> AbstractModel:
    """A model whose parameters vary continuously across one lattice (Ready, thesis Fig. 5.5).

    `x=("ratio", 4.0, 40.0)` makes `ratio` go linearly from 4 in the first column to 40 in the
    last; `y=("upper_a", 6.5, 4.0)` does the same from the first row to the last. Any name of
    `model.parameters()` works (limits included). Run it with `simulate` on a lattice of
    `shape`; `map_image` labels the picture with the ranges.
    """
    # the lattice is checked before a map is built: whole sizes (not floored), and the run's
    # memory with each map counted as one more field per cell (`check_run_size`)
    rows, cols = check_shape(shape, "parameter_map: shape", ndim=2)
    maps = sum(spec is not None for spec in (x, y))
    check_run_size((rows, cols), model.n_species + maps,
                   what=f"parameter_map: shape {rows}x{cols} with {model.n_species} species and {maps} parameter "
                        "map(s); this run")
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

"""The state of a cellular Potts model: a lattice of cell ids, a type per cell, the volumes.

Cell id 0 is the medium (type 0); cells 1..n carry types >= 1. `potts_blob` builds the
initial condition of Tinson's (2022) runs (CompuCell3D's BlobInitializer, appendix C2).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._checks import check_count, check_range, check_run_size, is_concrete


class PottsState(eqx.Module):
    """A Potts lattice: `ids` (rows x cols, int32, 0 = medium, 1..n = cells), `types`
    (n + 1, int32: the type of each cell id, `types[0] = 0` the medium's) and `volumes`
    (n + 1, int32: the number of sites of each id, counted from `ids` when not given).

    A cell whose volume reaches 0 keeps its id and type; no site can copy it back."""

    ids: jax.Array
    types: jax.Array
    volumes: jax.Array

    def __init__(self, ids, types, volumes=None):
        ids = jnp.asarray(ids)
        types = jnp.asarray(types)
        if ids.ndim != 2:
            raise ValueError(f"PottsState.ids must be a 2D lattice of cell ids (got shape {ids.shape})")
        if types.ndim != 1 or types.shape[0] < 1:
            raise ValueError(f"PottsState.types must be a 1D array, one type per cell id (got shape {types.shape})")
        if not (jnp.issubdtype(ids.dtype, jnp.integer) and jnp.issubdtype(types.dtype, jnp.integer)):
            raise ValueError("PottsState.ids and PottsState.types must be integer arrays")
        self.ids = ids.astype(jnp.int32)
        self.types = types.astype(jnp.int32)
        if volumes is None:
            volumes = jnp.bincount(self.ids.ravel(), length=types.shape[0])
        self.volumes = jnp.asarray(volumes, jnp.int32)

    def __check_init__(self):
        if not is_concrete(self.ids, self.types, self.volumes):
            return
        n = self.types.shape[0] - 1
        check_range(self.ids, f"PottsState.ids (cell ids; types has {n + 1} entries)", low=0, high=n)
        check_range(self.types, "PottsState.types", low=0)
        if int(self.types[0]) != 0:
            raise ValueError(f"PottsState.types[0] is the medium's type and must be 0 (got {int(self.types[0])})")
        if self.volumes.shape != self.types.shape:
            raise ValueError(f"PottsState.volumes must have one entry per cell id ({self.types.shape}), "
                             f"got {self.volumes.shape}")

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.ids.shape)

    @property
    def n_cells(self) -> int:
        """Cell ids besides the medium (vanished cells included)."""
        return self.types.shape[0] - 1

    def arrays(self):
        """(ids, types, volumes) as NumPy arrays."""
        return np.asarray(self.ids), np.asarray(self.types), np.asarray(self.volumes)

    def type_lattice(self):
        """The type of every site (rows x cols; 0 = medium), a JAX array."""
        return self.types[self.ids]


def potts_blob(shape, radius, cell_width, *, types=(1, 2), key=None, center=None) -> PottsState:
    """A disc of `radius` sites (centred at `center`, default the lattice's middle) cut into
    square cells `cell_width` sites wide, each of a type drawn uniformly from `types` with
    `key` (default `jax.random.key(0)`); the rest is medium. Tinson's (2022) runs: shape (100,
    100), radius 40, width 5, types (1, 2) (appendix C2, CompuCell3D's BlobInitializer with
    gap 0). Cells cut by the disc's edge are smaller; ids are numbered row by row from 1."""
    if len(tuple(shape)) != 2:
        raise ValueError(f"potts_blob shape must be (rows, cols) (got {shape!r})")
    rows, cols = (int(s) for s in shape)
    check_count(rows, "potts_blob shape[0]", "sites", low=1)
    check_count(cols, "potts_blob shape[1]", "sites", low=1)
    check_count(cell_width, "potts_blob cell_width", "sites", low=1)
    check_run_size((rows, cols), 2, what=f"a Potts lattice of {rows}x{cols} sites and its run")
    check_range(radius, "potts_blob radius", low=0, low_open=True)
    types = tuple(int(t) for t in types)
    if not types or min(types) < 1:
        raise ValueError(f"potts_blob types must be cell types >= 1 (got {types!r}); 0 is the medium")
    ci, cj = (rows // 2, cols // 2) if center is None else (float(center[0]), float(center[1]))
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    inside = (i - ci) ** 2 + (j - cj) ** 2 <= float(radius) ** 2
    block = ((i - int(np.floor(ci - radius))) // cell_width) * (cols + 1) + (j - int(np.floor(cj - radius))) // cell_width
    labels = np.unique(block[inside])
    ids = np.zeros((rows, cols), np.int32)
    ids[inside] = np.searchsorted(labels, block[inside]) + 1
    key = jax.random.key(0) if key is None else key
    drawn = jax.random.choice(key, jnp.asarray(types, jnp.int32), (labels.size,))
    return PottsState(jnp.asarray(ids), jnp.concatenate([jnp.zeros(1, jnp.int32), drawn]))

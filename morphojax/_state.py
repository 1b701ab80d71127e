"""The state of one simulation: species concentrations on a domain, with room to grow.

Fields have shape (species, *spatial): (species, rows, cols) on a lattice, (species,
vertices) on a mesh or a set of cells. The active region is the leading `size` block of
the spatial axes; the rest is unused capacity and holds zeros.
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._checks import STEP_COUNTER_MAX, default_float, is_concrete

_DEFAULT_NAMES = "abcdefghijklmnopqrstuvwxyz"


class State(eqx.Module):
    """Species concentrations of one simulation.

    Attributes:
        fields: array (species, *capacity), e.g. (species, rows, cols) on a lattice. Only
            the leading `size` block (top-left on a lattice) is the live tissue; the rest is
            unused capacity and holds zeros.
        size: int32 array with one entry per spatial axis, e.g. (rows, cols): the active
            region. Equals the capacity unless the state was made to grow.
        step: int32 scalar, steps simulated so far (across calls and phases).
        time: scalar, simulated time so far (sum of steps x dt).
        names: species names (static), e.g. ("a", "b").
        growable: (static) True when the state has room to grow (made with a `capacity`);
            steppers then keep the active region dynamic, otherwise they use the faster
            fixed-size path.

    Build one with `State.from_arrays([a, b])` or a model's `initial_state(key, shape)`;
    get NumPy arrays back with `state.arrays()`.
    """

    fields: Array
    size: Array
    step: Array
    time: Array
    names: tuple[str, ...] = eqx.field(static=True)
    growable: bool = eqx.field(static=True)

    def __init__(self, fields, size=None, step=0, time=0.0, names=None, growable=None):
        fields = jnp.asarray(fields)
        if not jnp.issubdtype(fields.dtype, jnp.floating):
            fields = fields.astype(default_float())
        if size is None and fields.ndim < 2:
            raise ValueError(f"State.fields must have shape (species, *spatial), e.g. (species, rows, cols) "
                             f"(got {fields.shape})")
        self.fields = fields
        self.size = jnp.asarray(fields.shape[1:] if size is None else size, dtype=jnp.int32)
        if isinstance(step, (int, np.integer)) and not 0 <= int(step) <= STEP_COUNTER_MAX:
            raise ValueError(f"State.step must lie in [0, {STEP_COUNTER_MAX}], what the int32 step counter holds "
                             f"(got {step})")
        self.step = jnp.asarray(step, dtype=jnp.int32)
        self.time = jnp.asarray(time, dtype=fields.dtype)
        if names is None:
            names = tuple(_DEFAULT_NAMES[: fields.shape[0]])
        self.names = tuple(names)
        if growable is None:
            if size is None:
                growable = False
            elif is_concrete(size):
                growable = tuple(np.asarray(size).tolist()) != tuple(fields.shape[1:])
            else:
                growable = True
        self.growable = bool(growable)

    def __check_init__(self):
        if len(self.names) != self.n_species:
            raise ValueError(f"State.names has {len(self.names)} entries for {self.n_species} species")
        if is_concrete(self.size) and self.size.ndim == 1:
            size = np.asarray(self.size)
            cap = self.capacity
            if (size < 1).any() or (size > np.asarray(cap)).any():
                raise ValueError(f"State.size {tuple(size)} must lie between (1, 1) and the capacity {tuple(cap)}")

    # ---- construction ---------------------------------------------------------------
    @classmethod
    def from_arrays(cls, arrays: Sequence, capacity=None, names=None, dtype=None) -> "State":
        """A state from one array per species (NumPy or JAX), all of the same shape: 2D
        (rows, cols) on a lattice, 1D (one value per vertex or cell) on a mesh or cells.

        A single 2D array is one species on a lattice. `capacity` (one size per axis)
        reserves room for growth; the arrays fill the leading corner and the rest is zero.
        `dtype` defaults to JAX's default float (float32, or float64 with x64 enabled).
        """
        if isinstance(arrays, (np.ndarray, jax.Array)) and np.ndim(arrays) == 2:
            arrays = [arrays]
        arrays = list(arrays)
        if not arrays:
            raise ValueError("State.from_arrays needs at least one species array")
        dtype = default_float() if dtype is None else dtype
        mats = []
        for i, arr in enumerate(arrays):
            if jnp.iscomplexobj(arr):
                raise ValueError(f"State.from_arrays: species {i} is complex; concentrations must be real "
                                 "(pass arr.real or np.abs(arr) explicitly)")
            arr = jnp.asarray(arr, dtype=dtype)
            if arr.ndim not in (1, 2, 3):
                raise ValueError(f"State.from_arrays: species {i} must be a 1D, 2D or 3D array (got shape {arr.shape})")
            mats.append(arr)
        shapes = {m.shape for m in mats}
        if len(shapes) != 1:
            raise ValueError(f"State.from_arrays: all species must have the same shape (got {sorted(shapes)})")
        shape = mats[0].shape
        if min(shape) < 1:
            raise ValueError(f"State.from_arrays: every spatial axis needs at least one cell (got {shape})")
        if is_concrete(mats):
            for i, m in enumerate(mats):
                if not np.isfinite(np.asarray(m)).all():
                    raise ValueError(f"State.from_arrays: species {i} contains NaN or infinite values")
        fields = jnp.stack(mats)
        if capacity is not None:
            capacity = tuple(int(c) for c in capacity)
            if len(capacity) != len(shape) or any(c < n for c, n in zip(capacity, shape)):
                raise ValueError(
                    f"State.from_arrays: capacity must have {len(shape)} sizes, each at least the array shape {shape} "
                    f"(got {capacity})"
                )
            fields = jnp.zeros((len(mats),) + capacity, dtype).at[(slice(None),) + _corner(shape)].set(fields)
        return cls(fields, size=shape, names=names, growable=capacity is not None)

    # ---- views ------------------------------------------------------------------------
    @property
    def ndim(self) -> int:
        """Number of spatial axes (2 on a lattice, 1 on a mesh or a set of cells)."""
        return self.size.shape[-1]

    @property
    def n_species(self) -> int:
        return self.fields.shape[-1 - self.ndim]

    @property
    def capacity(self) -> tuple[int, ...]:
        return tuple(self.fields.shape[-self.ndim:])

    @property
    def shape(self) -> tuple[int, ...]:
        """The active region, e.g. (rows, cols), as Python ints (concrete states only)."""
        return tuple(int(v) for v in np.asarray(self.size).reshape(-1, self.ndim)[0])

    def arrays(self) -> list[np.ndarray]:
        """One NumPy array per species, cropped to the active region."""
        if self.fields.ndim != 1 + self.ndim:
            raise ValueError(
                "arrays() needs a single state; this one is batched with leading axes "
                f"{self.fields.shape[:-1 - self.ndim]} (use frame(i) or index the fields)"
            )
        data = np.asarray(self.fields)
        return [data[(i,) + _corner(self.shape)].copy() for i in range(self.n_species)]

    def array(self, species) -> np.ndarray:
        """One species (by name or index), cropped to the active lattice."""
        return self.arrays()[self.index(species)]

    def index(self, species) -> int:
        """Position of a species given by name or index (0 .. n_species - 1); a ValueError otherwise."""
        if isinstance(species, (int, np.integer)):
            if not 0 <= species < self.n_species:
                raise ValueError(f"species index {species} out of range 0..{self.n_species - 1}")
            return int(species)
        if species not in self.names:
            raise ValueError(f"unknown species {species!r}; this state has {', '.join(self.names)}")
        return self.names.index(species)

    def frame(self, i: int) -> "State":
        """Element `i` of a state with a leading axis (snapshots from `rollout`, sweeps)."""
        return jax.tree_util.tree_map(lambda x: x[i], self)

    # ---- species bookkeeping between phases ----------------------------------------
    def with_species(self, name: str, values=None, copy_of=None) -> "State":
        """Append a species: a copy of an existing one (`copy_of`), a constant or an array."""
        if name in self.names:
            raise ValueError(f"species {name!r} already exists in this state ({', '.join(self.names)})")
        axis = -1 - self.ndim  # the species axis
        if copy_of is not None:
            new = self.fields[(Ellipsis, self.index(copy_of)) + (slice(None),) * self.ndim]
        else:
            values = 0.0 if values is None else values
            arr = jnp.asarray(values, self.fields.dtype)
            if arr.ndim == 0:  # a constant on the active region (works with a traced size)
                new = jnp.where(self.active(), arr, jnp.zeros((), self.fields.dtype))
            else:
                new = jnp.zeros(self.capacity, self.fields.dtype)
                new = new.at[_corner(arr.shape)].set(arr)
        fields = jnp.concatenate([self.fields, jnp.expand_dims(new, axis)], axis=axis)
        return State(fields, self.size, self.step, self.time, self.names + (name,), self.growable)

    def select(self, names: Sequence) -> "State":
        """Keep only the given species, in the given order."""
        idx = [self.index(n) for n in names]
        names = tuple(self.names[i] for i in idx)
        fields = self.fields[(Ellipsis, jnp.asarray(idx)) + (slice(None),) * self.ndim]
        return State(fields, self.size, self.step, self.time, names, self.growable)

    def rename(self, names: Sequence[str]) -> "State":
        """The same state with new species names (one per species)."""
        return State(self.fields, self.size, self.step, self.time, tuple(names), self.growable)

    def active(self):
        """Boolean mask of the active region over the capacity (works with a traced size)."""
        mask = True
        for axis, n in enumerate(self.capacity):
            index = jnp.arange(n).reshape((n,) + (1,) * (self.ndim - 1 - axis))
            size = self.size[..., axis].reshape(self.size.shape[:-1] + (1,) * self.ndim)
            mask = mask & (index < size)
        return mask

    def with_capacity(self, capacity) -> "State":
        """The same state with a different (larger) capacity for growth; reallocates."""
        capacity = tuple(int(c) for c in capacity)
        if len(capacity) != self.ndim:
            raise ValueError(f"capacity {capacity} must have {self.ndim} sizes, one per spatial axis")
        if is_concrete(self.size) and any(c < n for c, n in zip(capacity, self.shape)):
            raise ValueError(f"capacity {capacity} is smaller than the active region {self.shape}")
        # cells beyond the active region are zero, so copying the old block keeps the
        # invariant without reading the (possibly traced) active size
        keep = _corner(tuple(min(c, o) for c, o in zip(capacity, self.capacity)))
        fields = jnp.zeros(self.fields.shape[:-self.ndim] + capacity, self.fields.dtype)
        fields = fields.at[(Ellipsis,) + keep].set(self.fields[(Ellipsis,) + keep])
        return State(fields, self.size, self.step, self.time, self.names, growable=True)


def _corner(shape) -> tuple:
    """Index of the leading block of `shape` along the last len(shape) axes."""
    return tuple(slice(0, int(n)) for n in shape)

"""`Cells`: the state of the thesis's off-lattice simulator (thesis chapters 3-4).

Every cell is a point of unit radius (thesis 4.4) with its own concentrations, diffusion
rates (eq. 4.7 combines two cells' rates), polarity, birth iteration and fixed flag. The
cells live in fixed-capacity buffers in the jax-md manner: the live cells are the leading
`count` entries (division appends children after them, nothing ever dies), the rest is
unused capacity holding zeros. Running out of capacity, or out of room in the neighbour
search, is recorded with the iteration where it happened (`overflow_step`,
`neighbour_overflow_step`), never silently.

The cells also carry the neighbour list their last run left (`neighbours`, None before any
run): it is part of the run's state, so a run resumed from them, or from their file, goes
on bit for bit as the uninterrupted run (`_neighbours`).

Cells on a torus (`period`, the (width, height) of a periodic rectangle centred on the
origin: `create sqr_grid ... wrap`) keep their positions inside it, and every run of them
is periodic (`simulate_cells`), so a run resumed from them, or from their file, is too.

Units: lengths are cell radii (cells of a square grid sit 2 apart, the influence radius
is 3); angles are radians from the +x axis toward +y; time is iterations x dt.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._checks import check_memory, default_float
from ._neighbours import NeighbourList
from ._space import check_period, wrap_positions

NO_STEP = -1  # the value of a *_step field while nothing has happened
STATUS_FIELDS = ("overflow_step", "neighbour_overflow_step", "nonfinite_step")  # what went wrong, and when
PER_REAGENT = ("concentration", "diffusion")  # buffers of shape (species, capacity)


class Cells(eqx.Module):
    """Point cells with reagents, in buffers of fixed capacity.

    Attributes:
        position: (capacity, 2) cell centres, in cell radii.
        polarity: (capacity,) polarity angle in radians from +x toward +y. A cell that is
            not polarised still keeps an angle: divisions are placed relative to it.
        polarised: (capacity,) bool, whether the polarity steers anisotropic diffusion
            (thesis eq. 4.8); unpolarised cells diffuse isotropically.
        concentration: (species, capacity) reagent concentrations.
        diffusion: (species, capacity) per-cell diffusion rates (thesis 3.2, eq. 4.7).
        birth: (capacity,) int32, the iteration a cell appeared in (AGE = iteration - birth).
        fixed: (capacity,) bool, cells that collisions never move (thesis 4.8.3).
        count: int32 scalar, the live cells: entries [0, count) of every buffer.
        step: int32 scalar, iterations simulated so far (the next iteration's number).
        overflow_step: int32 scalar, the first iteration whose divisions did not fit in the
            capacity (those children were not created); -1 if none.
        neighbour_overflow_step: int32 scalar, the first iteration whose neighbour search
            ran out of room (a cell had more neighbours than `max_neighbours`, or a search
            bucket more cells than it holds); -1 if none.
        nonfinite_step: int32 scalar, the first iteration that produced NaN or Inf; -1 if none.
        species: reagent names (static), in the order of the concentration rows.
        lower, upper: (species,) the limits every concentration is clamped to after each
            iteration: `upper` the saturation limit (+inf for none; thesis 4.8.1 "define
            chemical R limit L"), `lower` 0 as in the thesis (4.1, step 6: "negative
            reagent concentrations are set to zero"), or a model's own lower limit for the
            reagents it reacts (FitzHugh-Nagumo's are -inf).
        anisotropic: (static) per reagent, whether its diffusion follows the polarity.
        neighbours: the `NeighbourList` the last `simulate_cells` call ended with (None for
            cells no run produced, and for cells rebuilt from their live buffers, as
            `concatenate` does): the next call goes on from it, so a resumed run equals an
            uninterrupted one bit for bit.
        period: (static) (width, height) of the torus the cells live on (a periodic
            rectangle centred on the origin), or None for an open domain.
    """

    position: Array
    polarity: Array
    polarised: Array
    concentration: Array
    diffusion: Array
    birth: Array
    fixed: Array
    count: Array
    step: Array
    overflow_step: Array
    neighbour_overflow_step: Array
    nonfinite_step: Array
    lower: Array
    upper: Array
    species: tuple[str, ...] = eqx.field(static=True)
    anisotropic: tuple[bool, ...] = eqx.field(static=True)
    neighbours: NeighbourList | None = None
    period: tuple[float, float] | None = eqx.field(static=True, default=None)

    @property
    def capacity(self) -> int:
        return self.position.shape[0]

    @property
    def n_species(self) -> int:
        return len(self.species)

    @property
    def alive(self) -> Array:
        """(capacity,) bool: the live cells (the leading `count` entries)."""
        return jnp.arange(self.capacity) < self.count

    def index(self, name: str) -> int:
        """The row of reagent `name` in `concentration` and `diffusion`."""
        if name not in self.species:
            raise ValueError(f"unknown reagent {name!r}; the cells carry {', '.join(self.species)}")
        return self.species.index(name)

    def live(self) -> dict[str, np.ndarray]:
        """NumPy copies of the live cells' buffers (concrete cells only), by field name."""
        n = int(self.count)
        return {
            "position": np.asarray(self.position[:n]),
            "polarity": np.asarray(self.polarity[:n]),
            "polarised": np.asarray(self.polarised[:n]),
            "concentration": np.asarray(self.concentration[:, :n]),
            "diffusion": np.asarray(self.diffusion[:, :n]),
            "birth": np.asarray(self.birth[:n]),
            "fixed": np.asarray(self.fixed[:n]),
        }

    def __getitem__(self, name: str) -> Array:
        """The concentrations of reagent `name` over the whole capacity."""
        return self.concentration[self.index(name)]

    # ---- status -------------------------------------------------------------------
    @property
    def ok(self) -> Array:
        """True where the run neither blew up nor ran out of cell or neighbour room."""
        return (self.overflow_step < 0) & (self.neighbour_overflow_step < 0) & (self.nonfinite_step < 0)

    def message(self) -> str:
        """What went wrong, in words (concrete cells); "ok" if nothing did."""
        problems = []
        if int(self.nonfinite_step) >= 0:
            problems.append(f"the concentrations became non-finite (NaN or Inf) at iteration "
                            f"{int(self.nonfinite_step)}: the run blew up; reduce dt")
        if int(self.overflow_step) >= 0:
            problems.append(f"divisions at iteration {int(self.overflow_step)} did not fit in the capacity of "
                            f"{self.capacity} cells (those children were not created); pass a larger capacity")
        if int(self.neighbour_overflow_step) >= 0:
            problems.append(f"the neighbour search ran out of room at iteration {int(self.neighbour_overflow_step)} "
                            "(neighbours were missed); pass a larger max_neighbours or bucket_size")
        return "; ".join(problems) if problems else "ok"

    # ---- building -----------------------------------------------------------------
    def with_capacity(self, capacity: int) -> "Cells":
        """The same cells, their run's status and their neighbour list, in buffers of
        `capacity` entries (at least `count`)."""
        resized = concatenate([self], capacity)
        resized = resized.replace(**{name: getattr(self, name) for name in STATUS_FIELDS})
        carried = None if self.neighbours is None else self.neighbours.resized(int(capacity))
        return resized.with_neighbours(carried)

    def with_period(self, period) -> Cells:
        """The same cells on the torus `period` ((width, height), both > 0), their live
        positions wrapped into it; None: on an open domain (positions unchanged)."""
        period = check_period(period)
        cells = dataclasses.replace(self, period=period)
        if period is None:
            return cells
        wrapped = jnp.where(self.alive[:, None], wrap_positions(self.position, period), self.position)
        return cells.replace(position=wrapped)

    def with_neighbours(self, neighbours: NeighbourList | None) -> "Cells":
        """A copy carrying `neighbours` (None: none, so the next run builds its own)."""
        return eqx.tree_at(lambda c: c.neighbours, self, neighbours, is_leaf=lambda x: x is None)

    def replace(self, **changes) -> "Cells":
        """A copy with some fields replaced (e.g. `cells.replace(upper=...)`)."""
        names = list(changes)
        return eqx.tree_at(lambda c: [getattr(c, k) for k in names], self, [changes[k] for k in names])


# Bytes a cell costs while it is built and stepped, per reagent and generously: its buffers
# in float64 as NumPy builds them, the device's float32 copies, and its neighbour-list rows
CELL_BYTES = 512


def check_cell_count(cells, what: str) -> None:
    """Refuse, before anything is allocated, `cells` cell-reagents that would need more
    memory than `memory_limit()` (ValueError saying how much, `check_memory`)."""
    check_memory(float(cells) * CELL_BYTES, what)


def make_cells(
    species: Sequence[str],
    position,
    *,
    concentration=None,
    diffusion=None,
    polarity=None,
    polarised=None,
    birth=None,
    fixed=None,
    lower=None,
    upper=None,
    anisotropic=(),
    capacity: int | None = None,
    step: int = 0,
    period=None,
) -> Cells:
    """Cells from NumPy-like arrays of the live cells (n of them), padded to `capacity`.

    `concentration`/`diffusion`: (species, n) arrays, or one value per species. `polarity`:
    angles in radians, or NaN where a cell is unpolarised (`polarised` then defaults to the
    finite entries). `anisotropic`: names of the reagents whose diffusion follows polarity,
    or one bool per reagent. `upper`: saturation limits per reagent (None = no limit);
    `lower`: the lower limits (default 0, as the thesis). `period`: (width, height) of the
    torus the cells live on (positions are wrapped into it), None for an open domain.
    """
    species = tuple(str(s) for s in species)
    if not species or len(set(species)) != len(species):
        raise ValueError(f"species must be distinct reagent names, at least one (got {species!r})")
    position = np.asarray(position, dtype=float)
    if position.ndim != 2 or position.shape[1] != 2:
        raise ValueError(f"position must have shape (cells, 2) (got {position.shape})")
    n = position.shape[0]
    capacity = n if capacity is None else capacity
    if isinstance(capacity, bool) or not isinstance(capacity, (int, np.integer)) or capacity < max(n, 1):
        raise ValueError(f"capacity must be an integer >= the number of cells ({max(n, 1)}) (got {capacity!r})")
    s = len(species)
    check_cell_count(int(capacity) * max(s, 1), f"a capacity of {capacity} cells of {s} reagents")

    def per_cell(values, name, default):
        arr = np.asarray(default if values is None else values, dtype=float)
        if arr.ndim == 0:
            arr = np.full((s, n), float(arr))
        elif arr.ndim == 1 and arr.shape[0] == s:
            arr = np.repeat(arr[:, None], n, axis=1)
        if arr.shape != (s, n):
            raise ValueError(f"{name} must be one value per reagent or an array ({s}, {n}) (got shape {arr.shape})")
        return arr

    conc = per_cell(concentration, "concentration", 0.0)
    diff = per_cell(diffusion, "diffusion", 0.0)
    if (diff < 0).any() or not np.isfinite(diff).all():
        raise ValueError("diffusion rates must be finite and >= 0")
    if not np.isfinite(conc).all():
        raise ValueError("concentration must be finite")
    angle = np.zeros(n) if polarity is None else np.broadcast_to(np.asarray(polarity, dtype=float), (n,)).copy()
    if polarised is None:
        polarised = np.isfinite(angle) if polarity is not None else np.zeros(n, bool)
    polarised = np.broadcast_to(np.asarray(polarised, dtype=bool), (n,))
    angle = np.where(np.isfinite(angle), angle, 0.0)
    birth = np.zeros(n, np.int32) if birth is None else np.broadcast_to(np.asarray(birth, np.int32), (n,))
    fixed = np.zeros(n, bool) if fixed is None else np.broadcast_to(np.asarray(fixed, bool), (n,))
    limits = np.full(s, np.inf) if upper is None else np.array(
        [np.inf if u is None else float(u) for u in (upper if np.ndim(upper) else [upper] * s)])
    if limits.shape != (s,) or np.isnan(limits).any() or (limits < 0).any():
        raise ValueError(f"upper must hold one limit >= 0 (or None) per reagent, {s} in all (got {upper!r})")
    floors = np.zeros(s) if lower is None else np.broadcast_to(np.asarray(lower, float), (s,)).copy()
    if np.isnan(floors).any() or np.isposinf(floors).any() or (floors > limits).any():
        raise ValueError(f"lower must hold one limit per reagent, below its upper limit (got {lower!r})")
    if anisotropic and all(isinstance(a, (bool, np.bool_)) for a in anisotropic):
        flags = tuple(bool(a) for a in anisotropic)
    else:
        unknown = [a for a in anisotropic if a not in species]
        if unknown:
            raise ValueError(f"anisotropic names unknown reagents {unknown}; the cells carry {', '.join(species)}")
        flags = tuple(name in anisotropic for name in species)
    if len(flags) != s:
        raise ValueError(f"anisotropic needs one flag per reagent ({s}) (got {len(flags)})")

    def pad(arr, axis=0):
        widths = [(0, 0)] * arr.ndim
        widths[axis] = (0, capacity - n)
        return np.pad(arr, widths)

    period = check_period(period)
    dtype = default_float()
    cells = Cells(
        position=jnp.asarray(pad(position), dtype),
        polarity=jnp.asarray(pad(angle), dtype),
        polarised=jnp.asarray(pad(polarised)),
        concentration=jnp.asarray(pad(conc, 1), dtype),
        diffusion=jnp.asarray(pad(diff, 1), dtype),
        birth=jnp.asarray(pad(birth), jnp.int32),
        fixed=jnp.asarray(pad(fixed)),
        count=jnp.asarray(n, jnp.int32),
        step=jnp.asarray(step, jnp.int32),
        overflow_step=jnp.asarray(NO_STEP, jnp.int32),
        neighbour_overflow_step=jnp.asarray(NO_STEP, jnp.int32),
        nonfinite_step=jnp.asarray(NO_STEP, jnp.int32),
        lower=jnp.asarray(floors, dtype),
        upper=jnp.asarray(limits, dtype),
        species=species,
        anisotropic=flags,
    )
    return cells if period is None else cells.with_period(period)



def concatenate(groups: Sequence[Cells], capacity: int | None = None) -> Cells:
    """Several groups of cells as one (indices follow the order of `groups`, as the
    thesis's `create` commands number cells in the order they are placed)."""
    groups = list(groups)
    if not groups:
        raise ValueError("concatenate needs at least one group of cells")
    first = groups[0]
    for g in groups[1:]:
        if g.species != first.species:
            raise ValueError(f"every group must carry the same reagents (got {first.species} and {g.species})")
        if g.period != first.period:
            raise ValueError(f"every group must live on the same torus (got periods {first.period} and {g.period})")
    parts = [g.live() for g in groups]
    arrays = {name: np.concatenate([p[name] for p in parts], axis=1 if name in PER_REAGENT else 0)
              for name in parts[0]}
    position = arrays.pop("position")
    return make_cells(
        first.species, position, **arrays, lower=np.asarray(first.lower), upper=np.asarray(first.upper),
        anisotropic=first.anisotropic, capacity=len(position) if capacity is None else capacity, step=int(first.step),
        period=first.period,
    )

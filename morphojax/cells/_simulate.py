"""`simulate_cells`: run the cell simulator for a number of iterations under one
`jax.lax.scan` (pure: `jit`, `vmap` over a parameter and `grad` of a loss of the final
concentrations all work)."""

from __future__ import annotations


import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._checks import as_float_array, check_count, check_finite, check_range, is_concrete
from .._progress import progress_bar
from .._repeat import repeat
from .._status import SimulationError
from ..models import AbstractModel
from ._neighbours import PATCH_SIZES, Search, table_size_for
from ._neighbours import needed_room as _needed_room
from ._rules import Chance, Change, Divide, React, Rule, check_rules
from ._space import Torus, as_domain
from ._state import Cells
from ._step import Settings, contacts, harmonic_rate, step

INFLUENCE_RADIUS = 3.0  # thesis 4.2: the six hexagonal or eight Moore neighbours of unit-radius cells
SKIN = 0.3  # Verlet skin: the list holds pairs within 3.3; a cell that moves 0.15 is patched in again
MAX_NEIGHBOURS = 20  # a packed or hexagonal tissue has 6-12 cells within 3.3; crowded growth more
BUCKET_SIZE = 8  # cells per bucket of side 3.3 (a packed tissue averages 3.4)
PIECES = 50  # a progress bar moves in 50 pieces of the run
MAX_ROOM = 512  # neighbours per cell or cells per bucket: no tissue of unit cells needs more


def simulate_cells(
    model: AbstractModel | None,
    cells: Cells,
    steps: int,
    dt=1.0,
    *,
    rules=(),
    key=None,
    species=None,
    domain=None,
    division_limit: int | None = None,
    influence_radius: float = INFLUENCE_RADIUS,
    max_neighbours: int | None = None,
    bucket_size: int | None = None,
    throw: bool = True,
    progress: bool | str = False,
    check_dt: bool = True,
) -> Cells:
    """Run `steps` iterations of the thesis's cell simulator (chapter 4).

    Args:
        model: a reaction every live cell runs every iteration (`React(model, species)`
            placed before `rules`), or None for rules only. The reagents it reacts take
            its lower limits and the smaller of its and the cells' upper limits. The
            cells carry their own diffusion rates (eq. 4.7 combines them); the model's
            rates are not used here: `cell_grid(shape, model)` seeds cells with them.
        cells: the initial `Cells` (with room to divide into: see `capacity`).
        steps: iterations to run.
        dt: the time step multiplying reactions and diffusion (not `Change` amounts).
        rules: `Rule`s evaluated every iteration, in order (thesis 4.8.5).
        key: a `jax.random` key, required when a rule draws random numbers.
        species: the reagents `model` reacts (default: the cells' first ones).
        domain: None (unbounded), (width, height) / `Box`, "packed" / `Packed(area)`, or
            `Torus(width, height)` (periodic: neighbours, diffusion and collisions across
            the edges by the minimum-image convention, positions wrapped into it; each
            side at least twice influence_radius + 0.3, the search's radius). Cells that
            live on a torus (`cells.period`, e.g. from a `wrap` grid or a file) run on it
            whatever the domain (None, or the same `Torus`; another is refused); cells
            run on a `Torus` come back living on it.
        division_limit: cells with more neighbours than this do not divide (4.8.1).
        influence_radius: neighbours are the cells closer than this (4.2).
        max_neighbours, bucket_size: room in the neighbour search: partners per cell, and
            cells per bucket on average over three in a row (a full build reads 3 x
            bucket_size candidates from each of a cell's three rows of buckets;
            `needed_room` says what cells need). Default: the room of the neighbour list
            the cells carry (for the same influence radius), else 20 and 8.
        throw: raise `SimulationError` (naming the iteration) when the run blew up, a
            division found no room or the neighbour search overflowed. Inside `jit` or
            `vmap` nothing is raised: read `cells.ok` / `cells.message()`.
        check_dt: refuse a dt beyond the explicit-Euler limit of the initial cells'
            exchange, dt <= 2 / lambda_max per reagent (lambda_max of sum_j D_ij (R_i -
            R_j), by power iteration; growth and motion change it later).
        progress: show a progress bar (a string names it); the run then goes in pieces
            of equal length (identical results, two compilations at most) and stops at
            the first piece that blew up.

    Returns the cells after the run; `cells.step` counts iterations across calls, so a
    run can be resumed by calling again with the result, or with `load_cells` of its
    file. The cells carry the run's neighbour list (`cells.neighbours`) and the next call
    goes on from it, so n calls, of any lengths (1 included), give bit for bit the cells
    of one call of the same iterations (same rules, key, dt, domain, division limit,
    influence radius and room).
    A call builds a list afresh for cells that carry none or one of another radius,
    capacity or `max_neighbours`: its cells then equal those of an uninterrupted run only
    up to the order of float sums (a patched list puts the same pairs in other slots).

    Decisions where the thesis is silent: a cell divides at most once per iteration (the
    first `Divide` rule that fires sets the angle); children are never fixed, even of a
    fixed parent (Listing A.6 grows from a fixed spine: fixed children would pile up on
    it); a child is its parent as the rules saw it, one update behind it.
    """
    if not isinstance(cells, Cells):
        raise ValueError(f"cells must be a Cells state (got {type(cells).__name__}); build one with mj.cell_grid")
    check_count(steps, "steps", "iterations")
    dt = as_float_array(dt, "dt")
    check_finite(dt, "dt")
    check_range(dt, "dt", low=0.0, low_open=True)
    check_range(influence_radius, "influence_radius", low=0.0, low_open=True)
    radius = float(influence_radius) + SKIN
    domain, cells = _torus_of(as_domain(domain), cells, radius)
    carried = cells.neighbours if isinstance(cells, Cells) else None
    same_search = carried is not None and carried.radius == radius and carried.skin == SKIN
    if max_neighbours is None:  # a resumed run keeps the room it had
        max_neighbours = carried.max_neighbours if same_search else MAX_NEIGHBOURS
    if bucket_size is None:
        bucket_size = carried.bucket_size if same_search else BUCKET_SIZE
    check_count(max_neighbours, "max_neighbours", "neighbours", low=1)
    check_count(bucket_size, "bucket_size", "cells", low=1)
    if division_limit is not None:
        check_count(division_limit, "division_limit", "neighbours")
    rules = tuple(rules)
    if model is not None:
        if not isinstance(model, AbstractModel):
            raise ValueError(f"model must be a morphojax model or None (got {type(model).__name__})")
        reacting = tuple(species) if species is not None else cells.species[: model.n_species]
        rules = (Rule(React(model, reacting)),) + rules
        cells = _with_model_limits(cells, model, reacting)
    rules = check_rules(rules, cells.species)
    if key is None:
        if _draws(rules):
            raise ValueError("key is required: a rule draws random numbers (Chance, a spread, or a Divide with spread)")
        key = jax.random.key(0)
    settings = Settings(
        dt=dt,
        domain=domain,
        influence_radius=float(influence_radius),
        division_limit=division_limit,
        search=Search(radius=radius, skin=SKIN, max_neighbours=int(max_neighbours),
                      bucket_size=int(bucket_size), table_size=table_size_for(cells.capacity),
                      patch_sizes=PATCH_SIZES, period=cells.period),
    )
    if check_dt and steps and is_concrete(cells, dt):
        _check_dt(cells, settings)
    out = _in_pieces(cells, rules, settings, key, steps, progress)
    if throw and is_concrete(out) and not bool(out.ok):  # under vmap or jit: read out.ok
        raise SimulationError(out.message())
    return out


def _torus_of(domain, cells: Cells, radius: float):
    """(domain, cells): cells on a torus run on it (a `Torus` of their period), and cells
    run on a `Torus` come to live on it; a torus narrower than twice the search's
    `radius` is refused (a cell would meet another through two images)."""
    if isinstance(domain, Torus):
        if cells.period is None:
            cells = cells.with_period(domain.period)
        elif cells.period != domain.period:
            raise ValueError(f"the cells live on a torus of {cells.period[0]:g} x {cells.period[1]:g}; domain "
                             f"Torus({domain.width:g}, {domain.height:g}) is another (pass domain=None)")
    elif cells.period is not None:
        if domain is not None:
            raise ValueError(f"the cells live on a torus of {cells.period[0]:g} x {cells.period[1]:g}: domain must be "
                             f"None or that Torus (got {type(domain).__name__})")
        domain = Torus(*cells.period)
    if isinstance(domain, Torus) and min(domain.period) < 2 * radius:
        raise ValueError(f"the torus of {domain.width:g} x {domain.height:g} is too small: each side must be at least "
                         f"2 x (influence_radius + {SKIN:g}) = {2 * radius:g} (the minimum-image convention)")
    return domain, cells


def _in_pieces(cells: Cells, rules, settings: Settings, key, steps: int, progress) -> Cells:
    """`_run`, in pieces of equal length under a progress bar when asked; the cells come
    back carrying the neighbour list the run ended with. The key schedule depends on the
    iteration only and the neighbour list goes from piece to piece (and from call to
    call, with the cells), so the pieces give the same cells as one run, bit for bit."""
    neighbours = _first_neighbours(cells, settings)
    cells = cells.with_neighbours(None)  # the list travels beside the cells inside a run
    if not progress or steps < 2 or not is_concrete(cells, rules, settings):
        cells, neighbours = _run(cells, neighbours, rules, settings, key, steps)
        return cells.with_neighbours(neighbours)
    piece = max(1, steps // PIECES)
    with progress_bar(steps, progress if isinstance(progress, str) else "cells", unit="iteration") as bar:
        done = 0
        while done < steps:
            n = min(piece, steps - done)
            cells, neighbours = _run(cells, neighbours, rules, settings, key, n)
            done += n
            bar.update(n)
            if int(cells.nonfinite_step) >= 0:
                break
    return cells.with_neighbours(neighbours)


def _first_neighbours(cells: Cells, settings: Settings):
    """The list a call starts from: the one the cells carry when it fits this search
    (then the call goes on exactly as the run that left it), else a full build."""
    search, carried = settings.search, cells.neighbours
    if not search.fits(carried, cells.capacity):
        return _build(cells.with_neighbours(None), settings)
    if is_concrete(carried, cells.count) and int(carried.built_count) <= int(cells.count):
        return carried.retagged(bucket_size=search.bucket_size)  # no build to compile
    return _carry_on(cells, settings)


@eqx.filter_jit
def _build(cells: Cells, settings: Settings):
    return settings.search.build(cells.position, cells.count)


@eqx.filter_jit
def _carry_on(cells: Cells, settings: Settings):
    return settings.search.carry_on(cells.neighbours, cells.position, cells.count)


@eqx.filter_jit
def _run(cells: Cells, neighbours, rules, settings: Settings, key, steps: int):
    """`steps` iterations from `cells` and their list (`repeat`: calls of any length,
    one included, give the bits of one call)."""
    cells = eqx.tree_at(
        lambda c: c.neighbour_overflow_step, cells,
        jnp.where((cells.neighbour_overflow_step < 0) & neighbours.overflow, cells.step, cells.neighbour_overflow_step),
    )
    touch = contacts(cells, neighbours, settings.influence_radius)
    cells, neighbours, _ = repeat(lambda carry: step(*carry, rules, settings, key), (cells, neighbours, touch), steps)
    return cells, neighbours


def needed_room(cells: Cells, influence_radius: float = INFLUENCE_RADIUS) -> tuple[int, int]:
    """(max_neighbours, bucket_size) these cells need now in `simulate_cells`'s search
    (neighbours within the influence radius + skin)."""
    return _needed_room(cells.position, cells.count, float(influence_radius) + SKIN, table_size_for(cells.capacity),
                        cells.period)


def _check_dt(cells: Cells, settings: Settings) -> None:
    """ValueError when dt exceeds 2 / lambda_max of some reagent's exchange."""
    largest = np.asarray(_exchange_spectral_radius(cells.with_neighbours(None), _first_neighbours(cells, settings),
                                                   settings))
    limit = 2.0 / np.maximum(largest, 1e-30)
    worst = int(np.argmin(limit))
    if float(settings.dt) > limit[worst] * (1 + 1e-3):
        raise ValueError(
            f"dt = {float(settings.dt):g} exceeds the explicit-Euler limit {limit[worst]:.4g} of reagent "
            f"{cells.species[worst]!r}'s exchange between these cells (2 / the largest eigenvalue, "
            f"{largest[worst]:.4g}, of sum_j D_ij (R_i - R_j)); use dt <= {limit[worst]:.4g}, or check_dt=False")


@eqx.filter_jit
def _exchange_spectral_radius(cells: Cells, neighbours, settings: Settings, iterations: int = 100):
    """Per reagent, the largest eigenvalue of the exchange operator sum_j D_ij (x_i - x_j)
    on the live cells (isotropic rates: anisotropy only lowers them), by power iteration
    (the operator is symmetric and positive semi-definite)."""
    touch = contacts(cells, neighbours, settings.influence_radius)
    rate_j = jnp.take(cells.diffusion, touch.index, axis=1, mode="clip")
    weight = jnp.where(touch.near, harmonic_rate(cells.diffusion[:, :, None], rate_j), 0.0)

    def apply(x):
        return jnp.sum(weight * (x[:, :, None] - jnp.take(x, touch.index, axis=1, mode="clip")), axis=-1)

    x = jnp.where(cells.alive, jax.random.uniform(jax.random.key(0), cells.concentration.shape) - 0.5, 0.0)

    def power(_, x):
        y = apply(x)
        return y / jnp.maximum(jnp.linalg.norm(y, axis=1, keepdims=True), 1e-30)

    x = jax.lax.fori_loop(0, iterations, power, x / jnp.linalg.norm(x, axis=1, keepdims=True))
    return jnp.sum(x * apply(x), axis=1)  # the Rayleigh quotient of a unit vector


def _with_model_limits(cells: Cells, model: AbstractModel, reacting) -> Cells:
    """The reagents `model` reacts take its lower limits and the smaller upper ones."""
    lower, upper = cells.lower, cells.upper
    model_lower = jnp.broadcast_to(jnp.asarray(model.lower), (model.n_species,))
    model_upper = jnp.broadcast_to(jnp.asarray(model.upper), (model.n_species,))
    for i, name in enumerate(reacting):
        row = cells.index(name)
        lower = lower.at[row].set(model_lower[i])
        upper = upper.at[row].min(model_upper[i])
    return cells.replace(lower=lower, upper=upper)


def _draws(rules) -> bool:
    for rule in rules:
        if any(isinstance(c, Chance) for c in rule.when):
            return True
        spread = getattr(rule.action, "spread", None)
        if isinstance(rule.action, (Change, Divide)) and not (is_concrete(spread) and float(spread) == 0.0):
            return True
    return False


__all__ = ["simulate_cells", "INFLUENCE_RADIUS"]

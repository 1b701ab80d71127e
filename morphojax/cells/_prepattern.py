"""Prepatterns: groups of cells placed on square or hexagonal grids, in discs, or anywhere
(the thesis's `create` and `use` commands, section 4.8.2-4.8.3).

Cells of unit radius sit `spacing` = 2 apart, so the influence radius 3 reaches the eight
Moore neighbours on a square grid and the six neighbours on a hexagonal one (thesis 4.2,
Fig. 4.1). Cells are numbered row by row from the lowest row (y increasing with the row),
column by column within a row, as the thesis's `set cell` indices count them; a hexagonal
grid shifts its odd rows half a spacing toward +x and its rows are spacing * sqrt(3) / 2
apart.

Every "spread" is the amplitude of a uniform deviation: a value v with spread d is drawn
from [v - d, v + d] (the thesis's `dev`).
"""

from __future__ import annotations

import math

import jax
import numpy as np

from .._checks import check_choice, check_range
from ..models import AbstractModel
from ._state import Cells, check_cell_count, make_cells

LATTICES = ("square", "hex")
SPACING = 2.0  # cell diameter: unit-radius cells just touch


def grid_positions(shape, lattice: str = "square", spacing: float = SPACING, at=(0.0, 0.0)) -> np.ndarray:
    """(rows * cols, 2) centres of a grid of `shape` = (rows, cols) centred on `at`."""
    rows, cols = _shape(shape)
    check_choice(lattice, "lattice", LATTICES)
    check_range(spacing, "spacing", low=0.0, low_open=True)
    check_cell_count(rows * cols, f"a grid of {rows}x{cols} cells")
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    if lattice == "square":
        x, y = c * spacing, r * spacing
    else:
        x, y = (c + 0.5 * (r % 2)) * spacing, r * spacing * math.sqrt(3) / 2
    xy = np.stack([x.ravel(), y.ravel()], axis=1).astype(float)
    xy -= (xy.min(axis=0) + xy.max(axis=0)) / 2
    return xy + np.asarray(at, float)


def disc_positions(radius: float, lattice: str = "square", spacing: float = SPACING, at=(0.0, 0.0)) -> np.ndarray:
    """Centres of the grid points within `radius` of `at` (a grid point sits on `at`)."""
    check_range(radius, "radius", low=0.0)
    check_choice(lattice, "lattice", LATTICES)
    pitch = spacing if lattice == "square" else spacing * math.sqrt(3) / 2
    # the grid around the disc is built first: refuse its size before it is (an infinite radius too)
    check_cell_count((2 * float(radius) / pitch + 3) * (2 * float(radius) / spacing + 5),
                     f"a disc of radius {radius} cell radii")
    half_rows = int(radius // pitch) + 1
    half_cols = int(radius // spacing) + 2
    rows, cols = 2 * half_rows + 1, 2 * half_cols + 1
    r, c = np.meshgrid(np.arange(rows) - half_rows, np.arange(cols) - half_cols, indexing="ij")
    shift = 0.5 * (np.abs(r) % 2) if lattice == "hex" else 0.0
    xy = np.stack([((c + shift) * spacing).ravel(), (r * pitch).ravel()], axis=1).astype(float)
    inside = np.hypot(xy[:, 0], xy[:, 1]) <= radius + 1e-9
    return xy[inside] + np.asarray(at, float)


def cells_at(
    positions,
    species,
    *,
    concentration=0.0,
    spread=0.0,
    diffusion=None,
    diffusion_spread=0.0,
    polarity=None,
    polarity_spread=0.0,
    jitter=0.0,
    fixed=False,
    upper=None,
    anisotropic=(),
    capacity: int | None = None,
    key=None,
) -> Cells:
    """Cells at the given (n, 2) `positions`, with reagents drawn as the thesis's `use`.

    Args:
        species: reagent names, or a model (its species, diffusion rates and limits).
        concentration, spread: per reagent (or one value for all) the initial
            concentration and the amplitude of its uniform noise.
        diffusion, diffusion_spread: per reagent the diffusion rate (default: the model's,
            or 0) and the amplitude of its noise (rates are kept >= 0).
        polarity, polarity_spread: angle in radians (None: unpolarised) and its noise.
        jitter: amplitude of a uniform displacement of every position, per axis.
        fixed: cells that collisions never move.
        upper, anisotropic: saturation limits and anisotropic reagents (see `make_cells`;
            a model gives its own lower and upper limits).
        capacity: room for divisions (default: just these cells).
        key: a `jax.random` key for the noise (needed when any spread or jitter is > 0).
    """
    names, model_rates, model_lower, model_upper = _species(species)
    positions = np.asarray(positions, float).reshape(-1, 2)
    n, s = positions.shape[0], len(names)
    for name, value in (("spread", spread), ("diffusion_spread", diffusion_spread),
                        ("polarity_spread", polarity_spread), ("jitter", jitter)):
        check_range(value, name, low=0.0)
    noisy = any(np.any(np.asarray(v) > 0) for v in (spread, diffusion_spread, polarity_spread, jitter))
    if noisy and key is None:
        raise ValueError("key is required when spread, diffusion_spread, polarity_spread or jitter is > 0")
    keys = jax.random.split(key, 4) if noisy else [None] * 4

    def uniform(k, shape, amplitude):
        amplitude = np.asarray(amplitude, float)
        if k is None or not np.any(amplitude > 0):
            return np.zeros(shape)
        return np.asarray(jax.random.uniform(k, shape, minval=-1.0, maxval=1.0)) * amplitude

    conc = _per_species(concentration, s, "concentration")[:, None] + uniform(
        keys[0], (s, n), _per_species(spread, s, "spread")[:, None])
    rates = model_rates if diffusion is None else _per_species(diffusion, s, "diffusion")
    if rates is None:
        rates = np.zeros(s)
    diff = np.maximum(rates[:, None] + uniform(keys[1], (s, n), _per_species(diffusion_spread, s, "diffusion_spread")[:, None]), 0.0)
    if polarity is None:
        angle = np.full(n, np.nan)
    else:
        angle = float(polarity) + uniform(keys[2], (n,), polarity_spread)
    xy = positions + uniform(keys[3], (n, 2), jitter)
    return make_cells(
        names, xy, concentration=conc, diffusion=diff, polarity=angle, fixed=np.full(n, bool(fixed)),
        lower=model_lower, upper=model_upper if upper is None else upper, anisotropic=anisotropic, capacity=capacity,
    )


def cell_grid(shape, species, *, lattice: str = "square", spacing: float = SPACING, at=(0.0, 0.0), **fill) -> Cells:
    """A grid of `shape` = (rows, cols) cells on a square or hexagonal lattice (the
    thesis's `create sqr_grid cols rows` and `create hex_grid cols rows`, in (rows, cols)
    order). Reagents, polarity and the rest as `cells_at`."""
    return cells_at(grid_positions(shape, lattice, spacing, at), species, **fill)


def cell_disc(radius: float, species, *, lattice: str = "square", spacing: float = SPACING, at=(0.0, 0.0), **fill) -> Cells:
    """The cells of a square or hexagonal grid within `radius` of `at` (the thesis's
    `create sqr_circle` and `create hex_circle`; the radius is in cell radii)."""
    return cells_at(disc_positions(radius, lattice, spacing, at), species, **fill)


def _shape(shape):
    if len(tuple(shape)) != 2:
        raise ValueError(f"shape must be (rows, cols) (got {shape!r})")
    rows, cols = (int(v) for v in shape)
    if rows < 1 or cols < 1 or (rows, cols) != tuple(shape):
        raise ValueError(f"shape must be two positive integers (rows, cols) (got {shape!r})")
    return rows, cols


def _species(species):
    if isinstance(species, AbstractModel):
        rates = np.asarray(species.diffusion(), float)
        if rates.ndim != 1:
            raise ValueError("a model with diffusion-rate maps cannot seed cells; give the rates per reagent")
        upper = [None if math.isinf(u) else float(u) for u in np.asarray(species.upper)]
        return tuple(species.species), rates, np.asarray(species.lower, float), upper
    if isinstance(species, str):
        species = (species,)
    return tuple(species), None, None, None


def _per_species(value, s: int, name: str) -> np.ndarray:
    arr = np.asarray(value, float)
    if arr.ndim == 0:
        return np.full(s, float(arr))
    if arr.shape != (s,):
        raise ValueError(f"{name} needs one value per reagent ({s}) or one for all (got shape {arr.shape})")
    return arr


__all__ = ["cell_disc", "cell_grid", "cells_at", "disc_positions", "grid_positions"]

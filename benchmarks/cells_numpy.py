"""A straightforward vectorised NumPy port of one iteration of the cell simulator: the
baseline of bench_cells.py.

The iteration of morphojax/cells/_step.py (thesis 4.1), written the way one would port it
to NumPy without a compiler: no fixed-capacity buffers (division appends to the arrays),
no Verlet list (the neighbours are found afresh every iteration), no padding.

1. neighbours: every pair of cells closer than the influence radius, once each (i < j),
   from `scipy.spatial.cKDTree.query_pairs`;
2. rules on the current state, their effects accumulated (thesis 4.8.5): `Change`,
   `React` with the Bard reaction sp (alpha - u v), sp (u v - v - beta) scaled by dt and
   the rule's scale (eqs. 4.5-4.6), `Divide`; conditions `Always`, `Compare`, `Within`
   and `Chance`;
3. diffusion over the pairs: dt D_ij (R_j - R_i) added to cell i and taken from cell j,
   with D_ij = 2 D_i D_j / (D_i + D_j) the harmonic mean of eq. 4.7 (`np.add.at`);
4. collisions over the pairs closer than 2: (0.25 - 0.5 / |d|) d for each cell of the
   pair, d pointing to the other (eq. 4.9); fixed cells never move;
5. limits: concentrations into [0, upper], rates >= 0, positions into the domain;
6. division: each dividing cell with at most `division_limit` neighbours appends a child
   one unit away at angle polarity + direction, a copy of the parent as the rules saw it
   (thesis 4.1, 4.4), clamped into the domain.

What the benchmarked listings do not use is left out and refused: anisotropic diffusion
(eq. 4.8), `Map` and `Polarize` (eq. 4.10), reactions other than Bard's. Arrays keep the
dtype of the cells they come from (float32 by default), as morphojax does.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.spatial import cKDTree

import morphojax.cells as mc
from morphojax.models import Bard

CONTACT = 2.0  # unit-radius cells overlap below this distance (eq. 4.9)


@dataclasses.dataclass
class NumpyCells:
    """The live cells as NumPy arrays: position (n, 2), polarity (n,), polarised (n,),
    concentration and diffusion (species, n), birth (n,), fixed (n,); upper (species,);
    species names; step, the next iteration's number."""

    position: np.ndarray
    polarity: np.ndarray
    polarised: np.ndarray
    concentration: np.ndarray
    diffusion: np.ndarray
    birth: np.ndarray
    fixed: np.ndarray
    upper: np.ndarray
    species: tuple[str, ...]
    step: int

    @property
    def count(self) -> int:
        return self.position.shape[0]


def from_cells(cells: mc.Cells) -> NumpyCells:
    """The live cells of a morphojax `Cells` (concrete), copied into NumPy arrays."""
    if any(cells.anisotropic):
        raise NotImplementedError("the NumPy port has no anisotropic diffusion (eq. 4.8)")
    live = cells.live()
    return NumpyCells(
        position=live["position"].copy(), polarity=live["polarity"].copy(), polarised=live["polarised"].copy(),
        concentration=live["concentration"].copy(), diffusion=live["diffusion"].copy(), birth=live["birth"].copy(),
        fixed=live["fixed"].copy(), upper=np.asarray(cells.upper), species=cells.species, step=int(cells.step),
    )


# ---- 1. neighbours ------------------------------------------------------------------------
@dataclasses.dataclass
class Pairs:
    """The pairs (i, j), i < j, closer than the influence radius; d = position[j] - position[i]."""

    i: np.ndarray
    j: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    distance: np.ndarray


def pairs_within(position: np.ndarray, radius: float) -> Pairs:
    """Every pair strictly closer than `radius` (query_pairs includes the radius itself:
    the strict test on the cells' own dtype then matches morphojax's)."""
    ij = cKDTree(position).query_pairs(radius, output_type="ndarray")
    i, j = ij[:, 0], ij[:, 1]
    dx = position[j, 0] - position[i, 0]
    dy = position[j, 1] - position[i, 1]
    near = dx * dx + dy * dy < np.asarray(radius * radius, position.dtype)
    i, j, dx, dy = i[near], j[near], dx[near], dy[near]
    return Pairs(i, j, dx, dy, np.sqrt(dx * dx + dy * dy))


def neighbour_counts(pairs: Pairs, n: int) -> np.ndarray:
    return np.bincount(pairs.i, minlength=n) + np.bincount(pairs.j, minlength=n)


# ---- 2. rules -------------------------------------------------------------------------------
@dataclasses.dataclass
class Effects:
    conc: np.ndarray
    rates: np.ndarray
    divide: np.ndarray
    direction: np.ndarray


_COMPARE = {"==": np.equal, "!=": np.not_equal, "<": np.less, "<=": np.less_equal, ">": np.greater,
            ">=": np.greater_equal}


def _value(v, s: NumpyCells, near_count: np.ndarray):
    if not isinstance(v, mc.Var):
        return np.asarray(v, s.position.dtype)
    if v.kind == "conc":
        return s.concentration[s.species.index(v.name)]
    if v.kind == "diff":
        return s.diffusion[s.species.index(v.name)]
    if v.kind == "AGE":
        return (s.step - s.birth).astype(s.position.dtype)
    if v.kind == "BIRTH":
        return s.birth.astype(s.position.dtype)
    if v.kind == "NEIGHBORS":
        return near_count.astype(s.position.dtype)
    raise NotImplementedError("the NumPy port has no Map values")


def _holds(condition, s: NumpyCells, near_count, rng) -> np.ndarray:
    n = s.count
    value = lambda v: _value(v, s, near_count)  # noqa: E731
    if isinstance(condition, mc.Always):
        return np.ones(n, bool)
    if isinstance(condition, mc.Compare):
        return np.broadcast_to(_COMPARE[condition.op](value(condition.left), value(condition.right)), (n,))
    if isinstance(condition, mc.Within):
        x = value(condition.value)
        return np.broadcast_to((x >= value(condition.low)) & (x <= value(condition.high)), (n,))
    return rng.random(n) < value(condition.probability)


def _uniform(rng, n: int, amplitude) -> np.ndarray:
    amplitude = float(np.asarray(amplitude))
    return rng.uniform(-amplitude, amplitude, n) if amplitude > 0 else np.zeros(n)


def apply_rules(rules, s: NumpyCells, near_count: np.ndarray, dt: float, rng) -> Effects:
    """The accumulated effects of the rules on the current state (thesis 4.8.5)."""
    n = s.count
    fx = Effects(np.zeros_like(s.concentration), np.zeros_like(s.diffusion), np.zeros(n, bool),
                 np.zeros(n, s.position.dtype))
    for rule in rules:
        if (rule.start is not None and s.step < rule.start) or (rule.stop is not None and s.step > rule.stop):
            continue
        mask = np.ones(n, bool)
        for condition in rule.when:
            mask &= _holds(condition, s, near_count, rng)
        action = rule.action
        if isinstance(action, mc.Change):
            amount = np.broadcast_to(_value(action.amount, s, near_count), (n,)) + _uniform(rng, n, action.spread)
            target = fx.conc if action.target.kind == "conc" else fx.rates
            target[s.species.index(action.target.name)] += np.where(mask, amount, 0).astype(target.dtype)
        elif isinstance(action, mc.React):
            if not isinstance(action.model, Bard):
                raise NotImplementedError("the NumPy port reacts only Bard's reaction (eqs. 4.5-4.6)")
            a, b = (s.species.index(name) for name in action.species)
            alpha, beta, sp = (float(np.asarray(getattr(action.model, k))) for k in ("alpha", "beta", "sp"))
            u, v = s.concentration[a], s.concentration[b]
            scale = dt * sp * _value(action.scale, s, near_count)
            uv = u * v
            fx.conc[a] += np.where(mask, scale * (alpha - uv), 0)
            fx.conc[b] += np.where(mask, scale * (uv - v - beta), 0)
        elif isinstance(action, mc.Divide):
            first = mask & ~fx.divide  # the first divide rule that fires sets the direction
            angle = float(np.asarray(action.direction)) + _uniform(rng, n, action.spread)
            fx.direction = np.where(first, angle, fx.direction).astype(fx.direction.dtype)
            fx.divide |= mask
        else:
            raise NotImplementedError(f"the NumPy port has no {type(action).__name__} action")
    return fx


# ---- 3-4. diffusion and collisions ---------------------------------------------------------
def diffusion_change(s: NumpyCells, pairs: Pairs, dt: float) -> np.ndarray:
    """dt sum_j D_ij (R_j - R_i) per reagent and cell (eq. 4.7), shape (species, n)."""
    change = np.zeros_like(s.concentration)
    for r in range(len(s.species)):
        rate_i, rate_j = s.diffusion[r, pairs.i], s.diffusion[r, pairs.j]
        total = rate_i + rate_j
        combined = np.where(total > 0, 2 * rate_i * rate_j / np.where(total > 0, total, 1), 0)
        flux = dt * combined * (s.concentration[r, pairs.j] - s.concentration[r, pairs.i])
        np.add.at(change[r], pairs.i, flux)
        np.add.at(change[r], pairs.j, -flux)
    return change


def collision_offset(s: NumpyCells, pairs: Pairs) -> np.ndarray:
    """Eq. 4.9 over the overlapping pairs (0 < |d| < 2), shape (n, 2); zero for fixed cells."""
    touch = (pairs.distance < CONTACT) & (pairs.distance > 0)
    i, j, d = pairs.i[touch], pairs.j[touch], pairs.distance[touch]
    weight = 0.25 - 0.5 / d
    push = np.stack([weight * pairs.dx[touch], weight * pairs.dy[touch]], axis=1)
    offset = np.zeros_like(s.position)
    np.add.at(offset, i, push)
    np.add.at(offset, j, -push)
    offset[s.fixed] = 0
    return offset


# ---- 5. limits ------------------------------------------------------------------------------
def clamp_positions(domain, position: np.ndarray, count: int) -> np.ndarray:
    if domain is None:
        return position
    if isinstance(domain, mc.Packed):
        half = np.full(2, math.sqrt(float(np.asarray(domain.area)) * count) / 2)
    else:
        half = np.array([float(np.asarray(domain.width)), float(np.asarray(domain.height))]) / 2
    half = half.astype(position.dtype)
    return np.clip(position, -half, half)


# ---- 6. division ----------------------------------------------------------------------------
def divide(s: NumpyCells, parents_state: NumpyCells, wants: np.ndarray, direction: np.ndarray, domain=None) -> NumpyCells:
    """A child for every cell in `wants`, appended in index order: a copy of the parent as
    the rules saw it (`parents_state`, the iteration's current state), one unit from its
    current position at its polarity + direction, clamped into the domain (thesis 4.1, 4.4)."""
    parents = np.flatnonzero(wants)
    if parents.size == 0:
        return s
    p = parents_state
    angle = (p.polarity[parents] + direction[parents]).astype(s.polarity.dtype)
    child = p.position[parents] + np.stack([np.cos(angle), np.sin(angle)], axis=1)
    position = np.concatenate([s.position, child])
    return dataclasses.replace(
        s,
        position=clamp_positions(domain, position, len(position)).astype(s.position.dtype),
        polarity=np.concatenate([s.polarity, angle]),
        polarised=np.concatenate([s.polarised, p.polarised[parents]]),
        concentration=np.concatenate([s.concentration, p.concentration[:, parents]], axis=1),
        diffusion=np.concatenate([s.diffusion, p.diffusion[:, parents]], axis=1),
        birth=np.concatenate([s.birth, np.full(parents.size, s.step, s.birth.dtype)]),  # born next iteration
        fixed=np.concatenate([s.fixed, np.zeros(parents.size, bool)]),
    )


# ---- the iteration ----------------------------------------------------------------------------
def step(s: NumpyCells, rules, dt: float, rng, *, radius: float = 3.0, division_limit: int | None = None,
         domain=None) -> NumpyCells:
    """One iteration (thesis 4.1), the same order as morphojax's `_step.step`."""
    n = s.count
    pairs = pairs_within(s.position, radius)
    near_count = neighbour_counts(pairs, n)
    fx = apply_rules(rules, s, near_count, dt, rng)
    concentration = np.clip(s.concentration + fx.conc + diffusion_change(s, pairs, dt), 0, s.upper[:, None])
    rates = np.maximum(s.diffusion + fx.rates, 0)
    position = clamp_positions(domain, s.position + collision_offset(s, pairs), n)
    nxt = dataclasses.replace(s, position=position, concentration=concentration.astype(s.concentration.dtype),
                              diffusion=rates, step=s.step + 1)
    wants = fx.divide
    if division_limit is not None:
        wants = wants & (near_count <= division_limit)
    return divide(nxt, s, wants, fx.direction, domain)


def run(s: NumpyCells, rules, steps: int, dt: float, rng, **settings) -> NumpyCells:
    for _ in range(steps):
        s = step(s, rules, dt, rng, **settings)
    return s

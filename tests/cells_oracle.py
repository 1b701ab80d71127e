"""An independent NumPy oracle of one iteration of the thesis's cell simulator (4.1):
brute-force neighbours, per-cell loops, the equations written out as the thesis states
them (4.7 harmonic mean, 4.8 anisotropy, 4.9 collision impulse, 4.10 polarization).

It interprets the same rule objects as the simulator but reads only their fields, so a
wrong evaluation in morphojax's compiled step shows up as a mismatch. Random draws cannot
be reproduced, so the oracle accepts only rules without Chance or spreads.

On a torus (`period`, (width, height) centred on the origin) every offset between two
cells is its nearest periodic image, written out per axis as d - L round(d / L), and
positions (children's too) are wrapped into [-L/2, L/2) after the iteration.
"""

from __future__ import annotations

import math

import numpy as np

import morphojax.cells as mc


def displacement(pos: np.ndarray, i: int, j: int, period=None) -> np.ndarray:
    """d = pos[j] - pos[i], on a torus its minimum image."""
    d = pos[j] - pos[i]
    if period is not None:
        d = d - np.asarray(period) * np.round(d / np.asarray(period))
    return d


def wrap(pos: np.ndarray, period) -> np.ndarray:
    """Positions wrapped into the torus centred on the origin (unchanged without one)."""
    if period is None:
        return pos
    size = np.asarray(period, float)
    return pos - size * np.floor((pos + size / 2) / size)


def neighbours(pos: np.ndarray, radius: float, period=None) -> list[list[int]]:
    n = len(pos)
    return [[j for j in range(n) if j != i and np.hypot(*displacement(pos, i, j, period)) < radius] for i in range(n)]


def _num(x):
    return float(np.asarray(x))


def _value(v, i, s, t, nb, maps):
    if not isinstance(v, mc.Var):
        return _num(v)
    if v.kind == "conc":
        return s["conc"][s["species"].index(v.name), i]
    if v.kind == "diff":
        return s["rates"][s["species"].index(v.name), i]
    if v.kind == "AGE":
        return float(t - s["birth"][i])
    if v.kind == "BIRTH":
        return float(s["birth"][i])
    if v.kind == "NEIGHBORS":
        return float(len(nb[i]))
    return maps[v.name][i]


_OPS = {"==": lambda a, b: a == b, "!=": lambda a, b: a != b, "<": lambda a, b: a < b,
        "<=": lambda a, b: a <= b, ">": lambda a, b: a > b, ">=": lambda a, b: a >= b}


def step(s: dict, rules, t: int, dt: float, radius: float = 3.0, division_limit=None, box=None,
         period=None) -> dict:
    """One iteration on a dict of live-cell arrays: pos (n,2), angle (n,), polarised (n,),
    conc (S,n), rates (S,n), birth (n,), fixed (n,), upper (S,), aniso (S,), species;
    `box` clamps positions into a rectangle, `period` makes the domain a torus."""
    pos, conc, rates = s["pos"], s["conc"], s["rates"]
    n, S = len(pos), conc.shape[0]
    nb = neighbours(pos, radius, period)
    dconc, drates = np.zeros_like(conc), np.zeros_like(rates)
    divide, direction = np.zeros(n, bool), np.zeros(n)
    angle, polarised = s["angle"].copy(), s["polarised"].copy()
    maps: dict[str, np.ndarray] = {}
    for rule in rules:
        in_window = (rule.start is None or t >= rule.start) and (rule.stop is None or t <= rule.stop)
        fired = np.zeros(n, bool)
        for i in range(n):
            ok = in_window
            for c in rule.when:
                val = lambda v: _value(v, i, s, t, nb, maps)  # noqa: E731
                if isinstance(c, mc.Compare):
                    ok = ok and _OPS[c.op](val(c.left), val(c.right))
                elif isinstance(c, mc.Within):
                    ok = ok and val(c.low) <= val(c.value) <= val(c.high)
                elif isinstance(c, mc.Chance):
                    raise NotImplementedError("the oracle has no random draws")
            fired[i] = ok
        a = rule.action
        if isinstance(a, mc.Change):
            row = s["species"].index(a.target.name)
            for i in np.flatnonzero(fired):
                amount = _value(a.amount, i, s, t, nb, maps)
                (dconc if a.target.kind == "conc" else drates)[row, i] += amount
        elif isinstance(a, mc.React):
            rows = [s["species"].index(x) for x in a.species]
            alpha, beta, sp = (_num(getattr(a.model, k)) for k in ("alpha", "beta", "sp"))
            for i in np.flatnonzero(fired):
                u, v = conc[rows[0], i], conc[rows[1], i]
                scale = _value(a.scale, i, s, t, nb, maps)
                dconc[rows[0], i] += dt * scale * sp * (alpha - u * v)
                dconc[rows[1], i] += dt * scale * sp * (u * v - v - beta)
        elif isinstance(a, mc.Divide):
            for i in np.flatnonzero(fired & ~divide):
                direction[i] = _num(a.direction)
            divide |= fired
        elif isinstance(a, mc.Map):
            out = maps.get(a.name, np.zeros(n)).copy()
            for i in np.flatnonzero(fired):
                x, lo, hi = (_value(v, i, s, t, nb, maps) for v in (a.source, a.low, a.high))
                y0, y1 = _value(a.out_low, i, s, t, nb, maps), _value(a.out_high, i, s, t, nb, maps)
                y = y0 + (x - lo) * (y1 - y0) / (hi - lo)
                out[i] = min(max(y, min(y0, y1)), max(y0, y1))
            maps[a.name] = out
        elif isinstance(a, mc.Polarize):
            row = s["species"].index(a.reagent)
            for i in np.flatnonzero(fired):
                p = np.zeros(2)
                for j in nb[i]:
                    d = displacement(pos, i, j, period)
                    p += (conc[row, j] - conc[row, i]) * d / np.hypot(*d)
                if p @ p > 0:
                    angle[i], polarised[i] = math.atan2(p[1], p[0]), True

    # diffusion (eqs. 4.7-4.8) and collision (eq. 4.9), on the current state
    flux = np.zeros_like(conc)
    offset = np.zeros_like(pos)
    for i in range(n):
        for j in nb[i]:
            d = displacement(pos, i, j, period)
            dist = np.hypot(*d)
            for r in range(S):
                di, dj = rates[r, i], rates[r, j]
                if s["aniso"][r]:
                    if s["polarised"][i]:
                        di *= abs(d @ [math.cos(s["angle"][i]), math.sin(s["angle"][i])]) / dist
                    if s["polarised"][j]:
                        dj *= abs(d @ [math.cos(s["angle"][j]), math.sin(s["angle"][j])]) / dist
                combined = 2 * di * dj / (di + dj) if di + dj > 0 else 0.0
                flux[r, i] += dt * combined * (conc[r, j] - conc[r, i])
            if 0 < dist < 2 and not s["fixed"][i]:
                offset[i] += (0.25 - 0.5 / dist) * d
    new = dict(s)
    new["conc"] = np.clip(conc + dconc + flux, 0.0, s["upper"][:, None])
    new["rates"] = np.maximum(rates + drates, 0.0)
    new_pos = pos + offset
    if box is not None:
        new_pos = np.clip(new_pos, -np.asarray(box) / 2, np.asarray(box) / 2)
    new["pos"], new["angle"], new["polarised"] = wrap(new_pos, period), angle, polarised

    # newborn cells, in index order: copies of the parents as the rules saw them (the
    # current state), placed and turned from the current position and polarity (4.1, 4.4)
    if division_limit is not None:
        divide &= np.array([len(x) <= division_limit for x in nb])
    for i in np.flatnonzero(divide):
        a = s["angle"][i] + direction[i]
        for key, old in (("conc", conc), ("rates", rates)):
            new[key] = np.concatenate([new[key], old[:, i:i + 1]], axis=1)
        new["pos"] = np.concatenate([new["pos"], wrap(pos[i] + np.array([[math.cos(a), math.sin(a)]]), period)])
        new["angle"] = np.append(new["angle"], a)
        new["polarised"] = np.append(new["polarised"], s["polarised"][i])
        new["birth"] = np.append(new["birth"], t + 1)
        new["fixed"] = np.append(new["fixed"], False)
    return new


def from_cells(cells) -> dict:
    live = cells.live()
    return {
        "pos": live["position"].astype(float), "angle": live["polarity"].astype(float),
        "polarised": live["polarised"].copy(), "conc": live["concentration"].astype(float),
        "rates": live["diffusion"].astype(float), "birth": live["birth"].copy(), "fixed": live["fixed"].copy(),
        "upper": np.asarray(cells.upper, float), "aniso": np.asarray(cells.anisotropic), "species": cells.species,
    }

"""An independent NumPy oracle for the cellular automata (no code shared with morphojax).

Written from the papers' definitions, as plainly as possible: explicit lists of neighbour
offsets, one periodic shift (np.roll) per offset, integer neighbour counts, and the
update decided with exact rational arithmetic (fractions.Fraction of the weights as the
user typed them, scaled to integers by their least common denominator).
"""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import numpy as np

SLACK = 1e-6  # a radius includes the shell at exactly its own distance


def offsets(radius, dim, neighbourhood):
    """All integer offsets within `radius` (excluding the origin): Euclidean (disc),
    Chebyshev (box, Moore's) or Manhattan (diamond, von Neumann's)."""
    m = int(math.floor(radius * (1 + SLACK)))
    out = []
    for o in itertools.product(range(-m, m + 1), repeat=dim):
        if not any(o):
            continue
        if neighbourhood == "disc":
            inside = sum(x * x for x in o) <= radius * radius * (1 + SLACK)
        elif neighbourhood == "diamond":
            inside = sum(abs(x) for x in o) <= radius * (1 + SLACK)
        else:
            inside = max(abs(x) for x in o) <= radius * (1 + SLACK)
        if inside:
            out.append(o)
    return out


def count(indicator, offs):
    """For every cell, how many of the cells at `cell + o` (periodic) are set, in the
    indicator's integer dtype."""
    total = np.zeros(indicator.shape, indicator.dtype)
    for o in offs:
        total += np.roll(indicator, shift=tuple(-x for x in o), axis=tuple(range(indicator.ndim)))
    return total


def young_step(cells, species, neighbourhood="disc", include_self=False, counts=np.int64):
    """One synchronous update of Young's K-species automaton (paper 002 eqs. 1-4).

    species: list of (r_act, r_inh, w_act, w_inh) as Python numbers; counts: the integer
    dtype of the neighbour counts and fields (a benchmark passes the one morphojax uses).
    """
    cells = np.asarray(cells)
    k, dim = len(species), cells.ndim
    fracs = [Fraction(str(w)) for s in species for w in s[2:]]
    den = 1
    for f in fracs:
        den = den * f.denominator // math.gcd(den, f.denominator)
    fields = []
    for j, (r_act, r_inh, w_act, w_inh) in enumerate(species):
        ind = (cells == j).astype(counts)
        act = set(offsets(r_act, dim, neighbourhood))
        ring = set(offsets(r_inh, dim, neighbourhood)) - act
        n_act = count(ind, sorted(act)) + (ind if include_self else 0)
        n_ring = count(ind, sorted(ring))
        a = Fraction(str(w_act)) * den
        b = Fraction(str(w_inh)) * den
        assert a.denominator == 1 and b.denominator == 1
        fields.append(int(a) * n_act + int(b) * n_ring)
    fields = np.stack(fields)
    best = fields.max(axis=0)
    winner = fields.argmax(axis=0)  # the first maximum: the lowest index wins a tie
    out = np.where(best > 0, winner, np.where(best < 0, k, cells))
    return out.astype(cells.dtype)


def young_run(cells, species, steps, **kwargs):
    for _ in range(steps):
        cells = young_step(cells, species, **kwargs)
    return cells


def life_step(cells, birth, survive):
    """Outer-totalistic rule on the Moore neighbourhood (3^d - 1 neighbours), periodic."""
    cells = np.asarray(cells)
    offs = [o for o in itertools.product((-1, 0, 1), repeat=cells.ndim) if any(o)]
    n = count(cells.astype(np.int64), offs)
    out = np.zeros_like(cells)
    for idx in np.ndindex(cells.shape):
        if cells[idx] == 1:
            out[idx] = 1 if n[idx] in survive else 0
        else:
            out[idx] = 1 if n[idx] in birth else 0
    return out


def order_parameter(cells, k):
    """Paper 002 eq. 5 with explicit loops over cells and their 2d direct neighbours."""
    cells = np.asarray(cells)
    dim = cells.ndim
    out = []
    for j in range(k + 1):
        total = 0
        for idx in np.ndindex(cells.shape):
            s = 1 if cells[idx] == j else -1
            for axis in range(dim):
                for step in (-1, 1):
                    nb = list(idx)
                    nb[axis] = (nb[axis] + step) % cells.shape[axis]
                    total += s * (1 if cells[tuple(nb)] == j else -1)
        out.append(abs(total) / (2 * dim * cells.size))
    return np.array(out)

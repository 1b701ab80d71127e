"""A NumPy reference for the cellular Potts model (paper 003, section III.B): the
Hamiltonian summed site by site over full neighbourhoods (each pair seen twice, halved),
and plain sequential Metropolis with random target sites and random neighbours, as
CompuCell3D runs it. Independent of morphojax.potts (no code shared)."""

from __future__ import annotations

import numpy as np

_NEAR = [(-1, 0), (1, 0), (0, -1), (0, 1)]
_DIAG = [(-1, -1), (-1, 1), (1, -1), (1, 1)]


def offsets(order):
    return _NEAR + (_DIAG if order == 2 else [])


def neighbour(i, j, di, dj, shape, boundary):
    """The neighbour site of (i, j) at (di, dj), or None beyond a fixed edge."""
    r, c = i + di, j + dj
    if boundary == "wrap":
        return r % shape[0], c % shape[1]
    if 0 <= r < shape[0] and 0 <= c < shape[1]:
        return r, c
    return None


def hamiltonian(ids, types, J, volume_weight, target_volume, order=2, boundary="fixed"):
    """H = 1/2 sum_i sum_{j in N(i)} J(t_i, t_j) [id_i != id_j] + lambda sum_{c >= 1} (v_c - V)^2."""
    ids, types, J = np.asarray(ids), np.asarray(types), np.asarray(J, float)
    contact = 0.0
    for i in range(ids.shape[0]):
        for j in range(ids.shape[1]):
            for di, dj in offsets(order):
                nb = neighbour(i, j, di, dj, ids.shape, boundary)
                if nb is not None and ids[nb] != ids[i, j]:
                    contact += J[types[ids[i, j]], types[ids[nb]]]
    volumes = np.bincount(ids.ravel(), minlength=len(types))
    return contact / 2 + volume_weight * float(((volumes[1:] - target_volume) ** 2).sum())


def local_delta(ids, types, volumes, J, volume_weight, target_volume, i, j, new, order, boundary):
    """The energy change of setting site (i, j) to cell `new`."""
    old = ids[i, j]
    d = 0.0
    for di, dj in offsets(order):
        nb = neighbour(i, j, di, dj, ids.shape, boundary)
        if nb is None:
            continue
        n = ids[nb]
        d += J[types[new], types[n]] * (new != n) - J[types[old], types[n]] * (old != n)
    if old > 0:
        d += volume_weight * ((volumes[old] - 1 - target_volume) ** 2 - (volumes[old] - target_volume) ** 2)
    if new > 0:
        d += volume_weight * ((volumes[new] + 1 - target_volume) ** 2 - (volumes[new] - target_volume) ** 2)
    return d


def metropolis(ids, types, J, temperature, target_volume, volume_weight, mcs, rng, order=2, boundary="fixed"):
    """Sequential Metropolis: `mcs` x sites copy attempts, each at a random site from a random
    neighbour, accepted with min(1, exp(-dH / T)). Returns (ids, accepted, sum of accepted dH)."""
    ids = np.array(ids)
    types, J = np.asarray(types), np.asarray(J, float)
    volumes = np.bincount(ids.ravel(), minlength=len(types))
    offs = offsets(order)
    rows, cols = ids.shape
    n = mcs * rows * cols
    sites_i, sites_j = rng.integers(0, rows, n), rng.integers(0, cols, n)
    dirs, us = rng.integers(0, len(offs), n), rng.random(n)
    accepted, total = 0, 0.0
    for k in range(n):
        i, j = sites_i[k], sites_j[k]
        nb = neighbour(i, j, *offs[dirs[k]], ids.shape, boundary)
        if nb is None:
            continue
        new, old = ids[nb], ids[i, j]
        if new == old:
            continue
        d = local_delta(ids, types, volumes, J, volume_weight, target_volume, i, j, new, order, boundary)
        if d <= 0 or (temperature > 0 and us[k] < np.exp(-d / temperature)):
            ids[i, j] = new
            volumes[old] -= 1
            volumes[new] += 1
            accepted += 1
            total += d
    return ids, accepted, total

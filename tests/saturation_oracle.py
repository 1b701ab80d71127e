"""NumPy oracles for tests/test_saturation.py: Wireworld, the thesis's iteration with its
rule-based reinforcement or eq. 7.1, written from the thesis (sections 4.3, 4.7, 6.6, 7.1,
7.2 and Listing A.12), independently of morphojax."""

from __future__ import annotations

import itertools

import numpy as np


def wireworld_step(cells: np.ndarray) -> np.ndarray:
    """One Wireworld generation on a periodic lattice of any dimension, cell by cell."""
    cells = np.asarray(cells)
    new = cells.copy()
    for idx in itertools.product(*(range(n) for n in cells.shape)):
        s = cells[idx]
        if s == 1:
            new[idx] = 2
        elif s == 2:
            new[idx] = 3
        elif s == 3:
            heads = 0
            for off in itertools.product((-1, 0, 1), repeat=cells.ndim):
                if any(off):
                    j = tuple((i + o) % n for i, o, n in zip(idx, off, cells.shape))
                    heads += cells[j] == 1
            new[idx] = 1 if heads in (1, 2) else 3
    return new


def moore_sum_noflux(u: np.ndarray) -> np.ndarray:
    """sum_j (u_j - u) over the eight neighbours, cells beyond the edge replaced by the
    nearest edge cell (the lattice's no-flux ghost cells)."""
    p = np.pad(u, 1, mode="edge")
    rows, cols = u.shape
    total = np.zeros_like(u)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr or dc:
                total += p[1 + dr:1 + dr + rows, 1 + dc:1 + dc + cols] - u
    return total


def rule_iteration(r, *, rise=(0.7, np.inf), gain=0.01, fall=(-np.inf, 0.3), loss=0.01, diffusion=0.01, limit=1.0):
    """One thesis iteration: the rules and diffusion read the current r, their changes are
    summed, and the result is clamped to [0, limit] (section 4.7)."""
    change = np.where((r > rise[0]) & (r < rise[1]), gain, 0.0) - np.where((r > fall[0]) & (r < fall[1]), loss, 0.0)
    return np.clip(r + change + diffusion * moore_sum_noflux(r), 0.0, limit)


def cubic_iteration(r, *, s=0.35, a=0.3, b=0.5, c=0.7, diffusion=0.01, dt=1.0, limit=1.0):
    """One forward-Euler step of thesis eq. 7.1 on the Moore sum, clamped to [0, limit]."""
    return np.clip(r + dt * (s * (r - a) * (r - b) * (r - c) + diffusion * moore_sum_noflux(r)), 0.0, limit)


def moore_sum_open(u: np.ndarray) -> np.ndarray:
    """sum_j (u_j - u) over the Moore neighbours that lie inside the grid, cell by cell."""
    rows, cols = u.shape
    out = np.zeros_like(u)
    for i in range(rows):
        for j in range(cols):
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    if (di or dj) and 0 <= i + di < rows and 0 <= j + dj < cols:
                        out[i, j] += u[i + di, j + dj] - u[i, j]
    return out


def laplacian_iteration(p, g, c, u, *, dp=0.01, dg=0.1, gain=0.0001, loss=0.01, window=(0.03, 0.04)):
    """One iteration of Listing A.13, its rules written out one by one (all read the
    current state; the changes and the diffusion are summed, then P in [0, 1], G >= 0)."""
    change_p, change_g, change_c = np.zeros_like(p), np.zeros_like(g), np.zeros_like(c)
    change_c[c == 0] += 1          # rule if C conc == 0 change C conc +1
    change_c[c == 1] -= 1          # rule if C conc == 1 change C conc -1
    change_p[c == 1] -= 1          # force all to zero
    grow = (c == 1) & (u < g) & (p >= window[0]) & (p <= window[1])
    change_p[grow] += 2            # some non-active neighbours are activated
    change_p[(c == 1) & (p > 0.9)] += 2  # keep the previously activated
    change_g[p == 0] += gain
    change_g[p == 1] -= loss
    p_new = np.clip(p + change_p + dp * moore_sum_open(p), 0.0, 1.0)
    g_new = np.maximum(g + change_g + dg * moore_sum_open(g), 0.0)
    return p_new, g_new, c + change_c

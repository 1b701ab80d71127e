"""Independent NumPy oracle for the hexagonal lattice and the thesis's Moore sum.

The operators are assembled as dense matrices from neighbour lists, cell by cell, sharing
no code with morphojax: the hexagonal neighbours are found two ways (the issue's odd-r
listing, and through axial coordinates: offset -> axial, add the six axial directions,
back to offset), the Moore sum as the eight surrounding cells with the square lattice's
ghost cells (no-flux: a ghost cell is the edge cell next to it). Everything is float64.
"""

from __future__ import annotations

import numpy as np

AXIAL_DIRECTIONS = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, -1), (-1, 1))


def hex_neighbours_listed(r, c):
    """The six neighbours of (r, c) as the issue lists them for the odd-r layout."""
    same = [(r, c - 1), (r, c + 1)]
    if r % 2 == 0:
        return same + [(r - 1, c - 1), (r - 1, c), (r + 1, c - 1), (r + 1, c)]
    return same + [(r - 1, c), (r - 1, c + 1), (r + 1, c), (r + 1, c + 1)]


def hex_neighbours_axial(r, c):
    """The six neighbours of (r, c) through axial coordinates (q, r) of the odd-r layout."""
    q = c - (r - (r & 1)) // 2
    out = []
    for dq, dr in AXIAL_DIRECTIONS:
        q2, r2 = q + dq, r + dr
        out.append((r2, q2 + (r2 - (r2 & 1)) // 2))
    return out


def hex_matrix(shape, boundary="wrap", operator="sum", neighbours=hex_neighbours_axial):
    """The (rows * cols)^2 matrix of the hexagonal operator: sum over the neighbours that
    exist of (u_j - u) (wrap: indices modulo the shape; no-flux: links that leave are
    dropped), times 2/3 for the Laplacian."""
    rows, cols = shape
    n = rows * cols
    m = np.zeros((n, n))
    for r in range(rows):
        for c in range(cols):
            i = r * cols + c
            for r2, c2 in neighbours(r, c):
                if boundary == "wrap":
                    r2, c2 = r2 % rows, c2 % cols
                elif not (0 <= r2 < rows and 0 <= c2 < cols):
                    continue
                j = r2 * cols + c2
                m[i, j] += 1.0
                m[i, i] -= 1.0
    return m * (2.0 / 3.0) if operator == "laplacian" else m


def moore_matrix(shape, boundary="wrap"):
    """The matrix of sum over the eight surrounding cells of (u_j - u) on a square lattice;
    no-flux reads a ghost cell outside the lattice as the nearest edge cell."""
    rows, cols = shape
    n = rows * cols
    m = np.zeros((n, n))
    for r in range(rows):
        for c in range(cols):
            i = r * cols + c
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    if dr == dc == 0:
                        continue
                    r2, c2 = r + dr, c + dc
                    if boundary == "wrap":
                        r2, c2 = r2 % rows, c2 % cols
                    else:
                        r2, c2 = min(max(r2, 0), rows - 1), min(max(c2, 0), cols - 1)
                    m[i, r2 * cols + c2] += 1.0
                    m[i, i] -= 1.0
    return m


def apply(matrix, field):
    """The operator `matrix` applied to a (rows, cols) field."""
    field = np.asarray(field, float)
    return (matrix @ field.ravel()).reshape(field.shape)


def bard_run(a, b, matrix, alpha, beta, sp, da, db, dt, steps, lower=(0.0, 0.0), upper=(np.inf, np.inf)):
    """Forward Euler of thesis eqs. 4.5-4.6 with the diffusion operator `matrix`, clamped
    to [lower, upper] after every step."""
    a, b = np.asarray(a, float).copy(), np.asarray(b, float).copy()
    for _ in range(steps):
        ra = sp * (alpha - a * b) + da * apply(matrix, a)
        rb = sp * (a * b - b - beta) + db * apply(matrix, b)
        a = np.clip(a + dt * ra, lower[0], upper[0])
        b = np.clip(b + dt * rb, lower[1], upper[1])
    return a, b


def centres(shape):
    """(x, y) of the hexagonal cell centres: odd rows shifted by 1/2, rows sqrt(3)/2 apart."""
    r, c = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    return c + 0.5 * (r % 2), r * np.sqrt(3.0) / 2.0

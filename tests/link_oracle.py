"""NumPy oracle for diffusion on the square lattice's links, written cell by cell.

For every cell i and every neighbour j of the stencil (offset (dr, dc), weight w), the term
of i gains w * D_ij * (u_j - u_i), D_ij the harmonic mean 2 a b / (a + b) (0 when a + b = 0;
thesis eq. 4.7) of the two cells' rates toward each other; an anisotropic rate is the cell's
rate times |d . p| / |d| (eq. 4.8), d = (dc, dr) in (x, y), p = (cos t, sin t) of the cell's
angle t, and 1 for an unpolarised cell (NaN angle).

Boundaries: "wrap" takes indices modulo the size; "no-flux" reflects a neighbour outside
the lattice onto the edge cell (index -1 -> 0, n -> n - 1: the lattice mirrored at its
border), with the mirrored polarity (a row reflection turns t into -t, a column reflection
into pi - t).
"""

import math

import numpy as np

OFFSETS = {
    "five-point": [((0, 1), 1.0), ((0, -1), 1.0), ((1, 0), 1.0), ((-1, 0), 1.0)],
    "nine-point": [((0, 1), 4 / 6), ((0, -1), 4 / 6), ((1, 0), 4 / 6), ((-1, 0), 4 / 6),
                   ((1, 1), 1 / 6), ((1, -1), 1 / 6), ((-1, 1), 1 / 6), ((-1, -1), 1 / 6)],
    "moore": [((dr, dc), 1.0) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if (dr, dc) != (0, 0)],
}


def _harmonic(a, b):
    return 0.0 if a + b == 0 else 2.0 * a * b / (a + b)


def _scale(angle, dr, dc):
    if angle is None or math.isnan(angle):
        return 1.0
    return abs(dc * math.cos(angle) + dr * math.sin(angle)) / math.hypot(dr, dc)


def _neighbour(r, c, rows, cols, boundary):
    """(row, col, row reflected, col reflected) of the cell at (r, c)."""
    if boundary == "wrap":
        return r % rows, c % cols, False, False
    rr, flip_r = (0, True) if r < 0 else (rows - 1, True) if r >= rows else (r, False)
    cc, flip_c = (0, True) if c < 0 else (cols - 1, True) if c >= cols else (c, False)
    return rr, cc, flip_r, flip_c


def link_term(u, rate, boundary="wrap", stencil="nine-point", angle=None):
    """sum_j w D_ij (u_j - u_i) for every cell of `u` (rows, cols); `rate` a number or a
    (rows, cols) map; `angle` None (isotropic), a number or a (rows, cols) array (NaN =
    unpolarised) of polarity angles in radians."""
    u = np.asarray(u, float)
    rows, cols = u.shape
    rate = np.broadcast_to(np.asarray(rate, float), u.shape)
    ang = None if angle is None else np.broadcast_to(np.asarray(angle, float), u.shape)
    out = np.zeros_like(u)
    for r in range(rows):
        for c in range(cols):
            for (dr, dc), w in OFFSETS[stencil]:
                rj, cj, flip_r, flip_c = _neighbour(r + dr, c + dc, rows, cols, boundary)
                a_i = None if ang is None else ang[r, c]
                a_j = None if ang is None else ang[rj, cj]
                if a_j is not None and not math.isnan(a_j):
                    if flip_r:
                        a_j = -a_j
                    if flip_c:
                        a_j = math.pi - a_j
                d_i = rate[r, c] * _scale(a_i, dr, dc)
                d_j = rate[rj, cj] * _scale(a_j, dr, dc)
                out[r, c] += w * _harmonic(d_i, d_j) * (u[rj, cj] - u[r, c])
    return out


def operator_matrix(shape, rate, boundary="wrap", stencil="nine-point", angle=None):
    """The matrix A with (A u).ravel() = link_term(u) for every u, column by column."""
    n = shape[0] * shape[1]
    cols = []
    for k in range(n):
        e = np.zeros(n)
        e[k] = 1.0
        cols.append(link_term(e.reshape(shape), rate, boundary, stencil, angle).ravel())
    return np.stack(cols, axis=1)


# ---- the hexagonal lattice (odd-r offset layout) ---------------------------------------------------
def hex_neighbours(r, c):
    """The six neighbours of (r, c) in the odd-r layout (odd rows shifted half a cell right)."""
    same = [(r, c - 1), (r, c + 1)]
    if r % 2 == 0:
        return same + [(r - 1, c - 1), (r - 1, c), (r + 1, c - 1), (r + 1, c)]
    return same + [(r - 1, c), (r - 1, c + 1), (r + 1, c), (r + 1, c + 1)]


def _centre(r, c):
    return c + 0.5 * (r % 2), r * math.sqrt(3.0) / 2.0


def hex_link_term(u, rate, boundary="wrap", operator="laplacian", angle=None):
    """sum_j w D_ij (u_j - u_i) on the hexagonal lattice (w = 2/3 for the Laplacian, 1 for
    the neighbour sum); d from the cell centres (x along a row, y down the rows); wrap takes
    indices modulo the size, no-flux drops the links that leave."""
    u = np.asarray(u, float)
    rows, cols = u.shape
    rate = np.broadcast_to(np.asarray(rate, float), u.shape)
    ang = None if angle is None else np.broadcast_to(np.asarray(angle, float), u.shape)
    w = 2.0 / 3.0 if operator == "laplacian" else 1.0
    out = np.zeros_like(u)
    for r in range(rows):
        for c in range(cols):
            x, y = _centre(r, c)
            for r2, c2 in hex_neighbours(r, c):
                if boundary != "wrap" and not (0 <= r2 < rows and 0 <= c2 < cols):
                    continue
                x2, y2 = _centre(r2, c2)
                dx, dy = x2 - x, y2 - y
                rj, cj = r2 % rows, c2 % cols
                scale_i = scale_j = 1.0
                if ang is not None:
                    for which, a in (("i", ang[r, c]), ("j", ang[rj, cj])):
                        if not math.isnan(a):
                            s = abs(dx * math.cos(a) + dy * math.sin(a)) / math.hypot(dx, dy)
                            scale_i, scale_j = (s, scale_j) if which == "i" else (scale_i, s)
                out[r, c] += w * _harmonic(rate[r, c] * scale_i, rate[rj, cj] * scale_j) * (u[rj, cj] - u[r, c])
    return out

"""Building a mesh's operator in NumPy, once, when a `Mesh` is made: the cotangent weights
and lumped masses, the weights of an anisotropic tensor, the padded slot-major neighbour
tables the step reads, and the spectral radius that bounds its time step. The operator
itself, its units and its stability limit are described in `_mesh`.
"""

from __future__ import annotations

import numpy as np

SAFETY = 1.01  # rho = SAFETY x the Lanczos estimate of the largest eigenvalue (from below)


def cotangent_operator(v: np.ndarray, f: np.ndarray, mass: str = "voronoi"):
    """(rows, cols, weights, masses): the symmetric cotangent weights w_ij as COO triplets
    (both directions, duplicates summed) and the lumped vertex areas M_i (see `_mesh`)."""
    corners = [v[f[:, k]] for k in range(3)]
    cots, sq = [], []
    for k in range(3):  # the angle at corner k is opposite the edge (k + 1, k + 2)
        a = corners[(k + 1) % 3] - corners[k]
        b = corners[(k + 2) % 3] - corners[k]
        cots.append((a * b).sum(1) / np.linalg.norm(np.cross(a, b), axis=1))
        sq.append(((corners[(k + 1) % 3] - corners[(k + 2) % 3]) ** 2).sum(1))  # edge opposite k, squared
    rows, cols, w = [], [], []
    for k in range(3):
        i, j = f[:, (k + 1) % 3], f[:, (k + 2) % 3]
        rows += [i, j]
        cols += [j, i]
        w += [0.5 * cots[k], 0.5 * cots[k]]
    rows, cols, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    area = 0.5 * np.linalg.norm(np.cross(corners[1] - corners[0], corners[2] - corners[0]), axis=1)
    m = np.zeros(len(v))
    if mass == "barycentric":
        for k in range(3):
            np.add.at(m, f[:, k], area / 3.0)
        return rows, cols, w, m
    # mixed Voronoi (Meyer et al. 2003, Fig. 4): the Voronoi region inside a non-obtuse
    # triangle; half the area at an obtuse corner and a quarter at the other two
    obtuse = np.stack([c < 0 for c in cots], 1)  # cot < 0: the angle is obtuse
    any_obtuse = obtuse.any(1)
    for k in range(3):
        # Voronoi part at corner k: (|e_k,k+1|^2 cot(angle k+2) + |e_k,k+2|^2 cot(angle k+1)) / 8
        voronoi = (sq[(k + 2) % 3] * cots[(k + 2) % 3] + sq[(k + 1) % 3] * cots[(k + 1) % 3]) / 8.0
        part = np.where(any_obtuse, np.where(obtuse[:, k], area / 2.0, area / 4.0), voronoi)
        np.add.at(m, f[:, k], part)
    return rows, cols, w, m


def neighbour_table(n: int, rows, cols, *ws):
    """Sum duplicate (i, j) weights and pack each vertex's neighbours into a padded table,
    slot-major: (neighbours (K, n) int32 padded with the vertex itself, then per weight
    array in `ws` its (K, n) table padded with 0)."""
    key = rows * n + cols
    uniq, inverse = np.unique(key, return_inverse=True)
    r, c = uniq // n, uniq % n  # sorted by row, then column
    degree = np.bincount(r, minlength=n)
    k = int(degree.max())
    start = np.concatenate([[0], np.cumsum(degree)[:-1]])
    slot = np.arange(len(r)) - start[r]
    table = np.repeat(np.arange(n)[:, None], k, axis=1)
    table[r, slot] = c
    out = [np.ascontiguousarray(table.T, np.int32)]
    for w in ws:
        weights = np.zeros((k, n))
        weights[slot, r] = np.bincount(inverse, weights=w, minlength=len(uniq))
        out.append(weights)
    return tuple(out)


def directional_weights(v: np.ndarray, f: np.ndarray, direction):
    """COO (rows, cols, weights) of the directional part of the anisotropic operator: per
    triangle T, the finite-element term -A_T (grad phi_i . t)(grad phi_j . t) of the tensor
    t t^T, t the unit direction projected into T's plane (the mean of its corners'
    directions for a per-vertex field). A triangle where the projection vanishes (the
    direction along its normal) gets half its in-plane identity instead, the isotropic mean."""
    d = np.asarray(direction, np.float64)
    if d.shape == (3,):
        d = np.broadcast_to(d, (len(v), 3))
    if d.shape != (len(v), 3) or not np.isfinite(d).all():
        raise ValueError(f"Mesh.direction must be a 3-vector or one finite 3-vector per vertex, shape ({len(v)}, 3) "
                         f"(got {np.shape(direction)})")
    p = [v[f[:, k]] for k in range(3)]
    normal = np.cross(p[1] - p[0], p[2] - p[0])
    area2 = np.linalg.norm(normal, axis=1)  # twice the area
    nhat = normal / area2[:, None]
    # grad phi_k = nhat x (edge opposite k, oriented k+1 -> k+2) / (2 A)
    grads = [np.cross(nhat, p[(k + 2) % 3] - p[(k + 1) % 3]) / area2[:, None] for k in range(3)]
    t = d[f].mean(1)
    t = t - (t * nhat).sum(1, keepdims=True) * nhat
    length = np.linalg.norm(t, axis=1)
    ok = length > 1e-6 * np.maximum(np.linalg.norm(d[f].mean(1), axis=1), 1e-300)
    t = np.where(ok[:, None], t / np.where(ok, length, 1.0)[:, None], 0.0)
    area = area2 / 2
    rows, cols, w = [], [], []
    for a in range(3):
        for b in range(3):
            if a == b:
                continue
            along = (grads[a] * t).sum(1) * (grads[b] * t).sum(1)
            iso = 0.5 * (grads[a] * grads[b]).sum(1)  # half the in-plane identity
            rows.append(f[:, a])
            cols.append(f[:, b])
            w.append(-area * np.where(ok, along, iso))
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(w)


def weight_matrix(table, weights):
    """The (V, V) sparse matrix W of the weights w_ij from slot-major tables (K, V)."""
    import scipy.sparse as sp

    n = table.shape[1]
    rows = np.tile(np.arange(n), table.shape[0])
    return sp.csr_matrix((np.ravel(weights), (rows, np.ravel(table))), shape=(n, n))


def largest_eigenvalue(table, weights, inverse_mass) -> float:
    """Largest eigenvalue of -L = M^-1 (D - W) (Lanczos on the symmetric form), in the
    mesh's length^-2, times `SAFETY`, capped by the Gershgorin bound (see `_mesh`)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import eigsh

    w = weight_matrix(table, weights)
    d = np.asarray(w.sum(1)).ravel()
    s = sp.diags(np.sqrt(inverse_mass))
    sym = s @ (sp.diags(d) - w) @ s
    gershgorin = float(np.max(inverse_mass * (np.abs(weights).sum(0) + np.abs(d))))
    try:
        lam = float(eigsh(sym, k=1, which="LA", tol=1e-6, maxiter=5000, return_eigenvectors=False)[0])
    except Exception:  # no convergence: the bound that holds for every matrix
        return gershgorin
    return min(SAFETY * lam, gershgorin)

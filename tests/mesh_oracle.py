"""An independent NumPy/SciPy oracle for reaction-diffusion on triangle meshes.

The cotangent Laplacian is assembled triangle by triangle in plain loops, its angles from
arccos of the normalised edge directions and its mixed Voronoi areas from the triangle's
circumcentre (the area of the quadrilateral vertex - edge midpoint - circumcentre - edge
midpoint), a different route from morphojax's vectorised cotangent formulas; the umbrella
Laplacian from each vertex's set of neighbours, not from a table of edges. `gray_scott_run`
is the same forward-Euler step as SciPy sparse products; benchmarks/bench_mesh.py times it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def _angle(p, a, b):
    """The angle at p of the triangle (p, a, b), in radians."""
    u, w = (a - p) / np.linalg.norm(a - p), (b - p) / np.linalg.norm(b - p)
    return float(np.arccos(np.clip(u @ w, -1.0, 1.0)))


def _polygon_area(points):
    """Area of a planar polygon in 3D (fan from its first point)."""
    total = np.zeros(3)
    for k in range(1, len(points) - 1):
        total += np.cross(points[k] - points[0], points[k + 1] - points[0])
    return 0.5 * np.linalg.norm(total)


def cotangent_matrices(vertices, faces, mass="voronoi"):
    """(K, M): the stiffness matrix K (K_ij = -w_ij off the diagonal, rows summing to 0, so
    -K is the cotangent Laplacian's numerator) and the diagonal lumped mass matrix M."""
    v = np.asarray(vertices, float)
    n = len(v)
    k = sp.lil_matrix((n, n))
    m = np.zeros(n)
    for tri in np.asarray(faces):
        pts = v[tri]
        angles = [_angle(pts[c], pts[(c + 1) % 3], pts[(c + 2) % 3]) for c in range(3)]
        area = 0.5 * np.linalg.norm(np.cross(pts[1] - pts[0], pts[2] - pts[0]))
        for c in range(3):
            i, j = tri[(c + 1) % 3], tri[(c + 2) % 3]
            w = 0.5 / np.tan(angles[c])
            k[i, j] -= w
            k[j, i] -= w
            k[i, i] += w
            k[j, j] += w
        if mass == "barycentric":
            for c in range(3):
                m[tri[c]] += area / 3.0
            continue
        obtuse = [a > np.pi / 2 for a in angles]
        if any(obtuse):
            for c in range(3):
                m[tri[c]] += area / 2.0 if obtuse[c] else area / 4.0
            continue
        # circumcentre of the triangle
        a, b, c3 = pts
        ab, ac = b - a, c3 - a
        nrm = np.cross(ab, ac)
        centre = a + (np.cross(nrm, ab) * (ac @ ac) + np.cross(ac, nrm) * (ab @ ab)) / (2.0 * (nrm @ nrm))
        for c in range(3):
            p, q, r = pts[c], pts[(c + 1) % 3], pts[(c + 2) % 3]
            m[tri[c]] += _polygon_area([p, (p + q) / 2, centre, (p + r) / 2])
    return k.tocsr(), sp.diags(m)


def laplacian(vertices, faces, mass="voronoi"):
    """The operator M^-1 (-K) as a sparse matrix (length^-2)."""
    k, m = cotangent_matrices(vertices, faces, mass)
    return sp.diags(1.0 / m.diagonal()) @ (-k)


def umbrella_laplacian(n, faces):
    """Paper 004's "equally weighted" Laplacian as a sparse matrix, from each vertex's set of
    edge neighbours gathered triangle by triangle in plain loops: (L u)_i = the mean of u
    over the neighbours of i, less u_i."""
    neighbours = [set() for _ in range(n)]
    for tri in np.asarray(faces):
        for a in tri:
            neighbours[int(a)].update(int(b) for b in tri if b != a)
    lap = sp.lil_matrix((n, n))
    for i, around in enumerate(neighbours):
        for j in around:
            lap[i, j] = 1.0 / len(around)
        lap[i, i] = -1.0
    return lap.tocsr()


def gray_scott_run(lap, u, v, feed, kill, du, dv, dt, steps, dtype=np.float64):
    """Forward Euler on Gray-Scott with the sparse operator `lap`, clamped at 0 (morphojax's
    default lower limit), computed in `dtype` throughout: the operator and both species are
    cast to it, and the parameters are Python floats, which NumPy applies in the arrays'
    dtype. A benchmark passes the dtype of the run it is compared with."""
    lap = lap.astype(dtype, copy=False)
    u, v = np.array(u, dtype), np.array(v, dtype)
    for _ in range(steps):
        uvv = u * v * v
        u, v = (np.maximum(u + dt * (-uvv + feed * (1 - u) + du * (lap @ u)), 0.0),
                np.maximum(v + dt * (uvv - (feed + kill) * v + dv * (lap @ v)), 0.0))
    return u, v


def grid_mesh(n, spacing=1.0):
    """A flat n x n grid of vertices, each square cut by the diagonal from (r, c) to
    (r + 1, c + 1): the cotangent weights are then 1 on the axis edges and 0 on the
    diagonals, and an interior vertex's area is spacing^2 (the five-point stencil)."""
    r, c = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    vertices = np.stack([c.ravel() * spacing, r.ravel() * spacing, np.zeros(n * n)], 1)
    idx = (r * n + c)[:-1, :-1].ravel()
    faces = np.concatenate([np.stack([idx, idx + 1, idx + n + 1], 1), np.stack([idx, idx + n + 1, idx + n], 1)])
    return vertices, faces

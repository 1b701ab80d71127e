"""Triangulated primitives for meshes: the geodesic sphere and surfaces of revolution (a
torus, a capsule), in NumPy, wound so that their normals point outward."""

from __future__ import annotations

import math

import numpy as np


MAX_ALONG = 10**5  # vertices along one direction of a built mesh


def count(length, spacing, least):
    if not spacing > 0:
        raise ValueError(f"spacing must be > 0 (got {spacing})")
    n = length / spacing
    if not n <= MAX_ALONG:  # a mesh of MAX_ALONG^2 vertices is already beyond what a run can hold
        raise ValueError(f"spacing {spacing:g} puts {n:.3g} vertices along a length of {length:g}; at most "
                         f"{MAX_ALONG} (use a larger spacing)")
    return max(least, int(round(n)))


def icosphere_arrays(subdivisions: int, radius: float = 1.0):
    """(vertices, faces) of a geodesic sphere (see `Mesh.icosphere`), outward winding."""
    if not isinstance(subdivisions, (int, np.integer)) or not 0 <= subdivisions <= 7:
        raise ValueError(f"icosphere subdivisions must be an integer in [0, 7] (got {subdivisions!r})")
    if not radius > 0:
        raise ValueError(f"icosphere radius must be > 0 (got {radius})")
    t = (1 + math.sqrt(5)) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                  [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                  [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(int(subdivisions)):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inverse = np.unique(edges, axis=0, return_inverse=True)
        mid = v[uniq].mean(1)
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = len(v) + inverse.reshape(3, -1).T  # midpoints of edges (0,1), (1,2), (2,0)
        a, b, c = f.T
        ab, bc, ca = m.T
        f = np.concatenate([np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1), np.stack([c, ca, bc], 1),
                            np.stack([ab, bc, ca], 1)])
        v = np.concatenate([v, mid])
    return v * radius, f


def revolve(r, z, spacing, closed: bool):
    """(vertices, faces) of the surface of revolution of the profile (r(s), z(s)) about z.

    Each profile point becomes a ring of about 2 pi r / spacing vertices (one vertex where
    r = 0: a pole), and neighbouring rings are stitched by walking both rings in angle and
    always advancing the one whose next vertex comes first, so triangles stay near
    equilateral from the poles to the widest ring. `closed`: the profile is a loop (a torus).
    """
    r, z = np.asarray(r, float), np.asarray(z, float)
    counts = [1 if ri <= 1e-12 else max(3, int(round(2 * np.pi * ri / spacing))) for ri in r]
    verts, starts = [], []
    for k, (ri, zi, n) in enumerate(zip(r, z, counts)):
        theta = (np.arange(n) + 0.5 * (k % 2)) * 2 * np.pi / n  # odd rings rotated half a step
        starts.append(sum(len(x) for x in verts))
        verts.append(np.stack([ri * np.cos(theta), ri * np.sin(theta), np.full(n, zi)], 1))
    faces = []
    pairs = [(k, k + 1) for k in range(len(r) - 1)] + ([(len(r) - 1, 0)] if closed else [])
    for a, b in pairs:
        faces += _stitch(starts[a], counts[a], (a % 2) * 0.5, starts[b], counts[b], (b % 2) * 0.5)
    return np.concatenate(verts), np.asarray(faces, np.int64)


def _stitch(sa, na, oa, sb, nb, ob):
    """Triangles between ring a (na vertices from index sa, angle offset oa steps) and ring b."""
    if na == 1 or nb == 1:  # a fan around a pole
        pole, s, n = (sa, sb, nb) if na == 1 else (sb, sa, na)
        tri = [(pole, s + i, s + (i + 1) % n) for i in range(n)]
        return [(t[0], t[2], t[1]) for t in tri] if na == 1 else tri  # outward winding
    ang_a = (np.arange(na + 1) + oa) / na
    ang_b = (np.arange(nb + 1) + ob) / nb
    # start both rings at the vertex of smallest angle; walk one full turn on each
    i = j = 0
    tri = []
    while i < na or j < nb:
        if j >= nb or (i < na and ang_a[i + 1] <= ang_b[j + 1]):
            tri.append((sa + i % na, sa + (i + 1) % na, sb + j % nb))
            i += 1
        else:
            tri.append((sa + i % na, sb + (j + 1) % nb, sb + j % nb))
            j += 1
    return tri

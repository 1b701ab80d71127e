"""A growing triangle mesh in NumPy: scaling of the vertices and division of its triangles.

The leopard paper's next step (its section 8.2): growth on a surface by "adding random new
vertices", approximating cell division. The geometry is kept here, outside compiled code,
and changes only at growth events; between events the operator is fixed and the fields
step in compiled chunks (`_mesh_run`). One event, in this order:

1. Scaling. Every vertex moves away from the initial mesh's centroid by the factor
   exp(rate * f_i * every * dt): lengths grow as exp(rate t), uniformly (f = 1) or driven
   by a per-vertex field f (a new vertex takes the mean of its parents').
2. Dilution (an option). Each vertex's concentrations are divided by the growth of its
   area, u_i <- u_i M_i / M_i', so that its mass M_i u_i is what it was.
3. Division. The triangles whose area exceeds `divide_area` are taken in a random order;
   each that is still whole in this event is split at the midpoint of one of its edges (a
   random edge, or its longest), and so is the triangle on the other side of that edge:
   two triangles become four, the winding kept. The new vertex takes the mean of its two
   parents' values. With barycentric masses (a third of each incident triangle's area) a
   midpoint split moves a sixth of each split triangle's area from each parent to the new
   vertex and keeps the third vertex's, so sum_i M_i u_i is unchanged exactly: division
   conserves mass and area (the new vertex lies on the old edge). With Voronoi masses it
   keeps the area but not the mass exactly.
4. Rebuild. The cotangent operator of the new mesh (`_mesh_build`, as `Mesh` builds it),
   padded to the vertex capacity: slots of inactive vertices point at themselves with zero
   weight, so the compiled chunks keep one shape from event to event.

Random choices come from NumPy's generator seeded with (`MeshGrowth.seed`, event number),
never from the fields, so the mesh after n steps is a function of the initial mesh, the
growth and n alone: a saved state's mesh is rebuilt by replaying the events
(`MeshGrowth.grown`), which is how a run resumes and a result is drawn.
"""

from __future__ import annotations

import numpy as np

from ._mesh import Mesh
from ._mesh_build import cotangent_operator, largest_eigenvalue, neighbour_table

SLOTS = 4  # the neighbour table's slots are padded to a multiple of this (fewer recompilations)


def triangle_areas(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """The area of each triangle `f` (F, 3) of the vertices `v` (V, 3)."""
    return 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)


class MeshGeometry:
    """The current vertices, faces and growth field of a growing mesh (NumPy, mutable)."""

    def __init__(self, mesh: Mesh, capacity: int, field=None):
        self.vertices = np.asarray(mesh.vertices, np.float64).copy()
        self.faces = np.asarray(mesh.faces, np.int64).copy()
        self.centre = self.vertices.mean(0)
        self.mass = mesh.mass
        self.capacity = int(capacity)
        n = len(self.vertices)
        self.field = np.ones(n) if field is None else np.asarray(field, np.float64).copy()
        self.events = 0
        self.overflow = False
        self.current_masses = None  # the masses of the operator the fields last stepped on

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    def masses(self) -> np.ndarray:
        return cotangent_operator(self.vertices, self.faces, self.mass)[3]

    def scale(self, log_factor: float) -> None:
        """Step 1: vertex i moves from the centroid by exp(log_factor * f_i)."""
        if log_factor:
            factor = np.exp(log_factor * self.field)[:, None]
            self.vertices = self.centre + (self.vertices - self.centre) * factor

    def divide(self, rng, divide_area: float, edge: str) -> list:
        """Step 3: split the triangles above `divide_area` (see the module docstring);
        returns the splits as (new vertex, parent a, parent b), in order. A split that would
        pass the capacity is not made: `overflow` is set instead."""
        v, f = self.vertices, self.faces
        big = np.flatnonzero(triangle_areas(v, f) > divide_area)
        if not len(big):
            return []
        # the face across each directed edge, looked up in the faces as they were when the
        # event began: a face split in this event is skipped, so every face read here is
        # one no split has changed, and so is the face across its edge (a split face is
        # marked touched with the face across its split edge)
        n = len(v)
        keys = (f * n + np.roll(f, -1, axis=1)).ravel()  # edge (a, b) of each face as a * n + b
        order = np.argsort(keys)
        sorted_keys = keys[order]

        def across(i, j):
            at = int(np.searchsorted(sorted_keys, j * n + i))
            return int(order[at] // 3) if at < len(keys) and sorted_keys[at] == j * n + i else None

        faces, field = [tuple(x) for x in f.tolist()], list(self.field)
        extra = []  # the new vertices' positions

        def at(x):
            return v[x] if x < n else extra[x - n]

        touched, splits = set(), []
        for k in rng.permutation(big):
            if k in touched:
                continue
            a, b, c = faces[k]
            corners = [(a, b, c), (b, c, a), (c, a, b)]  # (edge start, edge end, opposite)
            if edge == "random":
                i, j, o = corners[int(rng.integers(3))]
            else:  # the longest edge (the first of equal ones)
                i, j, o = max(corners, key=lambda e: float(((at(e[0]) - at(e[1])) ** 2).sum()))
            other = across(i, j)
            if other is not None and other in touched:
                continue
            if n + len(extra) >= self.capacity:
                self.overflow = True
                break
            m = n + len(extra)
            extra.append(0.5 * (at(i) + at(j)))
            field.append(0.5 * (field[i] + field[j]))
            splits.append((m, i, j))
            # (i, j, o) -> (i, m, o) + (m, j, o); the other side (j, i, d) -> (j, m, d) + (m, i, d)
            faces[k] = (i, m, o)
            faces.append((m, j, o))
            touched.update((k, len(faces) - 1))
            if other is not None:
                d = next(x for x in faces[other] if x not in (i, j))
                faces[other] = (j, m, d)
                faces.append((m, i, d))
                touched.update((other, len(faces) - 1))
        self.vertices = np.concatenate([v, np.reshape(extra, (-1, 3))])
        self.faces, self.field = np.asarray(faces, np.int64), np.asarray(field)
        return splits

    def event(self, growth, dt: float, fields=None):
        """One growth event; `fields` (species, capacity) NumPy values are transformed with
        it (diluted, new vertices filled) and returned, or None when not given."""
        self.events += 1
        rng = np.random.default_rng((int(growth.seed), self.events))
        fields = None if fields is None else np.array(fields, np.float64)  # a copy this event writes
        before = None
        if fields is not None and growth.dilute:
            before = self.masses() if self.current_masses is None else self.current_masses
        self.scale(float(growth.rate) * int(growth.every) * float(dt))
        n = self.n_vertices
        if before is not None:
            fields[:, :n] *= before / self.masses()
        splits = self.divide(rng, growth.divide_area, growth.edge) if growth.divide_area is not None else []
        if fields is not None:
            for m, a, b in splits:  # in order: a parent may be a vertex of this event
                fields[:, m] = 0.5 * (fields[:, a] + fields[:, b])
        return fields

    # ---- operators -------------------------------------------------------------------------
    def mesh(self) -> Mesh:
        """The current geometry as a `Mesh` (its operator built and checked as any mesh's)."""
        return Mesh(self.vertices, self.faces, mass=self.mass)

    def stepping_domain(self, slots: int = 0, rho: float | None = None, measure: bool = True):
        """(Mesh padded to the capacity for the compiled chunks, spectral radius of the real
        operator, NaN unless `measure`). Inactive vertices: no neighbours, zero weights, unit
        inverse mass. The padded mesh states `rho` (default: the real radius) as its radius,
        a static field: the run gives one fixed value, so that its chunks are not recompiled
        at every event."""
        v, f, cap = self.vertices, self.faces, self.capacity
        rows, cols, w, m = cotangent_operator(v, f, self.mass)
        if not (m > 0).all():
            raise ValueError(f"MeshGrowth: {int((m <= 0).sum())} vertices of the grown mesh have no positive area")
        table, weights = neighbour_table(len(v), rows, cols, w)
        real_rho = largest_eigenvalue(table, weights, 1.0 / m) if measure or rho is None else float("nan")
        k = max(slots, -(-table.shape[0] // SLOTS) * SLOTS)
        full = np.repeat(np.arange(cap, dtype=np.int32)[None], k, axis=0)
        full[: table.shape[0], : len(v)] = table
        wfull = np.zeros((k, cap))
        wfull[: table.shape[0], : len(v)] = weights
        inv = np.ones(cap)
        inv[: len(v)] = 1.0 / m
        self.current_masses = m
        padded = np.zeros((cap, 3))
        padded[: len(v)] = v
        domain = Mesh(padded, f[:1], mass=self.mass, neighbours=full, weights=wfull, inverse_mass=inv,
                      rho=real_rho if rho is None else rho)
        return domain, real_rho

"""A triangle mesh: the cotangent Laplace-Beltrami operator with a lumped mass matrix, or
the uniform "umbrella" Laplacian.

Fields have shape (species, vertices): one value per vertex, in the mesh's vertex order
(`State.from_arrays([u, v])` with 1D arrays). The operator is the standard linear-finite-
element Laplace-Beltrami operator of a triangulated surface (Pinkall & Polthier 1993;
Meyer, Desbrun, Schroeder & Barr 2003):

    (L u)_i = (1 / M_i) sum_j w_ij (u_j - u_i),   w_ij = (cot alpha_ij + cot beta_ij) / 2,

alpha_ij and beta_ij the angles opposite the edge (i, j) in its one or two triangles, and
M_i the vertex's area: the mixed Voronoi area of Meyer et al. (default) or a third of the
areas of its triangles ("barycentric"). Units: lengths in the mesh's own units, so L is in
length^-2 and diffusion rates in length^2 per unit time. A boundary edge has one triangle,
which makes the operator no-flux there; w is symmetric, so pure diffusion conserves the
mass-weighted total sum_i M_i u_i.

The operator is built once in NumPy (`_mesh_build`) and stored as array leaves: each
vertex's neighbours as a padded table (max degree, vertices) of indices with their weights
(zero on padding) and the inverse masses. The tables are slot-major, slot k of every vertex
in one row, so that the step reads a slot's weights contiguously. Applying it in JAX
(`_mesh_operator`) is a gather of the neighbours' values and a weighted sum, no scatter.

Stability: forward Euler on pure diffusion is stable while dt * D * rho <= 2, rho the
largest eigenvalue of -L (L is negative semi-definite for any mesh: -u^T M L u is the
Dirichlet energy of the linear interpolant); rho is computed at construction by Lanczos
iterations (scipy's eigsh) on the symmetric form M^-1/2 (D - W) M^-1/2, times 1.01 (the
iterations approach it from below), and never above the Gershgorin bound
max_i 2 sum_j |w_ij| / M_i, which holds for every matrix.

The umbrella operator (`operator="umbrella"`, Lundelius's "equally weighted" Laplacian):

    (L u)_i = (1 / deg_i) sum_j (u_j - u_i)   over the vertices j joined to i by an edge,

the same table form with w_ij = 1 and M_i = deg_i (`_mesh_operator.umbrella_operator`). It
ignores the geometry, so it has no length unit: L is per edge, rates are per unit time, and
on a regular triangulation of edge h it approximates (h^2 / 4) times Laplace-Beltrami. It is
symmetric in the degree-weighted inner product (the weights `masses()` returns and the
conjugate-gradient IMEX solve uses), pure diffusion conserves sum_i deg_i u_i, and rho <= 2.
It takes no `mass=` and no anisotropy.

Anisotropic diffusion (`direction=`, `along=`, `across=`): the finite-element operator of
the tangent tensor along t t^T + across (I - t t^T) on each triangle, t the direction field
projected into the triangle's plane. Its weights are linear in the tensor, so the domain
keeps the cotangent weights and those of t t^T and combines them in the step: `along` and
`across` stay differentiable leaves. It is symmetric with rows summing to zero (mass is
conserved) and reduces to the cotangent operator when along = across. Why this
construction: it is the Galerkin discretisation of div(D grad u), consistent on any
triangulation, where a per-edge reweighting (scaling w_ij by the edge's alignment with t)
is not; a scalar field's gradient or a coordinate axis gives t directly.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._checks import check_choice
from ._base import AbstractDomain
from ._mesh_build import cotangent_operator, directional_weights, largest_eigenvalue, neighbour_table
from ._mesh_files import read_mesh_file
from ._mesh_operator import PAIRABLE, apply_operator, gathered_packed, pack_pairs, umbrella_operator, unpack_pairs
from ._mesh_shapes import count, icosphere_arrays, revolve

MASSES = ("voronoi", "barycentric")
OPERATORS = ("cotangent", "umbrella")


# ---- checking a mesh in NumPy -----------------------------------------------------------------
def check_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """(vertices float64 (V, 3), faces int64 (F, 3)) after checking a triangle mesh.

    Raises a ValueError for: wrong shapes or non-finite coordinates; indices outside
    [0, V); degenerate faces (a repeated vertex, or an area below 1e-12 x the squared mean
    edge length); non-manifold edges (an edge shared by more than two faces, which also
    catches duplicated faces); vertices that no face uses (they would have no area).
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3:
        raise ValueError(f"Mesh.vertices must have shape (V, 3) with V >= 3 (got {v.shape})")
    if not np.isfinite(v).all():
        raise ValueError("Mesh.vertices contains NaN or infinite coordinates")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) < 1:
        raise ValueError(f"Mesh.faces must have shape (F, 3) with F >= 1: triangles only (got {f.shape})")
    if not np.issubdtype(f.dtype, np.integer):
        if not np.all(np.equal(np.mod(f, 1), 0)):
            raise ValueError("Mesh.faces must hold integer vertex indices")
    f = f.astype(np.int64)
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"Mesh.faces indices must lie in [0, {len(v) - 1}] (got {f.min()} to {f.max()})")
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    if repeated.any():
        raise ValueError(f"Mesh.faces: {int(repeated.sum())} degenerate faces repeat a vertex (first: face "
                         f"{int(np.argmax(repeated))})")
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    lengths2 = ((v[e[:, 0]] - v[e[:, 1]]) ** 2).sum(1)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    tiny = area <= 1e-12 * lengths2.mean()
    if tiny.any():
        raise ValueError(f"Mesh.faces: {int(tiny.sum())} degenerate faces have (almost) zero area (first: face "
                         f"{int(np.argmax(tiny))}); remove them (e.g. trimesh's process=True) first")
    undirected = np.sort(e, axis=1)
    _, counts = np.unique(undirected, axis=0, return_counts=True)
    if (counts > 2).any():
        raise ValueError(f"Mesh is not manifold: {int((counts > 2).sum())} edges are shared by more than two faces "
                         "(or faces are duplicated); the Laplace-Beltrami operator needs a manifold surface")
    used = np.zeros(len(v), bool)
    used[f.ravel()] = True
    if not used.all():
        raise ValueError(f"Mesh has {int((~used).sum())} vertices that no face uses (first: {int(np.argmin(used))}); "
                         "remove them, they would have no area")
    return v, f


def check_uv_layout(uv, uv_faces, faces):
    """(uv, uv_faces, faces) as float64/int64 arrays, checked: (T, 2) texture vertices and
    one texture vertex per face corner."""
    uv = np.asarray(uv, np.float64)
    uv_faces = np.asarray(uv_faces, np.int64)
    faces = np.asarray(faces, np.int64)
    if uv.ndim != 2 or uv.shape[1] != 2:
        raise ValueError(f"uv must have shape (texture vertices, 2) (got {uv.shape})")
    if uv_faces.shape != faces.shape:
        raise ValueError(f"uv_faces must have the faces' shape {faces.shape} (got {uv_faces.shape})")
    if uv_faces.size and (uv_faces.min() < 0 or uv_faces.max() >= len(uv)):
        raise ValueError(f"uv_faces must index the {len(uv)} texture vertices (got {uv_faces.min()}..{uv_faces.max()})")
    return uv, uv_faces, faces


# ---- the domain -------------------------------------------------------------------------------
class Mesh(AbstractDomain):
    """A triangle mesh: species live on its vertices and diffuse by the cotangent
    Laplace-Beltrami operator with a lumped mass matrix, or by the umbrella Laplacian (see
    the module docstring).

    Args:
        vertices: (V, 3) coordinates; lengths in the mesh's units (diffusion rates are then
            length^2 per unit time).
        faces: (F, 3) vertex indices of the triangles (a manifold surface, closed or with
            boundary; a boundary is no-flux).
        mass: "voronoi" (mixed Voronoi areas, Meyer et al. 2003; default) or "barycentric"
            (a third of each incident triangle's area); the cotangent operator's only.
        operator: "cotangent" (default) or "umbrella": (L u)_i = (1 / deg_i) sum_j
            (u_j - u_i) over the vertex's edges, without lengths (rates per unit time; its
            weights M_i are the degrees; no `mass=` other than the default, no `direction=`).

        direction: None (isotropic), or a tangent direction field for anisotropic
            diffusion: one 3-vector (e.g. an axis, projected onto each triangle) or one
            per vertex (e.g. the gradient of a scalar field). The diffusion tensor on a
            triangle is then along t t^T + across (I - t t^T) in its plane, t the unit
            projected direction: the finite-element operator of that tensor, which is the
            cotangent operator when along = across (see `directional_weights`).
        along, across: the factors of the diffusion rates along and across the direction
            (dimensionless, default 1). Array leaves: they can be swept and differentiated
            (the spectral radius is the one of the values given here).

        uv, uv_faces: texture coordinates as an OBJ file holds them, for textures
            (`mj.texture_image`, `write_obj(..., texture=)`): (T, 2) texture vertices and
            (F, 3) texture-vertex indices of each face's corners (a seam's vertex has one
            position and one texture vertex per side). Not used by the simulation.

    The remaining keyword arguments (`neighbours`, `weights`, `directional`,
    `inverse_mass`, `rho`) are the built operator, passed back by a saved file; leave them
    out to build it.

    Matrix expansion (`Growth`) is for lattices; a mesh grows with `MeshGrowth` (scaling
    and division, its operator rebuilt between compiled chunks). `Mesh.from_file`,
    `Mesh.icosphere`, `Mesh.torus` and `Mesh.capsule` make meshes (their keyword `options`
    are those above); `mj.mesh_image` draws values on one.
    """

    vertices: np.ndarray
    faces: np.ndarray
    neighbours: jnp.ndarray  # (K, V) int32: each vertex's neighbours, slot by slot, padded with itself
    weights: jnp.ndarray  # (K, V): cotangent weights w_ij, 0 on padding
    inverse_mass: jnp.ndarray  # (V,): 1 / M_i, length^-2
    direction: np.ndarray | None  # None, (3,) or (V, 3): the anisotropy's direction field
    directional: jnp.ndarray | None  # (K, V): weights of t t^T minus the isotropic ones, None if isotropic
    along: jnp.ndarray  # factor of the rates along the direction
    across: jnp.ndarray  # factor of the rates across it
    uv: np.ndarray | None  # (T, 2) texture vertices, or None
    uv_faces: np.ndarray | None  # (F, 3) texture vertices of each face's corners, or None
    mass: str = eqx.field(static=True)
    operator: str = eqx.field(static=True)  # "cotangent" or "umbrella"
    rho: float = eqx.field(static=True)

    def __init__(self, vertices, faces, mass: str = "voronoi", direction=None, along=1.0, across=1.0, *,
                 operator: str = "cotangent", uv=None, uv_faces=None, neighbours=None, weights=None,
                 directional=None, inverse_mass=None, rho=None):
        check_choice(mass, "Mesh.mass", MASSES)
        check_choice(operator, "Mesh.operator", OPERATORS)
        if operator == "umbrella" and mass != "voronoi":
            raise ValueError(f"Mesh: the umbrella operator weighs each vertex by its degree; mass={mass!r} is for "
                             "the cotangent operator (leave mass out)")
        if operator == "umbrella" and direction is not None:
            raise ValueError("Mesh: anisotropic diffusion (direction=) is built on the cotangent operator's "
                             "triangles; the umbrella operator has none: use operator='cotangent'")
        for name, value in (("along", along), ("across", across)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"Mesh.{name} must be a finite number > 0 (got {value})")
        built = (neighbours, weights, inverse_mass, rho)
        if all(x is not None for x in built):  # a saved operator: shapes checked, numbers as saved
            v = np.asarray(vertices, np.float64)
            f = np.asarray(faces, np.int64)
            table, w, inv, rho = (np.asarray(neighbours, np.int32), np.asarray(weights), np.asarray(inverse_mass),
                                  float(rho))
            wd = None if directional is None else np.asarray(directional)
            # saved before the tables became slot-major: (V, K), told apart by its first axis,
            # since K (the largest degree) is below V and a table is never square
            if table.ndim == 2 and table.shape[0] == len(v) != table.shape[1]:
                table, w, wd = table.T, w.T, None if wd is None else wd.T
            if (table.shape != w.shape or table.shape[1] != len(v) or inv.shape != (len(v),)
                    or (wd is not None and wd.shape != w.shape)):
                raise ValueError("Mesh: the saved operator does not match the vertices")
        else:
            v, f = check_mesh(vertices, faces)
            if operator == "umbrella":
                rows, cols, wc, m = umbrella_operator(len(v), f)
            else:
                rows, cols, wc, m = cotangent_operator(v, f, mass)
            if not (m > 0).all():
                raise ValueError(f"Mesh: {int((m <= 0).sum())} vertices have no positive area")
            inv = 1.0 / m
            if direction is None:
                table, w = neighbour_table(len(v), rows, cols, wc)
                wd = None
            else:
                # the weights are linear in the tensor: w = across w_cot + (along - across) w_tt,
                # w_tt on the same (i, j) pairs as the cotangent weights
                dr, dc, dw = directional_weights(v, f, direction)
                table, w, wd = neighbour_table(len(v), np.concatenate([rows, dr]), np.concatenate([cols, dc]),
                                                np.concatenate([wc, 0.0 * dw]), np.concatenate([0.0 * wc, dw]))
            combined = w if wd is None else float(across) * w + (float(along) - float(across)) * wd
            rho = largest_eigenvalue(table, combined, inv)
        self.vertices = v.astype(np.float32)
        self.faces = f.astype(np.int32)
        self.neighbours = jnp.asarray(table, jnp.int32)
        self.weights = jnp.asarray(w)
        self.inverse_mass = jnp.asarray(inv)
        self.direction = None if direction is None else np.asarray(direction, np.float32)
        self.directional = None if wd is None else jnp.asarray(wd)
        self.along = jnp.asarray(along, jnp.asarray(w).dtype)
        self.across = jnp.asarray(across, jnp.asarray(w).dtype)
        self.mass = mass
        self.operator = operator
        self.rho = float(rho)
        if (uv is None) != (uv_faces is None):
            raise ValueError("Mesh: give both uv and uv_faces (texture coordinates), or neither")
        if uv is not None:
            uv, uv_faces, _ = check_uv_layout(uv, uv_faces, self.faces)
            uv, uv_faces = uv.astype(np.float32), uv_faces.astype(np.int32)
        self.uv, self.uv_faces = uv, uv_faces

    # ---- the domain's interface ---------------------------------------------------------
    @property
    def spectral_radius(self) -> float:
        return self.rho

    @property
    def supports_growth(self) -> bool:
        return False  # matrix expansion is for lattices; a mesh grows with MeshGrowth

    @property
    def ndim(self) -> int:
        return 1

    @property
    def description(self) -> str:
        kind = "anisotropic" if self.directional is not None else (
            "umbrella" if self.operator == "umbrella" else "Laplace-Beltrami")
        return f"mesh {kind} operator ({self.n_vertices} vertices, spectral radius {self.rho:.4g})"

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    def _arrays(self, dtype):
        """(weights, neighbours, inverse masses) of the operator, the weights and masses in
        `dtype` and the anisotropy's parts combined."""
        w = self.weights
        if self.directional is not None:  # the tensor along t t^T + across (I - t t^T)
            w = self.across * w + (self.along - self.across) * self.directional
        w = w.astype(dtype)
        # the indices were checked at construction, so the gathers may promise to be in bounds
        return w, self.neighbours, self.inverse_mass.astype(dtype)

    def _operator(self, x):
        x = jnp.asarray(x)
        dtype = x.dtype if jnp.issubdtype(x.dtype, jnp.floating) else self.weights.dtype
        return apply_operator(x, *self._arrays(dtype))

    # The loop's layout: on the CPU, species that pair up (an even number, of a real dtype
    # with a complex counterpart) are carried packed as complex pairs, which makes the step
    # one gather and one loop (see _mesh_operator); `carry` packs, `interior` unpacks,
    # `write` packs the new values. Anything else is carried as it is: a complex carry
    # always means packed pairs.
    def carry(self, fields, size, dynamic):
        # dynamic: a growing mesh's chunk (`MeshGrowth`), its active vertices first
        self._check_fields(fields)
        pairs_up = fields.ndim == 2 and fields.shape[0] % 2 == 0 and fields.dtype in PAIRABLE
        return pack_pairs(fields) if pairs_up and jax.default_backend() == "cpu" else fields

    def interior(self, carried):
        return unpack_pairs(carried) if jnp.iscomplexobj(carried) else carried

    def diffusion(self, carried, rates):
        if jnp.iscomplexobj(carried):
            op = gathered_packed(carried, *self._arrays(jnp.real(carried).dtype))
        else:
            op = self._operator(carried)
        # the step shapes each species' rate for one spatial axis: (1,) or (vertices,)
        return [rates[i] * op[i] for i in range(len(op))]

    def write(self, carried, new, size, dynamic):
        return pack_pairs(new) if jnp.iscomplexobj(carried) else new

    def active_mask(self, shape, size):
        return jnp.arange(shape[-1]) < size[0]  # the active vertices come first

    def apply(self, fields):
        """The mesh's operator on per-vertex values (..., V): Laplace-Beltrami in length^-2, or
        the umbrella Laplacian (per edge)."""
        self._check_fields(fields)
        return self._operator(fields)

    def _check_fields(self, fields):
        if fields.shape[-1] != self.n_vertices:
            raise ValueError(f"fields on this Mesh need one value per vertex: last axis {self.n_vertices} "
                             f"(got shape {tuple(fields.shape)})")

    # ---- geometry ---------------------------------------------------------------------------
    def masses(self) -> np.ndarray:
        """The lumped vertex areas M_i (length^2) as NumPy; the vertex degrees for the umbrella
        operator (the weights it is symmetric in)."""
        return 1.0 / np.asarray(self.inverse_mass, np.float64)

    def total(self, values) -> np.ndarray:
        """The mass-weighted total sum_i M_i u_i over the last axis (conserved by pure diffusion)."""
        return np.asarray(values, np.float64) @ self.masses()

    # ---- construction --------------------------------------------------------------------
    @classmethod
    def from_file(cls, path, **options) -> "Mesh":
        """Read an OBJ, PLY, STL or OFF triangle mesh (`_mesh_files`: quads are split; the file's
        vertex numbering is kept, except STL's corners, which are welded by position; NaN
        coordinates, unused vertices and degenerate faces are refused by the checks of `Mesh`;
        an OBJ's texture coordinates are kept, welded across their seams)."""
        data = read_mesh_file(path)
        try:
            if "uv" in data:
                return cls(data["vertices"], data["faces"], uv=data["uv"], uv_faces=data["uv_faces"], **options)
            return cls(data["vertices"], data["faces"], **options)
        except ValueError as err:
            raise ValueError(f"Mesh.from_file: {path}: {err}") from None

    @classmethod
    def icosphere(cls, subdivisions: int = 3, radius: float = 1.0, **options) -> "Mesh":
        """A geodesic sphere: the icosahedron with each triangle split in four `subdivisions`
        times, projected to the sphere (10 4^n + 2 vertices: 642 for n = 3, 2562 for 4)."""
        return cls(*icosphere_arrays(subdivisions, radius), **options)

    @classmethod
    def torus(cls, major: float = 2.0, minor: float = 0.75, spacing: float = 0.1, **options) -> "Mesh":
        """A torus around z with radii `major` > `minor`, triangles about `spacing` wide."""
        if not (major > minor > 0):
            raise ValueError(f"Mesh.torus needs major > minor > 0 (got {major}, {minor})")
        phi = np.linspace(0.0, 2 * np.pi, count(2 * np.pi * minor, spacing, 6), endpoint=False)
        return cls(*revolve(major + minor * np.cos(phi), minor * np.sin(phi), spacing, closed=True), **options)

    @classmethod
    def capsule(cls, radius: float = 1.0, length: float = 3.0, spacing: float = 0.1, **options) -> "Mesh":
        """A capsule along x (a body-like shape): a cylinder of `radius` and `length` with
        hemispherical ends, triangles about `spacing` wide."""
        if not (radius > 0 and length >= 0 and spacing > 0):
            raise ValueError(f"Mesh.capsule needs radius > 0, length >= 0, spacing > 0 (got {radius}, {length}, "
                             f"{spacing})")
        arc = np.pi * radius / 2  # profile: cap (a quarter circle), side, cap, by arc length
        total = 2 * arc + length
        s = np.linspace(0.0, total, count(total, spacing, 4) + 1)
        r = np.where(s < arc, radius * np.sin(s / radius),
                     np.where(s > arc + length, radius * np.sin((total - s) / radius), radius))
        z = np.where(s < arc, -length / 2 - radius * np.cos(s / radius),
                     np.where(s > arc + length, length / 2 + radius * np.cos((total - s) / radius),
                              s - arc - length / 2))
        r[0] = r[-1] = 0.0
        v, f = revolve(r, z, spacing, closed=False)
        return cls(v[:, [2, 0, 1]], f, **options)  # the axis along x (a cyclic swap keeps the winding)


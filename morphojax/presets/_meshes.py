"""Presets on triangle meshes: Gray-Scott spots and stripes on a sphere and a torus, the
leopard paper's Turing spots on a body-like capsule (Lundelius's experiment, made stable),
and Gray-Scott stripes that ring a capsule under anisotropic diffusion.

Lengths are in the mesh's units, chosen so that an edge is about one lattice cell long:
the lattice presets' rates (Pearson's scaled Gray-Scott, Du = 0.2097, Dv = 0.105 cells^2
per unit time; the leopard paper's Fig. 4 Turing parameters) then give patterns of the same
size in edges as in cells. Every time step is 80% of the mesh's explicit-Euler limit
(`Mesh.max_stable_dt`) or the lattice preset's own dt, whichever is smaller.

Initial states are one value per vertex (`Initial` with shape (vertices,)): each species
uniform in a range ("uniform"), or Pearson's start on a mesh ("gray-scott": u = 1, v = 0
except on seeded patches, where (u, v) = (0.5, 0.25), plus noise of the run's seed). The patches
are part of the preset (discs of radius 4 around 12 vertices drawn once with NumPy seed 0),
as Pearson's central square is part of the lattice preset.
"""

from __future__ import annotations

import numpy as np

from .._experiment import Experiment, Initial, Phase
from ..domains import Mesh
from ..models import GrayScott, Turing
from ._registry import ExperimentPreset, register


def seed_patches(mesh: Mesh, count: int = 12, radius: float = 4.0, seed: int = 0) -> tuple:
    """Indices of the vertices within `radius` (straight-line distance, mesh units) of
    `count` vertices (every vertex of a smaller mesh) drawn with NumPy's generator `seed`."""
    v = np.asarray(mesh.vertices, np.float64)
    centres = v[np.random.default_rng(seed).choice(len(v), min(count, len(v)), replace=False)]
    near = ((v[:, None, :] - centres[None]) ** 2).sum(-1).min(1) <= radius ** 2
    return tuple(int(i) for i in np.flatnonzero(near))


def _dt(mesh: Mesh, model, ceiling: float) -> float:
    return min(ceiling, round(0.8 * mesh.max_stable_dt(float(model.max_diffusion())), 6))


# ---- Gray-Scott on a sphere and a torus ------------------------------------------------------
GS_PATTERNS = {"spots": (0.0367, 0.0649, "spots (Pearson's mitosis)"),
               "stripes": (0.0545, 0.062, "stripes (Pearson's coral)")}


def _surface(kind: str, quick: bool) -> Mesh:
    if kind == "sphere":  # edge about 1: radius 26 at 5 subdivisions, 13 at 4
        return Mesh.icosphere(4, 13.0) if quick else Mesh.icosphere(5, 26.0)
    return Mesh.torus(20.0, 8.0, 1.0) if not quick else Mesh.torus(10.0, 4.0, 1.0)


def _gray_scott_mesh(name, surface, pattern):
    feed, kill, what = GS_PATTERNS[pattern]

    def build(quick):
        mesh = _surface(surface, quick)
        model = GrayScott(feed=feed, kill=kill, du=0.2097, dv=0.105)
        steps = 3000 if quick else 15000
        return Experiment(
            name=name, initial=Initial("gray-scott", (mesh.n_vertices,), params=(0.02, seed_patches(mesh)),
                                 names=("u", "v")),
            phases=(Phase(model, steps=steps, dt=_dt(mesh, model, 1.0), frames=4, name="static", domain=mesh),),
            description=f"Gray-Scott F={feed}, k={kill}, Du=0.2097, Dv=0.105 on a {surface} of {mesh.n_vertices} "
                        f"vertices (edge about 1): {what}",
            figure="Lundelius, made stable", show="v", cmap="inferno")

    return build


for _surf in ("sphere", "torus"):
    for _pat in GS_PATTERNS:
        _name = f"mesh-gray-scott-{_pat}-{_surf}"
        register(ExperimentPreset(_name, f"Gray-Scott {GS_PATTERNS[_pat][2]} on a {_surf} mesh",
                                  "Lundelius Fig. 4 (stable)", _gray_scott_mesh(_name, _surf, _pat)))


# ---- the leopard paper's Turing spots on a body-like capsule -------------------------------
def _turing_capsule(quick):
    mesh = Mesh.capsule(8.0, 20.0, 1.0) if quick else Mesh.capsule(14.0, 40.0, 1.0)
    model = Turing(ratio=12.0, scale=3.0, lower=(0.0, 3.0))  # Fig. 4, bottom row (Lb)
    dt = _dt(mesh, model, 0.008)
    steps = int(round((30.0 if quick else 100.0) / dt))  # t = 100 as Fig. 4 (quick: 30)
    return Experiment(
        name="mesh-turing-capsule", initial=Initial("uniform", (mesh.n_vertices,), params=(4.0, (4.0, 5.0)),
                                                        names=("a", "b")),
        phases=(Phase(model, steps=steps, dt=dt, frames=4, name="static", domain=mesh),),
        description=f"leopard paper Fig. 4 (r = 12, s = 3, lower B = 3) on a capsule of {mesh.n_vertices} vertices: "
                    "A = 4, B ~ U[4, 5)",
        figure="leopard paper Fig. 4 on a body (section 8.2)", show="b", cmap="inferno")


register(ExperimentPreset("mesh-turing-capsule",
                          "the leopard paper's Turing spots (r = 12) on a body-like capsule mesh",
                          "leopard paper Fig. 4, section 8.2", _turing_capsule))


# ---- anisotropic diffusion: stripes that ring a body ---------------------------------------
def _rings_capsule(quick):
    # diffusion 4x slower along the body's axis than around it (the axis projected onto the
    # surface): the coral labyrinth, stretched around the body, closes into rings
    mesh = (Mesh.capsule(8.0, 24.0, 1.0, direction=(1.0, 0.0, 0.0), along=0.25) if quick
            else Mesh.capsule(14.0, 40.0, 1.0, direction=(1.0, 0.0, 0.0), along=0.25))
    feed, kill, _ = GS_PATTERNS["stripes"]
    model = GrayScott(feed=feed, kill=kill, du=0.2097, dv=0.105)
    return Experiment(
        name="mesh-gray-scott-rings-capsule",
        initial=Initial("gray-scott", (mesh.n_vertices,), params=(0.02, seed_patches(mesh)), names=("u", "v")),
        phases=(Phase(model, steps=6000 if quick else 15000, dt=_dt(mesh, model, 1.0), frames=4, name="static",
                      domain=mesh),),
        description=f"Gray-Scott F={feed}, k={kill} on a capsule of {mesh.n_vertices} vertices with anisotropic "
                    "diffusion (along the axis x 0.25, around it x 1): stripes ring the body",
        figure="issue 21: anisotropic diffusion on a mesh", show="v", cmap="inferno")


register(ExperimentPreset("mesh-gray-scott-rings-capsule", "Gray-Scott stripes ringing a capsule (anisotropic "
                          "diffusion along a direction field)", "anisotropic mesh diffusion", _rings_capsule))

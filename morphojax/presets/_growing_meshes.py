"""A leopard-style pattern grown on a surface: the leopard paper's next step (its section
8.2), growth on a 3D surface by adding random new vertices, on a limb-like tube.

The leopard's own phases (`_experiments._leopard`) on a capsule: spots form on the still
surface (definition: r = 40, s = 5, lower B = 2, from A = 4, B ~ U[4, 5)); then C starts as
a copy of B under reinforcement (t = 5, w = 5, Dc = 1) while the surface grows
(development: `MeshGrowth`, lengths x 2.5, the triangles dividing in a random order once
their area passes twice the starting mean, at their longest edge, which keeps the
triangles' shapes and so the time step's limit; without dilution, as matrix expansion
copies a cell's values): the spots open into rims, as the lattice leopard's into rosettes.
Lengths are in the mesh's units, an edge about one lattice cell; the time step is the
lattice leopard's or 40% of the mesh's explicit-Euler limit, whichever is smaller
(divisions make smaller triangles, and the run checks every rebuilt operator's limit).
"""

from __future__ import annotations

import math

import numpy as np

from .._experiment import Experiment, Initial, Phase
from .._growing_mesh import MeshGrowth
from ..domains import Mesh
from ..domains._mesh_growth import triangle_areas
from ..models import Composite, Reinforcement, Turing
from ._registry import ExperimentPreset, register

GROWTH = 2.5  # the limb's lengths grow by this factor over the development phase


def _leopard_limb(quick):
    # a tube a few of the leopard's spot spacings (about 20 edges) around
    mesh = Mesh.capsule(8.0, 24.0, 1.0) if quick else Mesh.capsule(12.0, 36.0, 1.0)
    turing = Turing(40.0, 5.0, lower=(0.0, 2.0))
    reinf = Reinforcement(threshold=5.0, width=5.0, diffusion=1.0)
    dt = min(0.0015, round(0.4 * mesh.max_stable_dt(float(turing.max_diffusion())), 6))
    # simulated times: the spots settle by t = 40 (the quick lattice leopard's random start
    # takes 18 on a 48 x 48 lattice), then the development phase
    t_def, t_dev = (40.0, 12.0) if quick else (60.0, 20.0)
    n_def, n_dev = int(round(t_def / dt)), int(round(t_dev / dt))
    every = 200  # steps between growth events
    rate = math.log(GROWTH) / (n_dev * dt)
    area = float(2.0 * triangle_areas(np.asarray(mesh.vertices, float), np.asarray(mesh.faces)).mean())
    capacity = int(mesh.n_vertices * GROWTH ** 2 * 1.4)
    growth = MeshGrowth(rate, divide_area=area, every=every, edge="longest", seed=0)
    return Experiment(
        name="mesh-leopard-limb", initial=Initial("uniform", (mesh.n_vertices,), params=(4.0, (4.0, 5.0)),
                                                    names=("a", "b")),
        phases=(
            Phase(turing, steps=n_def, dt=dt, domain=mesh, frames=2, name="definition"),
            Phase(Composite((turing, reinf)), steps=n_dev, dt=dt, domain=mesh, growth=growth,
                  add_species=(("c", "b"),), frames=4, name="development", capacity=(capacity,)),
        ),
        description=(f"the leopard's phases on a limb-like capsule of {mesh.n_vertices} vertices: spots "
                     f"(r=40 s=5 Lb=2, {n_def:,} steps), then C = copy of B under reinforcement (t=5, w=5, Dc=1) "
                     f"while the surface grows {GROWTH}x in length over {n_dev:,} steps, triangles above "
                     f"{area:.3g} dividing in a random order at their longest edge (capacity {capacity} "
                     "vertices); melanin texture"),
        figure="leopard paper section 8.2 (growth on a surface)", show="melanin", cmap="leopard")


register(ExperimentPreset("mesh-leopard-limb", "leopard spots opening into rosettes on a growing limb-like mesh "
                          "(new vertices added at random)", "leopard paper section 8.2", _leopard_limb))

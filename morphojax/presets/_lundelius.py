"""Lundelius's own grid setting (Figs. 1-3): Gray-Scott with Sims's kernel.

The paper weights each cell's 3 x 3 neighbourhood with [[0.05, 0.2, 0.05], [0.2, -1, 0.2],
[0.05, 0.2, 0.05]], which is 0.3 times the nine-point stencil [[1, 4, 1], [4, -20, 4],
[1, 4, 1]] / 6, so a rate D with that kernel is the rate 0.3 D on
`Lattice("nine-point", "wrap")` (the paper wraps its indices at every edge). The rates
D_A and D_B are not printed; the kernel is Sims's, so his D_A = 1.0 and D_B = 0.5 are used
(0.3 and 0.15 here), with dt 1. The grid is 100 x 100 with A all 1 and B all 0 but for
some cells at 1; the paper does not say which, so B starts at 1 on 12 squares of 4 x 4
cells at places drawn once (NumPy's generator, seed 0), the same for every run. Six images 750 iterations apart (Fig. 3: f = 0.055, k = 0.064; Figs. 1 and 2
print no f and k).

On meshes (Fig. 4: icospheres, tori, a bust) the paper's Laplacian is either PyMesh's
Laplace-Beltrami operator or "an equally weighted" one, the mean of the edge neighbours'
values less the vertex's own: `Mesh(..., operator="umbrella")`. Sims's kernel is the same
kind of operator on the grid (a weighted mean of the 8 neighbours less the centre), so his
rates D_A 1.0, D_B 0.5 and dt 1 carry over to it unscaled; on an icosphere its spectral
radius is about 1.5, so dt D_A rho = 1.5 keeps forward Euler stable, where the paper's runs
"oscillate greatly" and overflow. `lundelius-fig4-umbrella` runs Fig. 3's f and k so on an
icosphere of 10,242 vertices (edge about 1). It starts as the other mesh presets do,
(A, B) = (0.5, 0.25) on 12 discs of radius 4 edges (`seed_patches`) and (1, 0) elsewhere,
with noise of the run's seed: limits per vertex, which the grid's seeding phase uses to
set B = 1, are lattice maps only.

The start is two phases: one step whose lower limit on B is the seeded square (B = 1
there after it; A = 1, B = 0 is a steady state, so the step changes nothing else), then
the run. At f 0.055, k 0.064 a single seeded square only grows into a ring in 4500
iterations; scattered squares grow into worms that fill the grid.
"""

from __future__ import annotations

import numpy as np

from .._experiment import Experiment, Initial, Phase
from ..domains import Lattice, Mesh
from ..models import GrayScott
from ._meshes import seed_patches
from ._registry import ExperimentPreset, register

SIMS_SCALE = 0.3  # Sims's kernel = 0.3 x the nine-point stencil
SIMS_RATES = (1.0, 0.5)  # Sims's D_A, D_B for that kernel
FIG3 = (0.055, 0.064)  # f, k
SIDE, SQUARE, SQUARES = 100, 4, 12
IMAGES, EVERY = 6, 750  # "six 100 by 100 pixel images, with 750 iterations between each image"


def seeded_squares(side=SIDE, square=SQUARE, count=SQUARES):
    """B's start: 1 on `count` squares of `square` x `square` cells at places drawn by
    NumPy's generator with seed 0 (the same for every run and size), 0 elsewhere."""
    b = np.zeros((side, side))
    for r, c in np.random.default_rng(0).integers(0, side - square, size=(count, 2)):
        b[r:r + square, c:c + square] = 1.0
    return b


def _fig3(quick):
    side = 60 if quick else SIDE
    steps = 1500 if quick else IMAGES * EVERY
    feed, kill = FIG3
    du, dv = (SIMS_SCALE * d for d in SIMS_RATES)
    domain = Lattice("nine-point", "wrap")
    model = GrayScott(feed=feed, kill=kill, du=du, dv=dv)
    return Experiment(
        name="lundelius-fig3", initial=Initial("constant", (side, side), params=(1.0, 0.0), names=("u", "v")),
        phases=(Phase(model.replace(lower=(0.0, seeded_squares(side))), steps=1, dt=1.0, name="seed",
                      domain=domain),
                Phase(model, steps=steps, dt=1.0, frames=IMAGES, name="gray-scott", domain=domain)),
        description=f"Lundelius Fig. 3 on its {side}x{side} grid: Gray-Scott f {feed}, k {kill}, Sims's kernel (0.3 x "
                    f"the nine-point stencil, D_A 1.0, D_B 0.5), wrapped edges, A = 1 and B = 0 but {SQUARES} "
                    f"squares of {SQUARE}x{SQUARE} cells at B = 1, dt 1, {steps:,} iterations",
        figure="Lundelius Fig. 3", show="v", cmap="gray")


register(ExperimentPreset("lundelius-fig3", "Lundelius's own grid: Gray-Scott (f 0.055, k 0.064) with Sims's kernel "
                          "(0.3 x the nine-point stencil) from B = 1 on a few squares of a 100x100 grid",
                          "Lundelius Fig. 3", _fig3))


def _fig4_umbrella(quick):
    mesh = Mesh.icosphere(3, 6.5, operator="umbrella") if quick else Mesh.icosphere(5, 26.0, operator="umbrella")
    steps = 1500 if quick else IMAGES * EVERY
    feed, kill = FIG3
    model = GrayScott(feed=feed, kill=kill, du=SIMS_RATES[0], dv=SIMS_RATES[1])
    return Experiment(
        name="lundelius-fig4-umbrella",
        initial=Initial("gray-scott", (mesh.n_vertices,), params=(0.02, seed_patches(mesh)), names=("u", "v")),
        phases=(Phase(model, steps=steps, dt=1.0, frames=IMAGES, name="gray-scott", domain=mesh),),
        description=f"Lundelius Fig. 4 (icosphere) with its equally weighted Laplacian: Gray-Scott f {feed}, k {kill}, "
                    f"D_A 1.0, D_B 0.5 on the umbrella operator of an icosphere of {mesh.n_vertices} vertices, A = 1 "
                    f"and B = 0 but (0.5, 0.25) on 12 discs of radius 4 edges, dt 1, {steps:,} iterations",
        figure="Lundelius Fig. 4 (umbrella Laplacian)", show="v", cmap="gray")


register(ExperimentPreset("lundelius-fig4-umbrella", "Lundelius's mesh setting: Gray-Scott (f 0.055, k 0.064) with "
                          "its equally weighted (umbrella) Laplacian on an icosphere", "Lundelius Fig. 4",
                          _fig4_umbrella))

"""Parameter modulation on a lattice: thesis Figs. 5.11 and 5.12 (section 5.3).

Both listings grow a gradient of a signal R from producer cells (a reagent P marks them and
never changes, so here it is the production map of `Morphogen`): each iteration R gains a
fixed amount on the producers and loses a fixed amount everywhere else (clamped at 0), and
a `map` action turns R's concentration into a parameter. As in the thesis's other lattice
presets: its square lattice with the eight-neighbour sum (`Lattice("moore")`) and rates as
printed, dt 1, borders with fewer neighbours (no-flux), U and V from conc 4 dev 2 (Bard
form, alpha 16, beta 12); the thesis's cell index counts rows from the bottom of its
pictures, so its row 0 is our last row.

- Fig. 5.11: 81 x 81, one producer at the centre (cell 3280: R + 2.5 there, - 0.001
  elsewhere, D_R 0.05), the map R in [0.2, 3] -> scale in [0.005, 0.03] every iteration, U
  0.04, V 0.01, 10,000 iterations: spots grow in size from the centre outwards.
- Fig. 5.12: 81 x 81, producers along the bottom row (cells 0-80: R + 2, - 0.02 elsewhere,
  D_R 0.1); U and V neither react nor diffuse until iteration 5000, when U's rate is set
  once from R through [0, 100] -> [0.04, 0.15], V's to 0.01, and the reaction starts
  (scale 0.01) until 10,000: stripes near the producers turn into spots away from them. The
  one-time set is a phase boundary; R no longer changes in the second phase (nothing reads
  it there but the rate it set), so the modulated rate keeps the value of iteration 5000.
"""

from __future__ import annotations

import numpy as np

from .._experiment import Experiment, Initial, Phase
from ..domains import Lattice
from ..models import Bard, Composite, Modulated, Modulation, Morphogen
from ._registry import ExperimentPreset, registered

SIDE = 81
THESIS_START = ((2.0, 6.0), (2.0, 6.0), 0.0)  # U and V: conc 4 dev 2; R: conc 0


def producer_maps(cells, gain, loss, shape=(SIDE, SIDE)):
    """(production, removal) maps of R for the thesis's producer cells (its row-major
    indices from the bottom row): `gain` on them, `loss` everywhere else."""
    rows, cols = shape
    mask = np.zeros(rows * cols, bool)
    mask[list(cells)] = True
    mask = mask.reshape(shape)[::-1]  # the thesis's row 0 is at the bottom
    return np.where(mask, gain, 0.0), np.where(mask, 0.0, loss)


def _start(shape):
    return Initial("uniform", shape, params=THESIS_START, names=("a", "b", "r"))


@registered(ExperimentPreset, "thesis-fig5.11", "a producer's radial gradient sets the Turing scale: spots grow "
            "from the centre outwards", "thesis Fig. 5.11")
def _fig5_11(quick):
    side, steps = (41, 4000) if quick else (SIDE, 10000)
    centre = (side // 2) * side + side // 2  # the thesis's cell 3280 on 81 x 81
    production, removal = producer_maps([centre], 2.5, 0.001, (side, side))
    model = Modulated(Composite((Bard(alpha=16.0, beta=12.0, sp=0.01, da=0.04, db=0.01),
                                 Morphogen(production=production, removal=removal, diffusion=0.05))),
                      Modulation("0.sp", by="r", low=0.2, high=3.0, out_low=0.005, out_high=0.03))
    return Experiment(
        name="thesis-fig5.11", initial=_start((side, side)),
        phases=(Phase(model, steps=steps, dt=1.0, frames=4, name="modulated", domain=Lattice("moore", "no-flux")),),
        description=f"thesis Fig. 5.11 on {side}x{side}: R + 2.5 at the centre, - 0.001 elsewhere, D_R 0.05; "
                    "scale = map of R from [0.2, 3] onto [0.005, 0.03] every iteration; Bard 16/12, Du 0.04, Dv 0.01",
        figure="thesis Fig. 5.11", show="a")


@registered(ExperimentPreset, "thesis-fig5.12", "a gradient from the bottom row sets U's diffusion rate once: "
            "stripes to spots", "thesis Fig. 5.12")
def _fig5_12(quick):
    side, wait, steps = (41, 2500, 2500) if quick else (SIDE, 5000, 5000)
    production, removal = producer_maps(range(side), 2.0, 0.02, (side, side))
    gradient = Morphogen(production=production, removal=removal, diffusion=0.1)
    resting = Bard(alpha=16.0, beta=12.0, sp=0.0, da=0.0, db=0.0)  # no reaction, no diffusion yet
    frozen = Morphogen(diffusion=0.0)  # R as it was at the boundary
    reacting = Modulated(Composite((Bard(alpha=16.0, beta=12.0, sp=0.01, da=0.04, db=0.01), frozen)),
                         Modulation("0.da", by="r", low=0.0, high=100.0, out_low=0.04, out_high=0.15))
    domain = Lattice("moore", "no-flux")
    return Experiment(
        name="thesis-fig5.12", initial=_start((side, side)),
        phases=(Phase(Composite((resting, gradient)), steps=wait, dt=1.0, frames=1, name="gradient", domain=domain),
                Phase(reacting, steps=steps, dt=1.0, frames=4, name="reaction", domain=domain)),
        description=f"thesis Fig. 5.12 on {side}x{side}: R + 2 on the bottom row, - 0.02 elsewhere, D_R 0.1 for "
                    f"{wait:,} iterations; then Du = map of R from [0, 100] onto [0.04, 0.15], Dv 0.01 and Bard "
                    f"16/12 scale 0.01 for {steps:,}",
        figure="thesis Fig. 5.12", show="b")

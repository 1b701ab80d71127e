"""Presets of diffusion on a lattice's links: thesis Fig. 5.1 (per-cell rates), Fig. 5.13
(anisotropic diffusion along a polarity) and Figs. 5.14-5.15 (a polarity that follows a
reagent's gradient).

Both use the thesis's square lattice as it computes it: the equal-weight sum over the eight
neighbours (`Lattice(stencil="moore")`, section 4.3) with its rates as printed, dt 1 (its
default time step), and cells at the border that simply have fewer neighbours
(`boundary="no-flux"`).

Fig. 5.1 (section 5.1): 15 x 15 cells of rate 0 except cells 75-149 (row-major, so rows 5-9)
of rate 0.1, and 75 units of R in cell 108 (row 7, column 3). Per-cell rates diffuse in the
flux form, each link carrying the harmonic mean of its two cells' rates (eq. 4.7), which is
0 toward an impermeable cell: the 75 units stay on the band's 75 cells and even out to 1.0
each by about iteration 1000. R is species "a" of a Bard model with no reaction (sp = 0);
the thesis's `set cell 108 conc 75` is one step whose lower limit is 75 on that cell.

Fig. 5.13 (section 5.4): Listing 5.x's experiment (Bard form, alpha 16, beta 12, scale 0.01,
Du 0.08, Dv 0.01, conc 4 dev 2, 40 x 40, 5000 iterations, `use polarity 0`: every cell
polarised along a row), with U (= a) and V (= b) isotropic, both anisotropic, only V, or only
U (eq. 4.8). The thesis: only V gives stripes along the polarity, only U stripes across it,
both no direction. Its random numbers are not reproduced.

Figs. 5.14-5.15 (Listings A.1-A.2) on the hexagonal lattice they use (`hex_grid 100 100`,
without wrap: `HexLattice("no-flux", operator="sum")`, its six-neighbour sum with the rates
as printed): a producer cell (5050, row 50, column 50) adds 4 of R every iteration and every
other cell loses 0.001 (`Morphogen`), R diffuses at 0.05, and every cell is polarised along
R's gradient as it forms (`polarity=Polarize("r")`, eq. 4.10). Fig. 5.14: V anisotropic, U
0.024, V 0.00625, conc 4 dev 1, the reaction at scale 0.004 from the start, 10,000
iterations: radial stripes. Fig. 5.15: U anisotropic, U 0.03, the reaction at scale 0.006
only from iteration 3,000 (a second phase), 18,000 iterations: concentric rings. V is shown,
the listings' first chemical. `thesis-fig5.14` and `thesis-fig5.15` run the same listings on
cells.
"""

from __future__ import annotations

import numpy as np

from .._experiment import Experiment, Initial, Phase
from .._render import Gradient
from ..domains import HexLattice, Lattice, Polarize
from ..models import Bard, Composite, Morphogen
from ._lattices import thesis_run
from ._registry import ExperimentPreset, register

FIG5_1_SHAPE = (15, 15)
FIG5_1_BAND = (75, 150)  # cells 75-149, row-major
FIG5_1_CELL = 108
FIG5_1_RATE = 0.1
FIG5_1_AMOUNT = 75.0


def fig5_1_rates(shape=FIG5_1_SHAPE):
    """The per-cell rate map of thesis Fig. 5.1: 0.1 on cells 75-149 (row-major), 0 elsewhere."""
    d = np.zeros(int(shape[0]) * int(shape[1]))
    d[FIG5_1_BAND[0]:FIG5_1_BAND[1]] = FIG5_1_RATE
    return d.reshape(shape)


def _fig5_1(quick):
    seed = np.zeros(FIG5_1_SHAPE)
    seed.flat[FIG5_1_CELL] = FIG5_1_AMOUNT
    domain = Lattice("moore", "no-flux")
    steps = 300 if quick else 1000
    return Experiment(
        name="thesis-fig5.1", initial=Initial("constant", FIG5_1_SHAPE, params=(0.0, 0.0)),
        phases=(
            Phase(Bard(alpha=0.0, beta=0.0, sp=0.0, da=0.0, db=0.0, lower=(seed, 0.0)), steps=1, dt=1.0,
                  name="prepattern", domain=domain),
            Phase(Bard(alpha=0.0, beta=0.0, sp=0.0, da=fig5_1_rates(), db=0.0), steps=steps, dt=1.0,
                  frames=tuple(s for s in (2, 5, 50, 1000) if s <= steps), name="diffusion", domain=domain),
        ),
        description="thesis Fig. 5.1: 75 units in cell 108 spread over the 75 permeable cells 75-149 of a 15x15 "
                    "lattice (rate 0.1, 0 elsewhere; flux form, harmonic mean per link), each reaching 1.0",
        figure="thesis Fig. 5.1", show="a",
    )


FIG5_13 = dict(alpha=16.0, beta=12.0, sp=0.01, da=0.08, db=0.01)  # U = a, V = b
FIG5_13_CASES = {"isotropic": (), "both": ("a", "b"), "v": ("b",), "u": ("a",)}


def _fig5_13(case: str):
    def build(quick):
        shape, steps = ((32, 32), 1500) if quick else ((40, 40), 5000)
        domain = Lattice("moore", "no-flux", anisotropic=FIG5_13_CASES[case], polarity=0.0)
        which = " and ".join(FIG5_13_CASES[case]) or "no species"
        return thesis_run(f"thesis-fig5.13-{case}", FIG5_13, shape, steps, domain,
                          f"thesis Fig. 5.13 on {shape[0]}x{shape[1]} cells polarised along a row (angle 0): {which} "
                          "anisotropic (U = a, V = b; Du 0.08, Dv 0.01, scale 0.01, dt 1)", "thesis Fig. 5.13")

    return build


_WHAT = {"isotropic": "(a) both isotropic", "both": "(b) both anisotropic: no direction",
         "v": "(c) V anisotropic: stripes along the polarity", "u": "(d) U anisotropic: stripes across it"}
register(ExperimentPreset("thesis-fig5.1", "75 units diffusing over impermeable cells' gaps (per-cell rates, "
                          "flux form)", "thesis Fig. 5.1", _fig5_1))
for _case in FIG5_13_CASES:
    register(ExperimentPreset(f"thesis-fig5.13-{_case}", f"anisotropic diffusion along a row, {_WHAT[_case]}",
                              "thesis Fig. 5.13", _fig5_13(_case)))
register(ExperimentPreset(
    "thesis-fig5.13", "anisotropic diffusion: isotropic, both, only V, only U (four tiles)", "thesis Fig. 5.13",
    members=tuple(f"thesis-fig5.13-{c}" for c in FIG5_13_CASES),
    row_labels=("polarity 0",), col_labels=("isotropic", "both", "V only", "U only")))


FIG5_14_CASES = {  # anisotropic species, U's rate, scale, iterations before the reaction, iterations
    "5.14": (("b",), 0.024, 0.004, 0, 10000),
    "5.15": (("a",), 0.03, 0.006, 3000, 18000),
}
FIG5_14_COLOURS = {"5.14": Gradient([(0.0, "white"), (1.0, "#420009")]),
                   "5.15": Gradient([(40 / 99, "#0ee1da"), (80 / 99, "#80763e")])}


def _fig5_14(figure: str):
    def build(quick):
        anisotropic, du, scale, wait, steps = FIG5_14_CASES[figure]
        side = 60 if quick else 100
        if quick:
            wait, steps = wait // 3, steps // 3
        production = np.zeros((side, side))
        production[side // 2, side // 2] = 4.0  # the producer, cell 5050 of 100 x 100
        removal = np.where(production > 0, 0.0, 0.001)
        domain = HexLattice("no-flux", "sum", anisotropic=anisotropic, polarity=Polarize("c"))
        gradient = Morphogen(production=production, removal=removal, diffusion=0.05)
        bard = Bard(alpha=16.0, beta=12.0, sp=scale, da=du, db=0.00625)
        phases = (Phase(Composite((bard, gradient)), steps=steps - wait, dt=1.0, frames=4, name="polarised",
                        domain=domain),)
        if wait:
            phases = (Phase(Composite((bard.replace(sp=0.0), gradient)), steps=wait, dt=1.0, frames=1,
                            name="no reaction", domain=domain),) + phases
        which = "V" if anisotropic == ("b",) else "U"
        return Experiment(
            name=f"thesis-fig{figure}-lattice", initial=Initial("uniform", (side, side),
                                                                params=((3.0, 5.0), (3.0, 5.0), 0.0),
                                                                names=("a", "b", "r")),
            phases=phases,
            description=f"thesis Listing A.{1 if figure == '5.14' else 2} on a {side}x{side} hexagonal lattice "
                        f"(six-neighbour sum): {which} anisotropic along R's gradient from a central producer "
                        f"(+4, -0.001 elsewhere, D_R 0.05), Du {du}, Dv 0.00625, scale {scale}"
                        + (f" from iteration {wait:,}" if wait else "") + f", {steps:,} iterations",
            figure=f"thesis Fig. {figure} (Listing A.{1 if figure == '5.14' else 2})", show="b",
            cmap=FIG5_14_COLOURS[figure])

    return build


register(ExperimentPreset("thesis-fig5.14-lattice", "radial stripes: V anisotropic along a producer's gradient "
                          "(Polarize), hexagonal lattice", "thesis Fig. 5.14 (Listing A.1)", _fig5_14("5.14")))
register(ExperimentPreset("thesis-fig5.15-lattice", "concentric rings: U anisotropic along a producer's gradient "
                          "(Polarize), hexagonal lattice", "thesis Fig. 5.15 (Listing A.2)", _fig5_14("5.15")))

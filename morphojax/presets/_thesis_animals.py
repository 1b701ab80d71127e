"""The thesis's saturated animals on a lattice: the poison dart frog (Fig. 7.16, Listing A.16)
and the moray eel (Fig. 7.18, Listing A.17). `thesis-fig7.16-cells` and
`thesis-fig7.18-cells` run the same listings on cells.

Both listings create a `sqr_grid` without `wrap`, so they run on the thesis's square lattice
as it computes it: the eight-neighbour sum (`Lattice("moore", "no-flux")`) with the rates as
printed, at the listing's time step, from conc 4 dev 2 (U and V uniform in [2, 6)), Bard
form alpha 16, beta 12 (U = a, V = b), showing U through the listing's colour map. The
thesis's cell indices count rows from the bottom of its pictures (`set cells 0 to 4999` is
the lower half of a 100 x 100 grid), so its row 0 is our last row. Its random numbers are not
reproduced (`use seed 1` drives its own generator).

- Fig. 7.16: U limited at 6.3, V anisotropic; `use polarity 90` (vertical) except cells
  0-4999, the lower half, which are unpolarised and diffuse slowly (U 0.011, V 0.003 against
  0.30 and 0.02 above); scale 0.008, dt 0.5, 5000 iterations. Vertical stripes above, spots
  of different sizes below.
- Fig. 7.18: U and V limited at 6.5 on 200 x 100 cells; U diffuses at 0.40 on the lower 25
  rows and the upper 4, 0.20 on the rows between them and the body (0.05). A reagent P
  starts at 8 on cells 10240 and 10850 and diffuses at 0.01; the listing stops that at
  iteration 2500 (its rule "from 2500 until 2000" is an empty window, read as 2500, as
  the cell preset does). Cells where P > 0.01 gain 1 of V every iteration, which against
  V's limit of 6.5 holds them there: here V's lower limit is set from P by a steep map
  (`Modulation("0.lower_b", "p", 0.01, 0.011, 0, 6.5)`), so those cells stay at 6.5 and
  make the eel's black spot. Scale 0.03, dt 0.3, 5000 iterations.
"""

from __future__ import annotations

import numpy as np

from .._experiment import Experiment, Initial, Phase
from .._render import Gradient
from ..domains import Lattice
from ..models import Bard, Composite, Modulated, Modulation, Morphogen
from ._registry import ExperimentPreset, registered


def thesis_rows(values, shape) -> np.ndarray:
    """A per-cell array in the thesis's row-major order (row 0 at the bottom of its
    pictures) laid out on our lattice (row 0 at the top)."""
    return np.asarray(values).reshape(shape)[::-1]


def _cells(shape, ranges, default=0.0):
    """A thesis-order array of `default` with `value` on each (first, last) index range."""
    out = np.full(shape[0] * shape[1], default, float)
    for (first, last), value in ranges:
        out[first:last + 1] = value
    return out


FROG_SHAPE = (100, 100)


@registered(ExperimentPreset, "thesis-fig7.16", "poison dart frog on a lattice: vertical stripes above "
            "(V anisotropic), spots of many sizes below", "thesis Fig. 7.16 (Listing A.16)")
def _frog(quick):
    shape, steps = ((60, 60), 2500) if quick else (FROG_SHAPE, 5000)
    half = shape[0] * shape[1] // 2 - 1  # cells 0-4999 on 100 x 100: the lower half
    du = thesis_rows(_cells(shape, [((0, half), 0.011)], 0.30), shape)
    dv = thesis_rows(_cells(shape, [((0, half), 0.003)], 0.02), shape)
    polarity = thesis_rows(_cells(shape, [((0, half), np.nan)], np.pi / 2), shape)
    domain = Lattice("moore", "no-flux", anisotropic=("b",), polarity=polarity)
    return Experiment(
        name="thesis-fig7.16", initial=Initial("thesis", shape),
        phases=(Phase(Bard(alpha=16.0, beta=12.0, sp=0.008, da=du, db=dv, upper=(6.3, np.inf)), steps=steps, dt=0.5,
                      frames=4, name="saturated", domain=domain),),
        description=f"thesis Listing A.16 on {shape[0]}x{shape[1]}: U <= 6.3, V anisotropic along polarity 90 deg "
                    "on the upper half (Du 0.30, Dv 0.02), unpolarised below (Du 0.011, Dv 0.003); scale 0.008, dt 0.5",
        figure="thesis Fig. 7.16 (Listing A.16)", show="a",
        cmap=Gradient([(20 / 99, "#ffbf00"), (25 / 99, "cyan"), (45 / 99, "#202020")]))


EEL_SHAPE = (100, 200)  # sqr_grid 200 100: 200 columns, 100 rows
EEL_SPOT = (10240, 10850)  # the two cells where P starts at 8
EEL_STOP_P = 2500


@registered(ExperimentPreset, "thesis-fig7.18", "moray eel on a lattice: saturated RD, body parts of different "
            "U rates, a black spot held by a gradient", "thesis Fig. 7.18 (Listing A.17)")
def _eel(quick):
    shape = EEL_SHAPE
    first, second = (EEL_STOP_P // 2, EEL_STOP_P // 2) if quick else (EEL_STOP_P, 5000 - EEL_STOP_P)
    du = thesis_rows(_cells(shape, [((0, 4999), 0.40), ((5000, 5399), 0.20), ((19000, 19199), 0.20),
                                    ((19200, 19999), 0.40)], 0.05), shape)
    p0 = thesis_rows(_cells(shape, [((i, i), 8.0) for i in EEL_SPOT]), shape)
    bard = Bard(alpha=16.0, beta=12.0, sp=0.03, da=du, db=0.01, upper=(6.5, 6.5))
    held = Modulation("0.lower_b", by="p", low=0.01, high=0.011, out_low=0.0, out_high=6.5)
    domain = Lattice("moore", "no-flux")
    phase = lambda p_rate, steps, name, **kw: Phase(  # noqa: E731
        Modulated(Composite((bard, Morphogen(diffusion=p_rate)), species=("a", "b", "p")), held), steps=steps, dt=0.3, frames=2, name=name,
        domain=domain, **kw)
    return Experiment(
        name="thesis-fig7.18", initial=Initial("thesis", shape),
        phases=(phase(0.01, first, "gradient", add_species=(("p", p0),)), phase(0.0, second, "held")),
        description=f"thesis Listing A.17 on {shape[0]}x{shape[1]}: U, V <= 6.5, Du 0.40 / 0.20 / 0.05 by body part, "
                    f"Dv 0.01, scale 0.03, dt 0.3; P from 8 on two cells diffusing at 0.01 for {first:,} iterations, "
                    f"then held for {second:,}; V held at 6.5 where P > 0.01",
        figure="thesis Fig. 7.18 (Listing A.17)", show="a",
        cmap=Gradient([(25 / 99, "#30292d"), (30 / 99, "#e8e336"), (40 / 99, "white")]))

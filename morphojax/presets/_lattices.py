"""Presets that compare lattices: the thesis's square (Moore) and hexagonal lattices.

Thesis section 5.2.4, Fig. 5.10: the base experiment of Listing 5.1 (Bard form, alpha 16,
beta 12, scale 0.01, Du 0.06, Dv 0.01, conc 4 dev 2, dt 1, 5000 iterations) on 40 x 40
cells, once on the square lattice and once on the hexagonal one, every parameter the same.
The thesis's diffusion sums differences over the neighbours with equal weights, so the
runs use its own operators with its rates as printed: `Lattice(stencil="moore")` (eight
neighbours) and `HexLattice(operator="sum")` (six). With fewer neighbours the hexagonal
lattice diffuses less, which shortens the pattern's wavelength (the thesis's observation).
The thesis's random numbers are not reproduced (its seed 1 is its own generator's).
"""

from __future__ import annotations

from .._experiment import Experiment, Initial, Phase
from ..domains import HexLattice, Lattice
from ..models import Bard
from ._registry import ExperimentPreset, register

LISTING_5_1 = dict(alpha=16.0, beta=12.0, sp=0.01, da=0.06, db=0.01)  # U = a, V = b


def thesis_run(name, rates, shape, steps, domain, description, figure) -> Experiment:
    """One static run of the thesis's chapter 5 in the Bard form (alpha 16, beta 12 and the
    given rates), from its random start (conc 4 dev 2) at dt 1, showing V."""
    return Experiment(
        name=name, initial=Initial("thesis", shape, params=(2.0, 4.0)),
        phases=(Phase(Bard(**rates), steps=steps, dt=1.0, frames=4, name="static", domain=domain),),
        description=description, figure=figure, show="b")


def _fig5_10(lattice: str):
    def build(quick):
        domain = HexLattice("wrap", operator="sum") if lattice == "hex" else Lattice("moore", "wrap")
        shape, steps = ((24, 24), 2000) if quick else ((40, 40), 5000)
        where = "hexagonal lattice (six-neighbour sum)" if lattice == "hex" else "square lattice (Moore sum)"
        return thesis_run(f"thesis-fig5.10-{lattice}", LISTING_5_1, shape, steps, domain,
                          f"thesis Listing 5.1 on a {shape[0]}x{shape[1]} {where}: conc 4 dev 2, Du 0.06, Dv 0.01, "
                          "scale 0.01, dt 1", "thesis Fig. 5.10")

    return build


for _lattice, _what in (("square", "square lattice, eight-neighbour sum"), ("hex", "hexagonal lattice, six-neighbour sum")):
    register(ExperimentPreset(f"thesis-fig5.10-{_lattice}", f"thesis Listing 5.1 on a 40x40 {_what} (Turing pattern on V)",
                              "thesis Fig. 5.10", _fig5_10(_lattice)))
register(ExperimentPreset(
    "thesis-fig5.10", "the same Turing experiment on a square and a hexagonal lattice (two tiles)", "thesis Fig. 5.10",
    members=("thesis-fig5.10-square", "thesis-fig5.10-hex"), col_labels=("square", "hexagonal")))

"""The classic reactions of Tinson 2022 section II.C (and the Brusselator and Thomas's model
it names) forming their Turing patterns: `morphojax run fitzhugh-nagumo`, `gierer-meinhardt`,
`schnakenberg`, `brusselator`, `thomas`.

Tinson 2022 prints the equations but no parameters or pictures, so each preset runs the
model's defaults (see their docstrings: values inside the Turing-unstable regime, chosen by
the linear stability of the homogeneous state, wavelength about 7-9 cells on the
nine-point stencil) from that homogeneous state with 1% uniform noise, on a wrapping
128x128 lattice to simulated time 150; `quick`: 48x48 to time 60, where the spots have
formed but still move. dt is about half the diffusion limit, for the reaction's own
stiffness at the spots' peaks.
"""

from __future__ import annotations

from .._experiment import Experiment, Initial, Phase
from .._initial import STEADY_NOISE, around
from ..models import Brusselator, FitzHughNagumo, GiererMeinhardt, Schnakenberg, Thomas
from ._registry import ExperimentPreset, register

REACTIONS = {
    # name: (model class, dt, what)
    "fitzhugh-nagumo": (FitzHughNagumo, 0.15, "FitzHugh-Nagumo (Tinson 2022 II.C.1): spots and short stripes"),
    "gierer-meinhardt": (GiererMeinhardt, 0.035, "Gierer-Meinhardt activator-inhibitor: hexagonal spots"),
    "schnakenberg": (Schnakenberg, 0.02, "Schnakenberg (Tinson 2022 II.C.3): hexagonal spots"),
    "brusselator": (Brusselator, 0.02, "Brusselator (named in Tinson 2022 II.C): hexagonal spots"),
    "thomas": (Thomas, 0.015, "Thomas's substrate inhibition (named in Tinson 2022 II.C): spots of low u"),
}
TIME, QUICK_TIME = 150.0, 60.0


def _reaction(name, cls, dt, what):
    def build(quick):
        shape, T = ((48, 48), QUICK_TIME) if quick else ((128, 128), TIME)
        model = cls()
        steady = [float(v) for v in model.homogeneous_state()]
        return Experiment(
            name=name,
            initial=Initial("uniform", shape, params=tuple(around(v) for v in steady), names=model.species),
            phases=(Phase(model, steps=int(round(T / dt)), dt=dt, frames=4, name="static"),),
            description=f"{what}; defaults of mj.{cls.__name__}, from ({steady[0]:g}, {steady[1]:g}) "
                        f"with {STEADY_NOISE:.0%} noise, T = {T:g}, dt = {dt:g}",
            figure="Tinson 2022 section II.C (equations only)", show="u",
        )

    return build


for _name, (_cls, _dt, _what) in REACTIONS.items():
    register(ExperimentPreset(_name, _what, "Tinson 2022 section II.C", _reaction(_name, _cls, _dt, _what)))

"""The thesis's parameter study of a standard Turing pattern on a lattice: Figs. 5.3, 5.6-5.9.

Section 5.2 runs its base experiment, Listing 5.1 (Bard form, alpha 16, beta 12, scale
0.01, Du 0.06, Dv 0.01, conc 4 dev 2, dt 1, 5000 iterations on an 80 x 80 square grid),
and varies one parameter at a time. As in the thesis's other lattice presets (`_lattices`,
`_anisotropy`): its square lattice with the eight-neighbour sum (`Lattice("moore")`) and
rates as printed, cells at the border with fewer neighbours (`boundary="no-flux"`). Every
member of a series runs the listing's 5000 iterations ("stop at 5000") from the same
start; the thesis's random numbers are not reproduced.

- Fig. 5.3: the base experiment showing U and V.
- Fig. 5.4: the base experiment on V with the random seeds 1 to 5 side by side
  (`thesis-fig5.4`, run by one builder: a figure's members all run with the run's one
  seed). Each panel is `thesis-fig5.3-v` run with that seed (`--seed N` gives N + 1 to
  N + 5); the thesis's own generator is not reproduced, so the panels are five starts of
  this library's, not the thesis's five.
- Fig. 5.6: Du and Dv multiplied by 1/2, 1, 2, 3, 4; the thesis lowers dt to 0.8 and 0.6
  for factors 3 and 4 (the eight-neighbour sum is stable while dt * D * 12 <= 2).
- Fig. 5.7: scale s of 0.001, 0.005, 0.01, 0.02, 0.04.
- Fig. 5.9: Du of 0.04, 0.06, 0.10, 0.15, 0.40, 0.80, with dt 0.4 and 0.2 for the last two
  (the thesis's choices).
- Fig. 5.8: the parameter map the thesis made with Ready: one lattice whose Du goes
  linearly from 0.00 in the first column to 0.80 in the last (`parameter_map`), Dv 0.01.
  Per-cell rates diffuse in the flux form (each link carries the harmonic mean of its two
  cells' rates); dt 0.2, the largest the fastest column allows, for 25,000 iterations (the
  base experiment's simulated time, 5000).
- Fig. 5.5: four more maps, (a) Du against Dv, (b) alpha against beta, (c) alpha alone,
  (d) beta alone. Their ranges are not printed; these are chosen around section 5.2.3's
  findings (patterns for alpha in [10, 17] and beta in [10, 20]; Du and Dv in a linear
  relation): Du 0.02-0.40 against Dv 0.002-0.02, alpha 8-20 against beta 8-24, each at the
  largest dt its fastest rate allows, for the base experiment's simulated time.
- Fig. 7.14 (section 7.3): the map of Du (0.00-0.80 across, Fig. 5.8's range) against U's
  saturation limit L_U (`upper_a`, 10 at the top to 3 at the bottom; not printed either):
  where U stays below its limit the pattern is the standard one, below the steady state's
  U = 4 the reagents settle to constants.
"""

from __future__ import annotations

import json
import math
import time

import numpy as np

from .._experiment import Experiment, Initial, Phase
from .._run_experiment import run_experiment
from .._files import write_npz
from .._parameter_map import parameter_map
from .._render import montage
from ..domains import Lattice, max_stable_dt
from ..models import Bard
from ._lattices import LISTING_5_1
from ._registry import AutomatonPreset, ExperimentPreset, lookup, register, registered

LISTING_STEPS = 5000  # "stop at 5000"
LISTING_SIDE = 80  # "create sqr_grid 80 80"
FIG5_6_FACTORS = {"0.5": (0.5, 1.0), "1": (1.0, 1.0), "2": (2.0, 1.0), "3": (3.0, 0.8), "4": (4.0, 0.6)}  # factor, dt
FIG5_7_SCALES = (0.001, 0.005, 0.01, 0.02, 0.04)
FIG5_9_DU = {0.04: 1.0, 0.06: 1.0, 0.10: 1.0, 0.15: 1.0, 0.40: 0.4, 0.80: 0.2}  # Du -> dt
FIG5_8_RANGE = (0.0, 0.8)  # Du from the first column to the last
FIG5_8_DT = 0.2
FIG5_4_SEEDS = 5  # seeds 1-5, "from left to right"


def listing_5_1(name, rates, dt, show, description, figure, quick, shape=None, steps=None, model=None) -> Experiment:
    """Listing 5.1 on the thesis's square lattice with `rates` changed (and `dt`), showing
    `show` ("a" = U, "b" = V); `quick` runs 32 x 32 cells for 2000 iterations."""
    side = 32 if quick else LISTING_SIDE
    shape = shape or (side, side)
    steps = steps or (2000 if quick else LISTING_STEPS)
    return Experiment(
        name=name, initial=Initial("thesis", shape, params=(2.0, 4.0)),
        phases=(Phase(model if model is not None else Bard(**rates), steps=steps, dt=dt, frames=4, name="static",
                      domain=Lattice("moore", "no-flux")),),
        description=description, figure=figure, show=show)


def _series(figure, prefix, cases, what, labels, row_label):
    """Register one preset per case (`cases`: suffix -> (rates, dt, show, words)) and the
    figure that shows them side by side."""
    names = []
    for suffix, (rates, dt, show, words) in cases.items():
        name = f"{prefix}-{suffix}"

        def build(quick, name=name, rates=rates, dt=dt, show=show, words=words):
            return listing_5_1(name, rates, dt, show, f"thesis Listing 5.1 with {words} (square lattice, Moore sum, "
                               f"no-flux, dt {dt:g})", figure, quick)

        register(ExperimentPreset(name, f"thesis Listing 5.1 with {words}", figure, build))
        names.append(name)
    register(ExperimentPreset(prefix, what, figure, members=tuple(names), row_labels=(row_label,), col_labels=labels))


_series("thesis Fig. 5.3", "thesis-fig5.3",
        {"u": (LISTING_5_1, 1.0, "a", "U shown"), "v": (LISTING_5_1, 1.0, "b", "V shown")},
        "thesis Listing 5.1, the standard Turing pattern, shown on U and on V (two tiles)", ("U", "V"), "Listing 5.1")
_series("thesis Fig. 5.6", "thesis-fig5.6",
        {k: ({**LISTING_5_1, "da": LISTING_5_1["da"] * f, "db": LISTING_5_1["db"] * f}, dt, "b",
             f"Du and Dv multiplied by {k}") for k, (f, dt) in FIG5_6_FACTORS.items()},
        "thesis Listing 5.1 with Du and Dv multiplied by 1/2, 1, 2, 3, 4: larger features (five tiles)",
        tuple(f"x {k}" for k in FIG5_6_FACTORS), "V")
_series("thesis Fig. 5.7", "thesis-fig5.7",
        {f"{s:g}": ({**LISTING_5_1, "sp": s}, 1.0, "b", f"scale s = {s:g}") for s in FIG5_7_SCALES},
        "thesis Listing 5.1 with scale s from 0.001 to 0.04: smaller features as s grows (five tiles)",
        tuple(f"s = {s:g}" for s in FIG5_7_SCALES), "V")
_series("thesis Fig. 5.9", "thesis-fig5.9",
        {f"{du:.2f}": ({**LISTING_5_1, "da": du}, dt, "b", f"Du = {du:.2f}") for du, dt in FIG5_9_DU.items()},
        "thesis Listing 5.1 with Du from 0.04 to 0.80: negative spots, labyrinths, larger spots (six tiles)",
        tuple(f"Du = {du:.2f}" for du in FIG5_9_DU), "V")


@registered(AutomatonPreset, "thesis-fig5.4", "thesis Listing 5.1 on V with five random seeds side by side "
            "(thesis-fig5.3-v run with seeds N + 1 to N + 5 for --seed N: 1 to 5 by default)", "thesis Fig. 5.4")
def _fig5_4(seed, quick, out, frames):
    """`thesis-fig5.3-v` (quick: 32 x 32, 2000 iterations) run with the seeds seed + 1 to
    seed + 5, one panel each; writes the montage `out` and V of every panel (`.npz`)."""
    experiment = lookup("thesis-fig5.3-v").experiment(quick)
    seeds = [seed + k for k in range(1, FIG5_4_SEEDS + 1)]
    t0 = time.perf_counter()
    results = [run_experiment(experiment, seed=s) for s in seeds]
    seconds = time.perf_counter() - t0
    v = np.stack([np.asarray(r.state.array("b"), np.float32) for r in results])
    scale = max(1, 160 // v.shape[1])
    montage([r.image(scale=scale) for r in results], FIG5_4_SEEDS, row_labels=["V"],
            col_labels=[f"seed {s}" for s in seeds],
            title="thesis Fig. 5.4: Listing 5.1 with five random seeds").save(out)
    metadata = {"kind": "seed-series", "preset": "thesis-fig5.4", "member": "thesis-fig5.3-v", "seeds": seeds,
                "steps": experiment.phases[-1].steps, "experiment": experiment.to_dict()}
    npz = write_npz(out.with_suffix(".npz"), v=v, seeds=np.asarray(seeds), metadata=json.dumps(metadata))
    return {"steps": experiment.phases[-1].steps, "shape": list(v.shape[1:]), "seeds": seeds,
            "seconds_run": round(seconds, 3), "files": [str(out), str(npz)]}


def _fig5_8(quick):
    shape = (24, 96) if quick else (64, 256)
    steps = 5000 if quick else int(LISTING_STEPS / FIG5_8_DT)
    model = parameter_map(Bard(**LISTING_5_1), shape, x=("da", *FIG5_8_RANGE))
    return listing_5_1("thesis-fig5.8", None, FIG5_8_DT, "b",
                       f"thesis Fig. 5.8's parameter map on {shape[0]}x{shape[1]} cells: Du from 0.00 (first column) to "
                       f"0.80 (last), Dv 0.01, scale 0.01, Moore sum, no-flux, dt {FIG5_8_DT:g}, {steps:,} iterations",
                       "thesis Fig. 5.8", quick, shape=shape, steps=steps, model=model)


register(ExperimentPreset("thesis-fig5.8", "parameter map: Du from 0.00 to 0.80 across one lattice (negative spots, "
                          "labyrinths, larger spots)", "thesis Fig. 5.8", _fig5_8))


MAPS = {  # name: (figure, x, y, what)
    "thesis-fig5.5-a": ("thesis Fig. 5.5 (a)", ("da", 0.02, 0.40), ("db", 0.002, 0.02), "Du against Dv"),
    "thesis-fig5.5-b": ("thesis Fig. 5.5 (b)", ("alpha", 8.0, 20.0), ("beta", 8.0, 24.0), "alpha against beta"),
    "thesis-fig5.5-c": ("thesis Fig. 5.5 (c)", ("alpha", 8.0, 20.0), None, "alpha alone"),
    "thesis-fig5.5-d": ("thesis Fig. 5.5 (d)", ("beta", 8.0, 24.0), None, "beta alone"),
    "thesis-fig7.14": ("thesis Fig. 7.14", ("da", *FIG5_8_RANGE), ("upper_a", 10.0, 3.0), "Du against U's limit L_U"),
}


def _map(name):
    figure, x, y, what = MAPS[name]

    def build(quick):
        shape = (48, 48) if quick else (128, 128)
        rates = {**LISTING_5_1, x[0]: x[2]} if x[0] in ("da", "db") else LISTING_5_1
        if y is not None and y[0] in ("da", "db"):
            rates = {**rates, y[0]: max(y[1:])}
        # the largest multiple of 0.05 within the fastest rate's limit (0.2 for Du 0.8, as Fig. 5.9)
        dt = min(1.0, math.floor(20 * max_stable_dt(max(rates["da"], rates["db"]), "moore")) / 20)
        steps = 5000 if quick else int(round(LISTING_STEPS / dt))
        model = parameter_map(Bard(**LISTING_5_1), shape, x=x, y=y)
        ranges = f"{x[0]} {x[1]:g} to {x[2]:g} across" + (f", {y[0]} {y[1]:g} (top) to {y[2]:g} (bottom)" if y else "")
        return listing_5_1(name, None, dt, "b", f"{figure}'s parameter map on {shape[0]}x{shape[1]} cells: {ranges} "
                           f"(ranges chosen, not printed), Listing 5.1 otherwise, Moore sum, no-flux, dt {dt:g}, "
                           f"{steps:,} iterations", figure, quick, shape=shape, steps=steps, model=model)

    return build


for _name, (_figure, _x, _y, _what) in MAPS.items():
    register(ExperimentPreset(_name, f"parameter map: {_what} across one lattice (Listing 5.1; ranges chosen)", _figure,
                              _map(_name)))
register(ExperimentPreset("thesis-fig5.5", "parameter maps: Du x Dv, alpha x beta, alpha, beta (four tiles)",
                          "thesis Fig. 5.5", members=tuple(n for n in MAPS if n.startswith("thesis-fig5.5")),
                          row_labels=("V",), col_labels=("(a) Du x Dv", "(b) alpha x beta", "(c) alpha", "(d) beta")))

"""The papers' reaction-diffusion experiments as presets: `morphojax run NAME` or
`run_experiment(preset(NAME))`.

Parameters come from the leopard paper's Tables 1-2 and section 7 (figures 4-17), and the
thesis's listings (figures 7.13 and 7.15). Where a paper leaves a number out, the choice is
written next to it. Every preset has a `quick` variant (smaller lattice, fewer steps) that
runs in seconds, for demos and tests; it shows the same mechanism, not the same picture.

Conversions from the thesis: its diffusion sums differences over the 8 Moore neighbours
with equal weights, which approximates 3 x the Laplacian, so its D values are multiplied
by 3 for our isotropic nine-point stencil; its `scale` is Bard's `sp`; its default dt is 1;
its "conc 4 dev d" is uniform in [4 - d, 4 + d).
"""

from __future__ import annotations

import math

import numpy as np

from .._experiment import Experiment, Initial, Phase
from .._growth import Growth, Source
from ..models import Bard, Composite, GrayScott, Reinforcement, Turing
from .._render import Gradient
from ._registry import ExperimentPreset, register, registered

INF = math.inf


# ---- static domains: leopard paper Fig. 4 (Table 2) -------------------------------------
FIG4_RATIOS = (4.2, 6.0, 12.0, 20.0, 40.0)
FIG4_UA = (6.2, 6.0, 5.2, 4.4, 4.0)
FIG4_LB = (3.0, 3.0, 3.0, 3.5, 4.0)
FIG4_DT = (0.01, 0.01, 0.008, 0.006, 0.003)
# Table 1 gives "<= 33,333 iterations" for Fig. 4: 33,333 x dt = 100 for r = 40, so every
# column is run to the same simulated time T = 100 (10,000 to 33,333 steps).
FIG4_TIME = 100.0


def _fig4(r, ua, lb, dt, variant):
    def build(quick):
        T = 25.0 if quick else FIG4_TIME
        lower = (0.0, lb) if variant == "lb" else (0.0, 0.0)
        upper = (ua, INF) if variant == "ua" else (INF, INF)
        model = Turing(ratio=r, scale=3.0, lower=lower, upper=upper)
        shape = (32, 32) if quick else (50, 50)
        name = _fig4_name(r, variant)
        return Experiment(
            name=name, initial=Initial("paper", shape),
            phases=(Phase(model, steps=int(round(T / dt)), dt=dt, frames=4, name="static"),),
            description=f"Turing r={r:g}, s=3" + {"std": "", "ua": f", Ua={ua:g}", "lb": f", Lb={lb:g}"}[variant],
            figure="leopard paper Fig. 4", show="b",
        )

    return build


def _fig4_name(r, variant):
    return f"fig4-r{r:g}" + {"std": "", "ua": "-ua", "lb": "-lb"}[variant]


for _r, _ua, _lb, _dt in zip(FIG4_RATIOS, FIG4_UA, FIG4_LB, FIG4_DT):
    for _v, _what in (("std", "no upper limit, B >= 0"), ("ua", "upper limit on A"), ("lb", "lower limit on B")):
        register(ExperimentPreset(_fig4_name(_r, _v), f"static 50x50 Turing, r = {_r:g}, {_what}",
                                  "leopard paper Fig. 4", _fig4(_r, _ua, _lb, _dt, _v)))


# ---- growing domains: leopard paper Fig. 5 ------------------------------------------------
def _fig5(r, ua, lb, dt, variant):
    def build(quick):
        lower = (0.0, lb) if variant == "lb" else (0.0, 0.0)
        upper = (ua, INF) if variant == "ua" else (INF, INF)
        model = Turing(ratio=r, scale=3.0, lower=lower, upper=upper)
        start, grow = ((32, 32), 16) if quick else ((50, 50), 50)
        growth = Growth(rate=0.5)
        steps = grow * int(round(1.0 / (0.5 * dt)))
        return Experiment(
            name=_fig4_name(r, variant).replace("fig4", "fig5"),
            initial=Initial("paper", start, capacity=(start[0] + grow, start[1] + grow)),
            phases=(Phase(model, steps=steps, dt=dt, growth=growth, frames=4, name="growth"),),
            description=f"Turing r={r:g}, s=3 growing {start[0]}->{start[0] + grow} at 0.5 expansions/unit time",
            figure="leopard paper Fig. 5", show="b",
        )

    return build


for _r, _ua, _lb, _dt in zip(FIG4_RATIOS, FIG4_UA, FIG4_LB, FIG4_DT):
    for _v, _what in (("std", "B >= 0"), ("ua", "upper limit on A"), ("lb", "lower limit on B")):
        _n = _fig4_name(_r, _v).replace("fig4", "fig5")
        register(ExperimentPreset(_n, f"Turing r = {_r:g} growing 50x50 -> 100x100, {_what}",
                                  "leopard paper Fig. 5", _fig5(_r, _ua, _lb, _dt, _v)))


# ---- the thesis's saturated patterns (Bard form) -----------------------------------------
@registered(ExperimentPreset, "giraffe", "Bard form, both species saturated at 6.3: reticulated giraffe patches", "thesis Fig. 7.13")
def _giraffe(quick):
    model = Bard(alpha=16.0, beta=12.0, sp=0.005, da=3 * 0.04, db=3 * 0.01, upper=(6.3, 6.3))
    shape, steps = ((48, 48), 8000) if quick else ((100, 100), 38000)
    return Experiment(
        name="giraffe", initial=Initial("thesis", shape, params=(3.0, 4.0)),
        phases=(Phase(model, steps=steps, dt=1.0, frames=4, name="static"),),
        description="thesis listing: U, V limit 6.3, conc 4 dev 3, Du 0.04, Dv 0.01, scale 0.005, 38000 steps",
        figure="thesis Fig. 7.13", show="b",
        cmap=Gradient([(0.0, "#6b3e12"), (0.35, "#8a5220"), (0.6, "#f3ead6"), (1.0, "#fbf6ea")]),
    )


@registered(ExperimentPreset, "nudibranch", "Bard form, U saturated at 5.2: labyrinth with rare stable dots", "thesis Fig. 7.15")
def _nudibranch(quick):
    model = Bard(alpha=16.0, beta=12.0, sp=0.02, da=3 * 0.08, db=3 * 0.01, upper=(5.2, INF))
    shape = (48, 48) if quick else (100, 100)
    return Experiment(
        name="nudibranch", initial=Initial("thesis", shape, params=(2.0, 4.0)),
        phases=(Phase(model, steps=1500 if quick else 3000, dt=1.0, frames=4, name="static"),),
        description="thesis listing: U limit 5.2, conc 4 dev 2, Du 0.08, Dv 0.01, scale 0.02, 3000 steps",
        figure="thesis Fig. 7.15", show="b", cmap="nudibranch",
    )


# ---- classic Gray-Scott patterns (Pearson 1993) -------------------------------------------
GRAY_SCOTT = {
    # name: (F, k, what)
    "gray-scott-mitosis": (0.0367, 0.0649, "self-replicating spots"),
    "gray-scott-coral": (0.0545, 0.062, "coral growth / labyrinth"),
    "gray-scott-worms": (0.046, 0.063, "worms"),
    "gray-scott-holes": (0.039, 0.058, "negative spots"),
}


def _gray_scott(name, F, k):
    def build(quick):
        shape, steps = ((64, 64), 3000) if quick else ((128, 128), 20000)
        return Experiment(
            name=name, initial=Initial("gray-scott", shape, params=(0.2, 0.02)),
            phases=(Phase(GrayScott(feed=F, kill=k, du=0.2097, dv=0.105), steps=steps, dt=1.0, frames=4,
                          name="static"),),
            description=f"Gray-Scott F={F}, k={k}, Du=0.2097, Dv=0.105 (Pearson's scaling), dt=1",
            figure="Pearson 1993; Lundelius notes", show="v",
        )

    return build


for _n, (_F, _k, _what) in GRAY_SCOTT.items():
    register(ExperimentPreset(_n, f"Gray-Scott, {_what}", "Pearson 1993 (classic)", _gray_scott(_n, _F, _k)))


# ---- the animals of the leopard paper (growing domains) -----------------------------------
WHIPRAY_CMAP = Gradient([(0.0, "#e9dcc0"), (0.45, "#b89b6e"), (1.0, "#2b1d10")])


def _whipray_kind(name, start, grow, dt, spots, grown, spots_steps, description, figure):
    """Spots formed on a static lattice, then grown at 2.5 expansions per unit time (Figs. 9-10)."""
    period = round(1.0 / (2.5 * dt))
    return Experiment(
        name=name, initial=Initial("paper", start),
        phases=(
            Phase(spots, steps=spots_steps, dt=dt, frames=2, name="spots"),
            Phase(grown, steps=grow * period, dt=dt, growth=Growth(2.5), frames=4, name="growth",
                  capacity=(start[0] + grow, start[1] + grow)),
        ),
        description=description, figure=figure, show="b", cmap=WHIPRAY_CMAP,
    )


@registered(ExperimentPreset, "whipray", "reticulate whipray: spots (r=30) grown at r=8 into a reticulation", "leopard paper Fig. 9")
def _whipray(quick):
    start, grow = ((50, 50), 50) if quick else ((100, 100), 100)
    return _whipray_kind(
        "whipray", start, grow, 0.004, Turing(30.0, 3.0, lower=(0.0, 2.0)), Turing(8.0, 3.0, lower=(0.0, 2.0)),
        2000 if quick else 4000,
        "static r=30 s=3 Lb=2 (4,000 steps), then r=8 growing at 2.5/unit time to 200x200 (10,000 steps)",
        "leopard paper Fig. 9")


@registered(ExperimentPreset, "honeycomb-whipray", "honeycomb whipray: spots (r=30, s=6) grown into polygons", "leopard paper Fig. 10")
def _honeycomb(quick):
    start, grow = ((50, 50), 10) if quick else ((100, 100), 20)
    return _whipray_kind(
        "honeycomb-whipray", start, grow, 0.002, Turing(30.0, 6.0, lower=(0.0, 3.0)),
        Turing(8.0, 3.0, lower=(0.0, 3.0)), 8000 if quick else 20000,
        "static r=30 s=6 Lb=3 (20,000 steps), then r=8 s=3 growing at 2.5/unit time to 120x120",
        "leopard paper Fig. 10")


@registered(ExperimentPreset, "frog", "poison dart frog: stripes on a 50x10 strip grown to 125x85 (no-flux)", "leopard paper Fig. 11")
def _frog(quick, method="division"):
    """The frog of Fig. 11; `method` other than "division" grows it by interpolating the
    whole lattice one row and column larger instead (the control of section 8.2, Fig. 22)."""
    start, grow = (50, 10), 75
    dt = 0.01
    period = 200  # 1 / (0.5 x 0.01)
    upper = (6.8, 6.2)
    steady = 2000 if quick else 4000
    if quick:
        grow = 30
    return Experiment(
        name="frog" if method == "division" else f"frog-{method}", initial=Initial("paper", start),
        phases=(
            Phase(Turing(4.5, 4.0, upper=upper), steps=steady, dt=dt, boundary="no-flux", frames=1,
                  name="stripes"),
            Phase(Turing(4.5, 2.0, upper=upper), steps=grow * period, dt=dt, boundary="no-flux",
                  growth=Growth(0.5, method=method), frames=4, name="growth", capacity=(start[0] + grow, start[1] + grow)),
        ),
        description=f"static 50x10 r=4.5 s=4 Ua=6.8 Ub=6.2 ({steady:,} steps), then s=2 growing at 0.5/unit time to "
                    f"{start[0] + grow}x{start[1] + grow}"
                    + ("" if method == "division" else f" by {method} interpolation of the whole lattice"),
        figure="leopard paper Fig. 11" if method == "division" else "leopard paper Fig. 22", show="a",
        cmap=Gradient([(0.0, "#0c0a08"), (0.45, "#1c1710"), (0.75, "#f2c20f"), (1.0, "#ffe04a")]),
    )


FROG_METHODS = ("nearest", "bilinear", "bicubic")
for _method in FROG_METHODS:
    register(ExperimentPreset(f"frog-{_method}", f"the frog of Fig. 11 grown by {_method} interpolation instead of division",
                              "leopard paper Fig. 22", lambda quick, _m=_method: _frog(quick, _m)))
register(ExperimentPreset(
    "frog-interpolation", "the frog grown by matrix expansion, then by nearest, bilinear and bicubic interpolation "
    "(the paper: without division noise no spots form)", "leopard paper Fig. 22",
    members=("frog", *(f"frog-{m}" for m in FROG_METHODS)), row_labels=("frog",),
    col_labels=("matrix expansion", *FROG_METHODS)))


@registered(ExperimentPreset, "squirrel", "thirteen-lined ground squirrel: production on a row during growth", "leopard paper Fig. 12")
def _squirrel(quick):
    start, grow = ((50, 50), 40) if quick else ((100, 100), 80)
    dt = 0.004
    period = 200  # 1 / (1.25 x 0.004)
    return Experiment(
        name="squirrel", initial=Initial("constant", start, params=(4.0, 4.0), names=("a", "b")),
        phases=(
            Phase(Turing(20.0, 4.0, upper=(7.2, 7.2)), steps=grow * period, dt=dt, boundary="no-flux",
                  growth=Growth(1.25), sources=(Source("b", 0.01, "top-row"),), frames=4, name="growth",
                  capacity=(start[0] + grow, start[1] + grow)),
        ),
        description="A = B = 4, B produced in U[0, 0.01) on the top row, r=20 s=4 Ua=Ub=7.2, growing at 1.25 to 180x180",
        figure="leopard paper Fig. 12", show="b",
        cmap=Gradient([(0.0, "#3b2514"), (0.5, "#8d6a43"), (0.8, "#e6d2a8"), (1.0, "#f6ebd2")]),
    )


def leopard_row_weights(n: int = 30) -> np.ndarray:
    """Division probability per relative row position: halved in the middle third (the
    spine), the paper's hypothesis for elongated rosettes (which rows is not stated)."""
    w = np.ones(n)
    w[n // 3 : 2 * n // 3] = 0.5
    return w


LEOPARD_DEVELOPMENT = 12000  # iterations of the paper's development phase (section 7)


@registered(ExperimentPreset, "leopard", "leopard rosettes: definition, development and maintenance phases", "leopard paper Figs. 13-17")
def _leopard(quick, development=None):
    """The leopard of Figs. 13-17; `development` shortens its development phase to that many
    of the paper's iterations (Fig. 20; the quick run scales them as its own 4,500 to 12,000)."""
    turing = Turing(40.0, 5.0, lower=(0.0, 2.0))
    reinf = Reinforcement(threshold=5.0, width=5.0, diffusion=1.0)
    dt = 0.0015
    if quick:
        # quick: random spots (12,000 steps from the usual random start) stand in for the
        # neural-crest definition phase, which needs ~200,000 steps to break its stripes
        start, n_def, n_dev, n_main = (48, 48), 12000, 90 * 50, 8 * 500
        initial = Initial("paper", start)
        sources = ()
    else:
        start, n_def, n_dev, n_main = (130, 130), 220000, LEOPARD_DEVELOPMENT, 10000
        initial = Initial("constant", start, params=(4.0, 4.0), names=("a", "b"))
        sources = (Source("b", 0.01, "center-row"),)
    if development is not None:
        n_dev = int(development) if not quick else 50 * round(development * n_dev / LEOPARD_DEVELOPMENT / 50)
    dev_size = start[0] + n_dev // 50
    final = dev_size + -(-n_main // 500)
    return Experiment(
        name="leopard" if development is None else f"leopard-development-{development}", initial=initial,
        phases=(
            Phase(turing, steps=n_def, dt=dt, boundary="no-flux", sources=sources,
                  frames=(5000, n_def // 2, n_def) if not quick else 2, name="definition"),
            Phase(Composite((turing, reinf)), steps=n_dev, dt=dt, boundary="no-flux",
                  growth=Growth(rate=1.0 / (50 * dt), row_weights=leopard_row_weights()), add_species=(("c", "b"),),
                  frames=4, name="development", capacity=(dev_size, dev_size)),
            Phase(Composite((reinf, reinf)), steps=n_main, dt=dt, boundary="no-flux", keep=("b", "c"),
                  growth=Growth(rate=1.0 / (500 * dt)), frames=2, name="maintenance", capacity=(final, final)),
        ),
        description=(("definition (quick): random start at 48x48, r=40 s=5 Lb=2, 12,000 steps; " if quick else
                      "definition: A = B = 4 at 130x130, r=40 s=5 Lb=2, B produced on the central row, 220,000 steps; ")
                     + "development: C = copy of B under reinforcement (t=5, w=5, Dc=1), growth 13.33/unit time "
                     f"(middle rows divide half as often) to {dev_size}x{dev_size} in {n_dev:,} steps; maintenance: "
                     f"B and C reinforced, growth 1.33 to {final}x{final} in {n_main:,} steps; final melanin texture "
                     "from B and C"),
        figure="leopard paper Figs. 13-17" if development is None else "leopard paper Fig. 20", show="melanin",
        cmap="leopard",
    )


LEG_DEVELOPMENT = (10000, 9000, 8000, 7000, 6000, 5000)  # Fig. 20, top to bottom
for _n in LEG_DEVELOPMENT:
    register(ExperimentPreset(f"leopard-development-{_n}", f"the leopard with its development phase cut to {_n:,} "
                              "iterations", "leopard paper Fig. 20", lambda quick, _n=_n: _leopard(quick, _n)))
register(ExperimentPreset(
    "leopard-leg", "leopard spots to rosettes: the development phase cut from 10,000 to 5,000 iterations (the leg)",
    "leopard paper Fig. 20", members=tuple(f"leopard-development-{n}" for n in LEG_DEVELOPMENT), row_labels=("",),
    col_labels=tuple(f"{n:,}" for n in LEG_DEVELOPMENT)))


def _development(quick, row):
    dt = 0.004
    start, grow = ((50, 50), 50) if quick else ((100, 100), 100)
    upper = (5.7, INF) if row == "saturated" else (INF, INF)
    pre = Turing(8.0, 10.0, upper=upper)
    grower = Bard(sp=0.0, da=0.0, db=0.0, lower=-INF) if row == "none" else pre
    frames = (1, 1 + 9 * 50, grow * 50)  # after 1, 10 and all expansions (one every 50 steps)
    return Experiment(
        name=f"development-{row}", initial=Initial("paper", start),
        phases=(
            Phase(pre, steps=3000 if quick else 5000, dt=dt, frames=(3000 if quick else 5000,), name="prepattern"),
            Phase(grower, steps=grow * 50, dt=dt, growth=Growth(5.0), frames=frames, name="growth",
                  capacity=(start[0] + grow, start[1] + grow)),
        ),
        description=f"r=8 s=10{' Ua=5.7' if row == 'saturated' else ''} prepattern, then growth at 5/unit time to "
                    f"{start[0] + grow}x{start[1] + grow} with {'no reaction nor diffusion' if row == 'none' else row + ' RD'}",
        figure="leopard paper Fig. 6", show="b",
    )


for _row in ("none", "standard", "saturated"):
    register(ExperimentPreset(f"development-{_row}", f"Fig. 6 row: growth with {_row} reaction-diffusion",
                              "leopard paper Fig. 6", lambda quick, _row=_row: _development(quick, _row)))
register(ExperimentPreset(
    "development", "pattern development during growth: no RD, standard RD, saturated RD (three rows)",
    "leopard paper Fig. 6", members=("development-none", "development-standard", "development-saturated"),
    row_labels=("none", "standard", "saturated"), snapshots=True))
FIG4_ROWS = ("B >= 0", "Ua", "Lb")  # the rows of Figs. 4 and 5: variants std, ua, lb
for _fig, _what in (("fig4", "static"), ("fig5", "growing")):
    register(ExperimentPreset(
        _fig, f"the 15 {_what} patterns of Fig. {_fig[-1]} (rows: B >= 0, Ua, Lb; columns: r)",
        f"leopard paper Fig. {_fig[-1]}",
        members=tuple(_fig4_name(r, v).replace("fig4", _fig) for v in ("std", "ua", "lb") for r in FIG4_RATIOS),
        row_labels=FIG4_ROWS, col_labels=tuple(f"r = {r:g}" for r in FIG4_RATIOS)))


@registered(ExperimentPreset, "reinforcement-growth", "reinforcement keeps a pattern's shape while the domain doubles",
           "leopard paper Fig. 8")
def _reinforcement_growth(quick):
    dt = 0.004
    start, grow = ((50, 50), 50) if quick else ((100, 100), 100)
    return Experiment(
        name="reinforcement-growth", initial=Initial("paper", start),
        phases=(
            # the prepattern of Fig. 6 (r=8, s=10): B is split about evenly around t = 5.8
            Phase(Turing(8.0, 10.0), steps=3000 if quick else 5000, dt=dt, frames=1, name="prepattern"),
            Phase(Reinforcement(threshold=5.8, width=4.0, diffusion=1.5), steps=grow * 50, dt=dt, growth=Growth(5.0),
                  add_species=(("c", "b"),), keep=("c",), frames=(1, 1 + 9 * 50, grow * 50), name="reinforcement",
                  capacity=(start[0] + grow, start[1] + grow)),
        ),
        description="C = B of the Fig. 6 prepattern (r=8, s=10), then reinforcement t=5.8 w=4 Dc=1.5, growth at 5/unit time "
                    "to 200x200 (5,000 steps)",
        figure="leopard paper Fig. 8", show="c",
    )


"""Thesis chapter 7 on cells, the figures it prints no listing for: `morphojax run
thesis-fig7.11`, `thesis-fig7.12` and `thesis-fig7.9-cells`.

Fig. 7.11, "stable spot pattern (a) perturbed by (b) reinforcement, (c) explicit
production and (d) explicit consumption". Section 7.3 says only that reinforcement rules
or "just explicit production or consumption actions" were added to a reacting Turing
pattern, that they "introduced spatial heterogeneity ... and sometimes led to chaotic
configurations", and that (d) "even got spots with oscillatory behavior"; it prints no
listing, rates or iterations. The preset builds the experiment from the thesis's own
pieces, every number chosen here:

- (a) the spots: Listing 5.1's Turing rule (alpha 16, beta 12, Dv 0.01, U and V from
  4 +- 2) with Du 0.04, the first of Fig. 5.9's rates, whose V holds "negative spots"
  (round holes of V = 0, where U is high) on an 80 x 80 square grid wrapped into a torus
  (`wrap`, as Figs. 7.13 and 7.15), at scale 0.02 (Fig. 7.15's) so that the spots have
  settled by iteration 2000. The run goes on to 4000 unperturbed.
- (b)-(d) the same run (same seed: the same spots at 2000) with rules on V added from
  iteration 2000: (b) reinforcement as in Listing A.11, V pushed up above 5 and down below
  3 (by 0.05 per iteration); (c) production, V +0.01 in every cell every iteration; (d)
  consumption, V -0.01. A constant source of 0.01 per iteration is a twenty-fourth of the
  reaction's constant removal of V (s beta = 0.24); a larger one (0.02) dissolves the
  spots of (c) into the uniform state.

The picture is V at 4000 in the four panels, on one colour scale (0 to the largest V of
the four). The summary measures what the figure shows, per panel (`spots`): the spots
(connected regions of cells with V below half its range; on the torus), their count and
the spread of their sizes (coefficient of variation: the heterogeneity), V's mean, and
how much the pattern still moves, the mean |dV| per cell over the last 500 iterations
(`moving`), the fraction of the cells that oscillate over them (`reversing`: V turning
from rising to falling or back at least twice in eleven snapshots 50 apart), and the
spots at the perturbation's start (`start`). With seed 0
(benchmarks/results/gallery_cells_measured.md): 114 spots at 2000; at 4000 (a) 114 with
sizes spread 0.19 and moving 0.002 (settled), (b) 111, 0.12 (reinforcement raises the
background to a mean V of 6.1 and evens the spots: not the heterogeneity the text
reports), (c) 111, 0.22, (d) 121, 0.16 and moving 0.023: consumption keeps the spots
changing, but by drifting and splitting; no cell oscillates in any panel (`reversing` 0,
also with consumption 0.015 and 0.02, tried). The text's oscillating spots of (d) are not
reproduced, though a sink p puts the homogeneous state past a Hopf point: it shifts beta
to beta + p / s, and Turk's reaction's trace s (u - 1 - v) turns positive at v = 3.53,
p = 0.0094 here; the spots themselves stay stationary.

`quick` runs a 30 x 30 grid, perturbed from 300 until 600 (the spots have just formed).

Fig. 7.12, "a few patterns created by adding saturation limits to one or two reagents
during reaction and diffusion": the thesis prints none of its experiments. The preset runs
one Turing rule (alpha 16, beta 12, Du 0.08, Dv 0.01, scale 0.02: Fig. 7.15's rates, from
4 +- 2) on an 80 x 80 torus of cells for 3000 iterations (Fig. 7.15's), four times: (a)
without limits, for reference; (b) U limited at 5.2 (Fig. 7.15's limit); (c) V limited at
5.2; (d) both limited at 6.3 (Fig. 7.13's). The summary (`saturation`) measures what
section 7.3 says saturation does ("when one reagent hits its upper concentration limit,
the other one is usually forced to zero ... large areas of zero concentration and others
of maximum concentration"): per panel and reagent the range, the fraction of the cells at
the limit and at 0, of the cells at a reagent's limit the fraction where the other is at
0, V's spots (`spots`) and how much V still moves over the last 500 iterations. With seed
0: V is 0 in every cell where U is at its limit, in (b) and (d), but U is never 0 where V
is at its limit (the thesis's "usually" holds for U only); V is at 0 in 61% of the cells
in (b) (24% in (a)) and at its limit in 66% in (c) and 48% in (d); (b)'s thin stripes
still move at 3000 (0.28 per cell over 500 iterations), (c) and (d) have settled (0.004,
0.014).

Fig. 7.9, eq. 7.1's cubic reaction dR/dt = s (R - a)(R - b)(R - c) + D_R lap R with
s 0.35, a 0.3, b 0.5, c 0.7: the function's plot (left) and its pattern (right), "the same
grid, initial concentrations and diffusion rate as in Figure 7.4" (the listing of section
7.2: a 100 x 100 square grid, R limit 1, conc 0.5 dev 0.5, diff 0.01, its `use seed 2`
and black-to-white colour map). The listing language has no such reaction, so the preset
places the cells from that listing (`FIG7_9_TEXT`, its rules left out) and runs
`ThesisReinforcement` on them with `simulate_cells`; the iterations are not printed, so
Fig. 7.4's 2,700 are run. The lattice preset `thesis-fig7.9` is the same run on the Moore
stencil, without the plot. The summary (`cubic`) reads the plot from the model: its roots
(where the reaction changes sign) and whether each attracts or repels; and the pattern:
the fraction of the cells near each attracting value (within 0.1 of 0, b and the limit
1) and the mean |dR| per cell over the last 100 iterations (`moving`). `quick` runs a
40 x 40 grid for 600 iterations.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

import morphojax as mj

from ..cells import save_cells, simulate_cells, write_cells_svg
from ..models import ThesisReinforcement
from ._cells import CellPreset
from ._registry import register

FIG7_11_TEXT = """define chemical V
define chemical U

// ----- prepattern

use chemical U conc 4 dev 2 diff 0.04
use chemical V conc 4 dev 2 diff 0.01
create sqr_grid {side} {side} wrap

// ----- rules

rule always react U V scale 0.02 turing alpha 16 beta 12
{perturbation}
stop at {stop}
"""
FIG7_11_SIZE = {"side": 80, "start": 2000, "stop": 4000}  # chosen: the thesis prints none
FIG7_11_QUICK = {"side": 30, "start": 300, "stop": 600}
FIG7_11_PANELS = {  # panel: (label, the rules added from `start`)
    "a": ("(a) stable spots", ()),
    "b": ("(b) reinforcement", ("if V conc > 5 change V conc +0.05", "if V conc < 3 change V conc -0.05")),
    "c": ("(c) production", ("always change V conc +0.01",)),
    "d": ("(d) consumption", ("always change V conc -0.01",)),
}
MOVING_WINDOW = 500  # iterations over which `moving` is measured


def fig7_11_text(panel: str, side: int, start: int, stop: int) -> str:
    """The listing of one panel of Fig. 7.11 (see the module's notes)."""
    _, rules = FIG7_11_PANELS[panel]
    added = "".join(f"rule from {start} {rule}\n" for rule in rules)
    return FIG7_11_TEXT.format(side=side, stop=stop,
                               perturbation=f"// {FIG7_11_PANELS[panel][0]}\n{added}" if rules else "")


def spots(cells, reagent: str = "V", reach: float = 2.5) -> dict:
    """The spots of `reagent`: the connected regions of the cells below the middle of its
    range (cells within `reach`, 1.25 spacings of the square grid, joined, across the
    torus's edges where the cells live on one), their count, the coefficient of variation of
    their sizes (cells) and the reagent's mean."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    live = cells.live()
    value = np.asarray(live["concentration"][cells.species.index(reagent)], np.float64)
    position = np.asarray(live["position"], np.float64)
    box = None
    if cells.period is not None:
        box = np.asarray(cells.period, np.float64)
        position = np.mod(position + box / 2, box)
    low = value < 0.5 * (value.min() + value.max())
    pairs = cKDTree(position, boxsize=box).query_pairs(reach, output_type="ndarray")
    both = pairs[low[pairs[:, 0]] & low[pairs[:, 1]]]
    graph = coo_matrix((np.ones(len(both)), (both[:, 0], both[:, 1])), shape=(len(value),) * 2)
    _, label = connected_components(graph, directed=False)
    sizes = np.unique(label[low], return_counts=True)[1] if low.any() else np.zeros(0)
    spread = float(sizes.std() / sizes.mean()) if len(sizes) else float("nan")
    return {"spots": len(sizes), "size_cv": round(spread, 3), "mean": round(float(value.mean()), 3)}


def reversing(series, step: float = 0.05) -> float:
    """The fraction of the cells whose value goes up and down again, or down and up again,
    at least twice along `series` (times x cells), counting only changes over `step`
    between snapshots: cells that oscillate rather than drift."""
    d = np.diff(np.asarray(series, np.float64), axis=0)
    big = np.abs(d) > step
    turns = (np.sign(d[1:]) != np.sign(d[:-1])) & big[1:] & big[:-1]
    return round(float(np.mean(turns.sum(0) >= 2)), 4)


@dataclasses.dataclass(frozen=True)
class Fig7_11Preset(CellPreset):
    """Fig. 7.11's four panels, each its own listing (`listing_of`); `load` gives panel
    (d)'s, whose cells the run saves."""

    def load(self, quick: bool = False):
        return self.listing_of("d", quick)

    def listing_of(self, panel: str, quick: bool = False):
        return mj.load_listing(fig7_11_text(panel, **(FIG7_11_QUICK if quick else FIG7_11_SIZE)),
                               name=f"fig7.11-{panel}")


def _register(cls, run, name: str, description: str, figure: str, listing: str) -> None:
    """Register a preset of class `cls` whose run is `run(preset, seed, quick, out)`."""
    def build(seed, quick, out, frames):
        return run(item, seed, quick, out)

    item = cls(name, description, figure, build, listing=listing)
    register(item)


def _run_fig7_11(item: Fig7_11Preset, seed: int, quick: bool, out: Path) -> dict:
    size = FIG7_11_QUICK if quick else FIG7_11_SIZE
    window = min(MOVING_WINDOW, (size["stop"] - size["start"]) // 2)
    late = tuple(range(size["stop"] - window, size["stop"] + 1, window // 10))  # eleven, `window` / 10 apart
    shots = (size["start"], *late)
    t0 = time.perf_counter()
    runs, measured = {}, {}
    for panel in FIG7_11_PANELS:
        listing = item.listing_of(panel, quick)
        runs[panel] = listing.snapshots(shots, seed=seed, progress=f"Fig. 7.11 ({panel})")
        series = np.array([np.asarray(c.live()["concentration"][0]) for c in runs[panel][1:]])
        measured[panel] = {**spots(runs[panel][-1]), "moving": round(float(np.abs(series[-1] - series[0]).mean()), 4),
                           "reversing": reversing(series), "start": spots(runs[panel][0])["spots"]}
    seconds = time.perf_counter() - t0
    top = max(float(np.max(r[-1].live()["concentration"][0])) for r in runs.values())
    tiles = [mj.render_cells(r[-1], "V", size=300, style="voronoi", vmin=0.0, vmax=top) for r in runs.values()]
    mj.montage(tiles, len(tiles), col_labels=[FIG7_11_PANELS[p][0] for p in runs],
               title=f"V at iteration {shots[-1]}, perturbed from {shots[0]} (one colour scale, 0 to {top:.1f})").save(out)
    final = runs["d"][-1]
    shots = (shots[0], shots[-1])  # the cells saved are (d)'s at the end
    meta = {"kind": "cells", "listing": "fig7.11-d", "text": item.load(quick).text, "dt": 1.0,
            "warnings": [], "preset": item.name, "seed": seed, "iterations": list(shots), "quick": quick}
    files = [out, save_cells(out.with_suffix(".npz"), final, meta), write_cells_svg(final, out.with_suffix(".svg"), "V")]
    return {"listing": "fig7.11-a..d", "iterations": [shots[-1]], "cells": [int(final.count)], "spots": measured,
            "seconds_run": round(seconds, 3), "files": [str(f) for f in files]}


_register(Fig7_11Preset, _run_fig7_11,
          "thesis-fig7.11", "a stable spot pattern (Listing 5.1's Turing rule, Du 0.04, on an 80x80 torus of cells) "
          "perturbed from iteration 2000 by reinforcement, production and consumption of V (the thesis prints no "
          "listing: rules and rates chosen); the spots' count, size spread and movement measured",
          "thesis Fig. 7.11 (reconstructed: no listing printed)", "fig7.11")


# ---- Fig. 7.9: eq. 7.1's cubic, its plot and its pattern --------------------------------------
FIG7_9_TEXT = """define chemical R limit 1

// ----- prepattern

use seed 2
use chemical R conc 0.5 dev 0.5 diff 0.01
create sqr_grid {side} {side}

// ----- rules (none: eq. 7.1's reaction runs beside them)

colormap select gradient
colormap slot 00 use color "black"
colormap slot 99 use color "white"
stop at {stop}
"""
FIG7_9_SIZE = {"side": 100, "stop": 2700}  # Fig. 7.4's grid and iterations
FIG7_9_QUICK = {"side": 40, "stop": 600}
FIG7_9_LATE = 100  # iterations over which `moving` is measured


def _scalar(value) -> float:
    return float(np.ravel(np.asarray(value))[0])


def cubic_roots(model: ThesisReinforcement, samples: int = 1000) -> list[dict]:
    """Where the reaction of `model` changes sign on [lower, upper] (from the midpoints of
    `samples` equal parts, so that round roots fall between them, refined by bisection),
    each with `attracts`: the reaction falls through zero there."""
    lo, hi = _scalar(model.lower), _scalar(model.upper)
    x = lo + (np.arange(samples) + 0.5) * (hi - lo) / samples
    y = np.asarray(model.reaction(x[None]))[0]
    roots = []
    for i in np.flatnonzero(np.sign(y[:-1]) * np.sign(y[1:]) < 0):
        a, b = x[i], x[i + 1]
        for _ in range(50):
            m = 0.5 * (a + b)
            if np.sign(np.asarray(model.reaction(np.array([[m]])))[0, 0]) == np.sign(y[i]):
                a = m
            else:
                b = m
        roots.append({"at": round(float(0.5 * (a + b)), 4), "attracts": bool(y[i] > 0)})
    return roots


def _plot(model: ThesisReinforcement, height: int):
    """The reaction term y = s (x - a)(x - b)(x - c) on [0, 1], its roots marked."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    x = np.linspace(0.0, 1.0, 401)
    y = np.asarray(model.reaction(x[None]))[0]
    fig, ax = plt.subplots(figsize=(4.0, 4.0), dpi=height / 4.0)
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.plot(x, y, color="black")
    for root in cubic_roots(model):
        ax.plot(root["at"], 0.0, "o", color="black", mfc="black" if root["attracts"] else "white")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(f"y = s(x - a)(x - b)(x - c), s={_scalar(model.s):g}, a={_scalar(model.a):g}, b={_scalar(model.b):g}, "
                 f"c={_scalar(model.c):g}", fontsize=7)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    buffer.seek(0)
    return Image.open(buffer).convert("RGB")


@dataclasses.dataclass(frozen=True)
class Fig7_9Preset(CellPreset):
    """Fig. 7.9 on cells: Fig. 7.4's prepattern (`load`) under eq. 7.1's reaction (`model`)."""

    model: ThesisReinforcement = dataclasses.field(default_factory=ThesisReinforcement, repr=False)

    def load(self, quick: bool = False):
        return mj.load_listing(FIG7_9_TEXT.format(**(FIG7_9_QUICK if quick else FIG7_9_SIZE)), name="fig7.9")


def _run_fig7_9(item: Fig7_9Preset, seed: int, quick: bool, out: Path) -> dict:
    import jax

    listing = item.load(quick)
    steps = listing.steps
    t0 = time.perf_counter()
    cells = listing.prepattern(jax.random.split(jax.random.key(seed))[0])  # as `Listing.snapshots` places them
    late = simulate_cells(item.model, cells, steps - FIG7_9_LATE, 1.0, progress="Fig. 7.9")
    final = simulate_cells(item.model, late, FIG7_9_LATE, 1.0)
    seconds = time.perf_counter() - t0
    r, r_late = (np.asarray(c.live()["concentration"][0], np.float64) for c in (final, late))
    roots = cubic_roots(item.model)
    near = {"0": float(np.mean(r < 0.1)), f"{_scalar(item.model.b):g}": float(np.mean(np.abs(r - _scalar(item.model.b)) < 0.1)),
            "1": float(np.mean(r > 0.9))}
    pattern = mj.render_cells(final, "R", size=400, style="voronoi", cmap=listing.colormap, vmin=0.0, vmax=1.0)
    mj.montage([_plot(item.model, pattern.height), pattern], 2,
               col_labels=["the reaction term", f"R at iteration {steps}"]).save(out)
    meta = {"kind": "cells", "listing": listing.name, "text": listing.text, "dt": 1.0, "warnings": [],
            "preset": item.name, "seed": seed, "iterations": [steps], "quick": quick,
            "model": "ThesisReinforcement(s=0.35, a=0.3, b=0.5, c=0.7)"}
    files = [out, save_cells(out.with_suffix(".npz"), final, meta),
             write_cells_svg(final, out.with_suffix(".svg"), "R", cmap=listing.colormap)]
    cubic = {"roots": roots, "near": {k: round(v, 3) for k, v in near.items()},
             "moving": round(float(np.abs(r - r_late).mean()), 5)}
    return {"listing": listing.name, "iterations": [steps], "cells": [int(final.count)], "cubic": cubic,
            "seconds_run": round(seconds, 3), "files": [str(f) for f in files]}


_register(Fig7_9Preset, _run_fig7_9,
          "thesis-fig7.9-cells", "eq. 7.1's cubic reaction (s 0.35, a 0.3, b 0.5, c 0.7): its plot, and the pattern it "
          "makes on Fig. 7.4's 100x100 grid of cells (R limit 1, conc 0.5 dev 0.5, diff 0.01; 2700 iterations, not "
          "printed)", "thesis Fig. 7.9 (plot and pattern)", "fig7.9")


# ---- Fig. 7.12: saturation limits on one reagent or both ---------------------------------------
FIG7_12_TEXT = """define chemical U{limit_u}
define chemical V{limit_v}

// ----- prepattern

use chemical U conc 4 dev 2 diff 0.08
use chemical V conc 4 dev 2 diff 0.01
create sqr_grid {side} {side} wrap

// ----- rules

rule always react U V scale 0.02 turing alpha 16 beta 12
stop at {stop}
"""
FIG7_12_PANELS = {  # panel: (label, U's limit, V's limit)
    "a": ("(a) no limit", None, None),
    "b": ("(b) U limited at 5.2", 5.2, None),
    "c": ("(c) V limited at 5.2", None, 5.2),
    "d": ("(d) U and V limited at 6.3", 6.3, 6.3),
}
FIG7_12_SIZE = {"side": 80, "stop": 3000}  # Fig. 7.15's iterations
FIG7_12_QUICK = {"side": 30, "stop": 600}


def fig7_12_text(panel: str, side: int, stop: int) -> str:
    """The listing of one panel of Fig. 7.12 (see the module's notes)."""
    _, u, v = FIG7_12_PANELS[panel]
    return FIG7_12_TEXT.format(limit_u="" if u is None else f" limit {u:g}", limit_v="" if v is None else f" limit {v:g}",
                               side=side, stop=stop)


def saturation(cells) -> dict:
    """How saturated the cells are: per reagent its range, the fraction of the cells at its
    limit (within 1e-3; None where it has none) and at 0, and `others_zero`: of its cells
    at the limit, the fraction where every other reagent is at 0 (section 7.3: "when one
    reagent hits its upper concentration limit, the other one is usually forced to zero")."""
    live = cells.live()
    values = np.asarray(live["concentration"], np.float64)
    zero = values <= 1e-3
    out = {}
    for k, (name, value, limit) in enumerate(zip(cells.species, values, np.asarray(cells.upper, np.float64))):
        at = value >= limit - 1e-3 if np.isfinite(limit) else None
        others = np.delete(zero, k, axis=0).all(axis=0)
        out[name] = {"range": [round(float(value.min()), 3), round(float(value.max()), 3)],
                     "at_limit": None if at is None else round(float(at.mean()), 3),
                     "at_zero": round(float(zero[k].mean()), 3),
                     "others_zero": round(float(others[at].mean()), 3) if at is not None and at.any() else None}
    return out


@dataclasses.dataclass(frozen=True)
class Fig7_12Preset(CellPreset):
    """Fig. 7.12's panels, each its own listing (`listing_of`); `load` gives panel (d)'s."""

    def load(self, quick: bool = False):
        return self.listing_of("d", quick)

    def listing_of(self, panel: str, quick: bool = False):
        return mj.load_listing(fig7_12_text(panel, **(FIG7_12_QUICK if quick else FIG7_12_SIZE)),
                               name=f"fig7.12-{panel}")


def _run_fig7_12(item: Fig7_12Preset, seed: int, quick: bool, out: Path) -> dict:
    stop = (FIG7_12_QUICK if quick else FIG7_12_SIZE)["stop"]
    shots = (stop - min(MOVING_WINDOW, stop // 2), stop)
    t0 = time.perf_counter()
    runs, measured = {}, {}
    for panel in FIG7_12_PANELS:
        runs[panel] = item.listing_of(panel, quick).snapshots(shots, seed=seed, progress=f"Fig. 7.12 ({panel})")
        late, end = (np.asarray(c.live()["concentration"][1]) for c in runs[panel])
        measured[panel] = {**saturation(runs[panel][-1]), "V_spots": spots(runs[panel][-1]),
                           "moving": round(float(np.abs(end - late).mean()), 4)}
    seconds = time.perf_counter() - t0
    tiles = [mj.render_cells(r[-1], "V", size=300, style="voronoi") for r in runs.values()]
    mj.montage(tiles, len(tiles), col_labels=[FIG7_12_PANELS[p][0] for p in runs],
               title=f"V at iteration {stop} (each tile from its own minimum to maximum)").save(out)
    final = runs["d"][-1]
    meta = {"kind": "cells", "listing": "fig7.12-d", "text": item.load(quick).text, "dt": 1.0,
            "warnings": [], "preset": item.name, "seed": seed, "iterations": list(shots), "quick": quick}
    files = [out, save_cells(out.with_suffix(".npz"), final, meta), write_cells_svg(final, out.with_suffix(".svg"), "V")]
    return {"listing": "fig7.12-a..d", "iterations": [stop], "cells": [int(final.count)], "saturation": measured,
            "seconds_run": round(seconds, 3), "files": [str(f) for f in files]}


_register(Fig7_12Preset, _run_fig7_12,
          "thesis-fig7.12", "saturation limits on one reagent or both (none; U at 5.2; V at 5.2; both at 6.3) on one "
          "Turing rule (Du 0.08, scale 0.02) on an 80x80 torus of cells, 3000 iterations (the thesis prints none of its "
          "experiments: chosen); the cells at each limit and at 0 measured", "thesis Fig. 7.12 (reconstructed: no "
          "experiments printed)", "fig7.12")

__all__ = ["FIG7_11_PANELS", "FIG7_12_PANELS", "Fig7_9Preset", "Fig7_11Preset", "Fig7_12Preset", "cubic_roots", "fig7_11_text", "fig7_12_text", "saturation", "spots"]

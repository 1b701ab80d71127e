"""Thesis Fig. 6.11, a pattern on a uniformly growing tissue in four transitions:
`morphojax run thesis-fig6.11-a` to `thesis-fig6.11-d`.

The thesis prints no listing for Fig. 6.11. Its caption and section 6.6 compare the uniform
growth experiments of Figs. 6.7, 6.8 and 6.10 (Listings A.9-A.11: a disc of cells,
hex_circle 45, forms Turing's pattern until iteration 2000, then each cell divides with
probability 1/10000 per iteration until 15000). Each panel here is one of those listings
drawn as a transition, before and after, at one scale so that the tissue is seen growing:

- (a) "the effect of domain growth": Listing A.9, V at 2000 and 15000. The reaction and the
  diffusion go on, so the pattern is rebuilt at its own wavelength: more stripes of the
  same width, the border's share of the cells about the same.
- (b) "cell division with inactive reaction and diffusion": Listing A.10, V at 2000 and
  15000. A.10 stops the reaction and V's diffusion at 1999; U is not drawn but still
  diffuses there, so the preset stops U's diffusion in the same iteration as well
  ("change U diff -0.15", a line the thesis does not print), as the caption says.
  Children copy their parent: the regions are kept, their borders roughened.
- (c) "the copy of concentrations to a third chemical": Listing A.11, V and R at 2000, R
  being V mapped from [1, 7] onto [0, 2] at 1999.
- (d) "keeps the overall pattern under uniform growth": Listing A.11, R at 2000 and 15000,
  under reinforcement (R pushed towards 0 and 2).

The picture of each panel is a row of two tiles; the thesis does not say which iterations
its transitions show, so the preset chooses the start and the end of growth (2000 and
15000). Each run's summary measures its transition (`transition`): the regions where the
drawn reagent is high, before and after, their border, and how well the pattern before
predicts the one after when the tissue is scaled up to the grown one (`kept`, a
correlation). With seed 0 (benchmarks/results/gallery_cells.md): 1,813 cells grow to
5,237 (a), 5,314 (b) and 5,123 (d); the high regions go from 6 to 8 (a), 47 (b, the
stripes broken into fragments) and 7 (d); their border, from 0.16 of the near pairs to
0.14 (a: rebuilt at its wavelength), 0.21 (b: roughened) and 0.08 (d: the same pattern
enlarged); `kept` is 0.12 (a), 0.71 (b) and 0.65 (d), lowered in (d) by the rim's growth.

`quick` moves the listing's events sooner (the copy at 99, growth from 100 to 400 with
probability 1/500: the tissue grows about 1.8 times), a check in seconds: the pattern has
not formed by then, so the transition shows growth and the copy of noise, not the figure.
"""

from __future__ import annotations

import dataclasses
import re
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

import morphojax as mj

from ..cells import save_cells, write_cells_svg
from ._cells import CellPreset, _at_one_scale
from ._registry import register

GROWTH = (2000, 15000)  # Listings A.9-A.11: the pattern forms until 2000, the tissue grows until 15000
QUICK_GROWTH = (100, 400)
QUICK_PROBABILITY = 0.002  # growth 1/10000 for 13,000 iterations, 1/500 for 300 in `quick`
STOP_U = "\nrule from 1999 until 1999 always change U diff -0.15 // not printed: U stops too"


def _exactly_once(text: str, old: str, new: str) -> str:
    if text.count(old) != 1:
        raise ValueError(f"the listing no longer holds {old!r} once, which the preset edits")
    return text.replace(old, new)


def _stop_u(text: str) -> str:
    """Listing A.10 with U's diffusion stopped beside V's (panel (b))."""
    line = "rule from 1999 until 1999 always change V diff -0.01 // stop diffusion"
    return _exactly_once(text, line, line + STOP_U)


def _sooner(text: str, start: int = QUICK_GROWTH[0], end: int = QUICK_GROWTH[1],
            probability: float = QUICK_PROBABILITY) -> str:
    """A listing of Figs. 6.7-6.10 with its events moved: the reaction (and the diffusion
    Listing A.10 stops) until `start - 2`, the copy and the reinforcement from `start - 1`,
    growth with `probability` from `start` until `end`, snapped at both."""
    text = _exactly_once(text, "rule from 2000 until 15000 probability 0.0001",
                         f"rule from {start} until {end} probability {probability:g}")
    text = re.sub(r"\b1999\b", str(start - 1), text)
    text = re.sub(r"\buntil 1998\b", f"until {start - 2}", text)
    return re.sub(r"snap at [\d ]+then exit", f"snap at {start} {end} then exit", text)


@dataclasses.dataclass(frozen=True)
class GrowthPreset(CellPreset):
    """A transition of Fig. 6.11: `tiles` are (moment, reagent) pairs, the moment "start"
    or "end" of growth (`GROWTH`, or `QUICK_GROWTH` when quick, the listing then edited by
    `_sooner`)."""

    tiles: tuple = ()

    def load(self, quick: bool = False):
        listing = super().load()
        if not quick:
            return listing
        return mj.load_listing(_sooner(listing.text), name=listing.name)


def _regions(position: np.ndarray, value: np.ndarray, reach: float = 2.5) -> tuple[int, float]:
    """The connected regions of the cells above the middle of `value`'s range (cells within
    `reach`, 1.25 spacings of the hexagonal packing, joined) and the border: the fraction
    of the pairs within `reach` that join a high cell to a low one."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    high = value > 0.5 * (value.min() + value.max())
    pairs = cKDTree(position).query_pairs(reach, output_type="ndarray")
    mixed = high[pairs[:, 0]] != high[pairs[:, 1]]
    pairs_high = pairs[high[pairs[:, 0]] & high[pairs[:, 1]]]
    graph = coo_matrix((np.ones(len(pairs_high)), (pairs_high[:, 0], pairs_high[:, 1])), shape=(len(value),) * 2)
    _, label = connected_components(graph, directed=False)
    return len(np.unique(label[high])), float(mixed.mean())


def transition(before, after, reagent) -> dict:
    """How a growing tissue's pattern of `reagent` changed from the cells `before` to
    `after`: the cell counts, the high regions of each and their `border` (`_regions`:
    under enlargement a kept pattern's border falls, one rebuilt at its wavelength keeps
    it, a roughened one's rises) and `kept`, the correlation between each cell's value
    before and the value after at its place scaled about the centre by the growth of the
    tissue's RMS radius (near 1: the same pattern, enlarged uniformly; growth at the rim,
    where cells have room to divide, lowers it even for a kept pattern)."""
    from scipy.spatial import cKDTree

    def arrays(cells):
        live = cells.live()
        return (np.asarray(live["position"], np.float64),
                np.asarray(live["concentration"][cells.species.index(reagent)], np.float64))

    (p0, v0), (p1, v1) = arrays(before), arrays(after)
    p0, p1 = p0 - p0.mean(0), p1 - p1.mean(0)
    scale = np.sqrt((p1 ** 2).sum(1).mean() / (p0 ** 2).sum(1).mean())
    _, nearest = cKDTree(p1).query(p0 * scale)
    kept = float(np.corrcoef(v0, v1[nearest])[0, 1]) if v0.std() > 0 and v1.std() > 0 else float("nan")
    (n0, b0), (n1, b1) = _regions(p0, v0), _regions(p1, v1)
    return {"reagent": reagent, "cells": [len(v0), len(v1)], "regions": [n0, n1],
            "border": [round(b0, 3), round(b1, 3)], "kept": round(kept, 3)}


def _run_growth(item: GrowthPreset, seed: int, quick: bool, out: Path) -> dict:
    listing = item.load(quick)
    moments = dict(zip(("start", "end"), QUICK_GROWTH if quick else GROWTH))
    shots = sorted({moments[moment] for moment, _ in item.tiles})
    t0 = time.perf_counter()
    cells = dict(zip(shots, listing.snapshots(shots, seed=seed, progress=True)))
    seconds = time.perf_counter() - t0
    drawn = [(moments[moment], reagent) for moment, reagent in item.tiles]
    shown = [cells[s] for s, _ in drawn]
    scaled = {reagent: _at_one_scale(shown, reagent, 360, item.cmap) for reagent in {r for _, r in drawn}}
    tiles = [scaled[reagent][i] for i, (_, reagent) in enumerate(drawn)]
    labels = [f"{reagent}, iteration {s}" for s, reagent in drawn]
    mj.montage(tiles, len(tiles), col_labels=labels).save(out)
    final = cells[shots[-1]]
    meta = {"kind": "cells", "listing": listing.name, "text": listing.text, "dt": listing.dt,
            "warnings": list(listing.warnings), "preset": item.name, "seed": seed, "iterations": shots,
            "quick": quick}
    files = [out, save_cells(out.with_suffix(".npz"), final, meta),
             write_cells_svg(final, out.with_suffix(".svg"), drawn[-1][1], cmap=item.cmap)]
    (s0, r0), (s1, r1) = drawn
    return {"listing": listing.name, "iterations": shots, "cells": [int(cells[s].count) for s in shots],
            "transition": transition(cells[s0], cells[s1], r1) if r0 == r1 else None,
            "seconds_run": round(seconds, 3), "files": [str(f) for f in files]}


def _growth(name: str, listing: str, figure: str, description: str, tiles, edit: Callable | None = None):
    def build(seed, quick, out, frames):
        return _run_growth(item, seed, quick, out)

    item = GrowthPreset(name, description, figure, build, listing=listing, tiles=tuple(tiles), edit=edit,
                        one_scale=True)
    register(item)


_growth("thesis-fig6.11-a", "A.9", "thesis Fig. 6.11 (a) (Listing A.9)",
        "the effect of domain growth: V before and after uniform growth with reaction and diffusion on "
        "(iterations 2000 and 15000, chosen: the thesis does not print them); the pattern is rebuilt at its "
        "wavelength", (("start", "V"), ("end", "V")))
_growth("thesis-fig6.11-b", "A.10", "thesis Fig. 6.11 (b) (Listing A.10, U stopped too)",
        "cell division with reaction and diffusion inactive: V before and after uniform growth (iterations 2000 "
        "and 15000, chosen); U's diffusion is stopped beside V's (not printed); the regions are kept, roughened",
        (("start", "V"), ("end", "V")), edit=_stop_u)
_growth("thesis-fig6.11-c", "A.11", "thesis Fig. 6.11 (c) (Listing A.11)",
        "the copy of V to a third chemical R, mapped from [1, 7] onto [0, 2] at iteration 1999: V and R at 2000",
        (("start", "V"), ("start", "R")))
_growth("thesis-fig6.11-d", "A.11", "thesis Fig. 6.11 (d) (Listing A.11)",
        "reinforcement keeps R's pattern under uniform growth: R before and after (iterations 2000 and 15000, "
        "chosen: the thesis does not print them)", (("start", "R"), ("end", "R")))

__all__ = ["GrowthPreset", "transition"]

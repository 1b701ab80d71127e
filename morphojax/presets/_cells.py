"""The thesis's cell experiments, run from its own listings (Appendix A and chapter 5):
`morphojax run thesis-fig6.3` or `PRESETS["thesis-fig7.21"].run(quick=True)`.

Each preset reads a shipped listing (`mj.load_listing`), runs it with the seed's key and
writes the PNG `out` (the cells as discs coloured by the listing's first chemical through
its colour map, as the thesis's screenshots; or the interpolated texture where the thesis
shows one; a row of snapshots where the listing snaps), `out.npz` (the final cells with
the listing's text, seed and iterations: `mj.load_cells`) and `out.svg` (the final cells).
`quick` runs fewer iterations (in seconds), the pattern not yet formed.

Where a listing is inconsistent the preset decides, and says so here:
- Listing A.17 (moray eel, Fig. 7.18) stops the gradient's diffusion with a rule
  "from 2500 until 2000", an empty window that never fires; the preset reads it as
  "from 2500 until 2500" (the one-iteration window of Listing A.10's "stop diffusion"),
  so P stops spreading at iteration 2500.
- Listing A.18 (leopard, Fig. 7.21) gives 9 of its 32 seed cells and the other 23 only in
  a comment ("omitted for brevity"); the preset restores them.
- Fig. 5.1's listing has no `stop`; the preset snaps the iterations of the figure, 0, 2,
  5, 50 and 1000.

The panels of Figs. 6.3-6.5 that the listings do not run as printed are the options the
listings hold in comments, switched on (the text replaced must occur once, or the preset
fails): Fig. 6.3 (c) makes U anisotropic ("define chemical U //anisotropic"), (d) makes V
anisotropic with Du 0.04 ("diff 0.08 // 0.04"), and (a) is (b)'s run after 1000
iterations; Fig. 6.4's rows are Listing A.6's commented snap (iterations 0 to 16,000),
isotropic and with V anisotropic; Fig. 6.5 (b) divides at "direction 10 dev 0" (the
comment of "direction 0 dev 180"), so each child is turned exactly 10 degrees from its
parent.

Listings A.5, A.7 and A.8 (Figs. 6.3, 6.5, 6.6, and their variants) grow from one cell, so that cell's random
concentrations decide the run: V = 0 is absorbing under the clamp at 0 (there dV/dt =
-12 s), and the cell of seed 0 loses V in all three (seeds 1 and 2 keep it; the gallery
uses seed 1). Every child starts as its parent was when the rules ran, one update behind
it (thesis 4.1): that small difference is what breaks the symmetry of a tissue of clones.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Callable, ClassVar

import numpy as np

import morphojax as mj
from ..cells import load_listing, save_cells, write_cells_svg
from ..cells._listing import listing_path
from ._registry import AutomatonPreset, register

FIG6_4_SERIES = (0, 4000, 8000, 12000, 16000)  # Fig. 6.4's columns (A.6's commented snap)
# Section 7.1's listing (Fig. 7.1), printed in the text, not in Appendix A: Life by slow
# diffusion. R (limit 1) is 1 on live cells; a counter C alternates 0, 1. After an iteration
# of diffusion at rate 0.01 alone (C = 0), a cell holds R_i + 0.01 sum_j (R_j - R_i) over the
# 8 cells of the square grid within the influence radius 3 (spacing 2): 0.01 n on a dead
# cell with n live neighbours, 1 - 0.01 (8 - n) on a live one. At C = 1 every cell loses 1
# and gains 2 where R shows 3 live neighbours of a dead cell (0.03) or 2 or 3 of a live one
# (0.94, 0.95), clamped to [0, 1]: one generation of B3/S23 every two iterations. A live
# cell on the grid's edge has fewer than 8 neighbours, reads more than 0.954 and dies.
FIG7_1_LISTING = """define chemical R limit 1
define chemical C

// ----- prepattern

use chemical R conc 0 diff 0.01
use chemical C conc 0 diff 0
create sqr_grid 25 25
set cell 526 chemical R conc 1
set cell 527 chemical R conc 1
set cell 528 chemical R conc 1
set cell 553 chemical R conc 1
set cell 577 chemical R conc 1

// ----- rules
// periodic counter
rule if C conc == 0 change C conc +1
rule if C conc == 1 change C conc -1
// kill all positions by default
rule if C conc == 1 change R conc -1
// a position with three neighbors becomes populated
rule if C conc == 1 and
rule if R conc in 0.025 0.034 change R conc +2
// a position with two or three neighbors survives to next generation
rule if C conc == 1 and
rule if R conc in 0.935 0.954 change R conc +2
stop at 160
"""
A18_OMITTED_SEEDS = (1005, 1015, 1025, 1035, 1045, 1410, 1420, 1430, 1440, 1805, 1815, 1825, 1835, 1845,
                     2210, 2220, 2230, 2240, 2605, 2615, 2625, 2635, 2645)


def _fix_a17_window(text: str) -> str:
    wrong = "rule from 2500 until 2000 always change P diff -0.01"
    if wrong not in text:
        raise ValueError("Listing A.17 no longer holds the rule the preset corrects")
    return text.replace(wrong, "rule from 2500 until 2500 always change P diff -0.01")


def _replace(*pairs: tuple[str, str]) -> Callable[[str], str]:
    """An edit of a listing's text that replaces each `old` (which must occur exactly once)
    by `new`: the variants a figure shows beside the published listing's own run."""

    def edit(text: str) -> str:
        for old, new in pairs:
            if text.count(old) != 1:
                raise ValueError(f"the listing no longer holds {old!r} once, which the preset edits")
            text = text.replace(old, new)
        return text

    return edit


def _add_before_rules(text: str, lines: str) -> str:
    """Prepattern lines inserted before the rules (set commands must precede them)."""
    head, marker, tail = text.partition("// ----- rules")
    if not marker:
        raise ValueError("the listing has no '// ----- rules' section")
    return head + lines + marker + tail


@dataclasses.dataclass(frozen=True)
class CellPreset(AutomatonPreset):
    """A thesis experiment on cells: `listing` (a shipped name, or the name of `text`, a
    listing printed in the thesis's text rather than its appendix), the iterations shown
    (`snapshots`, default the listing's snaps or its end), `quick` iterations, the picture
    (`texture` or discs, through `cmap` where the listing names no colour map; a series of a
    growing tissue at `one_scale`) and an `edit` of the listing's text (see the module's
    notes)."""

    kind: ClassVar[str] = "cells"
    listing: str = ""
    snapshots: tuple = ()
    quick: tuple = ()
    texture: bool = False
    edit: Callable[[str], str] | None = dataclasses.field(default=None, repr=False)
    text: str = dataclasses.field(default="", repr=False)
    cmap: str = "inferno"
    one_scale: bool = False

    def load(self):
        """The listing as this preset runs it (after its edit)."""
        if self.text:
            text, name, folder = self.text, self.listing, None
        else:
            path = listing_path(self.listing)
            text, name, folder = path.read_text(), path.stem, path.parent
        if self.edit is not None:
            text = self.edit(text)
        return load_listing(text, name=name, folder=folder)


def _run_cells(item: CellPreset, seed: int, quick: bool, out: Path, frames: bool) -> dict:
    listing = item.load()
    shots = item.quick if quick else (item.snapshots or _listing_shots(listing))
    t0 = time.perf_counter()
    cells = listing.snapshots(shots, seed=seed, progress=True)
    seconds = time.perf_counter() - t0
    files = write_outputs(listing, cells, shots, out, texture=item.texture, size=360, cmap=item.cmap,
                          one_scale=item.one_scale, metadata={"preset": item.name, "seed": seed, "iterations": list(shots), "quick": quick})
    return {"listing": listing.name, "iterations": list(shots), "cells": [int(c.count) for c in cells],
            "seconds_run": round(seconds, 3), "files": [str(f) for f in files]}


def write_outputs(listing, cells, iterations, out: Path, *, texture: bool, reagent=None, size=512,
                  metadata: dict, cmap="inferno", one_scale: bool = False) -> tuple[Path, Path, Path]:
    """A listing's run as files: the PNG `out` (the cells through the listing's colour map,
    or `cmap` where it names none, as discs of `size` pixels or the texture of its `texture
    size`; a row of them for several snapshots, each fitted to its own cells, or with
    `one_scale` all drawn at one scale in the box that holds them all), `out.npz` (the last
    cells with the listing's text and `metadata`) and `out.svg`. Shared by the presets and
    `morphojax listing`."""
    cmap = listing.colormap or cmap
    if texture and one_scale:
        raise ValueError("write_outputs: one_scale draws discs; a texture is fitted to each snapshot's cells")
    if texture:
        tiles = [mj.cells_texture(c, reagent, size=listing.texture or size, cmap=cmap, method="natural") for c in cells]
    elif one_scale:
        tiles = _at_one_scale(cells, reagent, size, cmap)
    else:
        tiles = [mj.render_cells(c, reagent, size=size, cmap=cmap) for c in cells]
    picture = tiles[0] if len(tiles) == 1 else mj.montage(tiles, len(tiles),
                                                          col_labels=[f"iteration {i}" for i in iterations])
    picture.save(out)
    final = cells[-1]
    meta = {"kind": "cells", "listing": listing.name, "text": listing.text, "dt": listing.dt,
            "warnings": list(listing.warnings), **metadata}
    npz = save_cells(out.with_suffix(".npz"), final, meta)
    svg = write_cells_svg(final, out.with_suffix(".svg"), reagent, cmap=cmap)
    return out, npz, svg


def _at_one_scale(cells, reagent, size: int, cmap) -> list:
    """Discs of every snapshot at one scale: the box holding every snapshot's cells (with
    `render_cells`' default border of one radius and one more) fills `size` pixels on its
    longer side, and each snapshot, drawn into its own box at that scale, is placed where
    its box lies in it, so a growing tissue is seen growing."""
    from PIL import Image

    pad = 2.0  # render_cells: the cell radius 1 and its default margin 1
    boxes = [(p.min(0) - pad, p.max(0) + pad) for p in (np.asarray(c.live()["position"], np.float64) for c in cells)]
    low = np.min([b[0] for b in boxes], axis=0)
    high = np.max([b[1] for b in boxes], axis=0)
    scale = size / float(np.max(high - low))
    width, height = (max(1, int(round(float(x)))) for x in (high - low) * scale)
    tiles = []
    for c, (lo, hi) in zip(cells, boxes):
        tile = mj.render_cells(c, reagent, size=tuple(max(1, int(round(float(x)))) for x in (hi - lo) * scale),
                               cmap=cmap)
        canvas = Image.new("RGB", (width, height), "black")
        canvas.paste(tile, (int(round(float(lo[0] - low[0]) * scale)), int(round(float(high[1] - hi[1]) * scale))))
        tiles.append(canvas)
    return tiles


def _listing_shots(listing) -> tuple:
    snaps = sorted({i for s in listing.snaps for i in s.iterations if i <= (listing.steps or i)})
    return tuple(snaps) if len(snaps) > 1 else (listing.steps,)


def _cells(name, listing, figure, description, *, quick, snapshots=(), texture=False, edit=None, text="",
           cmap="inferno", one_scale=False):
    def build(seed, quick_, out, frames):
        return _run_cells(item, seed, quick_, out, frames)

    item = CellPreset(name, description, figure, build, listing=listing, snapshots=tuple(snapshots),
                      quick=tuple(quick), texture=texture, edit=edit, text=text, cmap=cmap,
                      one_scale=one_scale)
    register(item)


_cells("thesis-fig5.1-cells", "fig5.1", "thesis Fig. 5.1",
       "diffusion of one cell's reagent through a permeable band of impermeable cells (15x15 grid)",
       snapshots=(0, 2, 5, 50, 1000), quick=(0, 2, 5, 50))
_cells("thesis-fig5.2-cells", "fig5.2", "thesis Fig. 5.2",
       "a stable radial gradient of R from one producer cell (31x31 grid)", quick=(400,))
_cells("thesis-fig5.14", "A.1", "thesis Fig. 5.14 (Listing A.1)",
       "radial stripes: V anisotropic, polarity from a radial gradient, hexagonal grid 100x100", quick=(300,))
_cells("thesis-fig5.15", "A.2", "thesis Fig. 5.15 (Listing A.2)",
       "concentric stripes: U anisotropic, polarity from a radial gradient, hexagonal grid 100x100", quick=(300,))
_cells("thesis-fig6.1", "A.3", "thesis Fig. 6.1 (Listing A.3)",
       "shell growth: a row of 80 cells divides at age 200, freezing its pattern", quick=(1000,))
_cells("thesis-fig6.2", "A.4", "thesis Fig. 6.2 (Listing A.4)",
       "a growing front reaching the walls of a 200x200 domain, V anisotropic", quick=(1500,))
_cells("thesis-fig6.3", "A.5", "thesis Fig. 6.3 (Listing A.5)",
       "centre growth: only the newest cell divides, 137.5 degrees on (spiral phyllotaxis)", quick=(400,))
_cells("thesis-fig6.3-closeup", "A.5", "thesis Fig. 6.3 (a) (Listing A.5)",
       "centre growth close up: (b)'s run after only 1000 iterations (501 cells)", snapshots=(1000,),
       quick=(100,))
_cells("thesis-fig6.3-anisotropic-u", "A.5", "thesis Fig. 6.3 (c) (Listing A.5, U anisotropic)",
       "centre growth with Du 0.08 and U anisotropic (the listing's commented option)", quick=(100,),
       edit=_replace(("define chemical U //anisotropic", "define chemical U anisotropic")))
_cells("thesis-fig6.3-anisotropic-v", "A.5", "thesis Fig. 6.3 (d) (Listing A.5, Du 0.04, V anisotropic)",
       "centre growth with Du 0.04 and V anisotropic (the listing's commented options)", quick=(100,),
       edit=_replace(("define chemical V //anisotropic", "define chemical V anisotropic"),
                     ("diff 0.08 // 0.04", "diff 0.04")))
_cells("thesis-fig6.4", "A.6", "thesis Fig. 6.4 (Listing A.6)",
       "growth from a fixed spine of 40 cells, division limit 8", quick=(1500,))
_cells("thesis-fig6.4-series", "A.6", "thesis Fig. 6.4, top row (Listing A.6)",
       "growth from a fixed spine, isotropic: iterations 0, 4000, 8000, 12000 and 16000 (the listing's "
       "commented snap)", snapshots=FIG6_4_SERIES, quick=(0, 200, 400), one_scale=True)
_cells("thesis-fig6.4-anisotropic", "A.6", "thesis Fig. 6.4, bottom row (Listing A.6, V anisotropic)",
       "growth from a fixed spine with V anisotropic: stripes more uniformly oriented, iterations 0 to 16000",
       snapshots=FIG6_4_SERIES, quick=(0, 200, 400), one_scale=True,
       edit=_replace(("define chemical V //anisotropic", "define chemical V anisotropic")))
_cells("thesis-fig6.5", "A.7", "thesis Fig. 6.5 (Listing A.7)",
       "growth on borders: cells with 3 or fewer neighbours divide, from one cell", quick=(1500,))
_cells("thesis-fig6.5-directed", "A.7", "thesis Fig. 6.5 (b) (Listing A.7, direction 10)",
       "growth on borders, each child exactly 10 degrees from its parent (the listing's commented option)",
       quick=(1500,), edit=_replace(("divide direction 0 dev 180 // 10 dev 0", "divide direction 10 dev 0")))
_cells("thesis-fig6.6", "A.8", "thesis Fig. 6.6 (Listing A.8)",
       "branching: cells with 2 or fewer neighbours divide, sometimes 20 degrees aside. The cell count is a "
       "wide random variable (branches stop where they meet): seeds 0-5 end with 1,115-2,068 cells after "
       "10,000 iterations, the thesis's 2,058 one draw among them (benchmarks/results/bench_cells.md)",
       quick=(1500,))
_cells("thesis-fig6.7", "A.9", "thesis Fig. 6.7 (Listing A.9)",
       "uniform growth with reaction-diffusion: the pattern adjusts, keeping its wavelength",
       quick=(0, 300))
_cells("thesis-fig6.8", "A.10", "thesis Fig. 6.8 (Listing A.10)",
       "uniform growth with frozen concentrations: duplicates roughen the pattern", quick=(0, 300))
_cells("thesis-fig6.10", "A.11", "thesis Fig. 6.10 (Listing A.11)",
       "uniform growth with reinforcement of a copied pattern R", quick=(0, 300))
_cells("thesis-fig7.1-cells", "fig7.1", "thesis Fig. 7.1 (listing of section 7.1)",
       "the Game of Life (B3/S23) by rules on a 25x25 grid of cells: a glider, 80 generations in 160 iterations",
       snapshots=(0, 160), quick=(0, 16), text=FIG7_1_LISTING, cmap="viridis")  # dead cells seen
_cells("thesis-fig7.2-cells", "A.12", "thesis Fig. 7.2 (Listing A.12)",
       "Wireworld from three reagents and a clock of three iterations", snapshots=(0, 6, 12, 18, 24, 72),
       quick=(0, 6, 12))
_cells("thesis-fig7.3-cells", "A.13", "thesis Fig. 7.3 (Listing A.13)",
       "Laplacian growth (dielectric breakdown) from a probability gradient", quick=(200,))
_cells("thesis-fig7.7-cells", "A.14", "thesis Fig. 7.7 (Listing A.14)",
       "reinforcement pattern of a Dalmatian dog", quick=(200,))
_cells("thesis-fig7.8-cells", "A.15", "thesis Fig. 7.8 (Listing A.15)",
       "reinforcement pattern of an African wild dog", quick=(200,))
_cells("thesis-fig7.16-cells", "A.16", "thesis Fig. 7.16 (Listing A.16)",
       "poison dart frog: saturated RD, half the cells anisotropic along y", quick=(300,), texture=True)
_cells("thesis-fig7.18-cells", "A.17", "thesis Fig. 7.18 (Listing A.17)",
       "moray eel: saturated RD with body parts of different U rates and a V-producing gradient",
       quick=(300,), texture=True, edit=_fix_a17_window)
_cells("thesis-fig7.13-cells", "fig7.13", "thesis Fig. 7.13 (listing of section 7.3)",
       "giraffe: saturated RD (U and V limited at 6.3) from random concentrations on a 100x100 square grid of "
       "cells wrapped into a torus (`create sqr_grid 100 100 wrap`); spots grow, absorb smaller ones and settle "
       "into reticulated patches after 38,000 iterations. The listing as printed, on cells (eight neighbours within "
       "the influence radius, harmonic-mean rates); the lattice preset `giraffe` approximates it with a stencil",
       quick=(300,))
_cells("thesis-fig7.15-cells", "fig7.15", "thesis Fig. 7.15 (listing of section 7.3)",
       "nudibranch (Hypselodoris iacula): saturated RD (U limited at 5.2, Du 0.08) on a 100x100 square grid of "
       "cells wrapped into a torus (`create sqr_grid 100 100 wrap`): a labyrinth with rare small dots that stay, "
       "after 3,000 iterations. The listing as printed, on cells; the lattice preset `nudibranch` approximates it "
       "with a stencil", quick=(300,))
_cells("thesis-fig7.20", "fig7.20", "thesis Fig. 7.20 (listing of section 7.4)",
       "uniform growth with saturated RD (U limit 6.3): the pattern is kept and evolves", quick=(0, 300))
_cells("thesis-fig7.21", "A.18", "thesis Figs. 7.21-7.22 (Listing A.18)",
       "the thesis's leopard: saturated RD on a packed, growing hexagonal tissue; rosettes from growth",
       snapshots=(4000, 8000, 11000, 14000), quick=(600,), texture=True, edit=lambda text: _add_before_rules(
           text, "".join(f"set cell {i} chemical V conc 10\n" for i in A18_OMITTED_SEEDS) + "\n"))


def cells_picture(path: Path):
    """A saved cells run (`morphojax render`): the final cells as discs."""
    cells, meta = mj.load_cells(path)
    return mj.render_cells(cells, size=512), meta


__all__ = ["CellPreset", "cells_picture", "write_outputs"]

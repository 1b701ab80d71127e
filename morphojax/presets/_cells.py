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

Listings A.5, A.7 and A.8 (Figs. 6.3, 6.5, 6.6) grow from one cell, so that cell's random
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

import morphojax as mj
from ..cells import load_listing, save_cells, write_cells_svg
from ..cells._listing import listing_path
from ._registry import AutomatonPreset, register

A18_OMITTED_SEEDS = (1005, 1015, 1025, 1035, 1045, 1410, 1420, 1430, 1440, 1805, 1815, 1825, 1835, 1845,
                     2210, 2220, 2230, 2240, 2605, 2615, 2625, 2635, 2645)


def _fix_a17_window(text: str) -> str:
    wrong = "rule from 2500 until 2000 always change P diff -0.01"
    if wrong not in text:
        raise ValueError("Listing A.17 no longer holds the rule the preset corrects")
    return text.replace(wrong, "rule from 2500 until 2500 always change P diff -0.01")


def _add_before_rules(text: str, lines: str) -> str:
    """Prepattern lines inserted before the rules (set commands must precede them)."""
    head, marker, tail = text.partition("// ----- rules")
    if not marker:
        raise ValueError("the listing has no '// ----- rules' section")
    return head + lines + marker + tail


@dataclasses.dataclass(frozen=True)
class CellPreset(AutomatonPreset):
    """A thesis experiment on cells: `listing` (a shipped name), the iterations shown
    (`snapshots`, default the listing's snaps or its end), `quick` iterations, the picture
    (`texture` or discs) and an `edit` of the listing's text (see the module's notes)."""

    kind: ClassVar[str] = "cells"
    listing: str = ""
    snapshots: tuple = ()
    quick: tuple = ()
    texture: bool = False
    edit: Callable[[str], str] | None = dataclasses.field(default=None, repr=False)

    def load(self):
        """The listing as this preset runs it (after its edit)."""
        path = listing_path(self.listing)
        text = path.read_text()
        if self.edit is not None:
            text = self.edit(text)
        return load_listing(text, name=path.stem, directory=path.parent)


def _run_cells(item: CellPreset, seed: int, quick: bool, out: Path, frames: bool) -> dict:
    listing = item.load()
    shots = item.quick if quick else (item.snapshots or _listing_shots(listing))
    t0 = time.perf_counter()
    cells = listing.snapshots(shots, seed=seed, progress=True)
    seconds = time.perf_counter() - t0
    files = write_outputs(listing, cells, shots, out, texture=item.texture, size=360,
                          metadata={"preset": item.name, "seed": seed, "iterations": list(shots), "quick": quick})
    return {"listing": listing.name, "iterations": list(shots), "cells": [int(c.count) for c in cells],
            "seconds_run": round(seconds, 3), "files": [str(f) for f in files]}


def write_outputs(listing, cells, iterations, out: Path, *, texture: bool, reagent=None, size=512,
                  metadata: dict) -> tuple[Path, Path, Path]:
    """A listing's run as files: the PNG `out` (the cells through the listing's colour map,
    as discs of `size` pixels or the texture of its `texture size`; a row of them for
    several snapshots), `out.npz` (the last cells with the listing's text and `metadata`)
    and `out.svg`. Shared by the presets and `morphojax listing`."""
    cmap = listing.colormap or "inferno"
    if texture:
        tiles = [mj.cells_texture(c, reagent, size=listing.texture or size, cmap=cmap, method="natural") for c in cells]
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


def _listing_shots(listing) -> tuple:
    snaps = sorted({i for s in listing.snaps for i in s.iterations if i <= (listing.steps or i)})
    return tuple(snaps) if len(snaps) > 1 else (listing.steps,)


def _cells(name, listing, figure, description, *, quick, snapshots=(), texture=False, edit=None):
    def build(seed, quick_, out, frames):
        return _run_cells(item, seed, quick_, out, frames)

    item = CellPreset(name, description, figure, build, listing=listing, snapshots=tuple(snapshots),
                      quick=tuple(quick), texture=texture, edit=edit)
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
_cells("thesis-fig6.4", "A.6", "thesis Fig. 6.4 (Listing A.6)",
       "growth from a fixed spine of 40 cells, division limit 8", quick=(1500,))
_cells("thesis-fig6.5", "A.7", "thesis Fig. 6.5 (Listing A.7)",
       "growth on borders: cells with 3 or fewer neighbours divide, from one cell", quick=(1500,))
_cells("thesis-fig6.6", "A.8", "thesis Fig. 6.6 (Listing A.8)",
       "branching: cells with 2 or fewer neighbours divide, sometimes 20 degrees aside", quick=(1500,))
_cells("thesis-fig6.7", "A.9", "thesis Fig. 6.7 (Listing A.9)",
       "uniform growth with reaction-diffusion: the pattern adjusts, keeping its wavelength",
       quick=(0, 300))
_cells("thesis-fig6.8", "A.10", "thesis Fig. 6.8 (Listing A.10)",
       "uniform growth with frozen concentrations: duplicates roughen the pattern", quick=(0, 300))
_cells("thesis-fig6.10", "A.11", "thesis Fig. 6.10 (Listing A.11)",
       "uniform growth with reinforcement of a copied pattern R", quick=(0, 300))
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

"""The thesis's cell figures beyond the published listings' own runs (issue 38): Fig. 6.3
(a), (c), (d), Fig. 6.4's rows as time series, Fig. 6.5 (b), and Fig. 7.1, Life on cells
by section 7.1's listing. Each variant is its listing with the commented option switched
on, checked line by line against the published text; each runs at its quick size; Life
is checked generation by generation against B3/S23 counted on the cells' neighbours."""

from __future__ import annotations

import math

import jax
import numpy as np
import pytest

import morphojax as mj
from morphojax.cells import load_listing
from morphojax.presets._cells import FIG6_4_SERIES, FIG7_1_LISTING

INFLUENCE = 3.0  # the cells' influence radius (thesis 4.2)

VARIANTS = {  # preset: (published listing, {line of the published text: the line the preset runs})
    "thesis-fig6.3-closeup": ("A.5", {}),
    "thesis-fig6.3-anisotropic-u": ("A.5", {"define chemical U //anisotropic": "define chemical U anisotropic"}),
    "thesis-fig6.3-anisotropic-v": ("A.5", {"define chemical V //anisotropic": "define chemical V anisotropic",
                                            "use chemical U conc 4 dev 2 diff 0.08 // 0.04":
                                                "use chemical U conc 4 dev 2 diff 0.04"}),
    "thesis-fig6.4-series": ("A.6", {}),
    "thesis-fig6.4-anisotropic": ("A.6", {"define chemical V //anisotropic": "define chemical V anisotropic"}),
    "thesis-fig6.5-directed": ("A.7", {"rule probability 0.004 divide direction 0 dev 180 // 10 dev 0":
                                           "rule probability 0.004 divide direction 10 dev 0"}),
}


@pytest.mark.parametrize("name", list(VARIANTS))
def test_variants_change_only_the_commented_options(name):
    listing, changed = VARIANTS[name]
    published = load_listing(listing).text.splitlines()
    ran = mj.PRESETS[name].load()
    assert ran.text.splitlines() == [changed.get(line.strip(), line) for line in published]
    assert not ran.warnings and ran.steps == load_listing(listing).steps


def test_variants_state_their_panels():
    figures = {name: mj.PRESETS[name].figure for name in VARIANTS}
    assert figures["thesis-fig6.3-closeup"].startswith("thesis Fig. 6.3 (a)")
    assert figures["thesis-fig6.3-anisotropic-u"].startswith("thesis Fig. 6.3 (c)")
    assert figures["thesis-fig6.3-anisotropic-v"].startswith("thesis Fig. 6.3 (d)")
    assert figures["thesis-fig6.5-directed"].startswith("thesis Fig. 6.5 (b)")
    assert mj.PRESETS["thesis-fig6.3-closeup"].snapshots == (1000,)
    for name in ("thesis-fig6.4-series", "thesis-fig6.4-anisotropic"):  # the figure's columns
        assert mj.PRESETS[name].snapshots == FIG6_4_SERIES == (0, 4000, 8000, 12000, 16000)
    anisotropic = {name: {c.name for c in mj.PRESETS[name].load().chemicals if c.anisotropic} for name in VARIANTS}
    assert anisotropic == {"thesis-fig6.3-closeup": set(), "thesis-fig6.3-anisotropic-u": {"U"},
                           "thesis-fig6.3-anisotropic-v": {"V"}, "thesis-fig6.4-series": set(),
                           "thesis-fig6.4-anisotropic": {"V"}, "thesis-fig6.5-directed": {"V"}}
    rates = mj.PRESETS["thesis-fig6.3-anisotropic-v"].load().prepattern(jax.random.key(1))
    assert float(np.asarray(rates.diffusion)[rates.species.index("U"), 0]) == pytest.approx(0.04)


@pytest.mark.parametrize("name", ["thesis-fig6.3-closeup", "thesis-fig6.3-anisotropic-u",
                                  "thesis-fig6.3-anisotropic-v"])
def test_centre_growth_variants_run(name, tmp_path):
    """One division every other iteration from one cell, as Fig. 6.3 (b)."""
    item = mj.PRESETS[name]
    summary = item.run(seed=1, quick=True, out=tmp_path / "p.png")
    assert summary["iterations"] == list(item.quick) and summary["cells"] == [1 + item.quick[-1] // 2]
    cells, meta = mj.load_cells(tmp_path / "p.npz")
    assert cells.ok and meta["preset"] == name and (tmp_path / "p.svg").exists()


@pytest.mark.parametrize("name", ["thesis-fig6.4-series", "thesis-fig6.4-anisotropic"])
def test_spine_series_are_rows_of_snapshots(name, tmp_path):
    item = mj.PRESETS[name]
    summary = item.run(seed=0, quick=True, out=tmp_path / "p.png")
    assert summary["iterations"] == [0, 200, 400]
    assert summary["cells"][0] == 40 and summary["cells"][0] < summary["cells"][1] < summary["cells"][2]
    one = mj.render_cells(mj.load_cells(tmp_path / "p.npz")[0], size=360)
    from PIL import Image

    row = Image.open(tmp_path / "p.png")
    assert row.width >= 3 * one.width  # three tiles side by side


def test_a_series_of_a_growing_tissue_is_drawn_at_one_scale():
    """Fig. 6.4's rows: every snapshot at the scale of the box that holds them all, placed
    where its cells lie, so a row of 3 cells keeps its size and place beside a block."""
    from morphojax.presets._cells import _at_one_scale

    row = mj.cells_at(np.array([[0.0, 0.0], [2.0, 0.0], [4.0, 0.0]]), ("R",), concentration=1.0)
    block = mj.cells_at(np.array([[x, y] for x in range(-10, 15, 2) for y in range(-6, 7, 2)], float), ("R",),
                        concentration=1.0)
    tiles = _at_one_scale([row, block], None, 280, "inferno")
    assert [t.size for t in tiles] == [(280, 160), (280, 160)]  # the union box, x -12..16, y -8..8
    scale = 280 / 28
    for tile, (x0, x1, y0, y1) in zip(tiles, [(-1, 5, -1, 1), (-11, 15, -7, 7)]):  # the discs' extents
        ys, xs = np.nonzero(np.asarray(tile).sum(2))
        assert abs(xs.min() - (x0 + 12) * scale) <= 1 and abs(xs.max() + 1 - (x1 + 12) * scale) <= 1
        assert abs(ys.min() - (8 - y1) * scale) <= 1 and abs(ys.max() + 1 - (8 - y0) * scale) <= 1
    assert all(mj.PRESETS[n].one_scale for n in ("thesis-fig6.4-series", "thesis-fig6.4-anisotropic"))


def test_directed_division_turns_every_child_ten_degrees(tmp_path):
    """Fig. 6.5 (b): the first cell's polarity is 0 and each child is turned exactly 10
    degrees from its parent, so every polarity is a multiple of 10 degrees; the random run
    (a) spreads its children over the circle."""
    summary = mj.PRESETS["thesis-fig6.5-directed"].run(seed=1, quick=True, out=tmp_path / "b.png")
    cells, _ = mj.load_cells(tmp_path / "b.npz")
    assert summary["cells"][-1] > 10
    turns = np.degrees(np.asarray(cells.live()["polarity"], np.float64)) / 10.0
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-3)
    assert len(np.unique(np.round(turns))) > 3


# ---- Fig. 7.1: Life on cells --------------------------------------------------------------
def life_on_cells(positions, alive, generations):
    """B3/S23 on the cells' neighbour lists (every other cell within the influence radius),
    with the one difference the listing's windows make: a live cell with fewer than 8
    neighbours (on the grid's edge) reads more than 0.954 and does not survive. One array
    of live cells per generation, generation 0 first."""
    d = np.linalg.norm(positions[:, None] - positions[None], axis=-1)
    neighbours = (d <= INFLUENCE) & ~np.eye(len(positions), dtype=bool)
    degree = neighbours.sum(1)
    out = [alive]
    for _ in range(generations):
        n = neighbours @ alive.astype(int)
        alive = np.where(alive, ((n == 2) | (n == 3)) & (degree == 8), n == 3)
        out.append(alive)
    return out


def test_life_listing_is_b3_s23_on_the_cells_neighbours():
    """A random soup in the middle of the 25x25 grid (the published glider replaced),
    generation by generation for 20 generations (40 iterations)."""
    rng = np.random.default_rng(71)
    rows, cols = np.nonzero(rng.random((13, 13)) < 0.4)
    soup = "".join(f"set cell {(r + 6) * 25 + c + 6} chemical R conc 1\n" for r, c in zip(rows, cols))
    head, _, rules = FIG7_1_LISTING.partition("\n// ----- rules")
    head = "\n".join(line for line in head.splitlines() if not line.startswith("set cell"))
    listing = load_listing(head + "\n" + soup + "\n// ----- rules" + rules, name="soup")
    shots = tuple(range(0, 41, 2))
    states = listing.snapshots(shots, seed=0)
    positions = np.asarray(states[0].live()["position"], np.float64)
    live = [np.asarray(s["R"]) > 0.5 for s in states]
    assert live[0].sum() == len(rows)
    expected = life_on_cells(positions, live[0], len(shots) - 1)
    for g, (got, want) in enumerate(zip(live, expected)):
        np.testing.assert_array_equal(got, want, err_msg=f"generation {g}")
        values = np.asarray(states[g]["R"])
        assert np.all((values == 0) | (values == 1)), f"generation {g} is not binary"
    assert 0 < expected[-1].sum() != expected[0].sum()  # the soup lives and changes


def test_life_preset_moves_its_glider(tmp_path):
    """Fig. 7.1: the glider slides one cell down and one right every 4 generations (8
    iterations), its shape kept; 80 generations carry it 20 cells across the grid."""
    summary = mj.PRESETS["thesis-fig7.1-cells"].run(quick=True, out=tmp_path / "life.png")
    assert summary["iterations"] == [0, 16] and summary["cells"] == [625, 625]
    listing = mj.PRESETS["thesis-fig7.1-cells"].load()
    start, end = (np.asarray(c.live()["position"])[np.asarray(c["R"]) > 0.5] for c in
                  listing.snapshots((0, 16), seed=0))
    spacing = 2.0
    shifted = start + np.array([2 * spacing, -2 * spacing])  # 4 generations each: 2 cells right and down
    assert sorted(map(tuple, np.round(end, 3))) == sorted(map(tuple, np.round(shifted, 3)))
    assert mj.PRESETS["thesis-fig7.1-cells"].snapshots == (0, 160) and listing.steps == 160
    assert math.isclose(listing.dt, 1.0)

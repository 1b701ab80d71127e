"""Thesis chapter 7's figures without a printed listing, on cells
(`morphojax/presets/_cells_chapter7.py`): Fig. 7.11's panels hold their rules from the
perturbation on, start from the same spots, and production and consumption move V the way
they are named; the spot measure counts regions across the torus's edges. Fig. 7.9's plot
is read from the model (its roots and which attract), and its cells settle at the values
that attract. Fig. 7.12's limits hold and saturate the reagents they name. Small runs
(20 x 20 cells, 200 and 600 iterations) compile the cells' step three times: tens of
seconds on a loaded 2-core machine."""

from __future__ import annotations

import jax
import numpy as np
import pytest

import morphojax as mj
from morphojax.models import ThesisReinforcement
from morphojax.presets._cells_chapter7 import (
    FIG7_9_TEXT,
    FIG7_11_PANELS,
    FIG7_12_PANELS,
    cubic_roots,
    fig7_11_text,
    fig7_12_text,
    reversing,
    saturation,
    spots,
)

SMALL = {"side": 20, "start": 100, "stop": 200}


def test_fig7_11_panels_add_their_rules_from_the_perturbation():
    item = mj.PRESETS["thesis-fig7.11"]
    assert item.kind == "cells" and item.figure.startswith("thesis Fig. 7.11")
    texts = {p: mj.load_listing(fig7_11_text(p, **SMALL)) for p in FIG7_11_PANELS}
    assert len(texts["a"].rules) == 1  # the Turing rule alone
    for panel, count in (("b", 2), ("c", 1), ("d", 1)):
        added = texts[panel].rules[1:]
        assert len(added) == count and all(rule.start == SMALL["start"] for rule in added), panel
    assert "change V conc +0.01" in texts["c"].text and "change V conc -0.01" in texts["d"].text
    assert item.load().steps == 4000 and item.load(quick=True).steps == 600


@pytest.fixture(scope="module")
def produced_and_consumed():
    """Panels (c) and (d) (one compiled step: the same rules up to the sign of an amount)."""
    shots = (SMALL["start"], SMALL["stop"])
    return {p: mj.load_listing(fig7_11_text(p, **SMALL)).snapshots(shots, seed=0) for p in "cd"}


def test_fig7_11_production_and_consumption_perturb_the_same_pattern(produced_and_consumed):
    (c0, c1), (d0, d1) = produced_and_consumed["c"], produced_and_consumed["d"]
    v = {name: np.asarray(cells.live()["concentration"][0]) for name, cells in
         (("c0", c0), ("c1", c1), ("d0", d0), ("d1", d1))}
    np.testing.assert_array_equal(v["c0"], v["d0"])  # the same run until the rules start
    assert v["c1"].mean() > v["c0"].mean() + 0.1 > v["d1"].mean() + 0.2  # V produced, V consumed
    assert spots(c1)["mean"] == pytest.approx(v["c1"].mean(), abs=1e-3)


def test_spots_are_counted_across_the_torus():
    grid = mj.cells.cell_grid((10, 10), ("V",), concentration=5.0).with_period((20.0, 20.0))
    v = np.full((10, 10), 5.0)
    v[4:6, 0] = v[4:6, 9] = 0.0  # one spot across the left and right edges
    v[1, 4:6] = 0.0  # a second, of two cells
    v[7:9, 3:7] = 0.0  # a third, of eight
    cells = grid.replace(concentration=grid.concentration.at[0, :100].set(v.ravel()))
    found = spots(cells)
    assert found["spots"] == 3
    assert found["size_cv"] == pytest.approx(np.std([4, 2, 8]) / np.mean([4, 2, 8]), abs=1e-3)


def test_reversing_counts_cells_that_oscillate_not_those_that_drift():
    t = np.arange(11)[:, None]
    series = np.hstack([np.sin(t), 0.3 * t, np.sin(t) * 0.01, np.minimum(t, 4) * 0.5])  # cells as columns
    assert reversing(series) == 0.25  # only the first: the second drifts, the third is too small, the fourth stops


def test_fig7_9_reads_the_plot_from_the_model():
    roots = cubic_roots(ThesisReinforcement())  # Fig. 7.9's s 0.35, a 0.3, b 0.5, c 0.7
    assert [r["at"] for r in roots] == pytest.approx([0.3, 0.5, 0.7], abs=1e-4)
    assert [r["attracts"] for r in roots] == [False, True, False]  # b attracts; below a falls, above c rises
    flipped = cubic_roots(ThesisReinforcement(s=-0.35, a=0.2, b=0.45, c=0.9))
    assert [r["at"] for r in flipped] == pytest.approx([0.2, 0.45, 0.9], abs=1e-4)
    assert [r["attracts"] for r in flipped] == [True, False, True]


def test_fig7_9_cells_settle_on_the_cubics_attracting_values():
    """Fig. 7.4's prepattern, 20 x 20 cells, under eq. 7.1 for 600 iterations: most cells at 0
    or at the limit 1 (diffusion alone would gather them near the mean, 0.5)."""
    listing = mj.load_listing(FIG7_9_TEXT.format(side=20, stop=600))
    assert listing.species == ("R",) and listing.chemicals[0].limit == 1.0
    cells = listing.prepattern(jax.random.key(0))
    r = np.asarray(mj.cells.simulate_cells(ThesisReinforcement(), cells, 600, 1.0).live()["concentration"][0])
    assert r.min() >= 0.0 and r.max() <= 1.0
    assert np.mean((r < 0.1) | (r > 0.9)) > 0.6 and np.mean(np.abs(r - 0.5) < 0.1) < 0.3


def test_fig7_12_limits_saturate_the_reagents_they_name():
    """The four panels on a 20 x 20 torus for 600 iterations (one compiled step: the panels
    differ only in the cells' limits): a limited reagent never passes its limit and piles up
    on it, an unlimited one has none; limiting V flattens its high regions."""
    assert mj.PRESETS["thesis-fig7.12"].load().chemicals[0].limit == 6.3
    found = {}
    for panel, (_, limit_u, limit_v) in FIG7_12_PANELS.items():
        listing = mj.load_listing(fig7_12_text(panel, side=20, stop=600))
        assert [c.limit for c in listing.chemicals] == [limit_u, limit_v]
        found[panel] = saturation(listing.run(seed=0))
        for reagent, limit in (("U", limit_u), ("V", limit_v)):
            if limit is None:
                assert found[panel][reagent]["at_limit"] is None
            else:
                assert found[panel][reagent]["range"][1] <= limit + 1e-4
                assert found[panel][reagent]["at_limit"] > 0.05, (panel, reagent)
    assert found["a"]["V"]["range"][1] > 6.3  # without limits V's spots rise past them
    assert found["c"]["V"]["at_limit"] > 0.3  # V's plateau at its limit

"""Thesis Fig. 6.11's presets (`morphojax/presets/_cells_growth.py`): each resolves, and at a
reduced size (a disc of radius 10, growth over 200 iterations) the transition each panel is
about happens: the tissue grows; with reaction and diffusion stopped children are exact
copies (b), with them on the pattern's values change (a); R is V's copy mapped onto [0, 2]
(c) and is kept as well as by exact copies while V is not (d). The two runs compile the
cells' step twice: tens of seconds on a loaded 2-core machine."""

from __future__ import annotations

import numpy as np
import pytest

import morphojax as mj
from morphojax.presets._cells_growth import QUICK_GROWTH, _sooner, transition

PANELS = {"thesis-fig6.11-a": "A09_fig6.7", "thesis-fig6.11-b": "A10_fig6.8", "thesis-fig6.11-c": "A11_fig6.10",
          "thesis-fig6.11-d": "A11_fig6.10"}
START, END = 30, 230  # the copy at 29, growth from 30 until 230


def test_each_panel_resolves_to_its_listing():
    for name, listing in PANELS.items():
        item = mj.PRESETS[name]
        assert item.kind == "cells" and item.figure.startswith(f"thesis Fig. 6.11 ({name[-1]})")
        full, quick = item.load(), item.load(quick=True)
        assert full.name == listing and full.steps == 15000 and quick.steps == QUICK_GROWTH[1]
        assert "rule from 100 until 400 probability 0.002 divide" in quick.text
    assert "change U diff -0.15" in mj.PRESETS["thesis-fig6.11-b"].load().text
    assert "change U diff" not in mj.PRESETS["thesis-fig6.11-a"].load().text


def _small(name: str):
    text = _sooner(mj.PRESETS[name].load().text, START, END, 0.003)
    return mj.load_listing(text.replace("create hex_circle 45", "create hex_circle 10"), name=name)


def _values(cells, reagent):
    return np.asarray(cells.live()["concentration"][cells.species.index(reagent)])


@pytest.fixture(scope="module")
def frozen():
    return _small("thesis-fig6.11-b").snapshots((START, END), seed=0, capacity=400)


@pytest.fixture(scope="module")
def reinforced():
    return _small("thesis-fig6.11-d").snapshots((START, END), seed=0, capacity=400)


def test_b_division_without_reaction_or_diffusion_copies_values(frozen):
    before, after = frozen
    assert int(after.count) > 1.2 * int(before.count)  # the tissue grows
    v0, v1 = _values(before, "V"), _values(after, "V")
    assert np.isin(v1, v0).all()  # every cell is an exact copy of a cell of the start


def test_a_c_d_copy_reinforce_and_react_during_growth(reinforced, frozen):
    before, after = reinforced
    assert int(after.count) > 1.2 * int(before.count)
    v0, r0 = _values(before, "V"), _values(before, "R")
    assert np.corrcoef(r0, np.clip((v0 - 1.0) / 3.0, 0.0, 2.0))[0, 1] > 0.98  # (c): R = V mapped to [0, 2]
    assert r0.min() >= 0.0 and r0.max() <= 2.0
    assert not np.isin(_values(after, "V"), v0).all()  # (a): the reaction makes new values
    # (d): R's pattern is kept as well as by exact copies (b's V, 0.82 at this size: the
    # pattern is still noise at the scale of a cell), V's is not (0.83, 0.67 with seed 0)
    copied = transition(*frozen, "V")["kept"]
    r, v = transition(before, after, "R")["kept"], transition(before, after, "V")["kept"]
    assert r > copied - 0.05 and v < copied - 0.1

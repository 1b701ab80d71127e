"""The cell simulator's presets and command line: the same seed gives the same cells
through the API and `morphojax listing`; the presets' corrections of the published
listings; files written and read back."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest

import morphojax as mj
from morphojax.cli import main
from morphojax.presets._cells import A18_OMITTED_SEEDS

SMALL = """define chemical R
define chemical P
use chemical R conc 0 diff 0.05
use chemical P conc 0 diff 0
use chemical R conc 1 dev 0.5 diff 0.05
create hex_grid 9 7 dev 0.2
set cell 31 chemical P conc 1
// ----- rules
rule if P conc == 1 change R conc 0.8
rule if P conc == 0 change R conc -0.001
rule probability 0.01 divide direction 0 dev 180
stop at 30
"""


def _same(a, b):
    assert a.count == b.count
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_same_seed_same_cells_through_api_and_cli(tmp_path, capsys):
    path = tmp_path / "small.txt"
    path.write_text(SMALL)
    out = tmp_path / "small.png"
    assert main(["listing", str(path), "--seed", "3", "--out", str(out), "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["steps"] == 30 and summary["seed"] == 3
    saved, meta = mj.load_cells(out.with_suffix(".npz"))
    api = mj.load_listing(path).run(seed=3)
    assert int(api.count) > 63, "the run should have divided"
    _same(saved, api)
    assert meta["text"] == SMALL and meta["seed"] == 3
    assert out.exists() and out.with_suffix(".svg").exists()
    # the file resumes: 10 more iterations from it equal a run of 40 bit for bit (the file
    # holds the neighbour list the run patched, and its room, and the resumed call goes on
    # from them)
    listing = mj.load_listing(SMALL)
    assert meta["neighbour_list"]["built_count"] == int(saved.count)
    more = mj.simulate_cells(None, saved.with_capacity(api.capacity), 10, listing.dt, rules=listing.rules,
                             key=jax.random.split(jax.random.key(3))[1], domain=listing.domain,
                             division_limit=listing.division_limit)
    whole = listing.run(seed=3, steps=40)
    assert int(more.step) == 40 and int(more.count) == int(whole.count) > int(saved.count)
    _same(more, whole)
    # and `morphojax render` draws it
    assert main(["render", str(out.with_suffix(".npz")), "--out", str(tmp_path / "again.png")]) == 0


def test_listing_errors_are_clear(tmp_path, capsys):
    bad = tmp_path / "bad.txt"
    bad.write_text("define chemical R\ncreate sqr_grid 3 3\nrule if Q conc == 1 change R conc 1\n")
    assert main(["listing", str(bad), "--steps", "2"]) == 2
    assert "bad:3" in capsys.readouterr().err


def test_fig5_1_preset_conserves_the_reagent(tmp_path):
    summary = mj.PRESETS["thesis-fig5.1-cells"].run(quick=True, out=tmp_path / "fig.png")
    assert summary["iterations"] == [0, 2, 5, 50]
    cells, meta = mj.load_cells(tmp_path / "fig.npz")
    assert float(np.asarray(cells["R"]).sum()) == pytest.approx(75.0, rel=1e-6)  # a closed system (thesis 5.1)
    assert meta["preset"] == "thesis-fig5.1-cells"


def test_presets_correct_the_published_listings():
    leopard = mj.PRESETS["thesis-fig7.21"].load()
    cells = leopard.prepattern(jax.random.key(0))
    seeded = np.flatnonzero(np.asarray(cells["V"]) == 10.0)
    assert len(seeded) == 32 and set(A18_OMITTED_SEEDS) <= set(seeded.tolist())
    assert int(cells.count) == 2900 and leopard.steps == 14000
    eel = mj.PRESETS["thesis-fig7.18-cells"].load()
    stops = [rule for rule in eel.rules if rule.start == 2500]
    assert len(stops) == 1 and stops[0].stop == 2500 and not eel.warnings
    assert mj.load_listing("A.17").warnings, "the published listing keeps its warning"


def test_every_cell_preset_loads_its_listing():
    cell_presets = mj.presets.of_kind("cells")
    assert len(cell_presets) >= 20
    for item in cell_presets.values():
        listing = item.load()
        assert listing.species and (listing.steps or item.snapshots), item.name


@pytest.mark.parametrize("name", ["thesis-fig6.3", "thesis-fig6.7", "thesis-fig7.16-cells"])
def test_quick_presets_write_their_files(name, tmp_path):
    """Growth from one cell, a row of snapshots, an interpolated texture."""
    item = mj.PRESETS[name]
    summary = item.run(seed=1, quick=True, out=tmp_path / "p.png")
    assert summary["iterations"] == list(item.quick)
    cells, meta = mj.load_cells(tmp_path / "p.npz")
    assert int(cells.count) == summary["cells"][-1] and meta["seed"] == 1
    assert cells.ok and (tmp_path / "p.png").exists() and (tmp_path / "p.svg").exists()
    if name == "thesis-fig6.3":  # one division every other iteration, from one cell
        assert summary["cells"] == [1 + item.quick[-1] // 2]

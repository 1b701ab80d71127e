"""Cells on a torus (`create sqr_grid COLS ROWS wrap`, thesis 4.8.3 and Figs. 7.13, 7.15):
the neighbour search against a brute force over minimum images, a periodic run against
the NumPy oracle (cells_oracle.py with `period`), exact invariants (every reagent's total
under diffusion, eight neighbours per cell of a wrapped grid, the same result for a
translated tissue), files and resumed runs that stay periodic, the listing's `wrap` read
and written back, and bad input refused by name."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cells_oracle import from_cells
from cells_oracle import neighbours as brute_neighbours
from cells_oracle import step as oracle_step

import morphojax as mj
import morphojax.cells as mc
from morphojax.cells._contacts import contacts
from morphojax.cells._neighbours import find_neighbours, needed_room, torus_buckets

BARD = mj.Bard(alpha=16.0, beta=12.0, sp=0.01)
PERIOD = (16.0, 14.0)  # an 8 x 7 square grid at spacing 2
DT = 0.5
STEPS = 4


# ---- the search ------------------------------------------------------------------------------
@pytest.mark.parametrize("period, n", [((24.0, 20.0), 90), ((7.0, 30.0), 40)],
                         ids=["buckets-both-ways", "one-bucket-across"])
def test_torus_search_equals_a_brute_force_over_minimum_images(period, n):
    rng = np.random.default_rng(5)
    xy = (rng.uniform(-0.5, 0.5, (n, 2)) * period).astype(np.float32)
    xy[:3] += np.asarray(period, np.float32)  # outside the box: the search wraps them itself
    index, overflow = find_neighbours(jnp.asarray(xy), n, 3.3, 40, 12, 400, period)
    index = np.asarray(index)
    assert not bool(overflow)
    expected = brute_neighbours(xy.astype(float), 3.3, period)
    for i in range(n):
        assert sorted(index[i][index[i] < n].tolist()) == sorted(expected[i]), i
    most = max(len(x) for x in expected)
    assert needed_room(xy, n, 3.3, 400, period)[0] == most
    assert torus_buckets(period, 3.3, 400) == ((7, 6) if period[0] == 24.0 else (1, 9))


# ---- a periodic run against the oracle ------------------------------------------------------
@pytest.fixture(scope="module")
def torus():
    """64 jittered cells of an 8 x 7 grid (56) and 8 more near the edges, on a 16 x 14
    torus: overlaps, links and collisions across every edge, polarisation, divisions."""
    key = jax.random.key(7)
    grid = mc.grid_positions((7, 8))
    edge = np.array([[7.6, 0.3], [-7.7, 1.1], [2.0, 6.8], [-3.1, -6.9], [7.8, 6.8], [-7.9, -6.8], [0.4, 6.9],
                     [7.9, -3.0]])
    jitter = np.asarray(jax.random.uniform(key, grid.shape, minval=-0.5, maxval=0.5))
    position = np.concatenate([grid + jitter, edge])
    rng = np.random.default_rng(11)
    n = len(position)
    cells = mc.make_cells(("U", "V"), position, concentration=rng.uniform(3.0, 5.0, (2, n)),
                          diffusion=np.stack([rng.uniform(0.03, 0.07, n), rng.uniform(0.005, 0.02, n)]),
                          polarity=rng.uniform(-3, 3, n), anisotropic=("V",), upper=(None, 6.0), capacity=160,
                          period=PERIOD)
    rules = (
        mc.Rule(mc.React(BARD, ("U", "V"))),
        mc.Rule(mc.Map(mc.conc("V"), 2.0, 6.0, "M", 0.0, 1.0)),
        mc.Rule(mc.Change(mc.conc("U"), mc.mapped("M")), when=mc.Compare(mc.conc("V"), ">", 4.0)),
        mc.Rule(mc.Polarize("U"), when=mc.Compare(mc.NEIGHBORS, ">=", 5)),
        mc.Rule(mc.Divide(0.7), when=(mc.Compare(mc.BIRTH, "==", 0), mc.Compare(mc.conc("U"), ">", 5.0)),
                start=1, stop=2),
    )
    one_by_one = [cells]
    for _ in range(STEPS):
        one_by_one.append(mc.simulate_cells(None, one_by_one[-1], 1, DT, rules=rules))
    return cells, rules, one_by_one


def _worst(cells, state) -> float:
    got = from_cells(cells)
    assert got["pos"].shape == state["pos"].shape
    moved = np.abs(got["pos"] - state["pos"])
    moved = np.minimum(moved, np.asarray(PERIOD) - moved)  # one cell may sit on either edge
    np.testing.assert_array_equal(got["polarised"], state["polarised"])
    np.testing.assert_array_equal(got["birth"], state["birth"])
    turn = np.abs(np.angle(np.exp(1j * (got["angle"] - state["angle"]))))
    return float(max(moved.max(), np.abs(got["conc"] - state["conc"]).max(),
                     np.abs(got["rates"] - state["rates"]).max(), turn.max()))


def test_a_periodic_run_matches_the_numpy_oracle(torus):
    cells, rules, one_by_one = torus
    state = from_cells(cells)
    start = state["pos"]
    across = sum(np.hypot(*(start[j] - start[i])) >= 3.0 for i, row in enumerate(brute_neighbours(start, 3.0, PERIOD))
                 for j in row)
    assert across > 30, "the case should link cells across the edges"
    worst = []
    for t in range(STEPS):
        state = oracle_step(state, rules, t, DT, period=PERIOD)
        worst.append(_worst(one_by_one[t + 1], state))
    print("oracle agreement per iteration (max abs difference):", worst)
    assert max(worst) < 2e-5
    final = one_by_one[-1]
    assert int(final.count) > len(start), "the case should exercise division"
    assert final.period == PERIOD and final.neighbours.period == PERIOD
    live = np.asarray(final.live()["position"])
    assert (np.abs(live) <= np.asarray(PERIOD) / 2).all(), "positions wrap into the torus"


def test_a_run_resumed_from_its_file_stays_periodic_and_equals_one_call(torus, tmp_path):
    cells, rules, _ = torus
    whole = mc.simulate_cells(None, cells, STEPS, DT, rules=rules)
    half = mc.simulate_cells(None, cells, STEPS // 2, DT, rules=rules)
    path = mj.save_cells(tmp_path / "torus.npz", half)
    back, meta = mj.load_cells(path)
    assert meta["format"] == "morphojax-cells/3" and meta["period"] == list(PERIOD)
    assert back.period == PERIOD and back.neighbours.period == PERIOD
    resumed = mc.simulate_cells(None, back, STEPS - STEPS // 2, DT, rules=rules)  # no domain: the file's torus
    assert resumed.period == PERIOD
    for name in ("position", "concentration", "diffusion", "polarity", "birth", "count"):
        np.testing.assert_array_equal(np.asarray(getattr(resumed, name)), np.asarray(getattr(whole, name)), name)
    # a /2 file (before tori) loads as cells of an open domain
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if not k.startswith("neighbour_")}
    old = json.loads(str(arrays.pop("metadata")))
    old.pop("period"), old.pop("neighbour_list")
    np.savez_compressed(tmp_path / "v2.npz", **arrays, metadata=np.asarray(json.dumps({**old, "format": "morphojax-cells/2"})))
    assert mj.load_cells(tmp_path / "v2.npz")[0].period is None
    bad = {**old, "period": [16.0, 0.0]}
    np.savez_compressed(tmp_path / "bad.npz", **arrays, metadata=np.asarray(json.dumps(bad)))
    with pytest.raises(ValueError, match=r"bad\.npz .*'period' height must lie in \(0, \+inf\)"):
        mj.load_cells(tmp_path / "bad.npz")


def test_a_translated_tissue_gives_the_translated_result(torus):
    """Periodicity: every cell moved by a fraction of the box (wrapped) ends where the
    unmoved run's cells end, moved the same way, with the same concentrations."""
    cells, rules, one_by_one = torus
    shift = np.array([0.37 * PERIOD[0], -0.61 * PERIOD[1]])
    moved = cells.replace(position=cells.position + jnp.asarray(shift, cells.position.dtype)).with_period(PERIOD)
    out, ref = mc.simulate_cells(None, moved, STEPS, DT, rules=rules), one_by_one[-1]
    assert int(out.count) == int(ref.count)
    a, b = out.live(), ref.live()
    gap = np.abs(a["position"] - b["position"] - shift)
    gap = np.abs(gap - np.asarray(PERIOD) * np.round(gap / np.asarray(PERIOD)))
    print("translation: max position gap", gap.max(), "max concentration gap",
          np.abs(a["concentration"] - b["concentration"]).max())
    assert gap.max() < 2e-5
    np.testing.assert_allclose(a["concentration"], b["concentration"], atol=1e-5)
    np.testing.assert_array_equal(a["birth"], b["birth"])


# ---- invariants ------------------------------------------------------------------------------
def test_diffusion_on_a_wrapped_grid_conserves_every_reagent_and_links_eight_neighbours():
    listing = mc.load_listing("define chemical U\ndefine chemical V\nuse chemical U conc 4 dev 3 diff 0.1 dev 0.05\n"
                              "use chemical V conc 2 dev 2 diff 0.02\ncreate sqr_grid 9 7 wrap\nstop at 40\n")
    assert listing.domain == mc.Torus(18.0, 14.0)
    cells, out = listing.snapshots((0, 40), seed=2)
    assert cells.period == (18.0, 14.0) and int(cells.count) == 63
    total = np.asarray(cells.concentration, np.float64).sum(axis=1)
    drift = np.abs(np.asarray(out.concentration, np.float64).sum(axis=1) - total) / total
    print("diffusion on the torus: relative drift of the totals", drift)
    assert (drift < 2e-6).all()
    np.testing.assert_array_equal(np.asarray(out.position), np.asarray(cells.position))  # a grid stays put
    touch = contacts(out, out.neighbours, mc.INFLUENCE_RADIUS)
    assert (np.asarray(touch.count)[:63] == 8).all(), "every cell of a wrapped square grid has eight neighbours"
    spread = np.asarray(out.concentration).std(axis=1)
    assert (spread < 0.5 * np.asarray(cells.concentration).std(axis=1)).all(), "diffusion smooths across edges"


# ---- listings ---------------------------------------------------------------------------------
def test_a_listing_with_wrap_round_trips_through_the_writer():
    text = ("define chemical U limit 6.3\nuse chemical U conc 4 dev 3 diff 0.04\n"
            "create sqr_grid 10 8 at 1 -2 dev 0.3 fixed wrap\nset cell 3 chemical U conc 1\nstop at 5\n")
    listing = mc.load_listing(text)
    written = listing.to_text()
    assert "create sqr_grid 10 8 at 1 -2 dev 0.3 fixed wrap" in written and "define domain" not in written
    again = mc.load_listing(written)
    assert again == listing and again.domain == listing.domain == mc.Torus(20.0, 16.0)
    assert again != mc.load_listing(text.replace("10 8 at", "10 9 at"))
    for name in ("fig7.13", "fig7.15"):
        shipped = mc.load_listing(name)
        assert shipped.domain == mc.Torus(200.0, 200.0) and mc.load_listing(shipped.to_text()) == shipped


# ---- bad input -----------------------------------------------------------------------------------
def test_bad_tori_are_refused_by_name(torus):
    cells, rules, _ = torus
    with pytest.raises(ValueError, match=r"Torus width must lie in \(0, \+inf\) \(got 0\)"):
        mc.Torus(0, 5)
    with pytest.raises(ValueError, match=r"Torus height must lie in \(0, \+inf\) \(got -3\)"):
        mc.Torus(5, -3)
    with pytest.raises(ValueError, match=r"period height must lie in \(0, \+inf\)"):
        mc.make_cells(("U",), [[0.0, 0.0]], period=(10.0, float("nan")))
    with pytest.raises(ValueError, match=r"period must be None or \(width, height\)"):
        mc.make_cells(("U",), [[0.0, 0.0]], period=10.0)
    with pytest.raises(ValueError, match=r"torus of 6 x 20 is too small: .* at least .*6\.6"):
        mc.simulate_cells(None, mc.make_cells(("U",), [[0.0, 0.0]]), 1, domain=mc.Torus(6, 20))
    with pytest.raises(ValueError, match=r"live on a torus of 16 x 14: domain must be None or that Torus"):
        mc.simulate_cells(None, cells, 1, DT, rules=rules, domain=(30.0, 30.0))
    with pytest.raises(ValueError, match=r"Torus\(20, 14\) is another"):
        mc.simulate_cells(None, cells, 1, DT, rules=rules, domain=mc.Torus(20, 14))

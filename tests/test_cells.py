"""The off-lattice cell simulator (thesis chapter 4) against the NumPy oracle in
cells_oracle.py, exact invariants (mass, fixed cells, division counts and angles) and
finite differences."""

from __future__ import annotations

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
import morphojax.cells as mc
from morphojax.cells._neighbours import find_neighbours

from cells_oracle import displacement, from_cells, neighbours as brute_neighbours, step as oracle_step

BARD = mj.Bard(alpha=16.0, beta=12.0, sp=0.01)


def _scattered(n=40, seed=0, spread=12.0):
    rng = np.random.default_rng(seed)
    core = rng.uniform(-spread, spread, size=(n, 2))
    far = np.array([[90.0, -40.0], [91.5, -40.5], [-70.0, 55.0]])  # far outliers widen the buckets
    return np.concatenate([core, far])


# ---- neighbours -------------------------------------------------------------------------
@pytest.mark.parametrize("table, bucket", [(4096, 16), (64, 48)])  # buckets of side 3; widened to 23
def test_neighbours_equal_a_brute_force_search(table, bucket):
    pos = _scattered()
    capacity = len(pos) + 5  # dead entries must never appear
    padded = np.concatenate([pos, np.zeros((5, 2))])
    index, overflow = find_neighbours(jnp.asarray(padded, jnp.float32), jnp.asarray(len(pos)), 3.0, 32, bucket, table)
    assert not bool(overflow)
    index = np.asarray(index)
    expected = brute_neighbours(pos, 3.0)
    for i in range(len(pos)):
        found = sorted(int(j) for j in index[i] if j < capacity)
        assert found == sorted(expected[i]), i
    assert (index[len(pos):] == capacity).all()
    _, crowded = find_neighbours(jnp.asarray(padded, jnp.float32), jnp.asarray(len(pos)), 3.0, 32, 4, 64)
    assert bool(crowded), "a bucket holding more cells than bucket_size must be reported"


def test_neighbour_overflow_is_reported_with_the_iteration():
    cells = mc.cells_at(np.zeros((1, 2)), ("U",), capacity=40)
    rules = [mc.Rule(mc.Divide(math.radians(137.5)), when=mc.Compare(mc.AGE, "==", 1))]
    with pytest.raises(mj.SimulationError, match=r"neighbour search ran out of room at iteration \d+"):
        mc.simulate_cells(None, cells, 40, rules=rules, max_neighbours=4)
    out = mc.simulate_cells(None, cells, 40, rules=rules, max_neighbours=4, throw=False)
    assert int(out.neighbour_overflow_step) > 0 and not bool(out.ok)


def test_patched_neighbour_lists_keep_their_rule():
    """Cells jostle, a few jump and some are born every iteration: the patched list holds
    exactly the pairs whose references lie within the list radius, both ways, every cell
    stays within half the skin of its reference, so every pair now within the influence
    radius is listed (checked against a brute-force search). A crowd of movers rebuilds."""
    from morphojax.cells._neighbours import Search

    rng = np.random.default_rng(0)
    capacity, count, radius, skin = 150, 90, 3.0, 0.3
    pos = np.zeros((capacity, 2), np.float32)
    pos[:count] = rng.uniform(-14.0, 14.0, (count, 2))
    search = Search(radius=radius + skin, skin=skin, max_neighbours=40, bucket_size=8, table_size=600,
                    patch_sizes=(4, 16))
    update = jax.jit(search.update)
    lists = search.build(jnp.asarray(pos), jnp.asarray(count))
    for it in range(40):
        pos[:count] += rng.normal(0.0, 0.004, (count, 2)).astype(np.float32)
        jumpers = rng.choice(count, size=40 if it == 30 else int(rng.integers(0, 12)), replace=False)
        pos[jumpers] += rng.normal(0.0, 0.4, (len(jumpers), 2)).astype(np.float32) + (0.5 if it == 30 else 0.0)
        for _ in range(int(rng.integers(0, 3))):
            pos[count] = pos[rng.integers(0, count)] + rng.normal(0.0, 0.7, 2)
            count += 1
        lists = update(lists, jnp.asarray(pos), jnp.asarray(count))
        assert not bool(lists.overflow)
        index, reference = np.asarray(lists.index), np.asarray(lists.reference)[:count]
        rows = [{int(j) for j in index[i] if j < capacity} for i in range(count)]
        listed = {(i, j) for i in range(count) for j in rows[i] if i < j}
        assert all(i in rows[j] for i in range(count) for j in rows[i]), "the list must be symmetric"
        expected = {(i, j) for i, near in enumerate(brute_neighbours(reference, radius + skin)) for j in near if i < j}
        assert listed == expected, it
        assert (np.linalg.norm(pos[:count] - reference, axis=1) <= skin / 2 + 1e-6).all()
        for i, near in enumerate(brute_neighbours(pos[:count], radius)):
            assert set(near) <= rows[i], (it, i)
        assert (index[count:] == capacity).all()
    assert 0 < int(lists.builds) < 10, "patches, and a full build for the crowd of iteration 30"


def test_uniform_draws_the_bits_of_jax_random():
    """The rules' draws (`_evaluate.uniform`, Threefry unrolled) are `jax.random.uniform`'s
    bit for bit, traced or not, in [0, 1) and [-1, 1)."""
    from morphojax.cells._evaluate import uniform

    for seed in range(3):
        key = jax.random.fold_in(jax.random.key(seed), 11)
        for n in (1, 7, 1000):
            for low, high in ((0.0, 1.0), (-1.0, 1.0)):
                want = np.asarray(jax.jit(lambda k: jax.random.uniform(k, (n,), minval=low, maxval=high))(key))
                for got in (uniform(key, n, low, high), jax.jit(lambda k: uniform(k, n, low, high))(key)):
                    assert np.array_equal(np.asarray(got).view(np.uint32), want.view(np.uint32))


def test_first_hits_are_the_first_true_columns():
    """A patch's rows (`_first_hits`: a partial sort of the blocks that hold hits, then of
    their columns): each row's first `slots` True columns in order, then the row length;
    overflow when a row has more. Long rows too, with hits in every block, exactly `slots`
    hits spread over the row, and one more."""
    from morphojax.cells._neighbours import _first_hits

    rng = np.random.default_rng(2)
    cases = ((0.01, 6, 300), (0.05, 6, 300), (0.0, 3, 300), (0.5, 6, 4), (0.003, 18, 6144), (0.01, 18, 5000),
             (0.2, 8, 1000), (0.002, 4, 4097), (1.0, 18, 2000))
    for density, slots, n in cases:
        hit = rng.random((9, n)) < density
        if n > 1000:
            hit[0] = False
            hit[0, ::32] = True  # a hit in every block
            for row, hits in ((1, slots), (2, slots + 1)):  # as many hits as slots, spread; one more
                hit[row] = False
                hit[row, rng.choice(n, hits, replace=False)] = True
        for rows in (hit, hit & (np.cumsum(hit, axis=1) <= slots)):  # with and without an overflowing row
            index, overflow = _first_hits(jnp.asarray(rows), slots)
            want = np.full((9, slots), n)
            for r, row in enumerate(rows):
                found = np.flatnonzero(row)[:slots]
                want[r, :len(found)] = found
            assert np.array_equal(np.asarray(index), want)
            assert bool(overflow) == bool((rows.sum(axis=1) > slots).any())


def test_patch_sizes_change_no_bit(monkeypatch):
    """How many branches the patch has (each sized for up to so many movers) changes only
    how much work an iteration does, not its cells: a growing run gives the same bits with
    one branch of 64 movers and with branches of 4 to 64."""
    import morphojax.cells._simulate as simulate

    cells = mc.cell_grid((10, 12), ("U", "V"), lattice="hex", concentration=(4.0, 4.0), spread=(0.0, 1.0),
                         diffusion=(0.4, 0.01), upper=(4.05, None), capacity=300, key=jax.random.key(0))
    rules = (mc.Rule(mc.React(mj.Bard(alpha=16.0, beta=12.0, sp=1.0), ("U", "V"), scale=0.1)),
             mc.Rule(mc.Divide(0.0, math.pi), when=mc.Chance(2e-3)))
    outs = []
    for sizes in ((4, 8, 16, 32, 64), (64,)):
        monkeypatch.setattr(simulate, "PATCH_SIZES", sizes)
        outs.append(mc.simulate_cells(None, cells, 400, 0.1, rules=rules, key=jax.random.key(1), domain="packed",
                                      division_limit=6))
    assert int(outs[0].count) > 130
    for field in ("position", "concentration", "polarity", "birth"):
        assert np.array_equal(np.asarray(getattr(outs[0], field)), np.asarray(getattr(outs[1], field))), field


def test_patched_lists_give_the_statistics_of_rebuilt_ones(monkeypatch):
    """Patching the neighbour list where cells moved or were born, instead of rebuilding it
    (what the simulator did before), puts the same pairs in other slots: only the order of
    float sums changes, so a growing leopard-like tissue (Listing A.18's rules, packed,
    dividing by chance) ends with the same statistics: its cell count within 1% and the
    same pattern, spot count and dark fraction."""
    import morphojax.cells._simulate as simulate

    cells = mc.cell_grid((16, 18), ("U", "V"), lattice="hex", concentration=(4.0, 4.0), spread=(0.0, 1.0),
                         diffusion=(0.4, 0.01), upper=(4.05, None), capacity=600, key=jax.random.key(0))
    rules = (mc.Rule(mc.React(mj.Bard(alpha=16.0, beta=12.0, sp=1.0), ("U", "V"), scale=0.1)),
             mc.Rule(mc.Divide(0.0, math.pi), when=mc.Chance(2e-4)))
    runs = {}
    for sizes in (simulate.PATCH_SIZES, ()):  # () rebuilds whenever a cell moved or was born
        monkeypatch.setattr(simulate, "PATCH_SIZES", sizes)
        out = mc.simulate_cells(None, cells, 3000, 0.1, rules=rules, key=jax.random.key(1), domain="packed",
                                division_limit=6)
        runs[sizes] = (int(out.count), mj.describe(mc.cells_field(out, "V", size=96), wrap=False))
    (patched, a), (rebuilt, b) = runs.values()
    assert patched > 400 and abs(patched - rebuilt) <= 0.01 * rebuilt
    assert a.pattern == b.pattern == "spots"
    assert abs(a.spots - b.spots) <= 0.15 * b.spots and abs(a.dark_fraction - b.dark_fraction) < 0.05


# ---- one iteration against the oracle -------------------------------------------------------
@pytest.fixture(scope="module")
def mixed():
    key = jax.random.key(3)
    cells = mc.cell_grid((5, 6), ("U", "V"), lattice="hex", jitter=0.45, concentration=(4.0, 4.0), spread=(1.0, 1.0),
                         diffusion=(0.05, 0.02), diffusion_spread=(0.02, 0.01), polarity=0.3, polarity_spread=3.0,
                         anisotropic=("V",), upper=(None, 6.0), capacity=48, key=key)
    rules = (
        mc.Rule(mc.React(BARD, ("U", "V"))),
        mc.Rule(mc.Map(mc.conc("V"), 2.0, 6.0, "M", 0.0, 1.0)),
        mc.Rule(mc.Change(mc.conc("U"), mc.mapped("M")), when=mc.Compare(mc.conc("V"), ">", 4.0)),
        mc.Rule(mc.Change(mc.diff("V"), -0.001), when=mc.Within(mc.AGE, 0, 2)),
        mc.Rule(mc.Polarize("U"), when=mc.Compare(mc.NEIGHBORS, ">=", 5)),
        mc.Rule(mc.Divide(0.7), when=(mc.Compare(mc.BIRTH, "==", 0), mc.Compare(mc.conc("U"), ">", 4.3)),
                start=1, stop=2),
    )
    return cells, rules


def _compare(cells, state, rtol=2e-4, atol=2e-4):
    got = from_cells(cells)
    assert got["pos"].shape == state["pos"].shape
    np.testing.assert_allclose(got["pos"], state["pos"], rtol=rtol, atol=atol)
    np.testing.assert_allclose(got["conc"], state["conc"], rtol=rtol, atol=atol)
    np.testing.assert_allclose(got["rates"], state["rates"], rtol=rtol, atol=atol)
    np.testing.assert_array_equal(got["polarised"], state["polarised"])
    turn = np.angle(np.exp(1j * (got["angle"] - state["angle"])))
    np.testing.assert_allclose(turn, 0.0, atol=1e-4)
    np.testing.assert_array_equal(got["birth"], state["birth"])


def test_iterations_match_the_numpy_oracle(mixed):
    cells, rules = mixed
    state = from_cells(cells)
    dt = 0.5
    for t in range(4):
        cells = mc.simulate_cells(None, cells, 1, dt, rules=rules, domain=(24.0, 24.0), division_limit=5)
        state = oracle_step(state, rules, t, dt, division_limit=5, box=(24.0, 24.0))
        _compare(cells, state)
    assert int(cells.count) > 30, "the case should exercise division"
    assert int(cells.step) == 4


def _identical(a, b):
    """The same cells bit for bit: counts, positions, every species, every buffer, status."""
    assert int(a.count) == int(b.count) and int(a.step) == int(b.step)
    n = int(a.count) if a.capacity != b.capacity else a.capacity  # buffers of other sizes: the live cells
    np.testing.assert_array_equal(np.asarray(a.position)[:n], np.asarray(b.position)[:n], "position")
    for name in a.species:
        np.testing.assert_array_equal(np.asarray(a[name])[:n], np.asarray(b[name])[:n], name)
    for name in ("polarity", "polarised", "birth", "fixed"):
        np.testing.assert_array_equal(np.asarray(getattr(a, name))[:n], np.asarray(getattr(b, name))[:n], name)
    np.testing.assert_array_equal(np.asarray(a.diffusion)[:, :n], np.asarray(b.diffusion)[:, :n], "diffusion")
    for name in ("overflow_step", "neighbour_overflow_step", "nonfinite_step"):
        assert int(getattr(a, name)) == int(getattr(b, name)), name


def test_one_call_equals_resumed_calls(mixed, tmp_path):
    """The cells carry the neighbour list their run patched, and a resumed call goes on
    from it (from the cells, or from their file), so resumed calls give the cells of one
    call bit for bit, not merely up to the order of float sums."""
    cells, rules = mixed
    settings = dict(rules=rules, domain=(24.0, 24.0), division_limit=5)
    whole = mc.simulate_cells(None, cells, 4, 0.5, **settings)
    parts = cells
    for _ in range(2):
        parts = mc.simulate_cells(None, parts, 2, 0.5, **settings)
    assert int(whole.count) > int(cells.count), "the case should divide, so the list is patched"
    _identical(whole, parts)
    # through a file: the list is saved with the cells and read back
    half = mc.simulate_cells(None, cells, 2, 0.5, **settings)
    back, _ = mj.load_cells(mj.save_cells(tmp_path / "half.npz", half))
    for x, y in zip(jax.tree_util.tree_leaves(half), jax.tree_util.tree_leaves(back)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    _identical(whole, mc.simulate_cells(None, back, 2, 0.5, **settings))
    # in larger buffers the list goes on too
    _identical(whole, mc.simulate_cells(None, half.with_capacity(60), 2, 0.5, **settings))


def test_a_growing_run_resumed_many_times_equals_one_call():
    """A packed tissue growing by chance (divisions and the pushes they cause patch the
    list every few iterations): ten calls of 30 iterations give the cells of one call of
    300, bit for bit."""
    cells = mc.cell_grid((12, 12), ("U", "V"), lattice="hex", concentration=(4.0, 4.0), spread=(0.0, 1.0),
                         diffusion=(0.4, 0.01), upper=(4.05, None), capacity=400, key=jax.random.key(0))
    rules = (mc.Rule(mc.React(mj.Bard(alpha=16.0, beta=12.0, sp=1.0), ("U", "V"), scale=0.1)),
             mc.Rule(mc.Divide(0.0, math.pi), when=mc.Chance(2e-3)))
    settings = dict(rules=rules, key=jax.random.key(1), domain="packed", division_limit=6)
    whole = mc.simulate_cells(None, cells, 300, 0.1, **settings)
    parts = cells
    for _ in range(10):
        parts = mc.simulate_cells(None, parts, 30, 0.1, **settings)
    assert int(whole.count) > int(cells.count) + 20
    _identical(whole, parts)


def test_calls_of_one_iteration_equal_one_call():
    """Pieces of any length, 1 included, give the cells of one call bit for bit: a
    progress bar over fewer than 100 iterations runs pieces of 1, and a scan of length 1
    compiled alone fuses its iteration differently (an ulp in a few positions and
    concentrations)."""
    cells = mc.cell_grid((10, 10), ("U", "V"), lattice="hex", jitter=0.45, concentration=(4.0, 4.0),
                         spread=(1.0, 1.0), diffusion=(0.05, 0.02), diffusion_spread=(0.02, 0.01), polarity=0.3,
                         polarity_spread=3.0, anisotropic=("V",), upper=(None, 6.0), capacity=160,
                         key=jax.random.key(3))
    rules = (mc.Rule(mc.React(BARD, ("U", "V"))), mc.Rule(mc.Polarize("U"), when=mc.Compare(mc.NEIGHBORS, ">=", 5)),
             mc.Rule(mc.Divide(0.7), when=(mc.Compare(mc.BIRTH, "==", 0), mc.Compare(mc.conc("U"), ">", 4.3)),
                     start=1, stop=2))
    settings = {"rules": rules, "division_limit": 5}
    whole = mc.simulate_cells(None, cells, 6, 0.5, **settings)
    assert int(whole.count) > int(cells.count), "the case should divide and push"
    _identical(whole, mc.simulate_cells(None, mc.simulate_cells(None, cells, 1, 0.5, **settings), 5, 0.5, **settings))
    one_by_one = cells
    for _ in range(6):
        one_by_one = mc.simulate_cells(None, one_by_one, 1, 0.5, **settings)
    _identical(whole, one_by_one)
    _identical(whole, mc.simulate_cells(None, cells, 6, 0.5, progress="test", **settings))  # pieces of 1


def test_cells_files_without_a_neighbour_list_still_load_and_resume(mixed, tmp_path):
    """A file written before the list was saved (no list entries) loads, and a run resumed
    from it builds its list afresh; a file with half a list is refused, naming it."""
    cells, rules = mixed
    half = mc.simulate_cells(None, cells, 2, 0.5, rules=rules, domain=(24.0, 24.0), division_limit=5)
    path = mj.save_cells(tmp_path / "half.npz", half)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays["metadata"]))
    assert meta["neighbour_list"]["built_count"] == int(half.count)
    assert meta["format"] == "morphojax-cells/3"  # with a list: a reader of /1 only refuses it by its format
    assert meta["period"] is None and meta["neighbour_list"]["period"] is None  # an open domain
    old = {k: v for k, v in arrays.items() if not k.startswith("neighbour_")}
    meta.pop("neighbour_list")
    np.savez_compressed(tmp_path / "future.npz", **{**old, "metadata": np.asarray(json.dumps(
        {**meta, "format": "morphojax-cells/9"}))})
    with pytest.raises(ValueError, match=r"future\.npz.*'morphojax-cells/9'"):
        mj.load_cells(tmp_path / "future.npz")
    meta["format"] = "morphojax-cells/1"
    np.savez_compressed(tmp_path / "old.npz", **{**old, "metadata": np.asarray(json.dumps(meta))})
    back, _ = mj.load_cells(tmp_path / "old.npz")
    assert back.neighbours is None
    np.testing.assert_array_equal(np.asarray(back.position), np.asarray(half.position))
    more = mc.simulate_cells(None, back, 2, 0.5, rules=rules, domain=(24.0, 24.0), division_limit=5)
    assert more.neighbours is not None and int(more.step) == 4
    np.savez_compressed(tmp_path / "bad.npz", **{**old, "neighbour_index": arrays["neighbour_index"]})
    with pytest.raises(ValueError, match=r"bad\.npz .*neighbour list needs"):
        mj.load_cells(tmp_path / "bad.npz")
    wrong = arrays["neighbour_index"].copy()
    wrong[0, 0] = int(half.count)
    np.savez_compressed(tmp_path / "bad.npz", **{**arrays, "neighbour_index": wrong})
    with pytest.raises(ValueError, match=r"bad\.npz .*not live"):
        mj.load_cells(tmp_path / "bad.npz")


# ---- invariants -----------------------------------------------------------------------------
@pytest.mark.parametrize("anisotropic", [(), ("R",)])
def test_diffusion_conserves_every_reagent(anisotropic):
    key = jax.random.key(7)
    cells = mc.cell_grid((9, 11), ("R", "S"), lattice="hex", jitter=0.3, concentration=(5.0, 1.0), spread=(4.0, 1.0),
                         diffusion=(0.1, 0.05), diffusion_spread=(0.09, 0.04), polarity=0.0, polarity_spread=3.1,
                         anisotropic=anisotropic, key=key)
    before = np.asarray(cells.concentration, np.float64).sum(axis=1)
    out = mc.simulate_cells(None, cells, 60, 0.5)
    after = np.asarray(out.concentration, np.float64).sum(axis=1)
    np.testing.assert_allclose(after, before, rtol=2e-6)
    assert np.asarray(out.concentration).std(axis=1)[0] < np.asarray(cells.concentration).std(axis=1)[0]


def test_anisotropic_diffusion_follows_the_polarity():
    """Eq. 4.8 on a square grid polarised along x: per unit time a cell's second moments
    grow by sum_j w_j dx_j^2 (an exact identity of the linear exchange while no mass has
    reached the border): w = D for the two neighbours along x, D / sqrt 2 for the four
    diagonals, 0 for the two along y, and dx^2 = 4 (cells 2 apart)."""
    D, steps = 0.1, 6
    cells = mc.cell_grid((15, 15), ("R",), diffusion=D, polarity=0.0, anisotropic=("R",))
    cells = cells.replace(concentration=cells.concentration.at[0, 7 * 15 + 7].set(1.0))
    out = mc.simulate_cells(None, cells, steps, 1.0)
    r, xy = np.asarray(out["R"], np.float64), np.asarray(out.position, np.float64)
    var_x, var_y = (r * xy[:, 0] ** 2).sum(), (r * xy[:, 1] ** 2).sum()
    diagonal = 4 * (D / math.sqrt(2)) * 4
    assert var_x == pytest.approx(steps * (2 * D * 4 + diagonal), rel=1e-4)
    assert var_y == pytest.approx(steps * diagonal, rel=1e-4)


def test_collisions_relax_overlaps_and_spare_fixed_cells():
    rng = np.random.default_rng(1)
    pos = rng.uniform(-4.0, 4.0, size=(30, 2))
    fixed = np.zeros(30, bool)
    fixed[:3] = True
    cells = mc.make_cells(("R",), pos, fixed=fixed)
    out = mc.simulate_cells(None, cells, 300)
    moved = out.live()["position"]
    np.testing.assert_array_equal(moved[:3], np.asarray(cells.position)[:3])
    gaps = np.linalg.norm(moved[:, None] - moved[None], axis=-1)
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() > 2.0 - 0.05
    assert not np.allclose(moved[3:], np.asarray(cells.position)[3:])


@pytest.mark.parametrize("period", [None, (16.0, 14.0)])
def test_contacts_carry_the_collisions_sums_of_eq_4_9(period):
    """The collisions' sums are made with the contacts (`Contacts.push`): per cell
    sum_j (0.25 - 0.5 / |d_j|) d_j over the cells at 0 < |d_j| < 2 (minimum images on a
    torus), against a sum over every pair; a coincident pair pushes neither cell but counts
    as overlapping; a square grid of spacing 2 (touching, not overlapping) does not."""
    from morphojax.cells._contacts import contacts
    from morphojax.cells._neighbours import Search

    rng = np.random.default_rng(4)
    pos = rng.uniform(-6.5, 6.5, size=(40, 2))
    pos[7] = pos[3]  # coincident
    cells = mc.make_cells(("R",), pos).with_capacity(48)
    search = Search(radius=3.3, skin=0.3, max_neighbours=40, bucket_size=40, table_size=256, period=period)
    touch = contacts(cells, search.build(cells.position, cells.count), 3.0)
    want = np.zeros((40, 2))
    for i in range(40):
        for j in range(40):
            d = displacement(pos, i, j, period)
            gap = np.hypot(*d)
            if i != j and 0 < gap < 2:
                want[i] += (0.25 - 0.5 / gap) * d
    np.testing.assert_allclose(np.asarray(touch.push)[:40], want, atol=1e-5)
    np.testing.assert_array_equal(np.asarray(touch.push)[40:], 0.0)
    assert np.abs(want).max() > 0.1 and bool(touch.overlapping)
    apart = mc.make_cells(("R",), pos[[3, 7]] + [[0.0, 0.0], [0.0, 0.0]])  # only the coincident pair
    touch = contacts(apart, search.build(apart.position, apart.count), 3.0)
    assert bool(touch.overlapping) and np.abs(np.asarray(touch.push)).max() == 0.0
    grid = mc.cell_grid((6, 5), ("R",))
    touch = contacts(grid, search.build(grid.position, grid.count), 3.0)
    assert not bool(touch.overlapping) and np.abs(np.asarray(touch.push)).max() == 0.0


def test_packed_domain_holds_cells_inside_its_square():
    """A packed square of area 1 per cell is tighter than the disc of cells: after the
    tissue doubles, cells sit on its walls (at half its side, sqrt(count) / 2) and none
    beyond; with the default 3.2 per cell the same tissue is not pressed."""
    cells = mc.cell_disc(9.0, ("R",), lattice="hex", capacity=200)
    rules = [mc.Rule(mc.Divide(0.0), when=mc.Compare(mc.AGE, "==", 0), start=0, stop=0)]
    out = mc.simulate_cells(None, cells, 10, rules=rules, domain=mc.Packed(1.0), max_neighbours=64, bucket_size=32)
    assert int(out.count) == 2 * int(cells.count)
    half = math.sqrt(int(out.count)) / 2
    assert np.abs(out.live()["position"]).max() == pytest.approx(half, abs=1e-4)
    loose = mc.simulate_cells(None, cells, 10, rules=rules, domain="packed")
    assert np.abs(loose.live()["position"]).max() < math.sqrt(mc.PACKING_AREA * int(loose.count)) / 2 - 0.5


# ---- division ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def phyllotaxis():
    """Listing A.5's growth: only a cell of age 1 divides, at 137.5 degrees (Fig. 6.3)."""
    cells = mc.cells_at(np.zeros((1, 2)), ("U",), polarity=0.0, capacity=64)
    rules = (mc.Rule(mc.Divide(math.radians(137.5)), when=mc.Compare(mc.AGE, "==", 1)),)
    return cells, rules


def test_division_counts_and_angles_follow_the_rule(phyllotaxis):
    cells, rules = phyllotaxis
    two = mc.simulate_cells(None, cells, 2, rules=rules)
    assert int(two.count) == 2
    child = two.live()
    np.testing.assert_allclose(child["position"][1] - child["position"][0],
                               [math.cos(math.radians(137.5)), math.sin(math.radians(137.5))], atol=1e-6)
    assert child["birth"].tolist() == [0, 2]
    out = mc.simulate_cells(None, cells, 41, rules=rules)
    assert int(out.count) == 1 + 41 // 2  # one division every other iteration (5001 cells after 10000)
    turns = np.degrees(out.live()["polarity"]) % 360
    np.testing.assert_allclose(turns, (np.arange(int(out.count)) * 137.5) % 360, atol=1e-3)


def test_capacity_overflow_is_reported_with_the_iteration(phyllotaxis):
    cells, rules = phyllotaxis
    small = cells.with_capacity(4)
    with pytest.raises(mj.SimulationError, match="divisions at iteration 7 did not fit in the capacity of 4"):
        mc.simulate_cells(None, small, 12, rules=rules)
    out = mc.simulate_cells(None, small, 12, rules=rules, throw=False)
    assert int(out.count) == 4 and int(out.overflow_step) == 7


def test_division_limit_stops_crowded_cells():
    cells = mc.cell_grid((5, 5), ("U",), capacity=60)
    rules = [mc.Rule(mc.Divide(0.0), start=0, stop=0)]
    out = mc.simulate_cells(None, cells, 1, rules=rules, division_limit=5)
    neighbours = [len(x) for x in brute_neighbours(np.asarray(cells.position)[:25], 3.0)]
    assert int(out.count) == 25 + sum(n <= 5 for n in neighbours) == 25 + 16


# ---- randomness, transforms -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def growing():
    key = jax.random.key(11)
    cells = mc.cell_grid((4, 5), ("U", "V"), lattice="hex", concentration=4.0, spread=1.0, diffusion=(0.08, 0.01),
                         capacity=80, key=key)
    rules = (mc.Rule(mc.Divide(0.0, math.pi), when=mc.Chance(0.05), start=2),)
    return cells, rules


def test_same_key_same_cells(growing):
    cells, rules = growing
    a = mc.simulate_cells(BARD, cells, 12, 0.5, rules=rules, key=jax.random.key(1))
    b = mc.simulate_cells(BARD, cells, 12, 0.5, rules=rules, key=jax.random.key(1))
    c = mc.simulate_cells(BARD, cells, 12, 0.5, rules=rules, key=jax.random.key(2))
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert int(a.count) > 20
    assert not np.array_equal(np.asarray(a.position), np.asarray(c.position))


def test_a_growing_run_under_jit_vmap_and_grad(growing):
    cells, rules = growing
    key = jax.random.key(1)

    def final(sp):
        out = mc.simulate_cells(mj.Bard(alpha=16.0, beta=12.0, sp=sp), cells, 12, 0.5, rules=rules, key=key)
        return out

    def loss(sp):
        out = final(sp)
        return jnp.sum(jnp.where(out.alive, out["V"], 0.0) ** 2) / 100

    sps = jnp.asarray([0.005, 0.01, 0.02])
    swept = jax.jit(jax.vmap(final))(sps)
    eager = jax.vmap(final)(sps)  # without jit, nothing is raised from traced flags either
    np.testing.assert_array_equal(np.asarray(eager.count), np.asarray(swept.count))
    one = final(0.01)
    np.testing.assert_allclose(np.asarray(swept.concentration[1]), np.asarray(one.concentration), rtol=1e-5, atol=1e-5)
    assert (np.asarray(swept.count) == int(one.count)).all()  # the draws do not depend on sp

    grad = jax.grad(loss)(0.01)
    h = 1e-3
    fd = (loss(0.01 + h) - loss(0.01 - h)) / (2 * h)
    assert float(grad) == pytest.approx(float(fd), rel=0.02)
    assert abs(float(grad)) > 1e-3


# ---- errors ---------------------------------------------------------------------------------
def test_bad_inputs_name_the_parameter():
    cells = mc.cell_grid((3, 3), ("U", "V"))
    with pytest.raises(ValueError, match="dt must lie in"):
        mc.simulate_cells(None, cells, 1, -1.0)
    with pytest.raises(ValueError, match="names reagent 'W'"):
        mc.simulate_cells(None, cells, 1, rules=[mc.Rule(mc.Change("W", 1.0))])
    with pytest.raises(ValueError, match="key is required"):
        mc.simulate_cells(None, cells, 1, rules=[mc.Rule(mc.Change("U", 1.0), when=mc.Chance(0.5))])
    with pytest.raises(ValueError, match="Chance.probability must lie in"):
        mc.Chance(1.5)
    with pytest.raises(ValueError, match="before a Map defines it"):
        mc.simulate_cells(None, cells, 1, rules=[mc.Rule(mc.Change("U", mc.mapped("X")))])
    with pytest.raises(ValueError, match="capacity must be an integer >= the number of cells"):
        cells.with_capacity(3)
    with pytest.raises(ValueError, match="domain must be"):
        mc.simulate_cells(None, cells, 1, domain="round")
    with pytest.raises(ValueError, match="React.species must name distinct reagents"):
        mc.React(BARD, ("U", "U"))


def test_an_unstable_dt_is_refused_with_the_largest_stable_one():
    """The thesis's equal-weight sum over the eight Moore neighbours has spectral radius
    12 (less on a finite grid); the hexagonal six-neighbour sum 9."""
    square = mc.cell_grid((30, 32), ("R",), diffusion=0.3)
    with pytest.raises(ValueError, match=r"dt = 0.6 exceeds the explicit-Euler limit 0.55\d+ of reagent 'R'"):
        mc.simulate_cells(None, square, 1, 0.6)
    mc.simulate_cells(None, square, 1, 0.55)
    mc.simulate_cells(None, square, 1, 0.6, check_dt=False)
    hexagonal = mc.cell_grid((30, 32), ("R",), diffusion=0.3, lattice="hex")
    with pytest.raises(ValueError, match=r"limit 0.74\d+"):
        mc.simulate_cells(None, hexagonal, 1, 0.8)


@pytest.fixture(scope="module")
def jostling():
    """Overlapping cells that push each other apart while a reagent spreads: the neighbour
    list is reused between rebuilds (Verlet) inside one call."""
    rng = np.random.default_rng(4)
    pos = rng.uniform(-5.0, 5.0, size=(24, 2))
    conc = rng.uniform(0.0, 4.0, size=(1, 24))
    return mc.make_cells(("R",), pos, concentration=conc, diffusion=0.05, capacity=30)


def test_a_moving_run_in_one_call_matches_the_oracle(jostling):
    out = mc.simulate_cells(None, jostling, 6, 0.5)
    state = from_cells(jostling)
    for t in range(6):
        state = oracle_step(state, (), t, 0.5)
    _compare(out, state)
    assert np.asarray(out["R"], np.float64).sum() == pytest.approx(np.asarray(jostling["R"], np.float64).sum(), rel=1e-6)


def test_a_run_with_a_progress_bar_gives_the_same_cells(jostling):
    plain = mc.simulate_cells(None, jostling, 40, 0.5)
    shown = mc.simulate_cells(None, jostling, 40, 0.5, progress="test")  # pieces of 1 iteration
    for x, y in zip(jax.tree_util.tree_leaves(plain), jax.tree_util.tree_leaves(shown)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_a_models_own_limits_apply_to_its_reagents():
    """FitzHugh-Nagumo's reagents go negative (its lower limits are -inf); the thesis's 0
    holds for the others."""
    model = mj.FitzHughNagumo()
    cells = mc.cell_grid((3, 3), ("u", "v", "w"), concentration=(-0.5, -0.2, -1.0), diffusion=(0.1, 2.0, 0.0))
    out = mc.simulate_cells(model, cells, 1, 0.01)
    u, v, w = (np.asarray(out[n]) for n in ("u", "v", "w"))
    assert (u < 0).all() and (v < 0).all() and (w == 0).all()
    assert np.asarray(out.lower).tolist() == [-np.inf, -np.inf, 0.0]


def test_gradient_of_a_reaction_singular_at_zero_with_spare_capacity():
    """Gierer-Meinhardt divides by v: unused capacity (zeros) must not poison the gradient."""
    key = jax.random.key(5)
    cells = mc.cell_grid((3, 4), mj.GiererMeinhardt(), concentration=2.0, spread=0.2, capacity=20, key=key)

    def loss(rho):
        out = mc.simulate_cells(mj.GiererMeinhardt(rho=rho), cells, 10, 0.01)
        return jnp.sum(jnp.where(out.alive, out["u"], 0.0))

    grad = float(jax.grad(loss)(1.0))
    fd = (float(loss(1.0 + 1e-2)) - float(loss(1.0 - 1e-2))) / 2e-2
    assert np.isfinite(grad) and grad == pytest.approx(fd, rel=1e-2)


def test_uniform_at_draws_the_entries_of_uniform():
    """`uniform_at` (only the draws of the cells asked for) gives the bits of those entries
    of `uniform` over the whole capacity, traced or not, at the ends and in the middle."""
    from morphojax.cells._evaluate import uniform, uniform_at

    for seed in range(3):
        key = jax.random.fold_in(jax.random.key(seed), 5)
        for n in (1, 37, 3000):
            index = jnp.asarray(sorted({0, n - 1, n // 2, n // 3, 1 % n}), jnp.int32)
            want = np.asarray(uniform(key, n, -1.0, 1.0))[np.asarray(index)]
            for got in (uniform_at(key, index, n, -1.0, 1.0),
                        jax.jit(lambda k, i: uniform_at(k, i, n, -1.0, 1.0))(key, index)):
                assert np.array_equal(np.asarray(got).view(np.uint32), want.view(np.uint32))


@pytest.mark.parametrize("p_first", [0.02, 0.4])  # a few children (seat by seat) and many (whole buffers)
def test_division_angles_drawn_for_dividers_only_change_no_bit(p_first):
    """The rules' division angles, drawn only for the dividing cells (`Directions.at`),
    give the children of the angles drawn for every cell (`Directions.full`, what the
    rules did before): two `Divide` rules with their own direction and spread, the first
    that fires setting the angle; both of `divide`'s branches."""
    from morphojax.cells import _step
    from morphojax.cells._evaluate import apply_rules
    from morphojax.cells._rules import check_rules

    cells = mc.cell_grid((9, 10), ("A",), lattice="hex", concentration=(1.0,), spread=(0.5,), capacity=400,
                         key=jax.random.key(4))
    rules = check_rules((mc.Rule(mc.Divide(0.3, 1.0), when=mc.Chance(p_first)),
                         mc.Rule(mc.Divide(2.0, 0.5), when=(mc.Chance(p_first), mc.Compare(mc.conc("A"), ">", 1.0)))),
                        cells.species)
    lists = mc.simulate_cells(None, cells, 1, 0.1).neighbours
    touch = _step.contacts(cells, lists, 3.0)
    fx = apply_rules(rules, cells, touch, cells.step, jnp.asarray(0.1), jax.random.key(8))
    assert len(fx.direction.draws) == 2 and set(np.unique(np.asarray(fx.direction.rule))) == {-1, 0, 1}
    wants = fx.divide & cells.alive
    lazy = _step.divide(cells, cells, wants, fx.direction, cells.step)
    eager = _step.divide(cells, cells, wants, fx.direction.full(), cells.step)
    assert int(lazy.count) - int(cells.count) == int(jnp.sum(wants)) > 0
    assert (int(jnp.sum(wants)) > _step.FEW_DIVISIONS) == (p_first > 0.1)
    for field in ("position", "polarity", "concentration", "birth"):
        assert np.array_equal(np.asarray(getattr(lazy, field)), np.asarray(getattr(eager, field))), field
    # and an angle is its rule's direction + spread x that cell's draw over the whole capacity
    from morphojax.cells._evaluate import uniform

    rule = np.asarray(fx.direction.rule)
    for k, (direction, spread, key) in enumerate(fx.direction.draws):
        want = direction + spread * np.asarray(uniform(key, cells.capacity, -1.0, 1.0))
        np.testing.assert_array_equal(np.asarray(fx.direction.full())[rule == k], want[rule == k])


def test_chance_outside_its_window_draws_nothing_and_fires_nowhere():
    """A `Chance` is drawn only where some cell can still fire: outside its rule's window
    nothing divides; inside, the cells that divide are those whose draw is below p."""
    from morphojax.cells import _step
    from morphojax.cells._evaluate import apply_rules, uniform
    from morphojax.cells._rules import check_rules

    cells = mc.cell_grid((6, 6), ("A",), capacity=50)
    rules = check_rules((mc.Rule(mc.Divide(0.0), when=mc.Chance(0.3), start=5),), cells.species)
    lists = mc.simulate_cells(None, cells, 1, 0.1).neighbours
    touch = _step.contacts(cells, lists, 3.0)
    key = jax.random.key(2)
    before = apply_rules(rules, cells, touch, jnp.asarray(4), jnp.asarray(0.1), key)
    inside = apply_rules(rules, cells, touch, jnp.asarray(5), jnp.asarray(0.1), key)
    assert not bool(jnp.any(before.divide))
    draws = np.asarray(uniform(jax.random.fold_in(jax.random.fold_in(key, 0), 0), cells.capacity))
    want = (draws < 0.3) & (np.arange(cells.capacity) < 36)
    assert np.array_equal(np.asarray(inside.divide), want) and 0 < want.sum() < 36


def test_capacity_follows_the_cells_on_rungs(monkeypatch):
    """A growing listing whose capacity follows its cells on rungs (`capacity_rung`, from
    `RUNG_CELLS` cells) ends on a rung just above its cells, with the cells of a run that
    had all the room from the start: the same divisions, and positions and concentrations
    up to the order of float sums (XLA's reductions may group a row's terms by the
    buffers' length)."""
    import morphojax.cells._listing as listing_module
    from morphojax.cells._listing import capacity_rung

    for count in (1, 100, 1000, 5566, 100_000):
        for growth in (0, 50, 3000):
            rung = capacity_rung(count, growth)
            need = count + max(count // 16 + 64, 2 * growth)
            shift = max(rung.bit_length() - 3, 0)
            assert need <= rung < need * 1.25 + 1 and rung % (1 << shift) == 0 and 4 <= rung >> shift < 8
    text = ("define chemical U limit 4.05\ndefine chemical V\ndefine division_limit 6\ndefine domain packed\n"
            "define time_step 0.1\nuse chemical U conc 4 dev 0 diff 0.40\nuse chemical V conc 4 dev 1 diff 0.01\n"
            "create hex_grid 12 10\nrule always react U V scale 0.1 turing alpha 16 beta 12\n"
            "rule from 20 probability 0.003 divide direction 0 dev 180\n")
    listing = mj.load_listing(text)
    monkeypatch.setattr(listing_module, "RUNG_CELLS", 100)
    followed = listing.run(steps=200, seed=0)
    roomy = listing.run(steps=200, seed=0, capacity=600)
    count = int(followed.count)
    shift = max(followed.capacity.bit_length() - 3, 0)
    assert count > 150 and count < followed.capacity <= capacity_rung(count, count // 4)
    assert followed.capacity % (1 << shift) == 0  # a rung: 120 + 120 // 4 + 64 grown by half would not be
    assert int(roomy.count) == count and roomy.capacity == 600
    assert np.array_equal(np.asarray(followed.birth)[:count], np.asarray(roomy.birth)[:count])
    mine, room = followed.live(), roomy.live()
    for field in ("position", "concentration", "polarity"):
        np.testing.assert_allclose(mine[field], room[field], rtol=1e-4, atol=1e-4)

"""Growth by random matrix expansion, sources and multi-phase experiments."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
import oracle
from morphojax._growth import _insert

FROZEN = mj.Bard(sp=0.0, da=0.0, db=0.0, lower=-np.inf)  # no reaction, no diffusion, no clamp


def _distinct(shape, capacity, seed=0):
    rng = np.random.default_rng(seed)
    vals = rng.permutation(2 * shape[0] * shape[1]).reshape(2, *shape).astype(np.float32)
    return mj.State.from_arrays(list(vals), capacity=capacity)


def _remove_one_adjacent_duplicate(line):
    """The line with exactly one value duplicated next to itself, less that duplicate."""
    same = np.flatnonzero(line[1:] == line[:-1])
    assert len(same) == 1, f"expected exactly one adjacent duplicate, found {len(same)}"
    return np.delete(line, same[0])


def test_row_insertion_duplicates_exactly_one_cell_per_column():
    x = jnp.asarray(np.random.default_rng(1).permutation(30).reshape(1, 5, 6).astype(np.float32))
    x = jnp.pad(x, ((0, 0), (0, 1), (0, 0)))  # room for one more row
    rows = jnp.array([0, 4, 2, 2, 1, 3])
    y = np.asarray(_insert(x, rows, axis=-2))[0]
    for j in range(6):
        col = y[:6, j]
        assert col[rows[j]] == col[rows[j] + 1]
        np.testing.assert_array_equal(_remove_one_adjacent_duplicate(col), np.asarray(x)[0, :5, j])


@pytest.mark.parametrize("distribution", ["uniform", "shuffle", "normal", "triangular"])
def test_expansion_preserves_values(distribution):
    """With reaction and diffusion off, one expansion inserts a row then a column by
    duplicating one cell per column (then per row); all species divide alike."""
    state = _distinct((7, 9), (8, 10))
    out = mj.simulate(FROZEN, state, steps=1, dt=1.0, growth=mj.Growth(1.0, distribution), key=jax.random.key(3))
    assert out.shape == (8, 10)
    before = state.arrays()
    after = out.arrays()
    # undo the column insertion row by row, then the row insertion column by column
    dup_cols = []
    mid = []
    for s in range(2):
        rows = []
        for i in range(8):
            line = after[s][i]
            same = np.flatnonzero(line[1:] == line[:-1])
            assert len(same) == 1
            if s == 0:
                dup_cols.append(same[0])
            else:
                assert same[0] == dup_cols[i], "species must divide at the same cells"
            rows.append(np.delete(line, same[0]))
        mid.append(np.stack(rows))
    for s in range(2):
        for j in range(9):
            np.testing.assert_array_equal(_remove_one_adjacent_duplicate(mid[s][:, j]), before[s][:, j])


def test_final_size_counts_expansions():
    state = mj.paper_state(jax.random.key(0), (10, 12), capacity=(40, 40))
    growth = mj.Growth(rate=2.5)  # dt 0.004 -> one expansion every 100 steps
    out = mj.simulate(mj.Turing(8.0, 3.0), state, steps=1234, dt=0.004, growth=growth, key=jax.random.key(1))
    expected = -(-1234 // 100)
    assert out.shape == (10 + expected, 12 + expected)
    assert growth.expansions(1234, 0.004) == expected
    # cells beyond the active region stay zero
    fields = np.asarray(out.fields)
    assert not fields[:, 10 + expected:, :].any() and not fields[:, :, 12 + expected:].any()


@pytest.mark.parametrize("distribution", mj.DISTRIBUTIONS)
def test_birth_times_count_every_inserted_cell(distribution):
    """Fig. 3 as an array: expansion k inserts a row of cols + k - 1 cells and a column of rows + k."""
    h, w, n = 9, 13, 6
    birth = np.asarray(mj.Growth(1.0, distribution).birth_times((h, w), n, jax.random.key(3)))
    assert birth.shape == (h + n, w + n)
    counts = np.bincount(birth.ravel(), minlength=n + 1)
    np.testing.assert_array_equal(counts, [h * w] + [(w + k - 1) + (h + k) for k in range(1, n + 1)])
    assert birth.min() == 0 and birth.max() == n
    with pytest.raises(ValueError, match="birth_times"):
        mj.Growth(1.0, method="nearest").birth_times((h, w), n, jax.random.key(3))


def test_capacity_overflow_is_an_error_before_the_run():
    state = mj.paper_state(jax.random.key(0), (10, 10), capacity=(15, 30))
    with pytest.raises(ValueError, match=r"beyond the capacity 15x30"):
        mj.simulate(mj.Turing(8.0, 3.0), state, steps=1000, dt=0.004, growth=mj.Growth(2.5), key=jax.random.key(1))
    fixed = mj.paper_state(jax.random.key(0), (10, 10))
    with pytest.raises(ValueError, match="no room to grow"):
        mj.simulate(mj.Turing(8.0, 3.0), fixed, steps=10, dt=0.004, growth=mj.Growth(2.5), key=jax.random.key(1))
    with pytest.raises(ValueError, match="key is required"):
        mj.simulate(mj.Turing(8.0, 3.0), state, steps=10, dt=0.004, growth=mj.Growth(2.5))


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_unused_capacity_does_not_leak(boundary):
    """A state inside a larger capacity evolves exactly like the same state on its own lattice."""
    small = mj.paper_state(jax.random.key(4), (13, 17))
    roomy = mj.State.from_arrays(small.arrays(), capacity=(24, 31))
    model = mj.Turing(12.0, 3.0, lower=(0.0, 3.0))
    a = mj.simulate(model, small, steps=300, dt=0.008, boundary=boundary)
    b = mj.simulate(model, roomy, steps=300, dt=0.008, boundary=boundary)
    for x, y in zip(a.arrays(), b.arrays()):
        np.testing.assert_allclose(x, y, rtol=1e-6, atol=1e-6)
    assert not np.asarray(b.fields)[:, 13:, :].any()


@pytest.mark.parametrize(
    "boundary, shape, capacity",
    [("wrap", (9, 11), (20, 22)), ("no-flux", (150, 152), (167, 169))],
    ids=["wrap-one-block", "no-flux-two-blocks"],
)
def test_growing_run_matches_the_numpy_oracle(boundary, shape, capacity):
    """Reaction, diffusion and clamps on a growing lattice, step for step against the NumPy
    oracle on arrays of the exact active size (no capacity, no ghost cells), dividing where
    the simulator's draws say. The larger case runs on two blocks of the size ladder."""
    state = mj.paper_state(jax.random.key(2), shape, capacity=capacity)
    r, s, dt, lower = 12.0, 3.0, 0.008, (0.0, 3.0)
    period, n = 12, capacity[0] - shape[0] - 1  # one row and column of room left over
    growth, key = mj.Growth(1.0 / (period * dt)), jax.random.key(7)
    assert growth.period_steps(dt) == period
    got = mj.simulate(mj.Turing(r, s, lower=lower), state, steps=n * period, dt=dt, boundary=boundary,
                      growth=growth, key=key)
    fields = [np.asarray(f, float) for f in state.arrays()]
    for step in range(n * period):
        fields = oracle.euler(lambda a, b: oracle.turing_rates(a, b, r, s, boundary), fields, dt, lower,
                              (np.inf, np.inf), 1)
        if step % period == 0:  # an expansion ends the first step of every period
            kr, kc = jax.random.split(jax.random.fold_in(jax.random.fold_in(key, step), 0))
            h, w = fields[0].shape  # (draws of the capacity's length: one compiled draw)
            fields = oracle.insert_rows(fields, np.asarray(growth.draw(kr, h, capacity[1], capacity[0]))[:w])
            fields = oracle.insert_cols(fields, np.asarray(growth.draw(kc, w, capacity[0], capacity[1]))[: h + 1])
    assert got.shape == fields[0].shape == (capacity[0] - 1, capacity[1] - 1)
    for g, e in zip(got.arrays(), fields):
        assert np.abs(g - e).max() < 1e-3
    beyond = np.asarray(got.fields).copy()
    beyond[:, : got.shape[0], : got.shape[1]] = 0.0
    assert not beyond.any()


N_DRAWS = 4000


@pytest.mark.parametrize(
    "growth",
    [mj.Growth(1.0, "uniform"), mj.Growth(1.0, "normal"), mj.Growth(1.0, "triangular"),
     mj.Growth(1.0, "uniform", row_weights=np.array([1.0, 0.5, 1.0]))],
    ids=["uniform", "normal", "triangular", "weighted"],
)
def test_index_histograms_match_their_law(growth):
    """Chi-square goodness of fit of the dividing indices (fixed key) against the exact law."""
    from scipy import stats

    n = 30
    draw = jax.jit(lambda k: growth.draw(k, jnp.int32(n), N_DRAWS, 64, growth.row_weights))
    idx = np.asarray(draw(jax.random.key(7)))
    assert idx.min() >= 0 and idx.max() < n
    observed = np.bincount(idx, minlength=n)
    expected = growth.law(n, growth.row_weights) * N_DRAWS
    keep = expected > 0
    assert observed[~keep].sum() == 0
    _, p = stats.chisquare(observed[keep], expected[keep])
    assert p > 1e-3, (observed, expected.round(1))
    # and the test has power: the draws are far from a different law
    other = mj.Growth(1.0, "triangular" if growth.distribution != "triangular" else "uniform")
    _, p_other = stats.chisquare(observed[keep], other.law(n)[keep] / other.law(n)[keep].sum() * N_DRAWS)
    if growth.row_weights is None:
        assert p_other < 1e-6


@pytest.mark.parametrize("distribution", ["normal", "triangular"])
def test_all_ones_weights_draw_the_law_itself(distribution):
    """Weights multiply the law's exact masses: with all-ones weights the weighted sampler
    draws the unweighted law (the clipped normal piles its tails on the edge cells)."""
    growth = mj.Growth(1.0, distribution, spread=1.0)
    n = 7
    weighted = jax.jit(lambda k: growth.draw(k, jnp.int32(n), N_DRAWS, 16, jnp.ones(4)))
    plain = jax.jit(lambda k: growth.draw(k, jnp.int32(n), N_DRAWS, 16))
    from scipy import stats

    for draw in (weighted, plain):
        observed = np.bincount(np.asarray(draw(jax.random.key(3))), minlength=n)
        assert stats.chisquare(observed, growth.law(n) * N_DRAWS)[1] > 1e-3, observed


def test_draws_do_not_depend_on_the_block():
    """Eager runs compute on a block of the capacity, jit on all of it: the random numbers
    of divisions and sources must not depend on which (same key, same run)."""
    state = mj.paper_state(jax.random.key(0), (8, 8), capacity=(30, 30))
    mask = np.zeros((30, 30))
    mask[2:5, 2:5] = 1.0
    model, key = mj.Turing(4.2, 1.0), jax.random.key(1)
    cases = [(mj.Growth(10.0, "triangular"), ()), (mj.Growth(10.0), (mj.Source("b", 0.5, "all"),)),
             (mj.Growth(10.0), (mj.Source("b", 0.5, mask),))]
    for growth, sources in cases:
        run = lambda s: mj.simulate(model, s, 20, 0.01, growth=growth, sources=sources, key=key)
        eager, jitted = run(state), jax.jit(run)(state)
        assert eager.shape == (10, 10)
        np.testing.assert_allclose(np.asarray(eager.fields), np.asarray(jitted.fields), atol=1e-5)


def test_shuffle_uses_every_index_once_per_pass():
    growth = mj.Growth(1.0, "shuffle")
    for n, count in [(30, 30), (12, 40), (40, 40)]:
        idx = np.asarray(growth.draw(jax.random.key(n), jnp.int32(n), count, 48))
        counts = np.bincount(idx, minlength=n)
        assert counts.max() - counts.min() <= 1 and counts.sum() == count and idx.max() < n


def test_weights_halve_the_middle_rows():
    from morphojax.presets import leopard_row_weights

    growth = mj.Growth(1.0, row_weights=leopard_row_weights())
    law = growth.law(90, growth.row_weights)
    assert law[45] == pytest.approx(0.5 * law[5])


@pytest.mark.parametrize("method", ["nearest", "bilinear", "bicubic"])
def test_interpolation_growth(method):
    """Section 8.2's control: resample to (rows + 1, cols + 1); constants stay constant and a
    linear ramp stays a ramp (within the ends) for the linear methods."""
    ramp = np.add.outer(np.arange(9.0), 2 * np.arange(11.0)).astype(np.float32)
    state = mj.State.from_arrays([np.full((9, 11), 3.0), ramp], capacity=(12, 14))
    out = mj.simulate(FROZEN, state, steps=1, dt=1.0, growth=mj.Growth(1.0, method=method), key=jax.random.key(0))
    a, b = out.arrays()
    assert a.shape == (10, 12)
    np.testing.assert_allclose(a, 3.0, atol=1e-5)
    slack = 0.1 if method == "bicubic" else 1e-4  # cubic kernels overshoot slightly at the edges
    assert b.min() >= ramp.min() - slack and b.max() <= ramp.max() + slack
    if method != "nearest":
        inner = b[2:-2, 2:-2]
        np.testing.assert_allclose(np.diff(inner, 2, axis=1), 0.0, atol=1e-3)


def test_sources_add_production_on_their_row_only():
    state = mj.State.from_arrays([np.zeros((9, 7)), np.zeros((9, 7))], capacity=(9, 7))
    src = mj.Source("b", 0.01, "center-row")
    out = mj.simulate(FROZEN, state, steps=50, dt=1.0, sources=(src,), key=jax.random.key(2))
    a, b = out.arrays()
    assert not a.any()
    assert not np.delete(b, 4, axis=0).any()
    assert (b[4] > 0).all() and (b[4] < 50 * 0.01).all()
    assert b[4].mean() == pytest.approx(50 * 0.005, rel=0.2)


def test_growth_under_jit_vmap_and_grad():
    state = mj.paper_state(jax.random.key(0), (12, 12), capacity=(20, 20))
    growth = mj.Growth(2.5)

    def run(ratio, key):
        out = mj.simulate(mj.Turing(ratio, 3.0), state, steps=400, dt=0.004, growth=growth, key=key)
        return out.fields, out.size

    keys = jax.random.split(jax.random.key(5), 3)
    fields, sizes = jax.jit(jax.vmap(run, in_axes=(None, 0)))(8.0, keys)
    assert (np.asarray(sizes) == 16).all()
    single, _ = run(8.0, keys[2])
    np.testing.assert_allclose(np.asarray(fields[2]), np.asarray(single), rtol=1e-5, atol=1e-5)
    assert not np.allclose(np.asarray(fields[0]), np.asarray(fields[1]))  # different keys, different divisions
    grad = jax.grad(lambda r: jnp.mean(run(r, keys[0])[0][1] ** 2))(8.0)
    assert np.isfinite(float(grad)) and float(grad) != 0.0


def test_growth_compiles_once_per_phase():
    """The whole growing run is one compiled program, whatever sizes it passes through."""
    from morphojax import _loop

    state = mj.paper_state(jax.random.key(0), (10, 10), capacity=(30, 30))
    mj.simulate(mj.Turing(8.0, 3.0), state, steps=900, dt=0.004, growth=mj.Growth(2.5), key=jax.random.key(1))
    before = _loop._integrate._cached._cache_size()
    out = mj.simulate(mj.Turing(9.0, 2.0), state, steps=900, dt=0.004, growth=mj.Growth(2.5), key=jax.random.key(2))
    assert out.shape == (19, 19)
    assert _loop._integrate._cached._cache_size() == before


def test_block_ladder_placement_is_optimal():
    """The blocks a growing run computes on: as many as the geometric ladder, placed to
    minimise the computed cells; checked against every choice of that many sizes."""
    import itertools

    from morphojax._plan import geometric_ladder, placed_ladder

    rng = np.random.default_rng(0)
    for trial in range(20):
        first = int(rng.integers(20, 60))
        rows = sorted(int(r) for r in rng.integers(first, first + 90, 30))
        weights = [int(w) for w in rng.integers(1, 100, len(rows))]
        cap, area = first + 100, (lambda r: r * (r + 3))
        placed = placed_ladder(rows, weights, cap, 1.25, 8, area)

        def work(ladder):
            return sum(wt * area(next(b for b in ladder if b >= r)) for r, wt in zip(rows, weights))

        geometric = geometric_ladder(min(rows), max(rows), cap, 1.25, 8)
        cands = sorted({min(-(-r // 8) * 8, cap) for r in range(min(rows), max(rows) + 1)})
        best = min(work(c) for k in range(1, len(geometric) + 1) for c in itertools.combinations(cands, k)
                   if c[-1] >= max(rows))
        assert len(placed) <= len(geometric) and placed[-1] >= max(rows)
        assert work(placed) == best <= work(geometric)


def test_slow_growth_runs_exactly_the_steps_asked():
    """Expansions further apart than the blow-up check interval (512 steps here): the
    planned run must still take exactly `steps` steps and match the per-step path."""
    state = mj.State.from_arrays(mj.paper_state(jax.random.key(3), (12, 12)).arrays(), capacity=(20, 20))
    model, dt, key = mj.Turing(4.0, 3.0), 0.01, jax.random.key(4)
    growth = mj.Growth(rate=1.0 / (600 * dt))  # expansions at steps 1, 601, 1201
    out = mj.simulate(model, state, 1400, dt, growth=growth, key=key)
    assert int(out.step) == 1400 and out.size.tolist() == [15, 15]
    assert float(out.time) == pytest.approx(1400 * dt)
    per_step, _ = mj.rollout(model, state, 1400, dt, every=700, growth=growth, key=key)
    np.testing.assert_array_equal(np.asarray(out.fields), np.asarray(per_step.fields))


def test_progress_pieces_of_a_growing_run_share_compiled_programs(monkeypatch):
    """With a progress bar a growing run goes in pieces: the result is the same, and the
    pieces reuse a few compiled programs (one per block size) instead of one each."""
    from morphojax import _loop

    state = mj.State.from_arrays(mj.paper_state(jax.random.key(5), (150, 150)).arrays(), capacity=(200, 200))
    model, dt, key = mj.Turing(4.0, 3.0), 0.01, jax.random.key(6)
    growth = mj.Growth(rate=1.0 / (8 * dt))  # 50 expansions in 400 steps
    whole = mj.simulate(model, state, 400, dt, growth=growth, key=key)
    seen = []
    real = _loop._integrate

    def spy(*args, **kwargs):
        seen.append((kwargs["steps"], kwargs["segments"]))
        return real(*args, **kwargs)

    monkeypatch.setattr(_loop, "_integrate", spy)
    compiled = real._cached._cache_size()
    pieces = mj.simulate(model, state, 400, dt, growth=growth, key=key, progress=True)
    np.testing.assert_array_equal(np.asarray(pieces.fields), np.asarray(whole.fields))
    assert int(pieces.step) == 400 and pieces.size.tolist() == whole.size.tolist() == [200, 200]
    assert float(pieces.time) == float(whole.time)  # one clock, not one per piece
    assert len(seen) >= 10  # in pieces
    # a handful of compiled programs (the block sizes, the first piece), not one per piece
    assert real._cached._cache_size() - compiled <= 4

"""Cellular automata: Young's K-species automaton against the NumPy oracle, exact ties,
paper 002's K = 2 result, the order parameter, the soft relaxation, life-like rules,
jit/vmap, validation, pictures and meshes, presets and the `ca` command."""

import argparse
import json
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import ca_oracle as oracle
from morphojax.automata import (
    LifeLike,
    YoungCA,
    cells_image,
    changed_fraction,
    glider,
    hard_cells,
    one_hot_cells,
    order_parameter,
    parse_rule,
    random_cells,
    read_ply,
    slice_montage,
    species_mesh,
    volume_fractions,
    weighted_volume_difference,
    write_obj,
    write_ply,
    write_species_meshes,
)
from morphojax.automata._base import jit_step as _jit_step

YOUNG = (2.30, 6.01, 1.0, -0.2)
DUR = (3.2, 6.0, 1.0, -0.2)

# (shape, species, neighbourhood, include_self): 2D and 3D, K = 1, 2, 3, all three
# neighbourhoods, with and without the self cell, decimals that need denominators 5 to 50
CASES = [
    ((17, 19), [YOUNG], "disc", False),
    ((16, 15), [(2.0, 5.0, 0.8, -0.2), (1.0, 3.0, 1.0, -0.15)], "box", True),
    ((15, 16), [(1.5, 4.3, 1.0, -0.22), (2.3, 3.0, 0.5, -0.3), (1.0, 2.5, 1.0, -0.35)], "disc", True),
    ((13, 13, 14), [DUR], "disc", False),
    ((11, 12, 11), [(1.0, 3.0, 1.0, -0.2), (2.0, 4.0, 1.0, -0.1)], "box", False),
    ((12, 11, 13), [(1.5, 3.3, 1.0, -0.25), (2.2, 4.1, 1.0, -0.3), (1.0, 2.0, 1.0, -0.4)], "disc", True),
    # a last axis longer than one vector and not a multiple of it (the direct method carries
    # it widened periodically to whole vectors), and a 2D disc of over 255 cells (byte
    # partial sums widened)
    ((19, 45), [YOUNG, (3.0, 9.5, 1.0, -0.1)], "disc", False),
    # von Neumann's diamonds (paper 003 Fig. 1 (b)), with the self cell as paper 003's code
    # counts it, in 2D and 3D
    ((16, 17), [(2.0, 5.0, 0.8, -0.2), (1.0, 3.5, 1.0, -0.15)], "diamond", True),
    ((11, 12, 13), [(1.0, 3.0, 1.0, -0.2), (2.0, 4.0, 1.0, -0.1)], "diamond", False),
]


def _state(shape, k, seed):
    return np.random.default_rng(seed).integers(0, k + 1, shape).astype(np.int8)


@pytest.mark.parametrize("method", ["direct", "fft", "matmul"])
@pytest.mark.parametrize("case", range(len(CASES)), ids=lambda i: f"{len(CASES[i][0])}d-K{len(CASES[i][1])}-{CASES[i][2]}")
def test_step_matches_oracle_exactly(case, method):
    shape, species, neighbourhood, include_self = CASES[case]
    ca = YoungCA(species, neighbourhood, include_self, method=method)
    assert ca._plan(shape).method == method
    for seed in (0, 1):
        cells = _state(shape, len(species), seed)
        got = np.asarray(ca.step(cells))
        assert got.dtype == np.int8
        np.testing.assert_array_equal(got, oracle.young_step(cells, species, neighbourhood, include_self))


# disc weights at or below 0 (allowed while w_act > w_inh): paper 003's Appendix B2 panels
# wi = 1.00 and 1.05 at wa = 1 (its code's boxes, self counted), a 2D disc beside an
# ordinary species, a 3D box
LOW_DISC_CASES = [
    ((17, 16), [(2.0, 5.0, 0.0, -1.0)], "box", True),
    ((17, 16), [(2.0, 5.0, -0.05, -1.05)], "box", True),
    ((16, 18), [(2.0, 5.0, -0.3, -0.5), (1.0, 3.0, 1.0, -0.2)], "disc", False),
    ((11, 12, 11), [(1.0, 3.0, 0.0, -0.2)], "box", False),
]


@pytest.mark.parametrize("method", ["direct", "fft", "matmul"])
@pytest.mark.parametrize("case", range(len(LOW_DISC_CASES)))
def test_disc_weights_at_or_below_zero_match_oracle(case, method):
    shape, species, neighbourhood, include_self = LOW_DISC_CASES[case]
    ca = YoungCA(species, neighbourhood, include_self, method=method)
    assert ca._plan(shape).method == method
    k = len(species)
    for seed in (0, 1):
        cells = _state(shape, k, seed)
        if k == 1:  # sparse starts, as the paper's p = 0.015, leave rings empty
            cells = np.where(np.random.default_rng(seed + 7).random(shape) < 0.03, 0, 1).astype(np.int8)
        got = np.asarray(ca.step(cells))
        np.testing.assert_array_equal(got, oracle.young_step(cells, species, neighbourhood, include_self))
        # a species whose disc weighs <= 0 never gains a cell
        for j, sp in enumerate(species):
            if sp[2] <= 0:
                assert not ((got == j) & (cells != j)).any()
    if k == 1:  # one differentiated cell alone: its field is w_act (self counted) or 0
        lone = np.ones(shape, np.int8)
        lone[(3,) * len(shape)] = 0
        kept = np.asarray(ca.step(lone))[(3,) * len(shape)] == 0
        assert kept == (species[0][2] == 0 or not include_self)


@pytest.mark.parametrize("keys", [True, False])
def test_species_ties_go_to_the_lowest_index(keys):
    """Two identical species tie wherever both fields are equal; the first wins (as the
    oracle's argmax), both through the packed keys W_j (K + 1) + K - j and through the
    best/winner chain used when those keys would overflow int32."""
    species, shape = [YOUNG, YOUNG], (20, 21)
    ca = YoungCA(species, method="direct")
    plan = ca._plan(shape)
    assert plan.keys
    cells = _state(shape, 2, 5)
    w = np.asarray(ca.fields(cells))
    assert np.sum((w[0] == w[1]) & (w[0] > 0)) > 10  # the case under test occurs
    out = _jit_step(ca, cells, None, plan=plan._replace(keys=keys))
    np.testing.assert_array_equal(np.asarray(out), oracle.young_step(cells, species))


def test_fft_separate_counts_path_matches_oracle():
    """Weights with four decimals make the weighted kernel too large for one float32
    transform; the activator and ring counts are then transformed separately."""
    species = [(2.0, 5.0, 1.0, -0.1234), (1.5, 4.0, 0.875, -0.2115)]
    ca = YoungCA(species, method="fft")
    shape = (16, 17)
    assert ca._plan(shape).combined is False
    cells = _state(shape, 2, 3)
    np.testing.assert_array_equal(np.asarray(ca.step(cells)), oracle.young_step(cells, species))


def test_matmul_refuses_fields_too_large_for_exact_float32():
    """Weights over a denominator of 10^4 make the fields too large for the matrix-product
    transforms' error bound: an explicit method="matmul" is a ValueError, and "auto"
    never picks it (it falls back to an exact method)."""
    species = [(2.0, 5.0, 1.0, -0.1234)]
    with pytest.raises(ValueError, match=r"YoungCA\.method 'matmul'"):
        YoungCA(species, method="matmul")._plan((16, 16, 16))
    assert YoungCA(species)._plan((16, 16, 16)).method != "matmul"
    if jax.default_backend() == "cpu":  # small 3D lattices, K = 1
        assert YoungCA([DUR])._plan((16, 16, 16)).method == "matmul"


@pytest.mark.parametrize("shape, species, expected", [
    ((30, 30, 30), [DUR], "direct"),  # the paper 002 Table 1 case
    ((100, 100, 100), [DUR, DUR], "direct"),
    ((256, 256), [(2.3, 12.0, 1.0, -0.02)], "direct"),
    # larger radii: XLA:CPU emits the direct sums' last fusion as scalar code (measured
    # 5-20x slower; benchmarks/results/bench_automata.md), so the FFT is cheaper
    ((256, 256), [(2.3, 15.0, 1.0, -0.02)], "fft"),
    ((48, 48, 48), [(3.2, 8.0, 1.0, -0.05)], "fft"),
])
def test_auto_follows_the_measured_crossovers(shape, species, expected):
    if len(shape) == 3 and jax.default_backend() != "cpu":
        expected = "fft"  # the CPU-fitted model keeps the FFT for 3D lattices on GPUs
    assert YoungCA(species)._plan(shape).method == expected


def _tie_lattice(target_state):
    """A 15 x 15 lattice whose centre has 3 species-0 cells in its activator disc
    (radius 1.5: the 8 Moore neighbours) and 15 in its ring (1.5 < d <= 3: 20 cells)."""
    cells = np.ones((15, 15), np.int8)  # undifferentiated
    c = 7
    act = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0)]
    ring = [(dy, dx) for dy in range(-3, 4) for dx in range(-3, 4) if 2.25 < dy * dy + dx * dx <= 9]
    assert len(act) == 8 and len(ring) == 20
    for dy, dx in act[:3] + ring[:15]:
        cells[c + dy, c + dx] = 0
    cells[c, c] = target_state
    return cells


@pytest.mark.parametrize("method", ["direct", "fft", "matmul"])
@pytest.mark.parametrize("target", [0, 1])
def test_exact_tie_keeps_state(method, target):
    """3 x 1 + 15 x (-0.2) = 0 exactly: the cell keeps its state (float32 sums are not 0)."""
    assert np.float32(3.0) + sum([np.float32(-0.2)] * 15) != 0  # floating point would decide
    ca = YoungCA([(1.5, 3.0, 1.0, -0.2)], method=method)
    cells = _tie_lattice(target)
    assert float(ca.fields(cells)[0, 7, 7]) == 0.0
    assert int(ca.step(cells)[7, 7]) == target
    assert oracle.young_step(cells, [(1.5, 3.0, 1.0, -0.2)])[7, 7] == target


def test_exact_tie_survives_tracing():
    """The same tie through jit with traced parameters (FFT with separate counts)."""
    ca = YoungCA([(1.5, 3.0, 1.0, -0.2)])
    cells = _tie_lattice(0)
    out = eqx.filter_jit(lambda m, c: m.step(c))(ca, cells)
    assert int(out[7, 7]) == 0


@pytest.mark.parametrize("method", ["direct", "fft", "matmul"])  # fft with K = 1 carries a float indicator
def test_run_is_repeated_step_and_records(method):
    ca = YoungCA([YOUNG], method=method)
    cells = random_cells(jax.random.key(3), (24, 24), 1, p=0.1)
    ref = np.asarray(cells)
    for _ in range(6):
        ref = oracle.young_step(ref, [YOUNG])
    out = ca.run(cells, 6, save_every=2, history=True)
    np.testing.assert_array_equal(np.asarray(out.cells), ref)
    assert int(out.steps) == 6 and out.frames.shape == (4, 24, 24)
    np.testing.assert_array_equal(np.asarray(out.frame_steps), [0, 2, 4, 6])
    np.testing.assert_array_equal(np.asarray(out.frames[1]), np.asarray(ca.run(cells, 2).cells))
    assert out.changes.shape == (6,) and np.all(np.asarray(out.changes) >= 0)
    assert float(out.changes[-1]) == pytest.approx(float(changed_fraction(ca.run(cells, 5).cells, out.cells)))
    zero = ca.run(cells, 0)
    assert int(zero.steps) == 0 and not bool(zero.converged)
    assert ca._binary(ca._plan(cells.shape)) == (method != "direct")
    early = ca.run(cells, 40, stop_at_convergence=True, threshold=0.02)
    n = int(early.steps)
    assert bool(early.converged) and 0 < n < 40
    np.testing.assert_array_equal(np.asarray(early.cells), np.asarray(ca.run(cells, n).cells))
    assert float(changed_fraction(ca.run(cells, n - 1).cells, early.cells)) < 0.02


def test_a_run_in_pieces_behind_a_progress_bar_equals_one_loop(capsys):
    """`progress=True` runs pieces of about a twentieth (multiples of save_every) and joins
    them into exactly what one loop returns: cells, count, convergence, changes, frames,
    also when the run stops early inside a piece."""
    ca = YoungCA([YOUNG])
    cells = random_cells(jax.random.key(3), (24, 24), 1, p=0.1)
    cases = [dict(), dict(history=True), dict(save_every=3, history=True),
             dict(stop_at_convergence=True, threshold=0.02, history=True, save_every=2)]
    for options in cases:
        one = ca.run(cells, 41, **options)
        pieces = ca.run(cells, 41, progress="young", **options)
        for name in ("cells", "steps", "converged", "changes", "frames", "frame_steps"):
            a, b = getattr(one, name), getattr(pieces, name)
            assert (a is None) == (b is None), (name, options)
            if a is not None:
                np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=f"{name} {options}")
    assert int(one.steps) < 41  # the last case stopped early, inside a piece
    life = LifeLike("B3/S23")
    start = jax.random.bernoulli(jax.random.key(1), 0.4, (20, 20)).astype(jnp.int8)
    np.testing.assert_array_equal(np.asarray(life.run(start, 25).cells),
                                  np.asarray(life.run(start, 25, progress=True).cells))


@pytest.fixture(scope="module")
def k2_run():
    """Paper 002 section 4.2 on a reduced lattice: K = 2, both species (3.2, 6, 1, -0.2)."""
    ca = YoungCA([DUR, DUR])
    cells = random_cells(jax.random.key(0), (32, 32, 32), 2)
    return cells, ca.run(cells, 100, stop_at_convergence=True, history=True)


def test_k2_converges_to_well_segregated_state(k2_run):
    cells0, out = k2_run
    steps = int(out.steps)
    assert bool(out.converged) and 5 <= steps <= 40  # "a few tens of iterations" (paper: 20)
    changes = np.asarray(out.changes)
    assert changes[steps - 1] < 0.01 <= changes[steps - 2]  # stopped at the first < 1% step
    assert np.isnan(changes[steps:]).all()
    f0, f1, undiff = np.asarray(volume_fractions(out.cells, 2))
    assert abs(f0 - f1) < 0.04 and 0.35 < f0 < 0.5 and 0.35 < f1 < 0.5  # paper: 42.86%, 42.88%
    assert undiff < 0.2  # paper: 14.26%
    eps0 = np.asarray(order_parameter(cells0, 2))
    eps = np.asarray(order_parameter(out.cells, 2))
    assert np.all(eps0 < 0.2)  # well mixed (1/9 expected for three equal states)
    assert np.all((eps > 0.6) & (eps < 0.95))  # segregated, not dominated


def test_order_parameter():
    rng = np.random.default_rng(5)
    mixed = rng.integers(0, 2, (24, 24, 24))
    assert np.all(np.asarray(order_parameter(mixed, 1)) < 0.02)
    full = np.zeros((10, 12), np.int8)
    np.testing.assert_allclose(np.asarray(order_parameter(full, 2)), [1.0, 1.0, 1.0])
    three = rng.integers(0, 3, (40, 40, 40))
    np.testing.assert_allclose(np.asarray(order_parameter(three, 2)), 1 / 9, atol=0.01)
    small = rng.integers(0, 3, (5, 6, 4))
    np.testing.assert_allclose(np.asarray(order_parameter(small, 2)), oracle.order_parameter(small, 2), rtol=1e-6)


def test_volume_fractions_and_weighted_volume_difference():
    cells = np.array([[0, 1, 2, 2]], np.int8)
    np.testing.assert_allclose(np.asarray(volume_fractions(cells, 2)), [0.25, 0.25, 0.5])
    ca = YoungCA([DUR, (6.0, 10.0, 1.0, -0.3)])
    expected = [4 / 3 * math.pi * (ra**3 * wa + (ri**3 - ra**3) * wi) for ra, ri, wa, wi in (DUR, (6, 10, 1, -0.3))]
    np.testing.assert_allclose(np.asarray(weighted_volume_difference(ca)), expected, rtol=1e-5)
    n_act = len(oracle.offsets(3.2, 3, "disc"))
    n_ring = len(oracle.offsets(6.0, 3, "disc")) - n_act
    got = np.asarray(weighted_volume_difference(ca, discrete=True))[0]
    assert got == pytest.approx(n_act - 0.2 * n_ring, rel=1e-6)
    assert tuple(ca.neighbour_counts(3)[0]) == (n_act, n_ring)


def test_random_cells():
    key = jax.random.key(1)
    young = np.asarray(random_cells(key, (200, 200), 1, p=0.015))
    assert set(np.unique(young)) <= {0, 1} and abs((young == 0).mean() - 0.015) < 0.003
    multi = np.asarray(random_cells(key, (100, 100), 3, p=0.3))
    assert abs((multi < 3).mean() - 0.3) < 0.02 and {0, 1, 2} <= set(np.unique(multi))
    uniform = np.asarray(random_cells(key, (100, 100), 2))
    np.testing.assert_allclose(np.bincount(uniform.ravel()) / uniform.size, 1 / 3, atol=0.02)
    np.testing.assert_array_equal(uniform, np.asarray(random_cells(key, (100, 100), 2)))  # deterministic


# ---- the soft relaxation -----------------------------------------------------------------
@pytest.mark.parametrize("k", [1, 2])
def test_soft_step_tends_to_hard_step(k):
    species = [YOUNG, (1.5, 4.0, 1.0, -0.3)][:k]
    ca = YoungCA(species)
    cells = _state((20, 21), k, 11)
    hard = np.asarray(ca.step(cells))
    fields = np.asarray(ca.fields(cells))
    best = fields.max(0)
    species_tie = (best > 0) & ((fields == best).sum(0) > 1)  # split evenly by the softmax
    probs = one_hot_cells(cells, k)
    soft_step = eqx.filter_jit(lambda m, p, t: m.soft_step(p, t))
    errors = []
    for t in (1.0, 0.1, 1e-3, 1e-9):  # 1e-9: far below the transforms' float error
        soft = soft_step(ca, probs, jnp.float32(t))
        np.testing.assert_allclose(np.asarray(soft.sum(0)), 1.0, atol=1e-5)
        errors.append(int((np.asarray(hard_cells(soft)) != hard)[~species_tie].sum()))
    assert errors[0] >= errors[-1] and errors[-1] == 0
    cold = np.asarray(soft)
    np.testing.assert_allclose(cold[:, ~species_tie], np.asarray(one_hot_cells(hard, k))[:, ~species_tie], atol=1e-4)


def test_soft_step_keeps_state_on_exact_tie():
    ca = YoungCA([(1.5, 3.0, 1.0, -0.2)])
    for target in (0, 1):
        for temperature in (1e-3, 1e-9):
            p = ca.soft_step(one_hot_cells(_tie_lattice(target), 1), temperature)
            assert float(p[target, 7, 7]) > 0.999


def test_soft_run_gradients():
    """Every public parameter gets a finite non-zero gradient (smooth discs), and the
    gradient in w_inh agrees with central finite differences."""
    ca = YoungCA([(2.0, 4.5, 1.0, -0.2)])
    probs = one_hot_cells(_state((16, 16), 1, 2), 1)
    target = jnp.asarray(np.random.default_rng(4).uniform(size=(16, 16)), jnp.float32)

    @eqx.filter_jit
    def loss(model):
        return jnp.mean((model.soft_run(probs, 3, 2.0, edge=0.5)[0] - target) ** 2)

    grads = eqx.filter_jit(eqx.filter_grad(loss))(ca)
    for name in ("r_act", "r_inh", "w_act", "w_inh"):
        g = np.asarray(getattr(grads, name))
        assert np.all(np.isfinite(g)) and np.all(g != 0), name
    h = 1e-3  # (at low temperature the loss is sharply curved: finite differences need small h)
    bump = lambda d: eqx.tree_at(lambda m: m.w_inh, ca, ca.w_inh + d)
    fd = (loss(bump(h)) - loss(bump(-h))) / (2 * h)
    assert float(grads.w_inh[0]) == pytest.approx(float(fd), rel=0.02)


# ---- life-like rules ---------------------------------------------------------------------
def test_glider_moves_one_cell_diagonally_every_four_generations():
    life = LifeLike("B3/S23")
    start = glider((12, 12), at=(2, 3))
    out = life.run(start, 12, save_every=1)
    frames = np.asarray(out.frames)
    for t in range(13):
        shifted = np.roll(np.asarray(start), (t // 4, t // 4), (0, 1))
        assert np.array_equal(frames[t], shifted) == (t % 4 == 0), t
        assert frames[t].sum() == 5  # a glider always has five live cells


@pytest.mark.parametrize("rule", ["B3/S23", "B36/S23", "b2s", "day-and-night", "23/3"])
def test_life_like_matches_oracle(rule):
    life = LifeLike(rule)
    rng = np.random.default_rng(8)
    for shape in ((9, 10), (5, 6, 7)):
        cells = rng.integers(0, 2, shape).astype(np.int8)
        np.testing.assert_array_equal(np.asarray(life.step(cells)), oracle.life_step(cells, life.birth, life.survive))


def test_rule_notation():
    assert parse_rule("B3/S23") == ((3,), (2, 3)) == parse_rule("b3s23") == parse_rule("23/3") == parse_rule("life")
    assert LifeLike("highlife").rule == "B36/S23"
    with pytest.raises(ValueError, match=r"LifeLike\.rule.*B/S notation"):
        LifeLike("conway's")
    with pytest.raises(ValueError, match=r"LifeLike\.rule B9/S: neighbour counts must lie in \[0, 8\] on a 2D"):
        LifeLike("B9/S").step(np.ones((5, 5), np.int8))
    with pytest.raises(ValueError, match=r"must lie in \[0, 2\] on a 1D lattice \(got 3\)"):
        LifeLike("B3/S23").step(np.ones(7, np.int8))


# ---- jit and vmap ------------------------------------------------------------------------
def test_vmap_over_keys_and_parameters():
    ca = YoungCA([YOUNG])
    keys = jax.random.split(jax.random.key(9), 3)
    batch = jax.vmap(lambda k: ca.run(random_cells(k, (20, 20), 1, p=0.05), 5).cells)(keys)
    for i in range(3):
        single = ca.run(random_cells(keys[i], (20, 20), 1, p=0.05), 5).cells
        np.testing.assert_array_equal(np.asarray(batch[i]), np.asarray(single))
    # models stacked over w_inh (common denominator), and models built inside vmap
    ws = (-0.16, -0.2, -0.28)
    cells = _state((20, 20), 1, 6)
    models = [YoungCA([(2.3, 6.01, 1.0, w)], denominator=100) for w in ws]
    stacked = jax.tree.map(lambda *x: jnp.stack(x), *models)
    by_stack = eqx.filter_vmap(lambda m: m.step(cells))(stacked)
    by_build = jax.vmap(lambda w: YoungCA([(2.3, 6.01, 1.0, w)], denominator=100).step(cells))(jnp.asarray(ws))
    for i, w in enumerate(ws):
        ref = oracle.young_step(cells, [(2.3, 6.01, 1.0, w)])
        np.testing.assert_array_equal(np.asarray(by_stack[i]), ref)
        np.testing.assert_array_equal(np.asarray(by_build[i]), ref)
    with pytest.raises(ValueError, match=r"YoungCA\.denominator must be given"):
        jax.vmap(lambda w: YoungCA([(2.3, 6.01, 1.0, w)]).step(cells))(jnp.asarray(ws))


@pytest.mark.parametrize("method", ["direct", "fft", "matmul"])
def test_jit_closing_over_a_model(method):
    """A model built outside (never called before) or inside a jitted function, from
    Python numbers: the plan and the cached kernel spectra are worked out concretely."""
    species = {"direct": [(2.2, 5.5, 1.0, -0.3)], "fft": [(2.1, 5.4, 1.0, -0.3)],
               "matmul": [(2.05, 5.3, 1.0, -0.3)]}[method]  # not cached yet
    cells = _state((20, 20), 1, 12)
    ref = cells
    for _ in range(3):
        ref = oracle.young_step(ref, species)
    ca = YoungCA(species, method=method)
    np.testing.assert_array_equal(np.asarray(jax.jit(lambda c: ca.run(c, 3).cells)(cells)), ref)
    np.testing.assert_array_equal(np.asarray(ca.run(cells, 3).cells), ref)  # nothing traced left in a cache
    inside = jax.jit(lambda c: YoungCA(species).run(c, 3).cells)  # default denominator inside jit (radii traced)
    np.testing.assert_array_equal(np.asarray(inside(cells)), ref)


def test_jit_with_traced_radii_and_no_retrace():
    cells = _state((18, 18), 1, 7)
    step = eqx.filter_jit(eqx.debug.assert_max_traces(lambda m, c: m.step(c), max_traces=1))
    for r_act in (1.5, 2.3):  # same structure: one trace, radii are traced
        ca = YoungCA([(r_act, 5.0, 1.0, -0.2)], denominator=10)
        np.testing.assert_array_equal(np.asarray(step(ca, cells)), oracle.young_step(cells, [(r_act, 5.0, 1.0, -0.2)]))


# ---- validation --------------------------------------------------------------------------
@pytest.mark.parametrize(
    "make, pattern",
    [
        (lambda: YoungCA([(-1.0, 6.0, 1.0, -0.2)]), r"YoungCA\.r_act.*\[0, \+inf\)"),
        (lambda: YoungCA([(3.0, 2.0, 1.0, -0.2)]), r"YoungCA\.r_inh.*\[r_act, \+inf\).*species 0"),
        (lambda: YoungCA([(2.0, 6.0, 1.0, 0.2)]), r"YoungCA\.w_inh.*\(-inf, 0\)"),
        (lambda: YoungCA([(2.0, 6.0, 1.0, 0.0)]), r"YoungCA\.w_inh.*\(-inf, 0\)"),
        (lambda: YoungCA([(2.0, 6.0, -0.2, -0.2)]), r"YoungCA\.w_act.*> w_inh.*species 0 has w_act -0\.2 <= w_inh -0\.2"),
        (lambda: YoungCA([(2.0, 6.0, 1.0, -0.2), (2.0, 6.0, -0.5, -0.3)]), r"YoungCA\.w_act.*species 1 has w_act -0\.5"),
        (lambda: YoungCA([(2.0, 6.0, 1.0, -0.2)], neighbourhood="hex"), r"YoungCA\.neighbourhood.*'disc', 'box'"),
        (lambda: YoungCA([(2.0, 6.0, 1.0)]), r"YoungCA\.species\[0\].*\(r_act, r_inh, w_act, w_inh\)"),
        (lambda: YoungCA([]), r"YoungCA\.species needs at least one"),
        (lambda: YoungCA([(2.0, 6.0, 1.0, -0.1234567)]), r"YoungCA weights.*denominator"),
        (lambda: YoungCA([(2.0, 6.0, 1.0, -0.25)], denominator=3), r"YoungCA\.w_inh must be multiples of 1/denominator"),
        (lambda: YoungCA([(1.0, 2.0, 1000.004, -1000.0)], denominator=1), r"YoungCA\.w_act must be multiples of 1/den"),
        (lambda: YoungCA([(1.0, 2.0, 1.0, -0.2)], denominator=5.9), r"YoungCA\.denominator must be a whole number"),
        (lambda: YoungCA([(1.0, 2.0, 1.0, -0.2)]).run(np.zeros((8, 8), np.int8), 2.7), r"run\.steps must be an integer"),
        (lambda: changed_fraction(np.zeros((4, 4)), np.zeros((4, 5))), r"changed_fraction: .* same shape"),
        (lambda: YoungCA([(2.0, 6.0, 1.0, -0.2)], method="gpu"), r"YoungCA\.method"),
        (lambda: YoungCA([(2.0, np.nan, 1.0, -0.2)]), r"YoungCA\.r_inh must be finite"),
    ],
)
def test_bad_parameters(make, pattern):
    with pytest.raises(ValueError, match=pattern):
        make()


@pytest.mark.parametrize(
    "cells, pattern",
    [
        (np.zeros((20, 20), np.float32), r"cells must be an integer array.*float32"),
        (np.zeros((20, 20), bool), r"cells must be an integer array"),
        (np.full((20, 20), 3, np.int8), r"cells must hold states in \[0, 1\]"),
        (np.full((20, 20), -1, np.int32), r"cells must hold states in \[0, 1\]"),
        (np.zeros((12, 20), np.int8), r"at least 2 floor\(r_inh\) \+ 1 = 13 cells.*\(12, 20\)"),
    ],
)
def test_bad_cells(cells, pattern):
    with pytest.raises(ValueError, match=pattern):
        YoungCA([YOUNG]).step(cells)


def test_bad_run_and_initial_arguments():
    ca = YoungCA([YOUNG])
    cells = np.zeros((16, 16), np.int8)
    with pytest.raises(ValueError, match=r"run\.steps"):
        ca.run(cells, -1)
    with pytest.raises(ValueError, match=r"run\.threshold.*\[0, 1\]"):
        ca.run(cells, 1, threshold=2.0)
    with pytest.raises(ValueError, match=r"random_cells\.p.*\[0, 1\]"):
        random_cells(jax.random.key(0), (8, 8), 1, p=1.5)
    with pytest.raises(ValueError, match=r"soft_step temperature.*\(0, \+inf\)"):
        ca.soft_step(one_hot_cells(cells, 1), 0.0)


# ---- pictures, meshes, presets, command line ------------------------------------------------
def test_images_and_meshes(tmp_path):
    cells = np.array([[0, 1], [2, 2]], np.int8)
    img = cells_image(cells, 2, scale=3)
    assert img.size == (6, 6) and img.getpixel((0, 0)) != img.getpixel((5, 0)) != img.getpixel((0, 5))
    z, y, x = np.mgrid[:24, :24, :24]
    ball = np.where((z - 11.5) ** 2 + (y - 11.5) ** 2 + (x - 11.5) ** 2 <= 8.0**2, 0, 1).astype(np.int8)
    assert slice_montage(ball, 1, n=4, scale=2).width > 4 * 48
    verts, faces = species_mesh(ball, 0)
    tri = verts[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    assert area == pytest.approx(4 * math.pi * 8.0**2, rel=0.2)  # voxel staircase adds ~10%
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    assert np.all(np.unique(edges, axis=0, return_counts=True)[1] == 2)  # closed surface
    # outward normals: the signed volume of the counter-clockwise triangles is the ball's
    volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])).sum() / 6
    assert volume == pytest.approx(4 / 3 * math.pi * 8.0**3, rel=0.1)
    v2, f2 = read_ply(write_ply(tmp_path / "ball.ply", verts, faces, colour=(10, 20, 30)))
    np.testing.assert_array_equal(v2, verts)
    np.testing.assert_array_equal(f2, faces)
    text = write_obj(tmp_path / "ball.obj", verts, faces).read_text().splitlines()
    assert sum(line.startswith("v ") for line in text) == len(verts)
    assert sum(line.startswith("f ") for line in text) == len(faces)
    assert [p.name for p in write_species_meshes(ball, 1, tmp_path / "m")] == ["m_species0.ply"]


def test_presets_quick_and_deterministic(tmp_path):
    from morphojax import load_frames
    from morphojax.presets import AUTOMATON_PRESETS as PRESETS

    assert len(PRESETS) >= 6
    for name, preset in PRESETS.items():
        # (and `reinforcement-term`, a plot run through the same builder interface)
        assert name.startswith(("young-", "dur-", "life-", "thesis-", "reinforcement-")) and preset.description \
            and preset.figure
    a = PRESETS["young-b1"].run(seed=3, quick=True, out=tmp_path / "a.png", frames=True)
    b = PRESETS["young-b1"].run(seed=3, quick=True, out=tmp_path / "b.png", frames=False)
    assert a["steps"] == b["steps"] == 20 and (tmp_path / "a_frames.png").exists()
    frames, steps, frames_meta = load_frames(tmp_path / "a_frames.npz")  # checked metadata, version recorded
    assert len(frames) == len(steps) and steps[0] == 0 and frames_meta["states"] == 2
    assert a["volume_fractions"] == b["volume_fractions"]
    with np.load(tmp_path / "a.npz") as fa, np.load(tmp_path / "b.npz") as fb:
        final, meta = fa["cells"], json.loads(str(fa["metadata"]))
        np.testing.assert_array_equal(final, fb["cells"])
    rebuilt = YoungCA(**meta["params"])  # everything needed to reproduce the run is in the metadata
    cells0 = random_cells(jax.random.key(meta["seed"]), meta["lattice"], 1, meta["initial"]["p"])
    np.testing.assert_array_equal(np.asarray(rebuilt.run(cells0, meta["steps"]).cells), final)
    g = PRESETS["life-glider"].run(seed=0, quick=True, out=tmp_path / "g.png", frames=False)
    assert g["glider_moved_diagonally"]


def test_paper002_series_presets(tmp_path):
    """Fig. 7: a weaker inhibitor lets species 0 take most of the volume and push species 1
    away (section 4.3: 70% at w_0,inh = -0.15, species 1 back to 42.5% at -0.18). Fig. 11:
    with one start, a radius enters the automaton only through the cells its disc covers,
    so eps_0 is one value per neighbourhood (the step response) while WVD_0 moves
    continuously over the paper's -70 to 70."""
    from morphojax.presets import AUTOMATON_PRESETS as PRESETS

    fig7 = PRESETS["dur-fig7"].run(seed=0, quick=True, out=tmp_path / "f7.png")
    share = {r["w0_inh"]: r["volume_fractions"] for r in fig7["runs"]}
    assert all(r["converged"] for r in fig7["runs"])
    assert share[-0.15][0] > 0.6 and share[-0.15][0] > share[-0.2][0] > share[-0.3][0]
    assert share[-0.18][1] > share[-0.15][1] + 0.05
    fig11 = PRESETS["dur-fig11"].run(seed=0, quick=True, out=tmp_path / "f11.png")
    with np.load(tmp_path / "f11.npz") as data:
        eps, wvd, counts = data["order_parameter"][:, 0], data["weighted_volume_difference_0"], data["neighbour_counts_0"]
        meta = json.loads(str(data["metadata"]))
    assert meta["seeded"] and len(eps) == fig11["runs"] == 91
    assert wvd.min() < -65 and wvd.max() > 65 and np.all(np.diff(wvd) > 0)
    classes = {tuple(c) for c in counts}
    assert len(classes) == fig11["distinct_neighbourhoods"] >= 5
    for c in classes:  # one order parameter per neighbourhood
        same = np.all(counts == c, axis=1)
        assert np.ptp(eps[same]) == 0.0
    assert len(np.unique(eps)) >= 3  # and the steps differ


def test_paper002_wvd_series_without_one_start_or_with_weights(tmp_path):
    """Fig. 10: with a new start per run, runs of one neighbourhood no longer agree (the
    steps blur). Fig. 12: a weight moves the fields continuously, so eps_0 takes many values
    with one neighbourhood (no staircase). Fig. 13: species 1's parameters never change,
    yet its order parameter moves with species 0's radius (the paper's observation)."""
    from morphojax.presets import AUTOMATON_PRESETS as PRESETS

    def series(name):
        PRESETS[name].run(seed=0, quick=True, out=tmp_path / f"{name}.png")
        with np.load(tmp_path / f"{name}.npz") as data:
            return data["order_parameter"], data["neighbour_counts_0"]

    eps, counts = series("dur-fig10")
    spreads = [np.ptp(eps[np.all(counts == c, axis=1), 0]) for c in {tuple(c) for c in counts}]
    assert max(spreads) > 0.0
    eps, counts = series("dur-fig12")
    assert len({tuple(c) for c in counts}) == 1 and len(np.unique(eps[:, 0])) >= 10
    eps, counts = series("dur-fig13")
    assert eps.shape[1] == 3 and np.ptp(eps[:, 1]) > 0.02


def test_ca_command_3d(tmp_path, capsys):
    from morphojax.cli._ca import register

    parser = argparse.ArgumentParser()
    register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["ca", "--species", "1.5,3,1,-0.2", "--species", "1,2.5,1,-0.3", "--dim", "3",
                              "--size", "12", "--steps", "30", "--stop-at-convergence", "--seed", "2",
                              "--out", str(tmp_path / "run.png")])
    assert args.func(args) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["steps"] <= 30 and len(summary["volume_fractions"]) == 3
    assert (tmp_path / "run.png").exists() and (tmp_path / "run.npz").exists()
    assert any(f.endswith(".ply") for f in summary["files"])
    with pytest.raises(SystemExit):
        parser.parse_args(["ca", "--species", "1,2,3"])
    for bad, message in ((["--rule", "B3/S23", "--p", "1.5"], r"--p \(probability\) must lie in \[0, 1\]"),
                         (["--dim", "4"], r"--dim must be 2 or 3"),
                         (["--size", "0"], r"--size \(cells per side\) must lie in \[1, \+inf\)")):
        args = parser.parse_args(["ca", *bad, "--out", str(tmp_path / "bad.png")])
        with pytest.raises(ValueError, match=message):  # before any run: nothing written (main: exit 2)
            args.func(args)
    assert not (tmp_path / "bad.png").exists()

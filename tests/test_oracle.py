"""morphojax against the independent NumPy/SciPy oracle, step for step."""

import jax
import numpy as np
import pytest

import morphojax as mj
import oracle

SHAPE = (64, 64)


@pytest.fixture(scope="module")
def start():
    rng = np.random.default_rng(7)
    a = np.full(SHAPE, 4.0)
    b = rng.uniform(4.0, 5.0, SHAPE)
    return a, b


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
@pytest.mark.parametrize("stencil", ["nine-point", "five-point"])
def test_laplacian_matches_scipy(boundary, stencil, rng):
    x = rng.normal(size=(13, 17))
    got = np.asarray(mj.laplacian(x.astype(np.float32), boundary, stencil))
    np.testing.assert_allclose(got, oracle.laplacian(x, boundary, stencil), atol=2e-5)


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_turing_with_bounds_200_steps(start, boundary):
    """The issue's check: 200 steps of bounded Turing on 64x64, both boundaries, float32 < 1e-3."""
    a, b = start
    r, s, dt = 12.0, 3.0, 0.008
    lower, upper = (0.0, 4.3), (4.1, np.inf)
    model = mj.Turing(ratio=r, scale=s, lower=lower, upper=upper)
    state = mj.State.from_arrays([a, b])
    got = mj.simulate(model, state, steps=200, dt=dt, boundary=boundary).arrays()
    ref = oracle.euler(lambda a, b: oracle.turing_rates(a, b, r, s, boundary), [a, b], dt, lower, upper, 200)
    for g, e in zip(got, ref):
        assert np.abs(g - e).max() < 1e-3
    # the clamps changed the trajectory, so the check exercised them
    free = oracle.euler(lambda a, b: oracle.turing_rates(a, b, r, s, boundary), [a, b], dt, (0, 0), (np.inf,) * 2, 200)
    assert max(np.abs(f - e).max() for f, e in zip(free, ref)) > 0.05


def test_bard_five_point(start):
    a, b = start
    p = dict(alpha=15.0, beta=11.0, sp=0.5, Da=0.6, Db=0.15)
    model = mj.Bard(alpha=p["alpha"], beta=p["beta"], sp=p["sp"], da=p["Da"], db=p["Db"], upper=(np.inf, 6.0))
    got = mj.simulate(model, mj.State.from_arrays([a, b]), steps=150, dt=0.05, stencil="five-point").arrays()
    ref = oracle.euler(
        lambda a, b: oracle.bard_rates(a, b, p["alpha"], p["beta"], p["sp"], p["Da"], p["Db"], stencil="five-point"),
        [a, b], 0.05, (0.0, 0.0), (np.inf, 6.0), 150,
    )
    for g, e in zip(got, ref):
        assert np.abs(g - e).max() < 1e-3


def test_turing_equals_bard_form(start):
    """Turing(r, s) is Bard(16, 12, sp=1, Da=r s, Db=s): same trajectory."""
    a, b = start
    t = mj.Turing(ratio=6.0, scale=3.0, lower=(0.0, 3.0))
    state = mj.State.from_arrays([a, b])
    x1 = mj.simulate(t, state, steps=50, dt=0.01).fields
    x2 = mj.simulate(t.as_bard(), state, steps=50, dt=0.01).fields
    np.testing.assert_allclose(np.asarray(x1), np.asarray(x2), rtol=1e-6, atol=1e-6)  # same maths, maybe fused apart
    assert float(t.as_bard().da) == 6.0 * 3.0 and float(t.as_bard().sp) == 1.0


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_gray_scott(boundary, key):
    state = mj.gray_scott_state(key, SHAPE)
    u, v = (np.asarray(x, float) for x in state.arrays())
    F, k, Du, Dv = 0.0367, 0.0649, 0.2097, 0.105
    got = mj.simulate(mj.GrayScott(F, k, Du, Dv), state, steps=300, dt=1.0, boundary=boundary).arrays()
    ref = oracle.euler(lambda u, v: oracle.gray_scott_rates(u, v, F, k, Du, Dv, boundary),
                       [u, v], 1.0, (0, 0), (np.inf, np.inf), 300)
    for g, e in zip(got, ref):
        assert np.abs(g - e).max() < 1e-4


def test_reinforcement(rng):
    c = rng.uniform(0.0, 10.0, (40, 30))
    t, w, Dc, dt = 5.0, 5.0, 1.0, 0.0015 * 10
    got = mj.simulate(mj.Reinforcement(t, w, Dc), mj.State.from_arrays([c]), steps=100, dt=dt,
                      boundary="no-flux").arrays()[0]
    ref = oracle.euler(lambda c: oracle.reinforcement_rate(c, t, w, Dc, "no-flux"), [c], dt, (0,), (np.inf,), 100)[0]
    assert np.abs(got - ref).max() < 1e-3


def test_parameter_maps(start):
    """Ratio varying along x and the upper limit of A along y, as in Ready's parameter maps;
    the oracle's D(x) lap(u) is the pointwise form of a diffusion map (the default is the
    flux form, checked against its own oracle in test_anisotropy.py)."""
    a, b = start
    rows, cols = SHAPE
    ratio = np.broadcast_to(np.linspace(4.0, 12.0, cols)[None, :], SHAPE)
    ua = np.broadcast_to(np.linspace(5.0, 8.0, rows)[:, None], SHAPE)
    model = mj.Turing(ratio=ratio, scale=3.0, upper=(ua, np.inf))
    got = mj.simulate(model, mj.State.from_arrays([a, b]), steps=100, dt=0.008,
                      domain=mj.Lattice(maps="pointwise")).arrays()
    ref = oracle.euler(lambda a, b: oracle.turing_rates(a, b, ratio, 3.0), [a, b], 0.008, (0.0, 0.0), (ua, np.inf), 100)
    for g, e in zip(got, ref):
        assert np.abs(g - e).max() < 1e-3


def test_composite_equals_parts(start, rng):
    """A Composite evolves each part exactly as the part would alone."""
    a, b = start
    c = rng.uniform(0.0, 10.0, SHAPE)
    turing, reinf = mj.Turing(40.0, 5.0, lower=(0.0, 2.0)), mj.Reinforcement(5.0, 5.0, 1.0)
    both = mj.simulate(mj.Composite((turing, reinf)), mj.State.from_arrays([a, b, c]), steps=40, dt=0.0015)
    ab = mj.simulate(turing, mj.State.from_arrays([a, b]), steps=40, dt=0.0015)
    cc = mj.simulate(reinf, mj.State.from_arrays([c]), steps=40, dt=0.0015)
    np.testing.assert_allclose(np.asarray(both.fields[:2]), np.asarray(ab.fields), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(np.asarray(both.fields[2:]), np.asarray(cc.fields), rtol=1e-6, atol=1e-6)


def test_barrier_matches_oracle(start):
    a, b = start
    lower, upper = (0.0, 0.0), (6.2, np.inf)
    model = mj.Turing(ratio=4.2, scale=3.0, lower=lower, upper=upper)
    a0 = np.minimum(a, 6.0)
    got = mj.simulate(model, mj.State.from_arrays([a0, b]), steps=200, dt=0.0005, bounds="barrier").arrays()
    ref = oracle.euler_barrier(lambda a, b: oracle.turing_rates(a, b, 4.2, 3.0), [a0, b], 0.0005, lower, upper, 200)
    for g, e in zip(got, ref):
        assert np.abs(g - e).max() < 1e-3


def test_float64_when_enabled(start):
    a, b = start
    with jax.enable_x64(True):
        model = mj.Turing(ratio=12.0, scale=3.0, lower=(0.0, 3.0), upper=(5.2, np.inf))
        state = mj.State.from_arrays([a, b])
        assert state.fields.dtype == np.float64 and model.ratio.dtype == np.float64
        out = mj.simulate(model, state, steps=200, dt=0.008)
        assert out.fields.dtype == np.float64
        ref = oracle.euler(lambda a, b: oracle.turing_rates(a, b, 12.0, 3.0), [a, b], 0.008, (0.0, 3.0),
                           (5.2, np.inf), 200)
        for g, e in zip(out.arrays(), ref):
            assert np.abs(g - e).max() < 1e-10

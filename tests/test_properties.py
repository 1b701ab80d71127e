"""Property tests (hypothesis): conservation, clamps, determinism.

Lattice shapes are drawn from a small fixed set so compiled programs are reused across
examples; parameter values vary freely (they are traced, not compiled in).
"""

import jax
import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import morphojax as mj

SHAPES = [(8, 8), (9, 13)]
STEPS = 25


@given(
    shape=st.sampled_from(SHAPES),
    boundary=st.sampled_from(["wrap", "no-flux"]),
    stencil=st.sampled_from(["nine-point", "five-point"]),
    da=st.floats(0.0, 0.24),
    db=st.floats(0.0, 0.24),
    seed=st.integers(0, 2**31 - 1),
)
def test_pure_diffusion_conserves_mass(shape, boundary, stencil, da, db, seed):
    """With the reaction off (sp = 0) and no clamps, diffusion only moves mass around."""
    rng = np.random.default_rng(seed)
    fields = [rng.uniform(0.0, 10.0, shape) for _ in range(2)]
    model = mj.Bard(sp=0.0, da=da, db=db, lower=-np.inf, upper=np.inf)
    out = mj.simulate(model, mj.State.from_arrays(fields), steps=STEPS, dt=1.0, boundary=boundary, stencil=stencil)
    for before, after in zip(fields, out.arrays()):
        total = before.sum()
        assert abs(float(after.astype(np.float64).sum()) - total) <= 2e-6 * total * STEPS


@given(
    shape=st.sampled_from(SHAPES),
    boundary=st.sampled_from(["wrap", "no-flux"]),
    ratio=st.floats(1.0, 30.0),
    la=st.floats(0.0, 4.0),
    lb=st.floats(0.0, 4.5),
    width_a=st.floats(0.0, 4.0),
    width_b=st.floats(0.0, 4.0),
    seed=st.integers(0, 2**31 - 1),
)
def test_clamps_always_hold(shape, boundary, ratio, la, lb, width_a, width_b, seed):
    lower = (la, lb)
    upper = (la + width_a, lb + width_b)
    model = mj.Turing(ratio=ratio, scale=1.0, lower=lower, upper=upper)
    dt = 0.9 * mj.max_stable_dt(ratio)
    state = mj.random_state(jax.random.key(seed), shape, (0.0, 8.0), (0.0, 8.0))
    out = mj.simulate(model, state, steps=STEPS, dt=dt, boundary=boundary)
    for x, lo, hi in zip(out.arrays(), lower, upper):
        assert np.isfinite(x).all()
        assert x.min() >= np.float32(lo) and x.max() <= np.float32(hi)


@given(seed=st.integers(0, 2**31 - 1), ratio=st.floats(2.0, 20.0))
def test_same_key_same_result(seed, ratio):
    model = mj.Turing(ratio=ratio, scale=1.0)
    dt = 0.5 * mj.max_stable_dt(ratio)
    runs = [
        mj.simulate(model, mj.paper_state(jax.random.key(seed), SHAPES[1]), steps=STEPS, dt=dt).arrays()
        for _ in range(2)
    ]
    for x, y in zip(*runs):
        np.testing.assert_array_equal(x, y)
    other = mj.paper_state(jax.random.key(seed + 1), SHAPES[1]).arrays()[1]
    assert not np.array_equal(other, mj.paper_state(jax.random.key(seed), SHAPES[1]).arrays()[1])

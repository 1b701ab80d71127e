"""Members in lanes (`morphojax/_lanes.py`): a sweep's members stepped as one array with the
members in its last axis, the CPU default for built-in models.

The oracle is the same sweep run member by member (`vmap_size=1`), which equals lone runs of
`simulate` bit for bit (tests/test_sweep.py): every member in lanes must agree with it to
float rounding, on every built-in reaction, stencil, boundary and bounds policy, with
per-member starts and per-member dt; a member that blows up gets the exact first bad step.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
from morphojax import _lanes
from morphojax._sweep import sweep

SHAPE = (11, 13)  # not square, so rows and columns cannot be confused
STEPS = 40


CASES = {  # (model, vary, dt, options): dt half the stability limit of the largest rate
    "turing-limits-barrier": (mj.Turing(4.0, 3.0, lower=(0.5, 0.5), upper=(30.0, 30.0)),
                              {"ratio": [4.0, 12.0], "upper_a": [6.0, 30.0]}, 0.0002, dict(bounds=mj.Barrier())),
    "gray-scott-dt-no-flux": (mj.GrayScott(), {"feed": [0.03, 0.04], "dt": [0.5, 1.0]}, 0.5,
                              dict(boundary="no-flux")),
    "reinforcement-moore": (mj.Reinforcement(), {"threshold": [4.0, 6.0], "diffusion": [0.5, 1.0]}, 0.08,
                            dict(stencil="moore")),
    "gierer-meinhardt-lower-five-point": (mj.GiererMeinhardt(), {"nu": [1.5, 2.0], "lower_a": [0.0, 0.1]}, 0.01,
                                          dict(stencil="five-point")),
    "composite": (mj.Composite((mj.Turing(6.0, 1.0), mj.ThesisReinforcement())),
                  {"0.ratio": [4.0, 8.0], "1.s": [0.3, 0.4]}, 0.03, {}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_members_in_lanes_equal_member_by_member_runs(case):
    model, vary, dt, options = CASES[case]
    kw = dict(steps=STEPS, dt=dt, key=3, shape=SHAPE, describe_members=False, **options)
    lanes = sweep(model, vary, **kw)
    one_by_one = sweep(model, vary, vmap_size=1, **kw)
    assert lanes.config["lanes"] and not one_by_one.config["lanes"]
    assert lanes.config["vmap_size"] == 8  # float32: one AVX2 register of members
    want = one_by_one.fields
    assert np.isfinite(want).all() and (one_by_one.blowup_step == -1).all()
    np.testing.assert_allclose(lanes.fields, want, rtol=0, atol=1e-6 * max(1.0, float(np.abs(want).max())))
    np.testing.assert_array_equal(lanes.blowup_step, one_by_one.blowup_step)
    np.testing.assert_allclose(lanes.change, one_by_one.change, rtol=1e-3, atol=1e-6)
    # the members differ: the lanes carried their own parameters and starts
    assert not np.array_equal(lanes.fields[0], lanes.fields[-1])


def test_a_member_that_blows_up_in_lanes_gets_its_exact_first_bad_step():
    """A group only flags a non-finite member; the sweep re-runs the group member by member."""
    model = mj.Turing(4.2, 3.0)
    start = mj.paper_state(jax.random.key(1), SHAPE)
    res = sweep(model, {"dt": [0.004, 0.05, 0.3, 0.01]}, state=start, steps=STEPS, dt=0.004, check_dt=False,
                describe_members=False)
    assert res.config["lanes"]
    for i, dt in enumerate([0.004, 0.05, 0.3, 0.01]):
        final, bad, _ = mj.run_status(model, start, STEPS, dt, check_dt=False)
        assert res.blowup_step[i] == int(bad)
        if bad < 0:
            np.testing.assert_array_equal(res.fields[i], np.asarray(final.fields))  # re-run member by member
    assert (res.blowup_step[[1, 2]] >= 0).all() and (res.blowup_step[[0, 3]] == -1).all()


def test_what_runs_in_lanes():
    probe = mj.paper_state(jax.random.key(0), SHAPE)
    turing = mj.Turing(4.0, 3.0)
    assert _lanes.lanes_apply(turing, None, (), probe)
    assert _lanes.lanes_apply(mj.Composite((turing, mj.Reinforcement())), None, (), probe)
    # a user's reaction function is promised (species, rows, cols) arrays
    own = mj.Reaction(lambda x, p: -x, {}, diffusion=(1.0, 1.0), species=("a", "b"))
    assert not _lanes.lanes_apply(own, None, (), probe)
    assert not _lanes.lanes_apply(mj.Composite((own, mj.Reinforcement())), None, (), probe)
    # parameter maps, growth, sources and a state with room to grow run member by member
    assert not _lanes.lanes_apply(turing.replace(ratio=jnp.full(SHAPE, 4.0)), None, (), probe)
    assert not _lanes.lanes_apply(turing, mj.Growth(rate=1.0), (), probe)
    assert not _lanes.lanes_apply(turing, None, (object(),), probe)
    assert not _lanes.lanes_apply(turing, None, (), probe.with_capacity((16, 16)))
    assert _lanes.lane_count(jnp.float32) == 8 and _lanes.lane_count(np.float64) == 4

"""Bad input gets a clear ValueError naming the parameter; blow-ups report their step."""

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj


@pytest.fixture(scope="module")
def state():
    return mj.paper_state(jax.random.key(0), (12, 12))


@pytest.mark.parametrize(
    "make, pattern",
    [
        (lambda: mj.Turing(ratio=-1.0), r"Turing\.ratio.*\[0, \+inf\)"),
        (lambda: mj.Turing(scale=-0.5), r"Turing\.scale"),
        (lambda: mj.Bard(da=-0.1), r"Bard\.da"),
        (lambda: mj.GrayScott(dv=-1.0), r"GrayScott\.dv"),
        (lambda: mj.Reinforcement(diffusion=-1.0), r"Reinforcement\.diffusion"),
        (lambda: mj.Reinforcement(width=0.0), r"Reinforcement\.width.*\(0, \+inf\)"),
        (lambda: mj.Turing(lower=(0.0, 5.0), upper=(np.inf, 4.0)), r"lower must be <= upper.*'b'.*5.*4"),
        (lambda: mj.Turing(ratio=np.nan), r"Turing\.ratio must not be NaN"),
        (lambda: mj.Turing(scale=np.inf), r"Turing\.scale must be finite"),
        (lambda: mj.Turing(lower=(-np.inf, np.inf)), r"Turing\.lower must be finite or -inf"),
        (lambda: mj.Turing(lower=(0.0, 1.0, 2.0)), r"Turing\.lower needs 2 values"),
        (lambda: mj.Turing(ratio="fast"), r"Turing\.ratio must be a number"),
        (lambda: mj.model_from_name("oregonator"), r"unknown model 'oregonator'.*turing"),
        (lambda: mj.Turing().replace(colour=1.0), r"no parameter 'colour'.*ratio"),
    ],
)
def test_bad_model_parameters(make, pattern):
    with pytest.raises(ValueError, match=pattern):
        make()


_T = mj.Turing(4.0, 1.0)


@pytest.mark.parametrize(
    "make, pattern",
    [
        (lambda: mj.Phase(_T, steps=-5, dt=0.01), r"Phase\.steps must lie in \[0, \+inf\)"),
        (lambda: mj.Phase(_T, steps=2.5, dt=0.01), r"Phase\.steps must be an integer"),
        (lambda: mj.Phase(_T, steps=10, dt=0.0), r"Phase\.dt must lie in \(0, \+inf\)"),
        (lambda: mj.Phase("turing", steps=10, dt=0.01), r"Phase\.model must be a morphojax model"),
        (lambda: mj.Phase(_T, steps=10, dt=0.01, growth=2.0), r"Phase\.growth must be None, a Growth"),
        (lambda: mj.Phase(_T, steps=10, dt=0.01, sources=("b",)), r"Phase\.sources must be Source"),
        (lambda: mj.Growth(1.0, "normal", spread=np.inf), r"Growth\.spread .* must lie in \(0, \+inf\)"),
        (lambda: mj.Growth(1.0, "normal", spread="x"), r"Growth\.spread must be a number"),
        (lambda: mj.Source("b", 0.1, np.full((4, 4), np.nan)), r"Source\.region \(mask\)"),
        (lambda: mj.Source("b", 0.1, -np.ones((4, 4))), r"Source\.region \(mask weights\) must lie in \[0"),
    ],
)
def test_bad_experiment_parameters(make, pattern):
    with pytest.raises(ValueError, match=pattern):
        make()


def test_phase_takes_a_single_source():
    src = mj.Source("b", 0.1)
    assert mj.Phase(_T, steps=10, dt=0.01, sources=src).sources == (src,)


def test_run_experiment_argument_errors(tmp_path):
    exp = mj.Experiment("tiny", mj.Initial("paper", (8, 8)), phases=(mj.Phase(_T, steps=20, dt=0.01),))
    with pytest.raises(ValueError, match=r"run_experiment\.stop_after \(steps\) must lie in \[1, \+inf\)"):
        mj.run_experiment(exp, stop_after=0)
    with pytest.raises(ValueError, match=r"run_experiment\.checkpoint_every \(steps\) must lie in \[1"):
        mj.run_experiment(exp, checkpoint_path=tmp_path / "c.npz", checkpoint_every=-1)
    mj.run_experiment(exp, stop_after=10).save(tmp_path / "half.npz")
    other = mj.Experiment("tiny", exp.initial, phases=(mj.Phase(mj.Turing(5.0, 1.0), steps=20, dt=0.01),))
    with pytest.raises(ValueError, match=r"resume: the checkpoint was written by another experiment"):
        mj.run_experiment(other, resume=tmp_path / "half.npz")
    assert int(mj.run_experiment(exp, resume=tmp_path / "half.npz").state.step) == 20


def test_state_errors():
    with pytest.raises(ValueError, match="same shape"):
        mj.State.from_arrays([np.ones((4, 4)), np.ones((4, 5))])
    with pytest.raises(ValueError, match="1D, 2D or 3D array"):
        mj.State.from_arrays([np.ones((4, 4, 2, 2))])
    with pytest.raises(ValueError, match="NaN or infinite"):
        mj.State.from_arrays([np.full((3, 3), np.nan)])
    with pytest.raises(ValueError, match="capacity"):
        mj.State.from_arrays([np.ones((4, 4))], capacity=(3, 8))
    with pytest.raises(ValueError, match="unknown species 'z'"):
        mj.State.from_arrays([np.ones((2, 2))] * 2).array("z")


def test_simulate_argument_errors(state):
    model = mj.Turing(4.0, 3.0)
    with pytest.raises(ValueError, match="unknown boundary 'mirror'.*'wrap', 'no-flux'"):
        mj.simulate(model, state, steps=1, dt=0.01, boundary="mirror")
    with pytest.raises(ValueError, match="unknown stencil"):
        mj.simulate(model, state, steps=1, dt=0.01, stencil="seven")
    with pytest.raises(ValueError, match="steps must be a non-negative integer"):
        mj.simulate(model, state, steps=-3, dt=0.01)
    with pytest.raises(ValueError, match=r"dt must lie in \(0"):
        mj.simulate(model, state, steps=1, dt=0.0)
    with pytest.raises(ValueError, match="dt must not be NaN"):
        mj.simulate(model, state, steps=1, dt=float("nan"))
    with pytest.raises(ValueError, match="evolves 1 species"):
        mj.simulate(mj.Reinforcement(), state, steps=1, dt=0.01)
    with pytest.raises(ValueError, match="parameter map Turing.ratio has shape"):
        mj.simulate(mj.Turing(ratio=np.ones((5, 7))), state, steps=1, dt=0.001)
    with pytest.raises(ValueError, match="unknown bounds"):
        mj.simulate(model, state, steps=1, dt=0.01, bounds="soft")
    with pytest.raises(ValueError, match=r"rollout\.every must lie in \[1, steps = 10\] \(got 20\)"):
        mj.rollout(model, state, steps=10, dt=0.01, every=20)


def test_unstable_dt_reports_the_largest_stable_dt(state):
    model = mj.Turing(ratio=40.0, scale=5.0)  # Da = 200
    limit = 2.0 / (16.0 / 3.0 * 200.0)
    with pytest.raises(ValueError, match=re.escape(f"{limit:.6g}")) as info:
        mj.simulate(model, state, steps=1, dt=0.002)
    assert "check_dt=False" in str(info.value)
    assert mj.max_stable_dt(200.0) == pytest.approx(limit)
    assert mj.max_stable_dt(200.0, "five-point") == pytest.approx(2.0 / (8.0 * 200.0))
    mj.simulate(model, state, steps=1, dt=0.0015)  # the paper's dt for these parameters is fine


def test_barrier_needs_a_state_inside_the_limits(state):
    model = mj.Turing(4.2, 3.0, upper=(4.5, np.inf))
    on_limit = mj.State.from_arrays([np.full((12, 12), 4.0), np.zeros((12, 12))])  # B at its lower limit 0
    with pytest.raises(ValueError, match="strictly inside"):
        mj.simulate(model, on_limit, steps=1, dt=0.0005, bounds="barrier")
    with pytest.raises(ValueError, match="lower limits >= 0"):
        mj.simulate(mj.Turing(4.2, 3.0, lower=(-1.0, 0.0)), state, steps=1, dt=0.0005, bounds="barrier")
    mj.simulate(model, state, steps=1, dt=0.0005, bounds="barrier")  # A = 4 < 4.5 and B >= 4 > 0: fine


def _stepwise_first_bad(model, state, dt, max_steps):
    """Reference: one step at a time until the state is non-finite."""
    s = state
    for i in range(1, max_steps + 1):
        s = mj.simulate(model, s, steps=1, dt=dt, check_dt=False, throw=False)
        if not np.isfinite(np.asarray(s.fields)).all():
            return i
    return None


def test_blowup_reports_the_first_bad_step():
    state = mj.paper_state(jax.random.key(1), (10, 10))
    model = mj.Turing(ratio=4.0, scale=3.0)
    dt = 0.09  # 0.09 * 12 * 16/3 = 5.8 > 2: unstable
    expected = _stepwise_first_bad(model, state, dt, 400)
    assert expected is not None and expected > 1
    with pytest.raises(mj.SimulationError, match=f"at step {expected}\\b"):
        mj.simulate(model, state, steps=400, dt=dt, check_dt=False)
    final, bad, _ = mj.run_status(model, state, steps=400, dt=dt, check_dt=False)
    assert int(bad) == expected
    # in pieces (progress bar) the step is the same
    with pytest.raises(mj.SimulationError, match=f"at step {expected}\\b"):
        mj.simulate(model, state, steps=400, dt=dt, check_dt=False, progress=True)


def test_blowup_in_a_growing_run_reports_the_first_bad_step():
    """A planned growing run only marks the segment that blew up, then re-runs the piece
    to find the step: the state one step earlier must be finite, the state at it not."""
    start = mj.paper_state(jax.random.key(1), (10, 10))
    state = mj.State.from_arrays(start.arrays(), capacity=(120, 120))
    model, dt, key = mj.Turing(ratio=4.0, scale=3.0), 0.09, jax.random.key(2)
    opts = dict(growth=mj.Growth(rate=1.0 / (4 * dt)), key=key, check_dt=False)  # an expansion every 4 steps
    _, bad, overflow = mj.run_status(model, state, steps=400, dt=dt, **opts)
    bad = int(bad)
    assert bad > 8 and not bool(overflow)  # after several expansions
    before = mj.simulate(model, state, steps=bad - 1, dt=dt, throw=False, **opts)
    at = mj.simulate(model, state, steps=bad, dt=dt, throw=False, **opts)
    assert np.isfinite(np.asarray(before.fields)).all() and not np.isfinite(np.asarray(at.fields)).all()
    assert int(at.size[0]) == 10 + (bad + 3) // 4  # expansions at steps 1, 5, 9, ...
    with pytest.raises(mj.SimulationError, match=f"at step {bad}\\b"):
        mj.simulate(model, state, steps=400, dt=dt, **opts)
    with pytest.raises(mj.SimulationError, match=f"at step {bad}\\b"):  # the per-step path agrees
        mj.rollout(model, state, 400, dt, every=50, **opts)


def test_blowup_under_jit_raises():
    state = mj.paper_state(jax.random.key(1), (10, 10))
    run = jax.jit(lambda r: mj.simulate(mj.Turing(r, 3.0), state, steps=300, dt=0.09, check_dt=False).fields)
    with pytest.raises(Exception, match="non-finite"):
        jax.block_until_ready(run(4.0))


def test_blowup_under_vmap_is_recorded_per_member():
    state = mj.paper_state(jax.random.key(1), (10, 10))
    dts = jnp.array([0.01, 0.09])

    def one(dt):
        _, bad, _ = mj.run_status(mj.Turing(4.0, 3.0), state, steps=300, dt=dt, check_dt=False)
        return bad

    bad = jax.vmap(one)(dts)
    assert int(bad[0]) == -1
    assert int(bad[1]) == _stepwise_first_bad(mj.Turing(4.0, 3.0), state, 0.09, 300)

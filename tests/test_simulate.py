"""simulate / rollout behaviour: snapshots, progress pieces, bookkeeping, smooth bounds."""

import jax
import numpy as np
import pytest

import morphojax as mj
from morphojax._descriptors import describe

SHAPE = (20, 24)


@pytest.fixture(scope="module")
def setup():
    model = mj.Turing(ratio=12.0, scale=3.0, lower=(0.0, 3.0))
    state = mj.paper_state(jax.random.key(5), SHAPE)
    return model, state


def test_step_and_time_accounting(setup):
    model, state = setup
    out = mj.simulate(model, state, steps=70, dt=0.008)
    assert int(out.step) == 70 and float(out.time) == pytest.approx(0.56, rel=1e-6)
    out2 = mj.simulate(model, out, steps=30, dt=0.004)
    assert int(out2.step) == 100 and float(out2.time) == pytest.approx(0.68, rel=1e-6)
    same = mj.simulate(model, state, steps=0, dt=0.008)
    np.testing.assert_array_equal(np.asarray(same.fields), np.asarray(state.fields))


def test_split_runs_equal_one_run(setup):
    model, state = setup
    whole = mj.simulate(model, state, steps=100, dt=0.008)
    halves = mj.simulate(model, mj.simulate(model, state, steps=37, dt=0.008), steps=63, dt=0.008)
    np.testing.assert_array_equal(np.asarray(whole.fields), np.asarray(halves.fields))


def test_progress_gives_the_identical_result(setup):
    model, state = setup
    plain = mj.simulate(model, state, steps=6500, dt=0.008)
    shown = mj.simulate(model, state, steps=6500, dt=0.008, progress=True)
    np.testing.assert_array_equal(np.asarray(plain.fields), np.asarray(shown.fields))
    assert int(shown.step) == 6500


@pytest.mark.parametrize("solver", [None, mj.ETDRK(2)], ids=["euler", "etdrk2"])
def test_one_step_pieces_give_the_bits_of_one_call(setup, solver):
    """Steps one call at a time, and a progress bar over few steps (pieces of one step),
    equal one call bit for bit: a loop of one trip, which XLA inlines and fuses with the
    code around it, rounded ETDRK's step differently (by about 1e-6)."""
    model, state = setup
    whole = mj.simulate(model, state, steps=4, dt=0.008, solver=solver)
    single = state
    for _ in range(4):
        single = mj.simulate(model, single, steps=1, dt=0.008, solver=solver)
    np.testing.assert_array_equal(np.asarray(whole.fields), np.asarray(single.fields))
    _, plain = mj.rollout(model, state, 6, 0.008, every=1, solver=solver)
    _, shown = mj.rollout(model, state, 6, 0.008, every=1, progress=True, solver=solver)
    np.testing.assert_array_equal(np.asarray(plain.fields), np.asarray(shown.fields))


def test_status_of_one_call_and_of_pieces(setup):
    """A one-piece run's status comes whole out of the compiled program; a progress bar's
    pieces merge theirs: the same fields, dtypes and values."""
    from morphojax import _loop
    from morphojax._simulate import _prepare

    model, state = setup
    steps = 6500  # a progress bar cuts this into pieces
    one = mj.run_status(model, state, steps, 0.008).status
    domain, cfg, dt, sources, plan, solver = _prepare(model, state, steps, 0.008, None, None, None, "clip", None, (),
                                                      None, True, None, None, None, None)
    final, merged, _ = _loop.drive(model, domain, state, steps, dt, cfg, None, sources, None, None, None, True, None,
                                   None, "pieces", plan, solver)
    assert int(final.step) == steps
    for name in ("nonfinite_step", "overflow", "steady_at", "steps_taken", "incomplete"):
        a, b = getattr(one, name), getattr(merged, name)
        assert a.dtype == b.dtype, name
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert int(one.steps_taken) == steps and int(one.nonfinite_step) == -1 and one.ok is True


@pytest.mark.parametrize("value", [0.1, 0.003, np.float64(0.2), 3, np.float32(0.7), np.array(0.25)])
@pytest.mark.parametrize("dtype", [np.float32, np.float16, jax.numpy.bfloat16])
def test_dt_converted_on_the_host_as_on_the_device(value, dtype):
    """A number's dt, converted on the host and put once, is the value the device
    conversion gave (to the default float, then to the fields' dtype)."""
    from morphojax._checks import as_float_array
    host = as_float_array(value, "dt", dtype)
    device = as_float_array(jax.numpy.asarray(as_float_array(value, "dt")), "dt").astype(dtype)
    assert host.dtype == device.dtype and not host.weak_type
    np.testing.assert_array_equal(np.asarray(host), np.asarray(device))
    with pytest.raises(ValueError, match="real, not complex"):
        as_float_array(1j, "dt", dtype)


def test_rollout_snapshots_match_simulate(setup):
    model, state = setup
    final, frames = mj.rollout(model, state, steps=100, dt=0.008, every=25)
    assert frames.fields.shape == (4, 2) + SHAPE
    np.testing.assert_array_equal(np.asarray(frames.step), [25, 50, 75, 100])
    for i, n in enumerate([25, 50, 75, 100]):
        ref = mj.simulate(model, state, steps=n, dt=0.008)
        np.testing.assert_allclose(frames.frame(i).arrays()[1], ref.arrays()[1], rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(final.fields), np.asarray(frames.fields[-1]))


def test_rollout_saves_a_function_of_the_state(setup):
    model, state = setup
    _, means = mj.rollout(model, state, steps=60, dt=0.008, every=20, save=lambda s: s.fields[1].mean())
    assert means.shape == (3,)
    ref = mj.simulate(model, state, steps=40, dt=0.008).arrays()[1].mean()
    assert float(means[1]) == pytest.approx(float(ref), rel=1e-6)


def test_state_species_bookkeeping(setup):
    _, state = setup
    s3 = state.with_species("c", copy_of="b")
    assert s3.names == ("a", "b", "c")
    np.testing.assert_array_equal(s3.array("c"), state.array("b"))
    s2 = s3.select(["c", "a"])
    assert s2.names == ("c", "a")
    np.testing.assert_array_equal(s2.arrays()[1], state.array("a"))
    roundtrip = mj.State.from_arrays(state.arrays())
    np.testing.assert_array_equal(np.asarray(roundtrip.fields), np.asarray(state.fields))


def test_barrier_gives_a_pattern_like_clipping():
    """Leopard paper 5.4: rational barrier terms with k = 2 and a 20x smaller dt give a
    statistically similar pattern to clipping (same kind, wavelength and dark share).

    Spot counts and areas are left out on purpose: at this size they vary as much between
    two seeds of the clipped model as between clipping and the barrier."""
    cases = [
        mj.Turing(20.0, 3.0, upper=(4.4, np.inf)),  # upper limit on A (barrier from above)
        mj.Turing(12.0, 3.0, lower=(0.0, 3.0)),  # positive lower limit on B (from below)
    ]
    dts = [0.006, 0.008]
    T = 100.0
    for model, dt in zip(cases, dts):
        state = mj.paper_state(jax.random.key(11), (48, 48))
        clip = describe(mj.simulate(model, state, steps=int(T / dt), dt=dt).arrays()[1])
        smooth = describe(mj.simulate(model, state, steps=int(20 * T / dt), dt=dt / 20, bounds="barrier").arrays()[1])
        assert clip.pattern == smooth.pattern == "spots"
        assert smooth.wavelength == pytest.approx(clip.wavelength, rel=0.15)
        assert smooth.dark_fraction == pytest.approx(clip.dark_fraction, abs=0.08)

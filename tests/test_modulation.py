"""Parameter modulation (thesis section 5.3): `Morphogen` and `Modulated` against a NumPy
oracle written from the equations, the explicit-Euler check against the largest modulated
rate, files, gradients, and the thesis's Figs. 5.11-5.12 on a lattice."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import link_oracle
import morphojax as mj

SHAPE = (7, 6)
DT = 0.5
ALPHA, BETA, DB = 16.0, 12.0, 0.02
SP_RANGE = (0.2, 3.0, 0.005, 0.03)  # R from [0.2, 3] onto the scale in [0.005, 0.03]
DA_RANGE = (0.0, 4.0, 0.04, 0.15)  # R from [0, 4] onto U's rate in [0.04, 0.15]
RATE_R, REMOVAL = 0.05, 0.01


def _clamped_map(r, low, high, out_low, out_high):
    return out_low + np.clip((r - low) / (high - low), 0.0, 1.0) * (out_high - out_low)


def _production():
    p = np.zeros(SHAPE)
    p[3, 2] = 2.5
    return p


def oracle_step(a, b, r):
    """One forward-Euler step of U, V (Bard form, scale and U's rate read from R this step)
    and R (production on the producer, zero-order removal, clamped at 0), written from the
    equations; diffusion per link with the harmonic mean of per-cell rates (thesis eq. 4.7)."""
    sp = _clamped_map(r, *SP_RANGE)
    da = _clamped_map(r, *DA_RANGE)
    lap = lambda u, rate: link_oracle.link_term(u, rate, "no-flux", "moore")  # noqa: E731
    a2 = a + DT * (sp * (ALPHA - a * b) + lap(a, da))
    b2 = b + DT * (sp * (a * b - b - BETA) + lap(b, DB))
    r2 = r + DT * (_production() - REMOVAL + lap(r, RATE_R))
    return np.maximum(a2, 0.0), np.maximum(b2, 0.0), np.maximum(r2, 0.0)


def _model():
    inner = mj.Composite((mj.Bard(alpha=ALPHA, beta=BETA, sp=0.01, da=0.04, db=DB),
                          mj.Morphogen(production=_production(), removal=REMOVAL, diffusion=RATE_R)))
    return mj.Modulated(inner, [mj.Modulation("0.sp", "r", *SP_RANGE), mj.Modulation("0.da", "r", *DA_RANGE)])


def _start():
    rng = np.random.default_rng(3)
    return [rng.uniform(2, 6, SHAPE), rng.uniform(2, 6, SHAPE), rng.uniform(0, 5, SHAPE)]


DOMAIN = mj.Lattice("moore", "no-flux")


@pytest.fixture
def x64():
    with jax.enable_x64(True):
        yield


def test_modulated_steps_match_the_oracle():
    a, b, r = _start()
    state = mj.State.from_arrays([a, b, r], names=("a", "b", "r"))
    out = mj.simulate(_model(), state, 3, DT, domain=DOMAIN)
    for _ in range(3):
        a, b, r = oracle_step(a, b, r)
    np.testing.assert_allclose(out.array("a"), a, rtol=2e-5, atol=2e-5)
    np.testing.assert_allclose(out.array("b"), b, rtol=2e-5, atol=2e-5)
    np.testing.assert_allclose(out.array("r"), r, rtol=2e-5, atol=2e-5)


def test_modulation_map_is_clamped_linear_and_at_gives_the_maps():
    m = mj.Modulation("0.sp", "r", 0.2, 3.0, 0.005, 0.03)
    r = jnp.array([-1.0, 0.2, 1.6, 3.0, 10.0])
    np.testing.assert_allclose(m(r), [0.005, 0.005, 0.0175, 0.03, 0.03], rtol=1e-6)
    falling = mj.Modulation("0.sp", "r", 0.0, 1.0, 2.0, 1.0)  # a rising reagent, a falling parameter
    np.testing.assert_allclose(falling(jnp.array([0.0, 0.5, 2.0])), [2.0, 1.5, 1.0], rtol=1e-6)
    state = mj.State.from_arrays(_start(), names=("a", "b", "r"))
    fixed = _model().at(state)  # the wrapped model with this state's maps, for a one-time set
    np.testing.assert_allclose(np.asarray(fixed.parameters()["0.sp"]), _clamped_map(_start()[2], *SP_RANGE),
                               rtol=1e-6)


def test_dt_check_uses_the_largest_modulated_rate():
    """The Moore sum's spectral radius is 12, so dt must stay below 2 / (12 D_max): with U's
    rate modulated up to 0.15 that is 1.11, though the unmodulated rate (0.04) would allow 4.2."""
    model = _model()
    assert float(model.max_diffusion()) == pytest.approx(0.15)
    state = mj.State.from_arrays(_start(), names=("a", "b", "r"))
    with pytest.raises(ValueError, match="dt"):
        mj.simulate(model, state, 1, 1.5, domain=DOMAIN)


def test_bad_modulations_are_clear_errors():
    inner = mj.Composite((mj.Bard(), mj.Morphogen()))
    with pytest.raises(ValueError, match="not a parameter"):
        mj.Modulated(inner, mj.Modulation("scale", "r", 0, 1, 0, 1))
    with pytest.raises(ValueError, match="not a species"):
        mj.Modulated(inner, mj.Modulation("0.sp", "q", 0, 1, 0, 1))
    with pytest.raises(ValueError, match="must differ"):
        mj.Modulation("0.sp", "r", 1.0, 1.0, 0, 1)
    with pytest.raises(ValueError, match="Morphogen.removal"):
        mj.Morphogen(removal=-1.0)
    with pytest.raises(ValueError, match="out_low of '0.da' is not a value it accepts.*diffusion"):
        mj.Modulated(inner, mj.Modulation("0.da", "r", 0, 1, -0.1, 0.2))  # a negative rate
    bounded = mj.Composite((mj.Bard(upper=(np.inf, 6.5)), mj.Morphogen()))
    with pytest.raises(ValueError, match="out_high of '0.lower_b'.*lower must be <= upper"):
        mj.Modulated(bounded, mj.Modulation("0.lower_b", "r", 0, 1, 0.0, 7.0))  # past the upper limit


def test_files_rebuild_the_modulated_model_and_replace_reaches_the_maps():
    model = _model()
    again = mj.model_from_dict(mj.model_to_dict(model))
    assert type(again) is mj.Modulated and [m.parameter for m in again.modulations] == ["0.sp", "0.da"]
    for name, value in model.parameters().items():
        np.testing.assert_array_equal(np.asarray(again.parameters()[name]), np.asarray(value))
    changed = model.replace(**{"modulation0.out_high": 0.05, "0.beta": 11.0})
    assert float(changed.modulations[0].out_high) == pytest.approx(0.05)
    assert float(changed.model.parts[0].beta) == 11.0


def test_gradient_through_a_modulation_matches_finite_differences(x64):
    state = mj.State.from_arrays(_start(), names=("a", "b", "r"))
    weight = jnp.asarray(np.random.default_rng(4).normal(size=SHAPE))

    def loss(out_high, da_high):
        model = _model().replace(**{"modulation0.out_high": out_high, "modulation1.out_high": da_high})
        return jnp.sum(mj.simulate(model, state, 6, DT, domain=DOMAIN).fields[0] * weight)

    args = (0.03, 0.15)
    grads = jax.jit(jax.grad(loss, argnums=(0, 1)))(*args)
    loss = jax.jit(loss)
    for i in range(2):
        up, down = list(args), list(args)
        up[i] += 1e-6
        down[i] -= 1e-6
        fd = (loss(*up) - loss(*down)) / 2e-6
        assert float(grads[i]) == pytest.approx(float(fd), rel=1e-5)
        assert abs(float(grads[i])) > 1e-6  # both modulations matter


def test_thesis_figures_on_a_lattice():
    """Fig. 5.11: the producer's gradient peaks at the centre and falls below the map's
    range at the border. Fig. 5.12: R rises toward the producing bottom row and, after the
    boundary, stays as it was, so U's rate keeps the value it was set to."""
    fig11 = mj.run_experiment(mj.preset("thesis-fig5.11", quick=True), seed=0)
    r = fig11.state.array("r")
    side = r.shape[0]
    assert r[side // 2, side // 2] == r.max() and r[side // 2, side // 2] > 3.0 > r[0, 0]
    fig12 = mj.run_experiment(mj.preset("thesis-fig5.12", quick=True), seed=0, frames=True)
    r12 = fig12.state.array("r")
    assert np.all(np.diff(r12.mean(axis=1)) > 0)  # R rises toward the producers on the bottom row
    boundary = [s for label, s in fig12.frames if label.startswith("gradient")][-1]
    np.testing.assert_array_equal(boundary.array("r"), r12)  # R, and so U's rate, as set at the boundary
    assert np.ptp(boundary.array("a")) > 0 and fig12.state.step == 5000


def test_thesis_moray_eel_spot_is_held_by_its_gradient():
    """Fig. 7.18 on a lattice (quick): P only spreads, so its total stays the 16 units of its
    two starting cells through both phases (no-flux, no production); V's lower limit follows
    P, so wherever P is above the map's range V sits at its limit of 6.5."""
    from morphojax.presets._thesis_animals import EEL_SHAPE, EEL_SPOT, thesis_rows

    eel = mj.run_experiment(mj.preset("thesis-fig7.18", quick=True), seed=0, frames=True)
    for _, state in eel.frames + [("final", eel.state)]:
        if "p" in state.names:
            assert state.array("p").sum() == pytest.approx(16.0, rel=1e-5)
    p, v = eel.state.array("p"), eel.state.array("b")
    held = p >= 0.011
    assert held.sum() > 100 and np.all(v[held] == np.float32(6.5))
    start = thesis_rows(np.isin(np.arange(EEL_SHAPE[0] * EEL_SHAPE[1]), EEL_SPOT), EEL_SHAPE)
    assert np.all(held[start])  # the spot grows around the two cells P started on

"""jit, vmap and grad through `simulate`: gradients against central finite differences."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj

SHAPE = (16, 16)
STEPS = 30
DT = 0.004


def _state(dtype=None):
    rng = np.random.default_rng(3)
    return mj.State.from_arrays([np.full(SHAPE, 4.0), rng.uniform(3.0, 5.0, SHAPE)], dtype=dtype)


def _loss(model, state):
    out = mj.simulate(model, state, steps=STEPS, dt=DT)
    a, b = out.fields[0], out.fields[1]
    return jnp.mean(b**2) + 0.1 * jnp.mean(a * b)


def test_jit_matches_eager():
    model, state = mj.Turing(8.0, 3.0, lower=(0.0, 1.0)), _state()
    eager = mj.simulate(model, state, steps=STEPS, dt=DT)
    jitted = jax.jit(lambda m, s: mj.simulate(m, s, steps=STEPS, dt=DT))(model, state)
    np.testing.assert_array_equal(np.asarray(eager.fields), np.asarray(jitted.fields))
    assert int(jitted.step) == STEPS


def test_vmap_over_ratio_matches_loop():
    state = _state()
    ratios = jnp.array([4.0, 8.0, 12.0])
    batched = jax.vmap(lambda r: mj.simulate(mj.Turing(r, 3.0), state, steps=STEPS, dt=DT).fields)(ratios)
    for i, r in enumerate(ratios):
        single = mj.simulate(mj.Turing(float(r), 3.0), state, steps=STEPS, dt=DT).fields
        np.testing.assert_allclose(np.asarray(batched[i]), np.asarray(single), rtol=1e-6, atol=1e-6)


def test_vmap_over_keys():
    model = mj.Turing(8.0, 3.0)
    keys = jax.random.split(jax.random.key(0), 2)
    out = jax.vmap(lambda k: mj.simulate(model, mj.paper_state(k, SHAPE), steps=STEPS, dt=DT).fields)(keys)
    ref = mj.simulate(model, mj.paper_state(keys[1], SHAPE), steps=STEPS, dt=DT).fields
    np.testing.assert_allclose(np.asarray(out[1]), np.asarray(ref), rtol=1e-6, atol=1e-6)


@pytest.fixture(scope="module")
def x64():
    with jax.enable_x64(True):
        yield


PARAMS = ["ratio", "scale", "lower_b", "upper_a"]


def _model64():
    # B starts in [3, 5): cells clamped at lower_b = 3.5 make A grow into upper_a = 4.05,
    # so both limits are active and reach the loss.
    return mj.Turing(8.0, 3.0, lower=(0.0, 3.5), upper=(4.05, np.inf))


def test_gradients_match_finite_differences(x64):
    """d loss / d (ratio, scale, lower_b, upper_a) after a short run, vs central differences in float64."""
    state = _state(np.float64)
    base = _model64()
    values = {k: base.parameters()[k] for k in PARAMS}

    def loss_of(vals):
        return _loss(base.replace(**vals), state)

    grads = jax.grad(loss_of)(values)
    for name in PARAMS:
        h = 1e-5 * max(1.0, abs(float(values[name])))
        up = loss_of({**values, name: values[name] + h})
        down = loss_of({**values, name: values[name] - h})
        fd = (float(up) - float(down)) / (2 * h)
        g = float(grads[name])
        assert np.isfinite(g)
        assert abs(g) > 1e-8, f"{name}: gradient is zero, the parameter does not reach the loss"
        assert abs(g - fd) <= 1e-5 + 1e-4 * abs(fd), (name, g, fd)


def test_every_public_parameter_gets_a_gradient(x64):
    """Derived coefficients are computed from the public fields: none is silently cut off."""
    state = _state(np.float64)
    for model in [mj.Bard(16.0, 12.0, 1.0, 0.12, 0.03, upper=(6.3, 6.3)), _model64()]:
        params, static = eqx.partition(model, eqx.is_inexact_array)
        grads = jax.grad(lambda p: _loss(eqx.combine(p, static), state))(params)
        for name, g in zip(model._scalar_fields(), [getattr(grads, f) for f in model._scalar_fields()]):
            assert float(jnp.abs(g)) > 0, f"{type(model).__name__}.{name} has a zero gradient"


def test_checkpointed_gradient_equals_plain(x64):
    state = _state(np.float64)
    model = _model64()

    def loss(r, checkpoint):
        out = mj.simulate(model.replace(ratio=r), state, steps=STEPS, dt=DT, checkpoint=checkpoint)
        return jnp.mean(out.fields[1] ** 2)

    plain = jax.grad(loss)(8.0, None)
    ckpt = jax.grad(loss)(8.0, 7)
    np.testing.assert_allclose(float(ckpt), float(plain), rtol=1e-10)


def test_vmap_of_grad_equals_grad_of_vmap(x64):
    state = _state(np.float64)
    ratios = jnp.array([6.0, 9.0])

    def loss(r):
        return jnp.mean(mj.simulate(mj.Turing(r, 3.0), state, steps=STEPS, dt=DT).fields[1] ** 2)

    a = jax.vmap(jax.grad(loss))(ratios)
    b = jax.grad(lambda rs: jnp.sum(jax.vmap(loss)(rs)))(ratios)
    np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-10)


def test_no_recompile_for_new_parameter_values():
    """Parameters are traced arrays: new values reuse the compiled program."""
    state = _state()

    @eqx.filter_jit
    @eqx.debug.assert_max_traces(max_traces=1)
    def run(model, dt):
        return mj.simulate(model, state, steps=STEPS, dt=dt).fields

    for r, s, ub in [(4.0, 3.0, 6.0), (12.0, 2.0, 5.0), (20.0, 1.0, 7.5)]:
        run(mj.Turing(r, s, upper=(ub, np.inf)), jnp.asarray(0.002, jnp.float32))


def test_simulate_itself_compiles_once_per_configuration():
    """Eager calls with new parameter values hit the cache of the compiled core."""
    from morphojax import _loop

    state = _state()
    mj.simulate(mj.Turing(5.0, 2.0), state, steps=17, dt=0.001)
    before = _loop._integrate._cached._cache_size()
    for r in (6.0, 7.0, 9.5):
        mj.simulate(mj.Turing(r, 2.5, lower=(0.0, r / 10)), state, steps=17, dt=0.0011)
    assert _loop._integrate._cached._cache_size() == before

"""The classic reactions (FitzHugh-Nagumo, Gierer-Meinhardt, Schnakenberg, Brusselator) and
the user-written `Reaction`: step for step against the NumPy oracle, gradients, vmap, files,
bad input and the presets' Turing patterns."""

import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
import oracle
from morphojax._files import dumps

SHAPE = (20, 24)  # not square: a transposed axis would show
STEPS = 100
INF = np.inf

# name: (class, parameters, oracle rates, homogeneous state, dt, lower, upper); the limits
# sit inside the start's noise so the clamps act
CASES = {
    "fitzhugh-nagumo": (mj.FitzHughNagumo, dict(a=-0.3, b=0.45, epsilon=0.35, du=0.1, dv=2.0),
                        oracle.fitzhugh_nagumo_rates, (0.0, 0.0), 0.1, (-0.1, -INF), (0.15, INF)),
    "gierer-meinhardt": (mj.GiererMeinhardt, dict(rho=1.0, mu=1.0, nu=2.0, du=0.5, dv=10.0),
                         oracle.gierer_meinhardt_rates, (2.0, 2.0), 0.02, (0.0, 1.9), (2.3, INF)),
    "schnakenberg": (mj.Schnakenberg, dict(a=0.1, b=0.9, du=0.5, dv=10.0),
                     oracle.schnakenberg_rates, (1.0, 0.9), 0.02, (0.9, 0.0), (INF, 0.95)),
    "brusselator": (mj.Brusselator, dict(a=1.5, b=3.0, du=1.0, dv=10.0),
                    oracle.brusselator_rates, (1.5, 2.0), 0.02, (1.4, 0.0), (INF, 2.1)),
}


def _start(steady, shape=SHAPE, seed=3, spread=0.2):
    rng = np.random.default_rng(seed)
    return [s + spread * max(abs(s), 1.0) * rng.uniform(-1.0, 1.0, shape) for s in steady]


def _schnakenberg_fn(x, p):
    u, v = x[0], x[1]
    uuv = u * u * v
    return jnp.stack([p["a"] - u + uuv, p["b"] - uuv])


def _custom_schnakenberg(a=0.1, b=0.9, du=0.5, dv=10.0, lower=0.0, upper=INF):
    return mj.Reaction(_schnakenberg_fn, {"a": a, "b": b}, (du, dv), species=("u", "v"), lower=lower, upper=upper)


# ---- step for step against the oracle ---------------------------------------------------
@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
@pytest.mark.parametrize("name", list(CASES))
def test_matches_oracle_with_clamps(name, boundary):
    cls, params, rates, steady, dt, lower, upper = CASES[name]
    start = _start(steady)
    model = cls(**params, lower=lower, upper=upper)
    got = mj.simulate(model, mj.State.from_arrays(start, names=model.species), steps=STEPS, dt=dt,
                      boundary=boundary).arrays()
    args = tuple(params.values())
    ref = oracle.euler(lambda u, v: rates(u, v, *args, boundary), start, dt, lower, upper, STEPS)
    for g, e in zip(got, ref):
        assert np.abs(np.asarray(g, float) - e).max() < 2e-4 * max(1.0, np.abs(e).max()), name
    # the clamps changed the trajectory, so the check exercised them
    free = oracle.euler(lambda u, v: rates(u, v, *args, boundary), start, dt, (-INF, 1e-3), (INF, INF), STEPS)
    assert max(np.abs(f - e).max() for f, e in zip(free, ref)) > 1e-2


# ---- the user-written form ----------------------------------------------------------------
def test_reaction_reproduces_schnakenberg_exactly():
    start = _start((1.0, 0.9))
    state = mj.State.from_arrays(start, names=("u", "v"))
    limits = dict(lower=(0.9, 0.0), upper=(INF, 0.95))
    ref = mj.simulate(mj.Schnakenberg(a=0.1, b=0.9, du=0.5, dv=10.0, **limits), state, steps=STEPS, dt=0.02)
    got = mj.simulate(_custom_schnakenberg(**limits), state, steps=STEPS, dt=0.02)
    np.testing.assert_array_equal(np.asarray(got.fields), np.asarray(ref.fields))

    def as_list(x, p):  # one array per species also works
        u, v = x
        return [p["a"] - u + u * u * v, p["b"] - u * u * v]

    listed = mj.Reaction(as_list, {"a": 0.1, "b": 0.9}, (0.5, 10.0), species=("u", "v"), **limits)
    again = mj.simulate(listed, state, steps=STEPS, dt=0.02)
    np.testing.assert_allclose(np.asarray(again.fields), np.asarray(ref.fields), rtol=1e-6, atol=1e-6)


def test_reaction_three_species_against_oracle():
    """A linear exchange a -> b -> c -> a with decay of c: n species, per-species limits."""

    def cycle(x, p):
        a, b, c = x
        return jnp.stack([p["k"] * (c - a), p["k"] * (a - b), p["k"] * (b - c) - p["decay"] * c])

    k, decay, D, dt = 0.7, 0.2, (0.1, 0.3, 0.05), 0.1
    model = mj.Reaction(cycle, {"k": k, "decay": decay}, D, lower=0.0, upper=(INF, 1.1, INF))
    assert model.species == ("a", "b", "c")
    start = _start((1.0, 1.0, 1.0))
    got = mj.simulate(model, mj.State.from_arrays(start, names=model.species), steps=STEPS, dt=dt).arrays()

    def rates(a, b, c):
        lap = oracle.laplacian
        return (k * (c - a) + D[0] * lap(a), k * (a - b) + D[1] * lap(b), k * (b - c) - decay * c + D[2] * lap(c))

    ref = oracle.euler(rates, start, dt, (0.0,) * 3, (INF, 1.1, INF), STEPS)
    for g, e in zip(got, ref):
        assert np.abs(np.asarray(g, float) - e).max() < 1e-4


def test_reaction_parameters_and_replace():
    m = _custom_schnakenberg()
    assert list(m.parameters()) == ["a", "b", "diffusion_a", "diffusion_b", "lower_a", "lower_b", "upper_a", "upper_b"]
    r = m.replace(b=1.2, diffusion_v=20.0, lower_u=0.5)  # by letter or by species name
    assert float(r.parameters()["b"]) == pytest.approx(1.2)
    assert np.asarray(r.diffusion()).tolist() == [0.5, 20.0]
    assert float(r.lower[0]) == 0.5 and r.species == ("u", "v")
    assert np.asarray(m.replace(upper=(3.0, 4.0)).upper).tolist() == [3.0, 4.0]
    with pytest.raises(ValueError, match="no parameter 'gamma'"):
        m.replace(gamma=1.0)


def test_reaction_compiles_once_for_new_values():
    state = mj.State.from_arrays(_start((1.0, 0.9), (12, 12)), names=("u", "v"))

    @eqx.filter_jit
    @eqx.debug.assert_max_traces(max_traces=1)
    def run(model):
        return mj.simulate(model, state, steps=5, dt=0.02, check_dt=False).fields

    run(_custom_schnakenberg(a=0.1))
    run(_custom_schnakenberg(a=0.2, b=0.8, dv=12.0))  # a second trace would raise


# ---- transformations ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def x64():
    with jax.enable_x64(True):
        yield


def _gm_loss(model, state):
    out = mj.simulate(model, state, steps=30, dt=0.02)
    return jnp.mean(out.fields[0] ** 2) + 0.5 * jnp.mean(out.fields[1])


def test_gierer_meinhardt_gradients_match_finite_differences(x64):
    """Every public parameter (the five rates and the two limits that act) reaches the loss,
    and d loss / d p matches central differences in float64."""
    state = mj.State.from_arrays(_start((2.0, 2.0), (12, 12)), names=("u", "v"))
    base = mj.GiererMeinhardt(rho=1.0, mu=1.0, nu=2.0, du=0.5, dv=10.0, lower=(0.0, 1.9), upper=(2.3, INF))
    names = ["rho", "mu", "nu", "du", "dv", "lower_b", "upper_a"]
    values = {k: jnp.asarray(base.parameters()[k], jnp.float64) for k in names}

    def loss_of(vals):
        return _gm_loss(base.replace(**vals), state)

    grads = jax.grad(loss_of)(values)
    for name in names:
        h = 1e-5 * max(1.0, abs(float(values[name])))
        fd = (float(loss_of({**values, name: values[name] + h})) - float(loss_of({**values, name: values[name] - h}))) / (2 * h)
        g = float(grads[name])
        assert abs(g) > 1e-8, f"{name}: zero gradient"
        assert abs(g - fd) <= 1e-6 + 1e-4 * abs(fd), (name, g, fd)


def test_every_field_gets_a_gradient(x64):
    """The four models side by side in one Composite (one compiled gradient): every field of
    every model reaches the loss."""
    parts = [cls(**params, lower=lower, upper=upper) for cls, params, _, _, _, lower, upper in CASES.values()]
    model = mj.Composite(parts)
    start = [f for _, _, _, steady, *_ in CASES.values() for f in _start(steady, (10, 10))]
    state = mj.State.from_arrays(start, names=model.species)
    p, static = eqx.partition(model, eqx.is_inexact_array)

    def loss(p):
        return jnp.mean(mj.simulate(eqx.combine(p, static), state, steps=20, dt=0.02).fields ** 2)

    grads = jax.grad(loss)(p)
    for g, (cls, params, *_) in zip(grads.parts, CASES.values()):
        for field in params:
            assert float(jnp.abs(getattr(g, field))) > 0, f"{cls.__name__}.{field} has a zero gradient"


def test_reaction_gradients_equal_the_builtin(x64):
    state = mj.State.from_arrays(_start((1.0, 0.9), (10, 10)), names=("u", "v"))

    def loss(model):
        return jnp.mean(mj.simulate(model, state, steps=20, dt=0.02).fields[0] ** 2)

    g_custom = jax.grad(lambda a, b: loss(_custom_schnakenberg().replace(a=a, b=b)), argnums=(0, 1))(0.1, 0.9)
    g_builtin = jax.grad(lambda a, b: loss(mj.Schnakenberg(a=a, b=b)), argnums=(0, 1))(0.1, 0.9)
    np.testing.assert_allclose(np.asarray(g_custom), np.asarray(g_builtin), rtol=1e-12)
    assert all(abs(float(g)) > 0 for g in g_custom)


@pytest.mark.parametrize("custom", [False, True], ids=["Schnakenberg", "Reaction"])
def test_vmap_over_a_parameter_equals_a_loop(custom):
    state = mj.State.from_arrays(_start((1.0, 0.9), (12, 12)), names=("u", "v"))
    make = (lambda b: _custom_schnakenberg().replace(b=b)) if custom else (lambda b: mj.Schnakenberg(b=b))
    bs = jnp.array([0.8, 0.9, 1.05])
    run = lambda b: mj.simulate(make(b), state, steps=40, dt=0.02).fields
    batched = jax.vmap(run)(bs)
    for i, b in enumerate(bs):
        np.testing.assert_allclose(np.asarray(batched[i]), np.asarray(run(b)), rtol=1e-6, atol=1e-6)


# ---- files and names ----------------------------------------------------------------------
def test_builtins_round_trip_through_files():
    for cls, params, *_ in CASES.values():
        model = cls(**params)
        back = mj.model_from_dict(json.loads(dumps(mj.model_to_dict(model))))
        assert type(back) is cls
        for a, b in zip(jax.tree.leaves(model), jax.tree.leaves(back)):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_reaction_is_recorded_as_not_resumable():
    data = json.loads(dumps(mj.model_to_dict(_custom_schnakenberg())))
    fn = data["params"]["fn"]
    assert fn["resumable"] is False and fn["function"].endswith("_schnakenberg_fn") and fn["species"] == ["u", "v"]
    assert data["params"]["params"] == pytest.approx({"a": 0.1, "b": 0.9})
    with pytest.raises(ValueError, match="cannot rebuild it"):
        mj.model_from_dict(data)


@pytest.mark.parametrize("name", list(CASES))
def test_homogeneous_state_is_a_fixed_point(name):
    cls, params, rates, *_ = CASES[name]
    model = cls(**params)
    steady = [np.full((4, 4), float(v)) for v in model.homogeneous_state()]
    for r in rates(*steady, *params.values()):  # the oracle's rates vanish there
        assert np.abs(r).max() < 1e-6
    assert float(jnp.abs(model.reaction(jnp.stack([jnp.asarray(v, jnp.float32) for v in steady]))).max()) < 1e-5


def test_model_from_name_knows_the_new_models():
    for name, (cls, *_) in CASES.items():
        assert type(mj.model_from_name(name)) is cls
        assert type(mj.model_from_name(cls.__name__)) is cls
    assert float(mj.model_from_name("fitzhugh-nagumo", epsilon=0.5).epsilon) == 0.5
    assert float(mj.FitzHughNagumo().lower[0]) == -INF  # its values go negative
    assert float(mj.GiererMeinhardt().lower[1]) > 0.0  # the reaction divides by v


# ---- bad input ----------------------------------------------------------------------------
@pytest.mark.parametrize("make, match", [
    (lambda: mj.FitzHughNagumo(epsilon=-0.1), r"FitzHughNagumo.epsilon must lie in \[0, \+inf\)"),
    (lambda: mj.FitzHughNagumo(a=float("nan")), "FitzHughNagumo.a must not be NaN"),
    (lambda: mj.GiererMeinhardt(dv=-1.0), r"GiererMeinhardt.dv must lie in \[0, \+inf\)"),
    (lambda: mj.GiererMeinhardt(lower=(0.0, 0.0)), r"GiererMeinhardt.lower of v .* must lie in \(0, \+inf\)"),
    (lambda: mj.Schnakenberg(a=-0.1), r"Schnakenberg.a must lie in \[0, \+inf\)"),
    (lambda: mj.Schnakenberg(lower=(2.0, 0.0), upper=(1.0, INF)), "lower must be <= upper"),
    (lambda: mj.Brusselator(b=INF), "Brusselator.b must be finite"),
    (lambda: mj.Brusselator(lower=(0.0, 0.0, 0.0)), "Brusselator.lower needs 2 values"),
    (lambda: mj.Reaction("not a function", {}, (1.0,)), "Reaction.fn must be a function"),
    (lambda: mj.Reaction(_schnakenberg_fn, {"a": 0.1, "b": 0.9}, (1.0, 1.0, 1.0)), "Reaction.fn must return"),
    (lambda: mj.Reaction(_schnakenberg_fn, {"a": 0.1}, (1.0, 1.0)), "Reaction.fn failed"),
    (lambda: mj.Reaction(_schnakenberg_fn, {"a": 0.1, "lower_x": 1.0}, (1.0, 1.0)), "is taken"),
    (lambda: mj.Reaction(_schnakenberg_fn, {"a": "x", "b": 1.0}, (1.0, 1.0)), r"Reaction.params\['a'\] must be a number"),
    (lambda: mj.Reaction(_schnakenberg_fn, {"a": 0.1, "b": 0.9}, (1.0, -1.0)), r"Reaction.diffusion .* must lie in \[0"),
    (lambda: mj.Reaction(_schnakenberg_fn, {"a": 0.1, "b": 0.9}, 1.0), "species=.* or one diffusion rate per species"),
    (lambda: mj.Reaction(_schnakenberg_fn, {"a": 0.1, "b": 0.9}, (1.0, 1.0), species=("u", "u")), "distinct"),
    (lambda: mj.model_from_name("oregonator"), "unknown model 'oregonator'; allowed: .*brusselator"),
])
def test_bad_input_is_a_value_error(make, match):
    with pytest.raises(ValueError, match=match):
        make()


# ---- the presets ------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["fitzhugh-nagumo", "gierer-meinhardt", "schnakenberg", "brusselator"])
def test_preset_quick_form_makes_a_turing_pattern(name):
    """From the homogeneous state with 1% noise the quick run forms a pattern whose dominant
    wavelength is the linear prediction's 7-9 cells (not uniform, not blown up)."""
    experiment = mj.preset(name, quick=True)
    assert mj.PRESETS[name].figure == "Tinson 2022 section II.C"
    result = mj.run_experiment(experiment, seed=0)
    u = np.asarray(result.state.arrays()[0])
    d = mj.describe(u)
    assert d.finite and d.pattern in ("spots", "inverted spots", "stripes-labyrinth"), d
    assert 5.0 <= d.wavelength <= 12.0, d
    start = np.asarray(experiment.initial.build(jax.random.key(0)).arrays()[0])
    assert d.contrast > 10 * np.ptp(start)  # grown far beyond the start's noise


def test_default_starts_of_the_classic_reactions_are_near_their_steady_state():
    """`initial_state` (what `sweep(shape=...)` and the CLI use) starts each classic reaction
    at its homogeneous state with 1% noise (absolute near 0)."""
    for model in (mj.FitzHughNagumo(), mj.GiererMeinhardt(), mj.Schnakenberg(), mj.Brusselator()):
        state = mj.initial_state(model, jax.random.key(0), (8, 8))
        assert state.names == model.species
        for values, steady in zip(state.arrays(), model.homogeneous_state()):
            spread = 0.01 * max(abs(float(steady)), 1.0)
            assert np.abs(values - float(steady)).max() <= spread * (1 + 1e-6) and values.std() > 0

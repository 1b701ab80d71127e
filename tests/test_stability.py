"""Linear stability (`mj.dispersion`, `mj.turing_space`), homogeneous states within the limits
and Thomas's model: checked against an independent NumPy oracle (`dispersion_oracle`:
dense stencil matrices, reactions from their equations, central differences, eigvals) and
against runs of the simulator itself from the steady state with small noise."""

from __future__ import annotations

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dispersion_oracle as oracle
import morphojax as mj
from morphojax._files import dumps

INF = math.inf

# model, its NumPy reaction and the parameters that reaction takes
CLASSIC = {
    "turing": (mj.Turing(ratio=12.0, scale=3.0), oracle.turing, (12.0, 3.0)),
    "fitzhugh-nagumo": (mj.FitzHughNagumo(), oracle.fitzhugh_nagumo, (-0.3, 0.45, 0.35, 0.1, 2.0)),
    "gierer-meinhardt": (mj.GiererMeinhardt(), oracle.gierer_meinhardt, (1.0, 1.0, 2.0, 0.5, 10.0)),
    "schnakenberg": (mj.Schnakenberg(), oracle.schnakenberg, (0.1, 0.9, 0.5, 10.0)),
    "brusselator": (mj.Brusselator(), oracle.brusselator, (1.5, 3.0, 1.0, 10.0)),
    "thomas": (mj.Thomas(), oracle.thomas, (150.0, 100.0, 1.5, 13.0, 0.05, 0.5, 20.0)),
}
SIM_DT = {"turing": 0.01, "fitzhugh-nagumo": 0.15, "gierer-meinhardt": 0.035, "schnakenberg": 0.02,
          "brusselator": 0.02, "thomas": 0.015}


def _fd_jacobian(name, x):
    _, f, params = CLASSIC[name]
    return oracle.jacobian(lambda y: f(y, *params), x)


# ---- steady states and Jacobians ------------------------------------------------------------
@pytest.mark.parametrize("name", list(CLASSIC))
def test_steady_state_and_jacobian_against_the_oracle(name):
    model, f, params = CLASSIC[name]
    d = mj.dispersion(model, mj.Lattice(), (8, 8))
    x = np.asarray(d.steady_state, float)
    assert bool(d.converged)
    fd = _fd_jacobian(name, x)
    # the reaction vanishes there, to the float32 rounding of the state
    assert np.abs(f(x, *params)).max() < 1e-5 * (1 + np.abs(x).max()) * (1 + np.abs(fd).max())
    np.testing.assert_allclose(np.asarray(d.jacobian), fd, rtol=2e-4, atol=2e-4 * np.abs(fd).max())


def test_thomas_state_is_the_root_of_its_cubic():
    states = oracle.thomas_states(150.0, 100.0, 1.5, 13.0, 0.05)
    assert len(states) == 1
    u, v = mj.Thomas().homogeneous_state()
    np.testing.assert_allclose([float(u), float(v)], states[0], rtol=1e-5)
    # over a range of K, a one-root cubic's root every time, under vmap
    Ks = np.array([0.0, 0.02, 0.1, 0.3])
    us, vs = jax.vmap(lambda K: mj.Thomas(K=K).homogeneous_state())(jnp.asarray(Ks))
    for K, u, v in zip(Ks, np.asarray(us), np.asarray(vs)):
        roots = oracle.thomas_states(150.0, 100.0, 1.5, 13.0, K)
        assert any(np.allclose([u, v], r, rtol=1e-4) for r in roots), (K, roots)


def test_homogeneous_state_of_every_model_is_steady_under_the_clamped_step():
    def fn(x, p):
        u, v = x
        return jnp.stack([p["a"] - u + u * u * v, p["b"] - u * u * v])

    models = [cls() for cls in mj.models.MODELS.values()] + [
        mj.Morphogen(production=0.3, decay=0.1), mj.Morphogen(removal=0.2),
        mj.Composite((mj.Turing(), mj.Reinforcement())),
        mj.Reaction(fn, {"a": 0.1, "b": 0.9}, (0.5, 10.0), species=("u", "v")),
        mj.Modulated(mj.Composite((mj.Bard(), mj.Morphogen(production=0.1, decay=0.1))),
                     mj.Modulation("0.sp", by="r", low=0.0, high=2.0, out_low=0.5, out_high=1.5)),
    ]
    for model in models:
        x = jnp.stack([jnp.asarray(v, jnp.float32).reshape(1, 1) for v in model.homogeneous_state()])
        assert x.shape[0] == model.n_species, type(model).__name__
        lo, hi = (np.asarray(v, float).reshape(-1, 1, 1) for v in (model.lower, model.upper))
        step = np.clip(np.asarray(x) + 0.1 * np.asarray(model.reaction(x)), lo, hi)  # one clamped step
        np.testing.assert_allclose(step, np.asarray(x), atol=1e-5 * (1 + np.abs(np.asarray(x)).max()),
                                   err_msg=type(model).__name__)


def test_states_respect_the_limits_or_say_there_is_none():
    # Ua = 4: the state (4, 4) lies on a's upper limit, which the dispersion flags
    d = mj.dispersion(mj.Turing(ratio=40, scale=3.0, upper=(4.0, INF)), mj.Lattice(), (16, 16))
    assert bool(d.converged) and np.asarray(d.at_limit).tolist() == [True, False]
    # a removal larger than production with no decay: held at the lower limit 0
    assert float(mj.Morphogen(removal=1.0).homogeneous_state()[0]) == 0.0
    # Ua = 3.5 < 4: the reaction pulls a back below the limit, so the clamp holds nothing
    with pytest.raises(ValueError, match=r"Turing.homogeneous_state: no steady state within the limits"):
        mj.Turing(upper=(3.5, INF)).homogeneous_state()
    d = mj.dispersion(mj.Turing(ratio=12, scale=3.0, upper=(3.5, INF)), mj.Lattice(), (16, 16))
    assert not bool(d.converged) and not bool(d.turing_unstable) and math.isnan(float(d.fastest_wavelength))
    with pytest.raises(ValueError, match="no steady state"):  # production without decay or limit
        mj.Morphogen(production=1.0).homogeneous_state()


def test_fastest_wavelength_is_nan_for_a_stable_state():
    """Turing r = 3 < 4 (the threshold): the state (4, 4) is found, stable without
    diffusion, and every mode decays (checked by hand: det(J + mu D) > 0 and trace < 0 for
    all mu <= 0), so no mode is fastest-growing."""
    d = mj.dispersion(mj.Turing(ratio=3.0, scale=3.0), mj.Lattice(), (32, 32))
    assert bool(d.converged) and float(d.kinetic_rate) < 0 and float(d.fastest_rate) < 0
    assert not bool(d.turing_unstable)
    assert math.isnan(float(d.fastest_wavelength))
    assert math.isnan(d.python()["fastest_wavelength"])


def test_gray_scott_states_from_a_guess():
    F, k = 0.03, 0.01
    assert [float(v) for v in mj.GrayScott(feed=F, kill=k).homogeneous_state()] == [1.0, 0.0]
    root = math.sqrt(F * F - 4 * F * (F + k) ** 2)
    for sign in (1, -1):
        v = (F + sign * root) / (2 * (F + k))
        got = mj.GrayScott(feed=F, kill=k).homogeneous_state(guess=((F + k) / v * 1.05, v * 0.95))
        np.testing.assert_allclose([float(g) for g in got], [(F + k) / v, v], rtol=1e-4)


# ---- the modes and their rates --------------------------------------------------------------
@pytest.mark.parametrize("stencil", ["nine-point", "five-point", "moore"])
@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_modes_are_the_stencils_own_waves(stencil, boundary):
    """Every mode's eigenvalue and wavelength: the dense stencil matrix maps the mode's wave
    to eigenvalue x wave, and the wave's period is the wavelength reported."""
    shape = (6, 8)
    d = mj.dispersion(mj.Turing(ratio=12, scale=0.05), mj.Lattice(stencil, boundary), shape)
    matrix = oracle.stencil_matrix(stencil, boundary, shape)
    eig, lengths = np.asarray(d.eigenvalues, float), np.asarray(d.wavelengths, float)
    for kr, kc in np.ndindex(eig.shape):
        w = oracle.wave(shape, boundary, kr, kc).ravel()
        np.testing.assert_allclose(matrix @ w, eig[kr, kc] * w, atol=1e-5)
        assert lengths[kr, kc] == pytest.approx(oracle.period(shape, boundary, kr, kc), rel=1e-5)
    # and the modes are all of them: their eigenvalues are those of the dense matrix
    dense = np.linalg.eigvals(matrix).real
    np.testing.assert_allclose(np.unique(np.round(eig.ravel(), 5)), np.unique(np.round(dense, 5)), atol=2e-5)


@pytest.mark.parametrize("name", ["turing", "thomas", "brusselator"])
@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_rates_against_the_oracle(name, boundary):
    model = CLASSIC[name][0]
    shape = (10, 12)
    d = mj.dispersion(model, mj.Lattice("nine-point", boundary), shape)
    jac = _fd_jacobian(name, np.asarray(d.steady_state, float))
    diffusion = np.asarray(model.diffusion(), float)
    matrix = oracle.stencil_matrix("nine-point", boundary, shape)
    rates = np.asarray(d.rates, float)
    for kr, kc in np.ndindex(rates.shape):
        w = oracle.wave(shape, boundary, kr, kc).ravel()
        mu = float(w @ matrix @ w / (w @ w))  # the oracle's own eigenvalue of the mode
        expected = oracle.growth_rate(jac, diffusion, mu)
        assert rates[kr, kc] == pytest.approx(expected, rel=1e-3, abs=1e-3 * np.abs(jac).max())
    assert float(d.fastest_rate) == pytest.approx(rates.max())
    fastest = np.unravel_index(np.argmax(rates), rates.shape)
    assert float(d.fastest_wavelength) == pytest.approx(oracle.period(shape, boundary, *fastest), rel=1e-5)


def test_three_species_rates_use_the_general_eigenvalues():
    model = mj.Composite((mj.Turing(ratio=12, scale=3.0), mj.Morphogen(production=1.0, decay=0.5)))
    d = mj.dispersion(model, mj.Lattice(), (8, 8))
    two = mj.dispersion(mj.Turing(ratio=12, scale=3.0), mj.Lattice(), (8, 8))
    # the signal decays at its own rate -(0.5 + 0.1 |mu|) (its default diffusion 0.1),
    # independently of the Turing pair: each mode's rate is the larger of the two
    signal = -0.5 + 0.1 * np.asarray(two.eigenvalues)
    np.testing.assert_allclose(np.asarray(d.rates), np.maximum(np.asarray(two.rates), signal), rtol=1e-5, atol=1e-5)
    assert (signal > np.asarray(two.rates)).any()  # the check sees both
    assert np.asarray(d.jacobian).shape == (3, 3)


def test_thresholds_of_the_continuum_curve():
    """Turing's r > 4 (sqrt r = (4 + sqrt 64) / 6 = 2) and Murray's d_c = 27.0 for Thomas."""
    k = jnp.linspace(0.01, 3.0, 3000)
    for r, unstable in ((3.9, False), (4.1, True)):
        assert (float(jnp.max(mj.dispersion(mj.Turing(ratio=r, scale=3.0), mj.Lattice(), (8, 8)).curve(k))) > 0) \
            is unstable
    for dv, unstable in ((26.5, False), (27.5, True)):
        curve = mj.dispersion(mj.Thomas(du=1.0, dv=dv), mj.Lattice(), (8, 8)).curve(k)
        assert (float(jnp.max(curve)) > 0) is unstable


def test_thomas_defaults_are_turing_unstable():
    d = mj.dispersion(mj.Thomas(), mj.Lattice(), (64, 64))
    assert bool(d.turing_unstable) and float(d.kinetic_rate) < 0
    assert 6.0 <= float(d.fastest_wavelength) <= 10.0
    assert mj.Thomas().n_species == 2 and type(mj.model_from_name("thomas")) is mj.Thomas
    back = mj.model_from_dict(json.loads(dumps(mj.model_to_dict(mj.Thomas(K=0.1)))))
    assert type(back) is mj.Thomas and float(back.K) == pytest.approx(0.1)
    with pytest.raises(ValueError, match=r"Thomas.alpha .* must lie in \(0, \+inf\)"):
        mj.Thomas(alpha=0.0)
    with pytest.raises(ValueError, match=r"Thomas.K must lie in \[0, \+inf\)"):
        mj.Thomas(K=-1.0)


def test_thomas_preset_settles_near_the_predicted_wavelength():
    experiment = mj.preset("thomas", quick=True)
    assert mj.PRESETS["thomas"].figure == "Tinson 2022 section II.C"
    u = np.asarray(mj.run_experiment(experiment, seed=0).state.arrays()[0])
    d = mj.describe(u)
    assert d.finite and d.pattern in ("spots", "inverted spots"), d
    predicted = float(mj.dispersion(mj.Thomas(), mj.Lattice(), u.shape).fastest_wavelength)
    assert d.wavelength == pytest.approx(predicted, rel=0.2)


def test_thomas_gradients_reach_every_parameter():
    state = mj.State.from_arrays([np.full((6, 6), 37.0), np.linspace(24.0, 26.0, 36).reshape(6, 6)])

    def loss(p):
        return jnp.sum(mj.Thomas(**p).reaction(state.fields) ** 2)

    p = {k: jnp.asarray(float(v)) for k, v in mj.Thomas().parameters().items() if not k.startswith(("lower", "upper"))}
    grads = jax.grad(loss)(p)
    for name in ("a", "b", "alpha", "rho", "K"):
        assert float(grads[name]) != 0.0, name


def test_gradients_of_the_rates_and_the_state_match_central_differences():
    """The steady state differentiates by the implicit function theorem (one live Newton
    step from the root), so the fastest rate and the state have gradients."""
    cases = [
        (lambda r: mj.dispersion(mj.Turing(ratio=r, scale=3.0), mj.Lattice(), (32, 32)).fastest_rate, 12.0, 1e-2),
        (lambda a: mj.dispersion(mj.Brusselator(a=a), mj.Lattice(), (32, 32)).fastest_rate, 1.5, 1e-3),
        (lambda K: mj.dispersion(mj.Thomas(K=K), mj.Lattice(), (32, 32)).fastest_rate, 0.05, 1e-4),
        (lambda K: mj.Thomas(K=K).homogeneous_state()[0], 0.05, 1e-4),
        (lambda lb: mj.Morphogen(removal=1.0, lower=lb).homogeneous_state()[0], 0.5, 1e-3),  # held on it: 1
    ]
    for f, x, h in cases:
        grad = float(jax.grad(f)(x))
        fd = (float(f(x + h)) - float(f(x - h))) / (2 * h)
        assert grad == pytest.approx(fd, rel=2e-3, abs=1e-4), (x, grad, fd)
        assert grad != 0.0


def test_one_and_three_dimensional_lattices():
    """The three-point stencil's modes on a 12-cell ring are 2 cos(2 pi k / 12) - 2 with
    wavelength 12 / k; a 3D lattice's rates match the 2D formula of the same eigenvalue."""
    d = mj.dispersion(mj.Schnakenberg(), mj.Lattice("three-point"), (12,))
    k = np.arange(7)
    np.testing.assert_allclose(np.asarray(d.eigenvalues, float), 2 * np.cos(2 * np.pi * k / 12) - 2, atol=1e-6)
    np.testing.assert_allclose(np.asarray(d.wavelengths, float)[1:], 12 / k[1:], rtol=1e-6)
    d3 = mj.dispersion(mj.Schnakenberg(), mj.Lattice("nineteen-point"), (6, 6, 6))
    jac = _fd_jacobian("schnakenberg", np.asarray(d3.steady_state, float))
    mu = np.asarray(d3.eigenvalues, float).ravel()
    expected = [oracle.growth_rate(jac, (0.5, 10.0), m) for m in mu]
    np.testing.assert_allclose(np.asarray(d3.rates, float).ravel(), expected, rtol=1e-3, atol=1e-4)


def test_vmap_over_parameters_matches_one_by_one():
    ratios = jnp.asarray([3.0, 4.2, 12.0, 40.0])
    batched = jax.vmap(lambda r: mj.dispersion(mj.Turing(ratio=r, scale=3.0), mj.Lattice(), (32, 32)))(ratios)
    for i, r in enumerate(np.asarray(ratios)):
        one = mj.dispersion(mj.Turing(ratio=float(r), scale=3.0), mj.Lattice(), (32, 32))
        assert bool(batched.turing_unstable[i]) == bool(one.turing_unstable)
        np.testing.assert_allclose(np.asarray(batched.rates[i]), np.asarray(one.rates), rtol=1e-5, atol=1e-6)
        np.testing.assert_array_equal(np.asarray(batched.fastest_wavelength[i]), np.asarray(one.fastest_wavelength))
    assert not bool(batched.turing_unstable[0]) and bool(batched.turing_unstable[-1])


def test_mesh_modes_are_the_generalised_eigenproblem():
    """A mesh's modes against a dense generalised eigensolve (scipy.linalg.eigh with the
    lumped masses) of the operator rebuilt from its tables; and on a sphere of radius R
    the l = 1 and l = 2 harmonics' l (l + 1) / R^2."""
    import scipy.linalg

    mesh = mj.Mesh.icosphere(2, radius=5.0)
    d = mj.dispersion(mj.Turing(ratio=12, scale=0.05), mesh, modes=12)
    n = mesh.n_vertices
    w = np.zeros((n, n))
    table, weights = np.asarray(mesh.neighbours), np.asarray(mesh.weights, float)
    for slot in range(table.shape[0]):
        np.add.at(w, (np.arange(n), table[slot]), weights[slot])
    np.fill_diagonal(w, 0.0)
    stiffness = np.diag(w.sum(1)) - w
    masses = 1.0 / np.asarray(mesh.inverse_mass, float)
    dense = scipy.linalg.eigh(stiffness, np.diag(masses), eigvals_only=True)[:12]
    np.testing.assert_allclose(-np.asarray(d.eigenvalues, float), dense, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(dense[1:4], 2 / 25, rtol=0.03)
    np.testing.assert_allclose(dense[4:9], 6 / 25, rtol=0.03)
    assert math.isinf(float(d.wavelengths[0]))
    assert float(d.wavelengths[1]) == pytest.approx(2 * np.pi / math.sqrt(dense[1]), rel=1e-4)


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_hexagonal_modes_are_its_operators_eigenvalues(boundary):
    """A hexagonal lattice's modes against the eigenvalues of the dense operator that
    `hex_oracle` assembles from the odd-r neighbours, and the rates against eigvals."""
    import hex_oracle

    shape = (6, 5)
    d = mj.dispersion(mj.Thomas(), mj.HexLattice(boundary), shape)
    dense = np.sort(np.linalg.eigvals(hex_oracle.hex_matrix(shape, boundary, "laplacian")).real)[::-1]
    np.testing.assert_allclose(np.asarray(d.eigenvalues, float), dense, atol=1e-5)
    jac = _fd_jacobian("thomas", np.asarray(d.steady_state, float))
    expected = [oracle.growth_rate(jac, (0.5, 20.0), mu) for mu in dense]
    np.testing.assert_allclose(np.asarray(d.rates, float), expected, rtol=1e-3, atol=1e-3)


def test_bad_input_is_a_value_error():
    with pytest.raises(ValueError, match="needs its shape"):
        mj.dispersion(mj.Turing(), mj.Lattice())
    with pytest.raises(ValueError, match="parameter maps"):
        mj.dispersion(mj.Turing(ratio=np.full((4, 4), 12.0)), mj.Lattice(), (4, 4))
    with pytest.raises(ValueError, match="anisotropic"):
        mj.dispersion(mj.Turing(), mj.Lattice(anisotropic="a", polarity=0.3), (4, 4))
    with pytest.raises(ValueError, match="modes= counts a Mesh's lowest modes"):
        mj.dispersion(mj.Turing(), mj.Lattice(), (4, 4), modes=3)
    with pytest.raises(ValueError, match="turing_space: unknown parameter 'speed'"):
        mj.turing_space(mj.Turing(), mj.Lattice(), vary={"speed": [1.0]}, shape=(8, 8))
    with pytest.raises(ValueError, match="'dt' is a run's setting"):
        mj.turing_space(mj.Turing(), mj.Lattice(), vary={"dt": [0.1]}, shape=(8, 8))
    with pytest.raises(ValueError, match=r"turing_space member 1 \(ratio=-1\)"):
        mj.turing_space(mj.Turing(), mj.Lattice(), vary={"ratio": [1.0, -1.0]}, shape=(8, 8))


# ---- Turing spaces --------------------------------------------------------------------------
def test_turing_space_agrees_with_dispersion_member_by_member(tmp_path):
    ratios, uppers = [3.0, 4.2, 12.0, 40.0], [3.5, 4.0, INF]
    space = mj.turing_space(mj.Turing(scale=3.0), mj.Lattice(), vary={"ratio": ratios, "upper_a": uppers},
                            shape=(24, 24))
    assert space.shape == (4, 3) and space.unstable.dtype == bool
    for i, r in enumerate(ratios):
        for j, ua in enumerate(uppers):
            one = mj.dispersion(mj.Turing(ratio=r, scale=3.0, upper=(ua, INF)), mj.Lattice(), (24, 24))
            assert space.unstable[i, j] == bool(one.turing_unstable)
            assert space.converged[i, j] == bool(one.converged)
            np.testing.assert_allclose(space.wavelength[i, j], float(one.fastest_wavelength), rtol=1e-6)
    assert not space.converged[:, 0].any()  # Ua = 3.5: no steady state
    assert space.at_limit[:, 1, 0].all() and not space.at_limit[:, 2, 0].any()  # Ua = 4 holds a = 4
    np.testing.assert_array_equal(space.column("ratio")[:, 0], ratios)
    written = space.save(tmp_path / "space.png")
    assert written["png"].stat().st_size > 0
    rows = written["csv"].read_text().splitlines()
    assert rows[0].split(",")[:4] == ["member", "ratio", "upper_a", "unstable"] and len(rows) == 13
    # a list of sets and a large plane draw too
    listed = mj.turing_space(mj.Schnakenberg(), mj.Lattice(), vary=[{"a": 0.1}, {"a": 0.3, "b": 1.5}], shape=(16, 16))
    assert listed.shape == (2,) and listed.unstable.tolist() == [True, False]
    listed.save(tmp_path / "list.png")
    plane = mj.turing_space(mj.Thomas(), mj.Lattice(), vary={"dv": np.linspace(5, 40, 20), "K": np.linspace(0, 0.1, 18)},
                            shape=(16, 16))
    assert plane.unstable.any() and not plane.unstable.all()
    assert plane.image().width > 100


def test_turing_space_marks_states_on_and_beyond_a_limit(tmp_path):
    """Ua = 4 holds a on its limit 4 (the state (4, 4)): the table's at_limit is True and
    the picture hatches that member only; Ua = 3.5 lies below the reaction's own a = 4, so
    there is no state within the limits, reported as beyond_limit and drawn in its colour."""
    import dataclasses

    from morphojax import _turing_space as ts

    space = mj.turing_space(mj.Turing(scale=3.0), mj.Lattice(), vary={"ratio": [12.0, 40.0], "upper_a": [3.5, 4.0, INF]},
                            shape=(24, 24))
    table = {(r["ratio"], r["upper_a"]): r for r in space.table()}
    for ratio in (12.0, 40.0):
        assert [table[ratio, ua]["at_limit"] for ua in (3.5, 4.0, INF)] == [False, True, False]
        assert [table[ratio, ua]["beyond_limit"] for ua in (3.5, 4.0, INF)] == [True, False, False]
        assert table[ratio, 4.0]["unstable"] and table[ratio, 4.0]["converged"]
    # lower limits too: Lb = 4 holds b on it, Lb = 4.5 lies above the reaction's own b = 4
    lb = mj.turing_space(mj.Turing(ratio=12.0, scale=3.0), mj.Lattice(), vary={"lower_b": [0.0, 4.0, 4.5]},
                         shape=(16, 16))
    assert lb.limited().tolist() == [False, True, False] and lb.beyond_limit.tolist() == [False, False, True]
    csv_rows = space.save(tmp_path / "space.png")["csv"].read_text().splitlines()
    header = csv_rows[0].split(",")
    assert header[-2:] == ["at_limit", "beyond_limit"]
    assert [r.split(",")[-2] for r in csv_rows[1:4]] == ["false", "true", "false"]

    def pixels(s):
        return np.asarray(s.image(), int)

    marked = pixels(space)
    flags = space.at_limit.copy()
    flags[0, 1] = False  # (12, Ua = 4) drawn unmarked
    on_limit = (pixels(dataclasses.replace(space, at_limit=flags)) != marked).any(-1)
    flags = space.at_limit.copy()
    flags[0, 2, 0] = True  # (12, no limit) drawn marked
    off_limit = (pixels(dataclasses.replace(space, at_limit=flags)) != marked).any(-1)
    assert on_limit.any() and off_limit.any() and not (on_limit & off_limit).any()
    # the marked member's differing pixels are the hatching (the wavelength's text is written over it)
    assert (marked[on_limit] == ts.HATCH).all(-1).mean() > 0.8
    # the tiles are in Ua's order: the member without a limit lies right of the one on it
    assert np.nonzero(off_limit)[1].min() > np.nonzero(on_limit)[1].max()
    assert (marked == ts.BEYOND).all(-1).sum() > 2 * ts.TILE ** 2 - 100  # the two Ua = 3.5 tiles
    # a heat map (larger than LABELLED) hatches its Ua = 4 column and nothing else
    plane = mj.turing_space(mj.Turing(scale=3.0), mj.Lattice(), vary={"ratio": np.linspace(5, 40, 20),
                            "upper_a": [4.0] + [6.0] * 19}, shape=(16, 16))
    assert plane.limited()[:, 0].all() and not plane.limited()[:, 1:].any()
    heat = pixels(plane)
    cleared = pixels(dataclasses.replace(plane, at_limit=np.zeros_like(plane.at_limit)))
    hatch = (heat != cleared).any(-1)
    assert hatch.any() and (heat[hatch] == ts.HATCH).all(-1).mean() > 0.99  # (an axis label's edge over it)
    assert np.ptp(np.nonzero(hatch)[1]) < heat.shape[1] / 10  # one column of twenty


def test_turing_space_chunks_share_one_compiled_program(monkeypatch):
    """Members run CHUNK at a time, the last chunk padded with its last member, so every
    chunk reuses one traced program; results equal the unchunked ones."""
    from morphojax import _turing_space

    vary = {"ratio": np.linspace(3.0, 40.0, 10)}
    whole = mj.turing_space(mj.Turing(scale=3.0), mj.Lattice(), vary=vary, shape=(16, 16))
    traces = []
    inner = _turing_space.linear_stability
    monkeypatch.setattr(_turing_space, "linear_stability", lambda *a: traces.append(1) or inner(*a))
    monkeypatch.setattr(_turing_space, "CHUNK", 4)
    chunked = mj.turing_space(mj.Turing(scale=3.0), mj.Lattice(), vary=vary, shape=(16, 16))
    assert len(traces) == 1  # three chunks (4, 4, 2 + 2 padding), one trace
    np.testing.assert_array_equal(chunked.unstable, whole.unstable)
    np.testing.assert_allclose(chunked.wavelength, whole.wavelength, rtol=1e-6)
    np.testing.assert_allclose(chunked.rate, whole.rate, rtol=1e-6)


# ---- the simulator agrees with the prediction -----------------------------------------------
def _dominant_wavelength(u):
    """1 / the power-weighted mean |frequency| (cycles per cell) of u's deviation: the
    dominant wavelength of a field whose spectrum is one band."""
    p = np.abs(np.fft.fft2(u - u.mean())) ** 2
    fr, fc = np.meshgrid(np.fft.fftfreq(u.shape[0]), np.fft.fftfreq(u.shape[1]), indexing="ij")
    return 1.0 / float((p * np.hypot(fr, fc)).sum() / p.sum())


@pytest.mark.parametrize("name", list(CLASSIC))
def test_simulated_wavelength_follows_the_prediction_while_linear(name):
    """From the steady state with noise of 1e-4 (relative), the run's dominant wavelength
    after the fastest mode grew about e^7 is the prediction's within 10%; the perturbation is
    still linear: small, and growing at about the fastest rate between half time and the end."""
    model = CLASSIC[name][0]
    n, dt = 64, SIM_DT[name]
    d = mj.dispersion(model, mj.Lattice(), (n, n))
    assert bool(d.turing_unstable)
    x = np.asarray(d.steady_state, float)
    amp = 1e-4 * np.maximum(np.abs(x), 1.0)
    rng = np.random.default_rng(3)
    state = mj.State.from_arrays([x[i] + amp[i] * rng.uniform(-1, 1, (n, n)) for i in range(2)], names=model.species)
    half = int(round(3.5 / float(d.fastest_rate) / dt))
    middle = mj.simulate(model, state, half, dt)
    end = mj.simulate(model, middle, half, dt)
    u_mid, u_end = (np.asarray(s.arrays()[0], float) for s in (middle, end))
    wavelength = _dominant_wavelength(u_end)
    assert wavelength == pytest.approx(float(d.fastest_wavelength), rel=0.10)
    deviation = np.abs(u_end - x[0]).max()
    assert deviation < 0.1 * max(abs(x[0]), 1.0)  # still small
    measured = math.log(np.std(u_end) / np.std(u_mid)) / (half * dt)
    assert 0.75 * float(d.fastest_rate) <= measured <= 1.05 * float(d.fastest_rate)

"""Diffusion on the square lattice's links: per-cell rates in flux form (thesis eq. 4.7) and
anisotropic diffusion along a polarity (eq. 4.8), against the NumPy oracle in link_oracle.py;
thesis Figs. 5.1 and 5.13."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
from morphojax import _serialise
from morphojax.presets._anisotropy import FIG5_1_AMOUNT, fig5_1_rates

import link_oracle as oracle

STENCILS = ("nine-point", "five-point", "moore")
BOUNDARIES = ("wrap", "no-flux")
SHAPE = (12, 12)


@pytest.fixture
def x64():
    with jax.enable_x64(True):
        yield


def _inputs(shape=SHAPE, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.uniform(3.0, 5.0, shape)
    rate = rng.uniform(0.0, 1.0, shape)
    rate[rng.random(shape) < 0.1] = 0.0  # impermeable cells
    angle = rng.uniform(-np.pi, np.pi, shape)
    angle[rng.random(shape) < 0.2] = np.nan  # unpolarised cells
    return u, rate, angle


def _term(domain, u, rate):
    """The domain's diffusion term of one species `u` with rate `rate` (number or map)."""
    u = jnp.asarray(u)[None]
    rates = jnp.asarray(rate, u.dtype).reshape((1,) + (np.shape(rate) or (1, 1)))
    return domain.diffusion(domain.carry(u, jnp.asarray(u.shape[1:]), False), rates)[0]


# ---- operators against the oracle ---------------------------------------------------------------
@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("stencil", STENCILS)
def test_link_operators_against_oracle(x64, stencil, boundary):
    u, rate, angle = _inputs()
    cases = [  # (domain, rate, the oracle's angle)
        (mj.Lattice(stencil, boundary), rate, None),  # flux form of a map
        (mj.Lattice(stencil, boundary, anisotropic="a", polarity=0.7), 0.6, 0.7),  # one polarity
        (mj.Lattice(stencil, boundary, anisotropic=(0,), polarity=angle), rate, angle),  # per cell, some NaN
    ]
    for domain, d, a in cases:
        got = np.asarray(_term(domain, u, d))
        np.testing.assert_allclose(got, oracle.link_term(u, d, boundary, stencil, a), atol=1e-12)


@pytest.mark.parametrize("boundary", BOUNDARIES)
def test_pointwise_maps_and_scalar_rates_keep_the_stencil(x64, boundary):
    """maps='pointwise' is D(x) lap(u); a scalar rate takes the stencil's own path, bit for
    bit, whatever the maps option; species not declared anisotropic ignore the polarity."""
    u, rate, angle = _inputs(seed=1)
    lap = np.asarray(mj.laplacian(u, boundary))
    np.testing.assert_array_equal(np.asarray(_term(mj.Lattice(boundary=boundary, maps="pointwise"), u, rate)),
                                  np.asarray(rate * jnp.asarray(lap)))
    for domain in (mj.Lattice(boundary=boundary), mj.Lattice(boundary=boundary, maps="pointwise")):
        np.testing.assert_array_equal(np.asarray(_term(domain, u, 0.3)), np.asarray(0.3 * jnp.asarray(lap)))
    aniso_b = mj.Lattice(boundary=boundary, anisotropic="b", polarity=angle)
    two = jnp.asarray(np.stack([u, u]))
    terms = aniso_b.diffusion(aniso_b.carry(two, jnp.asarray(SHAPE), False), jnp.asarray([0.3, 0.3]).reshape(2, 1, 1))
    np.testing.assert_array_equal(np.asarray(terms[0]), np.asarray(0.3 * jnp.asarray(lap)))
    assert np.abs(np.asarray(terms[1]) - np.asarray(terms[0])).max() > 1e-3


@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("stencil", STENCILS)
def test_isotropic_limit_is_the_plain_stencil(x64, stencil, boundary):
    """No polarity: an anisotropic species diffuses as the stencil (exactly: the same path);
    all cells unpolarised, or a constant map in flux form: the stencil to rounding."""
    u, _, _ = _inputs(seed=2)
    plain = np.asarray(_term(mj.Lattice(stencil, boundary), u, 0.4))
    none = mj.Lattice(stencil, boundary, anisotropic="a")
    np.testing.assert_array_equal(np.asarray(_term(none, u, 0.4)), plain)
    unpolarised = mj.Lattice(stencil, boundary, anisotropic="a", polarity=np.full(SHAPE, np.nan))
    np.testing.assert_allclose(np.asarray(_term(unpolarised, u, 0.4)), plain, atol=1e-13)
    np.testing.assert_allclose(np.asarray(_term(mj.Lattice(stencil, boundary), u, np.full(SHAPE, 0.4))), plain,
                               atol=1e-13)


@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("stencil", STENCILS)
def test_operator_is_symmetric_and_within_the_stability_bound(x64, stencil, boundary):
    """The assembled operator (5 x 6 lattice) is symmetric (every cell has unit area, so the
    mass matrix is the identity), its columns sum to zero (mass), it equals the oracle's
    matrix, and its spectral radius is at most D_max times the stencil's."""
    shape = (5, 6)
    rng = np.random.default_rng(3)
    rate = rng.uniform(0.0, 2.0, shape)
    angle = rng.uniform(-np.pi, np.pi, shape)
    angle[0, 1] = np.nan
    domain = mj.Lattice(stencil, boundary, anisotropic="a", polarity=angle)
    eye = jnp.eye(shape[0] * shape[1]).reshape((-1,) + shape)
    m = np.asarray(jax.vmap(lambda e: _term(domain, e, rate))(eye)).reshape(eye.shape[0], -1).T
    np.testing.assert_allclose(m, m.T, atol=1e-14)
    np.testing.assert_allclose(m.sum(axis=0), 0.0, atol=1e-13)
    np.testing.assert_allclose(m, oracle.operator_matrix(shape, rate, boundary, stencil, angle), atol=1e-13)
    assert np.abs(np.linalg.eigvalsh(m)).max() <= rate.max() * domain.spectral_radius * (1 + 1e-12)


# ---- runs: mass, stability, gradients, vmap, files ------------------------------------------------
def _pure_diffusion(rate):
    return mj.Bard(alpha=0.0, beta=0.0, sp=0.0, da=rate, db=rate, lower=-np.inf)


@pytest.mark.parametrize("boundary", BOUNDARIES)
def test_mass_is_conserved(x64, boundary):
    u, rate, angle = _inputs(seed=4)
    state = mj.State.from_arrays([u, u[::-1]])
    for domain in (mj.Lattice("nine-point", boundary), mj.Lattice("moore", boundary, anisotropic=("a", "b"),
                                                                   polarity=angle)):
        out = np.stack(mj.simulate(_pure_diffusion(rate), state, steps=200, dt=0.08, domain=domain).arrays())
        np.testing.assert_allclose(out.sum(axis=(1, 2)), [u.sum(), u.sum()], rtol=1e-13)
        assert np.abs(out - np.stack([u, u[::-1]])).max() > 0.1  # it did diffuse


def test_dt_limit_refuses_an_unstable_dt():
    u, rate, angle = _inputs(seed=5)
    domain = mj.Lattice("moore", "wrap", anisotropic="a", polarity=angle)
    limit = domain.max_stable_dt(rate.max())
    assert limit == pytest.approx(2.0 / (12.0 * rate.max()))
    state = mj.State.from_arrays([u, u])
    with pytest.raises(ValueError, match="largest stable dt"):
        mj.simulate(_pure_diffusion(rate), state, steps=1, dt=1.05 * limit, domain=domain)
    mj.simulate(_pure_diffusion(rate), state, steps=1, dt=limit, domain=domain)


def test_gradients_against_finite_differences(x64):
    """d(loss)/d(polarity angle) and d(loss)/d(rate) of a Turing run with V anisotropic."""
    shape = (10, 10)
    rng = np.random.default_rng(6)
    state = mj.State.from_arrays([rng.uniform(3.0, 5.0, shape), rng.uniform(3.0, 5.0, shape)])
    weight = jnp.asarray(rng.normal(size=shape))
    cells = jnp.asarray(rng.uniform(-1.0, 1.0, shape))

    def loss(theta, db, spread):
        domain = mj.Lattice("moore", "no-flux", anisotropic="b", polarity=theta + spread * cells)
        out = mj.simulate(mj.Bard(16.0, 12.0, 0.05, 0.08, db), state, steps=30, dt=1.0, domain=domain)
        return jnp.sum(out.fields[1] * weight)

    args = (0.4, 0.01, 0.3)
    grads = jax.jit(jax.grad(loss, argnums=(0, 1, 2)))(*args)
    loss = jax.jit(loss)
    for i, h in enumerate((1e-5, 1e-7, 1e-5)):
        up, down = list(args), list(args)
        up[i] += h
        down[i] -= h
        fd = (loss(*up) - loss(*down)) / (2 * h)
        assert float(grads[i]) == pytest.approx(float(fd), rel=1e-5, abs=1e-9)
    assert abs(float(grads[0])) > 1e-6  # the polarity matters


def test_vmap_over_polarity_angles():
    u, _, _ = _inputs(seed=7)
    state = mj.State.from_arrays([u, u.T])
    model = mj.Bard(16.0, 12.0, 0.05, 0.08, 0.01)

    def run(theta):
        return mj.simulate(model, state, steps=20, dt=1.0, domain=mj.Lattice("moore", anisotropic="b",
                                                                              polarity=theta)).fields

    thetas = jnp.asarray([0.0, 0.8, 2.0])
    batched = np.asarray(jax.vmap(run)(thetas))
    for i, t in enumerate(thetas):
        np.testing.assert_allclose(batched[i], np.asarray(run(t)), rtol=1e-6, atol=1e-6)
    assert np.abs(batched[0] - batched[1]).max() > 1e-3


def test_domain_and_phase_round_trip():
    _, rate, angle = _inputs(seed=8)
    domain = mj.Lattice("moore", "no-flux", maps="pointwise", anisotropic=("b",), polarity=angle)
    assert domain.anisotropic == (1,) and np.isfinite(np.asarray(domain.polarity)).all()
    np.testing.assert_array_equal(np.asarray(domain.polarised), np.isfinite(angle))
    back = _serialise.domain_from_dict(json.loads(json.dumps(_serialise.domain_to_dict(domain))))
    assert (back.stencil, back.boundary, back.maps, back.anisotropic) == ("moore", "no-flux", "pointwise", (1,))
    np.testing.assert_array_equal(np.asarray(back.polarity), np.asarray(domain.polarity))
    np.testing.assert_array_equal(np.asarray(back.polarised), np.asarray(domain.polarised))
    phase = mj.Phase(mj.Bard(da=rate), steps=3, dt=0.5, domain=domain)
    again = mj.Phase.from_dict(json.loads(json.dumps(phase.to_dict())))
    np.testing.assert_array_equal(np.asarray(again.domain.polarity), np.asarray(domain.polarity))
    assert again.domain.anisotropic == (1,) and again.domain.maps == "pointwise"
    plain = _serialise.domain_from_dict(json.loads(json.dumps(_serialise.domain_to_dict(mj.Lattice()))))
    assert plain.polarity is None and plain.maps == "flux"


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="maps"):
        mj.Lattice(maps="harmonic")
    with pytest.raises(ValueError, match="anisotropic"):
        mj.Lattice(anisotropic=("uv",))
    with pytest.raises(ValueError, match="polarity must be an angle"):
        mj.Lattice(anisotropic="a", polarity=np.zeros(3))
    with pytest.raises(ValueError, match="polarity must be finite"):
        mj.Lattice(anisotropic="a", polarity=np.inf)
    u, _, _ = _inputs(seed=9)
    state = mj.State.from_arrays([u, u])
    with pytest.raises(ValueError, match="anisotropic names species 2"):
        mj.simulate(mj.Bard(), state, steps=1, dt=0.1, domain=mj.Lattice(anisotropic="c", polarity=0.0))
    with pytest.raises(ValueError, match="polarity has shape"):
        mj.simulate(mj.Bard(), state, steps=1, dt=0.1, domain=mj.Lattice(anisotropic="a", polarity=np.zeros((3, 3))))
    assert not mj.Lattice(anisotropic="a", polarity=0.0).supports_growth


# ---- thesis figures ----------------------------------------------------------------------------
def test_thesis_fig5_1_spreads_over_the_permeable_cells():
    """75 units in cell 108 spread over cells 75-149 (rate 0.1, the others 0): each holds 1.0
    by iteration 1000 (the thesis), none leaks into the impermeable cells, mass is kept."""
    result = mj.run_experiment(mj.preset("thesis-fig5.1"), seed=0)
    band = fig5_1_rates() > 0
    final = np.asarray(result.state.arrays()[0])
    assert band.sum() == 75 and final[~band].max() == 0.0
    assert final.sum() == pytest.approx(FIG5_1_AMOUNT, rel=1e-6)
    assert np.abs(final[band] - 1.0).max() < 1e-4


def structure_tensor(field):
    """Mean structure tensor (<gx^2>, <gy^2>, <gx gy>) of a (rows, cols) field: x along a row."""
    gy, gx = np.gradient(np.asarray(field, float))
    return (gx * gx).mean(), (gy * gy).mean(), (gx * gy).mean()


def test_thesis_fig5_13_orientation():
    """Only V anisotropic (polarity along a row): stripes along the rows, so the gradients
    point across them (<gy^2> >> <gx^2>); only U: stripes across (<gx^2> >> <gy^2>); both
    and isotropic: no strong direction (the quick form: 32 x 32 cells, 1500 iterations)."""
    ratio = {}
    for case in ("isotropic", "both", "v", "u"):
        result = mj.run_experiment(mj.preset(f"thesis-fig5.13-{case}", quick=True), seed=0)
        jxx, jyy, _ = structure_tensor(result.state.arrays()[1])
        ratio[case] = jyy / jxx
    assert ratio["v"] > 4.0, ratio
    assert ratio["u"] < 0.25, ratio
    for case in ("both", "isotropic"):
        assert 0.4 < ratio[case] < 2.5, ratio
        assert ratio["v"] > 2.5 * ratio[case] and ratio["u"] < ratio[case] / 2.5, ratio


def test_thesis_frog_stripes_above_spots_below():
    """Fig. 7.16 on a lattice (quick, 60 x 60): V anisotropic along the vertical polarity of
    the upper half lays vertical stripes there (gradients across them, along the rows:
    <gy^2> / <gx^2> well below 1); the unpolarised lower half has no direction."""
    result = mj.run_experiment(mj.preset("thesis-fig7.16", quick=True), seed=0)
    u = result.state.array("a")
    half = u.shape[0] // 2
    upper, lower = (structure_tensor(part) for part in (u[:half], u[half:]))
    assert upper[1] / upper[0] < 0.3
    assert 0.6 < lower[1] / lower[0] < 1.6


# ---- the hexagonal lattice ---------------------------------------------------------------------
HEX_SHAPE = (8, 7)


def _hex_inputs(seed=10):
    rng = np.random.default_rng(seed)
    u = rng.uniform(3.0, 5.0, HEX_SHAPE)
    rate = rng.uniform(0.0, 1.0, HEX_SHAPE)
    rate[rng.random(HEX_SHAPE) < 0.1] = 0.0
    angle = rng.uniform(-np.pi, np.pi, HEX_SHAPE)
    angle[rng.random(HEX_SHAPE) < 0.2] = np.nan
    return u, rate, angle


@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("operator", ("laplacian", "sum"))
def test_hex_link_operators_against_oracle(x64, boundary, operator):
    u, rate, angle = _hex_inputs()
    for domain, d, a in [(mj.HexLattice(boundary, operator), rate, None),
                         (mj.HexLattice(boundary, operator, anisotropic="a", polarity=0.7), 0.6, 0.7),
                         (mj.HexLattice(boundary, operator, anisotropic=(0,), polarity=angle), rate, angle)]:
        got = np.asarray(_term(domain, u, d))
        np.testing.assert_allclose(got, oracle.hex_link_term(u, d, boundary, operator, a), atol=1e-12)
        assert abs(got.sum()) < 1e-12  # mass
    plain = np.asarray(_term(mj.HexLattice(boundary, operator), u, 0.4))
    np.testing.assert_array_equal(np.asarray(_term(mj.HexLattice(boundary, operator, anisotropic="a"), u, 0.4)), plain)
    unpolarised = mj.HexLattice(boundary, operator, anisotropic="a", polarity=np.full(HEX_SHAPE, np.nan))
    np.testing.assert_allclose(np.asarray(_term(unpolarised, u, 0.4)), plain, atol=1e-13)


def test_hex_operator_is_symmetric_and_round_trips(x64):
    _, rate, angle = _hex_inputs(seed=11)
    domain = mj.HexLattice("no-flux", "sum", anisotropic="b", polarity=angle)
    eye = jnp.eye(HEX_SHAPE[0] * HEX_SHAPE[1]).reshape((-1,) + HEX_SHAPE)
    aniso_a = mj.HexLattice("no-flux", "sum", anisotropic="a", polarity=angle)
    m = np.asarray(jax.vmap(lambda e: _term(aniso_a, e, rate))(eye)).reshape(eye.shape[0], -1).T
    np.testing.assert_allclose(m, m.T, atol=1e-14)
    assert np.abs(np.linalg.eigvalsh(m)).max() <= rate.max() * aniso_a.spectral_radius * (1 + 1e-12)
    back = _serialise.domain_from_dict(json.loads(json.dumps(_serialise.domain_to_dict(domain))))
    assert (back.boundary, back.operator, back.anisotropic, back.maps) == ("no-flux", "sum", (1,), "flux")
    np.testing.assert_array_equal(np.asarray(back.polarity), np.asarray(domain.polarity))
    np.testing.assert_array_equal(np.asarray(back.polarised), np.asarray(domain.polarised))


# ---- polarity from a reagent's gradient (eq. 4.10) ------------------------------------------------
def test_gradient_polarity_points_along_the_gradient(x64):
    """A radial reagent polarises every cell radially (mod pi) and leaves the centre, where
    the eight differences cancel, unpolarised; a ramp along a row gives angle 0."""
    n = 15
    r, c = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    reagent = np.hypot(r - 7, c - 7)
    angle = np.asarray(mj.gradient_polarity(reagent, "no-flux"))
    assert np.isnan(angle[7, 7]) and np.isfinite(np.delete(angle.ravel(), 7 * n + 7)).all()
    inner = (np.abs(r - 7) <= 5) & (np.abs(c - 7) <= 5) & (reagent > 0)
    expected = np.arctan2(r - 7, c - 7)
    off = np.angle(np.exp(2j * (angle - expected)))[inner] / 2  # difference mod pi
    assert np.abs(off).max() < 0.25  # the 8-neighbour sum's angular error on a lattice
    axes = (reagent > 0) & ((r == 7) | (c == 7) | (np.abs(r - 7) == np.abs(c - 7))) & inner
    np.testing.assert_allclose(off[axes[inner]], 0.0, atol=1e-12)  # exact along the symmetry lines
    ramp = np.asarray(mj.gradient_polarity(np.broadcast_to(np.arange(n, dtype=float), (n, n)), "wrap"))
    np.testing.assert_allclose(ramp[:, 1:-1], 0.0, atol=1e-12)
    domain = mj.Lattice("moore", "no-flux", anisotropic="b", polarity=angle)
    assert float(domain.polarised[7, 7]) == 0.0 and float(np.asarray(domain.polarised).sum()) == n * n - 1


# ---- a polarity that follows a reagent during the run (Polarize, eq. 4.10) ----------------------
def _oracle_polarity(reagent, domain):
    """Eq. 4.10 written cell by cell: sum_j (R_j - R) d_j / |d_j| over the neighbours (the
    square lattice's eight, the mirrored edge cell beyond a no-flux border; the hexagonal
    lattice's six, none beyond a no-flux border), as angles with NaN where it vanishes."""
    rows, cols = reagent.shape
    out = np.full(reagent.shape, np.nan)
    for r in range(rows):
        for c in range(cols):
            px = py = 0.0
            if isinstance(domain, mj.HexLattice):
                x, y = oracle._centre(r, c)
                for r2, c2 in oracle.hex_neighbours(r, c):
                    if domain.boundary != "wrap" and not (0 <= r2 < rows and 0 <= c2 < cols):
                        continue
                    x2, y2 = oracle._centre(r2, c2)
                    diff = reagent[r2 % rows, c2 % cols] - reagent[r, c]
                    px, py = px + diff * (x2 - x), py + diff * (y2 - y)
            else:
                for (dr, dc), _ in oracle.OFFSETS["moore"]:
                    rj, cj, _, _ = oracle._neighbour(r + dr, c + dc, rows, cols, domain.boundary)
                    diff = reagent[rj, cj] - reagent[r, c]
                    px, py = px + diff * dc / np.hypot(dr, dc), py + diff * dr / np.hypot(dr, dc)
            if px or py:
                out[r, c] = np.arctan2(py, px)
    return out


POLARIZE_DOMAINS = {
    "square-no-flux": lambda pol: mj.Lattice("moore", "no-flux", anisotropic="b", polarity=pol),
    "square-wrap": lambda pol: mj.Lattice("nine-point", "wrap", anisotropic="b", polarity=pol),
    "hex-no-flux": lambda pol: mj.HexLattice("no-flux", "sum", anisotropic="b", polarity=pol),
    "hex-wrap": lambda pol: mj.HexLattice("wrap", anisotropic="b", polarity=pol),
}


@pytest.mark.parametrize("kind", list(POLARIZE_DOMAINS))
def test_polarize_follows_the_reagent_against_the_oracle(x64, kind):
    """V diffuses along the gradient of R (species c) as R itself spreads from a producer:
    every step the polarity is the oracle's eq. 4.10 of R at the start of that step."""
    shape = (8, 6)
    rng = np.random.default_rng(11)
    a, b, r = rng.uniform(3, 5, shape), rng.uniform(3, 5, shape), rng.uniform(0, 1, shape)
    production = np.zeros(shape)
    production[2, 3] = 1.0
    rates = (0.05, 0.08, 0.1)
    model = mj.Composite((mj.Bard(16.0, 12.0, 0.0, rates[0], rates[1]),
                          mj.Morphogen(production=production, diffusion=rates[2])))
    domain = POLARIZE_DOMAINS[kind](mj.Polarize("c"))
    out = mj.simulate(model, mj.State.from_arrays([a, b, r]), 4, 0.5, domain=domain)
    hex_ = kind.startswith("hex")
    boundary = domain.boundary
    for _ in range(4):
        angle = _oracle_polarity(r, domain)
        if hex_:
            term = lambda u, d, ang=None: oracle.hex_link_term(u, d, boundary, domain.operator, ang)  # noqa: E731
        else:
            term = lambda u, d, ang=None: oracle.link_term(u, d, boundary, domain.stencil, ang)  # noqa: E731
        a, b, r = (a + 0.5 * term(a, rates[0]), b + 0.5 * term(b, rates[1], angle),
                   r + 0.5 * (production + term(r, rates[2])))
    np.testing.assert_allclose(out.array("b"), b, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(out.array("c"), r, rtol=1e-10, atol=1e-10)


def test_polarize_is_carried_by_the_state_files_and_resumes(x64):
    """The polarity is a function of the state: a run cut in two is the uninterrupted run,
    the domain's file form rebuilds it, and a resting reagent gives the fixed polarity."""
    shape = (9, 9)
    rng = np.random.default_rng(12)
    state = mj.State.from_arrays([rng.uniform(3, 5, shape), rng.uniform(3, 5, shape), rng.uniform(0, 1, shape)])
    model = mj.Composite((mj.Bard(16.0, 12.0, 0.05, 0.08, 0.02), mj.Morphogen(diffusion=0.05)))
    domain = mj.Lattice("moore", "no-flux", anisotropic="b", polarity=mj.Polarize(2))
    whole = mj.simulate(model, state, 20, 0.5, domain=domain)
    halves = mj.simulate(model, mj.simulate(model, state, 8, 0.5, domain=domain), 12, 0.5, domain=domain)
    np.testing.assert_array_equal(whole.fields, halves.fields)
    back = _serialise.domain_from_dict(json.loads(json.dumps(_serialise.domain_to_dict(domain))))
    assert back == domain and back.follow == 2 and not back.supports_growth
    resting = mj.Composite((model.parts[0], mj.Morphogen(diffusion=0.0)))
    fixed = mj.Lattice("moore", "no-flux", anisotropic="b", polarity=mj.gradient_polarity(state.array("c")))
    np.testing.assert_allclose(mj.simulate(resting, state, 20, 0.5, domain=domain).fields,
                               mj.simulate(resting, state, 20, 0.5, domain=fixed).fields, rtol=1e-12)


def test_polarize_gradient_and_errors(x64):
    """d(loss)/d(R's rate) flows through the polarity R sets (against finite differences);
    a reagent beyond the model's species and a polarised mask with Polarize are refused."""
    shape = (8, 8)
    rng = np.random.default_rng(13)
    state = mj.State.from_arrays([rng.uniform(3, 5, shape), rng.uniform(3, 5, shape), rng.uniform(0, 1, shape)])
    weight = jnp.asarray(rng.normal(size=shape))
    domain = mj.Lattice("moore", "no-flux", anisotropic="b", polarity=mj.Polarize("c"))

    def loss(rate):
        model = mj.Composite((mj.Bard(16.0, 12.0, 0.05, 0.08, 0.02), mj.Morphogen(diffusion=rate)))
        return jnp.sum(mj.simulate(model, state, 10, 0.5, domain=domain).fields[1] * weight)

    g = jax.grad(loss)(0.05)
    fd = (loss(0.05 + 1e-6) - loss(0.05 - 1e-6)) / 2e-6
    assert float(g) == pytest.approx(float(fd), rel=1e-5) and abs(float(g)) > 1e-8
    with pytest.raises(ValueError, match="Polarize.reagent names species 2"):
        mj.simulate(mj.Bard(), mj.State.from_arrays([np.ones(shape)] * 2), 1, 0.1, domain=domain)
    with pytest.raises(ValueError, match="Polarize polarity follows"):
        mj.Lattice(polarity=mj.Polarize("c"), polarised=np.ones(shape))
    with pytest.raises(ValueError, match="Polarize.reagent"):
        mj.Polarize("concentration")


def _radial_ratio(v):
    """<(grad . e_r)^2> / <(grad . e_t)^2> over a ring around the centre of a hexagonal
    lattice's field (cell centres of the odd-r layout): small for radial stripes (the
    field changes across them, tangentially), large for concentric rings."""
    rows, cols = v.shape
    gy, gx = np.gradient(np.asarray(v, float))
    gy = gy / (np.sqrt(3.0) / 2.0)
    r, c = np.mgrid[0:rows, 0:cols]
    x = c + 0.5 * (r % 2) - (cols // 2 + 0.5 * ((rows // 2) % 2))
    y = (r - rows // 2) * np.sqrt(3.0) / 2.0
    dist = np.hypot(x, y)
    ring = (dist > 3) & (dist < 0.3 * rows)
    radial = (gx * x + gy * y) / np.maximum(dist, 1e-9)
    tangential = (gy * x - gx * y) / np.maximum(dist, 1e-9)
    return (radial[ring] ** 2).mean() / (tangential[ring] ** 2).mean()


def test_thesis_figs_5_14_and_5_15_on_the_hexagonal_lattice():
    """The polarity follows a central producer's gradient as it forms: with V anisotropic
    the stripes run radially (Fig. 5.14), with U anisotropic they ring the producer (Fig.
    5.15); quick forms, 60 x 60."""
    radial = _radial_ratio(mj.run_experiment(mj.preset("thesis-fig5.14-lattice", quick=True), seed=0)
                           .state.array("b"))
    rings = _radial_ratio(mj.run_experiment(mj.preset("thesis-fig5.15-lattice", quick=True), seed=0)
                          .state.array("b"))
    assert radial < 0.3 and rings > 3.0, (radial, rings)

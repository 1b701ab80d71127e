"""The hexagonal lattice and the thesis's Moore sum, against the NumPy oracle (float64)."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
from morphojax import _serialise

import hex_oracle as oracle

HEX = [(b, op) for b in ("wrap", "no-flux") for op in ("laplacian", "sum")]


@pytest.fixture(scope="module", autouse=True)
def x64():
    with jax.enable_x64(True):
        yield


def _field(shape, seed=0):
    return np.random.default_rng(seed).uniform(3.0, 5.0, shape)


# ---- operators -----------------------------------------------------------------------------
def test_oracle_neighbour_listings_agree():
    """The oracle's two constructions (the issue's listing, axial coordinates) are the same lattice."""
    for shape in ((6, 8), (7, 5)):
        for boundary in ("wrap", "no-flux"):
            if boundary == "wrap" and shape[0] % 2:
                continue
            listed = oracle.hex_matrix(shape, boundary, neighbours=oracle.hex_neighbours_listed)
            np.testing.assert_array_equal(listed, oracle.hex_matrix(shape, boundary))


@pytest.mark.parametrize("boundary, operator", HEX)
def test_hex_operator_against_oracle(boundary, operator):
    shapes = [(6, 8), (10, 9)] + ([(7, 6)] if boundary == "no-flux" else [])
    for shape in shapes:
        u = _field(shape, 1)
        got = np.asarray(mj.HexLattice(boundary, operator).apply(jnp.asarray(u)))
        np.testing.assert_allclose(got, oracle.apply(oracle.hex_matrix(shape, boundary, operator), u), atol=1e-12)


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_moore_against_oracle(boundary):
    for shape in ((6, 8), (7, 5)):
        u = _field(shape, 2)
        got = np.asarray(mj.Lattice("moore", boundary).apply(jnp.asarray(u)))
        np.testing.assert_allclose(got, oracle.apply(oracle.moore_matrix(shape, boundary), u), atol=1e-12)
    assert mj.Lattice("8").stencil == "moore" and "moore" in mj.STENCILS


def test_spectral_radii_against_eigenvalues():
    """The radius each domain states is the largest |eigenvalue| of its assembled operator
    where a lattice attains it, and bounds it on every other size and boundary."""
    def radius(m):
        return np.abs(np.linalg.eigvals(m)).max()

    for operator, rho in (("sum", 9.0), ("laplacian", 6.0)):
        assert mj.HexLattice(operator=operator).spectral_radius == rho
        assert radius(oracle.hex_matrix((6, 6), "wrap", operator)) == pytest.approx(rho, abs=1e-9)
        for shape, boundary in (((4, 5), "wrap"), ((8, 7), "wrap"), ((6, 6), "no-flux"), ((9, 7), "no-flux")):
            assert radius(oracle.hex_matrix(shape, boundary, operator)) <= rho + 1e-9
    moore = mj.Lattice("moore")
    assert moore.spectral_radius == 12.0  # the stripe mode; the checkerboard gives only 8
    assert radius(oracle.moore_matrix((4, 4), "wrap")) == pytest.approx(12.0, abs=1e-9)
    checker = np.indices((4, 4)).sum(0) % 2 * 2.0 - 1.0
    np.testing.assert_allclose(oracle.apply(oracle.moore_matrix((4, 4), "wrap"), checker), -8.0 * checker)
    for shape, boundary in (((5, 5), "wrap"), ((6, 7), "no-flux")):
        assert radius(oracle.moore_matrix(shape, boundary)) <= 12.0 + 1e-9
    # the dt limit follows from the radius in the one place it is computed
    assert moore.max_stable_dt(0.06) == pytest.approx(2.0 / (12.0 * 0.06))
    assert mj.HexLattice(operator="sum").max_stable_dt(0.06) == pytest.approx(2.0 / (9.0 * 0.06))
    # thesis Fig. 5.9 ran Du 0.40 at dt 0.4 and Du 0.80 at dt 0.2: within the Moore sum's
    # limit, beyond the nine-point stencil's for the converted rates (3 x Du)
    moore.check_dt(0.4, 0.40)
    moore.check_dt(0.2, 0.80)
    with pytest.raises(ValueError, match="largest stable dt is 0.3125"):
        mj.Lattice("nine-point").check_dt(0.4, 3 * 0.40)
    with pytest.raises(ValueError, match="hexagonal lattice neighbour sum"):
        mj.HexLattice(operator="sum").check_dt(3.8, 0.06)


# ---- invariants ----------------------------------------------------------------------------
@pytest.mark.parametrize("boundary, operator", HEX)
def test_hex_point_reflection(boundary, operator):
    """(r, c) -> (rows - 1 - r, cols - 1 - c) is the 180-degree rotation of an odd-r lattice
    with an even number of rows (it swaps the row parities and the half-cell shift): the
    operator commutes with it exactly, on either boundary."""
    u = _field((8, 7), 3)
    dom = mj.HexLattice(boundary, operator)
    np.testing.assert_allclose(np.asarray(dom.apply(u[::-1, ::-1])), np.asarray(dom.apply(u))[::-1, ::-1], atol=1e-12)


@pytest.mark.parametrize("operator", ["laplacian", "sum"])
def test_hex_plane_waves_invariant_under_60_degrees(operator):
    """On a wrapped 12 x 12 lattice the plane wave cos(k . x) and the same wave turned by
    60 degrees are both eigenfunctions with one eigenvalue, sum_j 2 (cos(k . d_j) - 1)
    (x 2/3 for the Laplacian), d_j the six unit neighbour directions."""
    shape = (12, 12)
    x, y = oracle.centres(shape)
    k = np.array([2 * np.pi * 2 / 12, 4 * np.pi / (12 * np.sqrt(3.0))])
    turn = np.array([[0.5, -np.sqrt(3.0) / 2], [np.sqrt(3.0) / 2, 0.5]])
    dirs = [np.array([np.cos(a), np.sin(a)]) for a in np.arange(6) * np.pi / 3]
    dom = mj.HexLattice("wrap", operator)
    factor = 2.0 / 3.0 if operator == "laplacian" else 1.0
    for kk in (k, turn @ k, turn @ turn @ k):
        u = np.cos(kk[0] * x + kk[1] * y + 0.3)
        lam = factor * sum(np.cos(kk @ d) - 1.0 for d in dirs)
        assert lam < -0.5
        np.testing.assert_allclose(np.asarray(dom.apply(u)), lam * u, atol=1e-10)


def _pure_diffusion(d=0.3):
    return mj.Bard(alpha=0.0, beta=0.0, sp=0.0, da=d, db=d, lower=-np.inf)


@pytest.mark.parametrize("domain", [mj.HexLattice("wrap"), mj.HexLattice("no-flux", "sum"), mj.HexLattice("no-flux"),
                                    mj.Lattice("moore", "wrap"), mj.Lattice("moore", "no-flux")],
                         ids=lambda d: f"{type(d).__name__}-{getattr(d, 'operator', getattr(d, 'stencil', ''))}-{d.boundary}")
def test_pure_diffusion_conserves_mass(domain):
    state = mj.State.from_arrays([_field((10, 9), 4), _field((10, 9), 5)])
    dt = 0.9 * domain.max_stable_dt(0.3)
    out = mj.simulate(_pure_diffusion(), state, 200, dt, domain=domain)
    np.testing.assert_allclose(np.asarray(out.fields).sum((1, 2)), np.asarray(state.fields).sum((1, 2)), rtol=1e-13)
    assert np.ptp(np.asarray(out.fields)) < np.ptp(np.asarray(state.fields))  # it did diffuse


# ---- runs ------------------------------------------------------------------------------------
@pytest.mark.parametrize("boundary, operator", HEX)
def test_turing_run_against_oracle(boundary, operator):
    """100 steps of the Bard form on a hexagonal lattice, step for step as the oracle."""
    shape = (10, 12) if boundary == "wrap" else (9, 12)
    a, b = _field(shape, 6), _field(shape, 7)
    params = dict(alpha=16.0, beta=12.0, sp=0.05, da=0.3, db=0.05)
    model = mj.Bard(**params, upper=(6.0, np.inf))
    out = mj.simulate(model, mj.State.from_arrays([a, b]), 100, 0.5, domain=mj.HexLattice(boundary, operator))
    ref = oracle.bard_run(a, b, oracle.hex_matrix(shape, boundary, operator), **params, dt=0.5, steps=100,
                          upper=(6.0, np.inf))
    for got, want in zip(out.arrays(), ref):
        np.testing.assert_allclose(got, want, atol=1e-10)
    assert np.ptp(ref[1]) > 0.1  # the run did something


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_moore_run_against_oracle(boundary):
    """The thesis's experiments run with its own operator and rates as printed (Listing 5.1)."""
    shape = (9, 10)
    a, b = _field(shape, 8), _field(shape, 9)
    params = dict(alpha=16.0, beta=12.0, sp=0.01, da=0.06, db=0.01)
    out = mj.simulate(mj.Bard(**params), mj.State.from_arrays([a, b]), 100, 1.0, domain=mj.Lattice("moore", boundary))
    ref = oracle.bard_run(a, b, oracle.moore_matrix(shape, boundary), **params, dt=1.0, steps=100)
    for got, want in zip(out.arrays(), ref):
        np.testing.assert_allclose(got, want, atol=1e-10)


def test_gradient_through_hex_run():
    """d loss / d (da, db, sp) through 60 steps on a no-flux hexagonal lattice, vs central differences."""
    state = mj.State.from_arrays([_field((8, 8), 10), _field((8, 8), 11)])
    base = {"da": 0.3, "db": 0.05, "sp": 0.05}
    domain = mj.HexLattice("no-flux")

    def loss(p):
        out = mj.simulate(mj.Bard(16.0, 12.0, p["sp"], p["da"], p["db"]), state, 60, 0.5, domain=domain)
        return jnp.mean(out.fields[1] ** 2) + 0.1 * jnp.mean(out.fields[0] * out.fields[1])

    values = {k: jnp.asarray(v) for k, v in base.items()}
    grads = jax.grad(loss)(values)
    for name in base:
        h = 1e-6
        fd = (float(loss({**values, name: values[name] + h})) - float(loss({**values, name: values[name] - h}))) / (2 * h)
        g = float(grads[name])
        assert abs(g) > 1e-6, name
        assert abs(g - fd) <= 1e-6 + 1e-5 * abs(fd), (name, g, fd)


# ---- refusals ------------------------------------------------------------------------------
def test_odd_rows_with_wrap_refused():
    model, state = mj.Turing(4.0, 3.0), mj.State.from_arrays([_field((7, 8)), _field((7, 8), 1)])
    with pytest.raises(ValueError, match="even number of rows"):
        mj.simulate(model, state, 2, 0.01, domain=mj.HexLattice("wrap"))
    with pytest.raises(ValueError, match="even number of rows"):
        mj.HexLattice().apply(np.zeros((5, 6)))
    mj.simulate(model, state, 2, 0.01, domain=mj.HexLattice("no-flux"))  # no-flux takes any number of rows
    with pytest.raises(ValueError, match="operator"):
        mj.HexLattice(operator="nine-point")


def test_growth_refused_with_polarity_and_interpolation_on_hex():
    model = mj.Turing(4.0, 3.0)
    growable = mj.State.from_arrays([_field((8, 8)), _field((8, 8), 1)], capacity=(12, 12))
    with pytest.raises(ValueError, match="growth is not supported on the hexagonal lattice"):
        mj.simulate(model, growable, 2, 0.01, domain=mj.HexLattice(anisotropic="b", polarity=0.3))
    with pytest.raises(ValueError, match="division only"):
        mj.simulate(model, growable, 2, 0.01, domain=mj.HexLattice(), growth=mj.Growth(1.0, method="bilinear"),
                    key=jax.random.key(0))
    with pytest.raises(ValueError, match="even number of rows"):  # a growing torus's active rows too
        mj.simulate(model, mj.State.from_arrays([_field((7, 8)), _field((7, 8), 1)], capacity=(12, 12)), 2, 0.01,
                    domain=mj.HexLattice("wrap"))
    assert mj.HexLattice().supports_growth and mj.HexLattice().expansion_copies == 2


# ---- growth ----------------------------------------------------------------------------------
def _collapse_runs_of_three(line):
    """`line` with its one run of three equal values cut to one (None unless there is exactly one)."""
    line = list(line)
    runs = [i for i in range(len(line) - 2) if line[i] == line[i + 1] == line[i + 2]]
    if len(runs) != 1:
        return None
    i = runs[0]
    return line[:i + 1] + line[i + 3:]


@pytest.mark.parametrize("distribution", ["uniform", "shuffle", "normal", "triangular"])
def test_hex_expansion_keeps_the_geometry(distribution):
    """After every expansion of a growing hexagonal lattice, every cell keeps its place
    across the lattice: each row holds one run of three copies of its dividing cell and,
    cut back to one, the row's cells in order; then each column likewise gives back the
    lattice before the expansion. So the cells after a dividing one moved by exactly two
    rows (same row parity, the same x) or two whole cells along their row, and the rows
    stay even (a torus stays a torus)."""
    growth = mj.Growth(rate=1.0, distribution=distribution)
    h, w, cap = 4, 6, (14, 16)
    ids = np.zeros(cap)
    ids[:h, :w] = np.arange(h * w).reshape(h, w) + 1
    x, size = jnp.asarray(ids)[None], jnp.asarray([h, w], jnp.int32)
    for k in range(4):
        # the lattice grown so far, and fresh labels of its cells as a second species (every
        # species divides at the same cells)
        before = np.asarray(x[0])[: int(size[0]), : int(size[1])]
        fresh = np.zeros(cap)
        fresh[: before.shape[0], : before.shape[1]] = np.arange(before.size).reshape(before.shape) + 1
        both, size = growth.expand(jnp.stack([x[0], jnp.asarray(fresh)]), size, jax.random.key(k),
                                   mj.HexLattice().expansion_copies)
        x = both[:1]
        rows, cols = int(size[0]), int(size[1])
        assert (rows, cols) == (before.shape[0] + 2, before.shape[1] + 2) and rows % 2 == 0
        labels = np.asarray(both[1])
        np.testing.assert_array_equal(np.asarray(both[0]), np.where(labels > 0, np.concatenate(
            [[0.0], before.ravel()])[labels.astype(int)], 0.0))  # the fields moved with their labels
        after, before = labels, fresh[: before.shape[0], : before.shape[1]]
        assert not after[rows:].any() and not after[:, cols:].any()  # nothing outside the active region
        collapsed = [_collapse_runs_of_three(r) for r in after[:rows, :cols]]
        assert all(c is not None for c in collapsed), k
        columns = [_collapse_runs_of_three(c) for c in np.asarray(collapsed).T]
        assert all(c is not None for c in columns), k
        np.testing.assert_array_equal(np.asarray(columns).T, before)


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_growable_hex_lattice_steps_its_active_region(boundary):
    """A state with room to grow runs on its active region as the oracle runs on that
    lattice alone: the ghost cells (wrap) and the dropped links (no-flux) follow the region."""
    shape = (8, 10) if boundary == "wrap" else (7, 10)
    a, b = _field(shape, 12), _field(shape, 13)
    params = dict(alpha=16.0, beta=12.0, sp=0.05, da=0.3, db=0.05)
    model = mj.Bard(**params, upper=(6.0, np.inf))
    out = mj.simulate(model, mj.State.from_arrays([a, b], capacity=(13, 15)), 50, 0.5,
                      domain=mj.HexLattice(boundary, "sum"))
    ref = oracle.bard_run(a, b, oracle.hex_matrix(shape, boundary, "sum"), **params, dt=0.5, steps=50,
                          upper=(6.0, np.inf))
    assert out.shape == shape
    for got, want in zip(out.arrays(), ref):
        np.testing.assert_allclose(got, want, atol=1e-12)


def test_growing_hex_run_between_expansions_against_oracle():
    """A growing wrapped hexagonal run: expansions after phase steps 1 and 1 + p; between
    them the run is the oracle's on the grown lattice, and the capacity check counts two
    rows and two columns per expansion."""
    shape, period = (6, 8), 10
    a, b = _field(shape, 14), _field(shape, 15)
    params = dict(alpha=16.0, beta=12.0, sp=0.05, da=0.3, db=0.05)
    model, domain = mj.Bard(**params), mj.HexLattice("wrap", "sum")
    growth, key = mj.Growth(rate=1.0 / (period * 0.5)), jax.random.key(3)
    state = mj.State.from_arrays([a, b], capacity=(10, 12))
    first = mj.simulate(model, state, 1, 0.5, domain=domain, growth=growth, key=key)
    assert first.shape == (8, 10)
    whole = mj.simulate(model, state, period, 0.5, domain=domain, growth=growth, key=key)
    ref = oracle.bard_run(*first.arrays(), oracle.hex_matrix(first.shape, "wrap", "sum"), **params, dt=0.5,
                          steps=period - 1)
    assert whole.shape == (8, 10)
    for got, want in zip(whole.arrays(), ref):
        np.testing.assert_allclose(got, want, atol=1e-12)
    with pytest.raises(ValueError, match="beyond the capacity"):  # three expansions: 12 x 14 > 10 x 12
        mj.simulate(model, state, 2 * period + 1, 0.5, domain=domain, growth=growth, key=key)


# ---- files, presets and pictures -------------------------------------------------------------
def test_phase_with_hex_round_trip():
    phase = mj.Phase(mj.Bard(), 10, 1.0, domain=mj.HexLattice("no-flux", "sum"))
    data = json.loads(json.dumps(phase.to_dict()))
    again = mj.Phase.from_dict(data)
    assert again.domain == phase.domain and isinstance(again.domain, mj.HexLattice)
    assert _serialise.domain_from_dict(_serialise.domain_to_dict(mj.Lattice("moore"))) == mj.Lattice("moore")


def test_hex_preset_runs_and_resumes(tmp_path):
    """The reduced Fig. 5.10 hexagonal run: a pattern forms, and the file it writes resumes
    to the uninterrupted result."""
    exp = mj.preset("thesis-fig5.10-hex", quick=True)
    assert isinstance(exp.phases[0].domain, mj.HexLattice)
    short = mj.Experiment(exp.name, exp.initial, (mj.Phase(exp.phases[0].model, 400, 1.0, domain=exp.phases[0].domain),))
    whole = mj.run_experiment(short, seed=0)
    assert np.ptp(whole.state.array("b")) > 1.0
    path = tmp_path / "half.npz"
    mj.run_experiment(short, seed=0, stop_after=200).save(path)
    resumed = mj.run_experiment(short, seed=0, resume=path)
    np.testing.assert_array_equal(resumed.state.array("b"), whole.state.array("b"))


def test_growing_hex_phase_round_trips_and_resumes(tmp_path):
    """A Phase with Growth on a HexLattice saves and loads to an equal phase, and a run
    stopped between expansions resumes from its file to the uninterrupted result."""
    exp = mj.preset("thesis-fig5.10-hex", quick=True)
    phase = mj.Phase(exp.phases[0].model, 30, 1.0, domain=mj.HexLattice("no-flux", "sum"),
                     growth=mj.Growth(rate=0.1, distribution="normal"), capacity=(12, 14), name="grow")
    again = mj.Phase.from_dict(json.loads(json.dumps(phase.to_dict())))
    assert again.domain == phase.domain and again.growth.distribution == "normal"
    grow = mj.Experiment("hex-grow", mj.Initial("thesis", (6, 8), params=(2.0, 4.0)), (phase,))
    whole = mj.run_experiment(grow, seed=1)
    assert whole.state.shape == (12, 14)  # three expansions, two rows and two columns each
    path = tmp_path / "half.npz"
    mj.run_experiment(grow, seed=1, stop_after=15).save(path)
    resumed = mj.run_experiment(grow, seed=1, resume=path)
    np.testing.assert_array_equal(resumed.state.array("b"), whole.state.array("b"))


def test_hex_image_places_cells_at_their_centres():
    """Each hexagon's centre pixel has its cell's colour; odd rows sit half a cell right."""
    a = np.arange(5 * 6, dtype=float).reshape(5, 6)
    scale = 10
    img = np.asarray(mj.hex_image(a, cmap="gray", vmin=0.0, vmax=29.0, scale=scale))
    x, y = oracle.centres(a.shape)
    px = ((x + 0.5) * scale).astype(int)
    py = ((y + 1.0 / np.sqrt(3.0)) * scale).astype(int)
    np.testing.assert_array_equal(img[py, px, 0], np.round(a / 29.0 * 255).astype(np.uint8))
    assert img.shape[1] == int(np.ceil(6.5 * scale))  # the half-cell shift of odd rows widens the picture

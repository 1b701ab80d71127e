"""The cellular Potts model (paper 003, section III.B) against the NumPy oracle
(tests/potts_oracle.py): the Hamiltonian, exact energy and volume bookkeeping of the
parallel sub-lattice sweeps, the colouring's independence, determinism, zero temperature,
the volume constraint and the two regimes of paper 003's J series."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
from morphojax.potts import _sweep
import potts_oracle as oracle

MCS = 20


def _paper(j_like, **kw):
    return mj.Potts.paper003(j_like, **kw)


@pytest.fixture(scope="module")
def blob():
    return mj.potts_blob((24, 24), 10, 5, key=jax.random.key(3))


@pytest.fixture(scope="module")
def paper_run(blob):
    model = _paper(3.0)
    final, trace = model.run(blob, MCS, jax.random.key(7), energy=True)
    return model, final, np.asarray(trace)


def _random_config(rng, shape, n_cells, n_types):
    ids = rng.integers(0, n_cells + 1, shape)
    types = np.concatenate([[0], rng.integers(1, n_types, n_cells)])
    half = rng.integers(0, 40, (n_types, n_types)) / 2.0
    return ids, types, np.triu(half) + np.triu(half, 1).T


@pytest.mark.parametrize("order,boundary", [(1, "fixed"), (2, "fixed"), (1, "wrap"), (2, "wrap")])
def test_energy_of_small_configurations_matches_oracle(order, boundary):
    rng = np.random.default_rng(order + 10 * len(boundary))
    for shape in [(3, 4), (4, 4), (5, 6)]:
        ids, types, J = _random_config(rng, shape, 5, 4)
        model = mj.Potts(J, 10.0, 3.0, 1.5, order=order, boundary=boundary)
        got = float(model.energy(mj.PottsState(ids, types)))
        assert got == oracle.hamiltonian(ids, types, J, 1.5, 3.0, order, boundary)


def test_energy_of_hand_made_pair():
    # two cells side by side on a 1x2 strip: one contact, volumes 1 and 1
    J = np.array([[0.0, 16.0, 16.0], [16.0, 2.0, 11.0], [16.0, 11.0, 2.0]])
    state = mj.PottsState(np.array([[1, 2]]), np.array([0, 1, 2]))
    model = mj.Potts(J, 10.0, 25.0, 2.0)
    assert float(model.energy(state)) == 11.0 + 2.0 * 2 * 24.0 ** 2


def test_accepted_changes_add_up_to_the_recomputed_energy(paper_run, blob):
    model, final, trace = paper_run
    ids, types, volumes = final.arrays()
    recomputed = oracle.hamiltonian(ids, types, model.J, 2.0, 25.0)
    assert trace[-1] == recomputed == float(model.energy(final))
    assert trace[-1] != float(model.energy(blob))  # something moved
    np.testing.assert_array_equal(volumes, np.bincount(ids.ravel(), minlength=len(types)))


def test_each_mcs_depends_on_its_own_key_only(paper_run, blob):
    model, final, trace = paper_run
    first = model.run(blob, 5, jax.random.key(7))  # the first 5 MCS of the 20-MCS run (the loop without trace)
    assert float(model.energy(first)) == trace[4]
    np.testing.assert_array_equal(np.asarray(model.run(blob, MCS, jax.random.key(7)).ids), np.asarray(final.ids))


def test_bookkeeping_on_a_torus_with_first_order_neighbours():
    rng = np.random.default_rng(5)
    ids = np.kron(rng.permutation(16).reshape(4, 4), np.ones((5, 5), int))  # 16 squares, id 0 the medium
    types = np.concatenate([[0], rng.integers(1, 3, 15)])
    J = np.array([[0, 12, 12], [12, 3, 9], [12, 9, 3]])
    model = mj.Potts(J, 6.0, 25.0, 1.0, order=1, boundary="wrap")
    state = mj.PottsState(ids, types)
    final, trace = model.run(state, MCS, jax.random.key(1), energy=True)
    out = np.asarray(final.ids)
    assert np.asarray(trace)[-1] == oracle.hamiltonian(out, types, J, 1.0, 25.0, 1, "wrap")
    assert set(np.unique(out)) <= set(range(16))
    np.testing.assert_array_equal(np.asarray(final.volumes), np.bincount(out.ravel(), minlength=16))


def test_one_change_per_cell_in_a_sub_sweep_priced_exactly(blob):
    model = _paper(3.0)
    sweep = jax.jit(lambda planes, vol, seed, colour: _sweep.sub_sweep(model, planes, vol, blob.types, seed, colour))
    ids0, types, vol0 = blob.arrays()
    planes = _sweep.to_colour_major(jnp.asarray(ids0))
    for k in range(8):
        seed = jnp.asarray([k * 7919 + 1, k + 12345], jnp.uint32)
        planes, vol, d_e, n = sweep(planes, blob.volumes, seed, k % 4)
        ids1 = np.asarray(_sweep.from_colour_major(planes))
        changed = ids1 != ids0
        assert int(n) == changed.sum()
        touched = np.concatenate([ids0[changed], ids1[changed]])
        counts = np.bincount(touched[touched > 0], minlength=len(types))
        assert counts.max(initial=0) <= 1  # the volume term stays exact
        colour = 2 * (np.nonzero(changed)[0] % 2) + np.nonzero(changed)[1] % 2
        assert (colour == k % 4).all()
        before = oracle.hamiltonian(ids0, types, model.J, 2.0, 25.0)
        assert float(d_e) == oracle.hamiltonian(ids1, types, model.J, 2.0, 25.0) - before
        ids0 = ids1
        blob = mj.PottsState(ids1, types)


@pytest.mark.parametrize("shape,boundary", [((6, 8), "fixed"), ((7, 5), "fixed"), ((6, 8), "wrap")])
def test_sites_updated_together_are_never_neighbours(shape, boundary):
    rows, cols = shape
    index = jnp.arange(rows * cols, dtype=jnp.int32).reshape(shape)
    planes = np.asarray(_sweep.to_colour_major(_sweep.even_lattice(index, boundary)))
    seen = []
    for a, b in itertools.product(range(2), range(2)):
        sites = [int(s) for s in planes[a, b].ravel() if s >= 0]
        seen += sites
        for s, t in itertools.combinations(sites, 2):
            (i, j), (k, l) = divmod(s, cols), divmod(t, cols)
            di, dj = abs(i - k), abs(j - l)
            if boundary == "wrap":
                di, dj = min(di, rows - di), min(dj, cols - dj)
            assert max(di, dj) >= 2, (s, t)  # outside each other's Moore (hence von Neumann) neighbourhood
    assert sorted(seen) == list(range(rows * cols))


def test_same_key_same_lattice(blob):
    model = _paper(3.0)
    a = model.run(blob, MCS, jax.random.key(11))
    b = model.run(blob, MCS, jax.random.key(11))
    c = model.run(blob, MCS, jax.random.key(12))
    np.testing.assert_array_equal(np.asarray(a.ids), np.asarray(b.ids))
    assert not np.array_equal(np.asarray(a.ids), np.asarray(c.ids))


def test_zero_temperature_never_raises_the_energy(blob):
    model = _paper(3.0, temperature=0.0)
    final, trace = model.run(blob, MCS, jax.random.key(2), energy=True)
    trace = np.concatenate([[float(model.energy(blob))], np.asarray(trace)])
    assert (np.diff(trace) <= 0).all() and trace[-1] < trace[0]
    assert trace[-1] == float(model.energy(final))


def test_parallel_sweeps_relax_like_sequential_metropolis(blob):
    """Mean energy after 20 MCS: the parallel sub-lattice sweeps against the oracle's sequential
    random-site Metropolis, over 4 seeds each (the same dynamics, so the same descent)."""
    model = _paper(3.0)
    ids, types, _ = blob.arrays()
    ours = [float(model.energy(model.run(blob, MCS, jax.random.key(100 + s)))) for s in range(4)]
    theirs = [oracle.hamiltonian(oracle.metropolis(ids, types, model.J, 10.0, 25.0, 2.0, MCS,
                                                   np.random.default_rng(s))[0], types, model.J, 2.0, 25.0)
              for s in range(4)]
    start = float(model.energy(blob))
    drop_ours, drop_theirs = start - np.mean(ours), start - np.mean(theirs)
    assert abs(drop_ours - drop_theirs) < 0.15 * drop_theirs


@pytest.fixture(scope="module")
def regimes():
    state = mj.potts_blob((40, 40), 16, 5, key=jax.random.key(0))
    out = {}
    for j in (0.5, 18.0):  # the ends of paper 003's series
        out[j] = (state, _paper(j).run(state, 200, jax.random.key(1)))
    out["stiff"] = (state, _paper(9.0, volume_weight=20.0).run(state, 200, jax.random.key(1)))
    return out


def test_volume_constraint_holds_near_target_on_average(regimes):
    # contact tension squeezes cells below V by about (contact energy per border site) / (4 lambda):
    # a few sites at the paper's lambda = 2, a fraction of a site at lambda = 20
    for j in (0.5, 18.0):
        v = np.asarray(regimes[j][1].volumes)[1:]
        assert 0.85 * 25.0 < v.mean() < 25.0 and np.median(np.abs(v - 25.0)) <= 4.0
    stiff = np.asarray(regimes["stiff"][1].volumes)[1:]
    assert abs(stiff.mean() - 25.0) < 0.75 and np.abs(stiff - 25.0).max() <= 3


def test_like_type_adhesion_series_gives_bands_then_mixing(regimes):
    # like_contacts: the share of cell-cell borders between cells of one type (random types: about 0.5)
    low = mj.type_clusters(regimes[0.5][1])["like_contacts"]
    high = mj.type_clusters(regimes[18.0][1])["like_contacts"]
    start = mj.type_clusters(regimes[0.5][0])["like_contacts"]
    assert low > max(start + 0.2, 0.7)  # like cells gather into bands
    assert high < min(start, 0.47)  # unlike contacts win: single cells of one type among the other


@pytest.mark.parametrize("kwargs,field", [
    (dict(J=np.ones((2, 3))), "Potts.J"),
    (dict(J=np.array([[0.0, 1.0], [2.0, 0.0]])), "Potts.J"),
    (dict(J=np.array([[0.0, np.nan], [np.nan, 0.0]])), "Potts.J"),
    (dict(temperature=-1.0), "Potts.temperature"),
    (dict(target_volume=0.0), "Potts.target_volume"),
    (dict(volume_weight=-2.0), "Potts.volume_weight"),
    (dict(order=3), "Potts.order"),
    (dict(boundary="mirror"), "Potts.boundary"),
])
def test_bad_parameters_are_value_errors_naming_the_field(kwargs, field):
    args = dict(J=np.array([[0.0, 16.0], [16.0, 2.0]]), temperature=10.0, target_volume=25.0, volume_weight=2.0)
    args.update(kwargs)
    with pytest.raises(ValueError, match=field.replace(".", r"\.")):
        mj.Potts(**args)


def test_bad_states_and_runs_are_value_errors(blob):
    model = _paper(3.0)
    with pytest.raises(ValueError, match="PottsState.types"):
        model.energy(mj.PottsState(np.array([[1, 2]]), np.array([0, 1, 3])))
    with pytest.raises(ValueError, match="PottsState.ids"):
        mj.PottsState(np.array([[1, 5]]), np.array([0, 1, 2]))
    with pytest.raises(ValueError, match=r"types\[0\]"):
        mj.PottsState(np.array([[1, 2]]), np.array([1, 1, 2]))
    with pytest.raises(ValueError, match="mcs"):
        model.run(blob, -1, jax.random.key(0))
    with pytest.raises(ValueError, match="wrap"):
        mj.Potts(model.J, 10.0, 25.0, 2.0, boundary="wrap").run(mj.PottsState(np.ones((5, 6), int), np.array([0, 1])),
                                                                1, jax.random.key(0))
    with pytest.raises(ValueError, match="cell_width"):
        mj.potts_blob((20, 20), 5, 0)


def test_blob_matches_the_paper_initializer():
    state = mj.potts_blob((100, 100), 40, 5, key=jax.random.key(0))
    ids, types, volumes = state.arrays()
    i, j = np.nonzero(ids > 0)
    assert ((i - 50) ** 2 + (j - 50) ** 2 <= 1600).all() and ((ids == 0) | (ids > 0)).all()
    assert volumes[1:].max() == 25 and (volumes[1:] > 0).all()
    assert set(np.unique(types[1:])) == {1, 2}
    assert abs((types[1:] == 1).mean() - 0.5) < 0.1


def test_preset_files_render_and_carry_their_parameters(tmp_path, regimes):
    from morphojax.cli._run import file_kind
    from morphojax.presets._potts import potts_picture, run_series

    out = tmp_path / "series.png"
    summary = run_series((0.5, 18.0), 0, True, out, "test", 2)  # the quick size: compiled by `regimes`
    assert file_kind(out.with_suffix(".npz")) == "potts"
    assert potts_picture(out.with_suffix(".npz")).size[0] > 2 * 40 * 3
    with np.load(out.with_suffix(".npz")) as data:
        ids, types = data["ids"], data["types"]
    assert ids.shape == (2, 40, 40)
    again = mj.Potts.paper003(0.5).run(mj.potts_blob((40, 40), 16, 5, key=jax.random.key(0)), 200,
                                       jax.random.fold_in(jax.random.key(0), 1))
    np.testing.assert_array_equal(ids[0], np.asarray(again.ids))  # the file is the run its metadata names
    assert summary["runs"][0]["like_contacts"] > summary["runs"][1]["like_contacts"]
    assert "potts-fig10" in mj.PRESETS and mj.PRESETS["potts-fig10"].kind == "potts"

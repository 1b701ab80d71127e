"""Reaction-diffusion on triangle meshes (`mj.Mesh`), against the NumPy/SciPy oracle in
tests/mesh_oracle.py, the sphere's spectrum, the square lattice, and exact invariants."""

import json
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh

import morphojax as mj
from morphojax import _serialise
from mesh_oracle import gray_scott_run, grid_mesh, laplacian
from morphojax.automata import read_ply

GS = dict(feed=0.0367, kill=0.0649, du=0.2097, dv=0.105)


def matrices_of(mesh):
    """(K, M) rebuilt from the domain's own arrays: what the JAX operator applies."""
    n = mesh.n_vertices
    table, w = np.asarray(mesh.neighbours), np.asarray(mesh.weights, float)  # slot-major (K, V)
    wm = sp.csr_matrix((w.ravel(), (np.tile(np.arange(n), table.shape[0]), table.ravel())), shape=(n, n))
    k = sp.diags(np.asarray(wm.sum(1)).ravel()) - wm
    return k, sp.diags(mesh.masses())


@pytest.fixture(scope="module")
def sphere():
    return mj.Mesh.icosphere(4)  # 2562 vertices, unit radius


@pytest.fixture(scope="module")
def small():
    return mj.Mesh.capsule(radius=1.0, length=1.5, spacing=0.35)


def test_operator_matches_oracle(small):
    rng = np.random.default_rng(0)
    x = rng.normal(size=(2, small.n_vertices))
    for mass in ("voronoi", "barycentric"):
        mesh = small if mass == "voronoi" else mj.Mesh(small.vertices, small.faces, mass="barycentric")
        ref = np.stack([laplacian(mesh.vertices, mesh.faces, mass) @ xi for xi in x])
        with jax.enable_x64(True):
            got = np.asarray(mesh.apply(jnp.asarray(x)))
        np.testing.assert_allclose(got, ref, rtol=2e-5, atol=2e-5 * np.abs(ref).max())


def test_both_forms_of_the_operator_agree_on_every_shape(small):
    """The CPU form (one (K, V) gather per pair of species) and the fused form (one gather
    per slot) give the same numbers for one field, species, and batches of species, also
    anisotropic, and the same gradients."""
    from morphojax.domains._mesh_operator import gathered_apart, gathered_fused

    mesh = mj.Mesh(small.vertices, small.faces, direction=[0.0, 0.0, 1.0], along=2.0, across=0.5)
    w = mesh.across * mesh.weights + (mesh.along - mesh.across) * mesh.directional
    rng = np.random.default_rng(3)
    for shape in [(mesh.n_vertices,), (2, mesh.n_vertices), (3, mesh.n_vertices), (4, 2, mesh.n_vertices)]:
        x = jnp.asarray(rng.normal(size=shape), jnp.float32)
        fused = np.asarray(gathered_fused(x, w, mesh.neighbours, mesh.inverse_mass))
        apart = np.asarray(gathered_apart(x, w, mesh.neighbours, mesh.inverse_mass))
        assert apart.shape == shape
        np.testing.assert_allclose(apart, fused, rtol=1e-6, atol=1e-6 * np.abs(fused).max())
        np.testing.assert_array_equal(np.asarray(mesh.apply(x)), apart if jax.default_backend() == "cpu" else fused)
        # the species packed as complex numbers are differentiated exactly like the plain reads
        grads = [np.asarray(jax.grad(lambda x, f=f: jnp.sum(jnp.sin(f(x, w, mesh.neighbours, mesh.inverse_mass))))(x))
                 for f in (gathered_fused, gathered_apart)]
        np.testing.assert_allclose(grads[1], grads[0], rtol=1e-5, atol=1e-5 * np.abs(grads[0]).max())


def test_sphere_spectrum(sphere):
    # the unit sphere's Laplace-Beltrami eigenvalues l (l + 1): 0, 2 (x3), 6 (x5)
    # dense (2562 vertices): Lanczos (eigsh) from a random start can miss a copy of the
    # degenerate l = 2 eigenvalue, which the icosphere's symmetry keeps exactly fivefold
    k, m = matrices_of(sphere)
    vals = scipy.linalg.eigh(k.toarray(), m.toarray(), subset_by_index=[0, 8], eigvals_only=True)
    assert abs(vals[0]) < 1e-6
    np.testing.assert_allclose(vals[1:4], 2.0, rtol=0.02)
    np.testing.assert_allclose(vals[4:9], 6.0, rtol=0.02)
    # the stored spectral radius is the largest eigenvalue (Lanczos, x 1.01), from above
    top = eigsh(k, k=1, M=m, which="LA", return_eigenvectors=False)[0]
    assert top <= sphere.spectral_radius <= 1.011 * top


def test_pure_diffusion_conserves_mass_and_constants(small):
    model = mj.GrayScott(feed=0.0, kill=0.0, du=0.3, dv=0.1, lower=-math.inf)  # v = 0: pure diffusion of u
    rng = np.random.default_rng(1)
    u = rng.uniform(0.5, 1.5, small.n_vertices)
    dt = 0.5 * small.max_stable_dt(0.3)
    with jax.enable_x64(True):
        out = mj.simulate(model, mj.State.from_arrays([u, np.zeros_like(u)]), 400, dt, domain=small)
        after = out.arrays()[0]
        assert small.total(after) == pytest.approx(small.total(u), rel=1e-12)
        assert after.std() < 0.2 * u.std()  # and it did diffuse
        const = mj.simulate(model, mj.State.from_arrays([np.full_like(u, 0.7), np.zeros_like(u)]), 50, dt,
                            domain=small)
        np.testing.assert_array_equal(const.arrays()[0], 0.7)
    np.testing.assert_array_equal(np.asarray(small.apply(jnp.full((small.n_vertices,), 3.0))), 0.0)


def test_flat_square_is_the_five_point_lattice():
    n = 24
    mesh = mj.Mesh(*grid_mesh(n))
    rng = np.random.default_rng(2)
    x = rng.normal(size=(n, n))
    lat = np.asarray(mj.laplacian(jnp.asarray(x), boundary="no-flux", stencil="five-point"))
    got = np.asarray(mesh.apply(jnp.asarray(x.ravel()))).reshape(n, n)
    np.testing.assert_allclose(got[1:-1, 1:-1], lat[1:-1, 1:-1], rtol=1e-5, atol=1e-5)
    # a Gray-Scott run from a central square: the same pattern as on the lattice, up to the
    # boundary's discretisation (vertex-centred half cells on the mesh, cell-centred ghost
    # cells on the lattice) once the pattern reaches the edges
    state = mj.gray_scott_state(jax.random.key(0), (n, n), square=0.3, noise=0.0)
    a, b = state.arrays()
    model = mj.GrayScott(**GS)
    on_lattice = mj.simulate(model, state, 300, 1.0, domain=mj.Lattice("five-point", "no-flux")).arrays()[1]
    on_mesh = mj.simulate(model, mj.State.from_arrays([a.ravel(), b.ravel()]), 300, 1.0, domain=mesh).arrays()[1]
    assert np.abs(on_mesh.reshape(n, n) - on_lattice).max() < 0.01 * on_lattice.max()
    assert on_lattice.max() > 0.1  # the pattern is alive


def test_gray_scott_run_matches_oracle(small):
    rng = np.random.default_rng(3)
    u, v = 1.0 - rng.uniform(0, 0.5, small.n_vertices), rng.uniform(0, 0.3, small.n_vertices)
    dt = 0.5 * small.max_stable_dt(GS["du"])
    ref = gray_scott_run(laplacian(small.vertices, small.faces), u, v, dt=dt, steps=100, **GS)
    with jax.enable_x64(True):
        got = mj.simulate(mj.GrayScott(**GS), mj.State.from_arrays([u, v]), 100, dt, domain=small).arrays()
    np.testing.assert_allclose(got[0], ref[0], atol=1e-5)
    np.testing.assert_allclose(got[1], ref[1], atol=1e-5)


def test_carried_layouts_hold_the_fields_exactly(small):
    """On the CPU a run carries two species packed as one complex array: packing and
    unpacking are exact, and the operator read from the packed layout is the plain one's.
    An odd number of species is carried as it is."""
    rng = np.random.default_rng(6)
    x = jnp.asarray(rng.normal(size=(4, small.n_vertices)), jnp.float32)
    rates = [jnp.ones(1)] * 4
    for fields in (x[:2], x):
        carried = small.carry(fields, None, False)
        assert jnp.iscomplexobj(carried) == (jax.default_backend() == "cpu")
        np.testing.assert_array_equal(np.asarray(small.interior(carried)), np.asarray(fields))
        np.testing.assert_array_equal(np.asarray(small.interior(small.write(carried, 2 * fields, None, False))),
                                      np.asarray(2 * fields))
        terms = np.stack([np.asarray(t) for t in small.diffusion(carried, rates[: len(fields)])])
        np.testing.assert_allclose(terms, np.asarray(small.apply(fields)), rtol=1e-6, atol=1e-6)
    assert not jnp.iscomplexobj(small.carry(x[:3], None, False))


@pytest.mark.parametrize("rates", [[0.3, 0.1, 0.2], [0.3, 0.1, 0.2, 0.05]])
def test_any_number_of_species_runs_against_the_oracle(small, rates):
    """Three species (carried as they are) and four (two packed pairs) diffusing at their own
    rates with a linear decay, in float64: forward Euler with the SciPy operator."""
    rates, decay = np.asarray(rates), 0.05
    model = mj.Reaction(lambda x, p: -p["decay"] * x, {"decay": decay}, diffusion=list(rates), lower=-math.inf)
    rng = np.random.default_rng(7)
    x0 = rng.uniform(0.5, 1.5, (len(rates), small.n_vertices))
    dt = 0.5 * small.max_stable_dt(rates.max())
    lap = laplacian(small.vertices, small.faces)
    ref = x0.copy()
    for _ in range(60):
        ref = ref + dt * (rates[:, None] * (lap @ ref.T).T - decay * ref)
    with jax.enable_x64(True):
        got = mj.simulate(model, mj.State.from_arrays(list(x0)), 60, dt, domain=small).fields
    np.testing.assert_allclose(np.asarray(got), ref, rtol=1e-6)  # the operator is stored in float32


def test_complex_values_are_operated_on_as_complex(small):
    """The operator is linear: on complex values, the operator of the real and imaginary
    parts (complex species are never packed in pairs)."""
    rng = np.random.default_rng(9)
    re, im = (jnp.asarray(rng.normal(size=(2, small.n_vertices)), jnp.float32) for _ in range(2))
    for z, a, b in ((re[0] + 1j * im[0], re[0], im[0]), (re + 1j * im, re, im)):
        got = np.asarray(small.apply(z))
        np.testing.assert_allclose(got.real, np.asarray(small.apply(a)), rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(got.imag, np.asarray(small.apply(b)), rtol=1e-5, atol=1e-5)


def test_dt_check_refuses_unstable_step_and_limit_is_tight(small):
    model = mj.GrayScott(feed=0.0, kill=0.0, du=1.0, dv=0.1, lower=-math.inf)
    limit = small.max_stable_dt(1.0)
    rng = np.random.default_rng(4)
    state = mj.State.from_arrays([rng.normal(size=small.n_vertices), np.zeros(small.n_vertices)])
    with pytest.raises(ValueError, match="largest stable dt is"):
        mj.simulate(model, state, 10, 1.05 * limit, domain=small)
    with jax.enable_x64(True):
        x0 = np.asarray(state.fields, float)
        s64 = mj.State.from_arrays(list(x0), dtype=jnp.float64)
        stable = mj.simulate(model, s64, 400, 0.99 * limit, domain=small).arrays()[0]
        unstable = mj.run_status(model, s64, 400, 1.05 * limit, domain=small, check_dt=False).state.arrays()[0]
    assert np.abs(stable).max() <= np.abs(x0[0]).max()
    assert not np.isfinite(unstable).all() or np.abs(unstable).max() > 1e3 * np.abs(x0[0]).max()


def test_vmap_and_grad(small):
    rng = np.random.default_rng(5)
    u, v = 1.0 - rng.uniform(0, 0.5, small.n_vertices), rng.uniform(0, 0.3, small.n_vertices)
    dt = 0.5 * small.max_stable_dt(GS["du"])
    with jax.enable_x64(True):
        state = mj.State.from_arrays([u, v])

        def loss(feed):
            out = mj.simulate(mj.GrayScott(feed=feed, kill=0.0649, du=0.2097, dv=0.105), state, 30, dt, domain=small)
            return jnp.sum(out.fields[1] ** 2 / small.inverse_mass)  # the mass-weighted total of v^2

        feeds = jnp.asarray([0.03, 0.04, 0.05])
        batched = jax.vmap(loss)(feeds)
        for f, b in zip(feeds, batched):
            assert float(b) == pytest.approx(float(loss(f)), rel=1e-10)
        g = float(jax.grad(loss)(0.04))
        h = 1e-6
        fd = (float(loss(0.04 + h)) - float(loss(0.04 - h))) / (2 * h)
        assert g == pytest.approx(fd, rel=1e-5)
        assert g != 0.0


def test_state_round_trip_in_vertex_order(small):
    rng = np.random.default_rng(6)
    u, v = rng.normal(size=small.n_vertices), rng.normal(size=small.n_vertices)
    state = mj.State.from_arrays([u, v], dtype=jnp.float32)
    assert state.ndim == 1 and state.shape == (small.n_vertices,)
    a, b = state.arrays()
    np.testing.assert_array_equal(a, u.astype(np.float32))
    np.testing.assert_array_equal(b, v.astype(np.float32))


def test_domain_serialises_exactly(small):
    data = json.loads(json.dumps(_serialise.domain_to_dict(small)))
    back = _serialise.domain_from_dict(data)
    assert isinstance(back, mj.Mesh) and back.rho == small.rho and back.mass == small.mass
    for name in ("vertices", "faces", "neighbours", "weights", "inverse_mass"):
        np.testing.assert_array_equal(np.asarray(getattr(back, name)), np.asarray(getattr(small, name)))


def test_a_saved_vertex_major_operator_still_loads(small):
    """Files written before the tables became slot-major hold them (V, K): read the same."""
    mesh = mj.Mesh(small.vertices, small.faces, direction=[0.0, 0.0, 1.0], along=2.0)
    params = _serialise.domain_to_dict(mesh)["params"]
    tables = ("neighbours", "weights", "directional")
    for name in tables:
        params[name] = np.asarray(getattr(mesh, name)).T.tolist()
    back = _serialise.domain_from_dict({"type": "Mesh", "params": params})
    for name in tables:
        np.testing.assert_array_equal(np.asarray(getattr(back, name)), np.asarray(getattr(mesh, name)))
    params["weights"] = params["weights"][:-1]
    with pytest.raises(ValueError, match="saved operator does not match"):
        _serialise.domain_from_dict({"type": "Mesh", "params": params})


def test_phase_with_mesh_serialises_and_resumes(tmp_path):
    exp = mj.preset("mesh-gray-scott-spots-sphere", quick=True)
    assert isinstance(exp.phases[-1].domain, mj.Mesh)
    loaded = mj.Experiment.from_dict(json.loads(json.dumps(exp.to_dict())))
    np.testing.assert_array_equal(np.asarray(loaded.phases[0].domain.weights), np.asarray(exp.phases[0].domain.weights))
    total = exp.total_steps
    whole = mj.run_experiment(exp, seed=3)
    ckpt = tmp_path / "half.npz"
    mj.run_experiment(exp, seed=3, checkpoint_path=ckpt, checkpoint_every=total // 2, stop_after=total // 2)
    resumed = mj.run_experiment(exp, seed=3, resume=ckpt)
    np.testing.assert_array_equal(np.asarray(resumed.state.fields), np.asarray(whole.state.fields))
    assert resumed.state.ndim == 1
    # the start read back from the file is the same start (one value per vertex)
    key = jax.random.key(3)
    np.testing.assert_array_equal(np.asarray(loaded.initial.build(key).fields), np.asarray(exp.initial.build(key).fields))


def test_initial_states_with_one_value_per_vertex():
    from morphojax._experiment import Initial

    n, key = 40, jax.random.key(1)
    paper = Initial("paper", (n,)).build(key)
    assert paper.shape == (n,) and paper.ndim == 1
    a, b = paper.arrays()
    assert (a == 4.0).all() and (b >= 4.0).all() and (b < 5.0).all()
    # the same draws as a lattice of one row: the vertex order is the only layout
    np.testing.assert_array_equal(np.asarray(paper.fields), np.asarray(mj.paper_state(key, (1, n)).fields)[:, 0])
    assert Initial("uniform", (n,), params=((0.0, 1.0), 2.5)).build(key).fields.shape == (2, n)
    seeded = (3, 7, 8)
    u, v = Initial("gray-scott", (n,), params=(0.0, seeded)).build(key).arrays()
    mask = np.isin(np.arange(n), seeded)
    assert (u[mask] == 0.5).all() and (v[mask] == 0.25).all() and (u[~mask] == 1.0).all() and (v[~mask] == 0.0).all()
    with pytest.raises(ValueError, match="needs seeded="):
        mj.gray_scott_state(key, (n,))
    with pytest.raises(ValueError, match="vertex indices"):
        mj.gray_scott_state(key, (n,), seeded=[n])
    with pytest.raises(ValueError, match="capacity"):
        mj.paper_state(key, (n,), capacity=(50,))
    with pytest.raises(ValueError, match=r"\(vertices,\) for a mesh or \(depth, rows, cols\)"):
        mj.paper_state(key, (2, 3, 4, 5))  # a 3D lattice's (depth, rows, cols) is a shape; four axes are not


@pytest.mark.parametrize("bad, match", [
    ((np.eye(3), [[0, 1, 1]]), "repeat a vertex"),
    ((np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]), [[0, 1, 2]]), "zero area"),
    ((np.eye(3), [[0, 1, 3]]), r"indices must lie in \[0, 2\]"),
    ((np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.0]]), [[0, 1, 2], [0, 1, 3], [0, 1, 4]]),
     "not manifold"),
    ((np.eye(4)[:, :3], [[0, 1, 2]]), "no face uses"),
    ((np.eye(3)[:, :2], [[0, 1, 2]]), r"shape \(V, 3\)"),
])
def test_bad_meshes_are_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        mj.Mesh(*bad)


@pytest.mark.parametrize("fmt", ["obj", "ply", "stl", "off"])
def test_from_file(tmp_path, fmt):
    trimesh = pytest.importorskip("trimesh")
    mesh = mj.Mesh.icosphere(1)
    path = tmp_path / f"ball.{fmt}"
    trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(str(path))
    back = mj.Mesh.from_file(path)
    assert back.n_vertices == mesh.n_vertices and len(back.faces) == len(mesh.faces)
    assert back.spectral_radius == pytest.approx(mesh.spectral_radius, rel=1e-4)
    with pytest.raises(ValueError, match="unknown format"):
        mj.Mesh.from_file(tmp_path / "ball.xyz")


def test_primitives_are_closed_and_outward():
    for mesh, area in ((mj.Mesh.icosphere(3), 4 * np.pi), (mj.Mesh.torus(2.0, 0.75, 0.2), 4 * np.pi ** 2 * 1.5),
                       (mj.Mesh.capsule(1.0, 3.0, 0.2), 4 * np.pi + 6 * np.pi)):
        v, f = mesh.vertices.astype(float), mesh.faces
        volume = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6
        assert volume > 0  # outward winding
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        assert (np.unique(edges, axis=0, return_counts=True)[1] == 2).all()  # closed
        assert mesh.masses().sum() == pytest.approx(area, rel=0.02)


def test_vertex_colours_in_ply_and_obj(tmp_path, small):
    values = np.asarray(small.vertices[:, 2])
    colours = mj.vertex_colours(values, cmap="viridis")
    assert colours.shape == (small.n_vertices, 3) and colours.dtype == np.uint8
    path = mj.write_ply(tmp_path / "c.ply", small.vertices, small.faces, colour=colours)
    v, f, c = read_ply(path, colours=True)
    np.testing.assert_array_equal(c, colours)
    np.testing.assert_array_equal(f, small.faces)
    lines = mj.write_obj(tmp_path / "c.obj", small.vertices, small.faces, colour=colours).read_text().splitlines()
    first = next(line for line in lines if line.startswith("v "))
    assert len(first.split()) == 7  # v x y z r g b


def test_mesh_image(small):
    img = mj.mesh_image(small, np.asarray(small.vertices[:, 2]), size=120)
    arr = np.asarray(img)
    assert img.size == (120, 120) and arr.std() > 10  # a drawn, shaded surface on the background


def test_cli_mesh_and_preset_picture(tmp_path):
    from morphojax.cli import main

    src = tmp_path / "ball.off"
    ball = mj.Mesh.icosphere(2, 5.0)
    import trimesh

    trimesh.Trimesh(ball.vertices, ball.faces, process=False).export(str(src))
    out = tmp_path / "ball.ply"
    assert main(["mesh", str(src), "--model", "gray-scott", "--steps", "20", "--out", str(out), "--quiet"]) == 0
    v, f, c = read_ply(out, colours=True)
    assert len(v) == ball.n_vertices and c is not None and (tmp_path / "ball.png").exists()
    assert main(["mesh", str(src), "--dt", "100", "--steps", "5", "--out", str(out), "--quiet"]) == 2  # refused
    # --operator umbrella runs the API's umbrella mesh: the same values, vertex for vertex
    assert main(["mesh", str(src), "--operator", "umbrella", "--steps", "20", "--dt", "0.5", "--out", str(out),
                 "--quiet"]) == 0
    with np.load(out.with_suffix(".npz")) as data:
        got = np.asarray(data["species_v"])
        assert json.loads(str(data["metadata"]))["operator"] == "umbrella"
    umbrella = mj.Mesh.from_file(src)
    umbrella = mj.Mesh(umbrella.vertices, umbrella.faces, operator="umbrella")
    model = mj.GrayScott()
    from morphojax.cli._mesh import mesh_state

    want = mj.simulate(model, mesh_state(model, umbrella, jax.random.key(0)), 20, 0.5, domain=umbrella).array("v")
    assert np.isfinite(got).all()
    np.testing.assert_array_equal(got, np.asarray(want))
    exp = mj.preset("mesh-gray-scott-spots-sphere", quick=True)
    state = exp.initial.build(jax.random.key(0))
    assert state.ndim == 1 and state.shape == (exp.phases[0].domain.n_vertices,)
    img = mj.render_experiment(state, exp)
    assert img.size == (384, 384)


def test_anisotropic_operator_on_a_flat_square():
    # direction x on the right-triangle grid: the tensor diag(along, across) gives exactly
    # along x the second difference in x plus across x the one in y at interior vertices
    n = 16
    v, f = grid_mesh(n)
    mesh = mj.Mesh(v, f, direction=(1.0, 0.0, 0.0), along=2.0, across=0.5)
    x = np.random.default_rng(7).normal(size=(n, n))
    got = np.asarray(mesh.apply(jnp.asarray(x.ravel()))).reshape(n, n)[1:-1, 1:-1]
    dxx = x[1:-1, 2:] + x[1:-1, :-2] - 2 * x[1:-1, 1:-1]
    dyy = x[2:, 1:-1] + x[:-2, 1:-1] - 2 * x[1:-1, 1:-1]
    np.testing.assert_allclose(got, 2.0 * dxx + 0.5 * dyy, atol=1e-5)
    assert mesh.spectral_radius == pytest.approx(4 * 2.0 + 4 * 0.5, rel=0.011)  # the grid's top mode
    same = mj.Mesh(v, f, direction=(1.0, 0.0, 0.0))  # along = across = 1: the cotangent operator
    np.testing.assert_allclose(np.asarray(same.apply(jnp.asarray(x.ravel()))),
                               np.asarray(mj.Mesh(v, f).apply(jnp.asarray(x.ravel()))), atol=1e-5)


def test_anisotropic_mesh_conserves_mass_serialises_and_differentiates():
    rng = np.random.default_rng(8)
    base = mj.Mesh.capsule(1.0, 1.5, 0.35)
    field = rng.normal(size=(base.n_vertices, 3))  # any per-vertex field
    mesh = mj.Mesh(base.vertices, base.faces, direction=field, along=1.0, across=0.25)
    back = _serialise.domain_from_dict(json.loads(json.dumps(_serialise.domain_to_dict(mesh))))
    np.testing.assert_array_equal(np.asarray(back.directional), np.asarray(mesh.directional))
    assert back.rho == mesh.rho and float(back.across) == 0.25
    with jax.enable_x64(True):
        u = rng.uniform(0.5, 1.5, base.n_vertices)
        assert float(mesh.total(np.asarray(mesh.apply(jnp.asarray(u))))) == pytest.approx(0.0, abs=1e-9)

        def loss(across):
            m = mj.Mesh(base.vertices, base.faces, direction=(1.0, 0.0, 0.0))
            m = eqx.tree_at(lambda d: d.across, m, across)
            return jnp.sum(m.apply(jnp.asarray(u)) ** 2)

        g = float(jax.grad(loss)(0.5))
        fd = (float(loss(0.5 + 1e-6)) - float(loss(0.5 - 1e-6))) / 2e-6
        assert g == pytest.approx(fd, rel=1e-6) and g != 0.0


# ---- the umbrella operator (paper 004's "equally weighted" Laplacian) ------------------------
@pytest.fixture(scope="module")
def umbrella(small):
    return mj.Mesh(small.vertices, small.faces, operator="umbrella")


def _dense_operator(mesh):
    """The operator as a dense float64 matrix (column j: L applied to the unit field e_j)."""
    with jax.enable_x64(True):
        return np.asarray(mesh.apply(jnp.eye(mesh.n_vertices, dtype=jnp.float64)), np.float64).T


def test_umbrella_operator_matches_oracle(umbrella):
    """On a closed capsule and on a flat square with its boundary (corners of degree 2 and 3)."""
    from mesh_oracle import umbrella_laplacian

    rng = np.random.default_rng(40)
    for mesh in (umbrella, mj.Mesh(*grid_mesh(7), operator="umbrella")):
        x = rng.normal(size=(3, mesh.n_vertices))
        ref = (umbrella_laplacian(mesh.n_vertices, mesh.faces) @ x.T).T
        with jax.enable_x64(True):
            got = np.asarray(mesh.apply(jnp.asarray(x)))
        np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-6)
    corners = mj.Mesh(*grid_mesh(7), operator="umbrella").masses()[[0, 6, 42, 48]]
    np.testing.assert_allclose(corners, [3, 2, 2, 3])  # the diagonal runs from corner 0 to corner 48


def test_umbrella_operator_invariants(umbrella, small):
    """Constants are fixed points; L is symmetric in the degree-weighted inner product (the
    weights `masses()` gives the IMEX solve), so pure diffusion conserves sum deg_i u_i; its
    spectrum lies in [-2, 0] and the stated radius bounds it closely; it ignores lengths."""
    n = umbrella.n_vertices
    np.testing.assert_array_equal(np.asarray(umbrella.apply(jnp.full((n,), 3.0))), 0.0)
    lap = _dense_operator(umbrella)
    degrees = umbrella.masses()
    np.testing.assert_allclose(degrees, np.count_nonzero(lap - np.diag(np.diag(lap)), axis=1), rtol=1e-6)
    weighted = degrees[:, None] * lap
    np.testing.assert_allclose(weighted, weighted.T, atol=1e-6)
    eig = np.linalg.eigvals(lap).real
    assert eig.max() < 1e-9 and eig.min() >= -2.0 - 1e-9
    assert -eig.min() <= umbrella.rho <= 1.02 * -eig.min()
    assert umbrella.rho <= 2.0 and "umbrella" in umbrella.description
    scaled = mj.Mesh(3.0 * np.asarray(small.vertices), small.faces, operator="umbrella")
    np.testing.assert_allclose(_dense_operator(scaled), lap, atol=1e-12)  # no length unit
    model = mj.GrayScott(feed=0.0, kill=0.0, du=0.3, dv=0.1, lower=-math.inf)
    u = np.random.default_rng(41).uniform(0.5, 1.5, n)
    with jax.enable_x64(True):
        out = mj.simulate(model, mj.State.from_arrays([u, np.zeros_like(u)]), 300,
                          0.9 * umbrella.max_stable_dt(0.3), domain=umbrella).arrays()[0]
    assert umbrella.total(out) == pytest.approx(umbrella.total(u), rel=1e-12)
    assert out.std() < 0.2 * u.std()


def test_umbrella_gray_scott_run_matches_oracle(umbrella):
    from mesh_oracle import umbrella_laplacian

    rng = np.random.default_rng(42)
    n = umbrella.n_vertices
    u, v = 1.0 - rng.uniform(0, 0.5, n), rng.uniform(0, 0.3, n)
    dt = 0.9 * umbrella.max_stable_dt(GS["du"])
    ref = gray_scott_run(umbrella_laplacian(n, umbrella.faces), u, v, dt=dt, steps=100, **GS)
    with jax.enable_x64(True):
        got = mj.simulate(mj.GrayScott(**GS), mj.State.from_arrays([u, v]), 100, dt, domain=umbrella).arrays()
    np.testing.assert_allclose(got[0], ref[0], atol=1e-6)
    np.testing.assert_allclose(got[1], ref[1], atol=1e-6)


def test_umbrella_imex_is_backward_euler(umbrella):
    """IMEX(1) on pure diffusion is one backward-Euler step (I - dt D L) x1 = x, solved by
    conjugate gradients in the degree-weighted inner product, against a dense solve."""
    n = umbrella.n_vertices
    with jax.enable_x64(True):
        x = np.random.default_rng(43).normal(size=(2, n))
        model = mj.Reaction(lambda y, p: 0.0 * y, diffusion=[1.0, 0.3], lower=-np.inf)
        out = np.asarray(mj.simulate(model, mj.State.from_arrays(list(x)), 1, 5.0, domain=umbrella,
                                     solver=mj.IMEX(1)).fields)
    lap = _dense_operator(umbrella)
    for i, rate in enumerate((1.0, 0.3)):
        np.testing.assert_allclose(out[i], np.linalg.solve(np.eye(n) - 5.0 * rate * lap, x[i]), atol=1e-9)


def test_umbrella_mesh_serialises_and_refuses_what_it_lacks(umbrella, small):
    back = _serialise.domain_from_dict(json.loads(json.dumps(_serialise.domain_to_dict(umbrella))))
    assert back.operator == "umbrella" and back.rho == umbrella.rho
    for name in ("neighbours", "weights", "inverse_mass"):
        np.testing.assert_array_equal(np.asarray(getattr(back, name)), np.asarray(getattr(umbrella, name)))
    assert _serialise.domain_from_dict(_serialise.domain_to_dict(small)).operator == "cotangent"
    with pytest.raises(ValueError, match="operator"):
        mj.Mesh(small.vertices, small.faces, operator="uniform")
    with pytest.raises(ValueError, match="degree"):
        mj.Mesh(small.vertices, small.faces, mass="barycentric", operator="umbrella")
    with pytest.raises(ValueError, match="cotangent"):
        mj.Mesh(small.vertices, small.faces, direction=[0.0, 0.0, 1.0], operator="umbrella")
    mesh = mj.Mesh.icosphere(1, operator="umbrella")  # the primitives pass it on
    assert mesh.operator == "umbrella" and set(np.round(mesh.masses()).astype(int)) == {5, 6}

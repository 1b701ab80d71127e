"""Growing meshes (`MeshGrowth`): exact invariants of scaling and division, the values new
vertices take, the capacity's overflow, and phases that save, resume and draw (float64).

Every run here uses one model, one mesh capacity and one event period, so the compiled
chunk is shared by the module's runs."""

import dataclasses
import json

import jax
import numpy as np
import pytest

import morphojax as mj
from morphojax.domains._mesh_growth import MeshGeometry, triangle_areas

CAPACITY, EVERY, DT = 320, 10, 0.05


@pytest.fixture(scope="module", autouse=True)
def x64():
    with jax.enable_x64(True):
        yield


def _mesh(mass="barycentric"):
    return mj.Mesh.icosphere(2, 3.0, mass=mass)  # 162 vertices, triangles of area 0.32 to 0.41


def _diffusion(d=0.3):
    return mj.Bard(alpha=0.0, beta=0.0, sp=0.0, da=d, db=0.5 * d, lower=-np.inf)


def _state(mesh, seed=0):
    rng = np.random.default_rng(seed)
    v = mesh.n_vertices
    return mj.State.from_arrays([rng.uniform(1.0, 2.0, v), rng.uniform(0.0, 1.0, v)], capacity=(CAPACITY,))


def _edges(faces):
    return {(int(a), int(b)) for f in np.asarray(faces) for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}


# ---- the geometry alone (no compilation) ----------------------------------------------------
@pytest.mark.parametrize("edge", ["random", "longest"])
def test_division_keeps_a_closed_oriented_manifold(edge):
    """After every event: each split adds one vertex, two faces and three edges (a closed
    surface: V - E + F stays 2), every directed edge has its reverse once (one consistent
    winding, no hole, manifold), the area is unchanged and no triangle is left above
    the threshold that was not just made (children have half their parent's area)."""
    mesh = _mesh()
    growth = mj.MeshGrowth(0.0, divide_area=0.3, every=EVERY, edge=edge, seed=3)
    geo = MeshGeometry(mesh, 10_000)
    area = triangle_areas(geo.vertices, geo.faces).sum()
    for event in range(3):
        v0, f0 = geo.n_vertices, len(geo.faces)
        geo.event(growth, DT)
        splits = geo.n_vertices - v0
        assert len(geo.faces) == f0 + 2 * splits
        edges = _edges(geo.faces)
        assert len(edges) == 3 * len(geo.faces) and all((b, a) in edges for a, b in edges)
        assert geo.n_vertices - len(edges) // 2 + len(geo.faces) == 2
        np.testing.assert_allclose(triangle_areas(geo.vertices, geo.faces).sum(), area, rtol=1e-13)
    assert geo.n_vertices > 2 * mesh.n_vertices
    mj.Mesh(geo.vertices, geo.faces)  # Mesh's own checks: manifold, no degenerate face, every vertex used


def test_division_on_an_open_surface_splits_boundary_edges_alone():
    """A flat square sheet (a boundary): a split of a boundary edge adds one face, of an
    interior edge two; V - E + F stays 1 (a disc), every interior edge keeps its reverse,
    and the area is unchanged."""
    n = 6
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], 1)
    faces = [(r * n + c, r * n + c + 1, (r + 1) * n + c + 1) for r in range(n - 1) for c in range(n - 1)]
    faces += [(r * n + c, (r + 1) * n + c + 1, (r + 1) * n + c) for r in range(n - 1) for c in range(n - 1)]
    geo = MeshGeometry(mj.Mesh(vertices, np.asarray(faces), mass="barycentric"), 10_000)
    growth = mj.MeshGrowth(0.0, divide_area=0.3, every=EVERY, edge="random", seed=7)
    geo.event(growth, DT)
    edges = _edges(geo.faces)
    boundary = [e for e in edges if (e[1], e[0]) not in edges]
    interior = len(edges) - len(boundary)
    assert geo.n_vertices - (interior // 2 + len(boundary)) + len(geo.faces) == 1
    assert len(boundary) > 4 * (n - 1)  # some boundary edges were split
    np.testing.assert_allclose(triangle_areas(geo.vertices, geo.faces).sum(), (n - 1) ** 2, rtol=1e-13)
    assert np.allclose(geo.vertices[:, 2], 0.0) and len(geo.faces) > 2 * (n - 1) ** 2


def test_scaling_multiplies_lengths_by_the_rate():
    """Uniform scaling: after n events every vertex is exp(rate every dt n) times as far
    from the centroid and the area exp(2 rate every dt n) times; a field scales each vertex
    by its own factor (zero: the vertex stays)."""
    mesh = _mesh()
    rate, n = 0.4, 3
    grown = mj.MeshGrowth(rate, every=EVERY).grown(mesh, n * EVERY + EVERY - 1, DT)
    s = np.exp(rate * EVERY * DT * n)
    v0 = np.asarray(mesh.vertices, np.float64)
    centre = v0.mean(0)
    np.testing.assert_allclose(np.asarray(grown.vertices, np.float64), centre + (v0 - centre) * s, rtol=1e-6)
    np.testing.assert_allclose(grown.masses().sum(), mesh.masses().sum() * s ** 2, rtol=1e-6)
    field = (v0[:, 2] > 0).astype(float)  # the upper half grows, the lower stays
    half = mj.MeshGrowth(rate, field=field, every=EVERY).grown(mesh, n * EVERY, DT)
    moved = np.asarray(half.vertices, np.float64)
    np.testing.assert_allclose(moved[field == 0], v0[field == 0], atol=1e-6)
    np.testing.assert_allclose(moved[field == 1], (centre + (v0 - centre) * s)[field == 1], rtol=1e-6)


def test_bad_growth_is_refused():
    for kwargs, match in ((dict(rate=-1.0), "rate"), (dict(divide_area=0.0), "divide_area"),
                          (dict(every=0), "every"), (dict(edge="shortest"), "edge"),
                          (dict(field=np.ones((2, 2))), "field"), (dict(field=-np.ones(4)), "field")):
        with pytest.raises(ValueError, match=match):
            mj.MeshGrowth(**{"rate": 0.1, **kwargs})
    with pytest.raises(ValueError, match="162 vertices"):
        mj.MeshGrowth(0.1, field=np.ones(5)).grown(_mesh(), 10, DT)
    with pytest.raises(ValueError, match="anisotropic"):
        mj.MeshGrowth(0.1).grown(mj.Mesh.icosphere(1, direction=(1.0, 0.0, 0.0), along=0.5), 10, DT)
    with pytest.raises(ValueError, match="operator='umbrella'"):  # growth rebuilds the cotangent operator
        mj.MeshGrowth(0.1).grown(mj.Mesh.icosphere(1, operator="umbrella"), 10, DT)


# ---- runs ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def divided():
    """Pure diffusion while triangles above 0.33 divide (at random edges): 60 steps."""
    mesh = _mesh()
    growth = mj.MeshGrowth(0.0, divide_area=0.33, every=EVERY, seed=1)
    state = _state(mesh)
    out = mj.simulate(_diffusion(), state, 6 * EVERY, DT, domain=mesh, growth=growth)
    return mesh, growth, state, out


def test_division_conserves_mass_exactly(divided):
    """Without dilution and with barycentric masses, a midpoint split moves area and mass
    from the parents to the new vertex and keeps sum_i M_i u_i: with pure diffusion the
    mass-weighted total is the initial one (float64 rounding), on a mesh that grew."""
    mesh, growth, state, out = divided
    start = growth.grown(mesh, 0, DT)
    end = growth.grown(mesh, 6 * EVERY, DT, capacity=CAPACITY)
    assert out.shape == (end.n_vertices,) and end.n_vertices > mesh.n_vertices + 20
    before = start.total(np.stack(state.arrays()))
    np.testing.assert_allclose(end.total(np.stack(out.arrays())), before, rtol=1e-12)
    np.testing.assert_allclose(end.masses().sum(), start.masses().sum(), rtol=1e-12)
    assert not np.asarray(out.fields)[:, end.n_vertices:].any()  # the capacity beyond stays zero


def test_new_vertices_take_their_parents_mean():
    """With no reaction and no diffusion, a linear field stays linear: a midpoint's value is
    its parents' mean, the linear function at the midpoint (the oracle: the function)."""
    mesh = _mesh()
    growth = mj.MeshGrowth(0.0, divide_area=0.33, every=EVERY, seed=2)
    v = np.asarray(mesh.vertices, np.float64)
    still = mj.Bard(alpha=0.0, beta=0.0, sp=0.0, da=0.0, db=0.0, lower=-np.inf)
    linear = lambda p: np.stack([p[:, 0] + 2.0 * p[:, 1] - p[:, 2], 3.0 - p[:, 1]])
    state = mj.State.from_arrays(list(linear(v)), capacity=(CAPACITY,))
    out = mj.simulate(still, state, 3 * EVERY, DT, domain=mesh, growth=growth, check_dt=False)
    grown = growth.grown(mesh, 3 * EVERY, DT, capacity=CAPACITY)
    assert grown.n_vertices > mesh.n_vertices
    np.testing.assert_allclose(np.stack(out.arrays()), linear(np.asarray(grown.vertices, np.float64)), atol=1e-5)


@pytest.mark.parametrize("dilute", [False, True])
def test_scaling_with_and_without_dilution(dilute):
    """Uniform scaling by s per event on Voronoi masses: without dilution the values stay
    and the mass-weighted total grows as the area (s^2 per event); with dilution every
    vertex keeps its mass, so the total is the initial one. Pure diffusion between events."""
    mesh = _mesh("voronoi")
    rate = 0.3
    growth = mj.MeshGrowth(rate, every=EVERY, dilute=dilute)
    state = _state(mesh, 1)
    out = mj.simulate(_diffusion(), state, 3 * EVERY, DT, domain=mesh, growth=growth)
    start, end = growth.grown(mesh, 0, DT), growth.grown(mesh, 3 * EVERY, DT)
    s2 = np.exp(2 * rate * EVERY * DT * 3)
    factor = 1.0 if dilute else s2
    np.testing.assert_allclose(end.total(np.stack(out.arrays())), start.total(np.stack(state.arrays())) * factor,
                               rtol=1e-12)


def test_growth_events_do_not_recompile_the_chunks():
    """The operator rebuilt at every event keeps its padded shape, so the chunks between
    events are one compiled program however many events fall in the run (the first call's
    cut chunk aside): running 3 and then 6 events compiles nothing more."""
    from morphojax._loop import _integrate

    mesh = _mesh()
    growth = mj.MeshGrowth(0.05, divide_area=0.38, every=EVERY, seed=4)
    state = _state(mesh, 2).with_capacity((2 * CAPACITY,))
    mj.simulate(_diffusion(), state, 3 * EVERY, DT, domain=mesh, growth=growth)
    before = _integrate._cached._cache_size()
    out = mj.simulate(_diffusion(), state, 6 * EVERY, DT, domain=mesh, growth=growth)
    assert _integrate._cached._cache_size() == before
    assert out.shape[0] > growth.grown(mesh, 3 * EVERY, DT).n_vertices  # the later events divided


def test_a_run_in_pieces_is_the_whole_run():
    """Two pieces (the second with the phase's origin) end where one run ends, whether the
    second continues from the geometry the first left or replays the events."""
    from morphojax import _growing_mesh

    mesh = _mesh()
    growth = mj.MeshGrowth(0.1, divide_area=0.45, every=EVERY, dilute=True, seed=6)
    state = _state(mesh, 3)
    whole = mj.simulate(_diffusion(), state, 3 * EVERY, DT, domain=mesh, growth=growth)
    first = mj.simulate(_diffusion(), state, EVERY + 3, DT, domain=mesh, growth=growth)
    assert _growing_mesh._LAST[0][4] == EVERY + 3  # the second piece continues from this geometry
    continued = mj.simulate(_diffusion(), first, 2 * EVERY - 3, DT, domain=mesh, growth=growth, origin=0)
    _growing_mesh._LAST.clear()
    replayed = mj.simulate(_diffusion(), first, 2 * EVERY - 3, DT, domain=mesh, growth=growth, origin=0)
    assert whole.shape[0] > mesh.n_vertices
    for piece in (continued, replayed):
        assert piece.shape == whole.shape and int(piece.step) == int(whole.step)
        np.testing.assert_allclose(np.asarray(piece.fields), np.asarray(whole.fields), rtol=0, atol=1e-13)


def test_capacity_overflow_is_reported():
    """Divisions beyond the vertex capacity are not made; simulate raises, run_status says so."""
    mesh = _mesh()
    growth = mj.MeshGrowth(0.0, divide_area=0.33, every=EVERY, seed=1)
    small = _state(mesh).with_capacity((mesh.n_vertices + 5,))
    with pytest.raises(mj.SimulationError, match="capacity"):
        mj.simulate(_diffusion(), small, 2 * EVERY, DT, domain=mesh, growth=growth)
    run = mj.run_status(_diffusion(), small, 2 * EVERY, DT, domain=mesh, growth=growth)
    assert bool(run.overflow) and run.state.shape == (mesh.n_vertices + 5,)


def test_refusals():
    mesh, model = _mesh(), _diffusion()
    state = _state(mesh)
    growth = mj.MeshGrowth(0.1, every=EVERY)
    with pytest.raises(ValueError, match="rollout"):
        mj.rollout(model, state, 20, DT, 10, domain=mesh, growth=growth)
    with pytest.raises(ValueError, match="Mesh"):
        mj.simulate(model, mj.State.from_arrays([np.ones((4, 4))] * 2, capacity=(6, 6)), 20, DT, growth=growth)
    with pytest.raises(ValueError, match="Euler"):
        mj.simulate(model, state, 20, DT, domain=mesh, growth=growth, solver=mj.IMEX())
    with pytest.raises(ValueError, match="largest stable dt"):  # the limit of the grown operator
        mj.simulate(model, state, 20, 5.0, domain=mesh, growth=growth)
    with pytest.raises(ValueError, match="eagerly"):  # its geometry is NumPy between compiled chunks
        jax.jit(lambda s: mj.simulate(model, s, 20, DT, domain=mesh, growth=growth).fields)(state)
    with pytest.raises(ValueError, match="grown for 0 phase steps"):
        mj.simulate(model, _state(mj.Mesh.icosphere(1)), 20, DT, domain=mesh, growth=growth)
    with pytest.raises(ValueError, match="last"):
        phase = mj.Phase(model, 20, DT, domain=mesh, growth=growth)
        mj.Experiment("two", mj.Initial("uniform", (mesh.n_vertices,), (CAPACITY,), (1.0, 1.0)), (phase, phase))


# ---- phases: files, resume, pictures ---------------------------------------------------------
def test_phase_round_trips_resumes_and_draws(tmp_path):
    """A Phase with MeshGrowth saves and loads to an equal phase; an experiment stopped
    between growth events and resumed from its file ends where the whole run ends (the mesh
    of the saved state is rebuilt by replaying the events); the result draws on the grown mesh."""
    mesh = _mesh()
    growth = mj.MeshGrowth(0.1, divide_area=0.4, every=EVERY, dilute=True, edge="longest", seed=5,
                           field=np.linspace(0.5, 1.5, mesh.n_vertices))
    phase = mj.Phase(_diffusion(), 5 * EVERY, DT, domain=mesh, growth=growth, name="grow", capacity=(2 * CAPACITY,))
    again = mj.Phase.from_dict(json.loads(json.dumps(phase.to_dict())))
    assert (again.growth.divide_area, again.growth.every, again.growth.dilute, again.growth.edge,
            again.growth.seed) == (0.4, EVERY, True, "longest", 5)
    np.testing.assert_array_equal(np.asarray(again.growth.field), np.asarray(growth.field))
    assert float(again.growth.rate) == 0.1 and isinstance(again.domain, mj.Mesh)
    exp = mj.Experiment("grow", mj.Initial("uniform", (mesh.n_vertices,), None, ((1.0, 2.0), (0.0, 1.0))),
                        (phase,), show="a")
    whole = mj.run_experiment(exp, seed=4)
    path = tmp_path / "half.npz"
    mj.run_experiment(exp, seed=4, stop_after=2 * EVERY + 3).save(path)
    resumed = mj.run_experiment(mj.load_experiment(mj.load_npz(path)[1]), seed=4, resume=path)
    assert resumed.state.shape == whole.state.shape and whole.state.shape[0] > mesh.n_vertices
    np.testing.assert_allclose(np.asarray(resumed.state.fields), np.asarray(whole.state.fields), rtol=0, atol=1e-12)
    grown = exp.final_domain(whole.state)
    assert grown.n_vertices == whole.state.shape[0]
    # snapshots of a growing mesh differ in shape: taken piece by piece, not by one rollout
    framed = mj.run_experiment(dataclasses.replace(exp, phases=(dataclasses.replace(phase, frames=5),)), seed=4,
                               frames=True)
    assert [s.shape[0] for _, s in framed.frames][-1] == whole.state.shape[0] and len(framed.frames) == 5
    np.testing.assert_array_equal(np.asarray(framed.state.fields), np.asarray(whole.state.fields))
    picture = whole.image()
    assert picture.size == (384, 384) and len(set(np.asarray(picture).reshape(-1, 3)[:, 0].tolist())) > 10

"""1D and 3D lattices: the stencils against kernels written here from their definitions
(scipy.ndimage does the boundary), their eigenbases, Euler and ETDRK runs, mass."""

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.ndimage as ndi

import morphojax as mj

MODES = {"wrap": "wrap", "no-flux": "reflect"}


def kernel(stencil):
    """The stencil as a dense kernel: [1, -2, 1]; the 3D five-point; the isotropic 19-point
    (faces 2/6, edges 1/6, centre -24/6)."""
    if stencil == "three-point":
        return np.array([1.0, -2.0, 1.0])
    k = np.zeros((3, 3, 3))
    for o in itertools.product((-1, 0, 1), repeat=3):
        n = sum(map(abs, o))
        if stencil == "seven-point":
            k[tuple(a + 1 for a in o)] = {0: -6.0, 1: 1.0}.get(n, 0.0)
        else:
            k[tuple(a + 1 for a in o)] = {0: -24 / 6, 1: 2 / 6, 2: 1 / 6}.get(n, 0.0)
    return k


CASES = [("three-point", (13,)), ("seven-point", (5, 6, 7)), ("nineteen-point", (5, 6, 7))]


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
@pytest.mark.parametrize("stencil, shape", CASES)
def test_stencils_and_their_eigenbases(stencil, shape, boundary):
    with jax.enable_x64(True):
        x = np.random.default_rng(0).normal(size=(2,) + shape)
        lattice = mj.Lattice(stencil, boundary)
        expect = np.stack([ndi.correlate(xi, kernel(stencil), mode=MODES[boundary]) for xi in x])
        np.testing.assert_allclose(np.asarray(lattice.apply(x)), expect, atol=1e-12)
        lam = lattice.eigenvalues(shape)
        diagonal = lattice.inverse_transform(lam * lattice.transform(jnp.asarray(x)), shape)
        np.testing.assert_allclose(np.asarray(diagonal), expect, atol=1e-12)
        # the spectral radius bounds every eigenvalue and is attained on an even wrapped lattice
        assert np.abs(lam).max() <= lattice.spectral_radius + 1e-12
        even = mj.Lattice(stencil, "wrap").eigenvalues(tuple(2 * (n // 2) + 2 for n in shape))
        np.testing.assert_allclose(np.abs(even).max(), lattice.spectral_radius)


def test_three_d_gray_scott_against_numpy_and_with_etdrk():
    """Euler in 3D equals a NumPy Euler with the 19-point kernel; ETDRK(2) at 2x the step
    ends within Euler's own first-order error of it (about 4e-3 at dt 0.5, see
    benchmarks/results/solvers.md); pure diffusion with no-flux conserves mass."""
    with jax.enable_x64(True):
        shape = (9, 10, 11)
        rng = np.random.default_rng(1)
        u, v = 1.0 - 0.5 * rng.random(shape), 0.25 * rng.random(shape)
        state = mj.State.from_arrays([u, v])
        feed, kill, du, dv = 0.037, 0.06, 0.2, 0.1
        model = mj.GrayScott(feed, kill, du, dv)
        k = kernel("nineteen-point")
        a, b = u.copy(), v.copy()
        for _ in range(40):
            lu, lv = ndi.correlate(a, k, mode="wrap"), ndi.correlate(b, k, mode="wrap")
            a, b = (np.maximum(a + 0.5 * (du * lu - a * b * b + feed * (1 - a)), 0),
                    np.maximum(b + 0.5 * (dv * lv + a * b * b - (feed + kill) * b), 0))
        out = mj.simulate(model, state, 40, 0.5)  # the 3D default stencil is nineteen-point
        np.testing.assert_allclose(np.asarray(out.fields), np.stack([a, b]), atol=1e-12)
        etd = mj.simulate(model, state, 20, 1.0, solver=mj.ETDRK(2))
        assert float(jnp.abs(etd.fields - out.fields).max()) < 5e-3
        diffusion = mj.Reaction(lambda x, p: 0.0 * x, diffusion=[1.0], lower=-np.inf)
        mass = mj.simulate(diffusion, mj.State.from_arrays([u]), 30, 0.3, "no-flux", solver=mj.Euler())
        np.testing.assert_allclose(float(mass.fields.sum()), u.sum(), rtol=1e-13)


def test_one_d_default_stencil_and_refusals():
    state = mj.State.from_arrays([4.0 + 0.1 * np.random.default_rng(2).normal(size=31), np.full(31, 4.0)])
    out = mj.simulate(mj.Turing(4.0, 3.0), state, 50, 0.01)
    assert out.fields.shape == (2, 31) and np.isfinite(np.asarray(out.fields)).all()
    with pytest.raises(ValueError, match="2 spatial axes"):
        mj.simulate(mj.Turing(4.0, 3.0), state, 5, 0.01, stencil="nine-point")
    with pytest.raises(ValueError, match="anisotropic diffusion and polarity are defined on 2D"):
        mj.Lattice("nineteen-point", anisotropic="a", polarity=0.0)
    with pytest.raises(ValueError, match="explicit-Euler stability limit"):
        mj.simulate(mj.Turing(4.0, 3.0), state, 5, 0.2)  # D_a = 12 on [1, -2, 1]: limit 2 / 48


def test_solid_texture_preset(tmp_path):
    """gray-scott-3d (quick) writes slices, the fields and a closed isosurface; the same
    seed gives the same fields."""
    import trimesh

    first = mj.PRESETS["gray-scott-3d"].run(seed=0, quick=True, out=tmp_path / "a" / "gs.png")
    again = mj.PRESETS["gray-scott-3d"].run(seed=0, quick=True, out=tmp_path / "b" / "gs.png")
    a, b = np.load(tmp_path / "a" / "gs.npz"), np.load(tmp_path / "b" / "gs.npz")
    np.testing.assert_array_equal(a["v"], b["v"])
    assert a["v"].shape == (24, 24, 24) and np.ptp(a["v"]) > 0.2  # a pattern, not a decayed seed
    mesh = trimesh.load(tmp_path / "a" / "gs.ply")
    assert mesh.is_watertight and len(mesh.faces) == first["isosurface"]["faces"] > 1000
    assert again["files"][0].endswith("gs.png") and (tmp_path / "a" / "gs.png").stat().st_size > 0

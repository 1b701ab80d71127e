"""The packed eigenbasis (one complex FFT per pair of species on "wrap") against the
domain's own transforms: every solver's step agrees to float32 rounding."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
from morphojax.solvers._basis import Eigenbasis

SOLVERS = [mj.ETDRK(1), mj.ETDRK(2), mj.ETDRK(4), mj.IMEX(1), mj.IMEX(2), mj.IMEX(2, rtol=1e-3)]


def _reaction(x):
    return jnp.sin(3.0 * x) - 0.5 * x * jnp.roll(x, 1, axis=0)


def _steps(solver, basis, domain, x, rates, dt):
    """The solver's step (and its embedded estimate) from x, in `basis`, in x's dtype."""
    lam = jnp.asarray(basis.eigenvalues, x.dtype)
    rates = jnp.asarray(rates, x.dtype)

    def euler_rate():
        return _reaction(x) + rates * domain.apply(x)

    co = basis.multipliers(solver.coefficients(dt * rates * lam, dt))
    return solver.advance(co, x, _reaction, euler_rate, basis.fwd, basis.inv, lambda y: y)


@pytest.mark.parametrize("shape, stencil", [((6, 7), "nine-point"), ((8, 8), "five-point"), ((9,), "three-point"),
                                            ((4, 5, 6), "nineteen-point")])
@pytest.mark.parametrize("species", [2, 4])
def test_packed_steps_match_the_real_transforms(shape, stencil, species):
    """In float32 the packed step is as close to the float64 step as the real transforms'
    step is, within float32 rounding of the largest term a step adds, for every solver."""
    rng = np.random.default_rng(species + len(shape))
    domain = mj.Lattice(stencil, "wrap")
    x = rng.random((species,) + shape)
    rates = np.geomspace(0.1, 120.0, species).reshape((-1,) + (1,) * len(shape))
    dt = 0.2
    packed, plain = Eigenbasis(domain, shape, species), Eigenbasis(domain, shape, species, pack=False)
    assert packed.packed and not plain.packed
    with jax.enable_x64(True):
        # the largest term a step adds, dt times the largest Euler rate: the pair shares one
        # transform, so each species is rounded relative to the larger of the two
        x64 = jnp.asarray(x, jnp.float64)
        term = float(dt * jnp.abs(_reaction(x64) + rates * domain.apply(x64)).max()) + float(np.abs(x).max())
        eps = float(np.finfo(np.float32).eps)
        for solver in SOLVERS:
            exact = _steps(solver, plain, domain, jnp.asarray(x, jnp.float64), rates, dt)
            got = _steps(solver, packed, domain, jnp.asarray(x, jnp.float32), rates, dt)
            want = _steps(solver, plain, domain, jnp.asarray(x, jnp.float32), rates, dt)
            for e, g, w in zip(exact, got, want):
                if e is None:
                    assert g is None and w is None
                    continue
                e, g, w = (np.asarray(a, np.float64) for a in (e, g, w))
                err_packed, err_plain = np.abs(g - e).max(), np.abs(w - e).max()
                assert err_packed <= 2 * err_plain + eps * term, (solver.name, solver.order, err_packed, err_plain)
                np.testing.assert_allclose(g, w, rtol=0, atol=2 * eps * term)


def test_the_rule_packs_even_species_on_wrap_only():
    wrap, noflux = mj.Lattice("nine-point", "wrap"), mj.Lattice("nine-point", "no-flux")
    assert Eigenbasis(wrap, (5, 6), 2).packed and Eigenbasis(wrap, (5, 6), 4).packed
    assert [s.packs for s in SOLVERS] == [True, True, False, True, False, False]
    assert not Eigenbasis(wrap, (5, 6), 3).packed
    assert not Eigenbasis(noflux, (5, 6), 2).packed

"""The time-stepping policies: ETDRK and IMEX against a dense NumPy oracle, their order,
exactness on pure diffusion, gradients against finite differences, and the steady-state
stopping rule. Float64 where numbers are compared closely."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
from morphojax.solvers._phi import phi
from oracle import gray_scott_rates
from solver_oracle import Stepper, phi as phi_oracle

SHAPE = (6, 7)  # small and odd: the dense oracle has 42 x 42 matrices
FEED, KILL, DU, DV = 0.037, 0.06, 0.2, 0.1
SOLVERS = [mj.ETDRK(1), mj.ETDRK(2), mj.ETDRK(4), mj.IMEX(1), mj.IMEX(2)]


def _start(shape=SHAPE, seed=0):
    rng = np.random.default_rng(seed)
    return 1.0 - 0.5 * rng.random(shape), 0.25 * rng.random(shape)


def _gray_scott_reaction(x):
    du, dv = gray_scott_rates(x[0], x[1], FEED, KILL, 0.0, 0.0)
    return np.stack([du, dv])


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
@pytest.mark.parametrize("stencil", ["nine-point", "five-point"])
def test_solvers_match_the_dense_oracle(boundary, stencil):
    """Three steps at dt = 2 (beyond Euler's limit 1.875 for D = 0.2 on the nine-point
    stencil) agree with the schemes written in the stencil matrix's own eigenvectors."""
    with jax.enable_x64(True):
        u, v = _start()
        state = mj.State.from_arrays([u, v])
        model = mj.GrayScott(FEED, KILL, DU, DV)
        oracle = Stepper(SHAPE, boundary, stencil, [DU, DV], _gray_scott_reaction, lower=0.0)
        domain = mj.Lattice(stencil, boundary)
        for solver in SOLVERS:
            out = mj.simulate(model, state, 3, 2.0, domain=domain, solver=solver).fields
            expect = np.stack([u, v])
            for _ in range(3):
                step = oracle.etdrk if isinstance(solver, mj.ETDRK) else oracle.imex
                expect = np.maximum(step(expect, 2.0, solver.order), 0.0)  # the clamp at lower = 0
            np.testing.assert_allclose(np.asarray(out), expect, rtol=0, atol=1e-11,
                                       err_msg=f"{solver.name}({solver.order})")


def _diffusion_only(rates):
    return mj.Reaction(lambda x, p: 0.0 * x, diffusion=rates, lower=-np.inf)


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_exponential_steps_are_exact_for_pure_diffusion(boundary):
    """One step of dt = 25 (400x Euler's limit) equals exp(t D S) x, and conserves mass."""
    with jax.enable_x64(True):
        u, v = _start(seed=1)
        oracle = Stepper(SHAPE, boundary, "nine-point", [1.0, 0.3], lambda x: 0 * x)
        exact = oracle.etdrk(np.stack([u, v]), 25.0, 1)  # N = 0: e^z x, exactly
        model = _diffusion_only([1.0, 0.3])
        state = mj.State.from_arrays([u, v])
        for order in (1, 2, 4):
            out = np.asarray(mj.simulate(model, state, 1, 25.0, boundary, solver=mj.ETDRK(order)).fields)
            np.testing.assert_allclose(out, exact, atol=1e-12)
            np.testing.assert_allclose(out.sum(axis=(1, 2)), [u.sum(), v.sum()], rtol=1e-13)


def test_phi_functions_in_float32_at_every_scale():
    """Float32 to about one rounding from the zero mode to z = -1000, where the defining
    formulas cancel (phi_3 at z = -1e-3 loses every digit in float32), and across the
    switch from series to formula at |z| = 2."""
    z = -np.concatenate([[0.0], np.logspace(-8, 3, 200)])
    for k in (1, 2, 3):
        got = np.asarray(phi(jnp.asarray(z, jnp.float32), k), float)
        np.testing.assert_allclose(got, phi_oracle(z, k), rtol=5e-7, err_msg=f"phi_{k}")


@pytest.mark.parametrize("boundary", ["wrap", "no-flux"])
def test_orders_of_convergence(boundary):
    """Halving dt divides the error at t = 8 by 2^order (against the same solver at dt =
    1/64), Gray-Scott in float64 with the limits not binding."""
    with jax.enable_x64(True):
        u, v = _start((9, 10), seed=2)
        state = mj.State.from_arrays([u, v])
        model = mj.GrayScott(FEED, KILL, DU, DV)
        for solver in [mj.Euler()] + SOLVERS:
            ref = mj.simulate(model, state, 512, 1 / 64, boundary, solver=solver).fields
            errors = [float(jnp.abs(mj.simulate(model, state, int(8 / dt), dt, boundary, solver=solver).fields
                                    - ref).max()) for dt in (0.5, 0.25)]
            observed = np.log2(errors[0] / errors[1])
            assert abs(observed - solver.order) < 0.25, (solver.name, solver.order, errors)


@pytest.mark.parametrize("solver, boundary", [(mj.ETDRK(4), "no-flux"), (mj.IMEX(2), "no-flux"),
                                              (mj.ETDRK(1), "wrap"), (mj.ETDRK(2), "wrap"), (mj.IMEX(1), "wrap")],
                         ids=["etdrk4-no-flux", "imex2-no-flux", "etdrk1-wrap", "etdrk2-wrap", "imex1-wrap"])
def test_gradients_match_finite_differences(solver, boundary):
    with jax.enable_x64(True):
        u, v = _start(seed=3)
        state = mj.State.from_arrays([u, v])
        weights = np.random.default_rng(4).random((2,) + SHAPE)

        def loss(feed, du):
            model = mj.GrayScott(feed, KILL, du, DV)
            return jnp.sum(weights * mj.simulate(model, state, 6, 1.5, boundary, solver=solver).fields)

        grad = jax.grad(loss, argnums=(0, 1))(FEED, DU)
        eps = 1e-6
        fd = ((loss(FEED + eps, DU) - loss(FEED - eps, DU)) / (2 * eps),
              (loss(FEED, DU + eps) - loss(FEED, DU - eps)) / (2 * eps))
        np.testing.assert_allclose(np.asarray(grad), np.asarray(fd), rtol=1e-6)
        assert all(abs(float(g)) > 1e-6 for g in grad)


@pytest.fixture(scope="module")
def turing_start():
    return mj.paper_state(jax.random.key(7), (24, 26))


@pytest.mark.parametrize("solver", [mj.Euler(), mj.ETDRK(2)], ids=["euler", "etdrk2"])
def test_steady_state_stops_at_the_first_small_change(turing_start, solver):
    model, dt, tol = mj.Turing(4.0, 3.0), 0.02 if isinstance(solver, mj.Euler) else 0.1, 2e-3
    run = mj.run_status(model, turing_start, 20000, dt, solver=solver, until=mj.SteadyState(tol))
    k = int(run.state.step)
    assert 0 < k < 20000 and int(run.nonfinite_step) == -1
    np.testing.assert_allclose(float(run.steady_at), k * dt, rtol=1e-6)
    np.testing.assert_allclose(float(run.state.time), k * dt, rtol=1e-6)
    previous = mj.simulate(model, turing_start, k - 1, dt, solver=solver)
    last = mj.simulate(model, previous, 1, dt, solver=solver)
    earlier = mj.simulate(model, turing_start, k - 2, dt, solver=solver)
    assert float(jnp.abs(last.fields - previous.fields).max()) / dt < tol
    assert float(jnp.abs(previous.fields - earlier.fields).max()) / dt >= tol
    np.testing.assert_array_equal(np.asarray(last.fields), np.asarray(run.state.fields))


def test_steady_state_under_vmap_stops_each_member_on_its_own(turing_start):
    model, tol = mj.Turing(4.0, 3.0), 2e-3

    def stop(dt):
        run = mj.run_status(model, turing_start, 4000, dt, solver=mj.ETDRK(1), until=mj.SteadyState(tol))
        return run.steady_at, run.state.fields, run.state.step

    dts = jnp.asarray([0.05, 0.2])
    batched = jax.vmap(stop)(dts)
    for i, dt in enumerate(dts):  # a member frozen at its stop holds the fields of its run alone
        at, fields, step = stop(dt)
        np.testing.assert_allclose(float(batched[0][i]), float(at), rtol=1e-6)
        np.testing.assert_allclose(np.asarray(batched[1][i]), np.asarray(fields), rtol=1e-5, atol=1e-5)
        assert int(batched[2][i]) == int(step) < 4000
    assert np.isfinite(np.asarray(batched[0])).all() and batched[0][0] != batched[0][1]
    never = mj.run_status(model, turing_start, 30, 0.05, solver=mj.ETDRK(1), until=mj.SteadyState(tol))
    assert np.isnan(float(never.steady_at)) and int(never.state.step) == 30


def test_gradient_through_a_stopping_rule_is_the_fixed_runs(turing_start):
    """Reverse mode through the checkpointed loop: the gradient of the run that stopped at
    step k equals the gradient of a plain k-step run."""
    dt, tol = 0.1, 5e-2
    weights = np.random.default_rng(5).random((2, 24, 26))

    def loss(ratio, until=None, steps=3000):
        model = mj.Turing(ratio, 3.0)
        out = mj.simulate(model, turing_start, steps, dt, solver=mj.ETDRK(1), until=until)
        return jnp.sum(weights * out.fields), out.step

    (value, k), grad = jax.value_and_grad(loss, has_aux=True)(4.0, mj.SteadyState(tol))
    (value_k, _), grad_k = jax.value_and_grad(loss, has_aux=True)(4.0, None, int(k))
    assert 0 < int(k) < 3000
    np.testing.assert_allclose(float(value), float(value_k), rtol=1e-6)
    np.testing.assert_allclose(float(grad), float(grad_k), rtol=1e-4)


@pytest.mark.parametrize("call, message", [
    (lambda s: mj.simulate(mj.Turing(4.0, 3.0), s, 2, 0.1, solver=mj.ETDRK(2), domain=mj.HexLattice()),
     "runs on the Lattice"),
    (lambda s: mj.simulate(mj.Turing(4.0, 3.0), s.with_capacity((20, 20)), 2, 0.1, solver=mj.IMEX(1),
                           growth=mj.Growth(rate=1.0), key=jax.random.key(0)), "growing"),
    (lambda s: mj.simulate(mj.Turing(4.0, 3.0), s, 2, 0.1, solver=mj.ETDRK(1),
                           sources=[mj.Source("a", 1.0)], key=jax.random.key(0)), "sources"),
    (lambda s: mj.simulate(mj.Turing(4.0, 3.0).replace(scale=jnp.full((10, 10), 3.0)), s, 2, 0.1,
                           solver=mj.ETDRK(1)), "rate map"),
    (lambda s: mj.simulate(mj.Turing(4.0, 3.0), s, 2, 0.1, solver="rk4"), "solver must be"),
    (lambda s: mj.simulate(mj.Turing(4.0, 3.0), s, 2, 0.01, until=1e-3), "until must be"),
    (lambda s: mj.ETDRK(3), "ETDRK.order must be 1, 2 or 4"),
    (lambda s: mj.IMEX(order=4), "IMEX.order must be 1 or 2"),
    (lambda s: mj.SteadyState(tol=0.0), "SteadyState.tol"),
    (lambda s: mj.simulate(mj.Turing(4.0, 3.0), s, 2, 0.01, solver=mj.ETDRK(1), bounds="barrier"), "barrier"),
    (lambda s: mj.simulate(mj.Turing(4.0, 3.0), s, 2, 0.01, domain=mj.HexLattice(), solver=mj.IMEX(1),
                           sources=[mj.Source("a", 1.0)], key=jax.random.key(0)), "sources add a fixed amount"),
    (lambda s: mj.ETDRK(True), "ETDRK.order must be"),
    (lambda s: mj.ETDRK(2, rtol=1e-3, atol=0.0), "ETDRK.atol"),
    (lambda s: mj.simulate(mj.Turing(4.0, 3.0), eqx.tree_at(lambda t: t.step, s, jnp.asarray(2**31 - 1000, jnp.int32)),
                           10, 0.01, solver=mj.ETDRK(2, rtol=1e-3)), "step counter within int32"),
])
def test_refusals_name_what_to_use(call, message):
    state = mj.paper_state(jax.random.key(0), (10, 10))
    with pytest.raises(ValueError, match=message):
        call(state)


def test_the_diffusion_limit_is_eulers_only():
    state = mj.paper_state(jax.random.key(0), (10, 10))
    model = mj.Turing(40.0, 3.0)  # D_a = 120: Euler's limit is 0.003125
    with pytest.raises(ValueError, match="explicit-Euler stability limit"):
        mj.simulate(model, state, 2, 0.05)
    out = mj.simulate(model, state, 2, 0.05, solver=mj.ETDRK(1))
    assert np.isfinite(np.asarray(out.fields)).all()


def test_sweep_and_phase_take_a_solver():
    """A sweep member stepped with ETDRK equals the same run alone (vmapped, not in lanes),
    and a phase records its solver in its file form."""
    state = mj.paper_state(jax.random.key(0), (12, 14))
    model = mj.Turing(40.0, 3.0)  # beyond Euler's limit at dt = 0.1
    result = mj.sweep(model, {"ratio": [20.0, 40.0]}, state, steps=30, dt=0.1, solver=mj.ETDRK(2))
    alone = mj.simulate(model.replace(ratio=40.0), state, 30, 0.1, solver=mj.ETDRK(2))
    np.testing.assert_array_equal(np.asarray(result.fields[1]), np.asarray(alone.fields))
    assert result.config["solver"] == {"solver": "ETDRK", "order": 2}
    phase = mj.Phase(model, steps=30, dt=0.1, solver=mj.IMEX(1))
    assert mj.Phase.from_dict(phase.to_dict()) == phase
    assert mj.Phase(model, steps=3, dt=0.001).to_dict()["solver"] == {"solver": "Euler", "order": 1}


def test_adaptive_steps_reach_the_time_and_follow_the_tolerance():
    """steps * dt is the time reached; the error against a fine fixed-step run of the same
    scheme falls with rtol; a first step too large is rejected and retried inside jit."""
    with jax.enable_x64(True):
        u, v = _start((9, 10), seed=6)
        state = mj.State.from_arrays([u, v])
        model = mj.GrayScott(FEED, KILL, DU, DV)
        for scheme in (mj.ETDRK, mj.IMEX):
            fine = mj.simulate(model, state, 1024, 1 / 64, solver=scheme(2)).fields
            errors = []
            for rtol in (1e-2, 1e-4):
                run = mj.run_status(model, state, 4, 4.0, solver=scheme(2, rtol=rtol, atol=1e-9))
                np.testing.assert_allclose(float(run.state.time), 16.0, rtol=1e-12)
                assert int(run.steps_taken) == int(run.state.step) > 4  # dt = 4 was too large: retried smaller
                errors.append(float(jnp.abs(run.state.fields - fine).max()))
            assert errors[1] < errors[0] / 10, (scheme.__name__, errors)
        assert int(mj.run_status(model, state, 64, 0.25, solver=mj.ETDRK(2)).steps_taken) == 64


def test_adaptive_refusals():
    state = mj.paper_state(jax.random.key(0), (10, 10))
    with pytest.raises(ValueError, match="no embedded error estimate"):
        mj.ETDRK(4, rtol=1e-3)
    with pytest.raises(ValueError, match="ETDRK.rtol"):
        mj.ETDRK(2, rtol=-1.0)
    with pytest.raises(ValueError, match="adaptive solver"):
        mj.rollout(mj.Turing(4.0, 3.0), state, 10, 0.1, 5, solver=mj.ETDRK(2, rtol=1e-3))
    assert mj.solvers.solver_from_dict(mj.ETDRK(2, rtol=1e-3).to_dict()) == mj.ETDRK(2, rtol=1e-3)


def _dense(domain, shape):
    """The domain's operator as a dense matrix (columns: the operator on unit fields)."""
    n = int(np.prod(shape))
    return np.stack([np.asarray(domain.apply(np.eye(n)[j].reshape(shape))).ravel() for j in range(n)], axis=1)


@pytest.mark.parametrize("case", ["hex-wrap", "hex-no-flux", "mesh", "lattice-map"])
def test_imex_by_conjugate_gradients_solves_the_implicit_step(case):
    """Where no transform diagonalises the operator, IMEX(1) on pure diffusion is one
    backward-Euler step, (I - dt D L) x1 = x, against a dense NumPy solve (W-symmetric L)."""
    with jax.enable_x64(True):
        rng = np.random.default_rng(8)
        if case == "mesh":
            domain, shape = mj.Mesh.icosphere(1), None
            shape = (int(domain.inverse_mass.shape[0]),)
        elif case == "lattice-map":
            domain, shape = mj.Lattice(), (7, 8)
        else:
            domain, shape = mj.HexLattice(boundary=case.split("-", 1)[1]), (8, 9)
        rates = [1.0, 0.3] if case != "lattice-map" else [rng.uniform(0.5, 2.0, shape), 0.3 * np.ones(shape)]
        model = mj.Reaction(lambda x, p: 0.0 * x, diffusion=rates, lower=-np.inf)
        x = rng.normal(size=(2,) + shape)
        out = np.asarray(mj.simulate(model, mj.State.from_arrays(list(x)), 1, 5.0, domain=domain,
                                     solver=mj.IMEX(1)).fields)
        n = int(np.prod(shape))
        for i in range(2):
            if case == "lattice-map":  # the flux form's operator for this species' map
                single = mj.Reaction(lambda y, p: 0.0 * y, diffusion=[rates[i]], lower=-np.inf)
                step = lambda e: np.asarray(mj.simulate(single, mj.State.from_arrays([e]), 1, 1.0,  # noqa: E731
                                                        domain=domain, check_dt=False).fields[0]) - e
                matrix = np.stack([step(np.eye(n)[j].reshape(shape)).ravel() for j in range(n)], axis=1)
            else:
                matrix = rates[i] * _dense(domain, shape)
            expect = np.linalg.solve(np.eye(n) - 5.0 * matrix, x[i].ravel()).reshape(shape)
            np.testing.assert_allclose(out[i], expect, atol=1e-9)


def test_imex_two_on_the_hexagonal_lattice_is_second_order():
    with jax.enable_x64(True):
        u, v = _start((8, 9), seed=9)
        state = mj.State.from_arrays([u, v])
        model, domain = mj.GrayScott(FEED, KILL, DU, DV), mj.HexLattice()
        ref = mj.simulate(model, state, 256, 1 / 32, domain=domain, solver=mj.IMEX(2)).fields
        errors = [float(jnp.abs(mj.simulate(model, state, int(8 / dt), dt, domain=domain, solver=mj.IMEX(2)).fields
                                - ref).max()) for dt in (0.5, 0.25)]
        assert abs(np.log2(errors[0] / errors[1]) - 2) < 0.3, errors
        with pytest.raises(ValueError, match="pointwise rate maps"):
            mj.simulate(model.replace(du=jnp.full((8, 9), 0.2)), state, 2, 0.5,
                        domain=mj.Lattice(maps="pointwise"), solver=mj.IMEX(1))
        with pytest.raises(ValueError, match="ETDRK.*runs on the Lattice"):
            mj.simulate(model, state, 2, 0.5, domain=domain, solver=mj.ETDRK(1))


def test_a_state_set_rate_map_is_refused_before_the_run():
    """thesis-fig7.18's Modulated model sets U's rate from the state: a map, though the
    model's own rates are numbers. The transforms refuse it by name, before compiling."""
    import dataclasses

    experiment = mj.preset("thesis-fig7.18", quick=True)
    phases = tuple(dataclasses.replace(p, solver=mj.ETDRK(1)) for p in experiment.phases)
    with pytest.raises(ValueError, match="rate map of shape"):
        mj.run_experiment(dataclasses.replace(experiment, phases=phases), seed=0)


def test_a_phase_with_a_polarised_lattice_takes_a_solver_by_replace():
    """dataclasses.replace echoes a phase's stencil/boundary shorthands next to its domain;
    a polarised lattice agrees with them (its polarity has no shorthand)."""
    import dataclasses

    phase = mj.preset("thesis-fig5.13-v", quick=True).phases[0]
    changed = dataclasses.replace(phase, solver=mj.IMEX(1))
    assert changed.domain == phase.domain and changed.solver == mj.IMEX(1)
    with pytest.raises(ValueError, match="disagree"):
        mj.Phase(phase.model, 10, 1.0, domain=phase.domain, stencil="five-point")


def test_an_adaptive_run_short_of_its_time_says_so(turing_start):
    """max_steps attempts that do not reach steps * dt: not ok, with a message, and raised
    by simulate; the state's time says where it got to."""
    model = mj.Turing(4.0, 3.0)
    run = mj.run_status(model, turing_start, 10, 1.0, solver=mj.ETDRK(2, rtol=1e-3, max_steps=3))
    assert bool(run.incomplete) and not bool(run.status.ok) and float(run.state.time) < 10.0
    assert "stopped short of its time" in run.status.message()
    with pytest.raises(mj.SimulationError, match="stopped short of its time"):
        mj.simulate(model, turing_start, 10, 1.0, solver=mj.ETDRK(2, rtol=1e-3, max_steps=3))
    solver = mj.ETDRK(2, rtol=1e-3, atol=1e-5, max_steps=77)
    assert mj.solvers.solver_from_dict(solver.to_dict()) == solver


def test_until_on_a_phase_and_a_sweep(turing_start):
    """A phase and a sweep take a stopping rule: each member stops on its own step, with the
    fields of its run alone; a phase records the rule in its file form."""
    model, tol = mj.Turing(4.0, 3.0), 2e-3
    until = mj.SteadyState(tol)
    result = mj.sweep(model, {"dt": [0.05, 0.2]}, turing_start, steps=4000, dt=0.05, solver=mj.ETDRK(1),
                      until=until)
    for i, dt in enumerate((0.05, 0.2)):
        alone = mj.simulate(model, turing_start, 4000, dt, solver=mj.ETDRK(1), until=until)
        assert int(alone.step) < 4000
        np.testing.assert_allclose(np.asarray(result.fields[i]), np.asarray(alone.fields), rtol=1e-6, atol=1e-6)
    assert result.config["until"] == {"until": "steady-state", "tol": tol}
    phase = mj.Phase(model, steps=4000, dt=0.2, solver=mj.ETDRK(1), until=until)
    assert mj.Phase.from_dict(phase.to_dict()) == phase
    with pytest.raises(ValueError, match="Phase.until"):
        mj.Phase(model, steps=10, dt=0.01, until=1e-3)


def test_a_conjugate_gradient_solve_that_does_not_converge_is_reported(monkeypatch):
    """JAX's cg has no convergence flag: a solve that ends with half its digits lost returns
    NaN, so the run reports the step (here the first), and the message names the cause."""
    import morphojax.solvers._implicit as implicit

    model = mj.Reaction(lambda x, p: 0.0 * x, diffusion=[50.0], lower=-np.inf)
    state = mj.State.from_arrays([np.random.default_rng(3).normal(size=(10, 11))])  # a shape no other test traces
    converged = mj.run_status(model, state, 3, 2.0, domain=mj.HexLattice(), solver=mj.IMEX(1))
    assert bool(converged.status.ok)
    monkeypatch.setattr(implicit, "CG_MAXITER", 1)  # read when the step is traced
    state = mj.State.from_arrays([np.random.default_rng(3).normal(size=(10, 13))])
    run = mj.run_status(model, state, 3, 2.0, domain=mj.HexLattice(), solver=mj.IMEX(1))
    assert int(run.nonfinite_step) == 1
    assert "conjugate-gradient solve that did not converge" in run.status.message()

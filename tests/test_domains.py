"""Domains, execution plans, run status, general state shapes and safe result files."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
from morphojax import _serialise


def test_lattice_owns_the_stability_limit():
    for stencil, rho in (("nine-point", 16.0 / 3.0), ("five-point", 8.0)):
        lattice = mj.Lattice(stencil=stencil)
        assert lattice.spectral_radius == rho
        assert lattice.max_stable_dt(36.0) == pytest.approx(2.0 / (rho * 36.0))
        assert mj.max_stable_dt(36.0, stencil) == lattice.max_stable_dt(36.0)
        # traced rates (a fit's time step follows its parameters): the same formula in JAX
        traced = jax.jit(lattice.max_stable_dt)(jnp.asarray(36.0))
        assert float(traced) == pytest.approx(lattice.max_stable_dt(36.0), rel=1e-6)
    assert mj.Lattice().max_stable_dt(0.0) == float("inf")
    with pytest.raises(ValueError, match=r"largest stable dt is 0\.0104167"):
        mj.Lattice().check_dt(0.011, 36.0)
    with pytest.raises(ValueError, match="max_diffusion"):
        mj.max_stable_dt(-1.0)


def test_domain_and_shorthands(key):
    state = mj.paper_state(key, (12, 14))
    model = mj.Turing(8.0, 1.0)
    by_domain = mj.simulate(model, state, 30, 0.01, domain=mj.Lattice("five-point", "no-flux"))
    by_words = mj.simulate(model, state, 30, 0.01, "no-flux", stencil="five-point")
    np.testing.assert_array_equal(np.asarray(by_domain.fields), np.asarray(by_words.fields))
    with pytest.raises(ValueError, match="either domain= or the lattice shorthands"):
        mj.simulate(model, state, 3, 0.01, "wrap", domain=mj.Lattice())
    with pytest.raises(ValueError, match="either domain= or the lattice shorthands"):
        mj.rollout(model, state, 3, 0.01, 1, stencil="five-point", domain=mj.Lattice())
    with pytest.raises(ValueError, match="domain must be a morphojax domain"):
        mj.simulate(model, state, 3, 0.01, domain="wrap")
    with pytest.raises(ValueError, match="unknown boundary"):
        mj.Lattice(boundary="open")


def test_phase_domain_round_trip():
    phase = mj.Phase(mj.Turing(), 10, 0.01, domain=mj.Lattice("five-point", "no-flux"))
    assert (phase.stencil, phase.boundary) == ("five-point", "no-flux")
    again = mj.Phase.from_dict(phase.to_dict())
    assert again.domain == phase.domain
    assert dataclasses.replace(phase, steps=5).domain == phase.domain  # echoed shorthands agree
    with pytest.raises(ValueError, match="disagree"):
        mj.Phase(mj.Turing(), 10, 0.01, boundary="wrap", domain=mj.Lattice(boundary="no-flux"))
    # a phase saved before domains existed reads as the same lattice
    old = {k: v for k, v in phase.to_dict().items() if k != "domain"}
    assert mj.Phase.from_dict(old).domain == phase.domain
    with pytest.raises(ValueError, match="unknown domain type"):
        _serialise.domain_from_dict({"type": "Moebius", "params": {}})


@pytest.mark.parametrize("shape, capacity, steps", [((20, 22), (60, 62), 200), ((150, 152), (170, 172), 120)])
def test_plans_agree(key, shape, capacity, steps):
    """The block ladder (planned segments) and the whole-capacity reference give identical runs."""
    state = mj.State.from_arrays(mj.paper_state(key, shape).arrays(), capacity=capacity)
    model, dt = mj.Turing(4.0, 3.0, lower=(0.0, 2.0)), 0.01
    growth = mj.Growth(rate=1.0 / (6 * dt))
    run = dict(growth=growth, key=jax.random.key(3))
    ladder = mj.simulate(model, state, steps, dt, plan=mj.BlockLadder(), **run)
    whole = mj.simulate(model, state, steps, dt, plan=mj.WholeCapacity(), **run)
    np.testing.assert_array_equal(np.asarray(ladder.fields), np.asarray(whole.fields))
    assert ladder.size.tolist() == whole.size.tolist() == [shape[0] - (-steps // 6), shape[1] - (-steps // 6)]
    with pytest.raises(ValueError, match="plan must be"):
        mj.simulate(model, state, 6, dt, plan="ladder", **run)


def test_run_status(key):
    state = mj.paper_state(key, (10, 10))
    healthy = mj.run_status(mj.Turing(4.0, 3.0), state, 20, 0.01)
    assert isinstance(healthy, mj.Run) and healthy.status.ok is True and healthy.status.message() == "ok"
    final, bad, overflow = healthy  # unpacks as before
    assert int(bad) == -1 and not bool(overflow)
    blown = mj.run_status(mj.Turing(4.0, 3.0), state, 300, 0.2, check_dt=False)
    assert not bool(blown.status.ok)
    assert f"at step {int(blown.nonfinite_step)}" in blown.status.message()
    with pytest.raises(mj.SimulationError, match=f"at step {int(blown.nonfinite_step)}"):
        blown.status.check(blown.state, throw=True)
    batched = jax.vmap(lambda dt: mj.RunStatus(*mj.run_status(mj.Turing(4.0, 3.0), state, 300, dt,
                                                              check_dt=False)[1:]).ok)(jnp.array([0.01, 0.2]))
    assert batched.tolist() == [True, False]


def test_states_of_any_spatial_shape():
    state = mj.State.from_arrays([np.arange(5.0), np.ones(5)], capacity=(8,), names=("u", "v"))
    assert (state.ndim, state.shape, state.capacity, state.n_species) == (1, (5,), (8,), 2)
    assert state.active().tolist() == [True] * 5 + [False] * 3
    np.testing.assert_array_equal(state.array("u"), np.arange(5.0))
    grown = state.with_species("w", 2.0).select(["w", "u"])
    np.testing.assert_array_equal(np.asarray(grown.fields[0]), [2.0] * 5 + [0.0] * 3)
    assert grown.with_capacity((10,)).capacity == (10,)
    with pytest.raises(ValueError, match="1 sizes"):
        state.with_capacity((10, 10))
    with pytest.raises(ValueError, match="2 spatial axes"):
        mj.simulate(mj.Turing(), state.rename(("a", "b")), 3, 0.01, stencil="nine-point")
    with pytest.raises(ValueError, match="growth is not supported on the three-point stencil"):
        mj.simulate(mj.Turing(), state.rename(("a", "b")), 3, 0.01)  # 1D runs on a 1D lattice, which does not grow
    batched = jax.tree_util.tree_map(lambda x: jnp.stack([x, x]), state)
    assert batched.n_species == 2 and batched.capacity == (8,)
    with pytest.raises(ValueError, match="batched"):
        batched.arrays()


def test_result_files_are_replaced_whole(tmp_path, key, monkeypatch):
    state = mj.paper_state(key, (6, 6))
    path = mj.save_npz(tmp_path / "run.npz", state, {"note": "first"})
    assert mj.load_npz(path)[1]["note"] == "first"

    def crash(handle, **arrays):
        handle.write(b"half an archive")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez_compressed", crash)
    with pytest.raises(OSError, match="disk full"):
        mj.save_npz(path, state, {"note": "second"})
    monkeypatch.undo()
    assert mj.load_npz(path)[1]["note"] == "first"  # the last good file is intact
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]  # no temporary left behind
    assert mj.save_npz(tmp_path / "bare", state, {}).name == "bare.npz"  # NumPy's suffix rule


def test_models_name_their_parameters_one_way():
    r = mj.Reinforcement(threshold=4.0, width=2.0, diffusion=0.5)
    assert list(r.parameters()) == ["threshold", "width", "diffusion", "lower_a", "upper_a"]
    assert float(r.replace(diffusion=2.0).parameters()["diffusion"]) == 2.0
    both = mj.Composite((mj.Turing(), r))
    assert set(both.parameters()) >= {"0.ratio", "1.diffusion"}
    assert float(both.replace(**{"1.diffusion": 3.0}).parts[1].diffusion()[0]) == 3.0
    for cls in (mj.Turing, mj.Bard, mj.GrayScott, mj.Reinforcement):
        assert "parameters" not in vars(cls) and "replace" not in vars(cls)  # final: nothing overridden


def test_a_blow_up_is_counted_from_the_state_and_from_the_call(key):
    state = mj.simulate(mj.Turing(4.0, 3.0), mj.paper_state(key, (10, 10)), 500, 0.01)
    run = mj.run_status(mj.Turing(4.0, 3.0), state, 300, 0.2, check_dt=False)
    bad = int(run.nonfinite_step)
    # the call's own count: that many steps from the state it started from make it non-finite
    before = mj.simulate(mj.Turing(4.0, 3.0), state, bad - 500 - 1, 0.2, check_dt=False, throw=False)
    at = mj.simulate(mj.Turing(4.0, 3.0), state, bad - 500, 0.2, check_dt=False, throw=False)
    assert np.isfinite(np.asarray(before.fields)).all() and not np.isfinite(np.asarray(at.fields)).all()
    with pytest.raises(mj.SimulationError, match=rf"at step {bad} \(step {bad - 500} of this call\)"):
        mj.simulate(mj.Turing(4.0, 3.0), state, 300, 0.2, check_dt=False)

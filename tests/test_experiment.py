"""Multi-phase experiments: plain data, determinism, checkpoint and resume, presets."""

import json

import jax
import numpy as np
import pytest

import morphojax as mj
from morphojax._descriptors import describe
from morphojax._experiment import Experiment, Initial, Phase
from morphojax.presets import REACTION_DIFFUSION_PRESETS as PRESETS, preset


def _two_phase():
    """A small leopard-like experiment: production on a row, then growth with C = copy of B."""
    turing = mj.Turing(40.0, 5.0, lower=(0.0, 2.0))
    return Experiment(
        name="tiny-leopard",
        initial=Initial("constant", (16, 16), params=(4.0, 4.0), names=("a", "b")),
        phases=(
            Phase(turing, steps=600, dt=0.0015, boundary="no-flux", sources=(mj.Source("b", 0.01, "center-row"),),
                  name="definition"),
            Phase(mj.Composite((turing, mj.Reinforcement(5.0, 5.0, 1.0))), steps=500, dt=0.0015, boundary="no-flux",
                  growth=mj.Growth(rate=1.0 / (50 * 0.0015), row_weights=[1.0, 0.5, 1.0]),
                  add_species=(("c", "b"),), name="development", capacity=(26, 26)),
            Phase(mj.Composite((mj.Reinforcement(5.0, 5.0, 1.0),) * 2), steps=300, dt=0.0015, keep=("b", "c"),
                  boundary="no-flux", name="maintenance"),
        ),
        show="melanin",
    )


@pytest.fixture(scope="module")
def full_run():
    return mj.run_experiment(_two_phase(), seed=3)


def test_experiment_round_trips_through_json():
    for exp in [_two_phase()] + [preset(n, quick=True) for n in ("leopard", "squirrel", "giraffe", "frog")]:
        data = json.loads(json.dumps(exp.to_dict()))
        again = Experiment.from_dict(data)
        assert again.to_dict() == exp.to_dict()


def test_same_seed_same_result(full_run):
    again = mj.run_experiment(_two_phase(), seed=3)
    for x, y in zip(full_run.state.arrays(), again.state.arrays()):
        np.testing.assert_array_equal(x, y)
    other = mj.run_experiment(_two_phase(), seed=4)
    assert not np.array_equal(other.state.arrays()[0], full_run.state.arrays()[0])


def test_phases_chain_species_and_sizes(full_run):
    state = full_run.state
    assert state.names == ("b", "c")
    assert state.shape == (26, 26)  # 16 + ceil(500 / 50)
    assert int(state.step) == 1400


@pytest.mark.parametrize("stop", [300, 750, 1060, 1200])
def test_resume_from_checkpoint_equals_uninterrupted(tmp_path, full_run, stop):
    """Stop in the definition, development (1060: after its last expansion, the capacity
    full) or maintenance phase, save, load, resume."""
    path = tmp_path / "ckpt.npz"
    partial = mj.run_experiment(_two_phase(), seed=3, stop_after=stop)
    partial.save(path)
    resumed = mj.run_experiment(_two_phase(), resume=path)
    for x, y in zip(resumed.state.arrays(), full_run.state.arrays()):
        np.testing.assert_array_equal(x, y)


def test_a_run_started_from_a_key_resumes_with_it(tmp_path, full_run):
    path = tmp_path / "key.npz"
    mj.run_experiment(_two_phase(), key=jax.random.key(3), stop_after=750).save(path)
    _, meta = mj.load_npz(path)
    assert meta["run"]["seed"] is None and meta["run"]["key"] == [0, 3]
    resumed = mj.run_experiment(_two_phase(), resume=path)  # no key given: the recorded one
    for x, y in zip(resumed.state.arrays(), full_run.state.arrays()):  # key(3) is what seed=3 uses
        np.testing.assert_array_equal(x, y)


def test_periodic_checkpoints_resume(tmp_path, full_run):
    path = tmp_path / "run.npz"
    mj.run_experiment(_two_phase(), seed=3, checkpoint_path=path, checkpoint_every=250, stop_after=850)
    state, meta = mj.load_npz(path)
    assert meta["run"]["phase"] == 1 and meta["run"]["phase_step"] == 250 and int(state.step) == 850
    resumed = mj.run_experiment(_two_phase(), resume=path)
    for x, y in zip(resumed.state.arrays(), full_run.state.arrays()):
        np.testing.assert_array_equal(x, y)


def test_result_file_holds_cropped_arrays_and_parameters(tmp_path, full_run):
    path = full_run.save(tmp_path / "res.npz")
    with np.load(path) as data:
        assert data["species_b"].shape == (26, 26)
        meta = json.loads(str(data["metadata"]))
    assert meta["experiment"]["phases"][0]["model"]["params"]["ratio"] == pytest.approx(40.0)
    assert meta["run"]["seed"] == 3
    state, _ = mj.load_npz(path)
    np.testing.assert_array_equal(state.array("c"), full_run.state.array("c"))


def test_frames_follow_the_phases():
    exp = _two_phase()
    exp = Experiment(exp.name, exp.initial, tuple(
        Phase(**{**p.__dict__, "frames": 2}) for p in exp.phases), show=exp.show)
    res = mj.run_experiment(exp, seed=3, frames=True)
    labels = [lbl for lbl, _ in res.frames]
    assert len(labels) == 6 and labels[0].startswith("definition step 300")
    assert res.frames[3][1].shape == (26, 26)  # the development phase's last frame
    final = mj.run_experiment(_two_phase(), seed=3)
    np.testing.assert_array_equal(final.state.arrays()[0], res.state.arrays()[0])  # snapshots change nothing
    # evenly spaced snapshots come from one rollout per phase: each equals the run stopped
    # there, also in the growing phase (its lattice 21x21 after 250 of its steps)
    stopped = mj.run_experiment(_two_phase(), seed=3, stop_after=600 + 250)
    label, snapshot = res.frames[2]
    assert label == "development step 250" and snapshot.shape == stopped.state.shape
    for x, y in zip(snapshot.arrays(), stopped.state.arrays()):
        np.testing.assert_array_equal(x, y)


# ---- the paper's presets, reduced (--quick) ------------------------------------------------
QUICK = {
    # name: (final lattice size, expected pattern class of the shown species or None)
    "whipray": ((100, 100), None),
    "frog": ((80, 40), None),
    "squirrel": ((90, 90), None),
    "leopard": ((146, 146), None),
    "giraffe": ((48, 48), "inverted spots"),
    "fig4-r40-lb": ((32, 32), "spots"),
}


@pytest.mark.parametrize("name", list(QUICK))
def test_quick_presets(name):
    size, pattern = QUICK[name]
    result = mj.run_experiment(preset(name, quick=True), seed=0)
    assert result.state.shape == size
    exp = result.experiment
    shown = result.state.array("b" if exp.show == "melanin" else exp.show)
    d = describe(shown, wrap=exp.phases[-1].boundary == "wrap")
    assert d.finite and d.pattern != "uniform"
    if pattern is not None:
        assert d.pattern == pattern
    img = result.image()
    assert img.size == (size[1], size[0])


def test_leopard_leg_rosettes_open_with_longer_development():
    """Fig. 20: the longer the development phase, the more the spots of B open into
    rosettes (dark centres enclosed by a spot: holes besides the background); at the
    shortest the spots stay solid. The quick run scales the paper's 10,000 and 5,000."""
    holes, sizes = {}, {}
    for n in (10000, 5000):
        result = mj.run_experiment(preset(f"leopard-development-{n}", quick=True), seed=0)
        holes[n] = describe(result.state.array("b"), wrap=False).holes
        sizes[n] = result.state.shape
    assert sizes[10000][0] > sizes[5000][0]
    assert holes[5000] == 1 and holes[10000] >= 3


def test_every_preset_builds():
    for name, p in PRESETS.items():
        if p.members:
            assert all(m in PRESETS for m in p.members)
            continue
        for quick in (True, False):
            exp = p.experiment(quick)
            assert exp.phases and all(ph.steps > 0 for ph in exp.phases)
            state = exp.initial.build(jax.random.key(0))
            for ph in exp.phases:
                state = ph.prepare(state)
                assert ph.model.n_species == state.n_species, (name, ph.name)
                if isinstance(ph.growth, mj.MeshGrowth):  # the mesh it grows fits the vertex capacity
                    assert not ph.growth.geometry(ph.domain, state.capacity[0], ph.steps, ph.dt).overflow, name
                elif ph.growth is not None:
                    ph.growth.check_capacity(state, ph.steps, ph.dt)
                    n = ph.growth.expansions(ph.steps, ph.dt)
                    state = mj.State.from_arrays(
                        [np.zeros((state.shape[0] + n, state.shape[1] + n))] * state.n_species,
                        capacity=state.capacity, names=state.names)

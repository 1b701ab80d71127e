"""What a newcomer meets: where files go, what commands print, render of every file kind,
animations in one colour range, Ctrl-C, suggestions for unknown names, refused inputs."""

import json

import jax
import numpy as np
import pytest
from PIL import Image

import fitting
import morphojax as mj
from morphojax.cli import main


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """One quick preset run from a fresh folder with the default output path."""
    import os

    folder = tmp_path_factory.mktemp("fresh")
    here = os.getcwd()
    os.chdir(folder)
    try:
        code = main(["run", "fig4-r12-lb", "--quick", "--no-progress", "--gif", "movie.gif"])
    finally:
        os.chdir(here)
    return code, folder


def test_runs_write_under_out_and_say_so(quick_run, capsys):
    code, folder = quick_run
    assert code == 0
    assert sorted(p.name for p in (folder / "out").iterdir()) == ["fig4-r12-lb.npz", "fig4-r12-lb.png"]
    assert not list(folder.glob("*.png"))  # nothing in the working folder itself
    movie = Image.open(folder / "movie.gif")
    assert movie.n_frames > 4


def test_quiet_prints_only_json(tmp_path, capsys):
    assert main(["ca", "--size", "14", "--steps", "3", "--out", str(tmp_path / "c.png")]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["steps"] == 3 and "wrote" in err and "c.png" in err
    assert main(["ca", "--size", "14", "--steps", "3", "--out", str(tmp_path / "c.png"), "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["steps"] == 3 and err == ""
    # ca's bar (pieces of the run) is named "ca"; --no-progress leaves only the human line
    assert main(["ca", "--size", "14", "--steps", "3", "--out", str(tmp_path / "c.png"), "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["steps"] == 3 and err.strip().startswith("ca: 3 steps") and "\r" not in err


def test_render_draws_every_file_kind(quick_run, tmp_path, capsys):
    _, folder = quick_run
    assert main(["render", str(folder / "out" / "fig4-r12-lb.npz"), "--out", str(tmp_path / "r.png")]) == 0
    assert main(["ca", "--dim", "3", "--size", "14", "--steps", "2", "--out", str(tmp_path / "c3.png"), "--quiet"]) == 0
    assert main(["render", str(tmp_path / "c3.npz"), "--out", str(tmp_path / "c3r.png")]) == 0
    assert Image.open(tmp_path / "c3r.png").size == Image.open(tmp_path / "c3.png").size  # the same slices
    sweep = mj.sweep(mj.Turing(scale=3.0), vary={"ratio": [4.0, 8.0]}, state=mj.paper_state(jax.random.key(0), (12, 12)),
                     steps=20, dt=0.005, progress=False)
    sweep.save_npz(tmp_path / "s.npz")
    assert main(["render", str(tmp_path / "s.npz"), "--out", str(tmp_path / "s.png")]) == 0
    assert Image.open(tmp_path / "s.png").size == sweep.montage().size
    (tmp_path / "x.npz").write_bytes(b"not an archive")
    assert main(["render", str(tmp_path / "x.npz"), "--out", str(tmp_path / "x.png")]) == 2
    assert "is not a morphojax .npz file" in capsys.readouterr().err


def test_unknown_names_suggest_the_closest(capsys):
    assert main(["run", "girafe"]) == 2
    assert "did you mean giraffe?" in capsys.readouterr().err
    with pytest.raises(ValueError, match="did you mean leopard"):
        mj.preset("leopards")


def test_ctrl_c_keeps_the_checkpoint_and_says_how_to_resume(tmp_path, monkeypatch, capsys):
    real = mj.run_experiment

    def interrupted(exp, **kwargs):
        real(exp, **{**kwargs, "stop_after": kwargs["checkpoint_every"]})  # writes a checkpoint
        raise KeyboardInterrupt

    monkeypatch.setattr(mj, "run_experiment", interrupted)
    out = tmp_path / "sp.png"
    code = main(["run", "fig4-r12-lb", "--quick", "--checkpoint-every", "500", "--out", str(out), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 130 and "Traceback" not in err
    assert f"morphojax resume {out.with_suffix('.npz')}" in err
    assert int(mj.load_npz(out.with_suffix(".npz"))[0].step) == 500


def test_animation_has_one_colour_range(tmp_path):
    frames = [np.full((4, 6), v) for v in (0.0, 0.5, 1.0)]
    path = mj.save_animation(tmp_path / "a.gif", frames, cmap="gray")
    movie = Image.open(path)
    greys = []
    for i in range(movie.n_frames):
        movie.seek(i)
        greys.append(movie.convert("RGB").getpixel((0, 0))[0])
    assert greys[0] <= 2 and abs(greys[1] - 128) <= 2 and greys[2] >= 253  # not each frame stretched alone
    with pytest.raises(ValueError, match="must end in one of"):
        mj.save_animation(tmp_path / "a.avi", frames)
    with pytest.raises(ValueError, match="2D array"):
        mj.save_animation(tmp_path / "b.gif", [np.zeros((2, 2, 2))])
    state = mj.paper_state(jax.random.key(0), (10, 10))
    _, rolled = mj.rollout(mj.Turing(), state, steps=20, dt=0.01, every=5)
    assert Image.open(mj.save_animation(tmp_path / "r.gif", rolled, species="b")).n_frames == 4


def test_gradient_from_a_photo_and_render_with_it(quick_run, tmp_path):
    """A photo's main colours as a Gradient (shared with fitting's palette): cream fur with
    brown spots gives cream at the low end and brown at the high end (pigment="dark"), the
    reverse with pigment="light"; `render --palette-from` draws a result in them."""
    rng = np.random.default_rng(0)
    mask = rng.uniform(size=(40, 50)) < 0.3
    brown, cream = np.array([120, 70, 20]), np.array([240, 225, 190])
    rgb = np.where(mask[..., None], brown, cream).astype(np.uint8)
    photo = tmp_path / "coat.png"
    Image.fromarray(rgb).save(photo)
    g = mj.Gradient.from_photo(photo, k=2)
    assert [p for p, _ in g.stops] == [0.0, 1.0]
    np.testing.assert_allclose(g.stops[0][1], cream, atol=3)
    np.testing.assert_allclose(g.stops[1][1], brown, atol=3)
    light = mj.Gradient.from_photo(rgb / 255.0, k=2, pigment="light")  # an RGB array works too
    np.testing.assert_allclose(light.stops[0][1], brown, atol=3)
    assert mj.photo_palette is fitting.photo_palette
    with pytest.raises(ValueError, match="pigment"):
        mj.Gradient.from_photo(photo, pigment="spots")
    with pytest.raises(ValueError, match="crop"):
        mj.Gradient.from_photo(photo, crop=(0, 0, 99, 10))
    _, folder = quick_run
    out = tmp_path / "coloured.png"
    assert main(["render", str(folder / "out" / "fig4-r12-lb.npz"), "--palette-from", str(photo),
                 "--out", str(out)]) == 0
    colours = np.asarray(Image.open(out).convert("RGB")).reshape(-1, 3)
    assert np.abs(colours - cream).sum(1).min() < 12 and np.abs(colours - brown).sum(1).min() < 12


def test_complex_concentrations_are_refused():
    with pytest.raises(ValueError, match="species 0 is complex"):
        mj.State.from_arrays([np.ones((3, 3)) * (1 + 2j)])


def test_progress_bars_are_named_by_phase(capsys):
    state = mj.paper_state(jax.random.key(0), (10, 10))
    mj.simulate(mj.Turing(), state, steps=20, dt=0.01, progress="definition")
    assert "definition" in capsys.readouterr().err


@pytest.mark.parametrize("crash_at", [1, 3, 5])
def test_a_crash_while_writing_a_checkpoint_keeps_the_last_one(tmp_path, monkeypatch, crash_at):
    """Killed during its k-th checkpoint write, a run leaves checkpoint k - 1 intact, and
    resuming it gives the uninterrupted run's arrays to the bit (also across growth)."""
    exp = mj.Experiment("crash", mj.Initial("paper", (16, 16), capacity=(20, 20)), phases=(
        mj.Phase(mj.Turing(4.0, 1.0), steps=200, dt=0.01, name="still"),
        mj.Phase(mj.Turing(4.0, 1.0), steps=400, dt=0.01, growth=mj.Growth(rate=1.0), name="growing")))
    whole = mj.run_experiment(exp, seed=3)
    path, real, writes = tmp_path / "ck.npz", np.savez_compressed, []

    def killed_on_a_write(handle, **arrays):
        writes.append(1)
        if len(writes) == crash_at:
            handle.write(b"half an archive")
            raise OSError("killed while writing")
        return real(handle, **arrays)

    monkeypatch.setattr(np, "savez_compressed", killed_on_a_write)
    with pytest.raises(OSError, match="killed"):
        mj.run_experiment(exp, seed=3, checkpoint_path=path, checkpoint_every=100)
    monkeypatch.undo()
    assert [p.name for p in tmp_path.iterdir()] == ([] if crash_at == 1 else ["ck.npz"])  # no temporary left
    if crash_at == 1:
        assert not path.exists()  # nothing was ever complete: nothing half-written either
        return
    state, _ = mj.load_npz(path)
    assert int(state.step) == 100 * (crash_at - 1)
    resumed = mj.run_experiment(exp, resume=path)
    np.testing.assert_array_equal(np.asarray(resumed.state.fields), np.asarray(whole.state.fields))
    assert resumed.state.shape == whole.state.shape == (20, 20)


def test_sweep_montage_agrees_with_its_table():
    """One colour range for every tile (a uniform member keeps its level, not stretched to
    black), the table's "uniform" marked on the tile, values to 3 significant digits."""
    res = mj.sweep(mj.Turing(scale=3.0), vary={"ratio": [1.0, 12.3456]}, state=mj.paper_state(jax.random.key(0), (16, 16)),
                   steps=1500, dt=0.008, progress=False)
    assert [row["pattern"] for row in res.table][0] == "uniform"
    b = res.arrays()[:, 1]
    level = float(b[0].mean())
    expected = mj.to_image(np.full((1, 1), level), vmin=float(b.min()), vmax=float(b.max())).getpixel((0, 0))
    def near(img):  # pixels within a few levels of the uniform member's colour
        return (np.abs(np.asarray(img, int) - np.asarray(expected)) <= 6).all(axis=-1).sum()

    shared = np.asarray(res.montage(scale=4))
    assert near(shared) > 64 * 64 // 2  # the uniform tile at its level
    assert near(res.montage(scale=4, per_tile=True)) < 64 * 64 // 2  # stretched on its own
    assert (shared == 255).all(axis=-1).any()  # the white box of the "uniform" mark


def test_explorer_builds_and_reruns_on_a_slider_move():
    pytest.importorskip("ipywidgets")
    state = mj.paper_state(jax.random.key(0), (16, 16))
    ex = mj.explore(mj.Turing(8.0, 1.0), state, 200, 0.01, names=["ratio", "scale"])
    assert set(ex.sliders) == {"ratio", "scale"} and ex.sliders["ratio"].min == 2.0 and ex.sliders["ratio"].max == 32.0
    first = ex.image.value
    assert first[:4] == b"\x89PNG"
    ex.sliders["ratio"].value = 20.0  # what a user's drag does
    assert ex.values["ratio"] == 20.0 and ex.image.value != first and "steps in" in ex.status.value
    moved = ex.image.value
    ex.sliders["scale"].value = 4.0  # 20 x 4 = 80: dt 0.01 is beyond the limit 0.0047
    assert "largest stable dt is" in ex.status.value and ex.image.value == moved
    with pytest.raises(ValueError, match="not finite scalar parameters"):
        mj.explore(mj.Turing(), state, 10, 0.01, names=["colour"])


def test_sweep_map_opens_the_member_clicked():
    """The clickable parameter map: one button per member in the montage's layout, coloured
    by a table column; a click shows that member's pattern and table row (headless)."""
    pytest.importorskip("ipywidgets")
    res = mj.sweep(mj.Turing(scale=3.0), vary={"ratio": [1.0, 12.0, 20.0], "scale": [2.0, 3.0]},
                   state=mj.paper_state(jax.random.key(0), (16, 16)), steps=800, dt=0.006, progress=False)
    explorer = mj.explore_sweep(res, colour_by="wavelength", scale=2)
    assert len(explorer.buttons) == 6 and explorer.selected is None
    assert "repeat(2, 30px)" in explorer.widget.children[0].children[1].layout.grid_template_columns
    colours = {b.style.button_color for b in explorer.buttons}
    assert len(colours) > 1 and all(c.startswith("#") for c in colours)
    explorer.buttons[3].click()  # ratio 12, scale 3
    assert explorer.selected == 3 and "ratio = 12" in explorer.details.value
    import io as _io
    shown = np.asarray(Image.open(_io.BytesIO(explorer.image.value)).convert("RGB"))
    expected = np.asarray(mj.to_image(res.arrays()[1, 1, 1], scale=2))
    np.testing.assert_array_equal(shown, expected)
    by_pattern = mj.explore_sweep(res, colour_by="pattern")
    assert len(by_pattern.buttons) == 6
    with pytest.raises(ValueError, match="no column"):
        mj.explore_sweep(res, colour_by="colourfulness")

"""The command line: presets, run, resume, render; determinism; clear errors."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

import morphojax as mj
from morphojax.cli import main


def _arrays(path):
    with np.load(path) as data:
        return {k: data[k] for k in data.files if k.startswith("species_")}, json.loads(str(data["metadata"]))


def test_presets_lists_the_papers_experiments(capsys):
    assert main(["presets"]) == 0
    out = capsys.readouterr().out
    for name in ("leopard", "whipray", "frog", "squirrel", "giraffe", "nudibranch", "fig4-r40-lb", "development"):
        assert name in out
    # one table of every kind, fitting a 100-column terminal
    for name in ("young-fig8", "dur-fig9", "life-glider"):
        assert name in out
    table, closing = out.splitlines()[:-1], out.splitlines()[-1]
    assert max(len(line) for line in table) <= 100 and json.loads(closing)["presets"] == len(mj.PRESETS)
    kinds = {p.kind for p in mj.PRESETS.values()}
    assert kinds >= {"reaction-diffusion", "automaton", "potts"}
    for kind in kinds:  # each kind has its section
        assert f"{kind} presets" in out
    assert all(p.figure and p.description and p.build or getattr(p, "members", ()) for p in mj.PRESETS.values())


def test_run_dispatches_on_the_preset_kind(tmp_path, capsys):
    """An automaton preset runs through `morphojax run` like an experiment; it is no experiment."""
    assert main(["run", "life-glider", "--quick", "--out", str(tmp_path / "g")]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["image"] == str(tmp_path / "g.png") and summary["glider_moved_diagonally"]
    assert (tmp_path / "g.png").exists() and (tmp_path / "g.npz").exists()
    with pytest.raises(ValueError, match="'life-glider' is an automaton run"):
        mj.preset("life-glider")


def test_core_does_not_import_fitting():
    """`fit` reaches the command line through the entry-point group, never through the core."""
    code = ("import sys, morphojax, morphojax.cli; assert 'fitting' not in sys.modules; "
            "from importlib.metadata import entry_points; "
            "print(sorted(e.value for e in entry_points(group='morphojax.commands')))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert "fitting._cli:register" in res.stdout


def test_run_writes_png_and_npz_and_is_deterministic(tmp_path, capsys):
    out1, out2 = tmp_path / "a.png", tmp_path / "b.png"
    assert main(["run", "fig4-r12-lb", "--quick", "--seed", "7", "--out", str(out1), "--no-progress"]) == 0
    assert main(["run", "fig4-r12-lb", "--quick", "--seed", "7", "--out", str(out2), "--no-progress"]) == 0
    img = Image.open(out1)
    assert img.size == (64, 64)  # 32x32 lattice at 2 pixels per cell
    a1, meta = _arrays(out1.with_suffix(".npz"))
    a2, _ = _arrays(out2.with_suffix(".npz"))
    assert set(a1) == {"species_a", "species_b"} and a1["species_b"].shape == (32, 32)
    for k in a1:
        np.testing.assert_array_equal(a1[k], a2[k])
    assert meta["run"]["seed"] == 7
    assert meta["experiment"]["phases"][0]["model"]["params"]["lower"] == [0.0, 3.0]
    # the same run through the Python API gives the same arrays
    api = mj.run_experiment(mj.Experiment.from_dict(meta["experiment"]), seed=7)
    np.testing.assert_array_equal(api.state.array("b"), a1["species_b"])


def test_a_figure_of_several_runs_reports_each_runs_pattern(tmp_path, capsys):
    """`frog-interpolation` (leopard paper Fig. 22): one montage, one file per member, and
    per member the pattern, spots and holes of its final shown species, as read back from
    that member's file."""
    out = tmp_path / "fig22.png"
    assert main(["run", "frog-interpolation", "--quick", "--no-progress", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert out.exists() and summary["members"] == ["frog", "frog-nearest", "frog-bilinear", "frog-bicubic"]
    finals = {}
    for d in summary["descriptors"]:
        arrays, meta = _arrays(tmp_path / f"fig22_{d['member']}.npz")
        finals[d["member"]] = arrays["species_a"]
        again = mj.describe(arrays["species_a"], wrap=False)
        assert d["size"] == [80, 40] and (d["spots"], d["holes"], d["pattern"]) == (again.spots, again.holes, again.pattern)
        method = d["member"].partition("-")[2] or "division"
        assert meta["experiment"]["phases"][1]["growth"]["method"] == method
    assert not np.allclose(finals["frog"], finals["frog-nearest"])


def test_frames_and_resume(tmp_path):
    out = tmp_path / "sp.png"
    assert main(["run", "fig4-r12-lb", "--quick", "--frames", "--checkpoint-every", "1000", "--out", str(out),
                 "--no-progress"]) == 0
    frames = sorted((tmp_path / "sp_frames").glob("*.png"))
    assert len(frames) >= 4 and (tmp_path / "sp_frames" / "frames.png").exists()
    final, _ = _arrays(out.with_suffix(".npz"))
    # resume a checkpoint taken mid-run: same final arrays (growing runs: see test_experiment)
    state, meta = mj.load_npz(out.with_suffix(".npz"))
    partial = mj.run_experiment(mj.Experiment.from_dict(meta["experiment"]), seed=0, stop_after=1000)
    ckpt = tmp_path / "partial.npz"
    partial.save(ckpt)
    assert main(["resume", str(ckpt), "--out", str(tmp_path / "resumed.png"), "--no-progress"]) == 0
    resumed, _ = _arrays(tmp_path / "resumed.npz")
    for k in final:
        np.testing.assert_array_equal(final[k], resumed[k])


def test_render(tmp_path):
    out = tmp_path / "g.png"
    main(["run", "nudibranch", "--quick", "--out", str(out), "--no-progress"])
    assert main(["render", str(out.with_suffix(".npz")), "--species", "a", "--cmap", "viridis",
                 "--out", str(tmp_path / "r.png")]) == 0
    assert Image.open(tmp_path / "r.png").size == (96, 96)


def test_every_option_of_every_command_has_a_help_text():
    """`morphojax COMMAND --help` says what each option does: none is listed bare."""
    import argparse

    from morphojax.cli import build_parser

    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    bare = [f"{name} {' / '.join(action.option_strings) or action.dest}"
            for name, command in [("morphojax", parser), *commands.items()]
            for action in command._actions
            if not isinstance(action, (argparse._HelpAction, argparse._SubParsersAction))
            and not (action.help and action.help.strip())]
    assert len(commands) > 5 and "fit" in commands
    assert not bare, f"options without a help text: {bare}"


def test_bad_input_is_a_clear_error(tmp_path, capsys):
    assert main(["run", "tiger"]) == 2  # a clear message and the usage-error status, no traceback
    assert "unknown preset 'tiger'" in capsys.readouterr().err
    assert main(["render", str(tmp_path / "missing.npz"), "--out", str(tmp_path / "x.png")]) == 2
    assert "no such result file" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("morphojax") is None, reason="console script not installed")
def test_console_script_is_installed():
    res = subprocess.run(["morphojax", "presets"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and "leopard" in res.stdout


def test_every_command_ends_with_a_json_line(tmp_path, capsys):
    """presets and render close with a JSON line, as the other commands do; render draws a
    3D lattice's fields as slices; mesh and listing take --no-progress and the one --quiet."""
    from morphojax._files import write_npz

    assert main(["presets"]) == 0
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert line["presets"] == len(mj.PRESETS) and sum(line["kinds"].values()) == len(mj.PRESETS)
    volume = np.random.default_rng(0).random((6, 7, 8))
    write_npz(tmp_path / "solid.npz", u=volume, v=volume, metadata=json.dumps({"kind": "solid"}))
    assert main(["render", str(tmp_path / "solid.npz"), "--out", str(tmp_path / "solid.png")]) == 0
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert line["image"] == str(tmp_path / "solid.png") and (tmp_path / "solid.png").stat().st_size > 0
    for command in ("mesh", "listing"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = capsys.readouterr().out
        assert "--no-progress" in text and "print only the JSON line" in text


def test_run_a_preset_on_a_larger_lattice(tmp_path, capsys):
    """--shape sets the lattice (--scale only the picture); a growing preset is refused by name."""
    assert main(["run", "fig4-r12", "--quick", "--shape", "20", "22", "--scale", "1", "--no-progress",
                 "--out", str(tmp_path / "a.png"), "--quiet"]) == 0
    state, meta = mj.load_npz(tmp_path / "a.npz")
    assert state.shape == (20, 22) and Image.open(tmp_path / "a.png").size[:2] != (0, 0)
    assert mj.load_experiment(meta).initial.shape == (20, 22)
    capsys.readouterr()
    assert main(["run", "leopard", "--shape", "60", "70", "--out", str(tmp_path / "b.png")]) == 2
    assert "runs on its own lattice only: it grows" in capsys.readouterr().err


def test_fit_names_every_model_it_takes(tmp_path, capsys):
    Image.fromarray((np.random.default_rng(0).random((48, 48)) * 255).astype("uint8")).save(tmp_path / "x.png")
    assert main(["fit", str(tmp_path / "x.png"), "--model", "nonsense", "--json", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err
    for name in ("anisotropic-turing", "young", "leopard", "'auto'", "brusselator"):
        assert name in err


def test_render_draws_a_mesh_result(tmp_path):
    """The .npz that `morphojax mesh` writes renders as its mesh, seen as mesh draws it."""
    assert main(["mesh", "sphere", "--steps", "20", "--no-progress", "--quiet", "--out", str(tmp_path / "m.ply")]) == 0
    assert main(["render", str(tmp_path / "m.npz"), "--out", str(tmp_path / "r.png"), "--quiet"]) == 0
    assert Image.open(tmp_path / "r.png").size == Image.open(tmp_path / "m.png").size

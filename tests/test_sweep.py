"""Parameter sweeps: grid order, equality with single runs, chunking without recompiles,
blow-ups, files, sharding over 4 forced host devices, spatial maps and the CLI.

The oracle for every batched member is `simulate` run alone with the same inputs (the
same model, initial state and key). Member by member (`vmap_size=1`) and vmapped, the
results are bit for bit identical; in lanes (the CPU default for built-in models, see
`morphojax/_lanes.py` and tests/test_lanes.py) they agree to float rounding, and bit for bit
with each other whatever the chunking."""

import argparse
import csv
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import equinox as eqx
import jax
import numpy as np
import pytest

import morphojax as mj
from morphojax import _batch
from morphojax._descriptors import describe, relative_change
from morphojax._parameter_map import parameter_map
from morphojax._render import map_image
from morphojax._sweep import sweep
from morphojax._sweep_result import load_sweep
from morphojax.cli._sweep import build_sweep, parse_values, register

ROOT = Path(__file__).resolve().parents[1]
SHAPE = (16, 16)
STEPS, DT = 60, 0.004
RATIOS = [4.2, 8.0, 12.0]
UPPER_A = [6.2, 3.5]  # A falls below 4 early on, so only a low U_a bites in 60 steps


def close(batched, lone):
    """Members in lanes against a lone run: equal to float rounding (1e-6 of the field's scale)."""
    np.testing.assert_allclose(batched, lone, rtol=0, atol=1e-6 * max(1.0, float(np.abs(lone).max())))


def alone(model, state, steps=STEPS, dt=DT, **kw):
    final, bad, _ = mj.run_status(model, state, steps, dt, **kw)
    return np.stack([np.asarray(final.fields)[:, : int(final.size[0]), : int(final.size[1])]][0]), int(bad)


@pytest.fixture(scope="module")
def start():
    return mj.paper_state(jax.random.key(7), SHAPE)


@pytest.fixture(scope="module")
def grid(start):
    return sweep(mj.Turing(scale=3.0), {"ratio": RATIOS, "upper_a": UPPER_A}, state=start, steps=STEPS, dt=DT)


@pytest.fixture(scope="module")
def exact(start):
    """The grid member by member: bit for bit a lone run's numbers."""
    return sweep(mj.Turing(scale=3.0), {"ratio": RATIOS, "upper_a": UPPER_A}, state=start, steps=STEPS, dt=DT,
                 vmap_size=1)


# ---- grid layout and equality with single runs ------------------------------------------------
def test_grid_shape_order_and_equality_with_single_runs(grid, exact, start):
    assert grid.config["lanes"] and not exact.config["lanes"]
    arrays = grid.arrays()
    assert isinstance(arrays, np.ndarray)
    assert arrays.shape == (3, 2, 2) + SHAPE
    assert grid.shape == (3, 2) and len(grid.table) == 6
    np.testing.assert_array_equal(grid.column("ratio"), np.repeat(RATIOS, 2).reshape(3, 2))
    np.testing.assert_array_equal(grid.column("upper_a"), np.tile(UPPER_A, 3).reshape(3, 2))
    for i, r in enumerate(RATIOS):
        for j, ua in enumerate(UPPER_A):
            want, bad = alone(mj.Turing(r, 3.0, upper=(ua, np.inf)), start)
            close(arrays[i, j], want)
            np.testing.assert_array_equal(exact.arrays()[i, j], want)
            row = grid.table[i * 2 + j]
            assert (row["i_ratio"], row["i_upper_a"]) == (i, j)
            assert row["ratio"] == pytest.approx(r) and row["upper_a"] == pytest.approx(ua)
            assert row["blowup_step"] == bad == -1
    # the members really differ (the grid is not one run repeated)
    assert not np.array_equal(arrays[0, 0], arrays[2, 0])
    assert not np.array_equal(arrays[2, 0], arrays[2, 1])


def test_member_gives_back_everything_to_reproduce_a_run(grid):
    m = grid.member((1, 1))
    assert m.values == {"ratio": 8.0, "upper_a": 3.5}
    again = mj.simulate(**m.kwargs())
    close(grid.arrays()[1, 1], np.stack(again.arrays()))
    assert int(grid.state((1, 1)).step) == STEPS


def test_per_member_keys_with_growth_rate_varying(tmp_path):
    """Each member its own start and growth noise, the growth rate swept; equal to lone runs."""
    model = mj.Turing(8.0, 3.0, lower=(0.0, 2.0))
    rates = [0.0, 2.0, 4.0]
    res = sweep(model, {"growth_rate": rates}, shape=(12, 12), capacity=(16, 16), key=5, steps=40, dt=0.01,
                growth=mj.Growth(rate=1.0))
    assert res.arrays().shape == (3, 2, 14, 14)  # cropped to the largest lattice: 2 expansions at rate 4
    sizes = [tuple(s) for s in res.size]
    assert sizes[0] == (12, 12) and sizes[0] < sizes[1] < sizes[2]
    root = jax.random.key(5)
    for i, rate in enumerate(rates):
        k = jax.random.fold_in(root, i)
        state = mj.initial_state(model, jax.random.fold_in(k, 0), (12, 12), capacity=(16, 16))
        final = mj.simulate(model, state, 40, 0.01, growth=mj.Growth(rate=rate), key=jax.random.fold_in(k, 1))
        np.testing.assert_array_equal(res.fields[i], np.asarray(final.fields))
        np.testing.assert_array_equal(res.size[i], np.asarray(final.size))
    # different members, different starts
    assert not np.array_equal(res.fields[0], mj.simulate(model, mj.initial_state(
        model, jax.random.fold_in(jax.random.fold_in(root, 1), 0), (12, 12), capacity=(16, 16)), 40, 0.01).fields)


def test_explicit_list_and_batched_initial_states(start):
    base = mj.Turing(scale=3.0)
    sets = [{"ratio": 4.2, "upper_a": 6.2}, {"ratio": 12.0}, {"ratio": 20.0, "lower_b": 3.0}]
    starts = [mj.paper_state(jax.random.key(i), SHAPE) for i in range(3)]
    states = jax.tree_util.tree_map(lambda *x: np.stack(x), *starts)  # one State with a member axis
    res = sweep(base, sets, state=states, steps=STEPS, dt=0.003)
    assert res.arrays().shape == (3, 2) + SHAPE and res.axes is None
    models = [mj.Turing(4.2, 3.0, upper=(6.2, np.inf)), mj.Turing(12.0, 3.0), mj.Turing(20.0, 3.0, lower=(0.0, 3.0))]
    for i, m in enumerate(models):
        want, _ = alone(m, mj.paper_state(jax.random.key(i), SHAPE), dt=0.003)
        close(res.arrays()[i], want)
    # names a set leaves out keep the base value
    assert res.values["upper_a"][1] == np.inf and res.values["lower_b"][0] == 0.0
    img = res.montage()
    assert img.width >= 2 * SHAPE[1] and img.height >= 2 * SHAPE[0]


# ---- chunks and compilation -----------------------------------------------------------------------
@pytest.mark.parametrize("vmap_size", [1, None])
def test_chunks_with_a_padded_last_chunk_match_and_compile_once(exact, start, monkeypatch, vmap_size):
    """Member by member, 6 members in chunks of 4 (the last holds 2 members and 2 copies of the
    last one); in lanes, 11 members in chunks of 8 (groups of 8: the last padded with 5)."""
    lanes = vmap_size is None
    ratios = [4.2, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0] if lanes else RATIOS
    vary = {"ratio": ratios} if lanes else {"ratio": RATIOS, "upper_a": UPPER_A}
    kw = dict(state=start, steps=STEPS, dt=DT, vmap_size=vmap_size, describe_members=False)
    if lanes:  # a member's bits do not depend on the chunking: one chunk of 16 gives the same
        want = sweep(mj.Turing(scale=3.0), vary, batch_size=16, **kw).arrays()
        for i in (0, 10):
            close(want[i], alone(mj.Turing(ratios[i], 3.0), start)[0])
    else:
        want = exact.arrays()
    traced = eqx.filter_jit(eqx.debug.assert_max_traces(_batch._batch_program, max_traces=1))
    monkeypatch.setattr(_batch, "_run_batch", traced)
    before = _batch._TRACES["batch"]
    size = 8 if lanes else 4
    chunked = sweep(mj.Turing(scale=3.0), vary, batch_size=size, **kw)
    assert chunked.config["batch_size"] == size and chunked.config["lanes"] == lanes
    np.testing.assert_array_equal(chunked.arrays(), want)
    # new values of the same shapes reuse the program: parameters are traced, not baked in
    other = sweep(mj.Turing(scale=2.5), {k: list(np.asarray(v) * 0.9) for k, v in vary.items()}, batch_size=size,
                  **kw)
    assert other.arrays().shape == chunked.arrays().shape
    assert _batch._TRACES["batch"] == before + 1  # one trace for every chunk of both sweeps


@pytest.mark.parametrize("vmap_size", [2, 3])
def test_vmap_width_does_not_change_results(exact, start, vmap_size):
    """Whole-chunk vmap (3 = the chunk) and lax.map over vmapped pairs give the same bits."""
    res = sweep(mj.Turing(scale=3.0), {"ratio": RATIOS, "upper_a": UPPER_A}, state=start, steps=STEPS, dt=DT,
                batch_size=3, vmap_size=vmap_size)
    assert res.config["vmap_size"] == vmap_size and not res.config["lanes"]
    np.testing.assert_array_equal(res.arrays(), exact.arrays())


def test_default_chunk_is_bounded_and_a_multiple_of_the_devices():
    cpu = jax.devices("cpu")[:1]
    assert _batch._chunk_size(None, 10_000, 2 * 128 * 128, cpu) == 16
    # small sweeps are split so every core gets a chunk (one dispatching thread per core)
    workers = min(os.cpu_count() or 1, _batch._MAX_WORKERS, 5)
    assert _batch._chunk_size(None, 5, 2 * 16 * 16, cpu) == -(-5 // workers)
    # one CPU device: groups of `lanes` members in lanes, else one member at a time; several
    # devices: the whole chunk vmapped; an explicit vmap_size is kept
    assert _batch._layout(None, cpu, 4, 8) == (8, True) and _batch._layout(None, cpu, 8, 0) == (1, False)
    assert _batch._layout(None, cpu * 2, 8, 8) == (8, False) and _batch._layout(3, cpu, 8, 8) == (3, False)
    assert _batch._chunk_size(3, 10, 100, cpu * 4) == 4  # rounded up to the 4 devices
    with pytest.raises(ValueError, match="batch_size"):
        _batch._chunk_size(0, 10, 100, cpu)
    # multi-host: contiguous equal blocks covering every member once
    blocks = [_batch._host_block(10, i, 3) for i in range(3)]
    assert [b[:2] for b in blocks] == [(0, 4), (4, 8), (8, 10)] and {b[2] for b in blocks} == {4}


# ---- blow-ups, descriptors, settled ------------------------------------------------------------------
def test_a_blowup_member_is_recorded_and_the_others_are_fine(start):
    res = sweep(mj.Turing(4.2, 3.0), {"dt": [0.004, 0.3, 0.01]}, state=start, steps=STEPS, dt=DT, check_dt=False)
    rows = res.table
    assert [r["pattern"] for r in rows][1] == "unstable"
    assert rows[1]["blowup_step"] >= 0 and rows[1]["settled"] is False
    _, bad = alone(mj.Turing(4.2, 3.0), start, dt=0.3, check_dt=False)
    assert rows[1]["blowup_step"] == bad
    for i in (0, 2):
        assert rows[i]["blowup_step"] == -1 and rows[i]["finite"] and rows[i]["pattern"] != "unstable"
        assert np.isfinite(res.arrays()[i]).all()
    img = np.asarray(res.montage(scale=1))
    assert (img == 128).all(axis=-1).any()  # the grey NaN tile


def test_descriptors_and_settled_in_the_table(start):
    # member 0 starts at the steady state A = B = 4 and stays there; member 1 is a fresh random start
    calm_start = mj.constant_state(SHAPE, 4.0, 4.0)
    states = jax.tree_util.tree_map(lambda *x: np.stack(x), calm_start, start)
    res = sweep(mj.Turing(scale=3.0), [{"ratio": 8.0}, {"ratio": 8.0}], state=states, steps=STEPS, dt=DT,
                settle_steps=20)
    calm, busy = res.table
    assert calm["pattern"] == "uniform" and calm["settled"] is True and calm["change"] == 0.0
    assert busy["settled"] is False and busy["change"] > 0.05
    # the change is that of the last 20 steps, measured as `relative_change` does on the host
    mid = mj.simulate(mj.Turing(8.0, 3.0), start, STEPS - 20, DT)
    end = mj.simulate(mj.Turing(8.0, 3.0), mid, 20, DT)
    assert busy["change"] == pytest.approx(float(relative_change(mid.fields, end.fields)), rel=1e-4)
    d = describe(res.arrays()[1, 1])
    assert (busy["wavelength"], busy["pattern"], busy["spots"]) == (d.wavelength, d.pattern, d.spots)


def test_table_and_states_are_written_and_readable(grid, tmp_path):
    written = grid.save(tmp_path / "map.png")
    assert {p.suffix for p in written.values()} == {".png", ".csv", ".json", ".npz"}
    assert all(p.exists() for p in written.values())
    with written["csv"].open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 6 and {"ratio", "upper_a", "pattern", "wavelength", "settled", "blowup_step"} <= set(rows[0])
    assert float(rows[3]["ratio"]) == pytest.approx(8.0) and rows[3]["pattern"] == grid.table[3]["pattern"]

    def no_constants(name):
        raise AssertionError(f"non-standard JSON constant {name}")

    meta = json.loads(written["json"].read_text(), parse_constant=no_constants)  # strict JSON
    assert meta["config"]["model"]["type"] == "Turing" and meta["axes"]["ratio"] == RATIOS
    assert meta["config"]["steps"] == STEPS and len(meta["table"]) == 6
    with np.load(written["npz"]) as data:
        assert data["species_b"].shape == (3, 2) + SHAPE
        np.testing.assert_array_equal(data["species_b"], grid.arrays()[:, :, 1])
        assert json.loads(str(data["metadata"]))["config"]["dt"] == DT
    back = load_sweep(written["npz"])
    np.testing.assert_array_equal(back.arrays(), grid.arrays())
    assert back.names == ("ratio", "upper_a") and back.table == json.loads(json.dumps(back.table))
    assert float(back.model.scale) == 3.0
    from PIL import Image

    with Image.open(written["png"]) as img:
        assert img.width > 2 * SHAPE[1] and img.height > 3 * SHAPE[0]


# ---- bad input ------------------------------------------------------------------------------------
@pytest.mark.parametrize("vary, match", [
    ({"ratoi": [1, 2]}, r"unknown parameter 'ratoi'.*allowed: ratio, scale, lower_a"),
    ({"ratio": []}, r"'ratio' needs a non-empty"),
    ({}, r"vary is empty.*ratio"),
    ([], r"list of parameter sets is empty"),
    ({"ratio": [4.0, float("nan")]}, r"values of 'ratio' must be finite"),
    ({"upper_a": [float("-inf")]}, r"'upper_a' must be finite or \+inf"),
    ({"growth_rate": [1.0]}, r"growth_rate.*needs a growth schedule"),
    ({"ratio": [4.0, -1.0]}, r"member 1 \(ratio=-1\).*Turing.ratio"),
    ({"ratio": [4.0, 40.0]}, r"member 1 \(ratio=40\).*explicit-Euler stability limit"),
])
def test_bad_input_names_the_parameter(start, vary, match):
    with pytest.raises(ValueError, match=match):
        sweep(mj.Turing(scale=3.0), vary, state=start, steps=1, dt=0.008)


def test_bad_state_and_keys(start):
    with pytest.raises(ValueError, match="shape` and `key`"):
        sweep(mj.Turing(), {"ratio": [4.0]}, steps=1, dt=0.01)
    with pytest.raises(ValueError, match="room to grow"):
        sweep(mj.Turing(), {"ratio": [4.0]}, state=start, steps=1, dt=0.01, growth=mj.Growth(1.0), key=0)
    with pytest.raises(ValueError, match="key is required"):
        sweep(mj.Turing(), {"ratio": [4.0]}, state=start.with_capacity((20, 20)), steps=1, dt=0.01,
              growth=mj.Growth(1.0))
    with pytest.raises(ValueError, match="state has 3"):
        sweep(mj.Turing(), {"ratio": [4.0]}, state=start.with_species("c", 1.0), steps=1, dt=0.01)


# ---- spatial parameter maps -------------------------------------------------------------------------
def test_parameter_map_varies_along_x_and_y_and_matches_a_constant_map(start):
    rows, cols = SHAPE
    model = parameter_map(mj.Turing(scale=3.0), SHAPE, x=("ratio", 4.0, 12.0), y=("upper_a", 6.5, 5.0))
    ratio = np.asarray(model.ratio)
    assert ratio.shape == SHAPE
    np.testing.assert_allclose(ratio[0], np.linspace(4, 12, cols), rtol=1e-6)
    np.testing.assert_allclose(ratio[:, 3], 4.0 + 8.0 * 3 / (cols - 1), rtol=1e-6)
    upper = np.asarray(model.upper)
    assert upper.shape == (2,) + SHAPE
    np.testing.assert_allclose(upper[0][:, 0], np.linspace(6.5, 5.0, rows), rtol=1e-6)
    assert np.isinf(upper[1]).all()
    out = mj.simulate(model, start, STEPS, DT)
    assert np.isfinite(np.stack(out.arrays())).all()
    img = map_image(out.arrays()[1], x=("ratio", 4.0, 12.0), y=("upper_a", 6.5, 5.0), title="map")
    assert img.width > 2 * cols and img.height > 2 * rows
    # a "map" whose ends are equal is the scalar model: exactly in the pointwise form, to
    # float rounding in the flux form (the default: harmonic means of equal rates, summed by link)
    flat = parameter_map(mj.Turing(scale=3.0), SHAPE, x=("ratio", 8.0, 8.0))
    scalar = np.stack(mj.simulate(mj.Turing(8.0, 3.0), start, STEPS, DT).arrays())
    np.testing.assert_array_equal(
        np.stack(mj.simulate(flat, start, STEPS, DT, domain=mj.Lattice(maps="pointwise")).arrays()), scalar)
    np.testing.assert_allclose(np.stack(mj.simulate(flat, start, STEPS, DT).arrays()), scalar, rtol=1e-5, atol=1e-5)
    with pytest.raises(ValueError, match="unknown parameter 'rate'.*allowed: ratio"):
        parameter_map(mj.Turing(), SHAPE, x=("rate", 1, 2))


# ---- several devices --------------------------------------------------------------------------------
SHARDED = textwrap.dedent("""
    import json, sys
    import jax, numpy as np
    import morphojax as mj
    from morphojax._sweep import sweep
    RATIOS, UPPER_A, STEPS, DT = json.loads(sys.argv[2])
    start = mj.paper_state(jax.random.key(7), (16, 16))
    res = sweep(mj.Turing(scale=3.0), {"ratio": RATIOS, "upper_a": UPPER_A}, state=start,
                steps=STEPS, dt=DT, batch_size=4)
    np.save(sys.argv[1], res.arrays())
    print(json.dumps({"devices": len(jax.devices()), "member_devices": res.member_devices.tolist(),
                      "sharding": res.sharding, "batch_size": res.config["batch_size"]}))
""")


def test_sharded_over_four_forced_host_devices_matches_one_device(exact, tmp_path):
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4", JAX_PLATFORMS="cpu",
               PYTHONPATH=str(ROOT))
    out = tmp_path / "sharded.npy"
    proc = subprocess.run([sys.executable, "-c", SHARDED, str(out), json.dumps([RATIOS, UPPER_A, STEPS, DT])],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    info = json.loads(proc.stdout.strip().splitlines()[-1])
    assert info["devices"] == 4 and info["batch_size"] == 4  # one member per device per chunk
    assert "'batch': 4" in info["sharding"]
    # chunk 1 puts members 0-3 on devices 0-3, chunk 2 members 4-5 on devices 0-1 (padding on 2-3)
    assert info["member_devices"] == [0, 1, 2, 3, 0, 1]
    np.testing.assert_array_equal(np.load(out), exact.arrays())  # vmapped: bit for bit


MULTIHOST = textwrap.dedent("""
    import json, sys
    import jax
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    port, pid, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    jax.distributed.initialize(coordinator_address=f"localhost:{port}", num_processes=2, process_id=pid)
    import numpy as np
    import morphojax as mj
    from morphojax._sweep import sweep
    RATIOS, UPPER_A, STEPS, DT = json.loads(sys.argv[4])
    start = mj.paper_state(jax.random.key(7), (16, 16))
    res = sweep(mj.Turing(scale=3.0), {"ratio": RATIOS, "upper_a": UPPER_A}, state=start, steps=STEPS, dt=DT)
    np.save(out, res.arrays())
    print(json.dumps({"processes": jax.process_count(), "member_devices": res.member_devices.tolist()}))
""")


def test_two_processes_with_jax_distributed_each_run_half_and_gather(grid, tmp_path):
    """Multi-host in miniature: two CPU processes joined by `jax.distributed` (gloo collectives)."""
    import socket

    with socket.socket() as sock:
        sock.bind(("localhost", 0))
        port = sock.getsockname()[1]
    env = dict(os.environ, JAX_PLATFORMS="cpu", PYTHONPATH=str(ROOT))
    env.pop("XLA_FLAGS", None)
    args = json.dumps([RATIOS, UPPER_A, STEPS, DT])
    procs = [subprocess.Popen([sys.executable, "-c", MULTIHOST, str(port), str(i), str(tmp_path / f"p{i}.npy"), args],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env) for i in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err[-3000:]
    infos = [json.loads(o.strip().splitlines()[-1]) for o, _ in outs]
    assert all(info["processes"] == 2 for info in infos)
    owners = infos[0]["member_devices"]
    assert len(set(owners[:3])) == 1 and len(set(owners[3:])) == 1 and owners[0] != owners[3]  # 3 members each
    for i in range(2):  # every process returns the full, gathered result
        np.testing.assert_array_equal(np.load(tmp_path / f"p{i}.npy"), grid.arrays())


# ---- command line ------------------------------------------------------------------------------------
def parser():
    p = argparse.ArgumentParser(prog="morphojax")
    register(p.add_subparsers(dest="command", required=True))
    return p


def test_cli_end_to_end_on_a_tiny_grid(tmp_path, capsys):
    out = tmp_path / "maps" / "map.png"
    args = parser().parse_args(["sweep", "--model", "turing", "--vary", "ratio=4:12:2", "--vary", "upper_a=5,6",
                                "--fixed", "scale=3", "--steps", str(STEPS), "--shape", "16", "16", "--seed", "7",
                                "--no-progress", "--out", str(out)])
    assert args.func(args) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["members"] == 4 and summary["shape"] == [2, 2]
    assert summary["dt"] == pytest.approx(0.8 * mj.max_stable_dt(36.0), rel=1e-2)  # r = 12, s = 3
    for suffix in (".png", ".csv", ".json", ".npz"):
        assert out.with_suffix(suffix).exists()
    back = load_sweep(out.with_suffix(".npz"))
    assert back.arrays().shape == (2, 2, 2, 16, 16)
    np.testing.assert_allclose(back.axes[0], [4.0, 12.0])
    # the CLI's shared start is the library's shared start for the same seed
    m = back.member((1, 0))
    close(back.arrays()[1, 0], np.stack(mj.simulate(**m.kwargs()).arrays()))


def test_cli_values_and_errors():
    assert parse_values("ratio", "4:40:9") == pytest.approx(list(np.linspace(4, 40, 9)))
    assert parse_values("ratio", "4, 8,12") == [4.0, 8.0, 12.0]
    assert parse_values("ratio", "5") == [5.0]
    for text in ("4:40", "4:40:0", "4:40:2.5", "a:b:3", "4,,x", "", "1:2:3:4"):
        with pytest.raises(ValueError, match=r"--vary ratio"):
            parse_values("ratio", text)

    def build(*extra):
        return build_sweep(parser().parse_args(["sweep", "--model", "turing", "--out", "x.png", *extra]))

    with pytest.raises(ValueError, match=r"unknown parameter 'foo'.*allowed: ratio"):
        build("--vary", "foo=1,2")
    with pytest.raises(ValueError, match=r"values of 'ratio' must be finite"):
        build("--vary", "ratio=4,inf")
    with pytest.raises(ValueError, match=r"unknown model 'turnig'; allowed: turing"):
        build_sweep(parser().parse_args(["sweep", "--model", "turnig", "--vary", "ratio=4", "--out", "x.png"]))
    with pytest.raises(ValueError, match=r"has no parameter 'sclae'"):
        build("--vary", "ratio=4", "--fixed", "sclae=3")
    with pytest.raises(ValueError, match=r"--vary ratio is given twice"):
        build("--vary", "ratio=4", "--vary", "ratio=5")
    model, vary, kw = build("--vary", "ratio=4:40:9", "--vary", "upper_a=4:6.5:6", "--fixed", "scale=3")
    assert list(vary) == ["ratio", "upper_a"] and len(vary["upper_a"]) == 6
    assert kw["dt"] <= mj.max_stable_dt(120.0) and kw["steps"] == int(np.ceil(100 / kw["dt"] - 1e-9))
    # the real entry point reports bad input as a one-line error with status 2
    from morphojax import cli as _cli

    wired = "sweep" in _cli.build_parser()._subparsers._group_actions[0].choices
    if not wired:  # before `register` is listed in the main CLI
        _cli.COMMANDS.append(("sweep", register))
    try:
        assert _cli.main(["sweep", "--model", "turing", "--vary", "ratoi=1", "--out", "x.png"]) == 2
    finally:
        if not wired:
            _cli.COMMANDS.remove(("sweep", register))

"""Hostile files and inputs (issue 35): every size checked against the memory limit before it
is spent, every loader's failure one ValueError naming the file, metadata checked against
itself and its arrays, nothing read outside its place. Files are generated (hypothesis); each
test checks the refusal, never the allocation, and compiles nothing."""

from __future__ import annotations

import io
import json
import os
import re
import time
import zipfile
from pathlib import Path

import jax
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import morphojax as mj
from morphojax._checks import (STEP_COUNTER_MAX, check_memory, check_run_size, check_shape, check_step_counter,
                               memory_limit, parse_memory)
from morphojax._serialise import load_npz, save_npz
from morphojax._files import FORMAT_VERSION, npz_members

FEW = settings(max_examples=25, deadline=None, derandomize=True,
               suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture
def small_limit(monkeypatch):
    monkeypatch.setenv("MORPHOJAX_MAX_MEMORY", "64M")
    return 64 * 2**20


def _npy_header(shape, descr="<f4") -> bytes:
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(out, {"descr": descr, "fortran_order": False, "shape": tuple(shape)})
    return out.getvalue()


def _result_file(path: Path, meta_changes=None, *, experiment=True) -> Path:
    """A valid result of a quick preset (built, not run), with `meta_changes` applied to its JSON."""
    state = mj.State.from_arrays([np.full((32, 32), 4.0), np.full((32, 32), 4.5)], names=("a", "b"))
    meta = {}
    if experiment:
        exp = mj.preset("fig4-r4.2", quick=True)
        meta = {"experiment": exp.to_dict(), "run": {"seed": 0, "phase": 0, "phase_step": 0, "phase_origin": None}}
    path = save_npz(path, state, meta)
    if meta_changes:
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
        meta = json.loads(str(arrays["metadata"]))
        for field, value in meta_changes.items():
            target = meta["run"] if field.startswith("run.") else meta
            target[field.removeprefix("run.")] = value
        arrays["metadata"] = np.asarray(json.dumps(meta))
        np.savez_compressed(path, **arrays)
    return path


# ---- 1. resources bounded before they are spent --------------------------------------------
def test_memory_limit_from_the_environment(monkeypatch):
    assert parse_memory("32G") == 32 * 2**30 and parse_memory("512M") == 512 * 2**20
    assert parse_memory("1.5GB") == int(1.5 * 2**30) and parse_memory("4096") == 4096
    monkeypatch.setenv("MORPHOJAX_MAX_MEMORY", "2G")
    assert memory_limit() == 2 * 2**30
    with pytest.raises(ValueError, match=r"this run needs about 61 GB; the limit is 2.15 GB"):
        check_memory(61e9, "this run")
    for bad in ("lots", "-3G", "0", "nanG"):
        monkeypatch.setenv("MORPHOJAX_MAX_MEMORY", bad)
        with pytest.raises(ValueError, match="MORPHOJAX_MAX_MEMORY must be a positive size"):
            memory_limit()
    monkeypatch.delenv("MORPHOJAX_MAX_MEMORY")
    assert 0 < memory_limit() < 2**50  # half the machine's


@FEW
@given(shape=st.lists(st.integers(1, 10**9), min_size=1, max_size=3), species=st.integers(1, 8),
       members=st.integers(1, 10**7), scale=st.integers(1, 10**6))
def test_run_sizes_are_refused_by_their_estimate(shape, species, members, scale):
    limit = memory_limit()
    try:
        check_run_size(shape, species, members=members, scale=scale)
    except ValueError as err:
        assert "needs about" in str(err) and "the limit is" in str(err)
    else:  # what passes is within the limit by the same estimate, counted exactly
        cells = int(np.prod(np.asarray(shape, dtype=object)))
        assert cells * species * 16 * members <= limit


@FEW
@given(shape=st.lists(st.one_of(st.integers(-3, 0), st.floats(0.1, 1e6).filter(lambda x: not x.is_integer()),
                                st.booleans(), st.complex_numbers(), st.text(max_size=2)), min_size=1, max_size=3))
def test_bad_shapes_are_refused_not_floored(shape):
    with pytest.raises(ValueError, match="shape"):
        check_shape(shape, "shape")
    with pytest.raises(ValueError, match="shape"):
        mj.initial_state(mj.Turing(), jax.random.key(0), tuple(shape) if len(shape) > 1 else tuple(shape) * 2)


def test_initial_state_and_complex_parameters():
    with pytest.raises(ValueError, match=r"whole numbers, not 16.5"):
        mj.paper_state(jax.random.key(0), (16.5, 16))
    with pytest.raises(ValueError, match="needs about"):
        mj.paper_state(jax.random.key(0), (10**6, 10**6))
    with pytest.raises(ValueError, match="must be real, not complex"):
        mj.Turing(ratio=4 + 1j)


def test_step_counter_is_int32():
    check_step_counter(0, STEP_COUNTER_MAX)
    with pytest.raises(ValueError, match="int32"):
        check_step_counter(10, STEP_COUNTER_MAX - 5)
    with pytest.raises(ValueError, match="int32"):
        check_step_counter(0, 2**31 + 5)


@FEW
@given(shape=st.lists(st.integers(10**4, 10**7), min_size=1, max_size=3),
       descr=st.sampled_from(["<f4", "<f8", "<i4", "|u1", "<c16"]), compressed=st.booleans())
def test_npz_member_headers_are_read_before_loading(tmp_path, shape, descr, compressed):
    path = tmp_path / "claims.npz"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED if compressed else zipfile.ZIP_STORED) as zf:
        zf.writestr("species_a.npy", _npy_header(shape, descr) + b"\0" * 64)
        zf.writestr("metadata.npy", _npy_header((), "<U2") + b"{\0\0\0}\0\0\0")
    with pytest.raises(ValueError, match=r"claims\.npz is not a morphojax result file \(member 'species_a' declares"):
        load_npz(path)


def test_npz_over_the_limit_and_bombs_are_refused(tmp_path, small_limit):
    honest = tmp_path / "honest.npz"
    np.savez(honest, cells=np.zeros(20 * 2**20, np.uint8))  # 20 MB: fine under 64 MB
    assert npz_members(honest)["cells"][0] == (20 * 2**20,)
    big = tmp_path / "big.npz"
    np.savez(big, cells=np.zeros(80 * 2**20, np.uint8))  # 80 MB > 64 MB
    with pytest.raises(ValueError, match=r"reading .*big\.npz needs about 83.9 MB; the limit is 67.1 MB"):
        npz_members(big)


def test_decompression_bomb_is_refused_from_its_declared_size(tmp_path, monkeypatch):
    import morphojax._files as files

    monkeypatch.setattr(files, "BOMB_SIZE", 1 << 20)  # the rule at a test's size: 1 MB, not 256 MB
    path = tmp_path / "bomb.npz"
    np.savez_compressed(path, cells=np.zeros(8 << 20, np.uint8))  # 8 MB of zeros in ~8 kB
    with pytest.raises(ValueError, match=r"expands from .* more than 200 times"):
        files.npz_members(path)


def test_cli_sizes_refused_before_anything_runs(capsys, small_limit):
    from morphojax.cli import main

    cases = [
        (["run", "fig4-r4.2", "--scale", "100000"], r"run: error: this run .* needs about"),
        (["run", "fig4-r4.2", "--scale", "0"], r"--scale must be a whole number >= 1"),
        (["sweep", "--model", "turing", "--vary", "ratio=4:40:2", "--shape", "50000", "50000", "--out", "s.png"],
         r"this sweep \(2 members of 50000x50000 cells\) needs about"),
        (["sweep", "--model", "turing", "--vary", "ratio=4:40:1000000", "--out", "s.png"], "needs about"),
        (["sweep", "--model", "turing", "--vary", "ratio=4:40:1000000000000", "--out", "s.png"],
         r"at most 1000000 members"),
        (["sweep", "--model", "turing", "--vary", "ratio=4:40:2", "--steps", str(2**31 + 5), "--out", "s.png"],
         r"step counter"),
    ]
    for argv, match in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
        assert __import__("re").search(match, err), (argv, err)
    assert main(["ca", "--dim", "3", "--size", "3000"]) == 2  # bad input: 2, as every command
    assert re.search(r"morphojax ca: error: this automaton \(3000\^3 cells", capsys.readouterr().err)


# ---- 3. one kind of error from every loader -------------------------------------------------
def _damaged(good: Path, data) -> Path:
    """`good`'s bytes damaged as a disk or a download would (drawn by hypothesis), as bad.npz."""
    raw = bytearray(good.read_bytes())
    how = data.draw(st.sampled_from(["truncate", "flip", "random", "empty", "append"]))
    if how == "truncate":
        raw = raw[:data.draw(st.integers(0, len(raw) - 1))]
    elif how == "flip":
        for at in data.draw(st.lists(st.integers(0, len(raw) - 1), min_size=1, max_size=8)):
            raw[at] ^= 0xFF
    elif how == "random":
        raw = bytearray(data.draw(st.binary(min_size=1, max_size=4096)))
    elif how == "empty":
        raw = bytearray()
    else:
        raw += data.draw(st.binary(min_size=1, max_size=64))
    bad = good.with_name("bad.npz")
    bad.write_bytes(bytes(raw))
    return bad


@FEW
@given(data=st.data())
def test_damaged_results_raise_one_value_error(tmp_path_factory, data):
    bad = _damaged(_result_file(tmp_path_factory.mktemp("r") / "good.npz"), data)
    try:
        state, meta = load_npz(bad)
    except ValueError as err:
        assert "bad.npz" in str(err)
    else:  # a change the archive survives (an appended tail, a flipped unused byte) reads the same
        assert state.names == ("a", "b")


@pytest.mark.parametrize("flag", [0x01, 0x08 | 0x01, 0x20, 0x40])
def test_archives_with_flipped_flag_bits_are_refused_by_name(tmp_path, flag):
    """A flipped flag bit in an archive's directory makes zipfile raise RuntimeError ("encrypted,
    password required") or NotImplementedError ("strong encryption", "compressed patched
    data"): one ValueError naming the file, from every npz loader."""
    for name, write, load in (("result.npz", lambda p: _result_file(p, experiment=False), load_npz),
                              ("frames.npz", _frames_file, mj.load_frames)):
        raw = bytearray(write(tmp_path / name).read_bytes())
        at = raw.index(b"PK\x01\x02") + 8  # the first member's flags in the central directory
        raw[at] |= flag
        (tmp_path / name).write_bytes(bytes(raw))
        with pytest.raises(ValueError, match=rf"{name.replace('.', '[.]')} is not a morphojax"):
            load(tmp_path / name)


@pytest.mark.parametrize("loader", ["result", "sweep", "cells"])
def test_loaders_refuse_devices_folders_and_missing_files(tmp_path, loader):
    load = {"result": mj.load_npz, "sweep": mj.load_sweep, "cells": mj.load_cells}[loader]
    for path, match in ((Path("/dev/zero"), "not a regular file"), (tmp_path, "a folder"),
                        (tmp_path / "none.npz", "no such")):
        with pytest.raises(ValueError, match=match):
            load(path)
    fifo = tmp_path / "pipe.npz"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="not a regular file"):  # never blocks
        load(fifo)


MESH_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


@FEW
@given(fmt=st.sampled_from(["obj", "stl", "off", "ply"]), data=st.binary(max_size=2048),
       keep=st.integers(0, len(MESH_OBJ)))
def test_random_and_broken_mesh_files_raise_value_error(tmp_path_factory, fmt, data, keep):
    folder = tmp_path_factory.mktemp("m")
    for name, content in (("random", data), ("cut", MESH_OBJ.encode()[:keep]),
                          ("latin", MESH_OBJ.replace("v 0 0 1", "# caf\xe9\nv 0 0 1").encode("latin-1"))):
        path = folder / f"{name}.{fmt}"
        path.write_bytes(content)
        try:
            mesh = mj.Mesh.from_file(path)
        except ValueError as err:
            assert str(path) in str(err) or path.name in str(err)
        else:
            assert mesh.n_vertices >= 3


def test_meshes_keep_numbering_and_refuse_nan(tmp_path):
    tet = tmp_path / "tet.obj"
    tet.write_text(MESH_OBJ)
    mesh = mj.Mesh.from_file(tet)
    np.testing.assert_array_equal(mesh.vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert mesh.faces.shape == (4, 3)
    (tmp_path / "latin.obj").write_bytes(("# made by Ren\xe9\n" + MESH_OBJ).encode("latin-1"))
    assert mj.Mesh.from_file(tmp_path / "latin.obj").n_vertices == 4
    (tmp_path / "nan.obj").write_text(MESH_OBJ.replace("v 0 0 1", "v nan 0 1"))
    with pytest.raises(ValueError, match="nan.obj.*NaN"):
        mj.Mesh.from_file(tmp_path / "nan.obj")
    (tmp_path / "unused.obj").write_text("v 5 5 5\n" + MESH_OBJ.replace("f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4",
                                                                          "f 2 4 3\nf 2 3 5\nf 2 5 4\nf 3 4 5"))
    with pytest.raises(ValueError, match="unused.obj.*no face uses"):
        mj.Mesh.from_file(tmp_path / "unused.obj")
    (tmp_path / "far.obj").write_text(MESH_OBJ + "f 1 2 9\n")
    with pytest.raises(ValueError, match=r"far.obj.*vertex index 9 is outside 1..4"):
        mj.Mesh.from_file(tmp_path / "far.obj")
    (tmp_path / "lie.off").write_text("OFF\n100000000 1 0\n0 0 0\n")
    with pytest.raises(ValueError, match="declares 100000000 vertices"):
        mj.Mesh.from_file(tmp_path / "lie.off")


def test_nan_vertices_nan_pixels_and_large_images_are_refused(tmp_path, monkeypatch):
    """NaN or infinite coordinates in OFF and PLY files, NaN pixels in an array target or
    palette, and an image whose header size passes the memory limit: each a ValueError
    naming what is wrong, before anything is decoded or fitted."""
    from PIL import Image

    fitting = pytest.importorskip("fitting")
    faces = "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
    (tmp_path / "nan.off").write_text("OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\nnan 0 1\n" + faces)
    (tmp_path / "inf.ply").write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                                      "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
                                      "end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 inf\n" + faces)
    for name in ("nan.off", "inf.ply"):
        with pytest.raises(ValueError, match=rf"{name}: .*NaN or infinite"):
            mj.Mesh.from_file(tmp_path / name)
    grey = np.random.default_rng(0).random((40, 40))
    grey[3, 3] = np.nan
    with pytest.raises(ValueError, match="NaN or infinite"):
        fitting.load_target(grey, cell_pixels=1.0)
    with pytest.raises(ValueError, match="Gradient.from_photo: .*NaN"):
        mj.Gradient.from_photo(np.stack([grey] * 3, -1))
    Image.fromarray(np.zeros((300, 400), np.uint8)).save(tmp_path / "big.png")
    monkeypatch.setenv("MORPHOJAX_MAX_MEMORY", "1M")
    with pytest.raises(ValueError, match=r"the 400x300 image .*big.png needs about 3.84 MB; the limit is 1.05 MB"):
        fitting.load_target(tmp_path / "big.png", cell_pixels=1.0)
    with pytest.raises(ValueError, match=r"Gradient.from_photo: the 400x300 image .* the limit is 1.05 MB"):
        mj.Gradient.from_photo(tmp_path / "big.png")


@FEW
@given(data=st.binary(max_size=512), cut=st.integers(0, 400))
def test_broken_images_raise_value_error(tmp_path_factory, data, cut):
    from PIL import Image

    fitting = pytest.importorskip("fitting")
    folder = tmp_path_factory.mktemp("img")
    good = folder / "good.png"
    Image.fromarray((np.arange(64 * 64).reshape(64, 64) % 251).astype(np.uint8)).save(good)
    deep = _png16(folder / "deep.png", (np.arange(64 * 64 * 3).reshape(64, 64, 3) * 97 % 65536).astype(np.uint16))
    for name, content in (("random.png", data), ("cut.png", good.read_bytes()[:cut]),
                          ("cut16.png", deep.read_bytes()[:cut])):
        (folder / name).write_bytes(content)
        try:
            fitting.load_target(folder / name, cell_pixels=2.0)
        except ValueError:
            pass
        try:
            mj.Gradient.from_photo(folder / name)
        except ValueError:
            pass


def test_sixteen_bit_pngs_are_read_at_their_depth(tmp_path):
    from PIL import Image

    fitting = pytest.importorskip("fitting")
    stripes = np.where(np.arange(64) % 16 < 8, 1000, 1100).astype(np.uint16)  # both above 255
    Image.fromarray(np.tile(stripes, (64, 1))).save(tmp_path / "deep.png")
    target = fitting.load_target(tmp_path / "deep.png", cell_pixels=2.0)
    assert target.pixels.min() == 0.0 and target.pixels.max() == 1.0  # contrast kept, not clipped to 255


def _png16(path: Path, samples, *, interlace=False) -> Path:
    """A 16-bit PNG written by hand (Pillow writes 16-bit grey only): `samples` (rows, cols) grey
    or (rows, cols, 2|3|4) grey+alpha, RGB, RGBA; rows cycle through the five filters (encoded
    from the samples, so they vectorise), Adam7 interlacing on request."""
    import struct
    import zlib

    def filtered(raw, bpp):  # raw (rows, bytes) -> each row with its filter byte, filters 0-4 in turn
        r = raw.astype(np.int32)
        left = np.pad(r, ((0, 0), (bpp, 0)))[:, :-bpp]
        up = np.pad(r, ((1, 0), (0, 0)))[:-1]
        corner = np.pad(up, ((0, 0), (bpp, 0)))[:, :-bpp]
        p = left + up - corner
        pa, pb, pc = abs(p - left), abs(p - up), abs(p - corner)
        paeth = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, up, corner))
        preds = [0 * r, left, up, (left + up) // 2, paeth]
        return b"".join(bytes([y % 5]) + ((r[y] - preds[y % 5][y]) % 256).astype(np.uint8).tobytes()
                        for y in range(len(r)))

    a = np.asarray(samples, ">u2")
    a = a[..., None] if a.ndim == 2 else a
    rows, cols, bands = a.shape
    passes = ([(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)]
              if interlace else [(0, 0, 1, 1)])
    data = b"".join(filtered(np.ascontiguousarray(sub).reshape(len(sub), -1).view(np.uint8), 2 * bands)
                    for sub in (a[y0::dy, x0::dx] for x0, y0, dx, dy in passes) if sub.size)

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    head = struct.pack(">IIBBBBB", cols, rows, 16, {1: 0, 2: 4, 3: 2, 4: 6}[bands], 0, 0, int(interlace))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", head) + chunk(b"IDAT", zlib.compress(data))
                     + chunk(b"IEND", b""))
    return path


@FEW
@given(data=st.data(), bands=st.sampled_from([1, 2, 3, 4]), interlace=st.booleans())
def test_sixteen_bit_colour_pngs_match_their_eight_bit_versions(tmp_path_factory, data, bands, interlace):
    """A 16-bit PNG of any kind (grey, grey+alpha, RGB, RGBA; every filter; interlaced or not)
    is read at 16 bits: each channel is its samples / 65535 exactly, and within 1/255 of the
    same picture saved at 8 bits (its contrast too), where Pillow alone keeps 8 bits of colour."""
    from PIL import Image

    pytest.importorskip("fitting")
    from fitting._target import _channel, open_image

    rows, cols = data.draw(st.integers(1, 24)), data.draw(st.integers(1, 24))
    samples = np.asarray(data.draw(st.lists(st.integers(0, 65535), min_size=rows * cols * bands,
                                            max_size=rows * cols * bands)), np.uint16).reshape(rows, cols, bands)
    folder = tmp_path_factory.mktemp("deep")
    deep = open_image(_png16(folder / "deep.png", samples[..., 0] if bands == 1 else samples, interlace=interlace),
                      "test")
    eight = np.round(samples / 257.0).astype(np.uint8)
    Image.fromarray(eight[..., 0] if bands == 1 else eight, {1: "L", 2: "LA", 3: "RGB", 4: "RGBA"}[bands]).save(
        folder / "eight.png")
    shallow = open_image(folder / "eight.png", "test")
    exact = samples / 65535.0
    own = {"red": exact[..., 0], "green": exact[..., 0 if bands < 3 else 1],
           "blue": exact[..., 0 if bands < 3 else 2], "alpha": exact[..., -1] if bands in (2, 4) else None}
    for channel in ("red", "green", "blue", "alpha", "luminance", "value"):
        if channel == "alpha" and bands in (1, 3):
            with pytest.raises(ValueError, match="no alpha channel"):
                _channel(deep, channel)
            continue
        got, want = _channel(deep, channel), _channel(shallow, channel)
        assert got.shape == (rows, cols)
        if channel in own:
            np.testing.assert_allclose(got, own[channel], atol=1e-7)  # all 16 bits, not the high byte
            assert abs(np.ptp(got) - np.ptp(want)) <= 1 / 255 + 1e-9  # the contrast of the 8-bit picture
        assert np.abs(got - want).max() <= 1 / 255 + 1e-4, channel  # (+ Pillow's 8-bit luminance weights)


@pytest.mark.parametrize("bands", [1, 2, 3, 4])
def test_sixteen_bit_contrast_below_eight_bits_is_kept(tmp_path, bands):
    """Stripes of 1030 and 1100 share their high byte (4): at 8 bits they are one grey, and the
    target was refused as "no contrast"; at 16 bits they are the target's 0 and 1."""
    fitting = pytest.importorskip("fitting")
    stripes = np.tile(np.where(np.arange(64) % 16 < 8, 1030, 1100).astype(np.uint16), (64, 1))
    samples = np.stack([stripes] * bands, axis=-1)
    if bands in (2, 4):
        samples[..., -1] = 65535  # opaque
    path = _png16(tmp_path / "faint.png", samples[..., 0] if bands == 1 else samples)
    target = fitting.load_target(path, cell_pixels=2.0)
    assert target.pixels.min() == 0.0 and target.pixels.max() == 1.0
    assert np.ptp(target.field) > 0.9 and target.rgb is not None and target.rgb.shape[:2] == (64, 64)
    crop = fitting.load_target(path, crop=(0, 0, 40, 32), channel="blue", cell_pixels=2.0)
    assert crop.pixels.shape == (32, 40) and crop.pixels.max() == 1.0
    if bands == 1:  # the palette of a photo reads it at its depth too (Pillow clips a 16-bit grey at 255)
        stripes[:, ::2] = 50000
        stops = mj.Gradient.from_photo(_png16(tmp_path / "grey.png", stripes)).stops
        assert len({colour for _, colour in stops}) >= 2


TARGET_ARRAYS = ("field", "pixels", "rgb", "values")


def test_an_open_sixteen_bit_image_reads_as_its_file(tmp_path):
    """An open PIL image of a 16-bit grey (as opened, or made in memory as 'I;16', 'I;16B'
    or 'I') gives the target its PNG's path gives, field, pixels and palette thumbnail, at 16
    bits: not the target of its 8-bit quantisation (Pillow's own RGB of an 'I;16' clips it
    at 255, a white thumbnail)."""
    from PIL import Image

    fitting = pytest.importorskip("fitting")
    rows, cols = np.mgrid[0:64, 0:64]
    grey = (30000 + 300 * np.sin(cols / 2.5) * np.cos(rows / 3.5)).astype(np.uint16)  # all within one high byte's 2
    path = tmp_path / "deep.png"
    Image.fromarray(grey).save(path)  # Pillow writes a 16-bit grey PNG
    by_path = fitting.load_target(path, cell_pixels=2.0)
    with Image.open(path) as opened:
        given_open = [fitting.load_target(opened, cell_pixels=2.0)]
    given_open += [fitting.load_target(im, cell_pixels=2.0) for im in (
        Image.fromarray(grey), Image.fromarray(grey.astype(">u2")), Image.fromarray(grey).convert("I"))]
    assert [im.mode for im in (Image.fromarray(grey), Image.fromarray(grey.astype(">u2")))] == ["I;16", "I;16B"]
    for target in given_open:
        for name in TARGET_ARRAYS:
            np.testing.assert_array_equal(getattr(target, name), getattr(by_path, name), err_msg=name)
    eight = fitting.load_target(Image.fromarray(np.round(grey / 257.0).astype(np.uint8)), cell_pixels=2.0)
    assert np.abs(eight.pixels - by_path.pixels).max() > 0.1  # 8 bits hold ~3 levels of these stripes
    assert by_path.rgb.max() < 0.5  # the thumbnail of a mid grey, not clipped to white


@pytest.mark.parametrize("mode", ["RGBA", "LA", "P", "RGB"])
def test_an_open_image_reads_as_its_file(tmp_path, mode):
    """Colour, alpha and palette images given open read as their files: a 16-bit RGB PNG
    opened but not decoded at its depth, the others as Pillow reads them."""
    from PIL import Image

    fitting = pytest.importorskip("fitting")
    rng = np.random.default_rng(1)
    path = tmp_path / f"{mode}.png"
    Image.fromarray((rng.random((48, 48, 4)) * 255).astype(np.uint8), "RGBA").convert(mode).save(path)
    deep = _png16(tmp_path / "rgb16.png", (rng.random((48, 48, 3)) * 65535).astype(np.uint16))
    for file in (path, deep):
        by_path = fitting.load_target(file, cell_pixels=2.0)
        with Image.open(file) as opened:
            given_open = fitting.load_target(opened, cell_pixels=2.0)
        for name in TARGET_ARRAYS:
            np.testing.assert_array_equal(getattr(given_open, name), getattr(by_path, name), err_msg=name)


@pytest.mark.parametrize("mode", ["La", "RGBa", "LAB", "HSV"])
def test_an_open_image_of_a_mode_a_target_cannot_read_is_refused(mode):
    from PIL import Image

    fitting = pytest.importorskip("fitting")
    with pytest.raises(ValueError, match=rf"load_target\.source: an image of mode '{mode}' cannot be read; "
                                         r"allowed modes: 1, L, LA, P, .*I;16.*F"):
        fitting.load_target(Image.new(mode, (32, 32)), cell_pixels=2.0)


def test_sixteen_bit_colour_png_that_pillow_cannot_read_deep_is_refused(tmp_path, monkeypatch):
    """Where this Pillow cannot decode the low bytes (a raw mode it lacks), the file is
    refused by name with the advice to convert it, never read at 8 bits."""
    import morphojax._deep_png as deep

    fitting = pytest.importorskip("fitting")
    monkeypatch.setitem(deep.DEEP_RAWMODES, "RGB;16B", ("RGB", "RGB;99L"))
    path = _png16(tmp_path / "rgb16.png", np.full((20, 20, 3), 1000, np.uint16))
    with pytest.raises(ValueError, match=r"rgb16\.png is a 16-bit RGB PNG, which this Pillow reads only at 8 bits .*"
                                         r"convert it to 8-bit colour or 16-bit grey"):
        fitting.load_target(path, cell_pixels=2.0)


def test_cli_prints_one_line_and_debug_shows_the_traceback(tmp_path, capsys):
    from morphojax.cli import main

    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"PK\x03\x04 not really a zip")
    for argv in (["render", str(bad), "--out", str(tmp_path / "x.png")], ["resume", str(bad)],
                 ["render", "/dev/zero", "--out", str(tmp_path / "x.png")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err and "error:" in err
    with pytest.raises(ValueError, match="bad.npz"):
        main(["--debug", "render", str(bad), "--out", str(tmp_path / "x.png")])


# ---- 2. metadata checked, not trusted -------------------------------------------------------
def test_results_record_version_and_round_trip(tmp_path):
    state, meta = load_npz(_result_file(tmp_path / "r.npz"))
    assert meta["morphojax"] == mj.__version__ and meta["format_version"] == FORMAT_VERSION
    assert state.shape == (32, 32) and state.names == ("a", "b")


@pytest.mark.parametrize("change, field", [
    ({"run.phase": 99}, "'phase'"), ({"run.phase": -1}, "'phase'"), ({"run.phase_step": -5}, "'phase_step'"),
    ({"run.phase_step": 10**6}, "'phase_step'"), ({"step": -1}, "'step'"), ({"step": 2**40}, "'step'"),
    ({"capacity": [8, 8]}, "'capacity'"), ({"size": [16, 32]}, "'size'"), ({"species": "ab"}, "'species'"),
    ({"species": [1, 2]}, "'species'"), ({"species": ["a", "a"]}, "'species'"), ({"run": None}, "'run'"),
    ({"time": "nan"}, "'time'"), ({"run.seed": "zero"}, "'seed'"), ({"run.phase_origin": -3}, "'phase_origin'"),
    ({"experiment": {"phases": []}}, "'experiment'"),
])
def test_tampered_result_fields_are_refused_by_name(tmp_path, change, field):
    path = _result_file(tmp_path / "t.npz", change)
    with pytest.raises(ValueError, match=rf"t\.npz .*{field}"):
        load_npz(path)


def test_resume_of_phase_99_is_refused(tmp_path, capsys):
    from morphojax.cli import main

    path = _result_file(tmp_path / "late.npz", {"run.phase": 99})
    assert main(["resume", str(path)]) == 2
    assert "'phase'" in capsys.readouterr().err


def test_a_checkpoint_claiming_more_steps_than_it_ran_is_refused(tmp_path, capsys):
    """A checkpoint's `phase` and `phase_step` place it at a step of its experiment; a file
    claiming completion (or a later point) at another step is refused, not written out."""
    from morphojax.cli import main

    phases = mj.preset("fig4-r4.2", quick=True).phases
    done = _result_file(tmp_path / "done.npz", {"run.phase": len(phases), "step": 10})
    stale = tmp_path / ".done.99999999-kill.npz"  # left by a killed write (no such process)
    stale.write_bytes(b"half an archive")
    assert main(["resume", str(done)]) == 2
    assert not stale.exists()  # removed by the resume, although it wrote nothing
    err = capsys.readouterr().err
    assert f"step {sum(p.steps for p in phases)} of its experiment" in err and "'step' is 10" in err
    assert "already complete" not in err and not (tmp_path / "done.png").exists()
    late = _result_file(tmp_path / "late.npz", {"run.phase_step": 7, "run.phase_origin": 0, "step": 7})
    state, meta = load_npz(late)
    meta["run"]["phase_step"] = 5  # the state ran 7 steps of phase 1
    with pytest.raises(ValueError, match=r"'phase' \(0\) and 'phase_step' \(5\) put this checkpoint at step 5"):
        mj.run_experiment(mj.load_experiment(meta), resume=(state, meta))


def test_newer_files_warn_naming_both_versions(tmp_path):
    path = _result_file(tmp_path / "new.npz", {"morphojax": "99.0.0"}, experiment=False)
    with pytest.warns(UserWarning, match=rf"morphojax 99.0.0, newer than this morphojax {mj.__version__}"):
        load_npz(path)
    path = _result_file(tmp_path / "fmt.npz", {"format_version": FORMAT_VERSION + 1}, experiment=False)
    with pytest.warns(UserWarning, match="file format 2"):
        load_npz(path)


def _preset_file(path: Path, kind: str, meta_changes=None, array_changes=None) -> Path:
    """A file as the automaton, Potts or solid presets write it (small, made here, not run),
    with `meta_changes` applied to its JSON and `array_changes` to its arrays."""
    from morphojax._files import write_npz

    rng = np.random.default_rng(1)
    if kind == "automaton":
        arrays = {"cells": rng.integers(0, 3, (2, 9, 10)).astype(np.int8)}
        meta = {"automaton": "YoungCA", "params": [{"species": [{}, {}]}] * 2, "lattice": [9, 10], "seed": 3,
                "steps": 12}
    elif kind == "potts":
        arrays = {"ids": rng.integers(0, 5, (2, 9, 10)).astype(np.int32), "types": np.array([0, 1, 1, 2, 2]),
                  "j_like": np.array([3.0, 15.0])}
        meta = {"kind": "potts", "j_like": [3.0, 15.0], "lattice": [9, 10], "seed": 3, "mcs": 40}
    else:
        arrays = {"u": rng.random((6, 7, 8)), "v": rng.random((6, 7, 8))}
        meta = {"kind": "solid", "lattice": [6, 7, 8], "steps": 20, "dt": 1.0, "seed": 3}
    meta.update(meta_changes or {})
    arrays.update(array_changes or {})
    return write_npz(path, metadata=np.asarray(json.dumps(meta)), **arrays)


def _load_preset_file(kind, path):
    from morphojax.presets._preset_files import load_automaton, load_potts, load_solid

    return {"automaton": load_automaton, "potts": load_potts, "solid": load_solid}[kind](path)


@pytest.mark.parametrize("kind", ["automaton", "potts", "solid"])
def test_preset_files_round_trip_and_render(tmp_path, kind):
    """Each kind reads back what was written (arrays, metadata with version and format) and
    `morphojax render` draws it."""
    from morphojax.cli import main

    path = _preset_file(tmp_path / f"{kind}.npz", kind)
    *arrays, meta = _load_preset_file(kind, path)
    with np.load(path) as data:
        np.testing.assert_array_equal(arrays[0], data[{"automaton": "cells", "potts": "ids", "solid": "v"}[kind]])
    assert meta["lattice"] == list(arrays[0].shape[-len(meta["lattice"]):]) and meta["seed"] == 3
    assert meta["morphojax"] == mj.__version__ and meta["format_version"] == FORMAT_VERSION
    assert main(["render", str(path), "--out", str(tmp_path / f"{kind}.png"), "--quiet"]) == 0


@pytest.mark.parametrize("lattice", [[9, 10], [6, 7, 8]])
def test_a_stack_of_automaton_runs_renders_as_a_montage_of_runs(tmp_path, lattice):
    """A preset's stack of runs (one axis more than its lattice, 2D or 3D) is drawn run by
    run, side by side: the same tile as one run's file, twice."""
    from PIL import Image

    from morphojax.cli import main

    runs = np.random.default_rng(2).integers(0, 3, (2, *lattice)).astype(np.int8)
    one = _preset_file(tmp_path / "one.npz", "automaton", {"lattice": lattice}, {"cells": runs[0]})
    two = _preset_file(tmp_path / "two.npz", "automaton", {"lattice": lattice}, {"cells": runs})
    for path in (one, two):
        assert main(["render", str(path), "--out", str(path.with_suffix(".png")), "--quiet"]) == 0
    tile, both = Image.open(one.with_suffix(".png")), Image.open(two.with_suffix(".png"))
    assert 2 * tile.width <= both.width < 3 * tile.width and tile.height <= both.height < 2 * tile.height


@pytest.mark.parametrize("kind, meta_changes, array_changes, field", [
    ("automaton", {"lattice": [9, 11]}, None, "'lattice'"),
    ("automaton", {"lattice": [0, 10]}, None, "'lattice'"),
    ("automaton", {"steps": -4}, None, "'steps'"),
    ("automaton", {"seed": "one"}, None, "'seed'"),
    ("automaton", {"automaton": "Rule110"}, None, "'automaton'"),
    ("automaton", {"params": [{"rates": 1}]}, None, "'params'"),
    ("automaton", None, {"cells": np.full((9, 10), -1, np.int8)}, "state -1|states -1"),
    ("automaton", None, {"cells": np.zeros((9, 10), np.float32)}, "whole numbers"),
    ("potts", {"j_like": [3.0]}, None, "'j_like'"),
    ("potts", {"j_like": [3.0, 16.0]}, None, "'j_like'"),
    ("potts", {"mcs": 2.5}, None, "'mcs'"),
    ("potts", {"lattice": [10, 9]}, None, "'lattice'"),
    ("potts", None, {"types": np.array([0, 1])}, "do not index"),
    ("solid", {"lattice": [6, 7, 9]}, None, "'lattice'"),
    ("solid", {"dt": 0}, None, "'dt'"),
    ("solid", {"steps": True}, None, "'steps'"),
    ("solid", None, {"u": np.zeros((6, 7))}, "field 'u'"),
    ("solid", None, {"v": np.full((6, 7, 8), np.nan)}, "field 'v'"),
])
def test_tampered_preset_files_are_refused_by_name(tmp_path, capsys, kind, meta_changes, array_changes, field):
    """A tampered field is refused by every reader, the API's and `render`'s, naming the file
    and the field, and nothing is drawn."""
    from morphojax.cli import main

    path = _preset_file(tmp_path / "t.npz", kind, meta_changes, array_changes)
    with pytest.raises(ValueError, match=rf"t\.npz is not a morphojax .* file \(.*({field})"):
        _load_preset_file(kind, path)
    assert main(["render", str(path), "--out", str(tmp_path / "t.png")]) == 2
    assert re.search(field, capsys.readouterr().err) and not (tmp_path / "t.png").exists()


@FEW
@given(data=st.data(), kind=st.sampled_from(["automaton", "potts", "solid"]))
def test_damaged_preset_files_raise_one_value_error(tmp_path_factory, data, kind):
    """Damaged bytes of an automaton, Potts or solid file: one ValueError naming the file,
    or, where the damage missed what matters, the same arrays as the good file."""
    good = _preset_file(tmp_path_factory.mktemp("p") / "good.npz", kind)
    bad = _damaged(good, data)
    try:
        got = _load_preset_file(kind, bad)
    except ValueError as err:
        assert "bad.npz" in str(err)
    else:
        np.testing.assert_array_equal(got[0], _load_preset_file(kind, good)[0])


def test_cells_files_are_checked(tmp_path):
    from morphojax.cells._state import make_cells

    cells = make_cells(["a"], np.random.default_rng(0).random((5, 2)), concentration=np.ones((1, 5)), capacity=8)
    good = mj.save_cells(tmp_path / "c.npz", cells, {"seed": 1})
    back, meta = mj.load_cells(good)
    assert int(back.count) == 5 and meta["morphojax"] == mj.__version__ and meta["format_version"] == FORMAT_VERSION
    with np.load(good) as data:
        arrays = {k: data[k] for k in data.files}
    for name, value, match in (("position", np.full((5, 2), np.nan), "NaN"),
                               ("metadata", None, "'capacity'"), ("concentration", np.ones((1, 3)), "shape")):
        tampered = dict(arrays)
        if name == "metadata":
            meta = json.loads(str(arrays["metadata"]))
            meta["capacity"] = 2
            tampered["metadata"] = np.asarray(json.dumps(meta))
        else:
            tampered[name] = value
        np.savez_compressed(tmp_path / "bad.npz", **tampered)
        with pytest.raises(ValueError, match=rf"bad\.npz .*{match}"):
            mj.load_cells(tmp_path / "bad.npz")


# ---- 5. a listing reads only its own files ---------------------------------------------------
def test_listing_reads_only_its_own_folder(tmp_path):
    (tmp_path / "L.txt").write_text("X\nXX\n")
    inside = 'define chemical R\ncreate shape "L.txt"\n'
    assert mj.load_listing(inside, folder=tmp_path).prepattern(jax.random.key(0)).count == 3
    with pytest.raises(ValueError, match="has no folder"):
        mj.load_listing(inside).prepattern(jax.random.key(0))
    (tmp_path / "blank.txt").write_text("  \n")
    with pytest.raises(ValueError, match="'blank.txt' holds no letter"):
        mj.load_listing('define chemical R\ncreate shape "blank.txt"\n', folder=tmp_path).prepattern(jax.random.key(0))
    os.mkfifo(tmp_path / "pipe.txt")
    (tmp_path / "zero.txt").symlink_to("/dev/zero")
    (tmp_path / "big.txt").write_bytes(b"X" * (2 << 20))
    for name, match in (("/etc/passwd", "outside the listing's folder"),
                        ("../../../../etc/hostname", "outside the listing's folder"),
                        ("pipe.txt", "not a regular file"), ("zero.txt", "outside the listing's folder"),
                        ("big.txt", "at most 1048576")):
        with pytest.raises(ValueError, match=match):
            mj.load_listing(f'define chemical R\ncreate shape "{name}"\n', folder=tmp_path).prepattern(
                jax.random.key(0))


@pytest.mark.parametrize("line, match", [
    ("stop at 100000000000000000000", "<= 2147483647"), ("define time_step 1e400", "finite number"),
    ("create sqr_grid 100000 100000", "at most 10000000 cells"), ("create hex_circle 1e9", "at most 10000000"),
    ("texture size 100000 100000", "at most 100000000 pixels"),
])
def test_listing_numbers_it_cannot_hold_are_refused_with_the_line(line, match):
    with pytest.raises(ValueError, match=rf"<text>:2: .*{match}"):
        mj.load_listing(f"define chemical R\n{line}\n")


def _sweep_file(path: Path, changes=None, arrays_changes=None) -> Path:
    """A sweep file of two 8x8 members written by hand (nothing simulated)."""
    from morphojax._serialise import model_to_dict
    from morphojax._files import write_npz

    meta = {"kind": "morphojax.sweep", "names": ["ratio"], "axes": {"ratio": [4.0, 5.0]}, "members": None,
            "config": {"model": model_to_dict(mj.Turing()), "steps": 1, "dt": 0.01, "boundary": "wrap",
                       "shape": [8, 8]},
            "species": ["a", "b"], "seconds": 0.1, "table": [{"member": 0}, {"member": 1}]}
    meta |= changes or {}
    arrays = {"species_a": np.full((2, 8, 8), 4.0, np.float32), "species_b": np.full((2, 8, 8), 4.5, np.float32),
              "value_ratio": np.asarray([4.0, 5.0]), "size": np.full((2, 2), 8), "blowup_step": np.full(2, -1),
              "overflow": np.zeros(2, bool), "change": np.zeros(2)}
    arrays |= arrays_changes or {}
    return write_npz(path, metadata=np.asarray(json.dumps(meta)), **arrays)


def test_sweep_files_round_trip_and_tampered_fields_are_refused(tmp_path):
    back = mj.load_sweep(_sweep_file(tmp_path / "s.npz"))
    assert len(back) == 2 and back.species == ("a", "b")
    for changes, arrays, match in (
            ({"table": [{"member": 0}]}, None, "'table'"), ({"names": [3]}, None, "'names'"),
            ({"species": []}, None, "'species'"), ({"axes": {"ratio": [4.0]}}, None, "'axes'"),
            ({"config": {}}, None, "'config'"), (None, {"blowup_step": np.full(5, -1)}, "'blowup_step'"),
            (None, {"value_ratio": np.asarray([4.0, 5.0, 6.0])}, "do not hold 3 members"),
            (None, {"species_a": np.full((3, 8, 8), 4.0)}, "same shape")):
        bad = _sweep_file(tmp_path / "bad.npz", changes, arrays)
        with pytest.raises(ValueError, match=rf"bad\.npz .*{match}"):
            mj.load_sweep(bad)


def _frames_file(path: Path, meta_changes=None, arrays_changes=None, **kwargs) -> Path:
    """A frames file of four 6x5 snapshots of states 0..2, written by `save_frames`, then its
    JSON and arrays changed by hand (as a damaged or hostile file would be)."""
    frames = (np.arange(4 * 6 * 5).reshape(4, 6, 5) % 3).astype(np.int8)
    path = mj.save_frames(path, frames, np.asarray([0, 5, 10, 15]), states=3, **kwargs)
    if meta_changes or arrays_changes:
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
        meta = json.loads(str(arrays["metadata"]))
        meta |= meta_changes or {}
        arrays |= (arrays_changes or {}) | {"metadata": np.asarray(json.dumps(meta))}
        np.savez_compressed(path, **arrays)
    return path


def test_frames_files_record_version_and_round_trip(tmp_path):
    from morphojax.presets._automaton_outputs import frames_outputs

    frames, steps, meta = mj.load_frames(_frames_file(tmp_path / "f.npz", metadata={"seed": 7}))
    assert frames.shape == (4, 6, 5) and frames.dtype == np.int8 and steps.tolist() == [0, 5, 10, 15]
    assert meta["morphojax"] == mj.__version__ and meta["format_version"] == FORMAT_VERSION
    assert meta["format"] == "morphojax-frames/1" and meta["states"] == 3 and meta["seed"] == 7
    stacked = mj.save_frames(tmp_path / "runs.npz", np.zeros((2, 3, 4, 4), np.int8), [0, 1, 2], frame_axis=1,
                             runs=[{"w2": -0.2}, {"w2": -0.4}])
    assert mj.load_frames(stacked)[2]["runs"] == [{"w2": -0.2}, {"w2": -0.4}]
    # the automata's --frames files are written through it (unfilled snapshots, step -1, left out)
    written = frames_outputs(tmp_path / "ca.png", np.ones((3, 8, 8), np.int8), np.asarray([0, 4, -1]), 2, 1)
    frames, steps, meta = mj.load_frames(written[0])
    assert frames.shape == (2, 8, 8) and steps.tolist() == [0, 4] and meta["states"] == 3
    assert meta["morphojax"] == mj.__version__ and meta["format_version"] == FORMAT_VERSION


@pytest.mark.parametrize("meta_changes, arrays_changes, field", [
    ({"format": "morphojax-cells/1"}, None, "'format'"), ({"count": 5}, None, "'count'"),
    ({"count": -1}, None, "'count'"), ({"count": "4"}, None, "'count'"), ({"frame_axis": 2}, None, "'frame_axis'"),
    ({"frame_axis": True}, None, "'frame_axis'"), ({"shape": [4, 6, 6]}, None, "'shape'"),
    ({"dtype": "float32"}, None, "'dtype'"), ({"states": 2}, None, "'states'"), ({"states": 0}, None, "'states'"),
    ({"runs": [1, 2, 3, 4]}, None, "'runs'"), (None, {"steps": np.asarray([0, 5, 5, 15])}, "'steps' must increase"),
    (None, {"steps": np.asarray([0, 5, 10])}, "'steps' must hold 4 integers"),
    (None, {"steps": np.asarray([-3, 5, 10, 15])}, "'steps' must lie in"),
    (None, {"steps": np.asarray([0, 5, 10, 2**40])}, "'steps' must lie in"),
    (None, {"steps": np.asarray([0.0, 5, 10, 15])}, "'steps' must hold 4 integers"),
    (None, {"frames": np.zeros((3, 6, 5), np.int8)}, "'shape'"),
    (None, {"frames": np.full((4, 6, 5), "a")}, "'frames' holds <U1, not numbers"),
])
def test_tampered_frames_fields_are_refused_by_name(tmp_path, meta_changes, arrays_changes, field):
    path = _frames_file(tmp_path / "t.npz", meta_changes, arrays_changes)
    with pytest.raises(ValueError, match=rf"t\.npz is not a valid morphojax frames file \(.*{field}"):
        mj.load_frames(path)


@FEW
@given(field=st.sampled_from(["format", "count", "frame_axis", "shape", "dtype", "states", "runs"]),
       value=st.one_of(st.none(), st.booleans(), st.integers(-2**40, 2**40), st.text(max_size=12),
                       st.lists(st.integers(-3, 10), max_size=4), st.floats(allow_nan=False)))
def test_any_other_frames_metadata_value_is_refused_or_consistent(tmp_path_factory, field, value):
    """Every metadata field of a frames file is checked against the others and the arrays: any
    other value is refused naming the file (and a field or array), or is one the arrays agree
    with (only `states` has such values: any whole number above the largest cell value)."""
    good = {"format": "morphojax-frames/1", "count": 4, "frame_axis": 0, "shape": [4, 6, 5], "dtype": "int8",
            "states": 3}
    if field in good and value == good[field] and type(value) is type(good[field]):
        return
    path = _frames_file(tmp_path_factory.mktemp("frames") / "h.npz", {field: value})
    consistent = field == "states" and isinstance(value, int) and not isinstance(value, bool) and value >= 3
    try:
        mj.load_frames(path)
    except ValueError as err:
        assert not consistent and "h.npz is not a valid morphojax frames file" in str(err)
        assert "metadata field" in str(err) or "its array" in str(err)
    else:
        assert consistent, (field, value)


def test_frames_files_from_newer_versions_warn_and_damaged_ones_are_refused(tmp_path):
    path = _frames_file(tmp_path / "new.npz", {"morphojax": "99.0.0"})
    with pytest.warns(UserWarning, match=rf"morphojax 99.0.0, newer than this morphojax {mj.__version__}"):
        mj.load_frames(path)
    path = _frames_file(tmp_path / "fmt.npz", {"format_version": FORMAT_VERSION + 1})
    with pytest.warns(UserWarning, match="file format 2"):
        mj.load_frames(path)
    raw = _frames_file(tmp_path / "raw.npz").read_bytes()
    for name, content in (("cut.npz", raw[: len(raw) // 2]), ("empty.npz", b""), ("flipped.npz", raw[:200] + bytes(
            b ^ 0x5A for b in raw[200:260]) + raw[260:])):
        (tmp_path / name).write_bytes(content)
        with pytest.raises(ValueError, match=rf"{name.replace('.', '[.]')}"):
            mj.load_frames(tmp_path / name)
    np.savez(tmp_path / "bare.npz", frames=np.zeros((2, 3, 3)), steps=np.arange(2))  # no metadata: not trusted
    with pytest.raises(ValueError, match=r"bare\.npz is not a morphojax frames file \(no 'metadata' entry\)"):
        mj.load_frames(tmp_path / "bare.npz")
    with pytest.raises(ValueError, match="'steps' must increase"):  # refused before anything is written
        mj.save_frames(tmp_path / "never.npz", np.zeros((2, 3, 3)), [4, 1])
    assert not (tmp_path / "never.npz").exists()


# ---- 4 and 6. nothing silently changed; checked before the work, cleaned after it ------------
def test_out_folder_and_unwritable_outputs_are_refused_before_the_work(tmp_path, capsys, monkeypatch):
    from morphojax.cli import main
    from morphojax.cli._output import out_arg, picture_path

    monkeypatch.chdir(tmp_path)
    assert picture_path(out_arg("o/"), "ca") == Path("o") / "ca.png" and (tmp_path / "o").is_dir()
    assert picture_path(out_arg("pic"), "ca") == Path("pic.png")
    (tmp_path / "afile").write_text("")
    sweep = ["sweep", "--model", "turing", "--vary", "ratio=4,5", "--shape", "8", "8", "--steps", "1"]
    assert main(sweep + ["--out", "afile/s.png"]) == 2
    assert "afile is a file, not a folder" in capsys.readouterr().err
    fit = ["fit", str(tmp_path / "p.png"), "--model", "turing", "--json", "r.json"]
    for extra, match in ((["--fixed", "ratio=-3"], r"--fixed: Turing.ratio .* must lie in \[0, \+inf\)"),
                         (["--preview", "r.json"], "two outputs have the same path"),
                         (["--preview", "afile/p.png"], "afile is a file")):
        assert main(fit + extra) == 2, extra
        assert __import__("re").search(match, capsys.readouterr().err), extra
    for gif, match in (("afile/y.gif", "afile is a file"), ("y.png", "--gif must end in one of .gif, .mp4")):
        assert main(["run", "fig4-r6", "--quick", "--out", "r.png", "--gif", gif]) == 2, gif  # before the run
        assert match in capsys.readouterr().err, gif
        assert not (tmp_path / "r.npz").exists(), gif


def test_an_unwritable_folder_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    """A folder the user cannot write (as root every folder is writable, so the permission
    check is made to say no) is refused by name before the sweep runs."""
    import morphojax._files
    from morphojax.cli import main

    locked = tmp_path / "locked"
    locked.mkdir()
    real_access = os.access
    monkeypatch.setattr(morphojax._files.os, "access", lambda p, mode: Path(p) != locked and real_access(p, mode))
    monkeypatch.setattr(mj, "sweep", _no_grid)  # refused before any member runs
    sweep = ["sweep", "--model", "turing", "--vary", "ratio=4,5", "--shape", "8", "8", "--steps", "1"]
    assert main(sweep + ["--out", str(locked / "s.png")]) == 2
    assert f"cannot write {locked / 's.png'}: the folder {locked} is not writable" in capsys.readouterr().err
    with pytest.raises(ValueError, match="is not writable"):
        mj.save_npz(locked / "r.npz", mj.State.from_arrays([np.zeros((4, 4))]), {})


def test_cell_constructors_refuse_sizes_beyond_memory_before_allocating():
    """A grid, a disc or a capacity past the memory limit is a ValueError saying how much it
    needs, at once (before: a raw MemoryError, after 83 s for `cell_disc(1e9)`)."""
    import morphojax.cells as mc

    for build in (lambda: mc.cell_grid((100_000, 100_000), ["u"]), lambda: mc.cell_disc(1e9, ["u"]),
                  lambda: mc.cell_disc(float("inf"), ["u"]), lambda: mc.cells_at([[0.0, 0.0]], ["u"], capacity=10**10)):
        t0 = time.perf_counter()
        with pytest.raises(ValueError, match=r"needs about .* GB; the limit is"):
            build()
        assert time.perf_counter() - t0 < 5
    assert int(mc.cell_grid((6, 5), ["u", "v"]).count) == 30  # ordinary sizes build as before


def test_the_fit_api_refuses_what_it_can_check_before_fitting():
    """`fitting.fit` itself (not only the command line) refuses a fixed value the model
    refuses, a step count past the step counter and a fractional shape before any
    simulation: the same checks as `morphojax fit`, each naming the keyword."""
    import fitting

    target = np.random.default_rng(0).random((32, 32))
    for kwargs, match in (({"fixed": {"ratio": -3}}, r"^fixed: Turing.ratio .* must lie in \[0, \+inf\)"),
                          ({"steps": 2**31 + 5}, r"^steps must lie in \[0, 2147483647\]"),
                          ({"shape": (2.5, 3)}, r"^shape must hold whole numbers")):
        with pytest.raises(ValueError, match=match):
            fitting.fit(target, "turing", progress=False, **kwargs)


def test_files_get_the_umask_and_killed_writes_are_cleaned(tmp_path):
    from morphojax._files import write_npz

    old = os.umask(0o027)
    try:
        dead = tmp_path / ".r.999999999-abc.npz"  # a write whose process is gone
        dead.write_bytes(b"half")
        alive = tmp_path / f".r.{os.getppid()}-abc.npz"  # one still being written by a live process
        alive.write_bytes(b"half")
        path = write_npz(tmp_path / "r.npz", a=np.ones(3))
        assert (path.stat().st_mode & 0o777) == 0o640
        assert not dead.exists() and alive.exists()
    finally:
        os.umask(old)
    with pytest.raises(ValueError, match="is a file, not a folder"):
        write_npz(path / "x.npz", a=np.ones(1))


def test_simulate_refuses_steps_past_the_int32_step_counter():
    state = mj.paper_state(jax.random.key(0), (6, 6))
    with pytest.raises(ValueError, match="step counter within int32"):
        mj.simulate(mj.Turing(), state, 2**31 + 5, 0.01)


def test_python_api_refuses_automaton_and_potts_lattices_beyond_memory(monkeypatch):
    """The sizes the command line checks are checked in the Python API too, before any
    allocation: a lattice start, an automaton run, a Potts blob."""
    monkeypatch.setenv("MORPHOJAX_MAX_MEMORY", "1G")
    with pytest.raises(ValueError, match=r"lattice of 3000x3000x3000 cells .* needs about .*; the limit is 1"):
        mj.random_cells(jax.random.key(0), (3000, 3000, 3000), k=2)
    with pytest.raises(ValueError, match="whole numbers"):
        mj.random_cells(jax.random.key(0), (10.5, 10))
    with pytest.raises(ValueError, match=r"Potts lattice of 200000x200000 sites .* needs about"):
        mj.potts_blob((200_000, 200_000), 40, 5)
    monkeypatch.setenv("MORPHOJAX_MAX_MEMORY", "1M")  # a 200^2 run of 3 states needs about 8 MB
    cells = np.zeros((200, 200), np.int8)
    with pytest.raises(ValueError, match=r"automaton run \(200x200 cells, 3 states\) needs about"):
        mj.YoungCA([(2.3, 6.01, 1.0, -0.3), (2.3, 6.01, 1.0, -0.3)]).run(cells, 1)


# ---- 1 (continued). a sweep's size in the Python API, not only on the command line ---------------
def _no_grid(*args, **kwargs):
    raise AssertionError("the sweep built its members (or ran them) before checking its size")


@FEW
@given(counts=st.lists(st.integers(1, 1000), min_size=1, max_size=3), side=st.integers(1, 3000),
       listed=st.booleans())
def test_python_sweep_sizes_are_refused_before_the_grid_is_built(monkeypatch, counts, side, listed):
    """`mj.sweep` refuses, from the counts alone, a sweep whose members need more memory than
    the limit (the estimate `check_run_size` makes for the command line), naming `vary` and
    stating the estimate; what passes goes on to the next check (here: no `key`, so nothing runs)."""
    monkeypatch.setenv("MORPHOJAX_MAX_MEMORY", "64M")
    names = ["ratio", "upper_a", "lower_a"][:len(counts)]
    members = int(np.prod(counts, dtype=object))
    if listed and members <= 10**5:  # a list of parameter sets: one member per set (the list is the user's)
        counts, names, vary = [members], names[:1], [{"ratio": 4.0}] * members
    else:
        vary = {name: np.linspace(4.0, 5.0, count) for name, count in zip(names, counts)}
    cells = side * side * 2
    needed = cells * (64 * min(members, 64) + 16 * members)
    with monkeypatch.context() as patch, pytest.raises(ValueError) as err:
        if needed > 64 * 2**20:
            patch.setattr(np, "meshgrid", _no_grid)
        mj.sweep(mj.Turing(), vary, shape=(side, side), key=None, dt=0.01, steps=10)
    if needed > 64 * 2**20:
        assert f"sweep: vary gives {members} members (" in str(err.value)
        assert f"each 2 species on {side}x{side} cells; this sweep needs about" in str(err.value)
        assert "the limit is 67.1 MB" in str(err.value)
    else:
        assert "give a shared initial `state`" in str(err.value)


def test_python_sweep_member_count_and_steps_are_checked_against_the_counters(monkeypatch):
    monkeypatch.setattr(np, "meshgrid", _no_grid)  # 2^32 members: the grid alone would need 68 GB
    with pytest.raises(ValueError, match=r"vary gives 4294967296 members \(ratio x upper_a = 65536 x 65536\); a sweep "
                                         r"has at most 2147483647 members"):
        mj.sweep(mj.Turing(), {"ratio": range(2**16), "upper_a": range(2**16)}, shape=(4, 4), key=0, dt=0.01)
    with pytest.raises(ValueError, match="sweep: steps must keep the step counter within int32"):
        mj.sweep(mj.Turing(), {"ratio": [4.0, 5.0]}, shape=(4, 4), key=0, dt=0.01, steps=2**31 + 5)
    with pytest.raises(ValueError, match=r"sweep: shape must hold whole numbers, not 16.5"):
        mj.sweep(mj.Turing(), {"ratio": [4.0, 5.0]}, shape=(16.5, 16), key=0, dt=0.01)
    for dt, match in ((float("nan"), "sweep.dt must not be NaN"), (-0.01, r"sweep.dt must lie in \(0, \+inf\)")):
        with pytest.raises(ValueError, match=match):  # before any member runs
            mj.sweep(mj.Turing(), {"ratio": [4.0, 5.0]}, shape=(4, 4), key=0, dt=dt, steps=1)


def test_cli_numbers_are_refused_up_front_and_bounds_read_in_full(tmp_path, capsys):
    """`sweep --dt nan` is refused before the sweep (it used to run, then fail formatting the
    table) and a step count past the counter shows its bound in full, not as 2.14748e+09."""
    from morphojax.cli import main

    sweep = ["sweep", "--model", "turing", "--vary", "ratio=4,5", "--shape", "8", "8", "--steps", "1", "--no-progress",
             "--out", str(tmp_path / "s.png")]
    for dt in ("nan", "inf", "0"):
        assert main(sweep + ["--dt", dt]) == 2
        assert f"--dt must be a finite number > 0 (got {float(dt)})" in capsys.readouterr().err
    assert main(["ca", "--steps", "2147483653", "--out", str(tmp_path / "c.png")]) == 2
    assert "--steps must lie in [0, 2147483647] (got 2147483653)" in capsys.readouterr().err


def test_python_sweep_states_and_parameter_maps_are_sized_before_the_run(monkeypatch):
    """The issue's own wording, for a shared start given as a State, a capacity, and a map."""
    import morphojax._sweep

    monkeypatch.setenv("MORPHOJAX_MAX_MEMORY", "12G")
    monkeypatch.setattr(morphojax._sweep, "run_batched", _no_grid)  # refused before the run, not by it
    state = mj.State.from_arrays([np.full((500, 500), 4.0), np.full((500, 500), 4.5)])
    with pytest.raises(ValueError, match=r"sweep: vary gives 4000 members \(ratio\), each 2 species on 500x500 cells; "
                                         r"this sweep needs about 34 GB; the limit is 12.9 GB"):
        mj.sweep(mj.Turing(), {"ratio": np.linspace(4, 40, 4000)}, state=state, dt=0.01, steps=10)
    with pytest.raises(ValueError, match=r"on 2000x2000 cells; this sweep needs about"):  # the capacity, not the shape
        mj.sweep(mj.Turing(), {"ratio": np.linspace(4, 40, 400)}, shape=(8, 8), capacity=(2000, 2000), key=0,
                 dt=0.01, steps=10)
    with pytest.raises(ValueError, match=r"parameter_map: shape 1000000x1000000 with 2 species and 1 parameter "
                                         r"map\(s\); this run needs about"):
        mj.parameter_map(mj.Turing(), (10**6, 10**6), x=("ratio", 4.0, 40.0))
    with pytest.raises(ValueError, match=r"parameter_map: shape must hold whole numbers, not 16.5"):
        mj.parameter_map(mj.Turing(), (16.5, 16), x=("ratio", 4.0, 40.0))
    assert mj.parameter_map(mj.Turing(), (4, 6), x=("ratio", 4.0, 40.0)).ratio.shape == (4, 6)

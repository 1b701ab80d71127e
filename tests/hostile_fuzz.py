"""The hostile inputs behind benchmarks/results/hostile.md (issue 35), run as a script:

    MORPHOJAX_MAX_MEMORY=2G python tests/hostile_fuzz.py [N]

Each class generates N inputs (default 40) from a fixed seed, feeds each to the loader or
command that takes it, and counts the outcomes: "refused" (one ValueError naming the file or
flag), "read" (a valid object came back: the damage missed every byte that matters), "other"
(any other exception: a bug). The CLI cases also count exit codes and tracebacks. Nothing is
simulated: every refusal comes before the work. Not collected by pytest (no `test_` prefix);
`test_hostile.py` holds the same classes as tests at a smaller size.
"""

from __future__ import annotations

import collections
import contextlib
import io
import json
import os
import random
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

import morphojax as mj
from morphojax._serialise import load_npz, save_npz

ROOT = Path(tempfile.mkdtemp(prefix="hostile-"))
RNG = random.Random(35)


def outcome(fn, name: str) -> str:
    try:
        fn()
    except ValueError as err:
        return "refused" if name in str(err) or "needs about" in str(err) else "refused (file not named)"
    except Exception as err:  # noqa: BLE001 - counting what escapes is the point
        return f"other: {type(err).__name__}: {str(err)[:80]}"
    return "read"


def damaged(raw: bytes) -> bytes:
    how = RNG.choice(["truncate", "flip", "random", "empty", "append", "zero-run"])
    b = bytearray(raw)
    if how == "truncate":
        return bytes(b[:RNG.randrange(len(b))])
    if how == "flip":
        for _ in range(RNG.randint(1, 16)):
            b[RNG.randrange(len(b))] ^= RNG.randrange(1, 256)
        return bytes(b)
    if how == "random":
        return RNG.randbytes(RNG.randint(1, 4096))
    if how == "empty":
        return b""
    if how == "zero-run":
        at = RNG.randrange(len(b))
        b[at:at + 64] = bytes(min(64, len(b) - at))
        return bytes(b)
    return bytes(b) + RNG.randbytes(RNG.randint(1, 64))


def result_file(path: Path, experiment: bool = True) -> Path:
    state = mj.State.from_arrays([np.full((32, 32), 4.0), np.full((32, 32), 4.5)], names=("a", "b"))
    meta = {}
    if experiment:
        meta = {"experiment": mj.preset("fig4-r4.2", quick=True).to_dict(),
                "run": {"seed": 0, "phase": 0, "phase_step": 0, "phase_origin": None}}
    return save_npz(path, state, meta)


def header_bomb(path: Path) -> Path:
    shape = tuple(RNG.choice([10**4, 10**6, 10**9]) for _ in range(RNG.randint(1, 3)))
    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(head, {"descr": RNG.choice(["<f4", "<f8", "|u1"]), "fortran_order": False,
                                                "shape": shape})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(RNG.choice(["species_a.npy", "cells.npy", "metadata.npy"]), head.getvalue() + b"\0" * 128)
    return path


TAMPER = [("run", "phase", 99), ("run", "phase", -1), ("run", "phase_step", -5), ("run", "phase_step", 10**6),
          (None, "step", -1), (None, "step", 2**40), (None, "capacity", [8, 8]), (None, "size", [16, 32]),
          (None, "species", "ab"), (None, "species", [1, 2]), (None, "run", None), (None, "time", "nan"),
          ("run", "seed", "zero"), ("run", "phase_origin", -3), (None, "experiment", {"phases": []}),
          (None, "species", ["a", "a"])]


def tampered(path: Path, where, field, value) -> Path:
    with np.load(result_file(path)) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays["metadata"]))
    (meta[where] if where else meta)[field] = value
    arrays["metadata"] = np.asarray(json.dumps(meta))
    np.savez_compressed(path, **arrays)
    return path


MESH = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
MESH_VARIANTS = [MESH.replace("v 0 0 1", "v nan 0 1"), MESH.replace("v 0 0 1", "v inf 0 1"), MESH + "f 1 2 9\n",
                 "v 5 5 5\n" + MESH.replace("f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4", "f 2 4 3\nf 2 3 5\nf 2 5 4\nf 3 4 5"),
                 ("# Ren\xe9\n" + MESH), MESH + "f 1 2\n", MESH.replace("f 1 3 2", "f 1 1 2")]


def cli(argv) -> tuple[int, bool]:
    from morphojax.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exit_:
            code = exit_.code if isinstance(exit_.code, int) else 1
        except Exception:  # noqa: BLE001 - what the program would print as a traceback
            return 1, True
    return code, "Traceback" in err.getvalue()


CLI_SIZES = [
    ["run", "fig4-r4.2", "--scale", "100000"], ["run", "fig4-r4.2", "--scale", "0"],
    ["run", "fig4-r4.2", "--scale", "-2"], ["ca", "--dim", "3", "--size", "3000"], ["ca", "--size", "10000000"],
    ["ca", "--steps", str(2**31 + 5)],
    ["sweep", "--model", "turing", "--vary", "ratio=4:40:2", "--shape", "50000", "50000", "--out", "s.png"],
    ["sweep", "--model", "turing", "--vary", "ratio=4:40:1000000", "--out", "s.png"],
    ["sweep", "--model", "turing", "--vary", "ratio=4:40:1000000000000", "--out", "s.png"],
    ["sweep", "--model", "turing", "--vary", "ratio=4:40:1000", "--vary", "scale=1:2:1000", "--out", "s.png"],
    ["sweep", "--model", "turing", "--vary", "ratio=4:40:2", "--steps", str(2**31 + 5), "--out", "s.png"],
    ["sweep", "--model", "turing", "--vary", "ratio=4:40:2", "--shape", "0", "5", "--out", "s.png"],
    ["sweep", "--model", "turing", "--vary", "ratio=4:40:2", "--scale", "0", "--out", "s.png"],
]


BEFORE = os.environ.get("HOSTILE_BEFORE") == "1"  # an older tree: skip what would crash or hang the machine


def listing(text, folder):
    try:
        return mj.load_listing(text, folder=folder)
    except TypeError:  # before `folder=` existed
        return mj.load_listing(text, directory=folder)


def main(n: int = 40) -> dict:
    table = collections.defaultdict(collections.Counter)
    good = result_file(ROOT / "good.npz").read_bytes()
    for k in range(n):
        p = ROOT / f"damaged{k}.npz"
        p.write_bytes(damaged(good))
        table["damaged result npz (truncated, flipped, random, empty, appended)"][outcome(lambda: load_npz(p),
                                                                                          p.name)] += 1
        q = header_bomb(ROOT / f"claims{k}.npz")
        table["npz member header claiming 10^4..10^27 elements"][outcome(lambda: load_npz(q), q.name)] += 1
    bomb = ROOT / "bomb.npz"
    if BEFORE:
        n_bomb = 0
    else:
        n_bomb = 1
    if n_bomb:
        with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as zf, zf.open("cells.npy", "w", force_zip64=True) as f:
            np.lib.format.write_array_header_1_0(f, {"descr": "|u1", "fortran_order": False, "shape": (3_200_000_000,)})
            for _ in range(49):
                f.write(bytes(64 << 20))
        table["npz of 3 MB expanding to 3.2 GB"][outcome(lambda: mj.load_npz(bomb), bomb.name)] += 1
    for where, field, value in TAMPER:
        p = tampered(ROOT / f"t_{field}.npz", where, field, value)
        table["result metadata tampered (16 fields)"][outcome(lambda: load_npz(p), p.name)] += 1
    for k in range(n):
        for fmt in ("obj", "stl", "off", "ply"):
            p = ROOT / f"mesh{k}.{fmt}"
            p.write_bytes(damaged(MESH.encode()) if k % 2 else RNG.randbytes(RNG.randint(0, 2048)))
            table["random or damaged mesh bytes (OBJ, STL, OFF, PLY)"][outcome(lambda: mj.Mesh.from_file(p),
                                                                               p.name)] += 1
    for k, text in enumerate(MESH_VARIANTS):
        p = ROOT / f"variant{k}.obj"
        p.write_bytes(text.encode("latin-1"))
        table["OBJ with NaN/inf vertex, bad index, unused vertex, Latin-1 byte, 2-corner or repeated face"][
            outcome(lambda: mj.Mesh.from_file(p), p.name)] += 1
    from PIL import Image

    import fitting

    png = ROOT / "good.png"
    Image.fromarray((np.arange(96 * 96).reshape(96, 96) % 251).astype(np.uint8)).save(png)
    for k in range(n):
        p = ROOT / f"img{k}.png"
        p.write_bytes(damaged(png.read_bytes()))
        table["damaged or random PNG (fitting.load_target)"][outcome(
            lambda: fitting.load_target(p, cell_pixels=2.0), p.name)] += 1
    for special in ("/dev/zero", str(ROOT)):
        for label, fn in (("result", mj.load_npz), ("sweep", mj.load_sweep), ("cells", mj.load_cells),
                          ("mesh", lambda s: mj.Mesh.from_file(Path(s) / "x.obj" if Path(s).is_dir() else s + ".obj")),
                          ("listing", lambda s: mj.load_listing(Path(s)))):
            table["/dev/zero, a folder, a pipe as any file kind"][outcome(lambda: fn(special), "")] += 1
    fifo = ROOT / "pipe.npz"
    os.mkfifo(fifo)
    for fn in () if BEFORE else (mj.load_npz, mj.load_sweep, mj.load_cells):  # before: blocks forever
        table["/dev/zero, a folder, a pipe as any file kind"][outcome(lambda: fn(fifo), "")] += 1
    (ROOT / "L.txt").write_text("X\n")
    names = ("/etc/passwd", "../../../../etc/hostname", "L.txt") + (() if BEFORE else ("pipe.npz", "/dev/zero"))
    for name in names:  # before: the pipe blocked forever and /dev/zero ran out of memory
        for folder in (None, ROOT):
            text = f'define chemical R\ncreate shape "{name}"\n'
            table["listing `create shape` outside its folder, a pipe, a device, no folder"][
                outcome(lambda: listing(text, folder).prepattern(__import__("jax").random.key(0)),
                        "")] += 1
    for line in ("stop at 100000000000000000000", "define time_step 1e400", "create sqr_grid 100000 100000",
                 "create hex_circle 1e9", "texture size 100000 100000", "set cell 99999999999 chemical R conc 1"):
        table["listing numbers it cannot hold"][outcome(lambda: mj.load_listing(f"define chemical R\n{line}\n"),
                                                        "<text>")] += 1
    (ROOT / "big.txt").write_bytes(b"X" * (8 << 20))
    table["listing `create shape` outside its folder, a pipe, a device, no folder"][outcome(
        lambda: listing('define chemical R\ncreate shape "big.txt"\n', ROOT).prepattern(
            __import__("jax").random.key(0)), "")] += 1
    os.chdir(ROOT)
    for argv in [] if BEFORE else CLI_SIZES:
        code, traceback = cli(argv)
        table["CLI sizes (--scale, --size/--dim, --shape, --vary counts, --steps)"][
            f"exit {code}{' with traceback' if traceback else ''}"] += 1
    for k in range(n):  # render (resume of a file that reads would run its experiment)
        code, traceback = cli(["render", str(ROOT / f"damaged{k}.npz"), "--out", "r.png"])
        table["CLI render of damaged results"][f"exit {code}{' with traceback' if traceback else ''}"] += 1
    for where, field, value in TAMPER:
        code, traceback = cli(["resume", str(ROOT / f"t_{field}.npz")])
        table["CLI resume of tampered checkpoints (phase 99, ...)"][
            f"exit {code}{' with traceback' if traceback else ''}"] += 1
    later_classes(table, n)
    return table


FRAMES_TAMPER = [("format", "morphojax-cells/1"), ("count", 5), ("count", -1), ("frame_axis", 2), ("shape", [4, 6, 6]),
                 ("dtype", "float32"), ("states", 2), ("runs", [1, 2]), ("steps", [0, 5, 5, 15]),
                 ("steps", [0, 5, 10]), ("steps", [-3, 5, 10, 15]), ("steps", [0, 5, 10, 2**40])]


def frames_file(path: Path, field=None, value=None) -> Path:
    """Four 6x5 snapshots of states 0..2 (`mj.save_frames`), with one metadata field or the
    steps array changed by hand."""
    path = mj.save_frames(path, (np.arange(120).reshape(4, 6, 5) % 3).astype(np.int8), [0, 5, 10, 15], states=3)
    if field is not None:
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
        meta = json.loads(str(arrays["metadata"]))
        if field == "steps":
            arrays["steps"] = np.asarray(value)
        else:
            meta[field] = value
        arrays["metadata"] = np.asarray(json.dumps(meta))
        np.savez_compressed(path, **arrays)
    return path


SWEEP_SIZES = [  # the Python API's sweeps and maps beyond the limit or the counters (run after the fixes only)
    {"vary": {"ratio": np.linspace(4, 40, 10**6)}, "shape": (50, 50)},
    {"vary": {"ratio": np.arange(2.0**16), "upper_a": np.arange(2.0**16)}, "shape": (4, 4)},
    {"vary": [{"ratio": 4.0}] * 10**5, "shape": (500, 500)}, {"vary": {"ratio": [4.0, 5.0]}, "shape": (50000, 50000)},
    {"vary": {"ratio": [4.0, 5.0]}, "shape": (8, 8), "capacity": (10**5, 10**5)},
    {"vary": {"ratio": [4.0, 5.0]}, "shape": (16.5, 16)},
    {"vary": {"ratio": [4.0, 5.0]}, "shape": (8, 8), "steps": 2**31 + 5},
]


def later_classes(table, n: int) -> None:
    """The classes added after the first table: frames files, 16-bit PNGs, the Python sweep."""
    # the 16-bit PNG writer of the tests (Pillow writes 16-bit grey only)
    from test_hostile import _png16

    import fitting

    if hasattr(mj, "load_frames"):
        good = frames_file(ROOT / "frames.npz").read_bytes()
        for k in range(n):
            p = ROOT / f"frames{k}.npz"
            p.write_bytes(damaged(good))
            table["damaged frames `.npz` (`mj.load_frames`)"][outcome(lambda: mj.load_frames(p), p.name)] += 1
        for field, value in FRAMES_TAMPER:
            p = frames_file(ROOT / f"ft_{field}.npz", field, value)
            table["frames metadata or steps tampered (12)"][outcome(lambda: mj.load_frames(p), p.name)] += 1
    for k in range(n):  # contrast below 8 bits: the high bytes of both stripes are equal
        bands = k % 4 + 1
        base = RNG.randrange(0, 65535 - 512) & ~0xFF
        low, high = base + RNG.randrange(0, 64), base + RNG.randrange(128, 256)
        stripes = np.tile(np.where(np.arange(48) % 12 < 6, low, high).astype(np.uint16), (48, 1))
        samples = np.stack([stripes] * bands, axis=-1)
        if bands in (2, 4):
            samples[..., -1] = 65535
        p = _png16(ROOT / f"deep{k}.png", samples[..., 0] if bands == 1 else samples, interlace=bool(k % 3 == 0))
        table["16-bit PNG (grey, grey+alpha, RGB, RGBA) with contrast below 8 bits (`fitting.load_target`)"][
            outcome(lambda: fitting.load_target(p, cell_pixels=2.0), p.name)] += 1
        q = ROOT / f"deepcut{k}.png"
        q.write_bytes(damaged(p.read_bytes()))
        table["damaged 16-bit PNG (`fitting.load_target`, `Gradient.from_photo`)"][
            outcome(lambda: fitting.load_target(q, cell_pixels=2.0), q.name)] += 1
        table["damaged 16-bit PNG (`fitting.load_target`, `Gradient.from_photo`)"][
            outcome(lambda: mj.Gradient.from_photo(q), q.name)] += 1
    for kwargs in [] if BEFORE else SWEEP_SIZES:  # before: a grid of 2^32 members, a 10^5-member run
        kw = {"key": 0, "dt": 0.01, "steps": 10} | kwargs
        table["Python `mj.sweep` sizes (10^6 members, a 2^32-member grid, 10^5 sets, huge shapes, 16.5, steps)"][
            outcome(lambda: mj.sweep(mj.Turing(), **kw), "sweep")] += 1
    if not BEFORE:
        for shape in ((10**6, 10**6), (16.5, 16)):
            table["Python `mj.sweep` sizes (10^6 members, a 2^32-member grid, 10^5 sets, huge shapes, 16.5, steps)"][
                outcome(lambda: mj.parameter_map(mj.Turing(), shape, x=("ratio", 4.0, 40.0)), "parameter_map")] += 1


if __name__ == "__main__":
    results = main(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
    print("| class | inputs | outcomes |\n|---|---:|---|")
    for name, counts in results.items():
        print(f"| {name} | {sum(counts.values())} | " + "; ".join(f"{v} {k}" for k, v in counts.most_common()) + " |")

"""Cellular-automaton presets (`morphojax run young-fig8`) and the `morphojax ca` command.

Every preset run writes, next to its PNG `out`: `out.npz` with the final cells and a
JSON `metadata` entry holding every parameter (automaton, lattice, initial condition,
seed, steps), meshes per species for 3D lattices (`out_species{j}.ply`) and, with
`frames=True`, the snapshots (`out_frames.npz` and `out_frames.png`). The same seed
gives the same output. Each preset has a `quick` variant that runs in seconds: smaller
lattices, same rules.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path
from typing import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from ._automata import (YOUNG_P, YoungCA, order_parameter, random_cells, volume_fractions,
                        weighted_volume_difference)
from ._automata_io import cells_image, slice_montage, write_species_meshes
from ._checks import check_range
from ._life import LifeLike, glider
from ._render import montage


@dataclasses.dataclass(frozen=True)
class CAPreset:
    """A named automaton experiment: `run(seed, quick, out, frames) -> summary dict`."""

    name: str
    description: str
    figure: str
    runner: Callable = dataclasses.field(repr=False)

    def run(self, seed: int = 0, quick: bool = False, out=None, frames: bool = False) -> dict:
        out = Path(out) if out is not None else Path(f"{self.name}.png")
        out = out if out.suffix.lower() == ".png" else out.with_suffix(".png")
        out.parent.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        summary = self.runner(int(seed), bool(quick), out, bool(frames))
        summary["seconds_total"] = round(time.perf_counter() - t0, 3)
        return {"preset": self.name, **summary}


PRESETS: dict[str, CAPreset] = {}


def _preset(name, description, figure):
    def deco(fn):
        PRESETS[name] = CAPreset(name, description, figure, fn)
        return fn

    return deco


# ---- shared plumbing -------------------------------------------------------------------
def _stats(cells, k) -> dict:
    return {"volume_fractions": [round(float(v), 5) for v in np.asarray(volume_fractions(cells, k))],
            "order_parameter": [round(float(v), 5) for v in np.asarray(order_parameter(cells, k))]}


def _timed_run(ca, cells, steps, **kwargs):
    t0 = time.perf_counter()
    result = ca.run(cells, steps, **kwargs)
    jax.block_until_ready(result.cells)
    return result, time.perf_counter() - t0


def _save_npz(out: Path, cells, metadata: dict, **arrays) -> Path:
    path = out.with_suffix(".npz")
    np.savez_compressed(path, cells=np.asarray(cells), metadata=json.dumps(metadata), **arrays)
    return path


def _picture(cells, k, scale, title=None) -> Image.Image:
    cells = np.asarray(cells)
    if cells.ndim == 2:
        return cells_image(cells, k, scale)
    if cells.ndim == 3:
        return slice_montage(cells, k, n=8, scale=scale, title=title)
    raise ValueError(f"pictures need a 2D or 3D lattice (got shape {cells.shape})")


def _frames_outputs(out: Path, frames, frame_steps, k, scale) -> list[str]:
    frames, frame_steps = np.asarray(frames), np.asarray(frame_steps)
    keep = frame_steps >= 0
    frames, frame_steps = frames[keep], frame_steps[keep]
    npz = out.with_name(out.stem + "_frames.npz")
    np.savez_compressed(npz, frames=frames, steps=frame_steps)
    mid = [f if f.ndim == 2 else f[f.shape[0] // 2] for f in frames]
    png = out.with_name(out.stem + "_frames.png")
    montage([cells_image(f, k, scale) for f in mid], min(len(mid), 6),
            col_labels=None, title="t = " + ", ".join(map(str, frame_steps))).save(png)
    return [str(npz), str(png)]


def run_automaton(ca: YoungCA, shape, *, p=None, steps: int, stop: bool, seed: int, out: Path, frames: bool,
                  threshold: float = 0.01, scale: int | None = None, extra: dict | None = None) -> dict:
    """One Young automaton run from `random_cells(key(seed), shape, K, p)` with every output
    written next to `out`; returns the summary."""
    k = ca.n_species
    cells0 = random_cells(jax.random.key(seed), shape, k, p)
    save_every = max(1, min(steps, 40) // 10) if frames else None
    result, seconds = _timed_run(ca, cells0, steps, stop_at_convergence=stop, threshold=threshold,
                                 save_every=save_every, history=True)
    n = int(result.steps)
    summary = {"steps": n, "converged": bool(result.converged), "lattice": list(shape),
               **_stats(result.cells, k), "seconds_run": round(seconds, 3),
               "changed_last": float(np.asarray(result.changes)[n - 1]) if n else None}
    metadata = {"automaton": "YoungCA", "params": ca.to_dict(), "lattice": list(shape), "seed": seed,
                "initial": {"p": p, "kind": "uniform over K+1 states" if p is None else "differentiated with probability p"},
                "steps": steps, "stop_at_convergence": stop, "threshold": threshold, "summary": summary,
                **(extra or {})}
    scale = scale or (3 if len(shape) == 3 else max(1, 400 // max(shape)))
    _picture(result.cells, k, scale, title=f"t = {n}").save(out)
    files = [str(out), str(_save_npz(out, result.cells, metadata, changes=np.asarray(result.changes)))]
    if len(shape) == 3:
        files += [str(p) for p in write_species_meshes(result.cells, k, out.with_suffix(""))]
    if frames:
        files += _frames_outputs(out, result.frames, result.frame_steps, k, scale)
    summary["files"] = files
    return summary


def line_chart(series: dict, width: int = 480, height: int = 300, title: str = "", ylim=(0.0, 1.0)) -> Image.Image:
    """A minimal line chart (pillow only): one polyline per labelled series over its index."""
    img = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default()
    left, right, top, bottom = 40, width - 110, 20, height - 30
    draw.rectangle([left, top, right, bottom], outline="black")
    n = max(len(v) for v in series.values())
    lo, hi = ylim
    for frac in (0.0, 0.5, 1.0):
        y = bottom - frac * (bottom - top)
        draw.text((4, y - 6), f"{lo + frac * (hi - lo):.1f}", fill="black", font=font)
    draw.text((left, bottom + 8), f"iteration 0 .. {n - 1}", fill="black", font=font)
    if title:
        draw.text((left, 4), title, fill="black", font=font)
    colours = ["#1d1208", "#d0743c", "#3b6ea5", "#6a9a3a", "#a53b6e", "#e0b02c", "#4bb3b0"]
    for i, (label, values) in enumerate(series.items()):
        pts = [(left + (right - left) * t / max(n - 1, 1), bottom - (min(max(v, lo), hi) - lo) / (hi - lo) * (bottom - top))
               for t, v in enumerate(values)]
        col = colours[i % len(colours)]
        if len(pts) > 1:
            draw.line(pts, fill=col, width=2)
        draw.text((right + 8, top + 14 * i), str(label), fill=col, font=font)
    return img


# ---- Young's 2D automaton (paper 003) ----------------------------------------------------
YOUNG_R1, YOUNG_R2, YOUNG_W1 = 2.30, 6.01, 1.0
FIG8_W2 = (-0.20, -0.24, -0.28, -0.32, -0.36, -0.40)  # stripes -> spots
FIG8_STEPS = 30  # paper 003: "each simulation is run for 30 time-steps"


@_preset("young-fig8", "Young's automaton, r1 = 2.30, r2 = 6.01, w1 = 1, w2 from -0.20 to -0.40: stripes to spots",
         "paper 003 Fig. 8 (Young 1984 Fig. 6)")
def _young_fig8(seed, quick, out, frames):
    size = 100 if quick else 200
    # one common denominator so the models stack into one vmapped run
    cas = [YoungCA([(YOUNG_R1, YOUNG_R2, YOUNG_W1, w)], denominator=25) for w in FIG8_W2]
    stacked = jax.tree.map(lambda *x: jnp.stack(x), *cas)
    cells0 = random_cells(jax.random.key(seed), (size, size), 1, YOUNG_P)
    save_every = 5 if frames else None
    t0 = time.perf_counter()
    result = eqx.filter_vmap(lambda m: m.run(cells0, FIG8_STEPS, save_every=save_every, history=True))(stacked)
    jax.block_until_ready(result.cells)
    seconds = time.perf_counter() - t0
    finals = np.asarray(result.cells)
    scale = max(1, 200 // size)
    montage([cells_image(c, 1, scale) for c in finals], len(FIG8_W2), col_labels=[f"w2 = {w:g}" for w in FIG8_W2],
            title=f"Young, r1 = {YOUNG_R1}, r2 = {YOUNG_R2}, w1 = 1, p = {YOUNG_P}, t = {FIG8_STEPS}").save(out)
    per = [{"w2": w, **_stats(c, 1)} for w, c in zip(FIG8_W2, finals)]
    metadata = {"automaton": "YoungCA", "params": [ca.to_dict() for ca in cas], "lattice": [size, size],
                "seed": seed, "initial": {"p": YOUNG_P}, "steps": FIG8_STEPS, "w2": list(FIG8_W2), "runs": per}
    files = [str(out), str(_save_npz(out, finals, metadata, changes=np.asarray(result.changes)))]
    if frames:
        strip = [cells_image(f, 1, scale) for f in np.asarray(result.frames).reshape(-1, size, size)]
        n_cols = np.asarray(result.frames).shape[1]
        frames_png = out.with_name(out.stem + "_frames.png")
        montage(strip, n_cols, row_labels=[f"w2 = {w:g}" for w in FIG8_W2],
                col_labels=[f"t = {t}" for t in np.asarray(result.frame_steps)[0]]).save(frames_png)
        frames_npz = out.with_name(out.stem + "_frames.npz")
        np.savez_compressed(frames_npz, frames=np.asarray(result.frames), steps=np.asarray(result.frame_steps)[0])
        files += [str(frames_png), str(frames_npz)]
    return {"steps": FIG8_STEPS, "lattice": [size, size], "runs": per, "seconds_run": round(seconds, 3), "files": files}


def _young_single(w2):
    def runner(seed, quick, out, frames):
        ca = YoungCA([(YOUNG_R1, YOUNG_R2, YOUNG_W1, w2)])
        size = 128 if quick else 256
        return run_automaton(ca, (size, size), p=YOUNG_P, steps=FIG8_STEPS, stop=False, seed=seed, out=out, frames=frames)

    return runner


_preset("young-stripes", "Young's automaton at w2 = -0.20: labyrinthine stripes", "paper 003 Fig. 8 (left)")(_young_single(-0.20))
_preset("young-spots", "Young's automaton at w2 = -0.40: isolated spots", "paper 003 Fig. 8 (right)")(_young_single(-0.40))


@_preset("young-b1", "paper 003's Python code: Moore boxes Ra = 2, Ri = 5, wa = 1, wi = 0.2, self counted, 20 steps",
         "paper 003 Fig. B1 (evolution over time)")
def _young_b1(seed, quick, out, frames):
    # the code sums the inhibitor over the whole box (self included): WS = Na wa - Ni wi,
    # i.e. weight wa - wi on the inner box and -wi on the ring
    wa, wi = 1.0, 0.2
    ca = YoungCA([(2, 5, wa - wi, -wi)], "box", include_self=True)
    size = 100  # the code's 100 x 100 grid is already quick
    return run_automaton(ca, (size, size), p=YOUNG_P, steps=20, stop=False, seed=seed, out=out, frames=frames,
                         extra={"code_weights": {"wa": wa, "wi": wi}})


# ---- paper 002: 3D, K species ------------------------------------------------------------
DUR_K2 = (3.2, 6.0, 1.0, -0.2)  # R_act, R_inh, w_act, w_inh of both species (section 4.2)
DUR_TABLE2 = ((6.0, 10.0, 1.0, -0.3), (4.0, 7.0, 1.0, -0.3), (4.3, 8.0, 1.0, -0.22))  # species 0-2 of Table 2
DUR_TABLE2_W3 = -0.2  # w_{3,inh} is "variable" in Table 2 / Fig. 8; species 3 is otherwise (3.2, 6, 1, .)


@_preset("dur-fig6", "3D, L = 100, K = 2, both species (3.2, 6, 1, -0.2), run to convergence (< 1% changed)",
         "paper 002 Fig. 6 (section 4.2: 42.86% / 42.88% / 14.26% after 20 iterations)")
def _dur_fig6(seed, quick, out, frames):
    ca = YoungCA([DUR_K2, DUR_K2])
    size = 40 if quick else 100
    summary = run_automaton(ca, (size,) * 3, p=None, steps=100, stop=True, seed=seed, out=out, frames=frames)
    summary["weighted_volume_difference"] = [round(float(v), 3) for v in np.asarray(weighted_volume_difference(ca))]
    return summary


@_preset("dur-fig8", "3D, L = 100, K = 4 species of Table 2 (w_3,inh = -0.2), run to convergence",
         "paper 002 Fig. 8 / Table 2")
def _dur_fig8(seed, quick, out, frames):
    ca = YoungCA([*DUR_TABLE2, (3.2, 6.0, 1.0, DUR_TABLE2_W3)])
    size = 48 if quick else 100
    summary = run_automaton(ca, (size,) * 3, p=None, steps=100, stop=True, seed=seed, out=out, frames=frames)
    summary["weighted_volume_difference"] = [round(float(v), 3) for v in np.asarray(weighted_volume_difference(ca))]
    return summary


FIG9_W0 = (-0.10, -0.15, -0.20, -0.25, -0.30)
_eps0_series = jax.jit(jax.vmap(lambda cells: order_parameter(cells, 2)[0]))


@_preset("dur-fig9", "order parameter eps_0 per iteration, K = 2, w_0,inh from -0.10 to -0.30 (identical starts)",
         "paper 002 Fig. 9")
def _dur_fig9(seed, quick, out, frames):
    size, steps = (32, 20) if quick else (100, 40)
    cells0 = random_cells(jax.random.key(seed), (size,) * 3, 2)
    series, finals, steps_run = {}, [], []
    t0 = time.perf_counter()
    for w0 in FIG9_W0:
        # one denominator for the whole series (1/20: all its weights are multiples), so
        # the compiled run is reused
        ca = YoungCA([(3.2, 6.0, 1.0, w0), DUR_K2], denominator=20)
        result = ca.run(cells0, steps, save_every=1)
        eps = _eps0_series(result.frames)
        series[f"w0 = {w0:g}"] = [float(v) for v in np.asarray(eps)]
        finals.append(np.asarray(result.cells))
        steps_run.append(int(result.steps))
    seconds = time.perf_counter() - t0
    chart = line_chart(series, title=f"eps_0 per iteration, L = {size}, K = 2")
    mids = montage([cells_image(c[size // 2], 2, max(1, 160 // size)) for c in finals], len(finals),
                   col_labels=[f"w0 = {w:g}" for w in FIG9_W0])
    canvas = Image.new("RGB", (max(chart.width, mids.width), chart.height + mids.height), "white")
    canvas.paste(chart, (0, 0))
    canvas.paste(mids, (0, chart.height))
    canvas.save(out)
    metadata = {"automaton": "YoungCA", "species_1": DUR_K2, "species_0": {"r_act": 3.2, "r_inh": 6.0, "w_act": 1.0},
                "w0_inh": list(FIG9_W0), "lattice": [size] * 3, "seed": seed, "initial": {"p": None},
                "steps": steps, "order_parameter_0": series}
    files = [str(out), str(_save_npz(out, np.stack(finals), metadata))]
    return {"steps": steps_run, "lattice": [size] * 3, "order_parameter_0_final": {k: round(v[-1], 4) for k, v in series.items()},
            "seconds_run": round(seconds, 3), "files": files}


# ---- life-like rules ---------------------------------------------------------------------
@_preset("life-glider", "Conway's B3/S23: a glider moves one cell diagonally every 4 generations",
         "Conway's Game of Life (Gardner 1970)")
def _life_glider(seed, quick, out, frames):
    life = LifeLike("B3/S23")
    size, gens = 16, (16 if quick else 64)  # 64 generations bring it back round the 16-torus
    cells0 = glider((size, size), at=((1 + seed) % size, (1 + seed) % size))
    result = life.run(cells0, gens, save_every=4)
    shown = np.asarray(result.frames)[:9]
    montage([cells_image(1 - f, 1, 8) for f in shown], len(shown),
            col_labels=[f"t={4 * i}" for i in range(len(shown))]).save(out)
    moved = np.array_equal(np.asarray(result.cells), np.roll(np.asarray(cells0), (gens // 4, gens // 4), (0, 1)))
    metadata = {"automaton": "LifeLike", "rule": life.rule, "lattice": [size, size], "seed": seed,
                "initial": "glider", "steps": gens}
    files = [str(out), str(_save_npz(out, result.cells, metadata, frames=np.asarray(result.frames)))]
    return {"steps": gens, "rule": life.rule, "glider_moved_diagonally": bool(moved), "files": files}


@_preset("life-soup", "Conway's B3/S23 from a random 50% soup on a torus", "Conway's Game of Life (Gardner 1970)")
def _life_soup(seed, quick, out, frames):
    life = LifeLike("B3/S23")
    size, gens = (64, 100) if quick else (256, 500)
    cells0 = jax.random.bernoulli(jax.random.key(seed), 0.5, (size, size)).astype(jnp.int8)
    result, seconds = _timed_run(life, cells0, gens, save_every=max(1, gens // 10) if frames else None)
    cells_image(1 - np.asarray(result.cells), 1, max(1, 512 // size)).save(out)
    metadata = {"automaton": "LifeLike", "rule": life.rule, "lattice": [size, size], "seed": seed,
                "initial": {"alive_probability": 0.5}, "steps": gens}
    files = [str(out), str(_save_npz(out, result.cells, metadata))]
    if frames:
        files += _frames_outputs(out, 1 - np.asarray(result.frames), result.frame_steps, 1, max(1, 256 // size))
    return {"steps": gens, "rule": life.rule, "alive": round(float(np.mean(np.asarray(result.cells))), 4),
            "seconds_run": round(seconds, 3), "files": files}


# ---- the `ca` command ----------------------------------------------------------------------
def _species(text: str):
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 4:
        raise argparse.ArgumentTypeError(f"a species is r_act,r_inh,w_act,w_inh (got {text!r})")
    return values


def register(subparsers) -> argparse.ArgumentParser:
    """Add the `ca` subcommand (a custom Young automaton or life-like run)."""
    p = subparsers.add_parser(
        "ca", help="run a custom cellular automaton (Young activator-inhibitor or life-like)",
        description="Young's activator-inhibitor automaton with K species (radii in lattice cells), or a "
                    "life-like B/S rule. Writes OUT.png, OUT.npz (cells + JSON metadata) and, in 3D, a mesh per species.",
    )
    p.add_argument("--species", type=_species, action="append", metavar="R_ACT,R_INH,W_ACT,W_INH",
                   help="one species (repeat for K species); default 3.2,6,1,-0.2")
    p.add_argument("--rule", default=None, help="a life-like rule instead, e.g. B3/S23 (0/1 cells, p = alive fraction)")
    p.add_argument("--neighbourhood", choices=["disc", "box"], default="disc")
    p.add_argument("--include-self", action="store_true", help="count the cell itself in its activator disc")
    p.add_argument("--dim", type=int, default=2, help="lattice dimension (default 2)")
    p.add_argument("--size", type=int, default=128, help="cells per side (default 128)")
    p.add_argument("--p", type=float, default=None,
                   help="probability a cell starts differentiated (Young: 0.015); default uniform over the K+1 states")
    p.add_argument("--steps", type=int, default=50)
    p.add_argument("--stop-at-convergence", action="store_true", help="stop once < --threshold of the cells change")
    p.add_argument("--threshold", type=float, default=0.01, help="convergence threshold (fraction, default 0.01)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--frames", action="store_true", help="also write intermediate snapshots (Young automata)")
    p.add_argument("--out", type=Path, default=Path("ca.png"))
    p.set_defaults(func=run_ca_command)
    return p


def run_ca_command(args) -> int:
    try:
        return _run_ca(args)
    except ValueError as err:  # bad parameters: a message, not a traceback
        raise SystemExit(f"morphojax ca: {err}") from err


def _run_ca(args) -> int:
    if args.dim not in (2, 3):  # the library takes any dimension; pictures and meshes need 2 or 3
        raise ValueError(f"--dim must be 2 or 3 (got {args.dim})")
    check_range(args.size, "--size (cells per side)", low=1)
    check_range(args.steps, "--steps", low=0)
    if args.p is not None:
        check_range(args.p, "--p (probability)", low=0.0, high=1.0)
    out = args.out if args.out.suffix.lower() == ".png" else args.out.with_suffix(".png")
    out.parent.mkdir(parents=True, exist_ok=True)
    shape = (int(args.size),) * int(args.dim)
    if args.rule:
        life = LifeLike(args.rule)
        cells0 = jax.random.bernoulli(jax.random.key(args.seed), 0.5 if args.p is None else args.p, shape).astype(jnp.int8)
        result, seconds = _timed_run(life, cells0, args.steps, stop_at_convergence=args.stop_at_convergence,
                                     threshold=args.threshold)
        _picture(1 - np.asarray(result.cells), 1, 3 if len(shape) == 3 else max(1, 400 // args.size)).save(out)
        metadata = {"automaton": "LifeLike", "rule": life.rule, "lattice": list(shape), "seed": args.seed,
                    "initial": {"alive_probability": 0.5 if args.p is None else args.p}, "steps": args.steps}
        summary = {"steps": int(result.steps), "converged": bool(result.converged), "rule": life.rule,
                   "seconds_run": round(seconds, 3), "files": [str(out), str(_save_npz(out, result.cells, metadata))]}
    else:
        ca = YoungCA(args.species or [(3.2, 6.0, 1.0, -0.2)], args.neighbourhood, args.include_self)
        summary = run_automaton(ca, shape, p=args.p, steps=args.steps, stop=args.stop_at_convergence, seed=args.seed,
                                out=out, frames=args.frames, threshold=args.threshold)
    print(json.dumps(summary))
    return 0


def main(argv=None) -> int:
    """Standalone entry point: `python -m morphojax._automata_cli ca ...` or a preset name."""
    parser = argparse.ArgumentParser(prog="morphojax-ca")
    sub = parser.add_subparsers(dest="command", required=True)
    register(sub)
    run = sub.add_parser("run", help="run a cellular-automaton preset")
    run.add_argument("name", choices=sorted(PRESETS))
    run.add_argument("--seed", type=int, default=0)
    run.add_argument("--quick", action="store_true")
    run.add_argument("--frames", action="store_true")
    run.add_argument("--out", type=Path, default=None)
    run.set_defaults(func=lambda a: print(json.dumps(PRESETS[a.name].run(a.seed, a.quick, a.out, a.frames))) or 0)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())

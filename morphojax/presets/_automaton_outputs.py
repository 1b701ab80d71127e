"""A cellular-automaton run with every output written next to a PNG path.

`run_automaton` (Young's automaton) and `run_life_like` (a life-like rule) start from
seeded random cells, run, and write `out` (the picture: the lattice in 2D, a montage of
slices in 3D), `out.npz` (the final cells and a JSON `metadata` entry with every parameter,
the seed and the summary), a mesh per species for 3D Young lattices
(`out_species{j}.ply`) and, with `frames=True`, the snapshots (`out_frames.npz` and
`out_frames.png`). The same seed gives the same files. The presets and `morphojax ca` use
them.

Automata names come from the package namespace when a function runs (`mj.YoungCA`, ...):
this module depends on their public names only, not on where they are implemented.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from PIL import Image, ImageDraw, ImageFont

import morphojax as mj
from .._files import write_npz
from .._frames_files import save_frames
from ..automata import SPECIES_COLOURS


def automaton_stats(cells, k) -> dict:
    """Volume fractions and order parameters of `cells` with `k` species, rounded for JSON."""
    return {"volume_fractions": [round(float(v), 5) for v in np.asarray(mj.volume_fractions(cells, k))],
            "order_parameter": [round(float(v), 5) for v in np.asarray(mj.order_parameter(cells, k))]}


def timed_run(automaton, cells, steps, **kwargs):
    """`automaton.run(cells, steps, **kwargs)` and the seconds it took (results ready)."""
    t0 = time.perf_counter()
    result = automaton.run(cells, steps, **kwargs)
    jax.block_until_ready(result.cells)
    return result, time.perf_counter() - t0


def save_cells_npz(out: Path, cells, metadata: dict, **arrays) -> Path:
    """`out.npz` with `cells`, the JSON `metadata` and any other named arrays."""
    return write_npz(out.with_suffix(".npz"), cells=np.asarray(cells), metadata=json.dumps(metadata), **arrays)


def default_scale(shape) -> int:
    """Pixels per cell of an automaton's picture: 3 for 3D slices, about 400 pixels a side in 2D."""
    return 3 if len(shape) == 3 else max(1, 400 // max(shape))


def lattice_picture(cells, k, scale, title=None) -> Image.Image:
    """A 2D lattice as an image, a 3D one as a montage of slices."""
    cells = np.asarray(cells)
    if cells.ndim == 2:
        return mj.cells_image(cells, k, scale)
    if cells.ndim == 3:
        return mj.slice_montage(cells, k, n=8, scale=scale, title=title)
    raise ValueError(f"pictures need a 2D or 3D lattice (got shape {cells.shape})")


def frames_outputs(out: Path, frames, frame_steps, k, scale) -> list[str]:
    """`out_frames.npz` (the snapshots and their steps) and `out_frames.png` (their montage,
    middle slices in 3D); returns both paths."""
    frames, frame_steps = np.asarray(frames), np.asarray(frame_steps)
    keep = frame_steps >= 0
    frames, frame_steps = frames[keep], frame_steps[keep]
    npz = out.with_name(out.stem + "_frames.npz")
    save_frames(npz, frames, frame_steps, states=k + 1)  # with checked metadata (version, format, states)
    mid = [f if f.ndim == 2 else f[f.shape[0] // 2] for f in frames]
    png = out.with_name(out.stem + "_frames.png")
    mj.montage([mj.cells_image(f, k, scale) for f in mid], min(len(mid), 6),
               col_labels=None, title="t = " + ", ".join(map(str, frame_steps))).save(png)
    return [str(npz), str(png)]


def run_automaton(ca, shape, *, p=None, steps: int, stop: bool, seed: int, out: Path, frames: bool,
                  threshold: float = 0.01, scale: int | None = None, extra: dict | None = None,
                  progress=False) -> dict:
    """One Young automaton run from `random_cells(key(seed), shape, K, p)` with every output
    written next to `out` (`progress`: a bar, as `AbstractAutomaton.run`); returns the summary."""
    k = ca.n_species
    cells0 = mj.random_cells(jax.random.key(seed), shape, k, p)
    save_every = max(1, min(steps, 40) // 10) if frames else None
    result, seconds = timed_run(ca, cells0, steps, stop_at_convergence=stop, threshold=threshold,
                                save_every=save_every, history=True, progress=progress)
    n = int(result.steps)
    summary = {"steps": n, "converged": bool(result.converged), "lattice": list(shape),
               **automaton_stats(result.cells, k), "seconds_run": round(seconds, 3),
               "changed_last": float(np.asarray(result.changes)[n - 1]) if n else None}
    metadata = {"automaton": "YoungCA", "params": ca.to_dict(), "lattice": list(shape), "seed": seed,
                "initial": {"p": p, "kind": "uniform over K+1 states" if p is None else "differentiated with probability p"},
                "steps": steps, "stop_at_convergence": stop, "threshold": threshold, "summary": summary,
                **(extra or {})}
    scale = scale or default_scale(shape)
    lattice_picture(result.cells, k, scale, title=f"t = {n}").save(out)
    files = [str(out), str(save_cells_npz(out, result.cells, metadata, changes=np.asarray(result.changes)))]
    if len(shape) == 3:
        files += [str(p) for p in mj.write_species_meshes(result.cells, k, out.with_suffix(""))]
    if frames:
        files += frames_outputs(out, result.frames, result.frame_steps, k, scale)
    summary["files"] = files
    return summary


def run_life_like(life, shape, *, p=None, steps: int, stop: bool, seed: int, out: Path,
                  threshold: float = 0.01, progress=False) -> dict:
    """One life-like run from cells alive with probability `p` (default 0.5) drawn from
    `key(seed)`, with its picture and `.npz` written next to `out`; returns the summary."""
    alive = 0.5 if p is None else p
    cells0 = jax.random.bernoulli(jax.random.key(seed), alive, shape).astype(jnp.int8)
    result, seconds = timed_run(life, cells0, steps, stop_at_convergence=stop, threshold=threshold,
                                progress=progress)
    lattice_picture(1 - np.asarray(result.cells), 1, default_scale(shape)).save(out)
    metadata = {"automaton": "LifeLike", "rule": life.rule, "lattice": list(shape), "seed": seed,
                "initial": {"alive_probability": alive}, "steps": steps}
    return {"steps": int(result.steps), "converged": bool(result.converged), "rule": life.rule,
            "seconds_run": round(seconds, 3), "files": [str(out), str(save_cells_npz(out, result.cells, metadata))]}


def line_chart(series: dict, width: int = 480, height: int = 300, title: str = "", ylim=(0.0, 1.0)) -> Image.Image:
    """A minimal line chart (pillow only): one polyline per labelled series over its index,
    in the species colours of the automata pictures."""
    n = max(len(v) for v in series.values())
    return xy_chart({label: (np.arange(len(v)), v) for label, v in series.items()}, width, height, title, ylim,
                    x_label=f"iteration 0 .. {n - 1}")


def xy_chart(series: dict, width: int = 480, height: int = 300, title: str = "", ylim=(0.0, 1.0), *,
             x_label: str = "", dots: bool = False) -> Image.Image:
    """A minimal chart (pillow only): `series` maps a label to its (x, y) values, drawn as
    a polyline (or, with `dots`, one dot per point) in the species colours of the automata
    pictures; y is clipped to `ylim`, x spans every series' range."""
    img = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default()
    left, right, top, bottom = 40, width - 110, 20, height - 30
    draw.rectangle([left, top, right, bottom], outline="black")
    xs = np.concatenate([np.asarray(x, float) for x, _ in series.values()])
    x_lo, x_hi = float(xs.min()), float(xs.max())
    x_span = x_hi - x_lo if x_hi > x_lo else 1.0
    lo, hi = ylim
    for frac in (0.0, 0.5, 1.0):
        y = bottom - frac * (bottom - top)
        draw.text((4, y - 6), f"{lo + frac * (hi - lo):.1f}", fill="black", font=font)
    if x_label:
        draw.text((left, bottom + 8), x_label, fill="black", font=font)
    if title:
        draw.text((left, 4), title, fill="black", font=font)
    for i, (label, (x, y)) in enumerate(series.items()):
        pts = [(left + (right - left) * (float(a) - x_lo) / x_span,
                bottom - (min(max(float(b), lo), hi) - lo) / (hi - lo) * (bottom - top)) for a, b in zip(x, y)]
        col = SPECIES_COLOURS[i % len(SPECIES_COLOURS)]
        if dots:
            for px, py in pts:
                draw.ellipse([px - 1.5, py - 1.5, px + 1.5, py + 1.5], fill=col)
        elif len(pts) > 1:
            draw.line(pts, fill=col, width=2)
        draw.text((right + 8, top + 14 * i), str(label), fill=col, font=font)
    return img

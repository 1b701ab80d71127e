"""Solid textures: Gray-Scott on a 3D lattice (Lundelius's future work, a texture carved
from a volume), `morphojax run gray-scott-3d` or `PRESETS["gray-scott-3d"].run()`.

The run writes its PNG `out` (evenly spaced slices of v along each axis), `out.npz` (the
final u and v, with a JSON `metadata` entry holding every parameter, the seed and the
run's status) and `out.ply`, the isosurface of v half way between its extremes (marching
cubes, closed at the lattice's faces), coloured through the same colour map. The same
seed gives the same files.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import ClassVar

import jax
import numpy as np

import morphojax as mj
from .._files import write_npz
from ._registry import AutomatonPreset, register

# Pearson's "worms" parameters (as the 2D preset gray-scott-worms): tubes and sheets in 3D
FEED, KILL = 0.046, 0.063
CMAP = "viridis"


@dataclasses.dataclass(frozen=True)
class SolidPreset(AutomatonPreset):
    """A reaction-diffusion run on a 3D lattice: `build(seed, quick, out, frames)` writes
    slices, the fields and an isosurface, as an automaton preset, under its own kind."""

    kind: ClassVar[str] = "solid"


def isosurface(volume, level: float | None = None):
    """(vertices (V, 3) float32 in cells, faces (F, 3) int32) of `volume` at `level` (default
    half way between its extremes), closed at the lattice's faces by a ring of padding."""
    from skimage.measure import marching_cubes

    volume = np.asarray(volume, np.float32)
    lo, hi = float(volume.min()), float(volume.max())
    level = (lo + hi) / 2 if level is None else float(level)
    if not lo < level < hi:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
    padded = np.pad(volume, 1, constant_values=lo)
    verts, faces, _, _ = marching_cubes(padded, level=level, allow_degenerate=False, gradient_direction="ascent")
    return (verts - 1).astype(np.float32), faces.astype(np.int32)


def slices_picture(volume, cmap=CMAP, title: str | None = None):
    """Four evenly spaced slices of a 3D field along each axis (rows), in one colour range."""
    volume = np.asarray(volume)
    if volume.ndim != 3:
        raise ValueError(f"slices_picture needs a 3D field (got shape {volume.shape})")
    lo, hi = float(volume.min()), float(volume.max())
    scale = max(1, 192 // max(volume.shape))
    tiles = [mj.to_image(np.take(volume, i, axis=axis), cmap, vmin=lo, vmax=hi, scale=scale)
             for axis in range(3) for i in np.linspace(0, volume.shape[axis] - 1, 4).round().astype(int)]
    return mj.montage(tiles, 4, row_labels=["axis 0", "axis 1", "axis 2"], title=title)


def _gray_scott_3d(seed, quick, out: Path, frames):
    size, steps, dt = (24, 1500, 1.0) if quick else (64, 6000, 1.0)
    shape = (size, size, size)
    model = mj.GrayScott(FEED, KILL)
    state = mj.gray_scott_state(jax.random.key(seed), shape, square=0.3)  # 0.2 of 24 cells decays in 3D
    t0 = time.perf_counter()
    run = mj.run_status(model, state, steps, dt, stencil="nineteen-point", boundary="wrap")
    jax.block_until_ready(run.state.fields)
    seconds = time.perf_counter() - t0
    u, v = (np.asarray(f) for f in run.state.fields)
    lo, hi = float(v.min()), float(v.max())
    slices_picture(v, CMAP, title=f"Gray-Scott in 3D (F {FEED}, k {KILL}), v, {size}^3, t = {steps * dt:g}").save(out)
    verts, faces = isosurface(v)
    ply = mj.write_ply(out.with_suffix(".ply"), verts, faces,
                       colour=mj.vertex_colours(np.full(len(verts), 0.75), CMAP, vmin=0.0, vmax=1.0),
                       comment="morphojax Gray-Scott isosurface of v")
    metadata = {"kind": "solid", "model": mj.model_to_dict(model), "lattice": list(shape),
                "stencil": "nineteen-point", "boundary": "wrap", "dt": dt, "steps": steps, "seed": seed,
                "initial": "gray_scott_state(key(seed), shape, square=0.3)", "iso_level": (lo + hi) / 2,
                "nonfinite_step": int(run.nonfinite_step), "quick": quick}
    npz = write_npz(out.with_suffix(".npz"), u=u, v=v, metadata=json.dumps(metadata))
    return {"lattice": list(shape), "steps": steps, "seconds_run": round(seconds, 3),
            "isosurface": {"vertices": int(len(verts)), "faces": int(len(faces))},
            "files": [str(out), str(npz), str(ply)]}


register(SolidPreset("gray-scott-3d", "Gray-Scott (Pearson's worms) on a 64^3 lattice, nineteen-point stencil: "
                                      "slices and an isosurface of a solid texture",
                     "Lundelius's future work (solid textures)", _gray_scott_3d))

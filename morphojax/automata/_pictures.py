"""Pictures of cellular-automaton lattices: one colour per state.

2D lattices become images (`cells_image`), 3D lattices a montage of evenly spaced
slices (`slice_montage`). The state colours are shared with the meshes (`_meshes`).
"""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageColor

from .._render import colormap_table, montage, to_image

# species colours (Dur 2023 style: distinct hues), then the undifferentiated state
SPECIES_COLOURS = ("#1d1208", "#d0743c", "#3b6ea5", "#6a9a3a", "#a53b6e", "#e0b02c", "#4bb3b0", "#7b5ea7")
UNDIFFERENTIATED = "#f3e3c3"


def state_colours(k: int) -> np.ndarray:
    """(k + 1, 3) uint8 colours: species 0..k-1, then the undifferentiated state k."""
    names = [SPECIES_COLOURS[j % len(SPECIES_COLOURS)] for j in range(k)] + [UNDIFFERENTIATED]
    cols = [ImageColor.getrgb(c)[:3] for c in names]
    return np.array(cols, np.uint8)


def state_table(k: int) -> np.ndarray:
    """A (256, 3) colour table (for `_render.to_image`) whose entry s is state s's colour."""
    table = colormap_table("gray").copy()
    table[: k + 1] = state_colours(k)
    return table


def cells_image(cells, k: int, scale: int = 1) -> Image.Image:
    """A 2D lattice of states 0..k as an RGB image (one colour per state)."""
    cells = np.asarray(cells)
    if cells.ndim != 2:
        raise ValueError(f"cells_image needs a 2D lattice (got shape {cells.shape})")
    return to_image(cells.astype(np.int64), cmap=state_table(k), vmin=0, vmax=255, scale=scale)


def slice_montage(cells, k: int, n: int = 6, axis: int = 0, scale: int = 2, ncols: int | None = None,
                  title: str | None = None) -> Image.Image:
    """`n` evenly spaced slices of a 3D lattice along `axis`, labelled by their index."""
    cells = np.asarray(cells)
    if cells.ndim != 3:
        raise ValueError(f"slice_montage needs a 3D lattice (got shape {cells.shape})")
    n = max(1, min(int(n), cells.shape[axis]))
    idx = np.linspace(0, cells.shape[axis] - 1, n).round().astype(int)
    images = [cells_image(np.take(cells, i, axis=axis), k, scale) for i in idx]
    ncols = ncols or min(n, 4)
    where = f"slices at axis-{axis} index " + ", ".join(map(str, idx))
    return montage(images, ncols, title=f"{title}; {where}" if title else where)

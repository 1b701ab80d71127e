"""Pictures of hexagonal lattices: every cell drawn as its hexagon, not a sheared grid.

A (rows, cols) field in the odd-r offset layout of `HexLattice` is resampled onto a square
pixel grid: each pixel takes the value of the cell whose centre is nearest (the hexagon
it lies in, exactly: the Voronoi cell of a hexagonal lattice of centres is the regular
hexagon), so pointy-topped hexagons of width `scale` pixels tile the picture with odd rows
shifted half a cell to the right, rows sqrt(3)/2 cells apart.
"""

from __future__ import annotations

import math

import numpy as np
from PIL import Image

from ._colours import _rgb, colormap_table, normalise
from .domains._hex import ROW_HEIGHT


def hex_cell_index(shape, scale: int = 8) -> np.ndarray:
    """For a (rows, cols) hexagonal lattice drawn with cells `scale` pixels wide, the
    (height, width) array of each pixel's cell as a flat index r * cols + c."""
    rows, cols = int(shape[0]), int(shape[1])
    scale = int(scale)
    if scale < 2:
        raise ValueError(f"hex_image.scale must be an integer >= 2 pixels per cell (got {scale})")
    width = int(math.ceil((cols + 0.5) * scale))
    height = int(math.ceil(((rows - 1) * ROW_HEIGHT + 2.0 / math.sqrt(3.0)) * scale))
    # pixel centres in cell units, the first cell's centre at (1/2, 1/sqrt(3)) from the corner
    x = (np.arange(width) + 0.5) / scale - 0.5
    y = (np.arange(height) + 0.5) / scale - 1.0 / math.sqrt(3.0)
    X, Y = np.meshgrid(x, y)
    r0 = np.floor(Y / ROW_HEIGHT).astype(int)
    best = np.full(X.shape, np.inf)
    index = np.zeros(X.shape, int)
    for r in (r0, r0 + 1):  # the nearest centre lies in one of the two rows around the pixel
        rr = np.clip(r, 0, rows - 1)
        shift = 0.5 * (rr % 2)
        for dc in (0, 1):
            cc = np.clip(np.floor(X - shift).astype(int) + dc, 0, cols - 1)
            d = (X - cc - shift) ** 2 + (Y - rr * ROW_HEIGHT) ** 2
            closer = d < best
            best = np.where(closer, d, best)
            index = np.where(closer, rr * cols + cc, index)
    return index


def hex_image(array, cmap="inferno", vmin=None, vmax=None, scale: int = 8, background="white") -> Image.Image:
    """A (rows, cols) field on a `HexLattice` as an RGB picture of hexagons.

    Args:
        array: the field, odd-r offset layout (odd rows shifted half a cell to the right).
        cmap, vmin, vmax: as for `to_image` (min-max normalised by default).
        scale: the width of a hexagon in pixels (an integer >= 2).
        background: colour of the pixels outside every hexagon (the jagged left and right
            edges of the offset rows and the top and bottom points).
    """
    a = np.asarray(array)
    if a.ndim != 2:
        raise ValueError(f"hex_image needs a 2D array (rows, cols) (got shape {a.shape})")
    index = hex_cell_index(a.shape, scale)
    colours = colormap_table(cmap)[(normalise(a, vmin, vmax) * 255).round().astype(np.uint8)].reshape(-1, 3)
    picture = colours[index]
    # pixels farther from their centre than a hexagon's corner (1/sqrt(3)) or outside the
    # rows' hexagons lie beyond the lattice: the background
    rows, cols = a.shape
    h, w = index.shape
    x = (np.arange(w) + 0.5) / scale - 0.5
    y = (np.arange(h) + 0.5) / scale - 1.0 / math.sqrt(3.0)
    X, Y = np.meshgrid(x, y)
    r, c = np.divmod(index, cols)
    dx, dy = np.abs(X - c - 0.5 * (r % 2)), np.abs(Y - r * ROW_HEIGHT)
    inside = (dx <= 0.5 + 1e-9) & (dy <= 1.0 / math.sqrt(3.0) - dx / math.sqrt(3.0) + 1e-9)
    picture = np.where(inside[..., None], picture, np.asarray(_rgb(background), np.uint8))
    return Image.fromarray(picture.astype(np.uint8), "RGB")


def render_hex(state, species=-1, cmap="inferno", vmin=None, vmax=None, scale: int = 8) -> Image.Image:
    """One species of a State on a `HexLattice` as hexagons (by name or index; default the
    last), the hexagonal counterpart of `render`."""
    arrays = state.arrays()
    return hex_image(arrays[state.index(species) if species != -1 else -1], cmap, vmin, vmax, scale)

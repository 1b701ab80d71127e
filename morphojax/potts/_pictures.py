"""Pictures of a Potts lattice: each site coloured by its cell's type, cell borders drawn."""

from __future__ import annotations

import numpy as np
from PIL import Image

from ._state import PottsState

# medium black, type 1 (condensing) blue, type 2 (non-condensing) green: Tinson's (2022) Fig. 10
TYPE_COLOURS = np.array([(0, 0, 0), (40, 90, 220), (40, 180, 80), (220, 160, 40), (200, 60, 60), (150, 80, 200)],
                        np.uint8)
BORDER = np.array((15, 15, 15), np.uint8)


def potts_image(state: PottsState, scale: int = 4, borders: bool = True) -> Image.Image:
    """`state` as an RGB image, `scale` pixels per site; with `borders`, the last pixel
    row/column of a site whose right or lower neighbour is another cell is dark."""
    ids, types, _ = state.arrays()
    if int(scale) < 1:
        raise ValueError(f"scale must be a positive number of pixels per site (got {scale!r})")
    scale = int(scale)
    t = types[ids]
    palette = TYPE_COLOURS[np.arange(int(t.max()) + 1) % len(TYPE_COLOURS)]
    palette[1:] = np.where(np.arange(1, len(palette))[:, None] % len(TYPE_COLOURS) == 0, (120, 120, 120),
                           palette[1:])
    rgb = np.repeat(np.repeat(palette[t], scale, 0), scale, 1)
    if borders and scale >= 2:
        right = np.zeros(ids.shape, bool)
        right[:, :-1] = ids[:, :-1] != ids[:, 1:]
        down = np.zeros(ids.shape, bool)
        down[:-1] = ids[:-1] != ids[1:]
        mask = np.zeros(rgb.shape[:2], bool)
        mask[:, scale - 1::scale] |= np.repeat(right, scale, 0)
        mask[scale - 1::scale, :] |= np.repeat(down, scale, 1)
        mask &= np.repeat(np.repeat(t > 0, scale, 0), scale, 1) | _grow(t > 0, scale)
        rgb[mask] = BORDER
    return Image.fromarray(rgb)


def _grow(occupied, scale):
    """Pixels of sites right of or below a cell site (so a cell's border with the medium shows)."""
    near = occupied.copy()
    near[:, 1:] |= occupied[:, :-1]
    near[1:] |= occupied[:-1]
    return np.repeat(np.repeat(near, scale, 0), scale, 1)

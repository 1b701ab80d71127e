"""Colours: colour maps as 256-entry lookup tables, gradients from colour stops, and the
normalisation of a field to [0, 1], shared by every picture (the lattice's, the hexagonal
lattice's, the mesh's, the cells') so no renderer imports another.

The perceptually uniform `inferno` (the papers' choice, default) and `viridis`, `gray`, the
thesis's palettes, or a `Gradient` built from colour stops as in the thesis's `colormap
slot` commands, e.g. `Gradient([(0.0, "white"), (1.0, "#5b3504")])`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from PIL import ImageColor

from . import _colormap_data


def _hex_table(chunks) -> np.ndarray:
    text = "".join(chunks)
    return np.frombuffer(bytes.fromhex(text), np.uint8).reshape(256, 3)


@dataclasses.dataclass(frozen=True)
class Gradient:
    """A colour map from (position, colour) stops, linear in RGB between stops.

    Positions lie in [0, 1] (0 = low end of the normalised range); colours are names or
    hex strings understood by pillow ("white", "#5b3504") or RGB tuples (0-255).
    """

    stops: tuple

    def __init__(self, stops: Sequence):
        stops = tuple((float(p), _rgb(c)) for p, c in stops)
        if len(stops) < 2:
            raise ValueError("Gradient needs at least two stops")
        positions = [p for p, _ in stops]
        if any(not 0.0 <= p <= 1.0 for p in positions) or positions != sorted(positions):
            raise ValueError(f"Gradient stop positions must increase within [0, 1] (got {positions})")
        object.__setattr__(self, "stops", stops)

    @classmethod
    def from_photo(cls, source, crop=None, k: int = 3, pigment: str = "dark", seed: int = 0) -> "Gradient":
        """The `k` main colours of a photo (a path, pillow image or (h, w, 3) RGB array;
        `crop` = (x0, y0, x1, y1) pixels), from k-means in CIELAB, as a gradient ordered by
        lightness: with pigment="dark" (default) the lightest colour takes a field's low
        end and the darkest its high end (dark spots = high concentration), "light" the
        reverse. Stops sit at the clusters' mean lightness, stretched to [0, 1]. The fitting
        package colours fitted coats with the same clustering (`photo_palette`)."""
        from ._palette import photo_stops

        return cls(photo_stops(source, crop=crop, k=k, pigment=pigment, seed=seed))

    def table(self) -> np.ndarray:
        """The 256-entry RGB lookup table (uint8, shape (256, 3)) interpolated between the colour stops."""
        pos = np.array([p for p, _ in self.stops])
        cols = np.array([c for _, c in self.stops], float)
        x = np.linspace(0.0, 1.0, 256)
        return np.stack([np.interp(x, pos, cols[:, k]) for k in range(3)], -1).round().astype(np.uint8)


def _rgb(colour):
    if isinstance(colour, str):
        try:
            return ImageColor.getrgb(colour)[:3]
        except ValueError as err:
            raise ValueError(f"unknown colour {colour!r}") from err
    rgb = tuple(int(v) for v in colour)
    if len(rgb) != 3 or any(not 0 <= v <= 255 for v in rgb):
        raise ValueError(f"a colour must be a name, hex string or (r, g, b) in 0-255 (got {colour!r})")
    return rgb


COLORMAPS = {
    "inferno": lambda: _hex_table(_colormap_data.INFERNO),
    "viridis": lambda: _hex_table(_colormap_data.VIRIDIS),
    "gray": lambda: np.repeat(np.arange(256, dtype=np.uint8)[:, None], 3, 1),
    # the thesis's giraffe and nudibranch palettes (colormap slots), and a leopard coat
    "giraffe": lambda: Gradient([(0.0, "white"), (0.6, "white"), (0.75, "#5b3504"), (1.0, "#5b3504")]).table(),
    "nudibranch": lambda: Gradient([(0.0, "white"), (0.2, "white"), (0.5, "#eaaa7a"), (1.0, "#eaaa7a")]).table(),
    "leopard": lambda: Gradient([(0.0, "#f3e3c3"), (0.5, "#c98a3c"), (1.0, "#1d1208")]).table(),
}


def colormap_table(cmap="inferno") -> np.ndarray:
    """The (256, 3) uint8 table of a colour map given by name, `Gradient` or table."""
    if isinstance(cmap, Gradient):
        return cmap.table()
    if isinstance(cmap, str):
        name = cmap.lower().replace("grey", "gray")
        if name not in COLORMAPS:
            raise ValueError(f"unknown colour map {cmap!r}; allowed: {', '.join(COLORMAPS)} or a Gradient")
        return COLORMAPS[name]()
    table = np.asarray(cmap)
    if table.shape != (256, 3):
        raise ValueError("a colour map table must have shape (256, 3)")
    return table.astype(np.uint8)


def normalise(x, vmin=None, vmax=None) -> np.ndarray:
    """Map `x` to [0, 1]: min-max by default, or a fixed range [vmin, vmax]."""
    x = np.asarray(x, float)
    finite = np.isfinite(x)
    lo = float(np.min(x[finite])) if vmin is None and finite.any() else (0.0 if vmin is None else float(vmin))
    hi = float(np.max(x[finite])) if vmax is None and finite.any() else (1.0 if vmax is None else float(vmax))
    if hi < lo:
        raise ValueError(f"vmax must be >= vmin (got vmin={lo:g}, vmax={hi:g})")
    span = hi - lo
    # a (numerically) constant field renders flat rather than as amplified rounding noise
    flat = span <= 1e-9 * max(1.0, abs(lo), abs(hi)) and vmin is None and vmax is None
    out = np.zeros_like(x) if span == 0 or flat else (x - lo) / span
    return np.clip(np.where(finite, out, 0.0), 0.0, 1.0)

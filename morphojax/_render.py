"""Rendering: concentrations to colour images (PNG through pillow), montages.

Colour maps are 256-entry lookup tables: the perceptually uniform `inferno` (the papers'
choice, default) and `viridis`, `gray`, or a `Gradient` built from colour stops as in the
thesis's `colormap slot` commands, e.g. `Gradient([(0.0, "white"), (1.0, "#5b3504")])`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from pathlib import Path

import numpy as np
from PIL import Image, ImageColor, ImageDraw, ImageFont

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


def to_image(x, cmap="inferno", vmin=None, vmax=None, scale: int = 1) -> Image.Image:
    """A 2D array as an RGB pillow Image through a colour map. `scale` enlarges by pixel repetition."""
    x = np.asarray(x)
    if x.ndim != 2:
        raise ValueError(f"to_image needs a 2D array (got shape {x.shape})")
    idx = (normalise(x, vmin, vmax) * 255).round().astype(np.uint8)
    img = Image.fromarray(colormap_table(cmap)[idx], "RGB")
    if scale != 1:
        img = img.resize((img.width * int(scale), img.height * int(scale)), Image.NEAREST)
    return img


def render(state, species=-1, cmap="inferno", vmin=None, vmax=None, scale: int = 1) -> Image.Image:
    """Render one species of a State (by name or index; default the last, B for Turing)."""
    return to_image(state.arrays()[state.index(species) if species != -1 else -1], cmap, vmin, vmax, scale)


def png_path(path) -> Path:
    """`path` as a Path ending in `.png` (any other suffix replaced): where a picture goes."""
    path = Path(path)
    return path if path.suffix.lower() == ".png" else path.with_suffix(".png")


def save_png(path, image_or_array, **kwargs) -> None:
    """Save a pillow Image, or a 2D array rendered with `to_image(**kwargs)`, as PNG."""
    img = image_or_array if isinstance(image_or_array, Image.Image) else to_image(image_or_array, **kwargs)
    img.save(path, format="PNG")


def montage(images: Sequence[Image.Image], ncols: int, *, row_labels=None, col_labels=None, title=None,
            pad: int = 4, background="white") -> Image.Image:
    """Lay images out on a grid with optional row/column labels and a title (pillow only)."""
    images = list(images)
    if not images:
        raise ValueError("montage needs at least one image")
    nrows = -(-len(images) // ncols)
    w = max(im.width for im in images)
    h = max(im.height for im in images)
    font = ImageFont.load_default()
    probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))

    def text_size(t):
        box = probe.textbbox((0, 0), str(t), font=font)
        return box[2] - box[0], box[3] - box[1]

    left = max((text_size(t)[0] for t in row_labels), default=0) + 2 * pad if row_labels else 0
    top = (max((text_size(t)[1] for t in col_labels), default=0) + 2 * pad) if col_labels else 0
    title_h = text_size(title)[1] + 2 * pad if title else 0
    width = left + ncols * (w + pad) + pad
    height = title_h + top + nrows * (h + pad) + pad
    canvas = Image.new("RGB", (width, height), background)
    draw = ImageDraw.Draw(canvas)
    if title:
        draw.text((pad, pad), str(title), fill="black", font=font)
    for j, label in enumerate(col_labels or []):
        tw, _ = text_size(label)
        draw.text((left + pad + j * (w + pad) + (w - tw) // 2, title_h + pad), str(label), fill="black", font=font)
    for i, label in enumerate(row_labels or []):
        _, th = text_size(label)
        draw.text((pad, title_h + top + pad + i * (h + pad) + (h - th) // 2), str(label), fill="black", font=font)
    for k, im in enumerate(images):
        i, j = divmod(k, ncols)
        canvas.paste(im, (left + pad + j * (w + pad), title_h + top + pad + i * (h + pad)))
    return canvas


def melanin(b, c) -> np.ndarray:
    """The leopard paper's pigmentation texture (Fig. 17 right) from B and C.

    Low B and C map to 0.3, high C to 0.5 and high B to 1.0 (eumelanin over pheomelanin);
    0 is white fur and 1 almost black. B and C are min-max normalised first.
    """
    bn, cn = normalise(b), normalise(c)
    base = 0.3 + 0.2 * cn
    return base + (1.0 - base) * bn


def render_experiment(state, experiment, scale: int = 1) -> Image.Image:
    """The final image of an experiment: its `show` species through its colour map, or the
    leopard's melanin texture (grey: white fur = 0, black = 1) when show == "melanin"."""
    if experiment.show == "melanin":
        m = melanin(state.array("b"), state.array("c"))
        return to_image(1.0 - m, cmap="gray", vmin=0.0, vmax=1.0, scale=scale)
    return to_image(state.array(experiment.show), cmap=experiment.cmap, scale=scale)

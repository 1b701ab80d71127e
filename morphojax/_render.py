"""Rendering: concentrations to colour images (PNG through pillow), montages and labelled pictures.

Colour maps and gradients live a floor below, in `_colours` (re-exported here for the
modules that draw with them); the hexagonal lattice's and the mesh's pictures are drawn by
`_render_hex` and `_render_mesh`, which need only the colours.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from ._colours import COLORMAPS, Gradient, _rgb, colormap_table, normalise  # noqa: F401 (re-exported)
from .domains import HexLattice, Mesh


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


LABEL_SIZE = 11  # pixels: the labels' font (Pillow's own scalable font where it has one)


@functools.lru_cache(maxsize=None)
def label_font():
    """The font of every label and title: Pillow's scalable default at `LABEL_SIZE` (its
    fixed bitmap font, whose spaces are a pixel wide, only where Pillow has no other)."""
    try:
        return ImageFont.load_default(size=LABEL_SIZE)
    except (TypeError, OSError):  # Pillow < 10.1, or built without FreeType
        return ImageFont.load_default()


def montage(images: Sequence[Image.Image], ncols: int, *, row_labels=None, col_labels=None, title=None,
            pad: int = 4, background="white") -> Image.Image:
    """Lay images out on a grid with optional row/column labels and a title (pillow only)."""
    images = list(images)
    if not images:
        raise ValueError("montage needs at least one image")
    nrows = -(-len(images) // ncols)
    w = max(im.width for im in images)
    h = max(im.height for im in images)
    font = label_font()
    probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))

    def text_size(t):
        box = probe.textbbox((0, 0), str(t), font=font)
        return box[2] - box[0], box[3] - box[1]

    left = max((text_size(t)[0] for t in row_labels), default=0) + 2 * pad if row_labels else 0
    top = (max((text_size(t)[1] for t in col_labels), default=0) + 2 * pad) if col_labels else 0
    title_h = text_size(title)[1] + 2 * pad if title else 0
    width = max(left + ncols * (w + pad) + pad, text_size(title)[0] + 2 * pad if title else 0)  # titles whole
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


def tile_montage(arrays, unstable, *, captions=None, row_labels=None, col_labels=None, title=None, cmap="inferno",
                 scale: int | None = None, vmin=None, vmax=None, marks=None) -> Image.Image:
    """2D arrays (n, rows, cols) as one labelled picture, e.g. the members of a parameter grid.

    With `captions` (one per array) the tiles are captioned and laid out on a near-square
    grid; otherwise `col_labels` gives the number of columns and `row_labels` (optional)
    the rows. Each tile is normalised on its own unless vmin/vmax are given; arrays marked
    `unstable` or not finite are grey tiles marked "NaN"; `marks` (a word or "" per tile,
    e.g. "uniform") are written on their tiles. `scale` defaults to about 80 pixels per tile.
    """
    data = np.asarray(arrays)
    if scale is None:
        scale = max(1, 80 // max(data.shape[-2:]))
    tiles = []
    for i in range(len(data)):
        x = data[i]
        if unstable[i] or not np.isfinite(x).all():
            tiles.append(_nan_tile(x.shape, scale))
        else:
            tiles.append(to_image(x, cmap=cmap, vmin=vmin, vmax=vmax, scale=scale))
            if marks is not None and marks[i]:
                _mark(tiles[-1], marks[i])
    if captions is not None:
        ncols = max(1, math.ceil(math.sqrt(len(data))))
        tiles = [_captioned(t, text) for t, text in zip(tiles, captions)]
        return montage(tiles, ncols, title=title)
    return montage(tiles, len(col_labels), row_labels=row_labels, col_labels=col_labels, title=title)


def _nan_tile(shape, scale):
    img = Image.new("RGB", (shape[1] * scale, shape[0] * scale), (128, 128, 128))
    ImageDraw.Draw(img).text((2, 2), "NaN", fill="white")
    return img


def _mark(img, text):
    """Write `text` on a tile, on a white box in its top-left corner (in place)."""
    draw = ImageDraw.Draw(img)
    box = draw.textbbox((2, 2), text, font=label_font())
    draw.rectangle((box[0] - 1, box[1] - 1, box[2] + 1, box[3] + 1), fill="white")
    draw.text((2, 2), text, fill="black", font=label_font())


def _captioned(img, text):
    font = label_font()
    box = ImageDraw.Draw(img).textbbox((0, 0), text, font=font)
    w, h = max(img.width, box[2] - box[0] + 4), img.height + box[3] - box[1] + 6
    canvas = Image.new("RGB", (w, h), "white")
    ImageDraw.Draw(canvas).text((2, 1), text, fill="black", font=font)
    canvas.paste(img, (0, h - img.height))
    return canvas


def map_image(array, x=None, y=None, cmap="inferno", scale: int = 2, title=None):
    """A picture of a parameter-map run, with the x range under it and the y range on the left.

    `x` and `y` are the `(name, start, stop)` given to `parameter_map`.
    """
    img = to_image(np.asarray(array), cmap=cmap, scale=scale)
    font = label_font()
    probe = ImageDraw.Draw(img)

    def size(t):
        b = probe.textbbox((0, 0), t, font=font)
        return b[2] - b[0], b[3] - b[1]

    ylo = f"{y[1]:g}" if y else ""
    yhi = f"{y[2]:g}" if y else ""
    left = max(size(ylo)[0], size(yhi)[0], size(y[0])[0] if y else 0) + 8
    th = size("Ag")[1] + 6
    top = th if title else 0
    canvas = Image.new("RGB", (left + img.width + 4, top + img.height + 2 * th), "white")
    canvas.paste(img, (left, top))
    d = ImageDraw.Draw(canvas)
    if title:
        d.text((4, 2), title, fill="black", font=font)
    if x:
        d.text((left, top + img.height + 2), f"{x[1]:g}", fill="black", font=font)
        d.text((left + img.width - size(f"{x[2]:g}")[0], top + img.height + 2), f"{x[2]:g}", fill="black", font=font)
        d.text((left + (img.width - size(f"{x[0]} ->")[0]) // 2, top + img.height + th), f"{x[0]} ->", fill="black",
               font=font)
    if y:
        d.text((2, top), ylo, fill="black", font=font)
        d.text((2, top + img.height - size(yhi)[1] - 2), yhi, fill="black", font=font)
        d.text((2, top + img.height // 2 - th // 2), f"{y[0]}", fill="black", font=font)
        d.text((2, top + img.height // 2 + 2), "v", fill="black", font=font)
    return canvas


def melanin(b, c) -> np.ndarray:
    """The leopard paper's pigmentation texture (Fig. 17 right) from B and C.

    Low B and C map to 0.3, high C to 0.5 and high B to 1.0 (eumelanin over pheomelanin);
    0 is white fur and 1 almost black. B and C are min-max normalised first.
    """
    bn, cn = normalise(b), normalise(c)
    base = 0.3 + 0.2 * cn
    return base + (1.0 - base) * bn


def experiment_picture(state, experiment) -> tuple[np.ndarray, dict]:
    """What an experiment shows of a state: (2D array, keyword arguments of `to_image`):
    its `show` species through its colour map, or, when show == "melanin", the leopard's
    melanin texture (0 = no pigment, 1 = black) through the experiment's colour map (fur
    tones with "leopard"), or in grey, white fur bright, under the default map."""
    if experiment.show == "melanin":
        m = melanin(state.array("b"), state.array("c"))
        if experiment.cmap == "inferno":
            return 1.0 - m, {"cmap": "gray", "vmin": 0.0, "vmax": 1.0}
        return m, {"cmap": experiment.cmap, "vmin": 0.0, "vmax": 1.0}
    return state.array(experiment.show), {"cmap": experiment.cmap}


def render_experiment(state, experiment, scale: int = 1, vmin=None, vmax=None) -> Image.Image:
    """The final image of an experiment (see `experiment_picture`); `vmin`/`vmax` fix the
    colour range (e.g. one range for all frames of a movie) where the picture has none."""
    array, style = experiment_picture(state, experiment)
    style = {"vmin": vmin, "vmax": vmax} | style
    if isinstance(experiment.phases[-1].domain, HexLattice):  # hexagons, not a sheared grid
        from ._render_hex import hex_image

        return hex_image(array, scale=max(2, 8 * scale), **style)
    if isinstance(experiment.phases[-1].domain, Mesh):  # the surface, seen from one side (grown, if it grows)
        from ._render_mesh import mesh_image

        return mesh_image(experiment.final_domain(state), array, size=384 * max(1, scale), **style)
    return to_image(array, scale=scale, **style)

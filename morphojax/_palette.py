"""Colours taken from a photo: k-means of its pixels in CIELAB, as stops of a colour map.

One piece of code serves the library's pictures (`Gradient.from_photo`, so a preset or a
run can be drawn in an animal's own colours) and the fitting package (`fitting` colours a
fitted coat with `photo_palette`). CIELAB (scikit-image's rgb2lab) is a perceptual space:
Euclidean distance there approximates colour difference, so its clusters are the colours a
person would name.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def kmeans(x, k: int, seed: int = 0, iters: int = 50):
    """Plain k-means (Lloyd's iterations, k-means++ start) of points x (n, d): (centres (k, d), labels (n,))."""
    x = np.asarray(x, np.float64)
    rng = np.random.default_rng(seed)
    centres = [x[rng.integers(len(x))]]
    for _ in range(1, k):
        d2 = np.min([((x - c) ** 2).sum(1) for c in centres], axis=0)
        p = d2 / d2.sum() if d2.sum() > 0 else None
        centres.append(x[rng.choice(len(x), p=p)])
    centres = np.array(centres)
    labels = np.zeros(len(x), int)
    for _ in range(iters):
        labels = np.argmin(((x[:, None, :] - centres[None]) ** 2).sum(-1), axis=1)
        new = np.array([x[labels == j].mean(0) if (labels == j).any() else centres[j] for j in range(k)])
        if np.allclose(new, centres):
            break
        centres = new
    return centres, labels


def photo_palette(rgb, values, k: int = 3, seed: int = 0, max_points: int = 20000) -> list:
    """Stops [(position, (r, g, b))] of the `k` main colours of `rgb` ((h, w, 3) in [0, 1]),
    each at the mean of `values` ((h, w), e.g. a normalised channel) over its cluster,
    sorted by position."""
    from skimage.color import lab2rgb, rgb2lab

    rgb = np.asarray(rgb, np.float64).reshape(-1, 3)
    vals = np.asarray(values, np.float64).reshape(-1)
    if len(rgb) != len(vals):
        raise ValueError(f"rgb and values must have the same pixels (got {len(rgb)} and {len(vals)})")
    if int(k) < 1:
        raise ValueError(f"k (number of colours) must be an integer >= 1 (got {k!r})")
    idx = np.random.default_rng(seed).permutation(len(rgb))[:max_points]
    lab = rgb2lab(rgb[idx][None])[0]
    centres, labels = kmeans(lab, int(k), seed)
    stops = []
    for j in range(int(k)):
        if (labels == j).any():
            colour = np.clip(lab2rgb(centres[j][None, None])[0, 0], 0, 1)
            stops.append((float(vals[idx][labels == j].mean()), tuple(int(round(255 * c)) for c in colour)))
    return sorted(stops)


def photo_stops(source, crop=None, k: int = 3, pigment: str = "dark", seed: int = 0) -> list:
    """The colour stops of a photo's `k` main colours, positions stretched to [0, 1] (see
    `Gradient.from_photo`, which builds its gradient from them)."""
    from PIL import Image, ImageOps

    from ._checks import check_choice

    check_choice(pigment, "pigment", ("dark", "light"))
    if isinstance(source, (str, Path)):
        from ._checks import check_memory
        from ._deep_png import read_deep_png
        from ._files import check_regular_file

        check_regular_file(source, "image")
        try:
            with Image.open(source) as im:
                check_memory(im.size[0] * im.size[1] * 16, f"Gradient.from_photo: the {im.size[0]}x{im.size[1]} "
                             f"image {source}")  # its size, from the header, before it is decoded
                # a 16-bit PNG scaled to 8 bits (Pillow's convert clips a 16-bit grey at 255)
                deep = read_deep_png(im, source)
                img = (deep if deep is not None else ImageOps.exif_transpose(im)).convert("RGB")
        except ValueError:
            raise
        except (OSError, SyntaxError, EOFError, TypeError, IndexError, MemoryError, Image.DecompressionBombError) as err:
            raise ValueError(f"Gradient.from_photo: cannot read image {source}: "
                             f"{str(err).strip() or type(err).__name__}") from None
    elif isinstance(source, Image.Image):
        img = source.convert("RGB")
    else:
        rgb = np.asarray(source)
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"Gradient.from_photo: an array must be (h, w, 3) RGB (got shape {rgb.shape})")
        if rgb.dtype.kind not in "fiu" or not np.all(np.isfinite(rgb)):
            raise ValueError("Gradient.from_photo: an array's colours must be finite real numbers (it holds NaN, "
                             "infinite or complex values)")
        img = Image.fromarray(np.clip(rgb * (255.0 if rgb.dtype.kind == "f" else 1.0), 0, 255).astype(np.uint8))
    if crop is not None:
        x0, y0, x1, y1 = (int(v) for v in crop)
        if not (0 <= x0 < x1 <= img.width and 0 <= y0 < y1 <= img.height):
            raise ValueError(f"Gradient.from_photo: crop {tuple(crop)} lies outside the image of "
                             f"{img.width}x{img.height} pixels")
        img = img.crop((x0, y0, x1, y1))
    img.thumbnail((200, 200))
    rgb = np.asarray(img, np.float64) / 255.0
    from skimage.color import rgb2lab

    lightness = rgb2lab(rgb)[..., 0] / 100.0
    stops = photo_palette(rgb, 1.0 - lightness if pigment == "dark" else lightness, k=k, seed=seed)
    positions = np.array([p for p, _ in stops])
    span = positions.max() - positions.min()
    if len(stops) < 2 or span <= 0:
        named = f" {source}" if isinstance(source, (str, Path)) else ""
        raise ValueError(f"Gradient.from_photo: the photo{named} has fewer than two distinct colours")
    # stretched to [0, 1]: the lowest value of a field takes the lightest (pigment "dark")
    return [((p - positions.min()) / span, c) for p, c in stops]

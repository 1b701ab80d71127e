"""The animal's colours: a palette from the photo's crop, and the fitted coat rendered in it.

`photo_palette` (morphojax's, shared with `mj.Gradient.from_photo`) clusters the crop's
colours with k-means in CIELAB (scikit-image's rgb2lab, a perceptual space where Euclidean
distance approximates colour difference); fitting orders the clusters by the mean target value (the normalised channel after `invert`, pigment high) of
their pixels. The palette is a list of stops (position, (r, g, b)): position is that mean
value, so the simulated pigment (also normalised to [0, 1], pigment high) is coloured by
interpolating between the stops in CIELAB.
"""

from __future__ import annotations

import numpy as np
from PIL import Image

# the clustering shared with `mj.Gradient.from_photo`
from morphojax import kmeans, photo_palette

__all__ = ["GREY", "colourise", "kmeans", "photo_palette", "render_coat"]


GREY = [(0.0, (0, 0, 0)), (1.0, (255, 255, 255))]


def unit(x) -> np.ndarray:
    """A field mapped to [0, 1] by its 2% and 98% quantiles (as the statistics see it)."""
    x = np.asarray(x, float)
    lo, hi = np.quantile(x, [0.02, 0.98])
    return np.clip((x - lo) / max(hi - lo, 1e-9), 0, 1)


def colourise(field, stops) -> np.ndarray:
    """(h, w, 3) uint8: a field in [0, 1] coloured by interpolating the stops in CIELAB."""
    from skimage.color import lab2rgb, rgb2lab

    pos = np.array([s[0] for s in stops], np.float64)
    lab = rgb2lab(np.array([s[1] for s in stops], np.float64)[None] / 255.0)[0]
    if len(pos) == 1:
        pos, lab = np.array([0.0, 1.0]), np.repeat(lab, 2, 0)
    # stretch the stops to [0, 1] so the field's full range uses the whole palette
    pos = (pos - pos.min()) / max(pos.max() - pos.min(), 1e-9)
    f = np.clip(np.asarray(field, np.float64), 0, 1)
    out = np.stack([np.interp(f, pos, lab[:, c]) for c in range(3)], -1)
    return np.round(255 * np.clip(lab2rgb(out), 0, 1)).astype(np.uint8)


def render_coat(result, size=512, palette="photo", seed: int = 0) -> Image.Image:
    """The fitted coat at `size` pixels (see `FitResult.render`)."""
    import dataclasses

    import jax

    import morphojax as mj

    width, height = (size, size) if np.isscalar(size) else (int(size[0]), int(size[1]))
    if palette == "photo":
        stops = result.palette or GREY
    elif palette == "grey":
        stops = GREY
    else:
        stops = list(palette)
    cell_pixels = max(float(result.target.get("cell_pixels", 1.0)), 1.0)
    sim = result.simulator
    field = np.asarray(result.fields["fit"])
    if sim is not None and isinstance(sim.template, (mj.AbstractModel, mj.YoungCA)) and sim.boundary == "wrap":
        rows = min(max(int(np.ceil(height / cell_pixels)), field.shape[0]), 256)
        cols = min(max(int(np.ceil(width / cell_pixels)), field.shape[1]), 256)
        big = dataclasses.replace(sim, shape=(rows, cols))
        field = np.asarray(jax.jit(lambda p, k: big.run(p, k))(result.params, jax.random.key(seed + 12345)))
    elif field.shape[0] * cell_pixels < height or field.shape[1] * cell_pixels < width:
        reps = (int(np.ceil(height / cell_pixels / field.shape[0])), int(np.ceil(width / cell_pixels / field.shape[1])))
        field = np.tile(field, reps)
    img = Image.fromarray(colourise(unit(field), stops), "RGB")
    scale = max(width / img.width, height / img.height)
    img = img.resize((int(np.ceil(img.width * scale)), int(np.ceil(img.height * scale))), Image.BICUBIC)
    return img.crop((0, 0, width, height))

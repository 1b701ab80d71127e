"""16-bit PNGs read at their depth.

Pillow reads a 16-bit grey PNG as mode 'I;16' (all 16 bits), but has no 16-bit colour mode:
it decodes 16-bit RGB, RGBA and grey-with-alpha PNGs to 8 bits (the high byte of each
sample), silently. A photo whose contrast lies below 1/256 of the range (a dark or
low-contrast 16-bit scan) then looks flat. The rule here: a 16-bit PNG is read at 16 bits,
or refused with a ValueError that names the file and says to convert it, never read at 8.

How: Pillow's own PNG decoder runs twice. Unfiltering works on bytes (the filters see
whole pixels of 6 or 8 bytes whatever the raw mode), so decoding the same data with the
little-endian raw mode of the same size ('RGB;16L' for 'RGB;16B') yields the other byte of
every big-endian sample: high bytes from the first pass, low bytes from the second.
Grey with alpha ('LA;16B', 4 bytes a pixel) is decoded once with the raw mode 'RGBA',
which keeps all four bytes. Where this Pillow refuses the second pass (a raw mode it
lacks, or tiles it no longer lets a reader set), the file is refused with the advice to
convert it (imageio, the other reader at hand, decodes PNGs with Pillow too).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageOps

DEPTH = 65535.0  # a 16-bit sample's largest value
# the raw mode Pillow decodes a 16-bit PNG with -> (its bands, the raw mode of a second pass
# giving the samples' low bytes, or None when the first pass holds all 16 bits)
DEEP_RAWMODES = {
    "I;16B": ("L", None),
    "RGB;16B": ("RGB", "RGB;16L"),
    "RGBA;16B": ("RGBA", "RGBA;16L"),
    "LA;16B": ("LA", "RGBA"),
}
LUMINANCE = (0.299, 0.587, 0.114)  # ITU-R 601-2, the weights of Pillow's RGB -> L


class DeepPicture:
    """A picture read at 16 bits: `values` (rows, cols, bands) float32 in [0, 1] (float32
    holds 16-bit samples exactly), with the few methods of a PIL image a loader uses
    (`size`, `mode`, `getbands`, `crop`, `convert` to 8 bits for previews) and `channel`,
    one channel at full depth."""

    def __init__(self, values: np.ndarray, bands: str):
        self.values, self.bands = values, bands

    @property
    def mode(self) -> str:
        return f"{self.bands};16"

    @property
    def size(self) -> tuple[int, int]:
        return self.values.shape[1], self.values.shape[0]

    width = property(lambda self: self.size[0])
    height = property(lambda self: self.size[1])

    def getbands(self) -> tuple[str, ...]:
        return tuple(self.bands)

    def crop(self, box) -> DeepPicture:
        x0, y0, x1, y1 = (int(v) for v in box)
        return DeepPicture(self.values[y0:y1, x0:x1], self.bands)

    def convert(self, mode: str) -> Image.Image:
        """An 8-bit PIL image (each sample rounded to the nearest of 256 levels) in `mode`."""
        eight = np.round(self.values * 255.0).astype(np.uint8)
        return Image.fromarray(eight[..., 0] if self.bands == "L" else eight, self.bands).convert(mode)

    def channel(self, name: str) -> np.ndarray:
        """One channel as float64 in [0, 1], as an 8-bit picture's would be read (luminance by
        Pillow's weights, saturation and value of HSV, alpha only where there is one; colour
        channels ignore alpha), at 16 bits."""
        if name == "alpha":
            if "A" not in self.bands:
                raise ValueError("channel 'alpha' requested but the image has no alpha channel")
            return self.values[..., -1].astype(np.float64)
        if self.bands in ("L", "LA"):
            grey = self.values[..., 0].astype(np.float64)
            return np.zeros_like(grey) if name == "saturation" else grey
        rgb = self.values[..., :3].astype(np.float64)
        if name == "luminance":
            return rgb @ np.asarray(LUMINANCE)
        if name in ("saturation", "value"):
            high, low = rgb.max(axis=-1), rgb.min(axis=-1)
            if name == "value":
                return high
            return np.divide(high - low, high, out=np.zeros_like(high), where=high > 0)
        return rgb[..., "rgb".index(name[0])]


def _rawmode(im: Image.Image) -> str | None:
    """The raw mode of a not yet loaded PNG's one tile (None for anything else)."""
    if im.format != "PNG" or len(getattr(im, "tile", ()) or ()) != 1:
        return None
    args = im.tile[0][3]
    return args if isinstance(args, str) else (args[0] if args and isinstance(args[0], str) else None)


def _with_rawmode(tile, rawmode: str):
    args = tile[3]
    new = tile[:3] + ((rawmode if isinstance(args, str) else (rawmode,) + tuple(args[1:])),)
    return tile._make(new) if hasattr(tile, "_make") else new


def read_deep_png(im: Image.Image, path) -> DeepPicture | None:
    """The 16-bit PNG `im` (opened from `path`, not yet loaded) at its depth, EXIF rotation
    applied; None when it is not a 16-bit PNG (read it as usual). A 16-bit colour PNG this
    Pillow cannot decode twice is refused (ValueError naming the file: convert it)."""
    rawmode = _rawmode(im)
    if rawmode not in DEEP_RAWMODES:
        return None
    bands, second = DEEP_RAWMODES[rawmode]
    first = np.asarray(ImageOps.exif_transpose(im))  # decodes: I;16 (all 16 bits), or the high bytes
    if second is None:
        return DeepPicture((first.astype(np.float32) / DEPTH)[..., None], bands)
    try:
        with Image.open(Path(path)) as again:
            again.tile = [_with_rawmode(again.tile[0], second)]
            other = np.asarray(ImageOps.exif_transpose(again))
        if other.shape != first.shape:
            raise ValueError(f"the second pass gave shape {other.shape}, not {first.shape}")
    except (ValueError, OSError, TypeError, AttributeError, IndexError, KeyError) as err:
        raise ValueError(f"{path} is a 16-bit {bands} PNG, which this Pillow reads only at 8 bits ({err}); convert "
                         "it to 8-bit colour or 16-bit grey first, e.g. with ImageMagick: "
                         "magick IN.png -depth 8 OUT.png") from None
    if bands == "LA":  # the raw pass holds every byte: L high, L low, A high, A low
        words = other.astype(np.uint16)
        samples = np.stack([words[..., 0] << 8 | words[..., 1], words[..., 2] << 8 | words[..., 3]], axis=-1)
    else:
        samples = first.astype(np.uint16) << 8 | other.astype(np.uint16)
    return DeepPicture(samples.astype(np.float32) / DEPTH, bands)

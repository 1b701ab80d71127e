"""Target photos: loading, cropping, channel, inversion, robust normalisation, resolution.

A `Target` is the photo's intensity at *lattice* resolution: one value per simulated cell.
The resolution is `cell_pixels` photo pixels per cell, given by the user or estimated so
that the photo's dominant wavelength spans `wavelength_cells` cells (default 10, in the 8-12
where the simulation is well resolved and still cheap). The estimate removes shading first
(a wide Gaussian high-pass, sigma = 1/8 of the crop) and measures the spectrum of the
resulting pigment map (thresholded at Otsu's level), so illumination gradients and fur
texture do not set the scale. A crop holding fewer than MIN_WAVELENGTHS wavelengths is
refused; fewer than WARN_WAVELENGTHS gives a warning.
"""

from __future__ import annotations

import dataclasses
import struct
from pathlib import Path

import numpy as np
from PIL import Image, ImageOps, UnidentifiedImageError

import morphojax as mj

CHANNELS = ("luminance", "red", "green", "blue", "alpha", "saturation", "value")
MIN_PIXELS = 16  # a crop smaller than this cannot show a texture
MIN_CELLS = 16  # nor can a lattice smaller than this
MIN_WAVELENGTHS = 2.0  # fewer wavelengths across the crop cannot be measured
WARN_WAVELENGTHS = 4.0  # fewer make the statistics noisy
ARRAY_SOURCE = "<array>"  # a Target's `source` when it was made from an array, not a picture


@dataclasses.dataclass
class Target:
    """A texture to fit.

    Attributes:
        field: 2D float array in [0, 1] at lattice resolution (rows, cols).
        pixels: the cropped, normalised photo at full resolution (for previews).
        cell_pixels: photo pixels per lattice cell.
        source, crop, channel, invert, quantiles: how it was made (saved with fits).
    """

    field: np.ndarray
    pixels: np.ndarray
    cell_pixels: float
    source: str = ""
    crop: tuple | None = None
    channel: str = "luminance"
    invert: bool = False
    quantiles: tuple = (0.02, 0.98)
    rgb: np.ndarray | None = None  # the crop's colours (at most 200 px a side), for the palette
    values: np.ndarray | None = None  # the normalised channel at the resolution of `rgb`
    # the pattern's wavelength (cells) the fit aims at, where it is not `field`'s own: a
    # training half carries its whole target's (`fitting.fit` sets it), the one the verdict
    # judges by; a user's value is kept. None: measured on `field`
    # (`fitting._verdict.target_wavelength`)
    wavelength: float | None = None

    def palette(self, k: int = 3) -> list | None:
        """The crop's main colours as stops ordered along the target's values (`photo_palette`), or None without colours."""
        if self.rgb is None:
            return None
        from ._palette import photo_palette

        return photo_palette(self.rgb, self.values, k=k)

    @property
    def shape(self):
        return self.field.shape

    @property
    def photo(self) -> bool:
        """Whether the target is a picture (a file or an image), not an array: its statistics
        carry a camera's error (`fitting.PHOTO_CAMERA`)."""
        return self.source != ARRAY_SOURCE

    def describe(self) -> dict:
        """JSON-ready description of how the target was made (file, crop, channel, inversion, cell pixels)."""
        return {"source": self.source, "crop": list(self.crop) if self.crop else None, "channel": self.channel,
                "invert": self.invert, "quantiles": list(self.quantiles), "cell_pixels": self.cell_pixels,
                "lattice": list(self.field.shape), "pixels": list(self.pixels.shape)}


PIXEL_BYTES = 32  # memory a photo's pixel costs in a fit (its float64 grey, normalised, resampled; the RGB decode)
DEEP_GREYS = ("I;16", "I;16B", "I;16L", "I;16N")  # 16-bit grey modes; 'I' holding values in [0, 65535] is one too
# the modes a target is read from (16-bit greys become `DeepPicture`s, 'I' beyond 16 bits and
# 'F' are read as numbers); premultiplied alpha ('La', 'RGBa'), 'LAB', 'HSV' and the packed
# 'BGR;*' modes have no channels a target can be read from, and are refused
READABLE_MODES = ("1", "L", "LA", "P", "PA", "RGB", "RGBA", "RGBX", "CMYK", "YCbCr", *DEEP_GREYS, "I", "F")


def open_image(path: Path, what: str):
    """The image at `path` as `as_picture` reads it, after its size, read from its header, was
    checked against the memory limit; any failure is a ValueError naming the file."""
    from morphojax._checks import check_memory  # the package's one memory limit (MORPHOJAX_MAX_MEMORY)

    if path.exists() and not path.is_file():
        raise ValueError(f"{what}: {path} is not a regular file")
    try:
        with Image.open(path) as im:
            width, height = im.size  # from the header: nothing decoded yet
            check_memory(width * height * PIXEL_BYTES, f"{what}: the {width}x{height} image {path}")
            return as_picture(im, what, path)
    except FileNotFoundError:
        raise ValueError(f"cannot read image {path}: no such file") from None
    except Image.DecompressionBombError as err:  # Pillow's guard against huge images
        raise ValueError(f"{what}: {path} is too large to open safely ({err}); crop or "
                         "downscale it first (at most about 180 megapixels)") from None
    except ValueError:
        raise
    except (UnidentifiedImageError, OSError, SyntaxError, EOFError, struct.error, TypeError, IndexError,
            MemoryError) as err:  # what Pillow's decoders raise on a broken file
        raise ValueError(f"cannot read image {path}: {str(err).strip() or type(err).__name__}") from None


def as_picture(im: Image.Image, what: str, path=None):
    """The PIL image `im` (opened from `path`, or given open) as a target reads it, the same
    whichever way it came, EXIF rotation applied: a 16-bit picture at its depth as a
    `DeepPicture` (a 16-bit PNG not yet decoded, see `morphojax._deep_png`; a grey of mode
    'I;16*', or 'I' holding values in [0, 65535], as samples / 65535), anything else loaded
    as it is. A mode outside `READABLE_MODES` is a ValueError naming `what` and the modes
    allowed."""
    from morphojax._deep_png import DEPTH, DeepPicture, read_deep_png

    if im.mode not in READABLE_MODES:
        source = f" ({path})" if path is not None else ""
        raise ValueError(f"{what}: an image of mode {im.mode!r}{source} cannot be read; allowed modes: "
                         f"{', '.join(READABLE_MODES)} (convert it first, e.g. image.convert('RGB'))")
    # a PNG not decoded yet: its samples, all 16 bits of them (a 16-bit colour PNG's second
    # pass reopens its file, which an image opened from a file object has not: refused there)
    deep = read_deep_png(im, path if path is not None else (getattr(im, "filename", "") or "<image>"))
    if deep is not None:
        return deep
    im = ImageOps.exif_transpose(im)
    im.load()
    if im.mode in DEEP_GREYS or im.mode == "I":
        samples = np.asarray(im)
        if im.mode in DEEP_GREYS or (samples.size and 0 <= samples.min() and samples.max() <= DEPTH):
            return DeepPicture((samples.astype(np.float32) / DEPTH)[..., None], "L")
    return im


def _channel(img: Image.Image, channel: str) -> np.ndarray:
    if channel not in CHANNELS:
        raise ValueError(f"unknown channel {channel!r}; allowed: {', '.join(CHANNELS)}")
    from morphojax._deep_png import DeepPicture

    if isinstance(img, DeepPicture):  # a 16-bit PNG from `open_image`: every channel at its depth
        return img.channel(channel)
    if img.mode in ("I", "F"):  # one grey channel of numbers (16-bit greys are `DeepPicture`s already)
        if channel == "alpha":
            raise ValueError("channel 'alpha' requested but the image has no alpha channel")
        grey = np.asarray(img, np.float64)
        if channel == "saturation":
            return np.zeros_like(grey)
        if not np.isfinite(grey).all():
            raise ValueError("the image holds NaN or infinite pixels")
        return grey
    if channel == "alpha":
        if "A" not in img.getbands():
            raise ValueError("channel 'alpha' requested but the image has no alpha channel")
        return np.asarray(img.getchannel("A"), np.float64) / 255.0
    rgb = img.convert("RGB")
    if channel == "luminance":
        return np.asarray(rgb.convert("L"), np.float64) / 255.0
    if channel in ("saturation", "value"):
        hsv = np.asarray(rgb.convert("HSV"), np.float64) / 255.0
        return hsv[..., 1] if channel == "saturation" else hsv[..., 2]
    return np.asarray(rgb, np.float64)[..., "rgb".index(channel[0])] / 255.0


def normalise(x: np.ndarray, quantiles=(0.02, 0.98)) -> np.ndarray:
    """Robust normalisation to [0, 1] by two quantiles (values beyond are clipped)."""
    lo, hi = np.quantile(x, quantiles)
    if hi - lo < 1e-6:
        raise ValueError("the target has no contrast: its intensity is (almost) constant in the crop")
    return np.clip((x - lo) / (hi - lo), 0.0, 1.0)


def estimate_cell_pixels(pixels: np.ndarray, wavelength_cells: float = 10.0) -> float:
    """Photo pixels per lattice cell such that the dominant wavelength spans `wavelength_cells`.

    Raises a ValueError when the crop holds fewer than MIN_WAVELENGTHS wavelengths and warns
    below WARN_WAVELENGTHS."""
    x = pixels
    factor = 1
    while max(x.shape) > 512:  # the spectrum's peak needs no more resolution than this
        x = x[: x.shape[0] // 2 * 2, : x.shape[1] // 2 * 2]
        x = 0.25 * (x[::2, ::2] + x[1::2, ::2] + x[::2, 1::2] + x[1::2, 1::2])
        factor *= 2
    from skimage.filters import gaussian

    # remove shading and illumination (scales much larger than the pattern), taper the edges
    x = x - gaussian(x, sigma=min(x.shape) / 8.0, mode="reflect", preserve_range=True)
    from skimage.filters import threshold_otsu

    if np.ptp(x) > 0:  # the pigment map: the pattern's phases, not their shading
        x = (x > threshold_otsu(x)).astype(np.float64)
        x = x - x.mean()
    window = np.outer(np.hanning(x.shape[0]), np.hanning(x.shape[1]))
    freq, power = mj.radial_power_spectrum(x * window)
    # look for the peak between one period per crop and 4 pixels per period
    band = (freq >= 1.0 / min(x.shape)) & (freq <= 0.25)
    if not band.any() or not (power[band] > 0).any():
        raise ValueError("could not measure a dominant wavelength in the target; give cell_pixels explicitly")
    k = int(np.flatnonzero(band)[np.argmax(power[band])])
    lo, hi = max(1, k - 1), min(len(power), k + 2)
    f_peak = float((freq[lo:hi] * power[lo:hi]).sum() / power[lo:hi].sum())
    lam = factor / f_peak
    across = min(pixels.shape) / lam
    if across < MIN_WAVELENGTHS:
        raise ValueError(f"the crop holds {across:.1f} pattern wavelengths ({lam:.0f} px each) across its "
                         f"{min(pixels.shape)} px; at least {MIN_WAVELENGTHS:g} are needed: crop a larger region "
                         "or give cell_pixels")
    if across < WARN_WAVELENGTHS:
        import warnings

        warnings.warn(f"the crop holds only {across:.1f} pattern wavelengths ({lam:.0f} px each); the texture "
                      f"statistics will be noisy (at least {WARN_WAVELENGTHS:g} recommended)", stacklevel=3)
    return float(lam / wavelength_cells)


def resample(pixels: np.ndarray, cell_pixels: float) -> np.ndarray:
    """Area-average the photo down to one value per lattice cell."""
    rows = int(round(pixels.shape[0] / cell_pixels))
    cols = int(round(pixels.shape[1] / cell_pixels))
    if rows < MIN_CELLS or cols < MIN_CELLS:
        raise ValueError(
            f"image too small to measure: at {cell_pixels:.2f} pixels per cell the crop {pixels.shape[1]}x"
            f"{pixels.shape[0]} px gives a {cols}x{rows} lattice; at least {MIN_CELLS}x{MIN_CELLS} cells are needed "
            "(crop a larger region or lower cell_pixels)"
        )
    img = Image.fromarray(pixels.astype(np.float32), mode="F")
    small = img.resize((cols, rows), Image.BOX if cell_pixels >= 1 else Image.BICUBIC)
    return np.clip(np.asarray(small, np.float64), 0.0, 1.0)


def load_target(source, *, crop=None, channel: str = "luminance", invert: bool = False,
                quantiles=(0.02, 0.98), cell_pixels: float | None = None, wavelength_cells: float = 10.0) -> Target:
    """Load a photo (path or array) as a fitting target.

    Args:
        source: image path (any format pillow reads; EXIF orientation is honoured; RGB,
            grey or with alpha; 16-bit PNGs and greys at 16 bits), an open PIL image (read as
            its file would be; modes in `READABLE_MODES`) or a 2D array.
        crop: (x0, y0, x1, y1) pixel box (after EXIF rotation), x1/y1 exclusive.
        channel: "luminance" (default), "red", "green", "blue", "alpha", "saturation", "value".
        invert: if True, dark pigment becomes high values (match a model where the pigment
            species is high where the photo is dark).
        quantiles: the (low, high) quantiles mapped to 0 and 1.
        cell_pixels: photo pixels per lattice cell; None estimates it from the dominant
            wavelength so that it spans `wavelength_cells` cells.
    """
    if isinstance(source, (str, Path)):
        path = Path(source)
        im = open_image(path, "load_target.source")
        name = str(path)
    elif isinstance(source, Image.Image):  # read as its file would be (`as_picture`)
        im, name = as_picture(source, "load_target.source"), "<image>"
    else:
        arr = np.asarray(source, np.float64)
        if arr.ndim != 2:
            raise ValueError(f"an array target must be 2D (got shape {arr.shape})")
        im, name, rgb = None, ARRAY_SOURCE, None
    if im is not None:
        width, height = im.size
        if crop is not None:
            x0, y0, x1, y1 = (int(v) for v in crop)
            if not (0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height):
                raise ValueError(
                    f"crop {tuple(crop)} lies outside the image of {width}x{height} pixels: need "
                    f"0 <= x0 < x1 <= {width} and 0 <= y0 < y1 <= {height}"
                )
            im = im.crop((x0, y0, x1, y1))
        pixels = _channel(im, channel)
        small = im.convert("RGB")
        small.thumbnail((200, 200))
        rgb = np.asarray(small, np.float64) / 255.0
    else:
        pixels = arr
        if crop is not None:
            x0, y0, x1, y1 = (int(v) for v in crop)
            if not (0 <= x0 < x1 <= arr.shape[1] and 0 <= y0 < y1 <= arr.shape[0]):
                raise ValueError(f"crop {tuple(crop)} lies outside the array of {arr.shape[1]}x{arr.shape[0]}")
            pixels = arr[y0:y1, x0:x1]
    if min(pixels.shape) < MIN_PIXELS:
        raise ValueError(f"image too small to measure: {pixels.shape[1]}x{pixels.shape[0]} px, need at least "
                         f"{MIN_PIXELS}x{MIN_PIXELS}")
    if not np.isfinite(pixels).all():
        raise ValueError("the target contains NaN or infinite values")
    pixels = normalise(pixels, quantiles)
    if invert:
        pixels = 1.0 - pixels
    if cell_pixels is None:
        cell_pixels = estimate_cell_pixels(pixels, wavelength_cells)
    elif not (np.isfinite(cell_pixels) and cell_pixels > 0):
        raise ValueError(f"cell_pixels must be a positive number (got {cell_pixels!r})")
    field = resample(pixels, float(cell_pixels))
    values = None
    if rgb is not None:
        values = np.asarray(Image.fromarray(pixels.astype(np.float32), mode="F").resize(
            (rgb.shape[1], rgb.shape[0]), Image.BOX), np.float64)
    return Target(field=field, pixels=pixels, cell_pixels=float(cell_pixels), source=name, rgb=rgb, values=values,
                  crop=tuple(int(v) for v in crop) if crop is not None else None, channel=channel,
                  invert=bool(invert), quantiles=tuple(quantiles))

"""Pattern descriptors: simple numbers that say what a pattern is (NumPy + scikit-image).

- `dominant_wavelength`: the peak of the radially averaged power spectrum, in cells;
- `dark_fraction`: the share of the lattice in the dark phase (below an Otsu threshold);
- spot statistics: number and mean area of connected bright (or dark) regions, counted
  with the lattice's periodic wrap when the boundary is toroidal;
- `classify`: uniform / spots / inverted spots / stripes-labyrinth / unstable (NaN);
- `relative_change`: how much a run still moved over its last steps (RMS change over the
  pattern's contrast), and `settled` = that change below a tolerance. It works on NumPy
  and on JAX arrays (`xp=jax.numpy`), so sweeps compute it inside the compiled batch.
"""

from __future__ import annotations

import dataclasses

import numpy as np


def radial_power_spectrum(x, nbins: int | None = None):
    """Radially averaged power spectrum of a 2D array (mean removed).

    Returns (frequencies in cycles per cell, mean power per frequency bin). Bin width is
    1 / max(rows, cols), so the bins line up with the lattice's own harmonics.
    """
    x = np.asarray(x, float)
    rows, cols = x.shape
    f = np.fft.fft2(x - x.mean())
    power = np.abs(f) ** 2 / x.size
    fy = np.fft.fftfreq(rows)[:, None]
    fx = np.fft.fftfreq(cols)[None, :]
    radius = np.sqrt(fx**2 + fy**2)
    step = 1.0 / max(rows, cols)
    nbins = nbins or int(np.ceil(radius.max() / step)) + 1
    idx = np.minimum(np.round(radius / step).astype(int), nbins - 1)
    total = np.bincount(idx.ravel(), power.ravel(), nbins)
    count = np.bincount(idx.ravel(), minlength=nbins)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1), 0.0)
    return np.arange(nbins) * step, mean


def dominant_wavelength(x) -> float:
    """Wavelength (cells) of the strongest spatial frequency; NaN for a uniform field.

    The peak bin is refined by the power-weighted mean frequency of it and its neighbours.
    """
    x = np.asarray(x, float)
    if not np.isfinite(x).all() or np.ptp(x) <= 1e-12 * max(1.0, np.abs(x).max()):
        return float("nan")
    freq, power = radial_power_spectrum(x)
    power = power.copy()
    power[0] = 0.0
    k = int(np.argmax(power))
    lo, hi = max(1, k - 1), min(len(power), k + 2)
    w = power[lo:hi]
    fpeak = float((freq[lo:hi] * w).sum() / w.sum()) if w.sum() > 0 else float(freq[k])
    return float("inf") if fpeak <= 0 else 1.0 / fpeak


def threshold(x) -> float:
    """Otsu threshold between the dark and bright phases (mid-range for 2-valued inputs)."""
    from skimage.filters import threshold_otsu

    x = np.asarray(x, float)
    if np.ptp(x) == 0:
        return float(x.flat[0])
    return float(threshold_otsu(x))


def dark_fraction(x, thresh=None) -> float:
    """Fraction of cells in the dark phase (below the Otsu threshold, or `thresh`)."""
    x = np.asarray(x, float)
    t = threshold(x) if thresh is None else thresh
    return float((x < t).mean())


def regions(mask, wrap: bool = True):
    """Connected regions (8-connectivity) of a boolean mask; merges across edges when `wrap`.

    Returns (labels, areas) with labels 1..n.
    """
    from skimage.measure import label

    mask = np.asarray(mask, bool)
    lab = label(mask, connectivity=2)
    n = int(lab.max())
    if n == 0:
        return lab, np.zeros(0, int)
    if wrap:
        parent = np.arange(n + 1)

        def find(i):
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        def union(a, b):
            for i, j in zip(a.ravel(), b.ravel()):
                if i and j:
                    ri, rj = find(i), find(j)
                    if ri != rj:
                        parent[max(ri, rj)] = min(ri, rj)

        # opposite edges touch (including diagonal neighbours across the seam)
        for shift in (-1, 0, 1):
            union(lab[0], np.roll(lab[-1], shift))
            union(lab[:, 0], np.roll(lab[:, -1], shift))
        roots = np.array([find(i) for i in range(n + 1)])
        _, relabel = np.unique(roots, return_inverse=True)
        lab = relabel[lab]
        n = int(lab.max())
    areas = np.bincount(lab.ravel(), minlength=n + 1)[1:]
    return lab, areas


@dataclasses.dataclass
class Descriptors:
    """Descriptors of one pattern; `as_dict()` gives a flat row for tables."""

    wavelength: float
    dark_fraction: float
    spots: int
    spot_area: float
    holes: int
    hole_area: float
    contrast: float
    pattern: str
    finite: bool
    change: float = float("nan")  # relative change over the last steps (NaN when not measured)
    settled: bool | None = None  # change < settle_tol (None when not measured)

    def as_dict(self):
        """The descriptors as a plain dict (JSON-ready), one key per field."""
        return dataclasses.asdict(self)


PATTERNS = ("uniform", "spots", "inverted spots", "stripes-labyrinth", "unstable")
SETTLE_TOL = 0.05  # default: settled when the last steps moved the pattern by < 5% of its contrast


def describe(x, wrap: bool = True, uniform_tol: float = 1e-3, previous=None,
             settle_tol: float = SETTLE_TOL) -> Descriptors:
    """Descriptors of a 2D pattern (see the module docstring).

    `uniform_tol` is the relative range (max - min) / max(|mean|, 1) below which the field
    counts as uniform. Spots are bright regions on a dark background; inverted spots (holes)
    are dark regions on a bright background; a pattern is "spots" when the bright phase is
    the minority and falls apart into many compact pieces, and a labyrinth otherwise.

    `previous`: the same field some steps earlier; then `change` is `relative_change(previous,
    x)` and `settled` is `change < settle_tol` (otherwise NaN and None).
    """
    x = np.asarray(x, float)
    change, settled = float("nan"), None
    if previous is not None:
        change = float(relative_change(previous, x, floor=uniform_tol))
        settled = bool(change < settle_tol)
    if not np.isfinite(x).all():
        return Descriptors(np.nan, np.nan, 0, np.nan, 0, np.nan, np.nan, "unstable", False, change, False)
    contrast = float(np.ptp(x))
    if contrast <= uniform_tol * max(abs(float(x.mean())), 1.0):
        return Descriptors(np.nan, 0.0, 0, 0.0, 0, 0.0, contrast, "uniform", True, change, settled)
    t = threshold(x)
    bright = x >= t
    _, spot_areas = regions(bright, wrap)
    _, hole_areas = regions(~bright, wrap)
    frac_dark = float((~bright).mean())
    pattern = _classify(bright, wrap)
    return Descriptors(
        wavelength=dominant_wavelength(x),
        dark_fraction=frac_dark,
        spots=int(len(spot_areas)),
        spot_area=float(spot_areas.mean()) if len(spot_areas) else 0.0,
        holes=int(len(hole_areas)),
        hole_area=float(hole_areas.mean()) if len(hole_areas) else 0.0,
        contrast=contrast,
        pattern=pattern,
        finite=True,
        change=change,
        settled=settled,
    )



def relative_change(previous, last, xp=np, floor: float = 1e-3):
    """How much a field moved between two times, relative to its own contrast.

    Per species (the last two axes are the lattice, any leading axes are species), the RMS
    of `last - previous` divided by the standard deviation of `last`, floored at
    `floor * max(|mean(last)|, 1)` (so a field relaxing to a constant does not divide by
    zero); the largest value over the species. 0 for a frozen pattern, about 1 or more
    when the pattern is still being rearranged; NaN or Inf when a field is not finite.
    `xp=jax.numpy` gives the same number inside compiled code.
    """
    prev, last = xp.asarray(previous), xp.asarray(last)
    axes = (-2, -1)
    rms = xp.sqrt(xp.mean((last - prev) ** 2, axis=axes))
    scale = xp.maximum(xp.std(last, axis=axes), floor * xp.maximum(xp.abs(xp.mean(last, axis=axes)), 1.0))
    return xp.max(rms / scale)


def compactness(labels, wrap: bool = True) -> np.ndarray:
    """Per region, perimeter^2 / (4 pi area) with the perimeter counted in cell edges.

    About 1.6 for a pixelated disc (edge counting overestimates a circle by 4/pi) and
    large for elongated stripes. Index i holds region i + 1.
    """
    lab = np.asarray(labels)
    n = int(lab.max())
    if n == 0:
        return np.zeros(0)
    perimeter = np.zeros(n + 1)
    for axis in (0, 1):
        for shift in (1, -1):
            other = np.roll(lab, shift, axis=axis)
            edge = lab != other
            if not wrap:  # edges at the lattice border do not count as perimeter
                border = np.zeros_like(edge)
                idx = [slice(None)] * 2
                idx[axis] = 0 if shift == 1 else -1
                border[tuple(idx)] = True
                edge &= ~border
            perimeter += np.bincount(lab[edge].ravel(), minlength=n + 1)
    area = np.bincount(lab.ravel(), minlength=n + 1)
    return (perimeter[1:] ** 2) / (4 * np.pi * np.maximum(area[1:], 1))


def _classify(bright, wrap) -> str:
    def isolated(mask):
        # the phase is a minority, in several compact pieces, none of which spans most of it
        if mask.mean() > 0.5:
            return False
        lab, areas = regions(mask, wrap)
        if len(areas) < 2 or areas.max() > 0.5 * areas.sum():
            return False
        return float(np.median(compactness(lab, wrap))) <= 3.0

    if isolated(bright):
        return "spots"
    if isolated(~bright):
        return "inverted spots"
    return "stripes-labyrinth"

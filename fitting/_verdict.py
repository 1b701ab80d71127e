"""The verdict: is the fitted coat as close to the target as the target is to itself?

One job: judge a fit on tiles of the target it did not see, in a texture distance the fit
does not optimise, against two yardsticks, and name the coats that are no answer at all.

**Held-out tiles** (`split_target`). A target wide enough to hold HELDOUT_WAVELENGTHS
pattern wavelengths in each half along both axes is cut in two along its longer axis: the
fit sees the first half, the verdict scores the second. A smaller target is fitted whole and
its verdict says so (`heldout["held_out"]` false): the two halves still give the floor, but
the fit has seen both.

**The texture distance** (`texture_distance`), NumPy, independent of `fitting._stats`:
each field has its shading removed (minus a Gaussian blur of sigma SHADING_WAVELENGTHS
target wavelengths) and is normalised by its 2% and 98% quantiles; then five groups, each
in [0, 1]:
- `spectrum`: the Hellinger distance (over sqrt 2) between radially averaged power spectra
  on one frequency grid (Hann window, zero-padded to SPECTRUM_PAD cells; SPECTRUM_BANDS
  log-spaced bands from 1/64 to 1/2 cycles per cell), each normalised to unit sum;
- `orientation`: half the distance between the structure tensors' coherence vectors
  c (cos 2 theta, sin 2 theta);
- `histogram`: the mean absolute difference of nine quantiles;
- `fraction`: the difference of the pigment fractions (above Otsu's threshold);
- `pieces`: the log ratio of connected pieces (pigment and background) per squared target
  wavelength, over log 10, capped at 1.
The distance is the root mean square of the five groups: 0 for the same texture, near 0.1
for two tiles of one coat, 0.4-0.6 between a coat and white noise.

**Yardsticks** (`judge`): the floor is the distance between the two halves of the target;
the noise is the distance from white noise with the held-out tile's values (its pixels
shuffled) to that tile. A fit is convincing when its mean distance over simulated samples is
at most FLOOR_FACTOR times the floor and at most NOISE_FACTOR times the noise.

**Degenerate coats** (`degenerate`): a fit whose samples are not finite, uniform, grid-scale
(dominant wavelength under GRID_SCALE cells) or off the target's wavelength by more than
WAVELENGTH_TOLERANCE is rejected with the reason; `auto` never ranks a rejected fit above
one that is not, and a rejected fit is never convincing.
"""

from __future__ import annotations

import math

import numpy as np

from ._families import structure_tensor

GRID_SCALE = 4.0  # cells: a pattern finer than this is the lattice's, not a coat's
WAVELENGTH_TOLERANCE = 0.2  # a fit's wavelength within 20% of the target's
HELDOUT_WAVELENGTHS = 4.0  # each half of a split target holds this many wavelengths per axis
SHADING_WAVELENGTHS = 2.0  # shading: what varies slower than this many wavelengths
SPECTRUM_PAD = 128
SPECTRUM_BANDS = 16
FLOOR_FACTOR = 2.0
NOISE_FACTOR = 0.6
GROUPS = ("spectrum", "orientation", "histogram", "fraction", "pieces")


def _prepared(field, wavelength: float) -> np.ndarray:
    """The field without its shading, normalised to [0, 1] by its 2% and 98% quantiles."""
    from skimage.filters import gaussian

    x = np.asarray(field, np.float64)
    x = x - gaussian(x, sigma=SHADING_WAVELENGTHS * wavelength, mode="reflect", preserve_range=True)
    lo, hi = np.quantile(x, (0.02, 0.98))
    return np.clip((x - lo) / max(hi - lo, 1e-12), 0.0, 1.0)


def _radial_spectrum(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies in cycles per cell, power) on the padded grid, Hann-windowed, mean removed."""
    rows, cols = x.shape
    size = max(SPECTRUM_PAD, rows, cols)
    window = np.outer(np.hanning(rows), np.hanning(cols))
    f = np.fft.rfft2((x - x.mean()) * window, s=(size, size))
    power = np.abs(f) ** 2
    radius = np.hypot(np.fft.fftfreq(size)[:, None], np.fft.rfftfreq(size)[None, :])
    idx = np.round(radius * size).astype(int)
    total = np.bincount(idx.ravel(), power.ravel())
    count = np.bincount(idx.ravel())
    return np.arange(len(total)) / size, total / np.maximum(count, 1)


def wavelength_of(field) -> float:
    """The dominant wavelength in cells (the peak of the padded radial spectrum, refined by
    its neighbours' power), measured like the verdict's spectrum; NaN for a flat field."""
    x = np.asarray(field, np.float64)
    if not np.isfinite(x).all() or np.ptp(x) <= 1e-9:
        return float("nan")
    freq, power = _radial_spectrum(x)
    band = (freq >= 1.0 / max(x.shape)) & (freq <= 0.5)
    if not (power[band] > 0).any():
        return float("nan")
    k = int(np.flatnonzero(band)[np.argmax(power[band])])
    lo, hi = max(1, k - 1), min(len(power), k + 2)
    peak = float((freq[lo:hi] * power[lo:hi]).sum() / power[lo:hi].sum())
    return 1.0 / peak


def _bands(x: np.ndarray) -> np.ndarray:
    freq, power = _radial_spectrum(x)
    edges = np.geomspace(1.0 / 64.0, 0.5, SPECTRUM_BANDS + 1)
    idx = np.digitize(freq, edges) - 1
    inside = (idx >= 0) & (idx < SPECTRUM_BANDS)
    bands = np.bincount(idx[inside], power[inside], SPECTRUM_BANDS)
    return bands / max(bands.sum(), 1e-300)


def _coherence_vector(x: np.ndarray) -> np.ndarray:
    """Coherence times (cos 2 theta, sin 2 theta) of the mean gradient (`stripe_angle`'s tensor)."""
    jxx, jyy, jxy = structure_tensor(x)
    norm = jxx + jyy
    return np.zeros(2) if norm <= 0 else np.array([jxx - jyy, 2.0 * jxy]) / norm


def _pieces_per_wavelength2(pigment: np.ndarray, wavelength: float) -> float:
    from skimage.measure import label

    pieces = label(pigment, connectivity=1).max() + label(~pigment, connectivity=1).max()
    return float(pieces) * wavelength**2 / pigment.size


def features(field, wavelength: float) -> dict:
    """The distance's description of one field at the target's `wavelength` (cells)."""
    from skimage.filters import threshold_otsu

    x = _prepared(field, wavelength)
    pigment = x > (threshold_otsu(x) if np.ptp(x) > 0 else 0.5)
    return {"spectrum": np.sqrt(_bands(x)), "orientation": _coherence_vector(x),
            "histogram": np.quantile(x, np.linspace(0.1, 0.9, 9)), "fraction": float(pigment.mean()),
            "pieces": _pieces_per_wavelength2(pigment, wavelength)}


def group_distances(a: dict, b: dict) -> dict:
    """Each group's distance in [0, 1] between two fields' `features`."""
    return {"spectrum": float(np.linalg.norm(a["spectrum"] - b["spectrum"]) / math.sqrt(2.0)),
            "orientation": float(np.linalg.norm(a["orientation"] - b["orientation"]) / 2.0),
            "histogram": float(np.mean(np.abs(a["histogram"] - b["histogram"]))),
            "fraction": abs(a["fraction"] - b["fraction"]),
            "pieces": min(1.0, abs(math.log((a["pieces"] + 1e-3) / (b["pieces"] + 1e-3))) / math.log(10.0))}


def texture_distance(a, b, wavelength: float) -> float:
    """The verdict's distance between two fields (module docstring); fields may differ in size."""
    return _rms(group_distances(features(a, wavelength), features(b, wavelength)))


def _rms(groups: dict) -> float:
    return float(math.sqrt(sum(v * v for v in groups.values()) / len(groups)))


def split_target(field) -> tuple[np.ndarray, np.ndarray, bool]:
    """(training part, held-out part, whether they are apart): the halves along the longer
    axis when each holds HELDOUT_WAVELENGTHS wavelengths per axis, else the whole field
    twice (module docstring)."""
    x = np.asarray(field)
    first, second = halves(x)
    lam = target_wavelength(x)
    apart = bool(np.isfinite(lam) and min(first.shape) >= HELDOUT_WAVELENGTHS * lam)
    return (first, second, True) if apart else (x, x, False)


def target_wavelength(field) -> float:
    """A target's dominant wavelength in cells, its shading (a Gaussian of sigma an eighth of
    its shorter side, as `fitting.estimate_cell_pixels` removes it) removed first: with a
    quarter of the longer side, the pufferfish's round body read 201 cells for its 10-cell dots."""
    from skimage.filters import gaussian

    x = np.asarray(field, np.float64)
    return wavelength_of(x - gaussian(x, sigma=min(x.shape) / 8.0, mode="reflect", preserve_range=True))


def halves(field) -> tuple[np.ndarray, np.ndarray]:
    """The two halves of a field along its longer axis (the within-target floor's pair)."""
    x = np.asarray(field)
    axis = int(x.shape[1] > x.shape[0])
    half = x.shape[axis] // 2
    return (x[:, :half], x[:, half: 2 * half]) if axis else (x[:half], x[half: 2 * half])


def off_scale(wavelength, target_wavelength: float):
    """Whether a pattern of `wavelength` cells (an array of them too) is grid-scale or off the
    target's wavelength by more than WAVELENGTH_TOLERANCE (not-a-number: off)."""
    wavelength = np.asarray(wavelength, np.float64)
    near = np.abs(wavelength / target_wavelength - 1.0) <= WAVELENGTH_TOLERANCE
    return ~(wavelength >= GRID_SCALE) | (~near if np.isfinite(target_wavelength) else False)


def degenerate(samples, target_wavelength: float) -> str | None:
    """Why a fit's simulated samples are no coat (module docstring), or None."""
    samples = [np.asarray(s, np.float64) for s in samples]
    if not all(np.isfinite(s).all() for s in samples):
        return "unstable: the simulation is not finite"
    if all(np.ptp(s) <= 1e-6 * max(1.0, float(np.abs(s).max())) for s in samples):
        return "uniform: no pattern forms"
    lam = float(np.nanmedian([wavelength_of(s) for s in samples]))
    if not np.isfinite(lam):
        return "uniform: no pattern forms"
    if lam < GRID_SCALE:
        return f"wavelength {lam:.1f} cells: grid-scale"
    if np.isfinite(target_wavelength) and abs(lam / target_wavelength - 1.0) > WAVELENGTH_TOLERANCE:
        return f"wavelength {lam:.1f} cells against the target's {target_wavelength:.1f}"
    return None


def noise_distance(tile, wavelength: float, seed: int = 0) -> float:
    """The noise yardstick: the distance from white noise with `tile`'s values (its pixels
    shuffled) to `tile`."""
    tile = np.asarray(tile, np.float64)
    shuffled = np.random.default_rng(seed).permutation(tile.ravel()).reshape(tile.shape)
    return texture_distance(shuffled, tile, wavelength)


def within_yardsticks(distance: float, floor: float, noise: float) -> bool:
    """Whether a distance is convincing: at most FLOOR_FACTOR x the floor and NOISE_FACTOR x the noise."""
    return bool(distance <= FLOOR_FACTOR * floor and distance <= NOISE_FACTOR * noise)


def _scale_of(whole) -> float:
    lam = target_wavelength(whole)
    return lam if np.isfinite(lam) else 10.0  # a flat target: the photos' resampled scale


def _sample_distances(samples, heldout, lam: float) -> tuple[dict, float]:
    """(each group's mean distance, the mean distance) of `samples` to the held-out tile."""
    target = features(heldout, lam)
    per_sample = [group_distances(features(s, lam), target) for s in samples]
    groups = {g: float(np.mean([p[g] for p in per_sample])) for g in GROUPS}
    return groups, float(np.mean([_rms(p) for p in per_sample]))


def heldout_distance(samples, whole, heldout) -> float:
    """The texture distance of a fit's `samples` to the held-out tile (`judge`'s `distance`,
    without the yardsticks): what `auto`'s screen ranks families by."""
    return _sample_distances(samples, heldout, _scale_of(whole))[1]


def judge(samples, whole, heldout, held_out: bool, seed: int = 0) -> dict:
    """The held-out report of a fit: its distance (mean over `samples`), the floor, the noise,
    the groups, the target's and the fit's wavelengths, and whether the fit is convincing
    (before the degenerate check, which `verdict` adds)."""
    lam = _scale_of(whole)
    groups, distance = _sample_distances(samples, heldout, lam)
    first, second = halves(whole)
    floor = texture_distance(first, second, lam)
    noise = noise_distance(heldout, lam, seed)
    convincing = within_yardsticks(distance, floor, noise)
    return {"distance": distance, "floor": floor, "noise": noise, "held_out": bool(held_out), "groups": groups,
            "target_wavelength": lam, "fit_wavelength": float(np.nanmedian([wavelength_of(s) for s in samples])),
            "convincing": convincing}


def verdict_text(family: str, heldout: dict, rejected: str | None, auto: bool) -> str:
    """The verdict in words: convincing or not, by how much, and the nearest family."""
    d, floor, noise = heldout["distance"], heldout["floor"], heldout["noise"]
    where = ("on held-out tiles" if heldout["held_out"] else
             f"on the target's halves (too small to hold a tile out: each half needs {HELDOUT_WAVELENGTHS:g} "
             "wavelengths along both axes)")
    numbers = (f"distance {d:.3f} {where}: {d / max(floor, 1e-12):.1f}x the within-target floor {floor:.3f} "
               f"(convincing at most {FLOOR_FACTOR:g}x) and {d / max(noise, 1e-12):.2f}x white noise's {noise:.3f} "
               f"(at most {NOISE_FACTOR:g}x)")
    if heldout["convincing"] and rejected is None:
        return f"convincing: {family} reproduces this photo; {numbers}"
    lead = "no family reproduces this photo; the nearest is" if auto else "no fit of family"
    tail = "" if auto else " reproduces this photo"
    why = f" (rejected: {rejected})" if rejected else ""
    return f"{lead} {family}{tail}{why}; {numbers}"

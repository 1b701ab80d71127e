"""Texture statistics, differentiable in JAX, computed the same way on a photo and on a
simulated field, so that their distance can drive a fit.

All statistics are computed on the field normalised to [0, 1] by two quantiles (robust to
outliers and to the different concentration units of models and photos), and are
independent of the lattice size: spatial frequencies are in cycles per cell, lags in cells.

- `spectrum`: the radially averaged power spectrum in fixed frequency bins, normalised to
  unit sum and taken in log (shape, not amplitude);
- `wavelength`: dominant wavelength in cells (a soft argmax of the spectrum);
- `quantiles`: sorted values at fixed levels (the intensity histogram);
- `dark`: fraction of the dark phase, with a soft (sigmoid) threshold at 0.5;
- `autocorr`: the radially averaged autocorrelation at a few lags;
- `pyramid` (multi-scale, in the style of Portilla and Simoncelli): a Laplacian pyramid of
  `pyramid_levels` octaves; per octave the log of its band's share of the variance, and between
  neighbouring octaves the correlation of the bands' magnitudes (spots and rosettes couple
  fine and coarse scales where labyrinths at one scale do not);
- `morphology` of the pigment phase (the field's high values; a photo's after `invert`):
  local stripe coherence (the structure tensor averaged by a Gaussian of sigma 1.7 cells,
  a sixth of the 10-cell wavelength photos are resampled to: high in stripes and
  labyrinths, lower around round spots, whatever the global orientation),
  and a granulometry of the light phase: the light area a morphological closing of the
  pigment fills with windows of radius 0.2 and 0.35 of the dominant wavelength (light regions
  narrower than the window: the light centres of rings, as in rosettes, holes, and the gaps
  between dense spots, but not an open background around sparse solid spots); dilation and
  erosion are separable max-pools (differentiable almost everywhere), interpolated linearly
  between whole radii;
- `orientation` (on by default; `StatsConfig(orientation=False)` drops it): structure-
  tensor coherence times (cos 2 theta, sin 2 theta) of the mean gradient, for stripes.
"""

from __future__ import annotations

import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


@dataclasses.dataclass(frozen=True)
class StatsConfig:
    """Which statistics, at which resolution, with which weights in the distance.

    Frequencies in cycles per cell; lags in cells. Weights multiply each group's residuals
    (each group is also divided by the square root of its length, so groups count alike).
    """

    n_bins: int = 24
    f_min: float = 0.02
    f_max: float = 0.5
    levels: tuple = (0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75, 0.85, 0.95)
    lags: tuple = (1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
    normalise_quantiles: tuple = (0.02, 0.98)
    softness: float = 0.05
    # compare pigment maps: each field is softly thresholded at its own Otsu threshold
    # (sigmoid of width `softness`) before the statistics, so a photo's shading and fur
    # texture and a model's concentration profile do not decide the fit
    binarise: bool = True
    orientation: bool = True
    # octaves of the Laplacian pyramid (0 leaves the group out)
    pyramid_levels: int = 3
    morphology: bool = True
    # Typical seed-to-seed standard deviation of each group (measured on 64x64 Turing
    # patterns): residuals are divided by these, so the distance is in units of noise.
    noise: tuple = (("spectrum", 0.15), ("wavelength", 0.02), ("quantiles", 0.01), ("dark", 0.005),
                    ("autocorr", 0.01), ("edges", 0.04), ("moments", 0.02), ("orientation", 0.1),
                    ("pyramid", 0.03), ("morphology", 0.02))
    # extra emphasis per group (1 = as the noise says)
    weights: tuple = ()
    # The target's own observation error per group, in the statistics' units: residuals are
    # divided by sqrt(seed noise^2 + camera^2), the synthetic likelihood of a target measured
    # with an error. () for none; None (the default): `fitting.fit` sets PHOTO_CAMERA for a
    # photo's target and () for an array's.
    camera: tuple | None = None

    def observation(self, name: str) -> float:
        """The target's observation error in one statistics group (0 without one)."""
        return float(dict(self.camera or ()).get(name, 0.0))

    def scale(self, name: str) -> float:
        """The noise scale of one statistics group (its weight in the loss is 1 / scale)."""
        return dict(self.noise).get(name, 1.0) / dict(self.weights).get(name, 1.0)

    def groups(self) -> tuple:
        """Names of the statistics groups in use, in the order of the statistics vector."""
        names = ["spectrum", "wavelength", "quantiles", "dark", "autocorr", "edges", "moments"]
        if self.pyramid_levels:
            names.append("pyramid")
        if self.morphology:
            names.append("morphology")
        if self.orientation:
            names.append("orientation")
        return tuple(names)


# How far a camera moves a coat's statistics (per group, in the statistics' units: the root
# mean square over components, the wavelength's as a log): shading, blur, sensor noise, JPEG,
# fur, perspective and tone at once, the clean photo's statistics against the degraded one's
# at the same scale, on both halves of the photo-like suite's 8 tuning coats
# (`benchmarks/fit_photolike.py --camera --tuning`, fit_photolike-camera-tuning.md). In units
# of the seed-to-seed spread: the histogram groups (quantiles, dark, moments) 15-20, edges 45,
# autocorrelation 8, spectrum, pyramid and morphology 4-5, wavelength 2, orientation 0.5.
# Without it a fit to a photo matched the camera's pigment share first: the known parameters'
# coats scored a loss 68-88% made of those three groups on 6 of the 8, and lost to the fit's
# answer by the loss on 5 (fit_photolike-oracle-tuning-before-camera.md). With it, `auto`
# returned the right family on 7 of the 8 tuning coats (5 before), each within 10% of its
# wavelength (7 before; fit_photolike-tuning.md); on the report seeds 5 of 10 (6 before) and
# 8 of 10 (9; fit_photolike.md): the tuning gain is not confirmed there.
PHOTO_CAMERA = (("spectrum", 0.645), ("wavelength", 0.0418), ("quantiles", 0.155), ("dark", 0.0756),
                ("autocorr", 0.0799), ("edges", 1.78), ("moments", 0.392), ("pyramid", 0.159),
                ("morphology", 0.0887), ("orientation", 0.0488))
"""The camera's error on a photo's statistics, per group (`StatsConfig.camera`): `fitting.fit`
adds it to the seed-to-seed noise of every photo's target."""


def normalise(x, cfg: StatsConfig = StatsConfig()):
    """Map a field to [0, 1] by its `normalise_quantiles` (differentiable)."""
    lo_q, hi_q = cfg.normalise_quantiles
    q = jnp.quantile(x, jnp.array([lo_q, hi_q], x.dtype))
    span = jnp.maximum(q[1] - q[0], 1e-6 * (jnp.abs(q[1]) + 1.0))
    return jnp.clip((x - q[0]) / span, 0.0, 1.0)


def otsu(z, bins: int = 64):
    """Otsu's threshold of values in [0, 1] (maximal between-class variance), in JAX."""
    hist = jnp.histogram(z, bins=bins, range=(0.0, 1.0))[0].astype(z.dtype)
    centres = (jnp.arange(bins, dtype=z.dtype) + 0.5) / bins
    w0 = jnp.cumsum(hist)
    w1 = jnp.sum(hist) - w0
    m0 = jnp.cumsum(hist * centres) / jnp.maximum(w0, 1.0)
    m1 = (jnp.sum(hist * centres) - jnp.cumsum(hist * centres)) / jnp.maximum(w1, 1.0)
    between = w0 * w1 * (m0 - m1) ** 2
    return (jnp.argmax(between).astype(z.dtype) + 1.0) / bins


@functools.lru_cache(maxsize=64)
def _bin_matrix(shape, n_bins, f_min, f_max):
    """(n_bins, rows * cols) averaging matrix of the FFT grid into radial frequency bins."""
    rows, cols = shape
    fy = np.fft.fftfreq(rows)[:, None]
    fx = np.fft.fftfreq(cols)[None, :]
    radius = np.sqrt(fx**2 + fy**2).ravel()
    edges = np.linspace(f_min, f_max, n_bins + 1)
    mats = np.zeros((n_bins, rows * cols), np.float32)
    for k in range(n_bins):
        inside = (radius >= edges[k]) & (radius < edges[k + 1])
        if inside.any():
            mats[k, inside] = 1.0 / inside.sum()
    centres = 0.5 * (edges[:-1] + edges[1:])
    return mats, centres.astype(np.float32)


@functools.lru_cache(maxsize=64)
def _radius(shape):
    fy = np.fft.fftfreq(shape[0])[:, None]
    fx = np.fft.fftfreq(shape[1])[None, :]
    return np.sqrt(fx**2 + fy**2).ravel().astype(np.float32)


@functools.lru_cache(maxsize=64)
def _lag_matrix(shape, lags):
    rows, cols = shape
    dy = np.minimum(np.arange(rows), rows - np.arange(rows))[:, None]
    dx = np.minimum(np.arange(cols), cols - np.arange(cols))[None, :]
    dist = np.sqrt(dx**2 + dy**2).ravel()
    mats = np.zeros((len(lags), rows * cols), np.float32)
    for k, lag in enumerate(lags):
        inside = np.abs(dist - lag) < 0.5
        mats[k, inside] = 1.0 / max(inside.sum(), 1)
    return mats


def _blur(z):
    """The binomial [1, 4, 6, 4, 1] / 16 filter along both axes (periodic)."""
    for axis in (0, 1):
        z = (6.0 * z + 4.0 * (jnp.roll(z, 1, axis) + jnp.roll(z, -1, axis))
             + jnp.roll(z, 2, axis) + jnp.roll(z, -2, axis)) / 16.0
    return z


def pyramid_stats(z, levels: int):
    """Laplacian-pyramid statistics of a field (see the module docstring): `levels` log band
    shares of the variance, then `levels - 1` magnitude correlations of neighbouring octaves.
    Each octave halves the lattice (odd sizes drop their last row or column)."""
    z = z - jnp.mean(z)
    var = jnp.mean(z * z) + 1e-12
    bands = []
    for _ in range(int(levels)):
        smooth = _blur(z)
        bands.append(z - smooth)
        rows, cols = smooth.shape[0] // 2 * 2, smooth.shape[1] // 2 * 2
        s = smooth[:rows, :cols]
        z = 0.25 * (s[0::2, 0::2] + s[1::2, 0::2] + s[0::2, 1::2] + s[1::2, 1::2])
    shares = [jnp.log(jnp.mean(b * b) / var + 1e-6) for b in bands]
    corr = []
    for fine, coarse in zip(bands[:-1], bands[1:]):
        up = jnp.repeat(jnp.repeat(jnp.abs(coarse), 2, 0), 2, 1)  # the coarse octave on the fine grid
        a = jnp.abs(fine[: up.shape[0], : up.shape[1]])
        a, up = a - jnp.mean(a), up - jnp.mean(up)
        corr.append(jnp.mean(a * up) / jnp.sqrt(jnp.mean(a * a) * jnp.mean(up * up) + 1e-12))
    return jnp.stack(shares + corr)


def _max_filter(z, radius: int):
    """The maximum over each cell's (2 radius + 1)^2 window (periodic), as two separable
    1D max-pools (a fifth of the 2D pool's cost, gradients included)."""
    size = 2 * radius + 1
    z = jnp.pad(z, ((radius, radius), (0, 0)), mode="wrap")
    z = jax.lax.reduce_window(z, -jnp.inf, jax.lax.max, (size, 1), (1, 1), "VALID")
    z = jnp.pad(z, ((0, 0), (radius, radius)), mode="wrap")
    return jax.lax.reduce_window(z, -jnp.inf, jax.lax.max, (1, size), (1, 1), "VALID")


LOCAL_SIGMA = 1.7  # cells: the local structure tensor's window, a sixth of a 10-cell wavelength


def _gradients(z):
    """Central differences along a row (x, increasing column) and a column (y), periodic."""
    return 0.5 * (jnp.roll(z, -1, 1) - jnp.roll(z, 1, 1)), 0.5 * (jnp.roll(z, -1, 0) - jnp.roll(z, 1, 0))


def morphology_stats(z, wavelength):
    """Local coherence and the light area closings fill, of the pigment `z` (high = pigment,
    in [0, 1]), at two windows; see the module docstring. `wavelength` in cells sets the
    windows (radius f x wavelength, clipped to 1..6 cells)."""
    gx, gy = _gradients(z)
    # the tensor smoothed by a periodic Gaussian of sigma LOCAL_SIGMA cells, through the FFT
    # (as one product: a cascade of small blurs costs ten times as much to compile and run)
    fy = np.fft.fftfreq(z.shape[0])[:, None]
    fx = np.fft.rfftfreq(z.shape[1])[None, :]
    gain = jnp.asarray(np.exp(-2.0 * np.pi**2 * LOCAL_SIGMA**2 * (fx**2 + fy**2)), z.dtype)
    tensor = jnp.stack([gx * gx, gy * gy, gx * gy])
    jxx, jyy, jxy = jnp.fft.irfft2(jnp.fft.rfft2(tensor) * gain, s=z.shape)
    coherence = jnp.sqrt((jxx - jyy) ** 2 + 4.0 * jxy**2 + 1e-12) / (jxx + jyy + 1e-6)
    weight = jxx + jyy  # where there are edges
    out = [jnp.sum(coherence * weight) / (jnp.sum(weight) + 1e-12)]
    # one program for every wavelength: the closings at windows of radius 1..6, picked below
    radii = jnp.arange(1, 7)
    enclosed = jnp.stack([jnp.mean(-_max_filter(-_max_filter(z, r), r) - z) for r in range(1, 7)])
    for fraction in (0.2, 0.35):  # linear between whole radii, so seeds do not jump between windows
        out.append(jnp.interp(jnp.clip(fraction * wavelength, 1.0, 6.0), radii.astype(z.dtype), enclosed))
    return jnp.stack(out)


def texture_stats(x, cfg: StatsConfig = StatsConfig()) -> dict:
    """The statistics of one 2D field (see the module docstring), as a dict of arrays."""
    x = jnp.asarray(x)
    if x.ndim != 2:
        raise ValueError(f"texture_stats needs a 2D field (got shape {x.shape})")
    z = normalise(x, cfg)
    if cfg.binarise:
        z = jax.nn.sigmoid((z - jax.lax.stop_gradient(otsu(z))) / cfg.softness)
    shape = tuple(z.shape)
    centred = z - jnp.mean(z)
    var = jnp.mean(centred**2) + 1e-12
    f = jnp.fft.fft2(centred)
    power = (jnp.abs(f) ** 2).ravel() / (z.size * var)
    bins, centres = _bin_matrix(shape, cfg.n_bins, cfg.f_min, cfg.f_max)
    spec = jnp.asarray(bins) @ power
    spec = spec / (jnp.sum(spec) + 1e-12)
    out = {"spectrum": jnp.log(spec + 1e-4)}
    # dominant frequency: power-weighted mean of |f| over the full-resolution grid, with the
    # power raised to a high exponent so the peak ring dominates (a soft argmax)
    radius = jnp.asarray(_radius(shape))
    band = (radius >= cfg.f_min) & (radius <= cfg.f_max)
    logp = jnp.where(band, jnp.log(power + 1e-12), -jnp.inf)
    w = jax.nn.softmax(4.0 * logp)  # = p^4 / sum p^4 over the band
    out["wavelength"] = 1.0 / jnp.sum(w * radius)
    out["quantiles"] = jnp.quantile(z, jnp.asarray(cfg.levels, z.dtype))
    out["dark"] = jnp.mean(jax.nn.sigmoid((0.5 - z) / cfg.softness))
    gx, gy = _gradients(z)
    grad2 = gx * gx + gy * gy
    # interface density (edge length per cell, times the wavelength to be scale-free) and
    # the third and fourth moments (spots skew one way, holes the other, stripes neither)
    out["edges"] = jnp.mean(jnp.sqrt(grad2 + 1e-6)) * out["wavelength"]
    sd = jnp.sqrt(var)
    out["moments"] = jnp.stack([jnp.mean(centred**3) / sd**3, jnp.mean(centred**4) / var**2])
    ac = jnp.real(jnp.fft.ifft2(jnp.abs(f) ** 2)).ravel() / (z.size * var)
    out["autocorr"] = jnp.asarray(_lag_matrix(shape, tuple(cfg.lags))) @ ac
    if cfg.pyramid_levels:
        out["pyramid"] = pyramid_stats(z, cfg.pyramid_levels)
    if cfg.morphology:
        out["morphology"] = morphology_stats(z, out["wavelength"])
    if cfg.orientation:
        jxx, jyy, jxy = jnp.mean(gx * gx), jnp.mean(gy * gy), jnp.mean(gx * gy)
        norm = jxx + jyy + 1e-12
        out["orientation"] = jnp.stack([(jxx - jyy) / norm, 2.0 * jxy / norm])
    return out


def stats_vector(stats: dict, cfg: StatsConfig = StatsConfig(), noise: dict | None = None):
    """The statistics as one vector in units of their noise: each component divided by its
    seed-to-seed standard deviation (`noise`, per component, or the config's per-group
    typical values), with the target's observation error added in quadrature (`camera`),
    and each group by sqrt(its length), so every group counts about as much as one
    statistic. The wavelength enters as a log (a relative error)."""
    parts = []
    for name in cfg.groups():
        v = jnp.atleast_1d(stats[name])
        if name == "wavelength":
            v = jnp.log(v)
        if noise is not None and name in noise:
            sd = jnp.maximum(jnp.atleast_1d(noise[name]), 0.25 * cfg.scale(name))
        else:
            sd = cfg.scale(name)
        if cfg.observation(name):  # the target's observation error, in quadrature
            sd = jnp.sqrt(jnp.square(sd) + cfg.observation(name) ** 2)
        parts.append(v / (sd * np.sqrt(v.shape[0])))
    return jnp.concatenate(parts)


def residuals(a: dict, b: dict, cfg: StatsConfig = StatsConfig(), noise: dict | None = None):
    """Residual vector between two sets of statistics, in units of noise."""
    return stats_vector(a, cfg, noise) - stats_vector(b, cfg, noise)


def distance(a: dict, b: dict, cfg: StatsConfig = StatsConfig(), noise: dict | None = None):
    """Squared distance between two sets of statistics: about 2 x (number of groups) between
    two seeds of the same parameters when `noise` is right."""
    d = residuals(a, b, cfg, noise)
    return jnp.sum(d * d)


def noise_of(stats_batch: dict) -> dict:
    """Per-component seed-to-seed standard deviation of a batch of statistics (leading axis
    = seeds); the wavelength's is that of its log."""
    out = {}
    for name, v in stats_batch.items():
        v = jnp.log(v) if name == "wavelength" else v
        out[name] = jnp.std(v, axis=0, ddof=1)
    return out


def mean_stats(fields, cfg: StatsConfig = StatsConfig()) -> dict:
    """Statistics averaged over a stack of fields (seeds), vmapped."""
    stats = jax.vmap(lambda x: texture_stats(x, cfg))(fields)
    return jax.tree_util.tree_map(lambda v: jnp.mean(v, axis=0), stats)


# The same functions as single compiled programs, for calls from Python outside a compiled
# program (the target's statistics, a fit's noise, report and intervals): run op by op, each
# of their operations is compiled on its own for every group's shape in every new process,
# some 400 small programs (benchmarks/results/fit_speed.md)
compiled_texture_stats = eqx.filter_jit(texture_stats)
compiled_distance = eqx.filter_jit(distance)
compiled_stats_vector = eqx.filter_jit(stats_vector)
compiled_noise_of = eqx.filter_jit(noise_of)

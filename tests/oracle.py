"""Independent NumPy/SciPy reference implementations of the model steps (the test oracle).

Written straight from the papers' equations, in float64, with scipy.ndimage doing the
stencil and the boundary (mode="wrap" for toroidal, mode="reflect" for no-flux), so they
share no code with morphojax. The benchmarks time these too, as the NumPy baseline.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.ndimage as ndi

NINE = np.array([[1, 4, 1], [4, -20, 4], [1, 4, 1]], float) / 6.0
FIVE = np.array([[0, 1, 0], [1, -4, 1], [0, 1, 0]], float)
MODES = {"wrap": "wrap", "no-flux": "reflect"}


def laplacian(x, boundary="wrap", stencil="nine-point", dtype=float):
    """The stencil computed in `dtype` (float64 for the tests; a benchmark passes its run's)."""
    kernel = (NINE if stencil == "nine-point" else FIVE).astype(dtype)
    return ndi.correlate(np.asarray(x, dtype), kernel, mode=MODES[boundary])


def turing_rates(a, b, r, s, boundary="wrap", stencil="nine-point", dtype=float):
    """Leopard paper eqs. 3-4, in `dtype` when a and b are (Python-float parameters keep it)."""
    da = 16.0 - a * b + r * s * laplacian(a, boundary, stencil, dtype)
    db = a * b - b - 12.0 + s * laplacian(b, boundary, stencil, dtype)
    return da, db


def bard_rates(a, b, alpha, beta, sp, Da, Db, boundary="wrap", stencil="nine-point"):
    da = sp * (alpha - a * b) + Da * laplacian(a, boundary, stencil)
    db = sp * (a * b - b - beta) + Db * laplacian(b, boundary, stencil)
    return da, db


def gray_scott_rates(u, v, F, k, Du, Dv, boundary="wrap", stencil="nine-point"):
    du = Du * laplacian(u, boundary, stencil) - u * v * v + F * (1.0 - u)
    dv = Dv * laplacian(v, boundary, stencil) + u * v * v - (F + k) * v
    return du, dv


def reinforcement_rate(c, t, w, Dc, boundary="wrap", stencil="nine-point"):
    gamma = 3.0 * math.sqrt(3.0) / (2.0 * w * w)
    return (gamma * (t - w - c) * (t - c) * (t + w - c) + Dc * laplacian(c, boundary, stencil),)


def euler(rates, fields, dt, lower, upper, steps):
    """Forward Euler with a clamp to [lower, upper] after every step (per species)."""
    fields = [np.asarray(f, float).copy() for f in fields]
    for _ in range(steps):
        d = rates(*fields)
        fields = [np.clip(f + dt * df, lo, hi) for f, df, lo, hi in zip(fields, d, lower, upper)]
    return fields


def barrier_terms(x, lo, hi, k=2):
    """Leopard paper section 5.4: 1/(x^k - L^k) and -1/(U^k - x^k) + 1/U^k."""
    out = np.zeros_like(x)
    if np.isfinite(lo):
        out += 1.0 / (x**k - lo**k)
    if np.isfinite(hi):
        out += -1.0 / (hi**k - x**k) + 1.0 / hi**k
    return out


def euler_barrier(rates, fields, dt, lower, upper, steps, k=2):
    fields = [np.asarray(f, float).copy() for f in fields]
    for _ in range(steps):
        d = rates(*fields)
        fields = [f + dt * (df + barrier_terms(f, lo, hi, k)) for f, df, lo, hi in zip(fields, d, lower, upper)]
    return fields


def insert_rows(fields, rows):
    """Random matrix expansion, its new row (leopard paper section 4): in every column j the
    cell at row rows[j] is duplicated and the cells below it move down by one."""
    return [np.stack([np.insert(f[:, j], rows[j], f[rows[j], j]) for j in range(f.shape[1])], axis=1)
            for f in fields]


def insert_cols(fields, cols):
    """Its new column: in every row i the cell at column cols[i] is duplicated."""
    return [np.stack([np.insert(f[i], cols[i], f[i, cols[i]]) for i in range(f.shape[0])]) for f in fields]


# ---- the classic reactions (paper 003 section II.C and the Brusselator), standard forms ----
def fitzhugh_nagumo_rates(u, v, a, b, eps, Du, Dv, boundary="wrap", stencil="nine-point"):
    du = (a - u) * (u - 1.0) * u - v + Du * laplacian(u, boundary, stencil)
    dv = eps * (b * u - v) + Dv * laplacian(v, boundary, stencil)
    return du, dv


def gierer_meinhardt_rates(u, v, rho, mu, nu, Du, Dv, boundary="wrap", stencil="nine-point"):
    du = rho * (u * u / v - mu * u) + Du * laplacian(u, boundary, stencil)
    dv = rho * (u * u - nu * v) + Dv * laplacian(v, boundary, stencil)
    return du, dv


def schnakenberg_rates(u, v, a, b, Du, Dv, boundary="wrap", stencil="nine-point"):
    du = a - u + u * u * v + Du * laplacian(u, boundary, stencil)
    dv = b - u * u * v + Dv * laplacian(v, boundary, stencil)
    return du, dv


def brusselator_rates(u, v, a, b, Du, Dv, boundary="wrap", stencil="nine-point"):
    du = a - (b + 1.0) * u + u * u * v + Du * laplacian(u, boundary, stencil)
    dv = b * u - u * u * v + Dv * laplacian(v, boundary, stencil)
    return du, dv


def pyramid_stats(z, levels):
    """Laplacian-pyramid statistics (fitting's `pyramid` group) by scipy convolutions: per
    octave log(band energy / variance + 1e-6), then neighbouring octaves' magnitude
    correlations (the coarse band repeated 2x2 onto the fine grid)."""
    z = np.asarray(z, np.float64) - np.mean(z)
    var = np.mean(z * z) + 1e-12
    kernel = np.array([1.0, 4.0, 6.0, 4.0, 1.0]) / 16.0
    bands = []
    for _ in range(levels):
        smooth = ndi.convolve1d(ndi.convolve1d(z, kernel, axis=0, mode="wrap"), kernel, axis=1, mode="wrap")
        bands.append(z - smooth)
        s = smooth[: smooth.shape[0] // 2 * 2, : smooth.shape[1] // 2 * 2]
        z = s.reshape(s.shape[0] // 2, 2, s.shape[1] // 2, 2).mean(axis=(1, 3))
    out = [math.log(np.mean(b * b) / var + 1e-6) for b in bands]
    for fine, coarse in zip(bands[:-1], bands[1:]):
        up = np.kron(np.abs(coarse), np.ones((2, 2)))
        a = np.abs(fine[: up.shape[0], : up.shape[1]])
        out.append(np.corrcoef(a.ravel(), up.ravel())[0, 1])
    return np.array(out)


def morphology_stats(z, wavelength):
    """fitting's `morphology` group by scipy: the structure tensor smoothed by a periodic
    Gaussian of sigma 1.7 cells, its edge-weighted mean coherence, and the mean light area a grey
    closing fills (square windows of radius 1..6, interpolated linearly at f x wavelength
    for f = 0.2 and 0.35; periodic)."""
    z = np.asarray(z, np.float64)
    gx = 0.5 * (np.roll(z, -1, 1) - np.roll(z, 1, 1))
    gy = 0.5 * (np.roll(z, -1, 0) - np.roll(z, 1, 0))
    # a periodic Gaussian of sigma 1.7 as a direct sum over wrapped offsets (no FFT)
    offsets = np.arange(-12, 13)
    w1 = np.exp(-offsets**2 / (2 * 1.7**2))
    tensor = []
    for t in (gx * gx, gy * gy, gx * gy):
        t_rows = sum(w * np.roll(t, k, 0) for k, w in zip(offsets, w1)) / w1.sum()
        tensor.append(sum(w * np.roll(t_rows, k, 1) for k, w in zip(offsets, w1)) / w1.sum())
    jxx, jyy, jxy = tensor
    coherence = np.sqrt((jxx - jyy) ** 2 + 4 * jxy**2 + 1e-12) / (jxx + jyy + 1e-6)
    out = [np.sum(coherence * (jxx + jyy)) / (np.sum(jxx + jyy) + 1e-12)]
    filled = [np.mean(ndi.grey_closing(z, size=(2 * r + 1, 2 * r + 1), mode="wrap") - z) for r in range(1, 7)]
    for f in (0.2, 0.35):
        out.append(np.interp(np.clip(f * wavelength, 1, 6), np.arange(1, 7), filled))
    return np.array(out)

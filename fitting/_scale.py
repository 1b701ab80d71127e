"""The target's scale: moving a point along its family's length parameter to a wavelength.

A family declares the parameter that sets its pattern's size and how the wavelength follows
it, wavelength ~ length ** power (`Family.length`, `Family.length_power`). Two stages use it:

- the global design moves every design point to the target's wavelength (`moved_length`;
  where linear stability placed the point there first, `fitting._predicted`, only if it
  settled off it);
- after the local search, the best point is moved to the target's wavelength when the move
  costs no more loss than the fit's own uncertainty allows (`snap_to_wavelength`).

The second keeps the rule that a fit reproduces the pattern's scale. The loss weighs the
wavelength against every other statistic, and a photo's other statistics are the ones a
camera corrupts (blur, fur, noise and JPEG move the spectrum's tail, the edges and the
histogram; they leave the peak where it is). So a local search can settle up to the 20% the
degenerate-coat rule allows away from the target's wavelength at a loss no better, within
its noise, than at the wavelength itself. Among points the likelihood cannot tell apart, the
one at the target's scale is returned. The wavelength here is the verdict's (the peak of each
sample's spectrum, median over seeds: `fitting._verdict.wavelength_of`), the one the
degenerate-coat rule judges and the target's is measured with, not the loss's soft argmax,
which differs from it by up to 10% on one coat. "Cannot tell apart" is the 95% likelihood-ratio
interval along one direction: a loss rise of at most (1 + 1 / seeds) x inflation x
chi2_1(95%) = 3.84, in the synthetic likelihood's units (`fitting._uncertainty`: a
component's variance is 1 + 1 / seeds, inflated by loss / noise floor for a misspecified
fit). No constant here was tuned on data.
"""

from __future__ import annotations

import numpy as np

SNAP_TOLERANCE = 0.05  # a fit within 5% of the target's wavelength is left where it is
SNAP_MOVES = 2  # wavelength ~ length ** power holds only roughly: at most two moves
CHI2_1_95 = 3.841459  # the 95% quantile of chi-square with one degree of freedom


def moved_length(length, wavelength, target_wavelength: float, power: float, low: float, high: float):
    """The length parameter(s) that bring a pattern of `wavelength` to `target_wavelength`
    (wavelength ~ length ** power), clipped to [low, high]; an unknown or non-positive
    wavelength leaves the length where it is."""
    length = np.asarray(length, np.float64)
    wavelength = np.asarray(wavelength, np.float64)
    known = np.isfinite(wavelength) & (wavelength > 0)
    factor = (target_wavelength / np.where(known, wavelength, np.nan)) ** (1.0 / power)
    return np.clip(np.where(known, length * factor, length), low, high)


def snap_threshold(seeds: int, inflation: float) -> float:
    """The loss a move along one direction may add and stay inside the 95% likelihood-ratio
    interval (module docstring)."""
    return (1.0 + 1.0 / int(seeds)) * max(float(inflation), 1.0) * CHI2_1_95


def snap_to_wavelength(theta, loss: float, wavelength: float, loss_at, *, target_wavelength: float, index: int,
                       power: float, low: float, high: float, threshold: float) -> dict:
    """Move `theta` (natural units) along parameter `index` toward `target_wavelength`.

    `loss_at(theta) -> (loss, wavelength)` evaluates a point as the fit does. A move is kept
    while its loss stays within `threshold` of `loss` (the best point's) and its wavelength is
    nearer the target's; at most SNAP_MOVES moves, none when the point is within
    SNAP_TOLERANCE already. Returns {"theta", "loss", "wavelength", "moved", "tried"}: the
    point returned (the start when no move is kept) and every move tried as
    (loss, wavelength) pairs, for the fit's record."""
    theta = np.asarray(theta, np.float64)
    best = {"theta": theta, "loss": float(loss), "wavelength": float(wavelength), "moved": False, "tried": []}
    if not (np.isfinite(target_wavelength) and np.isfinite(loss)):
        return best
    for _ in range(SNAP_MOVES):
        error = abs(best["wavelength"] / target_wavelength - 1.0)
        if not error > SNAP_TOLERANCE:  # within tolerance, or an unknown wavelength
            break
        candidate = best["theta"].copy()
        candidate[index] = moved_length(candidate[index], best["wavelength"], target_wavelength, power, low, high)
        if candidate[index] == best["theta"][index]:  # at a bound: the family cannot go further
            break
        new_loss, new_wavelength = (float(v) for v in loss_at(candidate))
        best["tried"].append((new_loss, new_wavelength))
        nearer = abs(new_wavelength / target_wavelength - 1.0) < error
        if not (nearer and new_loss <= float(loss) + threshold):
            break
        best.update(theta=candidate, loss=new_loss, wavelength=new_wavelength, moved=True)
    return best

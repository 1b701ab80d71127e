"""Saturation limits in the fit's global stage: where each fitted limit binds, and how that
place moves with the parameters that trade against it.

A limit acts only where it binds: beyond that its loss is flat and its gradient zero, and a
target made near the limit that just lets the pattern form has a basin a few hundredths of
the bounds wide along it (the bounded-Ua target: the loss is lowest within about 0.2 of the
true Ua; fit_synthetic.md), which neither the design nor a gradient finds. So each fitted
limit is scanned across its bounds at the best point so far (`LIMIT_SCAN` points
1/LIMIT_SCAN of the bounds apart).

Where the scan's minimum is a narrow band (`is_band`), it can be narrower than a scan step,
so its minimum is found again at 1/FINE of a step around it. And the band moves with the parameters
that trade against the limit: on the saturated-Ua target (true ratio 20, Ua 4.4) the
band lies at Ua 4.18 at ratio 27 and at 4.4 at ratio 20, and a fit that scanned only at the
design's best point (ratio 27) ended in the wrong band at twice the truth's loss
(fit_synthetic.md). So the limit is scanned again at `PROFILE_POINTS` - 1 other values of
each trading parameter (every fitted parameter but the limits, the family's length and the
stripes' angle), each point first moved to the target's wavelength along the length: a
profile of the band. The band's curve through the profile's minima (`Band.at`) is where
the refinement rounds put their points along the limit, two scan steps either side of it,
instead of in a box around one point that the band leaves as soon as the ratio moves; and
the intervals sample its valley (`Band.valley`, `fitting._uncertainty`).
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

LIMIT_SCAN = 48  # points of a fitted limit's scan, about 2% of its bounds apart
BAND_RISE = 1.1  # a scan's minimum is a band when both its neighbours score 10% more (`is_band`)
PROFILE_POINTS = 4  # values of each trading parameter a band is scanned at, the best point's among them
BAND_HALF_WIDTH = 2.0 / LIMIT_SCAN  # the rounds' points lie two scan steps either side of a band
VALLEY_STEPS = 4  # the intervals' samples divide each segment of a band's valley in this many
FINE = 8  # a band's minimum is found again at 1/FINE of a scan step within a step either side
VALLEY_OFFSETS = np.linspace(-1.0, 1.0, 9)  # the valley's samples across the band, in scan steps


def is_band(scan_losses, k: int) -> bool:
    """Whether a limit scan's minimum at index k is a narrow band: both neighbours one scan
    step away score at least BAND_RISE times more (bounded-Ua: its neighbours 18% and 29%
    higher; the five photos' lower_b scans at most 5%, fit_synthetic.md). A minimum at
    either end of the scan is not a band."""
    if k == 0 or k == len(scan_losses) - 1:
        return False
    return bool(min(scan_losses[k - 1], scan_losses[k + 1]) > BAND_RISE * scan_losses[k])


@dataclasses.dataclass(frozen=True)
class Band:
    """A limit's band: where along the limit (unit coordinate) the loss is lowest, as a
    function of the trading parameters. `centre` is the unit point of the first scan's
    minimum (found again at 1/FINE of a step); `curves` one (parameter index, the unit
    points of the band's minima in the order of that parameter) per trading parameter
    whose profile found the band at two values or more, the centre among them."""

    limit: int
    centre: np.ndarray
    curves: tuple = ()  # (j, the minima's unit points, ordered by coordinate j) per trading parameter

    def at(self, units) -> np.ndarray:
        """The band's place along the limit at each unit point: the centre's, moved by each
        curve's change from the centre's value of its parameter (piecewise linear, its end
        segments continued beyond the profile's ends)."""
        units = np.atleast_2d(units)
        place = np.full(len(units), float(self.centre[self.limit]))
        for j, minima in self.curves:
            values, places = minima[:, j], minima[:, self.limit]
            place += _linear(units[:, j], values, places) - _linear(self.centre[j], values, places)
        return place

    def valley(self, unit_point) -> np.ndarray:
        """Unit points along the band's valley through `unit_point` (a fit's optimum): for
        each curve, the path through the optimum and the profile's minima in the order of
        their trading parameter, each segment at VALLEY_STEPS - 1 points between its ends
        and at the minima, each of those moved along the limit by VALLEY_OFFSETS: up to a
        scan step either side, a quarter step apart (the band can be narrower than a scan
        step, and the path between two minima cuts across it where it bends: on the
        saturated-Ua target the truth's loss was 10.0 and samples a scan step from its band
        31). The intervals sample them: the trade-off, where the region's
        walk from the optimum leaves the narrow valley (`fitting._uncertainty`)."""
        start = np.asarray(unit_point, np.float64)
        out = []
        for j, minima in self.curves:
            path = sorted([start, *minima], key=lambda u: u[j])
            for a, b in itertools.pairwise(path):
                t = np.arange(1, VALLEY_STEPS)[:, None] / VALLEY_STEPS
                out.append(a + t * (b - a))
            out.append(np.asarray(minima))
        if not out:
            return np.empty((0, len(start)))
        points = np.concatenate(out)
        across = np.repeat(points, len(VALLEY_OFFSETS), axis=0)
        across[:, self.limit] += np.tile(VALLEY_OFFSETS, len(points)) / LIMIT_SCAN
        across[:, self.limit] = np.clip(across[:, self.limit], 1e-4, 1 - 1e-4)
        return across

    def place(self, units, offsets) -> np.ndarray:
        """`units` with the limit's coordinate put on the band, `offsets` (in [-1, 1]) times
        BAND_HALF_WIDTH from its centre."""
        out = np.array(units, dtype=np.float64, copy=True)
        out[:, self.limit] = np.clip(self.at(out) + np.asarray(offsets) * BAND_HALF_WIDTH, 1e-4, 1 - 1e-4)
        return out


def _linear(x, xs, ys):
    """Piecewise-linear interpolation through (xs, ys) (xs increasing, two or more), the
    end segments continued beyond xs's ends."""
    x = np.asarray(x, np.float64)
    inside = np.interp(x, xs, ys)
    below = ys[0] + (x - xs[0]) * (ys[1] - ys[0]) / (xs[1] - xs[0])
    above = ys[-1] + (x - xs[-1]) * (ys[-1] - ys[-2]) / (xs[-1] - xs[-2])
    return np.where(x < xs[0], below, np.where(x > xs[-1], above, inside))


def scan_line(unit_point, i: int) -> np.ndarray:
    """LIMIT_SCAN copies of a unit point, coordinate i evenly across its bounds."""
    line = np.repeat(np.asarray(unit_point, np.float64)[None], LIMIT_SCAN, axis=0)
    line[:, i] = (np.arange(LIMIT_SCAN) + 0.5) / LIMIT_SCAN
    return line


def profile_values(centre_value: float) -> np.ndarray:
    """The other values of a trading parameter (unit coordinates) a band is scanned at:
    PROFILE_POINTS evenly spread, less the one the centre stands for."""
    values = (np.arange(PROFILE_POINTS) + 0.5) / PROFILE_POINTS
    return values[np.abs(values - centre_value) >= 0.5 / PROFILE_POINTS]


def fine_line(unit_point, i: int) -> np.ndarray:
    """Copies of a unit point (a scan's minimum), coordinate i moved by every 1/FINE of a
    scan step up to one step either way, the point itself left out."""
    offsets = np.arange(-FINE + 1, FINE) / FINE
    offsets = offsets[offsets != 0] / LIMIT_SCAN
    line = np.repeat(np.asarray(unit_point, np.float64)[None], len(offsets), axis=0)
    line[:, i] = np.clip(line[:, i] + offsets, 1e-4, 1 - 1e-4)
    return line


def _band_minimum(evaluate, scan, i: int, evaluations: list, rec):
    """(the unit point, its loss) of a scan's minimum found again at 1/FINE of a step when
    the scan's minimum is a band (None when it is not): a band can be narrower than a scan
    step, its lowest loss between two of the scan's points (module docstring). The fine
    scan's evaluations are recorded as the stage "band"."""
    k = int(np.argmin(scan[2]))
    if not is_band(scan[2], k):
        return None
    stage, rec.stage = rec.stage, "band"
    fine = evaluate(fine_line(scan[0][k], i), move=False)
    rec.stage = stage
    evaluations.append(fine)
    m = int(np.argmin(fine[2]))
    if fine[2][m] < scan[2][k]:
        return np.asarray(fine[0][m], np.float64), float(fine[2][m])
    return np.asarray(scan[0][k], np.float64), float(scan[2][k])


def scan_limits(evaluate, best_unit, best_loss: float, limits, trading, rec):
    """Scan each fitted limit (indices `limits`) at the best point so far, and profile each
    band found along the `trading` parameters (module docstring). `evaluate(units, move)` is
    the design's: (unit points, parameters, losses, wavelengths), with `move` the points
    moved to the target's wavelength. Returns (every evaluation, in order; the bands)."""
    evaluations, bands = [], []
    for i in limits:
        rec.stage = "limits"
        scan = evaluate(scan_line(best_unit, i), move=False)
        evaluations.append(scan)
        k = int(np.argmin(scan[2]))
        band = _band_minimum(evaluate, scan, i, evaluations, rec) if scan[2][k] < best_loss else None
        if scan[2][k] < best_loss:
            best_unit, best_loss = scan[0][k], float(scan[2][k])
        if band is None:
            continue
        centre = band[0]
        if band[1] < best_loss:
            best_unit, best_loss = band
        curves = []
        rec.stage = "profile"
        for j in trading:
            starts = np.repeat(centre[None], len(profile_values(centre[j])), axis=0)
            starts[:, j] = profile_values(centre[j])
            moved = evaluate(starts, move=True)  # the other values, at the target's wavelength
            evaluations.append(moved)
            knots = [centre]  # the band's minima along j (a profile moves only j, a scan only i)
            for point in moved[0]:
                profile = evaluate(scan_line(point, i), move=False)
                evaluations.append(profile)
                m = int(np.argmin(profile[2]))
                if profile[2][m] < best_loss:
                    best_unit, best_loss = profile[0][m], float(profile[2][m])
                minimum = _band_minimum(evaluate, profile, i, evaluations, rec)
                if minimum is not None:
                    knots.append(minimum[0])
                    if minimum[1] < best_loss:
                        best_unit, best_loss = minimum
            if len(knots) >= 2:
                minima = np.stack(knots)
                curves.append((j, minima[np.argsort(minima[:, j], kind="stable")]))
        bands.append(Band(i, centre, tuple(curves)))
    return evaluations, bands

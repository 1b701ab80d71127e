"""One family's global stage: a design over the bounds that finds the basin to search from.

A Latin hypercube (or grid) of `n_design` points over the bounds, evaluated in compiled
batches (`fitting._runs.design_batch`: points x the design's seeds). Each point is also moved
along the family's length parameter to the target's wavelength (and an oriented family's
angle turned to the target's stripes): placed there by linear stability before its run where
the family declares it and the prediction is valid (`fitting._predicted`), moved by the
measured wavelength and the family's scaling law where not, or where the placed point settled
off it. A point off the target's scale (grid-scale, or more than 20% off its wavelength)
scores DEGENERATE_PENALTY more. Each fitted saturation limit is scanned across its bounds at
the best point so far and a narrow band it finds is profiled along the parameters that trade
against it (`fitting._limits`). Then `rounds` Latin hypercubes in boxes around the best
`keep` points (not moved again; halving each round), their points on the limits' bands.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from ._limits import scan_limits
from ._predicted import LANDED, applies, place
from ._runs import design_batch
from ._scale import moved_length
from ._verdict import off_scale

DEGENERATE_PENALTY = 1e6  # added to a design point's loss when it is off the target's scale


@dataclasses.dataclass(frozen=True)
class Design:
    """Every point the global stage evaluated, in order: unit coordinates, parameters, losses
    (penalised off the target's scale), wavelengths; the limits' bands it profiled; and, for a
    screen, each point's seed fields by its parameters' bytes (`samples_at`)."""

    unit: np.ndarray
    thetas: np.ndarray
    losses: np.ndarray
    wavelengths: np.ndarray
    bands: tuple
    samples: dict

    def samples_at(self, theta):
        """The seed fields of the design point `theta` (kept for a screen), or None."""
        return self.samples.get(np.asarray(theta, np.float32).tobytes())


def global_design(sim, space, stats, tstats, rec, *, seed, design, n_design, rounds, keep, batch_size, design_keys,
                  length, length_power, predicted, stripes, keep_samples=False) -> Design:
    """The global stage (module docstring). `length`: the index of the family's length
    parameter (None where it is not fitted); `stripes`: the target's stripe direction where
    an oriented family fits its angle; `predicted`: the family places points by linear
    stability; `keep_samples`: keep each point's seed fields (a screen scores the best's)."""
    names = list(space.names)
    angle = names.index("angle") if stripes is not None else None
    samples = {}  # a screen's design points' seed fields, by their parameters
    # the family declares it, fits its length, has a dispersion relation (`applies`), and the
    # design is a hypercube (a grid's levels along the length would all be placed at one value)
    predictable = predicted and length is not None and design != "grid" and applies(sim)

    def run_batch(thetas):
        pad = (-len(thetas)) % batch_size
        padded = np.concatenate([thetas, np.repeat(thetas[-1:], pad, 0)]) if pad else thetas
        out = [design_batch(sim, space, stats, jnp.asarray(padded[i: i + batch_size], jnp.float32), design_keys,
                            tstats)
               for i in range(0, len(padded), batch_size)]
        vals = np.concatenate([np.asarray(o[0]) for o in out])[: len(thetas)]
        lams = np.concatenate([np.asarray(o[1]) for o in out])[: len(thetas)]
        if keep_samples:  # each point's seeds, for the best one's samples (`auto` scores them)
            fields = np.concatenate([np.asarray(o[2]) for o in out])[: len(thetas)]
            for theta, f in zip(thetas, fields):
                samples[np.asarray(theta, np.float32).tobytes()] = f
        # a point off the target's scale (grid-scale, or more than 20% off its wavelength)
        # ranks after every point that is not (`fitting._verdict.off_scale`)
        vals = np.where(off_scale(lams, float(tstats["wavelength"])), vals + DEGENERATE_PENALTY, vals)
        return np.where(np.isfinite(vals), vals, np.inf), lams

    def evaluate(unit_points, move):
        """Losses at the points; with `move`, each point is first placed at the target's
        wavelength by linear stability where its prediction is valid
        (`fitting._predicted`), then moved to it along the family's length parameter by the
        measured wavelength (wavelength ~ length ** length_power, the family's declaration)
        and, for an oriented family, turned to the target's stripe direction (`stripes`),
        keeping the better of the two. A placed point that settled within LANDED of the
        target's wavelength, and a point the move leaves where it is (a bound, an unknown
        wavelength), is not simulated again."""
        thetas = space.from_unit(np.asarray(unit_points, np.float32))
        placed = np.zeros(len(thetas), bool)
        if move and predictable:
            thetas, placed = place(sim, names, thetas, length, float(tstats["wavelength"]), space.low[length],
                                   space.high[length])
        vals, lams = run_batch(thetas)
        if move and (length is not None or angle is not None):
            moved = thetas.copy()
            if length is not None:
                moved[:, length] = moved_length(thetas[:, length], lams, float(tstats["wavelength"]), length_power,
                                                space.low[length], space.high[length])
            if angle is not None:  # the direction modulo pi, inside the angle's bounds
                low = space.low[angle]
                moved[:, angle] = np.clip(low + (stripes - low) % np.pi, low, space.high[angle])
            for value, theta in zip(vals, thetas):
                rec(value, space.to_free(theta))
            landed = placed & (np.abs(lams / float(tstats["wavelength"]) - 1.0) <= LANDED)
            again = np.flatnonzero(~landed & np.any(moved != thetas, axis=1))
            if again.size:
                thetas, vals, lams = keep_better(thetas, vals, lams, again, moved[again], *run_batch(moved[again]))
            unit_points = space.to_unit(thetas)
        for value, theta in zip(vals, thetas):
            rec(value, space.to_free(theta))
        return unit_points, thetas, vals, lams

    rng = np.random.default_rng(seed)
    rec.stage = "design"
    all_unit, thetas, losses, wavelengths = evaluate(space.design(n_design, design, seed), move=True)
    # each fitted limit scanned at the best point so far, its band profiled along the
    # parameters that trade against it (`fitting._limits`)
    trading = [j for j in range(space.size) if j not in space.limits and j != length and j != angle]
    scans, bands = scan_limits(evaluate, all_unit[np.argmin(losses)], float(losses.min()), space.limits, trading,
                               rec)
    for u_new, th_new, l_new, w_new in scans:
        all_unit = np.concatenate([all_unit, u_new])
        thetas, losses = np.concatenate([thetas, th_new]), np.concatenate([losses, l_new])
        wavelengths = np.concatenate([wavelengths, w_new])
    rec.stage = "design"
    half = 0.25
    for _ in range(int(rounds)):
        best_u = all_unit[np.argsort(losses)[:keep]]
        local = []
        for u in best_u:  # a Latin hypercube in a box around each of the best so far, on the limits' bands
            box = space.design(max(2, n_design // keep), "lhs", int(rng.integers(1 << 30)))
            points = np.clip(u + (2 * box - 1) * half, 1e-4, 1 - 1e-4)
            for band in bands:
                points = band.place(points, 2 * box[:, band.limit] - 1)
            local.append(points)
        # the boxes surround moved points already at the target's wavelength: not moved again
        u_new, th_new, l_new, w_new = evaluate(np.concatenate(local), move=False)
        all_unit = np.concatenate([all_unit, u_new])
        thetas, losses = np.concatenate([thetas, th_new]), np.concatenate([losses, l_new])
        wavelengths = np.concatenate([wavelengths, w_new])
        half *= 0.5
    return Design(all_unit, thetas, losses, wavelengths, tuple(bands), samples)


def keep_better(thetas, vals, lams, rows, moved, moved_vals, moved_lams):
    """Points, losses and wavelengths with rows `rows` replaced by their moved points where
    the move scored lower (ties keep the point); new arrays."""
    thetas, vals, lams = np.array(thetas), np.array(vals), np.array(lams)
    better = np.asarray(moved_vals) < vals[rows]
    thetas[rows[better]], vals[rows[better]], lams[rows[better]] = (
        np.asarray(moved)[better], np.asarray(moved_vals)[better], np.asarray(moved_lams)[better])
    return thetas, vals, lams

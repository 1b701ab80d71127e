"""Credible intervals of fitted parameters: a Laplace approximation of the synthetic likelihood.

The statistics vector s(u) (`stats_vector`, each component in units of its measured
seed-to-seed noise and divided by sqrt(its group's length)) is modelled near the optimum u*
as Gaussian with mean s(u*) + J (u - u*). A group's components are not independent (the
bins of one spectrum, the levels of one pyramid move together), and the distance is built so
that each group counts as one statistic: two samples of the same parameters lie about 2 apart
per group (1 from each), whatever its length. The likelihood counts them the same way: a component has
variance 1 + 1 / seeds (the target is one sample, the fit a mean over `seeds` simulations), so
-log L is the fit's loss / (2 (1 + 1 / seeds)). With a flat prior on the unit coordinates u,
the posterior is then Gaussian with covariance (J^T Sigma^-1 J)^-1 (Wood 2010's synthetic
likelihood, linearised). Counting every component as independent (variance (1 / len_g) x
(1 + 1 / seeds)) gave intervals far too narrow on synthetic targets: they covered the truth in
13 of 39 cases, with errors of up to 28 of their standard deviations
(benchmarks/results/fit_synthetic.md).
J comes from central differences in u with common random numbers (the fit's own keys), since
gradients through truncated runs are biased and a difference of width h averages over the
small-scale ruggedness of the loss.

When the target is not a sample of the model (a photo: loss well above the noise floor),
the variances are inflated by loss / noise floor (the reduced chi-square correction for a
misspecified model), so the intervals widen with the misfit instead of claiming the precision
a perfect model would have.

The loss of a pattern-forming model is rugged and its valleys curve (ratio traded against
scale along a wavelength), so the curvature at the optimum alone still claims too much. The
intervals therefore also take in a region (`likelihood_region`): points around the optimum
(a Latin hypercube three Laplace sds wide, then a walk from the region's extreme points that
follows a curved valley out of the box) whose loss is below a threshold. The threshold is the
best loss plus (1 + 1 / seeds) x inflation x chi2_d(95%), the 95% likelihood-ratio region of
the synthetic likelihood above, or, if larger, the loss a true parameter gives at its 95th
percentile: a chi-square scaled to the noise floor (the mean loss of single simulations
against the fit's mean), with its degrees of freedom moment-matched to those single losses
(2 mean^2 / variance, the variance widened to a prediction's since it is estimated from
eight losses, at most one per statistics group; `sample_quantile`). The second asks
"would a sample of these parameters lie as close to the target?" (an ABC acceptance); the
likelihood-ratio threshold alone fails where the best point sits inside the target's noise:
on the synthetic spots target the best loss was 8.2, below the 12.5 that a sample lies from
its parameters' mean on average (10 groups x (1 + 1 / 4 seeds)). The groups' statistics
move together, so their losses spread like fewer than one chi-square degree of freedom per
group: on a second spots target (seed 10,001) the floor was 5.6 and the truth scored 11.3,
above the 9.7 that one degree per group allowed. Each parameter's interval spans the Laplace
interval and every accepted point: a projection of the joint region, so conservative.
The region is searched only where it can widen an interval: the walk starts from points
extreme along a side the Laplace interval leaves inside the bounds, and where it leaves none
(variances inflated by a photo's misfit stretch every interval to its bounds) the region is
not searched at all. On the README's cheetah fit that region cost 126 evaluations, 34 s of
a 77 s fit, for intervals that spanned every bound either way.

A saturation limit's band is narrower than any step of the walk, and it bends as the ratio
moves (`fitting._limits`): a fit of the saturated-Ua target sat at ratio 33.9, Ua 4.03 (loss
14.9; the truth, ratio 20, Ua 4.4, scored 10.0 with the same seeds), and the region around
it gave the ratio 30.9-34.2.
Where the fit's global stage profiled such a band, points along its valley (the path from
the optimum through the profile's minima, `Band.valley`) are accepted into the region too:
samples along the trade-off, which no box around the optimum reaches.

A parameter is *undetermined* when its 95% interval spans more than half its bounds (in
unit coordinates), or when the information matrix is singular along it (a flat direction,
such as upper_a above where it binds).
"""

from __future__ import annotations

import equinox as eqx
import jax
import numpy as np

from ._stats import compiled_stats_vector, mean_stats, stats_vector

Z95 = 1.959964
# The region's cost, in evaluations of the fit's loss (each `seeds` simulations): 16 d for
# the box, then at most 6 rounds of 4 steps from each of up to 2 d extreme points. A smaller
# box (8 d) or walk (5 x 3) lost coverage on the synthetic targets (see fit_synthetic.md)
REGION_POINTS = 16  # points of the region's first box, per fitted parameter
REGION_WALKS = 6  # rounds of the walk along the region, at most
REGION_STEPS = 4  # steps from each extreme point per round


@eqx.filter_jit
def _vectors(sim, space, cfg, thetas, keys, noise):
    def one(theta):
        params = space.as_dict(theta)
        fields = jax.vmap(lambda k: sim.run(params, k))(keys)
        return stats_vector(mean_stats(fields, cfg), cfg, noise)

    return jax.vmap(one)(thetas)


def group_variances(stats: dict, cfg, seeds: int) -> np.ndarray:
    """Per-component variance of the residual vector: 1 + 1 / seeds, each group one
    statistic (see the module docstring)."""
    n = sum(int(np.size(stats[name])) for name in cfg.groups())
    return np.full(n, 1.0 + 1.0 / seeds)


def laplace_intervals(jacobian, u_star, variances, level_z: float = Z95, flat: float = 1e-8):
    """Posterior sd and interval of each unit coordinate from the Jacobian (n_stats, d) of the
    statistics in u, the per-component variances and the optimum u* (d,).

    Returns (low_u, high_u, sd_u, flat_mask): the interval clipped to [0, 1], and which
    parameters lie along a direction the statistics do not see (information below `flat`
    times the largest)."""
    J = np.asarray(jacobian, np.float64)
    info = J.T @ (J / np.asarray(variances, np.float64)[:, None])
    evals, evecs = np.linalg.eigh(info)
    top = max(float(evals.max()), 1e-300)
    keep = evals > flat * top
    inv = np.where(keep, 1.0 / np.where(keep, evals, 1.0), 0.0)
    cov = (evecs * inv) @ evecs.T
    # a parameter with weight in a dropped (flat) eigen-direction has infinite variance
    flat_mask = (np.abs(evecs[:, ~keep]) > 1e-3).any(axis=1) if (~keep).any() else np.zeros(J.shape[1], bool)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    sd = np.where(flat_mask, np.inf, sd)
    u = np.asarray(u_star, np.float64)
    low = np.clip(u - level_z * sd, 0.0, 1.0)
    high = np.clip(u + level_z * sd, 0.0, 1.0)
    return low, high, sd, flat_mask


CORRELATED = 0.7  # parameters move together when the Laplace posterior's |correlation| reaches this


def correlated_pairs(jacobian, variances, names, flat_mask) -> list:
    """[[a, b], ...]: pairs of parameters whose Laplace posterior correlation (from the
    information J^T Sigma^-1 J, pseudo-inverted) is at least CORRELATED in size; a flat
    parameter (one the statistics do not see) pairs with nothing."""
    J = np.asarray(jacobian, np.float64)
    info = J.T @ (J / np.asarray(variances, np.float64)[:, None])
    cov = np.linalg.pinv(info, hermitian=True)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    pairs = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if flat_mask[i] or flat_mask[j] or sd[i] <= 0 or sd[j] <= 0:
                continue
            if abs(cov[i, j] / (sd[i] * sd[j])) >= CORRELATED:
                pairs.append([names[i], names[j]])
    return pairs


def undetermined_mask(low_u, high_u, flat_mask, span: float = 0.5):
    """Parameters whose interval covers more than `span` of the bounds, or that are flat."""
    return np.asarray(flat_mask) | ((np.asarray(high_u) - np.asarray(low_u)) > span)


def likelihood_region(losses_at, u_star, sd_u, delta: float, seed: int = 0, n: int | None = None,
                      star_loss: float | None = None, open_low=None, open_high=None):
    """Unit points of the 95% region around u*: those whose loss is within `delta` of the
    best loss seen. First a Latin hypercube of `n` points in a box of half-width 3 sd (at
    least 0.03, at most 0.5 of the bounds); then, for up to `REGION_WALKS` rounds, a walk
    along the region: `REGION_STEPS` Gaussian steps (sd half the box's half-width, or a
    quarter of the region's span once that is wider) from each accepted point that is
    extreme along some axis and not yet at its bound, which follows a curved valley out of
    the box. Stops when a round no longer widens the region, or it spans the bounds.
    `losses_at(unit_points)` gives the fit's loss at each point (`star_loss`: the loss at u*,
    when the caller has it). `open_low` / `open_high` (d booleans, default all): the sides
    along which the region can still widen the intervals; the walk starts only from points
    extreme along an open side, and a round widens the region only along one (the Laplace
    interval already reaches a closed side's bound). Returns the accepted points (u* first)
    and every loss."""
    u_star = np.asarray(u_star, np.float64)
    d = len(u_star)
    open_low = np.ones(d, bool) if open_low is None else np.asarray(open_low, bool)
    open_high = np.ones(d, bool) if open_high is None else np.asarray(open_high, bool)
    n = REGION_POINTS * d if n is None else int(n)
    width = np.clip(3.0 * np.where(np.isfinite(sd_u), sd_u, 0.5), 0.03, 0.5)
    rng = np.random.default_rng(seed)
    cells = np.stack([rng.permutation(n) for _ in range(d)], axis=1)
    box = np.clip(u_star + (2.0 * (cells + rng.uniform(size=(n, d))) / n - 1.0) * width, 0.0, 1.0)
    points = np.concatenate([u_star[None], box])
    if star_loss is None:
        losses = np.asarray(losses_at(points), np.float64)
    else:
        losses = np.concatenate([[float(star_loss)], np.asarray(losses_at(box), np.float64)])

    def accepted():
        ok = np.isfinite(losses) & (losses <= np.nanmin(losses) + delta)
        return points[ok | (np.arange(len(points)) == 0)]

    for _ in range(REGION_WALKS):
        region = accepted()
        span = np.ptp(region, axis=0)
        low, high = region.min(axis=0), region.max(axis=0)
        ends = [i for i, u in enumerate(region)  # extreme along an open side where there is room left
                if ((u == low) & (low > 0.0) & open_low).any() or ((u == high) & (high < 1.0) & open_high).any()]
        if not ends:
            break
        starts = np.repeat(region[ends], REGION_STEPS, axis=0)
        scale = 0.5 * np.maximum(width, 0.5 * span)  # the steps lengthen as the region does
        steps = np.clip(starts + rng.normal(size=starts.shape) * scale, 0.0, 1.0)
        points = np.concatenate([points, steps])
        losses = np.concatenate([losses, np.asarray(losses_at(steps), np.float64)])
        now = accepted()
        widened = (low - now.min(axis=0)) * open_low + (now.max(axis=0) - high) * open_high
        if (widened <= 0.01 * width).all():
            break
    return accepted(), losses


def sample_quantile(floor: float, groups: int, floor_losses=None, level: float = 0.95) -> float:
    """The `level` quantile of the loss a sample of the fitted parameters would score: a
    scaled chi-square with the noise floor as its mean and k degrees of freedom, k moment-
    matched to the single samples' losses where they are given, at most one per statistics
    group (module docstring).

    The spread is estimated from the n given losses, so the variance is that of a new
    sample's prediction: the sample variance x (1 + 1 / n) x (t_{n-1} / z)^2 at `level`, the
    factor that turns the plug-in bound mean + z s into the prediction bound mean + t_{n-1} s
    sqrt(1 + 1 / n) of normal losses (about 1.5 for n = 8). The plug-in quantile of eight
    chi-square losses is exceeded by a ninth 6-10% of the time, this one 4-7.3% (2 to 12
    degrees of freedom; tests)."""
    from scipy.stats import chi2, norm, t  # imported here: `import fitting` stays light

    k = float(groups)
    losses = None if floor_losses is None else np.asarray(floor_losses, np.float64)
    if losses is not None and len(losses) >= 3 and np.var(losses, ddof=1) > 0:
        n = len(losses)
        predictive = np.var(losses, ddof=1) * (1.0 + 1.0 / n) * (t.ppf(level, n - 1) / norm.ppf(level)) ** 2
        k = float(np.clip(2.0 * np.mean(losses) ** 2 / predictive, 1.0, groups))
    return float(floor) * float(chi2.ppf(level, k)) / k


BETTER = 0.98  # the region holds a better optimum where a point's loss is below this x the fit's


def interval_report(sim, space, cfg, theta, keys, tstats, noise, h: float = 0.04, inflate: float = 1.0,
                    seed: int = 0, floor: float = 0.0, floor_losses=None, valley=None):
    """({name: (low, high)} in natural units, [undetermined names], [correlated pairs],
    better) at the fitted `theta` (`correlated_pairs`); `better` is None, or (theta, loss)
    of the lowest point the region's walk found when its loss is below BETTER x the fit's:
    the local search stopped short of a lower basin along the region's valley (the fit goes
    on from there, `fitting._fit._conclude`);
    `inflate` (>= 1) multiplies the variances (loss / noise floor for a misspecified fit);
    without a region to search (the Laplace intervals reach every bound) `better` is None;
    `floor`, the fit's noise floor (the mean of `floor_losses`, single samples' losses),
    sets the region's absolute threshold (module docstring, `sample_quantile`); `valley`
    (unit points, or None) are samples along a saturation limit's trade-off
    (`fitting._limits.Band.valley`), accepted into the region as its own points are."""
    from scipy.stats import chi2

    u_star = space.to_unit(np.asarray(theta))
    u0 = np.clip(u_star, h, 1 - h)  # the difference points stay inside the bounds
    d = space.size
    pts = np.concatenate([u0 + h * np.eye(d), u0 - h * np.eye(d)])
    thetas = space.from_unit(np.asarray(pts, np.float32))
    vecs = np.asarray(_vectors(sim, space, cfg, thetas, keys, noise), np.float64)
    if not np.isfinite(vecs).all():
        return {n: (float("nan"), float("nan")) for n in space.names}, list(space.names), [], None
    J = (vecs[:d] - vecs[d:]).T / (2 * h)
    var = group_variances(tstats, cfg, len(keys)) * max(float(inflate), 1.0)
    scale = float(var[0])  # every component's variance: the loss in units of -2 log L
    low, high, sd, flat = laplace_intervals(J, u_star, var)
    correlated = correlated_pairs(J, var, space.names, flat)
    target = np.asarray(compiled_stats_vector(tstats, cfg, noise), np.float64)

    seen = []  # every point the region evaluates, with its loss

    def losses_at(units):  # in batches of 2d, the Jacobian's: the same compiled program
        out = []
        for i in range(0, len(units), 2 * d):
            part = units[i: i + 2 * d]
            padded = np.concatenate([part, np.repeat(part[-1:], 2 * d - len(part), 0)])
            v = np.asarray(_vectors(sim, space, cfg, space.from_unit(np.asarray(padded, np.float32)), keys, noise),
                           np.float64)
            out.append(((v - target) ** 2).sum(axis=1)[: len(part)])
        seen.extend(zip(np.asarray(units), np.concatenate(out)))
        return np.concatenate(out)

    # the sides the Laplace interval leaves inside the bounds: only there can the region widen
    # an interval (each is the union of both). Where it leaves none (a flat or a badly
    # misfitted direction on every parameter) the region is not searched, nor a lower point in it
    open_low, open_high = low > 0.0, high < 1.0
    better = None
    if open_low.any() or open_high.any():
        groups = len(cfg.groups())
        sample_q95 = sample_quantile(floor, groups, floor_losses) if np.isfinite(floor) else 0.0
        best = float(losses_at(u_star[None])[0])
        delta = max(scale * float(chi2.ppf(0.95, d)), sample_q95 - best)  # the likelihood-ratio region
        region, _ = likelihood_region(losses_at, u_star, sd, delta, seed, star_loss=best, open_low=open_low,
                                      open_high=open_high)
        if valley is not None and len(valley):
            along = np.asarray(valley, np.float64)
            region = np.concatenate([region, along[losses_at(along) <= best + delta]])
        low, high = np.minimum(low, region.min(axis=0)), np.maximum(high, region.max(axis=0))
        u_low, loss_low = min(seen, key=lambda item: item[1] if np.isfinite(item[1]) else np.inf)
        if loss_low < BETTER * best:
            better = (space.from_unit(np.asarray(u_low, np.float32)), float(loss_low))
    und = undetermined_mask(low, high, flat)
    out = {}
    for i, n in enumerate(space.names):
        lo_u, hi_u = u_star.copy(), u_star.copy()
        lo_u[i], hi_u[i] = low[i], high[i]
        a = float(space.from_unit(np.asarray(lo_u, np.float32))[i])
        b = float(space.from_unit(np.asarray(hi_u, np.float32))[i])
        out[n] = (min(a, b), max(a, b))
    return out, [n for n, f in zip(space.names, und) if f], correlated, better

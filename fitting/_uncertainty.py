"""Credible intervals of fitted parameters: a Laplace approximation of the synthetic likelihood.

The statistics vector s(u) (`stats_vector`, each component in units of its measured
seed-to-seed noise and divided by sqrt(its group's length)) is modelled near the optimum u*
as Gaussian with mean s(u*) + J (u - u*) and diagonal covariance Sigma: a component of group
g has variance (1 / len_g) x (1 + 1 / seeds) (the target is one sample, the fit a mean over
`seeds` simulations). With a flat prior on the unit coordinates u, the posterior is then
Gaussian with covariance (J^T Sigma^-1 J)^-1 (Wood 2010's synthetic likelihood, linearised).
J comes from central differences in u with common random numbers (the fit's own keys), since
gradients through truncated runs are biased and a difference of width h averages over the
small-scale ruggedness of the loss.

When the target is not a sample of the model (a photo: loss well above the noise floor),
the variances are inflated by loss / noise floor (the reduced chi-square correction for a
misspecified model), so the intervals widen with the misfit instead of claiming the precision
a perfect model would have.

A parameter is *undetermined* when its 95% interval spans more than half its bounds (in
unit coordinates), or when the information matrix is singular along it (a flat direction,
such as upper_a above where it binds).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._stats import mean_stats, stats_vector

Z95 = 1.959964


@eqx.filter_jit
def _vectors(sim, space, cfg, thetas, keys, noise):
    def one(theta):
        params = space.as_dict(theta)
        fields = jax.vmap(lambda k: sim.run(params, k))(keys)
        return stats_vector(mean_stats(fields, cfg), cfg, noise)

    return jax.vmap(one)(thetas)


def group_variances(stats: dict, cfg, seeds: int) -> np.ndarray:
    """Per-component variance of the residual vector (see the module docstring)."""
    parts = []
    for name in cfg.groups():
        n = int(np.size(stats[name]))
        parts.append(np.full(n, (1.0 / n) * (1.0 + 1.0 / seeds)))
    return np.concatenate(parts)


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


def undetermined_mask(low_u, high_u, flat_mask, span: float = 0.5):
    """Parameters whose interval covers more than `span` of the bounds, or that are flat."""
    return np.asarray(flat_mask) | ((np.asarray(high_u) - np.asarray(low_u)) > span)


def interval_report(sim, space, cfg, theta, keys, tstats, noise, h: float = 0.04, inflate: float = 1.0):
    """({name: (low, high)} in natural units, [undetermined names]) at the fitted `theta`;
    `inflate` (>= 1) multiplies the variances (loss / noise floor for a misspecified fit)."""
    u_star = space.to_unit(np.asarray(theta))
    u0 = np.clip(u_star, h, 1 - h)  # the difference points stay inside the bounds
    d = space.size
    pts = np.concatenate([u0 + h * np.eye(d), u0 - h * np.eye(d)])
    thetas = space.from_unit(jnp.asarray(pts, jnp.float32))
    vecs = np.asarray(_vectors(sim, space, cfg, thetas, keys, noise), np.float64)
    if not np.isfinite(vecs).all():
        return {n: (float("nan"), float("nan")) for n in space.names}, list(space.names)
    J = (vecs[:d] - vecs[d:]).T / (2 * h)
    var = group_variances(tstats, cfg, len(keys)) * max(float(inflate), 1.0)
    low, high, _, flat = laplace_intervals(J, u_star, var)
    und = undetermined_mask(low, high, flat)
    out = {}
    for i, n in enumerate(space.names):
        lo_u, hi_u = u_star.copy(), u_star.copy()
        lo_u[i], hi_u[i] = low[i], high[i]
        a = float(np.asarray(space.from_unit(jnp.asarray(lo_u, jnp.float32)))[i])
        b = float(np.asarray(space.from_unit(jnp.asarray(hi_u, jnp.float32)))[i])
        out[n] = (min(a, b), max(a, b))
    return out, [n for n, f in zip(space.names, und) if f]

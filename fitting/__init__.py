"""fitting: infer morphojax parameters from a target photo's texture statistics.

    import fitting
    target = fitting.load_target("targets/cheetah-01.jpg", crop=(300, 200, 700, 500), invert=True)
    result = fitting.fit(target, model="turing", fit=["ratio", "scale"])
    result.params, result.loss, result.noise_floor
    result.save_json("fit.json"); result.preview("fit.png")

How it works (and why): see `fitting._fit` (stages), `fitting._stats` (statistics),
`fitting._simulator` (forward model, time step, truncated gradients) and the README section
"Fitting". In short: statistics are compared in units of their seed-to-seed noise, averaged
over a few vmapped seeds; a coarse vmapped design finds the basin; Optimistix refines it with
gradients through the last steps of the simulation (exact gradients over whole runs are
dominated by where single spots sit and grow without bound, so only the final relaxation is
differentiated); Nelder-Mead takes over when gradients do not help.
"""

from ._fit import METHODS, FitResult, fit, gradient_descent
from ._report import loss_curve, preview, region_stats
from ._simulator import Simulator
from ._space import DEFAULT_BOUNDS, ParamSpace
from ._stats import StatsConfig, distance, mean_stats, noise_of, residuals, stats_vector, texture_stats
from ._target import CHANNELS, Target, estimate_cell_pixels, load_target

__all__ = [
    "CHANNELS",
    "DEFAULT_BOUNDS",
    "FitResult",
    "METHODS",
    "ParamSpace",
    "Simulator",
    "StatsConfig",
    "Target",
    "distance",
    "estimate_cell_pixels",
    "fit",
    "gradient_descent",
    "load_target",
    "loss_curve",
    "mean_stats",
    "noise_of",
    "preview",
    "region_stats",
    "residuals",
    "stats_vector",
    "texture_stats",
]

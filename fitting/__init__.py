"""fitting: infer morphojax parameters from a target photo's texture statistics.

    import fitting
    target = fitting.load_target("targets/cheetah-01.jpg", crop=(300, 200, 700, 500), invert=True)
    result = fitting.fit(target)  # model="auto": every family screened, the best fitted
    result.convincing, result.verdict  # judged on a held-out half of the target (`fitting._verdict`)
    result.family, result.params, result.intervals, result.undetermined, result.ranking
    result.render("coat.png", size=1024)  # the fitted coat in the photo's colours
    result.save_json("fit.json"); result.preview("fit.png")

How it works (and why): see `fitting._pipeline` (the stages, top to bottom), `fitting._verdict`
(the held-out verdict), `fitting._fit` (one family's fit), `fitting._stats` (statistics),
`fitting._simulator` (forward model, time step, truncated gradients) and the README section
"Fitting". In short: statistics are compared in units of their seed-to-seed noise, averaged
over a few vmapped seeds; a coarse vmapped design finds the basin; Optimistix refines it with
gradients through the last steps of the simulation (exact gradients over whole runs are
dominated by where single spots sit and grow without bound, so only the final relaxation is
differentiated); Nelder-Mead takes over when gradients do not help.
"""

from ._auto import ORIENTED_COHERENCE, penalised
from ._families import FAMILIES, Family, family, stripe_angle
from ._search import METHODS, gradient_descent
from ._pipeline import DEFAULTS, fit, progress_default
from ._result import FitResult
from ._verdict import texture_distance
from ._palette import colourise, kmeans, photo_palette
from ._uncertainty import laplace_intervals
from ._report import loss_curve, preview, region_stats
from ._simulator import Simulator
from ._space import DEFAULT_BOUNDS, ParamSpace
from ._stats import PHOTO_CAMERA, StatsConfig, distance, mean_stats, noise_of, residuals, stats_vector, texture_stats
from ._target import CHANNELS, Target, estimate_cell_pixels, load_target

__all__ = [
    "CHANNELS",
    "DEFAULTS",
    "DEFAULT_BOUNDS",
    "FAMILIES",
    "Family",
    "FitResult",
    "METHODS",
    "ORIENTED_COHERENCE",
    "PHOTO_CAMERA",
    "ParamSpace",
    "Simulator",
    "StatsConfig",
    "Target",
    "distance",
    "colourise",
    "estimate_cell_pixels",
    "family",
    "fit",
    "gradient_descent",
    "kmeans",
    "laplace_intervals",
    "load_target",
    "loss_curve",
    "mean_stats",
    "noise_of",
    "penalised",
    "photo_palette",
    "preview",
    "progress_default",
    "region_stats",
    "residuals",
    "stats_vector",
    "stripe_angle",
    "texture_distance",
    "texture_stats",
]

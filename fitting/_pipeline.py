"""`fitting.fit`: a photo's path through the fit, top to bottom.

1. The target (`fitting._target`): the photo at lattice resolution, its scale read from the
   pigment pattern; `fitting._verdict.split_target` keeps half of a large enough target
   apart for the verdict. The pattern's wavelength the fit aims at is the whole target's,
   as the scale and the verdict's (`Target.wavelength`).
2. The family: one family's fit (`fitting._fit.fit_one`: the design, `fitting._design`; the
   local search, `fitting._search`; the report and intervals, `fitting._uncertainty`),
   or `auto` (`fitting._auto`: every family screened, the best fitted in full, ranked by the
   held-out distance).
3. The verdict and the report (`fitting._verdict`): each full fit's samples against the
   held-out tile, degenerate coats rejected, convincing or not in words; the whole call's
   wall time and its stages in `timings`.
4. The refinement (`_refined`): the judged fit goes on from its best point on the whole
   target, so the parameters and intervals use all of it (the training half alone gave
   intervals that missed two of three true values of the bounded-Ua target, the whole
   covered all three; fit_synthetic.md); the verdict stays the training fit's. On a target
   too small to split, `auto` gives the intervals to the family it returns after the ranking
   (`_with_intervals`), not to every family it fits in full.
"""

from __future__ import annotations

import dataclasses
import time
from functools import partial
from pathlib import Path

from ._auto import TOP, fit_auto
from ._fit import add_intervals, fit_one
from ._fit import refine as refine_fit
from ._result import FitResult
from ._search import METHODS
from ._simulator import Simulator
from ._stats import PHOTO_CAMERA, StatsConfig
from ._target import Target, load_target
from ._verdict import (degenerate, heldout_distance, judge, split_target, target_wavelength,
                       verdict_text)

# One set of defaults for `fit` and `morphojax fit` (the CLI reads them from here).
DEFAULTS = {"model": "auto", "fit": None, "shape": (64, 64), "steps": None, "window": None, "seeds": 4,
            "design_seeds": 2, "seed": 0, "n_design": None, "rounds": 2, "keep": 1, "method": "bfgs",
            "max_steps": 40, "binarise": True, "orientation": True, "progress": None, "screen": "heldout",
            "refine": True}


def progress_default() -> bool:
    """`progress=None` means on when attached to a terminal or running in a notebook."""
    import sys

    try:
        from IPython import get_ipython

        shell = get_ipython()
        if shell is not None and type(shell).__name__ == "ZMQInteractiveShell":
            return True
    except ImportError:
        pass
    return bool(getattr(sys.stderr, "isatty", lambda: False)())


def _names(fit) -> list | None:
    if fit is None:
        return None
    return list(fit) if not isinstance(fit, str) else [n.strip() for n in fit.split(",") if n.strip()]


def check_fit_inputs(model, shape, seeds, steps, window, fixed, flag: str = "{}") -> None:
    """What can be checked before minutes of fitting, by the API and the command line alike:
    the lattice's shape, that its simulations fit in memory, steps and window within the step
    counter, and fixed values the model takes (`flag` formats a parameter's name as the
    caller spells it: "{}" for `fit`'s keywords, "--{}" for the command line's flags)."""
    import morphojax as mj
    from morphojax._checks import STEP_COUNTER_MAX, check_run_size, check_shape

    from ._families import FAMILIES

    shape = check_shape(shape, flag.format("shape"), ndim=2)
    check_run_size(shape, 3, members=max(int(seeds), 1),
                   what=f"this fit ({seeds} simulations of {shape[0]}x{shape[1]} cells at once)")
    for name, value in (("steps", steps), ("window", window)):
        if value is not None and not 0 <= value <= STEP_COUNTER_MAX:
            raise ValueError(f"{flag.format(name)} must lie in [0, {STEP_COUNTER_MAX}] (got {value})")
    if not fixed or not isinstance(model, str):
        return
    names = [model] if model != "auto" else list(FAMILIES)
    for name in names:  # a fixed value the model refuses is refused now, not after the fit's design
        family = FAMILIES.get(name)
        try:
            template = family.make(tuple(shape)) if family is not None else mj.model_from_name(name)
        except Exception:  # not a plain model (an experiment, a family built otherwise): the fit checks it
            continue
        known = template.parameters() if hasattr(template, "parameters") else {}
        own = {k: v for k, v in fixed.items() if k in known}
        if own:
            try:
                template.replace(**own)
            except ValueError as err:
                raise ValueError(f"{flag.format('fixed')}: {err}") from None


def fit(target, model=DEFAULTS["model"], fit=DEFAULTS["fit"], *, fixed=None, bounds=None, shape=DEFAULTS["shape"],
        steps: int | None = DEFAULTS["steps"], window: int | None = DEFAULTS["window"], seeds: int = DEFAULTS["seeds"],
        design_seeds: int = DEFAULTS["design_seeds"],
        seed: int = DEFAULTS["seed"], design: str = "lhs", n_design: int | None = DEFAULTS["n_design"],
        rounds: int = DEFAULTS["rounds"], keep: int = DEFAULTS["keep"], method: str = DEFAULTS["method"],
        max_steps: int = DEFAULTS["max_steps"], fallback: bool = True, stats: StatsConfig | None = None,
        boundary: str = "wrap", species=None, batch_size: int = 8, noise_seeds: int = 8,
        learning_rate: float = 0.05, length_scale: str | None = "family", progress: bool | None = DEFAULTS["progress"],
        intervals: bool = True, families=None, top: int = TOP, screen: str = DEFAULTS["screen"],
        refine: bool = DEFAULTS["refine"], simulator: Simulator | None = None) -> FitResult:
    """Fit parameters of `model` so its texture statistics match `target`'s.

    Args:
        target: a `Target` (see `load_target`), an image path, or a 2D array at lattice
            resolution (normalised by its quantiles like a photo).
        model: "auto" (screen every family, fit the best `top` in full, rank them; see
            `fitting._auto`), a family name ("turing", "anisotropic-turing", "bard",
            "gray-scott", "reinforcement", "young", "leopard"; `fitting.FAMILIES`), another
            model name, a model, a one-species `YoungCA`, or an `Experiment` (growing and
            multi-phase runs; see `Simulator` for names).
        fit: names of the parameters to fit; None fits the family's defaults (with "auto",
            names given apply to each family that has them).
        fixed: parameters held at given values; bounds: {name: (low, high)} overriding the
            family's (or `fitting.DEFAULT_BOUNDS`).
        shape: simulated lattice (rows, cols); steps / window: steps per simulation and how
            many of the last are differentiated (None: the family's).
        seeds: simulations averaged per evaluation (vmapped); design_seeds: the global
            stage's (at most `seeds`: it only has to find the basin, and it is most of the
            simulations); seed: the fit's random seed.
        design, n_design, rounds, keep: the global stage: a "lhs" or "grid" design of
            n_design points (default 12 per fitted parameter), a scan of each fitted limit
            (`LIMIT_SCAN` points across its bounds; a narrow band it finds is scanned again
            at three other values of each parameter that trades against the limit, such as
            the ratio: `fitting._limits`), then `rounds` Latin hypercubes in boxes (halving
            each round; along a banded limit, two scan steps either side of the band's curve)
            around the best `keep`, which start local searches.
        method: "bfgs", "lm" (Levenberg-Marquardt), "nelder-mead" or "gd"; max_steps: its
            iteration budget; fallback: Nelder-Mead when the gradient method does not improve.
        stats: which statistics and how they are weighted (default `StatsConfig()`: pigment
            maps, with orientation); its `camera`, None by default, becomes
            `fitting.PHOTO_CAMERA` for a photo's target (the camera's error on its
            statistics, added to the seed-to-seed noise) and none for an array's.
        length_scale: the fitted parameter that moves the wavelength ("family": the family's
            own, e.g. Turing's `scale`); the global stage moves each design point along it
            to the target's dominant wavelength (None to disable).
        progress: True for a progress bar, False for silence, None (default) for a bar in
            terminals and notebooks and one log line per stage on stderr elsewhere.
        intervals: compute the credible intervals (`fitting.laplace_intervals` and the
            likelihood region); with "auto", for the family returned only (none where it
            returns a rejected coat).
        families, top: for "auto", the families screened (default all) and how many are
            fitted in full (default `TOP`, 3).
        screen: for "auto", how the screen orders the families: "heldout" (default), the
            held-out distance of each family's best design point's samples, or "loss", the
            penalised training loss (`fitting._auto`).
        refine: where the target is split (a held-out half), refine the fit judged on it
            from its best point on the whole target, with the intervals (default); False
            returns the training half's fit.

    Returns:
        `FitResult` (see its docstring): `result.convincing` and `result.verdict` say whether
        the coat reproduces the target on a held-out tile (`fitting._verdict`);
        `result.save_json(path)`, `result.preview(path)`.
    """
    t_wall = time.perf_counter()
    check_fit_inputs(model, shape, seeds, steps, window, fixed)
    mode = None if progress is False else "bar" if progress or progress_default() else "log"
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; allowed: {', '.join(METHODS)}")
    if not isinstance(target, Target):  # a path, or an array already at lattice resolution
        target = load_target(target) if isinstance(target, (str, Path)) else load_target(target, cell_pixels=1.0)
    stats = StatsConfig() if stats is None else stats
    if stats.camera is None:  # a photo's statistics carry the camera's error; an array's none
        stats = dataclasses.replace(stats, camera=PHOTO_CAMERA if target.photo else ())
    options = dict(fixed=fixed, bounds=bounds, shape=shape, steps=steps, window=window, seeds=seeds, seed=seed,
                   design_seeds=design_seeds, design=design, n_design=n_design, rounds=rounds, keep=keep,
                   method=method, max_steps=max_steps, fallback=fallback, stats=stats, boundary=boundary,
                   species=species, batch_size=batch_size, noise_seeds=noise_seeds, learning_rate=learning_rate,
                   length_scale=length_scale, intervals=intervals)
    train, heldout, apart = split_target(target.field)
    # the training half aims at the whole target's wavelength: the one the verdict judges its
    # coat by (`fitting._verdict.judge`) and the resolution estimate read from the whole crop;
    # a half alone read the clean coat's 11-35% off on 3 of the 8 tuning coats of the
    # photo-like suite (benchmarks/results/fit_photolike-wavelengths-tuning.md)
    whole_wavelength = target.wavelength if target.wavelength is not None else target_wavelength(target.field)
    training = dataclasses.replace(target, field=train, wavelength=whole_wavelength) if apart else target
    # a split target's training fit is judged on the held-out half, then refined on the
    # whole (`_refined`), which computes the intervals: the training fit need not; `auto` on a
    # target too small to split gives them to the family it returns only (`_with_intervals`)
    refined = refine and apart
    auto = isinstance(model, str) and model == "auto"
    late = intervals and auto and not apart
    options["intervals"] = intervals and not refined and not late
    assess = _assessor(target.field, heldout, apart, seed)
    if auto:
        score = partial(heldout_distance, whole=target.field, heldout=heldout)
        result = fit_auto(training, _names(fit), families=families, top=top, progress=mode, assess=assess,
                          score=score, screen_rule=screen, **options)
    else:
        result = assess(fit_one(training, model, _names(fit), progress=mode, simulator=simulator, **options))
    if refined and result.rejected is None:
        result = _refined(result, target, intervals, mode)
    elif late and result.rejected is None:
        result = _with_intervals(result, target, mode)
    result.verdict = verdict_text(result.family, result.heldout, result.rejected, auto)
    result.fields["heldout"] = heldout
    result.config["split"] = {"train": list(train.shape), "heldout": list(heldout.shape), "apart": apart}
    result.timings["fit"] = result.timings.get("total", float("nan"))
    result.timings["total"] = time.perf_counter() - t_wall  # the whole call, `auto`'s screen and fits included
    return result


def _refined(result: FitResult, target: Target, intervals: bool, mode) -> FitResult:
    """The training fit refined on the whole target (`fitting._fit.refine`), its held-out
    verdict and ranking kept: the refined fit has seen the held-out half, so the verdict
    stays the training fit's, the estimate of how the fit generalises (model selection on
    held-out data, the final estimate from all of it). A refined coat that is degenerate is
    not returned: the training fit stands (without intervals), and the config says why."""
    whole = refine_fit(result, target, intervals=intervals, progress=mode)
    rejected = degenerate(whole.fields["samples"], result.heldout["target_wavelength"])
    if rejected is not None:
        result.config["refined"] = {"kept_training_fit": f"the refined coat is degenerate: {rejected}"}
        return result
    whole.heldout, whole.rejected, whole.convincing = result.heldout, None, result.convincing
    whole.ranking = result.ranking
    whole.fields["training_fit"] = result.fields["fit"]
    return whole


def _with_intervals(result: FitResult, target: Target, mode) -> FitResult:
    """`auto`'s returned fit on a target too small to split, given its intervals after the
    ranking (`fitting._fit.add_intervals`: the same point and samples, so its verdict and
    ranking stand): the families it did not return are not worth theirs, each a region of
    about 50-200 evaluations of the loss."""
    out = add_intervals(result, target, progress=mode)
    out.heldout, out.rejected, out.convincing, out.ranking = (result.heldout, result.rejected, result.convincing,
                                                              result.ranking)
    out.timings["verdict"] = result.timings.get("verdict", 0.0)
    return out


def _assessor(whole, heldout, apart: bool, seed: int):
    """A function that sets a full fit's held-out report, rejection and convincing flag."""

    def assess(result: FitResult) -> FitResult:
        t0 = time.perf_counter()
        samples = result.fields.get("samples", [result.fields["fit"]])
        result.heldout = judge(samples, whole, heldout, apart, seed=seed)
        result.rejected = degenerate(samples, result.heldout["target_wavelength"])
        result.convincing = bool(result.heldout["convincing"] and result.rejected is None)
        result.timings["verdict"] = time.perf_counter() - t0
        return result

    return assess



"""One family's fit to a target, its stages in order.

1. Target statistics (`target_stats`: `texture_stats` of the target field, with the
   pattern's own wavelength).
2. Global stage (`fitting._design`): a design over the bounds, its points moved to the
   target's wavelength, the saturation limits scanned, then refinement rounds.
3. Noise: at the best design point the seed-to-seed spread of each statistic is measured,
   so the loss is in units of simulation noise (a diagonal synthetic likelihood).
4. Local stage (`fitting._search`) from each kept point: an Optimistix solver on the
   unconstrained reparameterisation, gradients through the simulation's last `window`
   steps (`fitting._runs`), Nelder-Mead where gradients do not help.
5. Report (`_conclude`): the best point is moved to the target's wavelength where the
   likelihood cannot tell the two apart (`fitting._scale.snap_to_wavelength`), then
   re-simulated for the report: statistics of target and fit, the noise floor (the distance
   expected between the target and the fit if the target were a sample of the fitted
   model), region statistics, timings and the loss history.
6. Intervals (`fitting._uncertainty`). Where their region's walk finds a loss below the
   fit's, the local search goes on from that point once, and the report is made again.

The stages after the design share a `FitState`, kept on the result: `refine` goes on from a
fit's best point against another target (the pipeline's whole target after a fit on its
training half), and `add_intervals` concludes a fit again with intervals.
"""

from __future__ import annotations

import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np

import morphojax as mj

from ._design import DEGENERATE_PENALTY, global_design
from ._limits import LIMIT_SCAN
from ._result import FitResult
from ._runs import seed_run
from ._scale import snap_threshold, snap_to_wavelength
from ._search import local_stage, recording
from ._simulator import Simulator, fixed_tuple
from ._space import ParamSpace
from ._stats import compiled_distance, compiled_noise_of, compiled_texture_stats
from ._verdict import off_scale, target_wavelength, wavelength_of


def target_stats(field, stats, wavelength: float | None = None) -> dict:
    """The target's statistics as the fit compares them: `texture_stats`, with the
    wavelength the pattern's (the statistics' soft argmax of a photo's spectrum is pulled
    toward hair and sensor noise, the cheetah: 6.5 cells against the spots' 9.1), the peak
    of its spectrum with the shading removed (`fitting._verdict.target_wavelength`, within
    9% of the soft argmax on clean simulations): `wavelength` where it was measured on more
    than `field` (a training half carries its whole target's: `Target.wavelength`)."""
    tstats = jax.tree_util.tree_map(np.asarray, compiled_texture_stats(jnp.asarray(field, jnp.float32), stats))
    pattern = target_wavelength(field) if wavelength is None else float(wavelength)
    if np.isfinite(pattern):
        tstats["wavelength"] = np.asarray(pattern, tstats["wavelength"].dtype)
    return tstats


@dataclasses.dataclass(frozen=True)
class FitState:
    """What a fit's stages after the design share, kept on its result (`FitResult.resume`)
    so that the fit can go on from its best point against another target (`refine`)."""

    sim: Simulator
    space: ParamSpace
    stats: object  # the StatsConfig
    keys: object  # the fit's seeds (the local stage's and the report's)
    noise: dict  # each statistic's seed-to-seed spread at the best design point
    length: int | None  # the family's length parameter's index, for the move to the target's scale
    length_power: float
    settings: dict  # method, max_steps, learning_rate, fallback, seeds, seed, noise_seeds
    bands: tuple = ()  # the saturation limits' bands the global stage profiled (`fitting._limits`)
    # the local stage's ends, (loss, free point, method, start loss) best first, that the report
    # stage concluded from (`add_intervals` concludes from them again)
    finals: tuple = ()


def _as_template(model, shape):
    if isinstance(model, str):
        try:
            return mj.model_from_name(model)
        except ValueError:  # the message names every name a fit takes, families and models alike
            # _families builds on the core only; imported late as in _resolve
            from ._families import FAMILIES

            others = [n for n in mj.models.MODELS if n not in FAMILIES]
            raise ValueError(f"unknown model {model!r}; a fit takes a family ({', '.join(FAMILIES)}), 'auto', "
                             f"or a model name ({', '.join(others)})") from None
    if isinstance(model, (mj.AbstractModel, mj.Experiment, mj.YoungCA)):
        return model
    raise ValueError(f"model must be a model name, a model, an Experiment or a YoungCA (got {type(model).__name__})")


def _resolve(model, names, shape):
    """(family or None, template, fitted names, family bounds) for a model argument."""
    from ._families import FAMILIES, family, family_of

    if isinstance(model, str):
        fam = family(model) if model in FAMILIES else family_of(model)
        template = fam.make(tuple(shape)) if fam is not None else _as_template(model, shape)
    else:
        template = _as_template(model, shape)
        fam = family_of(template)
    if names is None:
        if fam is None:
            raise ValueError(f"fit=None needs a model family ({', '.join(FAMILIES)}); for this model or "
                             "experiment name the parameters to fit, e.g. fit=['ratio', 'scale']")
        names = list(fam.fit)
    return fam, template, names, (dict(fam.bounds) if fam is not None else {})


def fit_one(target, model, names, *, fixed, bounds, shape, steps, window, seeds, seed, design_seeds, design,
            n_design, rounds, keep, method, max_steps, fallback, stats, boundary, species, batch_size, noise_seeds,
            learning_rate, length_scale, intervals, progress, simulator=None, stage_prefix="",
            screen_only=False) -> FitResult:
    """One family's (or model's) fit; `fit` without "auto". `target` is a `Target` (the part
    of the photo the fit may see); `progress` a mode of `fitting._progress.make_progress`
    ("bar", "log" or None)."""
    fam, template, names, fam_bounds = _resolve(model, names, shape)
    n_design = 12 * max(len(names), 1) if n_design is None else n_design
    for name, value, low in (("seeds", seeds, 1), ("design_seeds", design_seeds, 1), ("n_design", n_design, 1),
                             ("keep", keep, 1), ("max_steps", max_steps, 0), ("batch_size", batch_size, 1)):
        if int(value) < low:
            raise ValueError(f"{name} must be an integer >= {low} (got {value!r})")
    t_start = time.perf_counter()
    timings = {}
    run = {"species": species, "boundary": boundary, "fixed": fixed_tuple(fixed)}
    if simulator is not None:
        sim = simulator
    elif fam is not None:
        sim = fam.simulator(shape, template, steps=steps, window=window, **run)
    else:  # a model of no family: `Simulator`'s own run
        steps = int(8000 if steps is None else steps)
        window = int(min(1000, steps) if window is None else window)
        sim = Simulator(template, shape=tuple(shape), steps=steps, window=window, **run)
    sim.check_names(names + [k for k, _ in sim.fixed])
    all_bounds = {n: fam_bounds[n] for n in names if n in fam_bounds}
    stripes = None  # the target's stripe direction, where an oriented family fits an angle
    if "angle" in names and sim.anisotropic:  # the half-turn centred on the target's stripes
        from ._families import orientation_bounds, stripe_angle

        stripes = stripe_angle(target.field)[0]
        all_bounds["angle"] = orientation_bounds(stripes)
    all_bounds.update({n: b for n, b in (bounds or {}).items() if n in names})
    space = ParamSpace.build(names, all_bounds)
    if length_scale == "family":
        length_scale = fam.length if fam is not None else "scale"
    power = fam.length_power if fam is not None else 0.5
    rates = [i for i, n in enumerate(names) if n.rpartition(":")[2] == "growth_rate"]
    if rates:  # fitted growth rates: compare the window every point reaches, check the room
        sim = dataclasses.replace(sim, compare=sim.final_shape({names[i]: space.low[i] for i in rates}))
        sim.check_capacity({names[i]: space.high[i] for i in rates})
    tstats = target_stats(target.field, stats, target.wavelength)  # the pattern's scale, not the fur's
    keys = jax.random.split(jax.random.key(seed + 1), seeds)

    label = stage_prefix + (fam.name if fam is not None else "fit")
    moves = length_scale in names or stripes is not None
    total = (n_design * (1 + int(rounds) + (1 if moves else 0)) + LIMIT_SCAN * len(space.limits)
             + keep * max(max_steps, 1) * 2)
    with recording(progress, label, total) as rec:
        result = _fit(target, sim, space, names, keys, tstats, stats, rec, timings, t_start, seed=seed,
                      design=design, n_design=n_design, rounds=rounds, keep=keep, method=method, max_steps=max_steps,
                      fallback=fallback, batch_size=batch_size, noise_seeds=noise_seeds, learning_rate=learning_rate,
                      length_scale=length_scale, length_power=power, predicted=fam is not None and fam.predicted,
                      seeds=seeds, design_keys=keys[: min(int(design_seeds), int(seeds))], stripes=stripes, intervals=intervals,
                      screen_only=screen_only)
    result.family = fam.name if fam is not None else (model if isinstance(model, str) else type(template).__name__)
    result.palette = None if screen_only else target.palette()
    result.simulator = sim
    return result


def _fit(target, sim, space, names, keys, tstats, stats, rec, timings, t_start, *, seed, design, n_design, rounds,
         keep, method, max_steps, fallback, batch_size, noise_seeds, learning_rate, length_scale, length_power,
         predicted, seeds, design_keys, stripes, intervals, screen_only=False):
    """The stages of one family's fit in order: the global design (`fitting._design`), the
    noise at its best point, the local search from the best `keep` (`fitting._search`), then
    the report and the intervals (`_conclude`). A screen stops after the design."""
    t0 = time.perf_counter()
    length = names.index(length_scale) if length_scale in names else None
    found = global_design(sim, space, stats, tstats, rec, seed=seed, design=design, n_design=n_design, rounds=rounds,
                          keep=keep, batch_size=batch_size, design_keys=design_keys, length=length,
                          length_power=length_power, predicted=predicted, stripes=stripes, keep_samples=screen_only)
    thetas, losses, wavelengths, bands = found.thetas, found.losses, found.wavelengths, found.bands
    order = np.argsort(losses)
    design_rows = [{**{n: float(thetas[i, j]) for j, n in enumerate(names)}, "loss": float(losses[i]),
                    "wavelength": float(wavelengths[i])} for i in order]
    timings["design"] = time.perf_counter() - t0
    if screen_only:  # `auto`'s screening: the design's best, scored with the config's noise scales
        best = order[0]
        params = {n: float(thetas[best, j]) for j, n in enumerate(names)}
        timings["total"] = time.perf_counter() - t_start
        score = float(losses[best]) - (DEGENERATE_PENALTY if off_scale(wavelengths[best], float(tstats["wavelength"]))
                                       else 0.0)
        best_fields = found.samples_at(thetas[best])
        fields = {"target": np.asarray(target.field)}
        if best_fields is not None:
            fields["samples"] = best_fields
        return FitResult(params=params, model=sim.build(params), loss=score, noise_floor=float("nan"),
                         history=[{k: v for k, v in row.items() if k != "z"} for row in rec.rows], timings=timings,
                         stats={}, report={}, design=design_rows, fields=fields,
                         config={"fit": names, "screen": True, "wavelength": float(wavelengths[best]),
                                 "target_wavelength": float(tstats["wavelength"])},
                         target=target.describe(), score=score)

    # ---- noise at the best design point -------------------------------------------------
    t0 = time.perf_counter()
    noise_keys = jax.random.split(jax.random.key(seed + 2), max(noise_seeds, 3))
    per_seed, _ = seed_run(sim, space, stats, jnp.asarray(thetas[order[0]], jnp.float32), noise_keys)
    noise = jax.tree_util.tree_map(np.asarray, compiled_noise_of(per_seed))
    timings["noise"] = time.perf_counter() - t0

    state = FitState(sim, space, stats, keys, noise, length, length_power,
                     {"method": method, "max_steps": max_steps, "learning_rate": learning_rate, "fallback": fallback,
                      "seeds": seeds, "seed": seed, "noise_seeds": noise_seeds}, bands)
    t0 = time.perf_counter()
    starts = [space.to_free(thetas[i]) for i in order[: min(keep, len(order))]]
    finals = local_stage(state, tstats, starts, rec)
    timings["local"] = time.perf_counter() - t0
    settings = {"fit": names, "bounds": {n: [lo, hi] for n, lo, hi in zip(names, space.low, space.high)},
                "requested_method": method, "seeds": seeds, "design_seeds": len(design_keys), "seed": seed,
                "design": design, "n_design": n_design, "rounds": rounds, "keep": keep, "max_steps": max_steps}
    return _conclude(target, state, tstats, finals, rec, timings, t_start, settings, design_rows, [], intervals)


# what `_conclude` and `refine` write into a result's config (a refinement writes them anew)
CONCLUDED = ("method", "scale_snap", "simulator", "stats", "starts", "restarted", "refined", "lower_in_region")


def _conclude(target, state: FitState, tstats, finals, rec, timings, t_start, settings, design_rows, history,
              intervals, restart: bool = True) -> FitResult:
    """The report stage from the local stage's `finals`: the best point moved to the
    target's scale where the likelihood cannot tell (`fitting._scale`), re-simulated for the
    noise floor, the samples and the region statistics, then the intervals; the result.
    Where the intervals' region walk finds a lower loss than the fit's (a curved valley the
    local search stopped in, as a saturation limit traded against the ratio), the local
    search goes on from there once (`restart`) and the report is made again if it ends lower."""
    t0 = time.perf_counter()
    sim, space, stats, keys, noise = state.sim, state.space, state.stats, state.keys, state.noise
    names, seeds, length = list(space.names), state.settings["seeds"], state.length
    best_loss, z_best, used, _ = finals[0]
    theta_best = space.from_free(np.asarray(z_best, np.float32))
    params = {n: float(theta_best[j]) for j, n in enumerate(names)}
    # the floor's seeds: as many as the noise's, so the same compiled batch serves both
    floor_keys = jax.random.split(jax.random.key(state.settings["seed"] + 3), max(state.settings["noise_seeds"], 3))
    runs = {}  # the fit's own seeds' run at a point, done once for the floor and the scale's move

    def run_at(theta):
        """(mean statistics, fields) of the fit's seeds (`keys`) at theta."""
        theta = jnp.asarray(theta, jnp.float32)
        token = np.asarray(theta).tobytes()
        if token not in runs:
            per_seed, fields = seed_run(sim, space, stats, theta, keys)
            runs[token] = (jax.tree_util.tree_map(lambda v: np.mean(np.asarray(v), axis=0), per_seed),
                           np.asarray(fields))
        return runs[token]

    def floor_at(theta):
        """(mean statistics, single samples' losses against them, the samples) at theta."""
        fit_stats = run_at(theta)[0]
        singles, samples = seed_run(sim, space, stats, jnp.asarray(theta, jnp.float32), floor_keys)
        singles = jax.tree_util.tree_map(np.asarray, singles)
        losses = np.array([float(compiled_distance({k: v[i] for k, v in singles.items()}, fit_stats, stats, noise))
                           for i in range(len(floor_keys))])
        return fit_stats, losses, samples

    fit_stats, floor_losses, samples = floor_at(theta_best)
    if not np.isfinite(best_loss):
        best_loss = float(compiled_distance(fit_stats, tstats, stats, noise))
        finals[0] = (best_loss, *finals[0][1:3], best_loss)
    floor = float(np.mean(floor_losses))
    snap = None
    if length is not None:  # the target's scale, where the likelihood cannot tell (`fitting._scale`)
        rec.stage = "scale"

        def loss_and_scale(theta):
            """(loss, wavelength) at theta: the loss as the local stage measures it, the
            wavelength as the verdict does (the median over seeds of each sample's peak)."""
            mean, fields = run_at(theta)
            return float(compiled_distance(mean, tstats, stats, noise)), float(np.nanmedian([wavelength_of(f) for f in fields]))

        snap_loss, snap_wavelength = loss_and_scale(theta_best)
        threshold = snap_threshold(seeds, best_loss / floor if floor > 0 else 1.0)
        snap = snap_to_wavelength(
            np.asarray(theta_best, np.float64), snap_loss, snap_wavelength, loss_and_scale,
            target_wavelength=float(tstats["wavelength"]), index=length, power=state.length_power,
            low=float(space.low[length]), high=float(space.high[length]), threshold=threshold)
        if snap["moved"]:
            theta_best = jnp.asarray(snap["theta"], jnp.float32)
            params = {n: float(theta_best[j]) for j, n in enumerate(names)}
            best_loss, used = snap["loss"], f"{used} + scale"
            fit_stats, floor_losses, samples = floor_at(theta_best)
            floor = float(np.mean(floor_losses))
    samples = np.asarray(samples)
    sample = samples[0]
    from ._report import region_stats

    report = {"target": region_stats(target.field), "fit": region_stats(sample)}
    score = float(compiled_distance(fit_stats, tstats, stats))
    _spent(timings, "report", t0)
    ivals, undetermined, correlated, better = {}, [], [], None
    if intervals:
        from ._uncertainty import interval_report

        t0 = time.perf_counter()
        rec.stage = "intervals"
        inflate = best_loss / floor if floor > 0 and np.isfinite(best_loss) else 1.0
        u_best = space.to_unit(np.asarray(theta_best))
        valley = np.concatenate([np.empty((0, space.size))] + [band.valley(u_best) for band in state.bands])
        ivals, undetermined, correlated, better = interval_report(
            sim, space, stats, theta_best, keys, tstats, noise, inflate=inflate, seed=state.settings["seed"],
            floor=floor, floor_losses=floor_losses, valley=valley)
        _spent(timings, "intervals", t0)
    if better is not None and restart:
        t0 = time.perf_counter()
        rec.stage = "restart"
        again = local_stage(state, tstats, [space.to_free(np.asarray(better[0], np.float32))], rec)
        _spent(timings, "restart", t0)
        if again[0][0] < best_loss:
            result = _conclude(target, state, tstats, sorted(again + finals, key=lambda f: f[0] if np.isfinite(f[0]) else np.inf), rec, timings,
                               t_start, settings, design_rows, history, intervals, restart=False)
            result.config["restarted"] = {"from": params, "loss": float(best_loss), "region_loss": better[1],
                                          "final_loss": float(again[0][0])}
            return result
    lower = None  # a lower point the region found that the fit did not go on from
    if better is not None and not restart:
        lower = {"params": {n: float(v) for n, v in zip(names, np.asarray(better[0]))}, "loss": better[1]}
    timings["total"] = time.perf_counter() - t_start
    history = history + [{k: v for k, v in row.items() if k != "z"} for row in rec.rows]  # `history`: earlier stages'

    config = {**settings, "method": used, "lower_in_region": lower,
              "scale_snap": None if snap is None else {
                  "moved": snap["moved"], "start_wavelength": snap_wavelength, "wavelength": snap["wavelength"],
                  "target_wavelength": float(tstats["wavelength"]), "start_loss": snap_loss,
                  "threshold": threshold, "tried": snap["tried"]},
              "simulator": sim.describe(), "stats": dataclasses.asdict(stats), "starts": [
                  {"start_loss": f[3], "final_loss": f[0], "method": f[2],
                   "params": {n: float(v) for n, v in zip(names, space.from_free(np.asarray(f[1], np.float32)))}}
                  for f in finals]}
    return FitResult(
        params=params, model=sim.build(params), loss=float(best_loss), noise_floor=floor, history=history,
        timings=timings, stats={"target": _tolist(tstats), "fit": _tolist(fit_stats), "noise": _tolist(noise)},
        report=report, design=design_rows, fields={"target": np.asarray(target.field), "fit": sample, "samples": samples},
        config=config, target=target.describe(), score=score, intervals=ivals, undetermined=undetermined,
        correlated=correlated, resume=dataclasses.replace(state, finals=tuple(finals)),
    )


def _spent(timings: dict, stage: str, t0: float) -> None:
    """Add the time since t0 to `stage`: a restart makes the report and the intervals again,
    and the breakdown counts both passes."""
    timings[stage] = timings.get(stage, 0.0) + time.perf_counter() - t0


def refine(result: FitResult, target, *, intervals: bool = True, progress=None) -> FitResult:
    """The fit gone on from its best point against another `Target`: the local search and
    the report stage again, with the first fit's simulator, parameter space, seeds and noise
    scales (`result.resume`). `fitting.fit` fits the training half of a split target, judges
    that fit on the held-out half, then refines it on the whole target, so that the
    parameters and intervals use all of it (`fitting._pipeline`)."""
    state = _resumable(result, "refine")
    t_start = time.perf_counter()
    tstats = target_stats(target.field, state.stats, target.wavelength)
    with recording(progress, f"refine {result.family}", 2 * max(int(state.settings["max_steps"]), 1)) as rec:
        rec.stage = "refine"
        start = state.space.to_free(np.asarray([result.params[n] for n in state.space.names], np.float32))
        finals = local_stage(state, tstats, [start], rec)
        timings = {k: v for k, v in result.timings.items() if k not in ("report", "intervals", "total")}
        timings["refine"] = time.perf_counter() - t_start
        refined = _conclude_again(result, target, tstats, finals, rec, timings, t_start, intervals=intervals)
    refined.palette = target.palette()
    refined.config["refined"] = {"from": dict(result.params), "training_loss": result.loss,
                                 "training_noise_floor": result.noise_floor, "method": refined.config["method"]}
    return refined


def add_intervals(result: FitResult, target, *, progress=None) -> FitResult:
    """A fit made without intervals, concluded again with them: the report stage from the
    same local-stage ends (`FitState.finals`), so the same move to the target's scale and the
    same point, samples and verdict, plus the intervals. It does not go on from a lower point
    their region finds (`config["lower_in_region"]` records it). `auto` on a target too small
    to split fits its families without intervals and gives them to the one it returns, whose
    ranking then still holds (`fitting._pipeline`)."""
    state = _resumable(result, "add_intervals", needs_finals=True)
    t_start = time.perf_counter()
    tstats = target_stats(target.field, state.stats, target.wavelength)
    with recording(progress, f"intervals {result.family}", 1) as rec:
        timings = {k: v for k, v in result.timings.items() if k != "total"}
        return _conclude_again(result, target, tstats, list(state.finals), rec, timings, t_start, intervals=True,
                               restart=False)


def _resumable(result: FitResult, caller: str, needs_finals: bool = False) -> FitState:
    """The fit state `refine` and `add_intervals` go on from (a screen's result keeps none;
    `needs_finals`: the local stage's ends too, which `add_intervals` concludes from)."""
    state = result.resume
    if state is None or (needs_finals and not state.finals):
        raise ValueError(f"{caller} needs a full fit's result (a screen's keeps no fit state)")
    return state


def _conclude_again(result: FitResult, target, tstats, finals, rec, timings, t_start, **conclude) -> FitResult:
    """The report stage of `result`'s fit run again from `finals` against `target`, with the
    first fit's state, settings, design and history: the new result's total time counts the
    first fit's, and it keeps its family, palette and simulator."""
    state = result.resume
    settings = {k: v for k, v in result.config.items() if k not in CONCLUDED}
    out = _conclude(target, state, tstats, finals, rec, timings, t_start, settings, result.design, result.history,
                    **conclude)
    out.timings["total"] += result.timings.get("total", 0.0)  # the first fit's stages and these
    out.family, out.palette, out.simulator = result.family, result.palette, result.simulator
    return out


def _tolist(tree):
    return {k: np.asarray(v).tolist() for k, v in tree.items()}

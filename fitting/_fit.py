"""Fitting model parameters to a target texture: a global design, then local optimisers.

1. Target statistics (`texture_stats` of the target field).
2. Global stage: a coarse design (Latin hypercube or grid) over the parameter bounds,
   evaluated as one vmapped batch (design points x `design_seeds` seeds); each point is
   also moved along the family's length parameter to the target's wavelength (and an
   oriented family's angle turned to the target's stripes): placed there by linear
   stability before its run where the family declares it and the prediction is valid
   (`fitting._predicted`), moved by the measured wavelength and the family's scaling law
   where not, or where the placed point settled off it. The target's wavelength is its
   pattern's (`fitting._verdict.target_wavelength`); a point off it (grid-scale, or more than
   20% away) scores DEGENERATE_PENALTY more, and a local search that ends off it keeps its
   start. Each fitted saturation limit is scanned across its bounds at the best point so
   far, and a narrow band it finds is profiled along the parameters that trade against it
   (`fitting._limits`). Then `rounds` Latin hypercubes in boxes around the best `keep`
   points (not moved again), their points on the limits' bands.
3. Noise: at the best design point the seed-to-seed spread of each statistic is measured,
   so the loss is in units of simulation noise (a diagonal synthetic likelihood).
4. Local stage from each kept point: an Optimistix solver on the unconstrained
   reparameterisation (BFGS on the loss, Levenberg-Marquardt on the residual vector,
   Nelder-Mead without gradients, or plain gradient descent), with gradients through the
   simulation's last `window` steps (checkpointed, so memory does not grow with steps).
   When gradients do not help (no improvement), Nelder-Mead takes over from the same start.
   The solver is stepped from Python, one compiled step at a time, and each step's point and
   loss go to the history (`_search`).
5. The best point is moved to the target's wavelength where the likelihood cannot tell the
   two apart (`fitting._scale.snap_to_wavelength`), then re-simulated for the report:
   statistics of target and fit, the noise floor (the distance expected between the target
   and the fit if the target were a sample of the fitted model), region statistics, timings
   and the loss history.
6. Intervals (`fitting._uncertainty`). Where their region's walk finds a loss below the
   fit's, the local search goes on from that point once, and the report is made again.

The stages after the design share a `FitState`, kept on the result: `refine` goes on from a
fit's best point against another target (the pipeline's whole target after a fit on its
training half).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import morphojax as mj

from ._limits import LIMIT_SCAN, scan_limits
from ._predicted import LANDED, applies, place
from ._result import FitResult
from ._scale import moved_length, snap_threshold, snap_to_wavelength
from ._simulator import Simulator, fixed_tuple
from ._space import ParamSpace
from ._stats import (compiled_distance, compiled_noise_of, compiled_texture_stats, distance, mean_stats, residuals,
                     texture_stats)
from ._verdict import off_scale, target_wavelength, wavelength_of

METHODS = ("bfgs", "lm", "nelder-mead", "gd")
DEGENERATE_PENALTY = 1e6  # added to a design point's loss when it is off the target's scale


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


def _stats_at(sim, space, cfg, theta, keys):
    params = space.as_dict(theta)
    fields = jax.vmap(lambda k: sim.run(params, k))(keys)
    return mean_stats(fields, cfg)


# Compiled once per (simulator structure, parameter space, statistics config, shapes) and
# reused by later fits: the simulator's model, the target statistics, keys and noise are
# traced arguments.
@eqx.filter_jit
def _design_batch(sim, space, cfg, thetas, keys, tstats):
    """(loss, wavelength, fields) of each design point: its seeds' fields are kept, so the
    best point's samples need no second run (`auto` scores them on the held-out tile)."""
    def one(theta):
        fields = jax.vmap(lambda k: sim.run(space.as_dict(theta), k))(keys)
        st = mean_stats(fields, cfg)
        return distance(st, tstats, cfg), st["wavelength"], fields

    return jax.vmap(one)(thetas)


@eqx.filter_jit
def _seed_run(sim, space, cfg, theta, keys):
    """Per-seed statistics at theta and every seed's field (one program serves the noise,
    the noise floor, the samples and, averaged, the fit's statistics)."""
    fields = jax.vmap(lambda k: sim.run(space.as_dict(theta), k))(keys)
    return jax.vmap(lambda f: texture_stats(f, cfg))(fields), fields


def _loss_of(sim, space, cfg, z, keys, tstats, noise) -> tuple[float, float]:
    """The local stage's (loss, wavelength) at z, through `_seed_run` (no separate compiled
    program). The wavelength is the verdict's (the median over seeds of each field's spectral
    peak, `wavelength_of`), not the loss's soft-argmax: the guard that keeps a search on the
    target's scale (`walked_off`) then judges it as the snap and the degenerate check do."""
    theta = space.from_free(np.asarray(z, np.float32))
    per_seed, fields = _seed_run(sim, space, cfg, theta, keys)
    mean = jax.tree_util.tree_map(lambda v: np.mean(np.asarray(v), axis=0), per_seed)
    peaks = [wavelength_of(f) for f in np.asarray(fields)]
    lam = float(np.nanmedian(peaks)) if np.isfinite(peaks).any() else float("nan")  # flat fields: no wavelength
    return float(compiled_distance(mean, tstats, cfg, noise)), lam



# The local search is stepped from Python (`_search`), one compiled step at a time, and
# records its point and loss after each step: no host callback inside its compiled program,
# which the persistent compilation cache would never keep (every new process would compile
# the search again; benchmarks/results/fit_speed.md).
def _loss_fn(z, args):
    sim, space, cfg, keys, tstats, noise = args
    return distance(_stats_at(sim, space, cfg, space.from_free(z), keys), tstats, cfg, noise), None


def _resid_fn(z, args):
    sim, space, cfg, keys, tstats, noise = args
    return residuals(_stats_at(sim, space, cfg, space.from_free(z), keys), tstats, cfg, noise), None


_NO_OPTIONS, _NO_TAGS = {}, frozenset()


def _searched(state, z):
    """(loss, point) of a search after a step: the accepted point `z` and its loss, which
    quasi-Newton and Gauss-Newton solvers keep (BFGS; Levenberg-Marquardt: the sum of
    squared residuals), or the best vertex of Nelder-Mead's simplex and its loss."""
    if hasattr(state, "f_simplex"):
        best = jnp.argmin(state.f_simplex)
        return state.f_simplex[best], state.simplex[best]
    info = state.f_info
    if hasattr(info, "f"):
        return info.f, z
    return sum(jnp.sum(r ** 2) for r in jax.tree_util.tree_leaves(info.residual)), z


@eqx.filter_jit
def _search_init(solver, fn, z, args):
    f_struct, aux_struct = eqx.filter_eval_shape(fn, z, args)
    return solver.init(fn, z, args, _NO_OPTIONS, f_struct, aux_struct, _NO_TAGS)


@eqx.filter_jit
def _search_step(solver, fn, z, args, state):
    """One step: (point, state, (loss, point) so far, whether the search stops), stopping
    as `optx.minimise` does (the solver's own test, a failure, a non-finite point)."""
    import optimistix as optx

    z, state, _ = solver.step(fn, z, args, _NO_OPTIONS, state, _NO_TAGS)
    done, result = solver.terminate(fn, z, args, _NO_OPTIONS, state, _NO_TAGS)
    stop = done | (result != optx.RESULTS.successful) | ~jnp.all(jnp.isfinite(z))
    return z, state, _searched(state, z), stop


def _search(solver, fn, z0, args, max_steps: int, rec):
    """`solver` (an Optimistix minimiser or least-squares solver) on `fn` from z0 for at
    most `max_steps` steps, as `optx.minimise(..., throw=False)` runs it, the search's
    current point and its loss recorded by `rec` after each step (`_searched`). Returns the
    point the solver returns, as `optx.minimise` does."""
    z = jnp.asarray(z0)
    state = _search_init(solver, fn, z, args)
    for _ in range(int(max_steps)):
        z, state, (loss, at), stop = _search_step(solver, fn, z, args, state)
        rec(loss, at)
        if bool(stop):
            break
    return z


class _Recorder:
    """Collects the losses and points of a fit's searches and shows them on its progress bar."""

    def __init__(self, bar=None):
        self.rows = []
        self.stage = ""
        self.start = 0
        self.bar = bar

    def __call__(self, loss, z):
        self.rows.append({"stage": self.stage, "start": self.start, "evaluation": len(self.rows),
                          "loss": float(loss), "z": np.asarray(z).tolist()})
        if self.bar is not None:
            self.bar.update(self.stage, float(loss))


@contextlib.contextmanager
def _recording(progress, label: str, total: int):
    """A `_Recorder` of the losses the compiled searches report, with a progress bar of
    `progress`'s mode (`fitting._progress.make_progress`), while the block runs."""
    from ._progress import make_progress

    bar = make_progress(progress, label, total)
    try:
        yield _Recorder(bar)
    finally:
        if bar is not None:
            bar.close()


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
    with _recording(progress, label, total) as rec:
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


def keep_better(thetas, vals, lams, rows, moved, moved_vals, moved_lams):
    """Points, losses and wavelengths with rows `rows` replaced by their moved points where
    the move scored lower (ties keep the point); new arrays."""
    thetas, vals, lams = np.array(thetas), np.array(vals), np.array(lams)
    better = np.asarray(moved_vals) < vals[rows]
    thetas[rows[better]], vals[rows[better]], lams[rows[better]] = (
        np.asarray(moved)[better], np.asarray(moved_vals)[better], np.asarray(moved_lams)[better])
    return thetas, vals, lams


def _fit(target, sim, space, names, keys, tstats, stats, rec, timings, t_start, *, seed, design, n_design, rounds,
         keep, method, max_steps, fallback, batch_size, noise_seeds, learning_rate, length_scale, length_power,
         predicted, seeds, design_keys, stripes, intervals, screen_only=False):
    # ---- global stage: a coarse design, then `rounds` finer designs around the best ------
    t0 = time.perf_counter()

    def run_batch(thetas):
        pad = (-len(thetas)) % batch_size
        padded = np.concatenate([thetas, np.repeat(thetas[-1:], pad, 0)]) if pad else thetas
        out = [_design_batch(sim, space, stats, jnp.asarray(padded[i: i + batch_size], jnp.float32), design_keys,
                             tstats)
               for i in range(0, len(padded), batch_size)]
        vals = np.concatenate([np.asarray(o[0]) for o in out])[: len(thetas)]
        lams = np.concatenate([np.asarray(o[1]) for o in out])[: len(thetas)]
        if screen_only:  # each point's seeds, for the best one's samples (`auto` scores them)
            fields = np.concatenate([np.asarray(o[2]) for o in out])[: len(thetas)]
            for theta, f in zip(thetas, fields):
                samples[np.asarray(theta, np.float32).tobytes()] = f
        # a point off the target's scale (grid-scale, or more than 20% off its wavelength)
        # ranks after every point that is not (`fitting._verdict.off_scale`)
        vals = np.where(off_scale(lams, float(tstats["wavelength"])), vals + DEGENERATE_PENALTY, vals)
        return np.where(np.isfinite(vals), vals, np.inf), lams

    length = names.index(length_scale) if length_scale in names else None
    angle = names.index("angle") if stripes is not None else None
    samples = {}  # a screen's design points' seed fields, by their parameters

    # the family declares it, fits its length, has a dispersion relation (`applies`), and the
    # design is a hypercube (a grid's levels along the length would all be placed at one value)
    predictable = predicted and length is not None and design != "grid" and applies(sim)

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
        best_fields = samples.get(np.asarray(thetas[best], np.float32).tobytes())
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
    per_seed, _ = _seed_run(sim, space, stats, jnp.asarray(thetas[order[0]], jnp.float32), noise_keys)
    noise = jax.tree_util.tree_map(np.asarray, compiled_noise_of(per_seed))
    timings["noise"] = time.perf_counter() - t0

    state = FitState(sim, space, stats, keys, noise, length, length_power,
                     {"method": method, "max_steps": max_steps, "learning_rate": learning_rate, "fallback": fallback,
                      "seeds": seeds, "seed": seed, "noise_seeds": noise_seeds}, tuple(bands))
    t0 = time.perf_counter()
    starts = [space.to_free(thetas[i]) for i in order[: min(keep, len(order))]]
    finals = _local_stage(state, tstats, starts, rec)
    timings["local"] = time.perf_counter() - t0
    settings = {"fit": names, "bounds": {n: [lo, hi] for n, lo, hi in zip(names, space.low, space.high)},
                "requested_method": method, "seeds": seeds, "design_seeds": len(design_keys), "seed": seed,
                "design": design, "n_design": n_design, "rounds": rounds, "keep": keep, "max_steps": max_steps}
    return _conclude(target, state, tstats, finals, rec, timings, t_start, settings, design_rows, [], intervals)


def _local_stage(state: FitState, tstats, starts, rec) -> list:
    """The local search from each start (free coordinates) against `tstats`: a list of
    (loss, z, method used, start loss), best first. Nelder-Mead takes over where the
    gradient method does not improve on its start by 1%, and a search that ends off the
    target's scale, from a start on it or farther from it than its start, keeps the start
    (`walked_off`)."""
    s = state.settings
    method, max_steps = s["method"], s["max_steps"]
    sim, space, stats, keys, noise = state.sim, state.space, state.stats, state.keys, state.noise
    args = (sim, space, stats, keys, tstats, noise)
    finals = []
    for k, z0 in enumerate(starts):
        z0 = jnp.asarray(z0, jnp.float32)
        rec.start = k
        if max_steps == 0:  # no local search: the design's best is scored in the report
            finals.append((float("nan"), np.asarray(z0), "design", float("nan")))
            continue
        start_loss, start_lam = _loss_of(sim, space, stats, z0, keys, tstats, noise)
        z, used = _local(method, args, z0, max_steps, s["learning_rate"], rec)
        end_loss, end_lam = _loss_of(sim, space, stats, z, keys, tstats, noise)
        if s["fallback"] and method != "nelder-mead" and max_steps > 0 and not end_loss < 0.99 * start_loss:
            z_nm, _ = _local("nelder-mead", args, z0, max_steps, s["learning_rate"], rec)
            nm_loss, nm_lam = _loss_of(sim, space, stats, z_nm, keys, tstats, noise)
            if nm_loss < end_loss:
                z, end_loss, end_lam, used = z_nm, nm_loss, nm_lam, f"{used}->nelder-mead"
        if walked_off(start_lam, end_lam, float(tstats["wavelength"])):
            z, end_loss, used = z0, start_loss, f"{used} (ended off the target's scale: kept the start)"
        finals.append((end_loss, np.asarray(z), used, start_loss))
    finals.sort(key=lambda f: f[0] if np.isfinite(f[0]) else np.inf)
    return finals


def walked_off(start_wavelength: float, end_wavelength: float, target_wavelength: float) -> bool:
    """Whether a local search that went from a point of `start_wavelength` to one of
    `end_wavelength` walked off the target's scale: it ends off it (`off_scale`) from a start
    on it, or farther from it (in log ratio) than its start. A start already off the scale
    does not free the search to go farther."""
    if not off_scale(end_wavelength, target_wavelength):
        return False
    if not off_scale(start_wavelength, target_wavelength):
        return True

    def away(lam):  # a flat field (NaN) is as far as can be
        return abs(math.log(lam / target_wavelength)) if np.isfinite(lam) and lam > 0 else math.inf

    return away(end_wavelength) > away(start_wavelength)


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
            per_seed, fields = _seed_run(sim, space, stats, theta, keys)
            runs[token] = (jax.tree_util.tree_map(lambda v: np.mean(np.asarray(v), axis=0), per_seed),
                           np.asarray(fields))
        return runs[token]

    def floor_at(theta):
        """(mean statistics, single samples' losses against them, the samples) at theta."""
        fit_stats = run_at(theta)[0]
        singles, samples = _seed_run(sim, space, stats, jnp.asarray(theta, jnp.float32), floor_keys)
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
        again = _local_stage(state, tstats, [space.to_free(jnp.asarray(better[0], jnp.float32))], rec)
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
    with _recording(progress, f"refine {result.family}", 2 * max(int(state.settings["max_steps"]), 1)) as rec:
        rec.stage = "refine"
        start = state.space.to_free(jnp.asarray([result.params[n] for n in state.space.names], jnp.float32))
        finals = _local_stage(state, tstats, [start], rec)
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
    with _recording(progress, f"intervals {result.family}", 1) as rec:
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


def _local(method, args, z0, max_steps, learning_rate, rec):
    """One local search from z0; returns (z, method used)."""
    import optimistix as optx

    if max_steps == 0:
        return z0, method
    rec.stage = method
    if method == "gd":
        at = [jnp.asarray(z0)]  # the point each step's loss was measured at

        def record(step, z_new, value):
            rec(value, at[-1])
            at.append(z_new)

        z, _ = gradient_descent(lambda z: _loss_fn(z, args)[0], z0, learning_rate=learning_rate, steps=max_steps,
                                callback=record)
        return z, "gd"
    if method == "lm":
        return _search(optx.LevenbergMarquardt(rtol=1e-3, atol=1e-3), _resid_fn, z0, args, max_steps, rec), "lm"
    solver = optx.BFGS(rtol=1e-3, atol=1e-3) if method == "bfgs" else optx.NelderMead(rtol=1e-3, atol=1e-3)
    return _search(solver, _loss_fn, z0, args, max_steps, rec), method


def gradient_descent(loss, z0, *, learning_rate: float = 0.05, steps: int = 50, callback=None,
                     normalise: bool = True):
    """A plain gradient-descent loop through `jax.grad`, for notebooks that watch the loss.

    `callback(step, z, loss)` is called after every step (plot, print, stop by raising
    StopIteration). With `normalise`, steps have length `learning_rate` in the direction of
    the negative gradient (robust to the large dynamic range of simulation gradients).
    Returns (z, losses).
    """
    value_and_grad = eqx.filter_jit(jax.value_and_grad(loss))
    z = jnp.asarray(z0)
    losses = []
    for k in range(int(steps)):
        value, g = value_and_grad(z)
        losses.append(float(value))
        if normalise:
            g = g / (jnp.linalg.norm(g) + 1e-12)
        z_new = z - learning_rate * g
        if callback is not None:
            try:
                callback(k, z_new, float(value))
            except StopIteration:
                z = z_new
                break
        z = z_new
    return z, losses

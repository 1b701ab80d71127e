"""One family's local search: an Optimistix solver stepped from Python, each step recorded.

From each start the design keeps, the solver works on the unconstrained reparameterisation
(`fitting._space`): BFGS on the loss, Levenberg-Marquardt on the residual vector, Nelder-Mead
without gradients, or plain gradient descent, with gradients through the simulation's last
`window` steps (`fitting._runs`). Where the gradient method does not improve on its start,
Nelder-Mead takes over from the same start; a search that walks off the target's scale keeps
its start (`walked_off`).

The solver is stepped from Python (`search`: Optimistix's init / step / terminate, each
compiled once), and each step's point and loss go to the fit's history (`Recorder`): no host
callback inside a compiled program, which the persistent compilation cache would never keep
(every new process would compile the search again; benchmarks/results/fit_speed.md).
"""

from __future__ import annotations

import contextlib
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._runs import loss_fn, loss_of, resid_fn
from ._verdict import off_scale

METHODS = ("bfgs", "lm", "nelder-mead", "gd")  # `fitting.fit(method=...)`

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


def search(solver, fn, z0, args, max_steps: int, rec):
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


class Recorder:
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
def recording(progress, label: str, total: int):
    """A `Recorder` of the losses the compiled searches report, with a progress bar of
    `progress`'s mode (`fitting._progress.make_progress`), while the block runs."""
    from ._progress import make_progress

    bar = make_progress(progress, label, total)
    try:
        yield Recorder(bar)
    finally:
        if bar is not None:
            bar.close()


def local_stage(state, tstats, starts, rec) -> list:
    """The local search from each start (free coordinates) against `tstats`, with the fit's
    `FitState` (`fitting._fit`): a list of (loss, z, method used, start loss), best first. Nelder-Mead takes over where the
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
        start_loss, start_lam = loss_of(sim, space, stats, z0, keys, tstats, noise)
        z, used = local_search(method, args, z0, max_steps, s["learning_rate"], rec)
        end_loss, end_lam = loss_of(sim, space, stats, z, keys, tstats, noise)
        if s["fallback"] and method != "nelder-mead" and max_steps > 0 and not end_loss < 0.99 * start_loss:
            z_nm, _ = local_search("nelder-mead", args, z0, max_steps, s["learning_rate"], rec)
            nm_loss, nm_lam = loss_of(sim, space, stats, z_nm, keys, tstats, noise)
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


def local_search(method, args, z0, max_steps, learning_rate, rec):
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

        z, _ = gradient_descent(lambda z: loss_fn(z, args)[0], z0, learning_rate=learning_rate, steps=max_steps,
                                callback=record)
        return z, "gd"
    if method == "lm":
        return search(optx.LevenbergMarquardt(rtol=1e-3, atol=1e-3), resid_fn, z0, args, max_steps, rec), "lm"
    solver = optx.BFGS(rtol=1e-3, atol=1e-3) if method == "bfgs" else optx.NelderMead(rtol=1e-3, atol=1e-3)
    return search(solver, loss_fn, z0, args, max_steps, rec), method


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

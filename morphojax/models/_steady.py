"""Homogeneous steady states of a reaction within its saturation limits, and the reaction's
local Jacobian: what `AbstractModel.homogeneous_state` and `mj.dispersion` stand on.

A homogeneous state of a clamped model is a state x that one step of the loop leaves as it
is: for every species i, either the reaction vanishes strictly inside the limits, or x_i
sits on a limit and the reaction pushes past it (f_i >= 0 at the upper limit, f_i <= 0 at
the lower one), so the clamp holds it. These are exactly the zeros of the natural map

    F(x) = x - clip(x + f(x), lower, upper),

which is -f(x) inside the limits. `solve` finds one by a semismooth Newton method: the
generalised Jacobian of F has the row -df_i/dx where x_i + f_i lies strictly inside the
limits and the unit row e_i where it is clipped; each step is damped by backtracking (the
first of 1, 1/2, 1/4, ... that lowers max |F|, or the smallest). It starts from a model's
closed form (`unclamped_state`), or a guess, and stops after `ITERATIONS` steps or when
both max_i |F_i| and the Newton step are <= sqrt(eps) (1 + max_i |x_i|), eps the dtype's
resolution (then `converged`), and takes one more full step where it does not raise the
residual (near a root it squares the error).

Everything is pointwise in space, so a model with parameter maps gets one state per cell,
and the whole solve runs under `jit` and `vmap` (fixed shapes, a `while_loop`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._checks import is_concrete

ITERATIONS = 50  # Newton steps at most
HALVINGS = 12  # backtracking step sizes tried per Newton step: 1, 1/2, ..., 2^-(HALVINGS - 1)


def local_jacobian(fn, x):
    """The Jacobian df_i/dx_j (species, species, *cells) of a reaction `fn` that acts cell
    by cell, at the stacked state `x` (species, *cells): one forward-mode product per
    species, with a tangent that is 1 in that species in every cell."""
    cols = [jax.jvp(fn, (x,), (jnp.zeros_like(x).at[j].set(1.0),))[1] for j in range(x.shape[0])]
    return jnp.stack(cols, axis=1)


def tolerance(dtype) -> float:
    """The relative residual below which a state counts as steady: sqrt(eps) of the dtype."""
    return float(np.sqrt(np.finfo(np.dtype(dtype)).eps))


def _limits(model, like):
    lo, hi = jnp.asarray(model.lower, like.dtype), jnp.asarray(model.upper, like.dtype)
    extra = like.ndim - 1
    if lo.ndim == 1:
        lo = lo.reshape(lo.shape + (1,) * extra)
    if hi.ndim == 1:
        hi = hi.reshape(hi.shape + (1,) * extra)
    return jnp.broadcast_to(lo, like.shape), jnp.broadcast_to(hi, like.shape)


def _start(model, guess):
    """The starting state (species, *cells) broadcast against the reaction's output: the
    guess, else the model's closed form, else 1 per species; clipped into the limits."""
    n = model.n_species
    if guess is None:
        guess = model.unclamped_state()
    if guess is None:
        guess = (1.0,) * n
    guess = tuple(guess) if isinstance(guess, (tuple, list)) or jnp.ndim(guess) >= 1 else (guess,)
    if len(guess) != n:
        raise ValueError(f"{type(model).__name__}: a guess needs one value per species {model.species} "
                         f"(got {len(guess)})")
    dtype = jnp.result_type(float, *[jnp.asarray(g) for g in guess], *jax.tree_util.tree_leaves(model))
    values = [jnp.asarray(g, dtype) for g in guess]
    shape = jnp.broadcast_shapes(*(v.shape for v in values))
    if len(shape) < 2:  # reactions are written for (species, rows, cols); a scalar state is one cell
        shape = (1,) * (2 - len(shape)) + shape
    x = jnp.stack([jnp.broadcast_to(v, shape) for v in values])
    out = jax.eval_shape(model.reaction, x).shape[1:]
    x = jnp.broadcast_to(x, (n,) + jnp.broadcast_shapes(shape, out))
    lo, hi = _limits(model, x)
    return jnp.clip(x, lo, hi)


def _residual(model, x, lo, hi):
    return x - jnp.clip(x + model.reaction(x), lo, hi)


def _size(F):
    """max_i |F_i| per cell, infinite where anything is not finite."""
    return jnp.max(jnp.where(jnp.isfinite(F), jnp.abs(F), jnp.inf), axis=0)


def _newton_step(model, x, lo, hi):
    """(F, delta): the natural map at x and the semismooth Newton step (0 in a cell whose
    generalised Jacobian is singular)."""
    n = x.shape[0]
    f = model.reaction(x)
    F = x - jnp.clip(x + f, lo, hi)
    free = (x + f > lo) & (x + f < hi)
    eye = jnp.eye(n, dtype=x.dtype).reshape((n, n) + (1,) * (x.ndim - 1))
    G = jnp.where(free[:, None], -local_jacobian(model.reaction, x), eye)
    G = jnp.moveaxis(G.reshape(n, n, -1), -1, 0)  # (cells, n, n)
    rhs = jnp.moveaxis(F.reshape(n, -1), -1, 0)[..., None]
    delta = jnp.moveaxis(-jnp.linalg.solve(G, rhs)[..., 0], 0, -1).reshape(x.shape)
    return F, jnp.where(jnp.all(jnp.isfinite(delta), axis=0), delta, 0.0)


def _done(x, F, delta):
    """Converged cells: x finite, and both the residual and the Newton step within
    sqrt(eps) (1 + max |x|) (the step's test keeps slow reactions, whose residual is small
    everywhere near the state, from stopping early)."""
    finite = jnp.all(jnp.isfinite(x), axis=0)
    scale = tolerance(x.dtype) * (1.0 + jnp.max(jnp.where(jnp.isfinite(x), jnp.abs(x), 0.0), axis=0))
    return finite & (_size(F) <= scale) & (_size(delta) <= scale)


@eqx.filter_jit
def _newton(model, x):
    lo, hi = _limits(model, x)
    steps = 0.5 ** jnp.arange(HALVINGS, dtype=x.dtype)

    def cond(carry):
        _, it, done = carry
        return (it < ITERATIONS) & ~jnp.all(done)

    def body(carry):
        x, it, _ = carry
        F, delta = _newton_step(model, x, lo, hi)
        done = _done(x, F, delta)
        size0 = _size(F)

        def trial(t):  # the damped step, projected into the limits
            y = jnp.clip(x + t * delta, lo, hi)
            return y, _size(_residual(model, y, lo, hi))

        ys, sizes = jax.vmap(trial)(steps)  # (HALVINGS, n, *cells), (HALVINGS, *cells)
        better = sizes < (1.0 - 1e-4 * steps.reshape((-1,) + (1,) * (sizes.ndim - 1))) * size0
        pick = jnp.where(jnp.any(better, axis=0), jnp.argmax(better, axis=0), jnp.argmin(sizes, axis=0))
        y = jnp.take_along_axis(ys, pick[None, None], axis=0)[0]
        # the full step where the residual did not grow (Newton's own convergence near a
        # root), else the damped one; converged cells stay where they are
        y = jnp.where(jnp.take_along_axis(sizes, pick[None], axis=0)[0] <= size0, y, x)
        return jnp.where(done, x, y), it + 1, done

    x, _, _ = jax.lax.while_loop(cond, body, (x, jnp.asarray(0), jnp.zeros(x.shape[1:], bool)))
    return _polished(model, x, lo, hi)


def _polished(model, x, lo, hi):
    """(x, converged, residual) after one more full Newton step where it does not raise the
    residual: the tests stop within sqrt(eps), and near a root the next step squares the
    error, down to the dtype's rounding."""
    F, delta = _newton_step(model, x, lo, hi)
    y = jnp.clip(x + delta, lo, hi)
    G, step = _newton_step(model, y, lo, hi)
    keep = _size(G) <= _size(F)
    x, F, delta = (jnp.where(keep, b, a) for a, b in ((x, y), (F, G), (delta, step)))
    return x, _done(x, F, delta), _size(F)


def solve(model, guess=None):
    """(state (species, *cells), converged (*cells), residual max |F| (*cells)): a
    homogeneous steady state of `model` within its limits (see the module docstring).
    Works traced; a model with scalar parameters gives cells of shape (1, 1).

    Differentiable in the model's parameters by the implicit function theorem: the search
    runs on stopped gradients, then one Newton step of the live model from the root, whose
    value is the root again (F = 0 there) and whose derivative is -G^-1 dF/dparameters."""
    x = _start(model, guess)
    if is_concrete(x, model):  # a closed form that already holds needs no Newton loop
        lo, hi = _limits(model, x)
        if bool(jnp.all(_done(x, *_newton_step(model, x, lo, hi)))):
            return _polished(model, x, lo, hi)
        return _newton(model, x)
    frozen = jax.tree_util.tree_map(lambda v: jax.lax.stop_gradient(v) if eqx.is_array(v) else v, model)
    x, ok, size = _newton(frozen, jax.lax.stop_gradient(x))
    lo, hi = _limits(model, x)
    _, delta = _newton_step(model, x, lo, hi)
    return jnp.where(ok, x + delta, x), ok, size


def homogeneous_values(model, guess=None) -> tuple:
    """The homogeneous state as a tuple (one array per species), raising when Newton's
    method did not converge: a ValueError for concrete values, an equinox runtime error
    under `jit`/`vmap` (where no Python exception can be raised)."""
    x, ok, size = solve(model, guess)
    if is_concrete(ok):
        if not bool(jnp.all(ok)):
            raise ValueError(
                f"{type(model).__name__}.homogeneous_state: no steady state within the limits found "
                f"(Newton's method stopped at {_show(x)} with residual {float(jnp.max(size)):.3g} after at most "
                f"{ITERATIONS} steps); give a guess= near one, or check the limits: a state the "
                "reaction leaves strictly beyond a limit is not held by the clamp")
    else:
        x = eqx.error_if(x, ~jnp.all(ok), "homogeneous_state: no steady state within the limits found")
    # scalar parameters give one state, returned as scalars; parameter maps one per cell
    scalar = all(jnp.ndim(v) == 0 for v in model.parameters().values())
    return tuple(v.reshape(()) if scalar and v.size == 1 else v for v in x)


def _show(x) -> str:
    flat = np.asarray(x).reshape(x.shape[0], -1)
    return "(" + ", ".join(f"{v:.4g}" for v in flat[:, 0]) + ")" + ("" if flat.shape[1] == 1 else " in its first cell")

"""Input validation shared by the models, the state and the steppers.

Checks run on concrete values only: inside `jax.jit`, `jax.vmap` or `jax.grad` the
values are tracers and cannot be inspected, so the checks are skipped there (the
compiled code then reports blow-ups itself, see `_simulate`).
"""

from __future__ import annotations

import numpy as np
import jax
import jax.numpy as jnp


def is_concrete(*values) -> bool:
    """True when no leaf of `values` is a JAX tracer."""
    return not any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(values))


def default_float():
    """The floating dtype JAX uses by default: float32, or float64 under `jax_enable_x64`."""
    return jnp.result_type(float)


def as_float_array(value, name: str):
    """Convert a parameter to a JAX floating array, with a clear error for non-numbers."""
    if isinstance(value, jax.Array) and jnp.issubdtype(value.dtype, jnp.floating):
        return value
    try:
        arr = np.asarray(value) if not isinstance(value, jax.Array) else value
    except Exception as err:  # pragma: no cover - exotic inputs
        raise ValueError(f"{name} must be a number or an array of numbers (got {value!r})") from err
    if not (jnp.issubdtype(arr.dtype, jnp.number) or arr.dtype == bool):
        raise ValueError(f"{name} must be a number or an array of numbers (got {value!r})")
    return jnp.asarray(arr, dtype=default_float())


def check_finite(value, name: str, *, allow_inf: str | None = None) -> None:
    """Raise ValueError if `value` holds NaN (or an infinity not allowed by `allow_inf`).

    `allow_inf` is None, "+" (only +inf allowed, for upper limits) or "-" (only -inf).
    """
    if not is_concrete(value):
        return
    arr = np.asarray(value)
    if np.isnan(arr).any():
        raise ValueError(f"{name} must not be NaN (got {_show(arr)})")
    if allow_inf == "+":
        bad = np.isneginf(arr)
    elif allow_inf == "-":
        bad = np.isposinf(arr)
    else:
        bad = np.isinf(arr)
    if bad.any():
        allowed = {"+": "finite or +inf", "-": "finite or -inf"}.get(allow_inf, "finite")
        raise ValueError(f"{name} must be {allowed} (got {_show(arr)})")


def check_range(value, name: str, *, low=None, high=None, low_open=False, high_open=False) -> None:
    """Raise ValueError naming `name` and the allowed interval when `value` leaves it."""
    if not is_concrete(value):
        return
    arr = np.asarray(value)
    ok = np.ones(arr.shape, bool)
    if low is not None:
        ok &= (arr > low) if low_open else (arr >= low)
    if high is not None:
        ok &= (arr < high) if high_open else (arr <= high)
    if not ok.all():
        lo = "-inf" if low is None else f"{low:g}"
        hi = "+inf" if high is None else f"{high:g}"
        interval = f"{'(' if low_open or low is None else '['}{lo}, {hi}{')' if high_open or high is None else ']'}"
        raise ValueError(f"{name} must lie in {interval} (got {_show(arr)})")


def check_count(value, name: str, unit: str, *, low=0) -> None:
    """Raise ValueError unless `value` is an integer (Python or NumPy, not bool) >= `low`:
    a number of steps, updates or the like (`unit` names them in the message)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer number of {unit} (got {value!r})")
    check_range(value, name, low=low)


def check_choice(value, name: str, allowed) -> None:
    if value not in allowed:
        options = ", ".join(repr(a) for a in allowed)
        raise ValueError(f"unknown {name} {value!r}; allowed: {options}")


def _show(arr) -> str:
    arr = np.asarray(arr)
    if arr.size == 1:
        return f"{arr.reshape(()).item():g}"
    return f"array of shape {arr.shape}, min {np.nanmin(arr):g}, max {np.nanmax(arr):g}" if np.isfinite(arr).any() else f"array of shape {arr.shape}"

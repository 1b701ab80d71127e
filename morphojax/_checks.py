"""Input validation shared by the models, the state and the steppers.

Checks run on concrete values only: inside `jax.jit`, `jax.vmap` or `jax.grad` the
values are tracers and cannot be inspected, so the checks are skipped there (the
compiled code then reports blow-ups itself, see `_simulate`).
"""

from __future__ import annotations

import math
import operator
import os

import numpy as np
import jax
import jax.numpy as jnp


def is_concrete(*values) -> bool:
    """True when no leaf of `values` is a JAX tracer."""
    return not any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(values))


def default_float():
    """The floating dtype JAX uses by default: float32, or float64 under `jax_enable_x64`."""
    return jnp.result_type(float)


_HOST_FLOATS = (np.float16, np.float32, np.float64)  # dtypes NumPy converts to as XLA does (round to nearest even)


def as_float_array(value, name: str, dtype=None):
    """Convert a parameter to a JAX floating array, with a clear error for non-numbers; with
    `dtype`, then cast to it. Numbers (not JAX arrays) are converted on the host and put on
    the device once, the same value as converting on the device (one operation instead of
    three on each short call)."""
    if dtype is not None and not isinstance(value, jax.Array) and np.dtype(dtype) in _HOST_FLOATS:
        arr = _host_number_array(value, name)
        return jax.device_put(arr.astype(default_float()).astype(dtype))
    out = _float_array(value, name)
    return out if dtype is None else out.astype(dtype)


def _float_array(value, name: str):
    if isinstance(value, jax.Array) and jnp.issubdtype(value.dtype, jnp.floating):
        return value
    return jnp.asarray(_host_number_array(value, name), dtype=default_float())


def _host_number_array(value, name: str):
    """`value` as an array of numbers (NumPy, or JAX as it is), refusing anything else."""
    try:
        arr = np.asarray(value) if not isinstance(value, jax.Array) else value
    except Exception as err:  # pragma: no cover - exotic inputs
        raise ValueError(f"{name} must be a number or an array of numbers (got {value!r})") from err
    if not (jnp.issubdtype(arr.dtype, jnp.number) or arr.dtype == bool):
        raise ValueError(f"{name} must be a number or an array of numbers (got {value!r})")
    if jnp.issubdtype(arr.dtype, jnp.complexfloating):  # casting would drop the imaginary part silently
        raise ValueError(f"{name} must be real, not complex (got {value!r})")
    return arr


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
        lo = "-inf" if low is None else _number(low)
        hi = "+inf" if high is None else _number(high)
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


def _number(x) -> str:
    """A bound or value as it was given: whole numbers in full (2147483653, not 2.14748e+09)."""
    if isinstance(x, (int, np.integer)) or (isinstance(x, float) and x.is_integer() and abs(x) < 1e15):
        return str(int(x))
    return f"{x:g}"


def _show(arr) -> str:
    arr = np.asarray(arr)
    if arr.size == 1:
        return _number(arr.reshape(()).item())
    return f"array of shape {arr.shape}, min {np.nanmin(arr):g}, max {np.nanmax(arr):g}" if np.isfinite(arr).any() else f"array of shape {arr.shape}"


# ---- resources: what a request will cost, checked before it is spent --------------------------
MEMORY_ENV = "MORPHOJAX_MAX_MEMORY"  # e.g. "32G", "512M", "2.5GB" or a number of bytes
_UNITS = {"": 1, "B": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}
STEP_COUNTER_MAX = 2**31 - 1  # a state's step counter is int32


def parse_memory(text: str) -> int:
    """`"32G"`, `"512M"`, `"1.5GB"`, `"2T"` or a number of bytes, as bytes."""
    raw = str(text).strip().upper()
    body = raw[:-1] if raw.endswith("B") and len(raw) > 1 and raw[-2] in "KMGT" else raw
    unit = body[-1] if body and body[-1] in "KMGTB" else ""
    number = body[:-1] if unit else body
    try:
        value = float(number) * _UNITS[unit]
    except ValueError:
        value = float("nan")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{MEMORY_ENV} must be a positive size such as 32G, 512M or a number of bytes "
                         f"(got {text!r})")
    return int(value)


def machine_memory() -> int:
    """Bytes of memory this process may use: the machine's, or its container's limit if lower."""
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - exotic platforms
        total = 8 * 2**30
    for limit_file in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = open(limit_file).read().strip()
        except OSError:
            continue
        if text.isdigit() and 0 < int(text) < total:
            total = int(text)
    return int(total)


def memory_limit() -> int:
    """The most memory one request may need, in bytes: `MORPHOJAX_MAX_MEMORY` if set, else half
    of the machine's memory."""
    text = os.environ.get(MEMORY_ENV, "").strip()
    return parse_memory(text) if text else machine_memory() // 2


def _gb(nbytes: float) -> str:
    gb = nbytes / 1e9
    return f"{gb:.3g} GB" if gb >= 1 else f"{nbytes / 1e6:.3g} MB"


def check_memory(nbytes, what: str) -> None:
    """Raise ValueError when `what` ("this run", "the npz member 'cells' of F") needs more
    than `memory_limit()`: "this run needs about 61 GB; the limit is 12 GB"."""
    nbytes, limit = float(nbytes), memory_limit()
    if not nbytes <= limit:  # also refuses NaN and inf
        source = (f"set by {MEMORY_ENV}" if os.environ.get(MEMORY_ENV, "").strip()
                  else f"half the machine's memory; set {MEMORY_ENV}, e.g. {MEMORY_ENV}=32G, to change it")
        raise ValueError(f"{what} needs about {_gb(nbytes)}; the limit is {_gb(limit)} ({source})")


def cells_of(shape) -> int:
    """The number of elements of `shape`, as an exact Python integer (no overflow)."""
    return math.prod(int(s) for s in shape)


def check_shape(shape, name: str, *, ndim=None) -> tuple[int, ...]:
    """`shape` as a tuple of positive Python ints; fractional, complex, boolean or non-positive
    sizes are refused, not floored."""
    try:
        items = tuple(shape)
    except TypeError:
        items = (shape,)
    if ndim is not None and len(items) not in ((ndim,) if isinstance(ndim, int) else tuple(ndim)):
        raise ValueError(f"{name} must have {ndim} entries (got {shape!r})")
    out = []
    for s in items:
        if isinstance(s, (bool, np.bool_)) or getattr(s, "dtype", None) == bool:
            raise ValueError(f"{name} must hold positive whole numbers (got {shape!r})")
        try:
            size = operator.index(s)  # ints, NumPy integers, 0-d integer arrays
        except TypeError:
            if not isinstance(s, (float, np.floating)):
                raise ValueError(f"{name} must hold positive whole numbers (got {shape!r})") from None
            if not (math.isfinite(s) and float(s).is_integer()):
                raise ValueError(f"{name} must hold whole numbers, not {s!r} (got {shape!r})") from None
            size = int(s)
        if size < 1:
            raise ValueError(f"{name} must hold positive sizes (got {shape!r})")
        out.append(size)
    return tuple(out)


def check_step_counter(start, steps, name: str = "steps") -> None:
    """Raise ValueError when `start + steps` would overflow the int32 step counter."""
    if not is_concrete(start, steps):
        return
    total = int(np.asarray(start)) + int(np.asarray(steps))
    if total > STEP_COUNTER_MAX:
        raise ValueError(f"{name} must keep the step counter within int32: the state is at step "
                         f"{int(np.asarray(start))} and {int(np.asarray(steps))} more steps reach {total}, "
                         f"beyond {STEP_COUNTER_MAX}")


def check_scale(scale, name: str = "scale (pixels per cell)") -> int:
    """`scale` as an int when it is a whole number >= 1."""
    if isinstance(scale, bool) or not isinstance(scale, (int, np.integer)) or scale < 1:
        raise ValueError(f"{name} must be a whole number >= 1 (got {scale!r})")
    return int(scale)


PICTURE_BYTES = 8  # bytes a picture's pixel costs while it is drawn (RGB, its alpha and a float value)


def check_picture(shape, scale, what: str = "this picture") -> int:
    """`scale` as a positive int, after checking that a picture of a lattice `shape` (its last two
    axes; a leading axis counts as that many tiles) drawn `scale` pixels per cell fits in memory."""
    check_scale(scale)
    check_memory(cells_of(shape) * int(scale) ** 2 * PICTURE_BYTES, what)
    return int(scale)


STATE_BYTES = 64  # bytes one cell of one species costs while it is stepped (float32 state, its ghost
# copy, the step's temporaries), an estimate on the generous side
KEPT_BYTES = 16  # ... and once it is kept (a sweep member's or a snapshot's field, its copy in the files)
IN_FLIGHT = 64  # members of a sweep stepped at once, at most


def check_run_size(shape, species: int = 2, *, members: int = 1, scale=None, what: str = "this run") -> None:
    """Refuse, before anything is allocated, a run of `members` lattices (sweep members or
    snapshots) of `shape` (or its capacity) with `species` species, each drawn `scale` pixels per
    cell, that would need more memory than `memory_limit()`; counts are exact Python integers."""
    cells = cells_of(shape) * int(species)
    members = int(members)
    nbytes = cells * (STATE_BYTES * min(members, IN_FLIGHT) + KEPT_BYTES * members)
    if scale is not None:
        nbytes += cells_of(shape) * members * int(scale) ** 2 * PICTURE_BYTES
    check_memory(nbytes, what)

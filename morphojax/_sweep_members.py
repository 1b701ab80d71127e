"""What a sweep varies: the names it accepts, their values, and the model of each member.

A sweep's `vary` is a grid `{name: values}` (the product of the lists, C order) or an
explicit list of parameter sets `[{name: value}, ...]`. `sweep_members` checks it and turns
it into one (n,) array of values per name; `member_model` builds member i's model (and
growth schedule and dt) from its values. It runs both on the host (to validate members,
to re-run one alone) and traced inside the batched program, so one compiled program
serves every value.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .models import AbstractModel

GROWTH_RATE = "growth_rate"  # the growth schedule's rate (needs growth=Growth(...))
DT = "dt"  # the time step, per member (steps stay the same for every member)


def allowed_names(model: AbstractModel, growth=None) -> list[str]:
    """Parameter names a sweep can vary: the model's `parameters()`, `dt`, and `growth_rate`."""
    return list(model.parameters()) + [DT, GROWTH_RATE]


def _describe_allowed(model, growth):
    names = list(model.parameters()) + [DT]
    names.append(GROWTH_RATE if growth is not None else f"{GROWTH_RATE} (with growth=Growth(...))")
    return ", ".join(names)


def _check_name(model, growth, name):
    if not isinstance(name, str) or name not in allowed_names(model, growth):
        raise ValueError(f"sweep: unknown parameter {name!r} for {type(model).__name__}; "
                         f"allowed: {_describe_allowed(model, growth)}")
    if name == GROWTH_RATE and growth is None:
        raise ValueError("sweep: varying 'growth_rate' needs a growth schedule (growth=Growth(rate=...)) "
                         "and a state with room to grow (capacity)")


def _check_values(name, values) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"sweep: the values of {name!r} must be numbers (got {values!r})") from err
    if arr.ndim == 0:
        arr = arr[None]
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"sweep: {name!r} needs a non-empty 1D list of values (got shape {arr.shape})")
    # +inf is a valid upper limit and -inf a valid lower limit ("no limit"), as in the models
    kind = name.rsplit(".", 1)[-1][:6]  # composites name parameters "PART.NAME"
    ok = np.isfinite(arr) | ((arr == np.inf) & (kind == "upper_")) | ((arr == -np.inf) & (kind == "lower_"))
    if not ok.all():
        allowed = {"upper_": "finite or +inf", "lower_": "finite or -inf"}.get(kind, "finite")
        raise ValueError(f"sweep: the values of {name!r} must be {allowed} (got {float(arr[~ok][0]):g})")
    return arr


def _base_value(model, growth, dt, name):
    if name == DT:
        return float(dt)
    if name == GROWTH_RATE:
        return float(np.asarray(growth.rate))
    value = np.asarray(model.parameters()[name])
    if value.ndim != 0:
        raise ValueError(f"sweep: {name!r} is a parameter map in the base model; give it in every member "
                         "of the list (or vary it on a grid)")
    return float(value)


def sweep_members(model, vary, growth, dt):
    """(names, grid axes or None, per-member values {name: (n,) array}, result shape)."""
    if isinstance(vary, Mapping):
        if not vary:
            raise ValueError(f"sweep: vary is empty; name at least one parameter: {_describe_allowed(model, growth)}")
        names = tuple(vary)
        for name in names:
            _check_name(model, growth, name)
        axes = tuple(_check_values(name, vary[name]) for name in names)
        mesh = np.meshgrid(*axes, indexing="ij")
        values = {name: m.reshape(-1) for name, m in zip(names, mesh)}
        return names, axes, values, tuple(len(a) for a in axes)
    if isinstance(vary, Sequence) and not isinstance(vary, str):
        rows = list(vary)
        if not rows:
            raise ValueError("sweep: the list of parameter sets is empty")
        if not all(isinstance(r, Mapping) for r in rows):
            raise ValueError("sweep: vary must be a dict {name: values} (a grid) or a list of dicts (explicit sets)")
        names = tuple(dict.fromkeys(k for r in rows for k in r))
        if not names:
            raise ValueError("sweep: the parameter sets name no parameter; "
                             f"allowed: {_describe_allowed(model, growth)}")
        for name in names:
            _check_name(model, growth, name)
        values = {}
        for name in names:
            base = None if all(name in r for r in rows) else _base_value(model, growth, dt, name)
            col = [r.get(name, base) for r in rows]
            values[name] = _check_values(name, col)
        return names, None, values, (len(rows),)
    raise ValueError("sweep: vary must be a dict {name: values} (a grid) or a list of dicts (explicit sets)")


def with_growth_rate(growth, rate):
    """`growth` with its rate replaced by `rate` (in the dtype of its current rate)."""
    return eqx.tree_at(lambda g: g.rate, growth, jnp.asarray(rate, jnp.asarray(growth.rate).dtype))


def member_model(model, growth, dt, changes: dict):
    """(model, growth, dt) of the member whose values are `changes` (traced or concrete)."""
    changes = dict(changes)
    dt = changes.pop(DT, dt)
    rate = changes.pop(GROWTH_RATE, None)
    m = model.replace(**changes) if changes else model
    if rate is not None:
        growth = with_growth_rate(growth, rate)
    return m, growth, dt


def label(values: dict) -> str:
    """A member's values as "name=value, ..." (in errors, captions and titles)."""
    return ", ".join(f"{k}={v:g}" for k, v in values.items())


def grid_labels(names, axes) -> tuple[list[str] | None, list[str]]:
    """(row labels, column labels) of a grid's picture: the last name's values head the
    columns (3 significant digits); each row is one combination of the others, as
    "name=value, ..." (None for a one-axis grid)."""
    cols = [f"{v:.3g}" for v in axes[-1]]
    if len(axes) == 1:
        return None, cols
    rows = [", ".join(f"{n}={v:.3g}" for n, v in zip(names[:-1], combo)) for combo in itertools.product(*axes[:-1])]
    return rows, cols

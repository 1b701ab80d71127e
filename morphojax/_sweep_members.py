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
import math
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._checks import STEP_COUNTER_MAX, check_run_size
from .models import AbstractModel

GROWTH_RATE = "growth_rate"  # the growth schedule's rate (needs growth=Growth(...))
DT = "dt"  # the time step, per member (steps stay the same for every member)
MAX_MEMBERS = STEP_COUNTER_MAX  # members are indexed and keyed (fold_in) by int32 counters


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


def check_members(names, counts, *, grid: bool = True, shape=None, species: int = 2) -> int:
    """The number of members of a sweep of `names` with `counts` values each (a grid: their
    product; a list of sets: one count), counted exactly before any member's values are built.
    Refused when it is beyond what the int32 member counters hold or, given the lattice `shape`
    (or capacity) of one member and its `species`, when the run would need more memory than
    the limit (`_checks.check_run_size`, the estimate the command line uses)."""
    n = math.prod(int(c) for c in counts)
    if grid and len(counts) > 1:
        which = f"{n} members ({' x '.join(names)} = {' x '.join(str(int(c)) for c in counts)})"
    else:
        which = f"{n} members ({names[0]})" if grid else f"{n} members (parameter sets of {', '.join(names)})"
    if n > MAX_MEMBERS:
        raise ValueError(f"sweep: vary gives {which}; a sweep has at most {MAX_MEMBERS} members, what its int32 "
                         "member counter holds")
    if shape is not None:
        cells = "x".join(str(int(s)) for s in shape)
        check_run_size(shape, species, members=n,
                       what=f"sweep: vary gives {which}, each {int(species)} species on {cells} cells; this sweep")
    return n


def sweep_members(model, vary, growth, dt, *, shape=None, species: int = 2):
    """(names, grid axes or None, per-member values {name: (n,) array}, result shape).

    The member count is checked (`check_members`, with the lattice `shape` and `species` of
    one member when given) before the members' values are built."""
    if isinstance(vary, Mapping):
        if not vary:
            raise ValueError(f"sweep: vary is empty; name at least one parameter: {_describe_allowed(model, growth)}")
        names = tuple(vary)
        for name in names:
            _check_name(model, growth, name)
        axes = tuple(_check_values(name, vary[name]) for name in names)
        check_members(names, [len(a) for a in axes], shape=shape, species=species)
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
        check_members(names, [len(rows)], grid=False, shape=shape, species=species)
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

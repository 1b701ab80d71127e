"""Rules as data (thesis 4.8.5, Listings 4.6-4.7, Table 4.1): per cell, when the
conditions hold, do the action. Every rule is evaluated for every cell inside the compiled
step, on the cells' *current* state; the effects are accumulated and applied together
(thesis 4.1, step 2), so the order of cells never matters.

    Rule(action, when=(condition, ...), start=None, stop=None)

Operands are numbers (traced arrays: a sweep or a gradient can go through them) or
variables of the cell: `conc("R")`, `diff("R")`, `AGE`, `BIRTH`, `NEIGHBORS`, or the name
of a `Map` computed earlier in the same iteration (`mapped("PAT")`).

Conditions: `Always()`, `Compare(a, op, b)` with op in == != < <= > >=, `Within(a, low,
high)` (the listing's `in`, both ends included) and `Chance(p)` (a fresh uniform draw per
cell, per rule and per iteration). The iteration window `start`/`stop` (the listing's
`from`/`until`) includes both ends; a listing's `and` chains become one rule with several
conditions.

Actions:
- `Change(target, amount, spread=0)`: add `amount` (+ a uniform draw in [-spread,
  spread]) to a concentration or a diffusion rate, once per iteration, not scaled by dt
  (the thesis's `change`: "only the given amount to be added").
- `React(model, species, scale=1)`: add dt * scale * the model's reaction on the named
  reagents (any morphojax reaction; the listing's `react U V scale s turing alpha a beta b`
  is `React(Bard(alpha=a, beta=b, sp=s), ("U", "V"))`, thesis eqs. 4.5-4.6).
- `Divide(direction=0, spread=0)`: divide after this iteration, the child one unit away at
  angle polarity + direction + a uniform draw in [-spread, spread] (radians; thesis 4.4).
- `Map(source, low, high, name, out_low, out_high)`: the clamped linear map of `source`
  from [low, high] to [out_low, out_high], named for later rules of the same iteration.
- `Polarize(reagent)`: the polarity follows the reagent's local gradient from the next
  iteration on (thesis eq. 4.10).
"""

from __future__ import annotations

import math
from typing import Union

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from .._checks import as_float_array, check_choice, check_finite, check_range
from ..models import AbstractModel

VARIABLES = ("conc", "diff", "AGE", "BIRTH", "NEIGHBORS", "map")
OPERATORS = ("==", "!=", "<", "<=", ">", ">=")


class Var(eqx.Module):
    """A per-cell quantity a rule reads: `conc("R")`, `diff("R")`, `AGE`, `BIRTH`,
    `NEIGHBORS` or a mapped value `mapped("PAT")`."""

    kind: str = eqx.field(static=True)
    name: str | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        check_choice(self.kind, "rule variable", VARIABLES)
        if (self.kind in ("conc", "diff", "map")) != (self.name is not None):
            raise ValueError(f"rule variable {self.kind!r} {'needs' if self.name is None else 'takes no'} a name")

    def __str__(self):
        return f"{self.name} {self.kind}" if self.kind in ("conc", "diff") else (self.name or self.kind)


def conc(name: str) -> Var:
    """The concentration of reagent `name`."""
    return Var("conc", name)


def diff(name: str) -> Var:
    """The diffusion rate of reagent `name`."""
    return Var("diff", name)


def mapped(name: str) -> Var:
    """The value a `Map` action named `name` computed earlier in the same iteration."""
    return Var("map", name)


AGE = Var("AGE")
BIRTH = Var("BIRTH")
NEIGHBORS = Var("NEIGHBORS")

Operand = Union[Var, Array]


def operand(value, name: str) -> Operand:
    """A rule operand: a `Var`, or a number made a float array (a traced leaf)."""
    if isinstance(value, Var):
        return value
    arr = as_float_array(value, name)
    check_finite(arr, name)
    return arr


# ---- conditions ------------------------------------------------------------------
class Always(eqx.Module):
    """True for every cell."""


class Compare(eqx.Module):
    """`left op right`, op one of == != < <= > >= (exact float comparison, as published)."""

    left: Operand
    op: str = eqx.field(static=True)
    right: Operand

    def __init__(self, left, op: str, right):
        check_choice(op, "comparison", OPERATORS)
        self.left, self.op, self.right = operand(left, "Compare.left"), op, operand(right, "Compare.right")


class Within(eqx.Module):
    """`low <= value <= high` (the listing's `if value in low high`)."""

    value: Operand
    low: Operand
    high: Operand

    def __init__(self, value, low, high):
        self.value, self.low, self.high = (operand(v, f"Within.{n}") for v, n in
                                           ((value, "value"), (low, "low"), (high, "high")))


class Chance(eqx.Module):
    """True with probability `probability` (a fresh draw per cell, rule and iteration)."""

    probability: Operand

    def __init__(self, probability):
        self.probability = operand(probability, "Chance.probability")
        if not isinstance(self.probability, Var):
            check_range(self.probability, "Chance.probability", low=0.0, high=1.0)


Condition = Union[Always, Compare, Within, Chance]


# ---- actions ---------------------------------------------------------------------
class Change(eqx.Module):
    """Add `amount` (+ uniform noise of amplitude `spread`) to `target`, a `conc(...)` or
    `diff(...)` variable, once per iteration (not scaled by dt)."""

    target: Var
    amount: Operand
    spread: Array

    def __init__(self, target, amount, spread=0.0):
        if isinstance(target, str):
            target = conc(target)
        if not isinstance(target, Var) or target.kind not in ("conc", "diff"):
            raise ValueError(f"Change.target must be conc(name) or diff(name) (got {target!r})")
        self.target, self.amount = target, operand(amount, "Change.amount")
        self.spread = as_float_array(spread, "Change.spread")
        check_range(self.spread, "Change.spread", low=0.0)


class React(eqx.Module):
    """Add dt * scale * `model.reaction` of the reagents `species` (in the model's order)."""

    model: AbstractModel
    species: tuple[str, ...] = eqx.field(static=True)
    scale: Operand

    def __init__(self, model: AbstractModel, species, scale=1.0):
        if not isinstance(model, AbstractModel):
            raise ValueError(f"React.model must be a morphojax model (got {type(model).__name__})")
        species = (species,) if isinstance(species, str) else tuple(species)
        if len(set(species)) != len(species):
            raise ValueError(f"React.species must name distinct reagents (got {species})")
        if len(species) != model.n_species:
            raise ValueError(f"React.species names {len(species)} reagents; {type(model).__name__} reacts "
                             f"{model.n_species} ({', '.join(model.species)})")
        self.model, self.species, self.scale = model, species, operand(scale, "React.scale")


class Divide(eqx.Module):
    """Divide after this iteration; the child sits one unit away at angle polarity +
    `direction` + uniform noise of amplitude `spread` (radians), and its polarity is turned
    by the same angle (so `direction` = 137.5 degrees makes the spiral of Fig. 6.3)."""

    direction: Array
    spread: Array

    def __init__(self, direction=0.0, spread=0.0):
        self.direction = as_float_array(direction, "Divide.direction")
        self.spread = as_float_array(spread, "Divide.spread")
        check_finite(self.direction, "Divide.direction")
        check_range(self.spread, "Divide.spread (radians)", low=0.0, high=math.pi)


class Map(eqx.Module):
    """Name the clamped linear map of `source` from [low, high] onto [out_low, out_high]."""

    source: Operand
    low: Operand
    high: Operand
    name: str = eqx.field(static=True)
    out_low: Operand
    out_high: Operand

    def __init__(self, source, low, high, name: str, out_low, out_high):
        self.source, self.low, self.high = (operand(v, "Map") for v in (source, low, high))
        self.name = str(name)
        self.out_low, self.out_high = operand(out_low, "Map.out_low"), operand(out_high, "Map.out_high")


class Polarize(eqx.Module):
    """Set the polarity along the gradient of `reagent` (eq. 4.10), from the next iteration."""

    reagent: str = eqx.field(static=True)


Action = Union[Change, React, Divide, Map, Polarize]


class Rule(eqx.Module):
    """Do `action` for the cells where every condition of `when` holds, on iterations
    `start` to `stop` (both included; None = unbounded)."""

    action: Action
    when: tuple = ()
    start: int | None = eqx.field(static=True, default=None)
    stop: int | None = eqx.field(static=True, default=None)

    def __init__(self, action, when=(), start: int | None = None, stop: int | None = None):
        if not isinstance(action, (Change, React, Divide, Map, Polarize)):
            raise ValueError(f"Rule.action must be Change, React, Divide, Map or Polarize (got {type(action).__name__})")
        when = (when,) if not isinstance(when, (tuple, list)) else tuple(when)
        for c in when:
            if not isinstance(c, (Always, Compare, Within, Chance)):
                raise ValueError(f"Rule.when holds conditions (Always, Compare, Within, Chance) (got {type(c).__name__})")
        for name, value in (("start", start), ("stop", stop)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 0):
                raise ValueError(f"Rule.{name} must be an iteration number >= 0 or None (got {value!r})")
        self.action, self.when, self.start, self.stop = action, when, start, stop

    def active(self, iteration: Array) -> Array:
        """Whether `iteration` lies in the window (a scalar bool)."""
        ok = jnp.asarray(True)
        if self.start is not None:
            ok &= iteration >= self.start
        if self.stop is not None:
            ok &= iteration <= self.stop
        return ok


def check_rules(rules, species: tuple[str, ...]) -> tuple[Rule, ...]:
    """The rules as a tuple, after checking every name they use against `species` and
    every mapped value against the maps defined before it."""
    rules = tuple(rules)
    maps: set[str] = set()
    for i, rule in enumerate(rules):
        if not isinstance(rule, Rule):
            raise ValueError(f"rules[{i}] must be a Rule (got {type(rule).__name__})")
        for var in _variables(rule):
            if var.kind in ("conc", "diff") and var.name not in species:
                raise ValueError(f"rules[{i}] names reagent {var.name!r}; the cells carry {', '.join(species)}")
            if var.kind == "map" and var.name not in maps:
                raise ValueError(f"rules[{i}] reads mapped value {var.name!r} before a Map defines it")
        action = rule.action
        if isinstance(action, React):
            for name in action.species:
                if name not in species:
                    raise ValueError(f"rules[{i}] reacts reagent {name!r}; the cells carry {', '.join(species)}")
        if isinstance(action, Polarize) and action.reagent not in species:
            raise ValueError(f"rules[{i}] polarizes along {action.reagent!r}; the cells carry {', '.join(species)}")
        if isinstance(action, Map):
            maps.add(action.name)
    return rules


def _variables(rule: Rule):
    leaves = jax.tree_util.tree_leaves(rule, is_leaf=lambda x: isinstance(x, Var))
    return [leaf for leaf in leaves if isinstance(leaf, Var)]

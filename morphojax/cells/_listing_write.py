"""Writing a listing back and comparing listings (thesis 4.8): `_write_listing` gives the
canonical text of a `Listing` (one command per line, defaults left out, every rule written
from its `Rule` data, numbers as the shortest decimals that read back to the same values),
and `rule_key`, `same_rules` and `_listing_key` compare rules and listings by their
structure and numbers (the basis of `Listing.__eq__`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import jax
import numpy as np

from ..models import Bard
from ._listing_commands import Create, SetCells, UseChemical, UsePolarity
from ._rules import Always, Chance, Change, Compare, Divide, Map, Polarize, React, Rule, Var, Within
from ._space import Box, Packed

if TYPE_CHECKING:
    from ._listing import Listing


# ---- writing -------------------------------------------------------------------------


def _format_number(value) -> str:
    """The shortest decimal that reads back to the same value in its own precision (a
    float32 leaf of a rule reads back from "0.0004", not "0.0003999999898951501")."""
    array = np.asarray(value)
    scalar = (array if array.dtype.kind == "f" else array.astype(np.float64)).reshape(())[()]
    magnitude = abs(float(scalar))
    if magnitude != 0 and (magnitude < 1e-6 or magnitude >= 1e15):
        return np.format_float_scientific(scalar, unique=True, trim="-")
    return np.format_float_positional(scalar, unique=True, trim="-")


def _format_degrees(radians) -> str:
    """The shortest degree string that reads back (through `math.radians` and the leaf's
    dtype) to the same angle leaf."""
    leaf = np.asarray(radians)
    degrees = math.degrees(float(leaf))
    for digits in range(1, 18):
        text = np.format_float_positional(degrees, precision=digits, unique=False, fractional=False, trim="-")
        if np.asarray(math.radians(float(text)), leaf.dtype) == leaf:
            return text
    return repr(degrees)


def _format_operand(value) -> str:
    return str(value) if isinstance(value, Var) else _format_number(value)


def _format_condition(condition) -> str:
    if isinstance(condition, Always):
        return "always"
    if isinstance(condition, Chance):
        return f"probability {_format_operand(condition.probability)}"
    if isinstance(condition, Compare):
        return f"if {_format_operand(condition.left)} {condition.op} {_format_operand(condition.right)}"
    if isinstance(condition, Within):
        return (f"if {_format_operand(condition.value)} in {_format_operand(condition.low)} "
                f"{_format_operand(condition.high)}")
    raise ValueError(f"the listing language cannot write the condition {condition!r}")


def _format_action(action) -> str:
    if isinstance(action, Change):
        dev = f" dev {_format_number(action.spread)}" if float(action.spread) != 0 else ""
        return f"change {action.target} {_format_operand(action.amount)}{dev}"
    if isinstance(action, React):
        model = action.model
        if not isinstance(model, Bard) or float(model.sp) != 1.0:
            raise ValueError("the listing language writes only react ... turing (Bard with sp = 1); "
                             f"cannot write {type(model).__name__}")
        return (f"react {' '.join(action.species)} scale {_format_operand(action.scale)} turing "
                f"alpha {_format_number(model.alpha)} beta {_format_number(model.beta)}")
    if isinstance(action, Divide):
        dev = f" dev {_format_degrees(action.spread)}" if float(action.spread) != 0 else ""
        return f"divide direction {_format_degrees(action.direction)}{dev}"
    if isinstance(action, Map):
        return (f"map {_format_operand(action.source)} {_format_operand(action.low)} {_format_operand(action.high)} "
                f"to {action.name} {_format_operand(action.out_low)} {_format_operand(action.out_high)}")
    if isinstance(action, Polarize):
        return f"polarize {action.reagent}"
    raise ValueError(f"the listing language cannot write the action {action!r}")


def _format_rule(rule: Rule) -> list[str]:
    window = "".join(f" {word} {value}" for word, value in (("from", rule.start), ("until", rule.stop)) if value is not None)
    conditions = [_format_condition(c) for c in rule.when] or ["always"]
    lines = [f"rule{window} {c} and" for c in conditions[:-1]]
    return lines + [f"rule{window} {conditions[-1]} {_format_action(rule.action)}"]


def _format_value_dev(word: str, given) -> str:
    if given is None:
        return ""
    value, dev = given
    return f" {word} {_format_number(value)}" + (f" dev {_format_number(dev)}" if dev else "")


def _format_command(command) -> str:
    if isinstance(command, UseChemical):
        return (f"use chemical {command.chemical}{_format_value_dev('conc', command.conc)}"
                f"{_format_value_dev('diff', command.diff)}")
    if isinstance(command, UsePolarity):
        if command.angle is None:
            return "use polarity none"
        dev = f" dev {_format_number(command.dev)}" if command.dev else ""
        return f"use polarity {_format_number(command.angle)}{dev}"
    if isinstance(command, Create):
        if command.kind == "shape":
            size = f' "{command.file}"'
        else:
            size = "".join(f" {v}" if isinstance(v, int) else f" {_format_number(v)}" for v in command.size)
        at = f" at {_format_number(command.at[0])} {_format_number(command.at[1])}" if tuple(command.at) != (0.0, 0.0) else ""
        dev = f" dev {_format_number(command.dev)}" if command.dev else ""
        return f"create {command.kind}{size}{at}{dev}{' fixed' if command.fixed else ''}"
    if isinstance(command, SetCells):
        cells = f"cell {command.first}" if command.first == command.last else f"cells {command.first} to {command.last}"
        chemical = f" chemical {command.chemical}" if command.chemical is not None else ""
        if command.polarity == "none":
            polarity = " polarity none"
        else:
            polarity = _format_value_dev("polarity", None if command.polarity is None else (command.polarity, command.polarity_dev))
        return (f"set {cells}{chemical}{_format_value_dev('conc', command.conc)}{_format_value_dev('diff', command.diff)}"
                f"{polarity}{' fixed' if command.fixed else ''}")
    raise ValueError(f"unknown prepattern command {command!r}")


def _write_listing(listing: Listing) -> list[str]:
    lines = []
    for c in listing.chemicals:
        limit = f" limit {_format_number(c.limit)}" if c.limit is not None else ""
        lines.append(f"define chemical {c.name}{limit}{' anisotropic' if c.anisotropic else ''}")
    if listing.division_limit is not None:
        lines.append(f"define division_limit {listing.division_limit}")
    if isinstance(listing.domain, Box):
        lines.append(f"define domain {_format_number(listing.domain.width)} {_format_number(listing.domain.height)}")
    elif isinstance(listing.domain, Packed):
        default = np.asarray(listing.domain.area) == np.asarray(Packed().area)
        lines.append("define domain packed" + ("" if default else f" area {_format_number(listing.domain.area)}"))
    if listing.dt != 1.0:
        lines.append(f"define time_step {_format_number(listing.dt)}")
    if listing.seed is not None:
        lines.append(f"use seed {listing.seed}")
    lines += [_format_command(c) for c in listing.commands]
    for rule in listing.rules:
        lines += _format_rule(rule)
    if listing.colormap_select is not None:
        lines.append(f"colormap select {listing.colormap_select}")
    for slot, colour in listing.colormap_slots:
        use = f'color "{colour}"' if isinstance(colour, str) else "rgb " + " ".join(str(int(v)) for v in colour)
        lines.append(f"colormap slot {slot} use {use}")
    if listing.texture is not None:
        lines.append(f"texture size {listing.texture[0]} {listing.texture[1]}")
    if listing.zoom is not None:
        lines.append(f"zoom level {_format_number(listing.zoom)}")
    for snap in listing.snaps:
        if snap.every is None:
            text = "snap at " + " ".join(str(i) for i in snap.at)
        else:
            text = f"snap from {snap.at[0]} repeat {snap.every[0]} step {snap.every[1]}"
        lines.append(text + (" then exit" if snap.exit else ""))
    if listing.stop is not None:
        lines.append(f"stop at {listing.stop}")
    return lines


# ---- comparing -----------------------------------------------------------------------


def rule_key(rule: Rule):
    """A comparable, hashable form of a rule: its tree structure (actions, conditions,
    names, operators, window) and its numbers as Python floats."""
    leaves, treedef = jax.tree_util.tree_flatten(rule)
    return treedef, tuple(tuple(np.asarray(leaf, float).ravel().tolist()) for leaf in leaves)


def same_rules(a, b) -> bool:
    """Whether two sequences of rules are the same rules with the same numbers."""
    a, b = tuple(a), tuple(b)
    return len(a) == len(b) and all(rule_key(x) == rule_key(y) for x, y in zip(a, b))


def _domain_key(domain):
    if domain is None:
        return None
    return type(domain).__name__, tuple(np.asarray(leaf, float).item() for leaf in jax.tree_util.tree_leaves(domain))


def _listing_key(listing: Listing):
    return (
        listing.chemicals, listing.dt, listing.stop, _domain_key(listing.domain), listing.division_limit,
        listing.seed, listing.commands, tuple(rule_key(r) for r in listing.rules), listing.colormap_select,
        listing.colormap_slots, listing.texture, listing.zoom, listing.snaps,
    )


__all__ = ["rule_key", "same_rules"]

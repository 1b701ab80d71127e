"""Writing a listing's statements back and comparing rules (thesis 4.8): `format_command`
and `format_rule` give the canonical text of a prepattern command and of a `Rule` (defaults
left out, every rule written from its `Rule` data, numbers as the shortest decimals that
read back to the same values), and `rule_key`, `same_rules` and `domain_key` compare rules
and domains by their structure and numbers. `Listing.to_text` and `Listing.__eq__` (in
`_listing`, which imports this module) are built from them.
"""

from __future__ import annotations

import math

import jax
import numpy as np

from ..models import Bard
from ._listing_commands import Create, SetCells, UseChemical, UsePolarity
from ._listing_tokens import format_number
from ._rules import Always, Chance, Change, Compare, Divide, Map, Polarize, React, Rule, Var, Within
from ._space import Torus

# ---- writing -------------------------------------------------------------------------


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
    return str(value) if isinstance(value, Var) else format_number(value)


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
        dev = f" dev {format_number(action.spread)}" if float(action.spread) != 0 else ""
        return f"change {action.target} {_format_operand(action.amount)}{dev}"
    if isinstance(action, React):
        model = action.model
        if not isinstance(model, Bard) or float(model.sp) != 1.0:
            raise ValueError("the listing language writes only react ... turing (Bard with sp = 1); "
                             f"cannot write {type(model).__name__}")
        return (f"react {' '.join(action.species)} scale {_format_operand(action.scale)} turing "
                f"alpha {format_number(model.alpha)} beta {format_number(model.beta)}")
    if isinstance(action, Divide):
        dev = f" dev {_format_degrees(action.spread)}" if float(action.spread) != 0 else ""
        return f"divide direction {_format_degrees(action.direction)}{dev}"
    if isinstance(action, Map):
        return (f"map {_format_operand(action.source)} {_format_operand(action.low)} {_format_operand(action.high)} "
                f"to {action.name} {_format_operand(action.out_low)} {_format_operand(action.out_high)}")
    if isinstance(action, Polarize):
        return f"polarize {action.reagent}"
    raise ValueError(f"the listing language cannot write the action {action!r}")


def format_rule(rule: Rule) -> list[str]:
    window = "".join(f" {word} {value}" for word, value in (("from", rule.start), ("until", rule.stop)) if value is not None)
    conditions = [_format_condition(c) for c in rule.when] or ["always"]
    lines = [f"rule{window} {c} and" for c in conditions[:-1]]
    return lines + [f"rule{window} {conditions[-1]} {_format_action(rule.action)}"]


def _format_value_dev(word: str, given) -> str:
    if given is None:
        return ""
    value, dev = given
    return f" {word} {format_number(value)}" + (f" dev {format_number(dev)}" if dev else "")


def format_command(command) -> str:
    if isinstance(command, UseChemical):
        return (f"use chemical {command.chemical}{_format_value_dev('conc', command.conc)}"
                f"{_format_value_dev('diff', command.diff)}")
    if isinstance(command, UsePolarity):
        if command.angle is None:
            return "use polarity none"
        dev = f" dev {format_number(command.dev)}" if command.dev else ""
        return f"use polarity {format_number(command.angle)}{dev}"
    if isinstance(command, Create):
        if command.kind == "shape":
            size = f' "{command.file}"'
        else:
            size = "".join(f" {v}" if isinstance(v, int) else f" {format_number(v)}" for v in command.size)
        at = f" at {format_number(command.at[0])} {format_number(command.at[1])}" if tuple(command.at) != (0.0, 0.0) else ""
        dev = f" dev {format_number(command.dev)}" if command.dev else ""
        return f"create {command.kind}{size}{at}{dev}{' fixed' if command.fixed else ''}{' wrap' if command.wrap else ''}"
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


def domain_key(domain):
    """A comparable form of a `Box`, `Packed` or `Torus` domain (None for none): its type and numbers."""
    if domain is None:
        return None
    if isinstance(domain, Torus):  # its sides are static fields, not leaves
        return "Torus", domain.period
    return type(domain).__name__, tuple(np.asarray(leaf, float).item() for leaf in jax.tree_util.tree_leaves(domain))


__all__ = ["domain_key", "format_command", "format_rule", "rule_key", "same_rules"]

"""griffe extension: the API pages leave out a class's construction machinery and its
private bases.

mkdocstrings' `filters: public` keeps every special method, since Python calls them on the
user's behalf; but `__check_init__` (equinox's checks) and `__post_init__` are how a class
builds itself, not something a user calls, and `__repr__` and the like say nothing a reader
needs. A special member is shown only where it is an operation a user writes: calling,
indexing, `len`, iterating (and `__init__`, which `merge_init_into_class` folds into the
class's own entry). Names with one leading underscore are private to griffe already.

A private base (a name with a leading underscore) is folded into the public classes built
on it: they show its members as their own and its bases as theirs.
"""

from __future__ import annotations

import copy

import griffe

SHOWN = frozenset({"__init__", "__call__", "__getitem__", "__len__", "__iter__"})


def hidden(name: str) -> bool:
    """Whether a class member named `name` stays off the API pages."""
    return name.startswith("__") and name.endswith("__") and name not in SHOWN


class HideClassMachinery(griffe.Extension):
    """Drops the hidden members from every class the package defines, once it is loaded.

    Dropped rather than marked private: a page renders a class through its re-exported
    name (`morphojax.Turing`), an alias whose members are aliases that ask their own parent,
    not the class, whether they are public."""

    def on_package(self, *, pkg, **kwargs) -> None:
        self._drop(pkg)

    def _drop(self, obj) -> None:
        for name, member in list(obj.members.items()):
            if member.is_alias:
                continue
            if member.is_class:
                _flatten_private_bases(member)
                for inner in [n for n in member.members if hidden(n)]:
                    member.del_member(inner)
            if member.is_class or member.is_module:
                self._drop(member)


def _flatten_private_bases(cls) -> None:
    """A class built on a private base (`_AbstractRatesAB`, which Schnakenberg and the
    Brusselator share) is shown as if it declared the base's members itself, with the base's
    own bases in its place: the reader sees every field and method of the public class and
    no private name."""
    bases, changed = [], False
    for expression, base in zip(cls.bases, _resolved(cls)):
        if base is None or not base.name.startswith("_"):
            bases.append(expression)
            continue
        _flatten_private_bases(base)
        changed = True
        bases.extend(base.bases)
        for name, member in base.members.items():
            if name not in cls.members and not member.is_alias:
                inherited = copy.copy(member)
                cls.set_member(name, inherited)
    if changed:
        cls.bases = bases


def _resolved(cls) -> list:
    """Each base of `cls` as the class it names, or None where it names none griffe loaded."""
    out = []
    for expression in cls.bases:
        try:
            target = cls.modules_collection.get_member(expression.canonical_path)
        except (AttributeError, KeyError):
            target = None
        out.append(target.final_target if target is not None and target.is_alias else target)
    return out

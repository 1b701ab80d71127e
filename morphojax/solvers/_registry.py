"""Solvers and stopping rules as plain data, for the files that record a run's phases."""

from __future__ import annotations

from ._base import AbstractSolver, Euler
from ._spectral import ETDRK, IMEX

_SOLVERS = {"Euler": Euler, "ETDRK": ETDRK, "IMEX": IMEX}


def solver_to_dict(solver: AbstractSolver | None) -> dict:
    return (solver or Euler()).to_dict()


def solver_from_dict(d: dict | None) -> AbstractSolver:
    """The solver a file records; files from before solvers existed ran forward Euler."""
    if not d:
        return Euler()
    name = d.get("solver")
    if name not in _SOLVERS:
        raise ValueError(f"unknown solver {name!r} in the file; known: {', '.join(_SOLVERS)}")
    if name == "Euler":
        return Euler()
    return _SOLVERS[name](order=int(d.get("order", 2)), rtol=d.get("rtol"), atol=d.get("atol"))

"""Solvers and stopping rules as plain data, for the files that record a run's phases."""

from __future__ import annotations

from ._base import AbstractSolver, Euler
from ._spectral import ETDRK, IMEX
from ._steady import SteadyState

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
    return _SOLVERS[name](order=int(d.get("order", 2)), rtol=d.get("rtol"), atol=d.get("atol"),
                          max_steps=int(d.get("max_steps", 100_000)))


def until_to_dict(until) -> dict | None:
    return None if until is None else until.to_dict()


def until_from_dict(d: dict | None):
    """The stopping rule a file records (None: none)."""
    if not d:
        return None
    if d.get("until") != "steady-state":
        raise ValueError(f"unknown stopping rule {d.get('until')!r} in the file; known: 'steady-state'")
    return SteadyState(tol=float(d["tol"]))

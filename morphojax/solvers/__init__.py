"""Time-stepping policies (`Euler`, `ETDRK`, `IMEX`) and stopping rules (`SteadyState`)."""

from ._base import AbstractSolver, Euler, as_solver
from ._spectral import ETDRK, IMEX
from ._registry import solver_from_dict, solver_to_dict, until_from_dict, until_to_dict
from ._steady import SteadyState

__all__ = ["AbstractSolver", "Euler", "ETDRK", "IMEX", "SteadyState", "as_solver", "solver_from_dict",
           "solver_to_dict", "until_from_dict", "until_to_dict"]

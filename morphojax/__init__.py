"""morphojax: a differentiable JAX simulator of biological pattern formation.

    import morphojax as mj
    model = mj.Turing(ratio=4.2, scale=3.0)
    state = mj.paper_state(jax.random.key(0), (128, 128))
    state = mj.simulate(model, state, steps=10_000, dt=0.01)
    a, b = state.arrays()
"""

from ._lattice import BOUNDARIES, STENCILS, laplacian, max_stable_dt
from ._models import (
    AbstractModel,
    Bard,
    Composite,
    GrayScott,
    Reinforcement,
    Turing,
    model_from_name,
)
from ._state import State
from ._initial import constant_state, gray_scott_state, initial_state, paper_state, random_state, thesis_state
from ._simulate import Barrier, SimulationError, rollout, run_status, simulate

__version__ = "0.1.0"

__all__ = [
    "AbstractModel",
    "BOUNDARIES",
    "Bard",
    "Barrier",
    "Composite",
    "GrayScott",
    "Reinforcement",
    "STENCILS",
    "SimulationError",
    "State",
    "Turing",
    "constant_state",
    "gray_scott_state",
    "initial_state",
    "laplacian",
    "max_stable_dt",
    "model_from_name",
    "paper_state",
    "random_state",
    "rollout",
    "run_status",
    "simulate",
    "thesis_state",
]

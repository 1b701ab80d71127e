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
from ._growth import DISTRIBUTIONS, Growth, Source
from ._experiment import Experiment, Initial, Phase, Result, run_experiment
from ._io import load_npz, save_npz
from ._render import Gradient, montage, render, save_png, to_image
from ._presets import PRESETS, preset

from ._version import __version__

__all__ = [
    "to_image",
    "save_png",
    "render",
    "preset",
    "montage",
    "PRESETS",
    "Gradient",
    "AbstractModel",
    "BOUNDARIES",
    "Bard",
    "Barrier",
    "Composite",
    "DISTRIBUTIONS",
    "Experiment",
    "Growth",
    "Initial",
    "Phase",
    "Result",
    "Source",
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
    "load_npz",
    "max_stable_dt",
    "model_from_name",
    "paper_state",
    "random_state",
    "rollout",
    "run_experiment",
    "run_status",
    "save_npz",
    "simulate",
    "thesis_state",
]

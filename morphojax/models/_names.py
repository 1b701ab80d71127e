"""Models by their command-line names (`morphojax run --model NAME`, sweeps, fits)."""

from __future__ import annotations

from ._base import AbstractModel
from ._classic import GrayScott
from ._reinforcement import Reinforcement
from ._turing import Bard, Turing

MODELS = {"turing": Turing, "bard": Bard, "gray-scott": GrayScott, "reinforcement": Reinforcement}


def model_from_name(name: str, **params) -> AbstractModel:
    """Build a model from its command-line name (`turing`, `bard`, `gray-scott`, `reinforcement`)."""
    key = name.lower().replace("_", "-")
    if key == "grayscott":
        key = "gray-scott"
    if key not in MODELS:
        raise ValueError(f"unknown model {name!r}; allowed: {', '.join(MODELS)}")
    model = MODELS[key]()
    return model.replace(**params) if params else model

"""Models by their command-line names (`morphojax run --model NAME`, sweeps, fits)."""

from __future__ import annotations

from ._base import AbstractModel
from ._classic import Brusselator, FitzHughNagumo, GiererMeinhardt, GrayScott, Schnakenberg, Thomas
from ._reinforcement import Reinforcement
from ._saturation import RuleReinforcement, ThesisReinforcement
from ._turing import Bard, Turing

MODELS = {
    "turing": Turing, "bard": Bard, "gray-scott": GrayScott, "reinforcement": Reinforcement,
    "fitzhugh-nagumo": FitzHughNagumo, "gierer-meinhardt": GiererMeinhardt, "schnakenberg": Schnakenberg,
    "brusselator": Brusselator, "thesis-reinforcement": ThesisReinforcement, "rule-reinforcement": RuleReinforcement,
    "thomas": Thomas,
}
_SPELLINGS = {"grayscott": "gray-scott", "fitzhughnagumo": "fitzhugh-nagumo", "fhn": "fitzhugh-nagumo",
              "gierermeinhardt": "gierer-meinhardt", "thesisreinforcement": "thesis-reinforcement",
              "rulereinforcement": "rule-reinforcement"}


def model_from_name(name: str, **params) -> AbstractModel:
    """Build a model from its command-line name (the keys of `MODELS`, e.g. `turing`,
    `gray-scott`, `fitzhugh-nagumo`; the class names work too: `GrayScott`, `FitzHughNagumo`). A
    user's `Reaction` has no name: it needs its function."""
    key = name.lower().replace("_", "-")
    key = _SPELLINGS.get(key, key)
    if key not in MODELS:
        raise ValueError(f"unknown model {name!r}; allowed: {', '.join(MODELS)}")
    model = MODELS[key]()
    return model.replace(**params) if params else model

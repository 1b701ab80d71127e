"""Reaction-diffusion models: the reaction terms, diffusion rates and saturation limits.

`_base` holds `AbstractModel` / `AbstractReaction` and the per-species helpers; each family
of reactions has its module (`_turing`: Bard, Turing; `_classic`: Gray-Scott and the other
two-species systems of the literature, Thomas's substrate inhibition among them;
`_reinforcement`; `_saturation`: the thesis's cubic and rule-based reinforcement;
`_morphogen`: a signal that only diffuses, is produced and removed; `_custom`: a user's own reaction); `_modulated` sets parameters
from a reagent's concentration (thesis 5.3);
`_composite` runs several side by side; `_names` builds a model from its command-line name;
`_steady` finds homogeneous steady states within the limits (Newton's method) and the
reaction's local Jacobian.
"""

from ._base import AbstractModel, AbstractReaction, per_species
from ._classic import Brusselator, FitzHughNagumo, GiererMeinhardt, GrayScott, Schnakenberg, Thomas
from ._composite import Composite
from ._custom import Reaction, ReactionFunction
from ._modulated import Modulated, Modulation
from ._morphogen import Morphogen
from ._names import MODELS, model_from_name
from ._reinforcement import Reinforcement
from ._saturation import RuleReinforcement, ThesisReinforcement
from ._turing import Bard, Turing, bard_reaction

__all__ = [
    "AbstractModel",
    "AbstractReaction",
    "Bard",
    "bard_reaction",
    "Brusselator",
    "Composite",
    "FitzHughNagumo",
    "GiererMeinhardt",
    "GrayScott",
    "MODELS",
    "Modulated",
    "Modulation",
    "Morphogen",
    "model_from_name",
    "per_species",
    "Reaction",
    "ReactionFunction",
    "Reinforcement",
    "RuleReinforcement",
    "Schnakenberg",
    "ThesisReinforcement",
    "Thomas",
    "Turing",
]

"""Presets: every named run of the papers' figures, of every kind, in one registry.

    mj.PRESETS["leopard"].figure                 # "leopard paper Figs. 13-17"
    mj.run_experiment(mj.preset("leopard", quick=True))
    mj.PRESETS["young-fig8"].run(seed=0, quick=True, out="young.png")

`PRESETS` maps each name to its `Preset` (its `kind`, the figure it reproduces and its
builder); `morphojax presets` lists them and `morphojax run NAME` runs one. The registry is
`_registry`; the reaction-diffusion experiments are `_experiments`, the cellular automata
`_automata`.
"""

from ._registry import (PRESETS, AutomatonPreset, ExperimentPreset, Preset, lookup, of_kind, preset, register,
                        registered)
from ._experiments import FIG4_RATIOS, leopard_row_weights
from . import _automata  # noqa: F401  (registers the automaton presets)
from . import _reactions  # noqa: F401  (registers the classic reactions' Turing patterns)
from . import _lattices  # noqa: F401  (registers the square/hexagonal lattice presets)
from . import _parameters  # noqa: F401  (registers thesis Figs. 5.3, 5.6-5.9: Listing 5.1's parameter study)
from . import _potts  # noqa: F401  (registers the cellular Potts presets)
from . import _anisotropy  # noqa: F401  (registers thesis Figs. 5.1 and 5.13: per-cell rates, anisotropy)
from . import _modulation  # noqa: F401  (registers thesis Figs. 5.11 and 5.12: parameters set from a gradient)
from . import _meshes  # noqa: F401  (registers the triangle-mesh presets)
from . import _growing_meshes  # noqa: F401  (registers the growing-mesh preset)
from . import _saturation  # noqa: F401  (registers the thesis chapter 7 presets: Wireworld, reinforcement patterns)
from . import _thesis_animals  # noqa: F401  (registers the thesis's frog and moray eel on a lattice)
from . import _cells  # noqa: F401  (registers the thesis's cell experiments, run from its listings)
from . import _cells_growth  # noqa: F401  (registers thesis Fig. 6.11: transitions on growing cells)
from . import _cells_chapter7  # noqa: F401  (registers thesis chapter 7's unlisted figures on cells: Figs. 7.9, 7.11, 7.12)
from . import _saturation_map  # noqa: F401  (registers thesis Fig. 7.14 with its caption's areas)
from . import _solids  # noqa: F401  (registers the 3D lattice's solid texture)
from . import _lundelius  # noqa: F401  (registers paper 004's own grid setting)
from . import _reinforcement_term  # noqa: F401  (registers the leopard paper's Fig. 7: the reinforcement term's plot)
from ._automaton_outputs import run_automaton, run_life_like

REACTION_DIFFUSION_PRESETS = of_kind(ExperimentPreset.kind)  # snapshots of PRESETS by kind
AUTOMATON_PRESETS = of_kind(AutomatonPreset.kind)

__all__ = [
    "AUTOMATON_PRESETS",
    "AutomatonPreset",
    "ExperimentPreset",
    "FIG4_RATIOS",
    "leopard_row_weights",
    "lookup",
    "of_kind",
    "preset",
    "Preset",
    "PRESETS",
    "REACTION_DIFFUSION_PRESETS",
    "register",
    "registered",
    "run_automaton",
    "run_life_like",
]

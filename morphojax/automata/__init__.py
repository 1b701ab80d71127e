"""Cellular automata on periodic integer lattices of any dimension.

    from morphojax.automata import YoungCA, random_cells    # or: import morphojax as mj
    ca = YoungCA([(3.2, 6.0, 1.0, -0.2)])                   # (r_act, r_inh, w_act, w_inh)
    out = ca.run(random_cells(jax.random.key(0), (30, 30, 30)), 100, stop_at_convergence=True)

Where each job lives (private modules, re-exported here and by `morphojax`):

- `_base`: `AbstractAutomaton` (input checks, `step`, `run`); `_loop`: the compiled
  loop and `AutomatonRun`;
- `_young`: `YoungCA`, Young's activator-inhibitor rule with exact integer fields;
  `_geometry`: its neighbourhoods; `_direct`, `_fft`, `_matmul`: the three counting
  methods; `_choice`: the plan and `auto`'s cost model; `_caches`: plans and kernel
  spectra of concrete models; `_soft`: the differentiable relaxation;
- `_life`: life-like (B/S) rules; `_wireworld`: Wireworld (thesis Fig. 7.2);
  `_laplacian`: the thesis's Laplacian (DBM) growth (Fig. 7.3);
- `_cells`: random lattices and the one-hot form; `_observables`: volume fractions,
  order parameter, convergence, weighted volume difference;
- `_pictures`: images and slice montages; `_meshes`: marching-cubes meshes, PLY and OBJ.
"""

from ._base import AbstractAutomaton
from ._cells import YOUNG_P, hard_cells, one_hot_cells, random_cells
from ._geometry import NEIGHBOURHOODS
from ._life import RULES, LifeLike, glider, parse_rule
from ._loop import AutomatonRun
from ._meshes import read_ply, species_mesh, write_obj, write_ply, write_species_meshes
from ._observables import (
    changed_fraction,
    has_converged,
    order_parameter,
    volume_fractions,
    weighted_volume_difference,
)
from ._pictures import SPECIES_COLOURS, UNDIFFERENTIATED, cells_image, slice_montage, state_colours
from ._young import METHODS, YoungCA
from ._wireworld import WIREWORLD_COLOURS, Wireworld, wireworld_clock
from ._laplacian import LaplacianGrowth, LaplacianRun

__all__ = [
    "AbstractAutomaton",
    "AutomatonRun",
    "cells_image",
    "changed_fraction",
    "glider",
    "wireworld_clock",
    "hard_cells",
    "has_converged",
    "LaplacianGrowth",
    "LaplacianRun",
    "LifeLike",
    "METHODS",
    "NEIGHBOURHOODS",
    "one_hot_cells",
    "order_parameter",
    "parse_rule",
    "random_cells",
    "read_ply",
    "RULES",
    "slice_montage",
    "SPECIES_COLOURS",
    "species_mesh",
    "state_colours",
    "UNDIFFERENTIATED",
    "volume_fractions",
    "weighted_volume_difference",
    "Wireworld",
    "WIREWORLD_COLOURS",
    "write_obj",
    "write_ply",
    "write_species_meshes",
    "YOUNG_P",
    "YoungCA",
]

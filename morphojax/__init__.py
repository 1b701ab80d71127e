"""morphojax: a differentiable JAX simulator of biological pattern formation.

    import morphojax as mj
    model = mj.Turing(ratio=4.2, scale=3.0)
    state = mj.paper_state(jax.random.key(0), (128, 128))
    state = mj.simulate(model, state, steps=10_000, dt=0.01)
    a, b = state.arrays()
"""

from .domains import BOUNDARIES, STENCILS, AbstractDomain, HexLattice, Lattice, laplacian, max_stable_dt
from .domains import Mesh
from .domains import Polarize, gradient_polarity
from .models import (
    AbstractModel,
    Bard,
    Brusselator,
    Composite,
    FitzHughNagumo,
    GiererMeinhardt,
    GrayScott,
    Modulated,
    Modulation,
    Morphogen,
    Reaction,
    Reinforcement,
    RuleReinforcement,
    Schnakenberg,
    ThesisReinforcement,
    Thomas,
    Turing,
    model_from_name,
)
from ._state import State
from ._initial import constant_state, gray_scott_state, initial_state, paper_state, random_state, thesis_state
from ._bounds import Barrier
from ._status import Run, RunStatus, SimulationError
from ._plan import BlockLadder, WholeCapacity
from .solvers import ETDRK, IMEX, AbstractSolver, Euler, SteadyState
from ._simulate import rollout, run_status, simulate
from ._growth import DISTRIBUTIONS, Growth, Source
from ._growing_mesh import MeshGrowth
from ._experiment import Experiment, Initial, Phase, load_experiment
from ._run_experiment import Result, run_experiment
from ._serialise import load_npz, model_from_dict, model_to_dict, save_npz
from ._files import to_jsonable
from ._frames_files import load_frames, save_frames
from ._render import Gradient, experiment_picture, map_image, montage, render, render_experiment, save_png, to_image
from ._animation import save_animation
from ._palette import kmeans, photo_palette
from ._explore import Explorer, SweepExplorer, explore, explore_sweep
from ._render_hex import hex_image, render_hex
from ._mesh_texture import texture_image
from ._render_mesh import mesh_image, vertex_colours
from .presets import PRESETS, leopard_row_weights, preset
from ._descriptors import Descriptors, describe, radial_power_spectrum, relative_change
from ._sweep import sweep
from ._sweep_result import Member, SweepResult, load_sweep
from ._parameter_map import parameter_map
from ._stability import Dispersion, dispersion
from ._turing_space import TuringSpace, turing_space
from .automata import (
    RULES as LIFE_RULES,
    YOUNG_P,
    AbstractAutomaton,
    AutomatonRun,
    LaplacianGrowth,
    LifeLike,
    Wireworld,
    YoungCA,
    cells_image,
    changed_fraction,
    glider,
    hard_cells,
    has_converged,
    one_hot_cells,
    order_parameter,
    parse_rule,
    random_cells,
    slice_montage,
    species_mesh,
    volume_fractions,
    weighted_volume_difference,
    wireworld_clock,
    write_obj,
    write_ply,
    write_species_meshes,
)
from .potts import Potts, PottsState, potts_blob, potts_image, type_clusters
from . import cells
from .cells import (Cells, Listing, cell_disc, cell_grid, cells_at, cells_texture, load_cells, load_listing, render_cells,
                    save_cells, simulate_cells, write_cells_svg)

from ._compilation_cache import use_compilation_cache
from ._version import __version__

__all__ = [
    "use_compilation_cache",
    "AbstractAutomaton",
    "AbstractDomain",
    "AbstractModel",
    "AutomatonRun",
    "Bard",
    "Brusselator",
    "Barrier",
    "BlockLadder",
    "BOUNDARIES",
    "cells_image",
    "changed_fraction",
    "Composite",
    "constant_state",
    "describe",
    "dispersion",
    "Dispersion",
    "Descriptors",
    "DISTRIBUTIONS",
    "Experiment",
    "explore",
    "explore_sweep",
    "Explorer",
    "SweepExplorer",
    "experiment_picture",
    "FitzHughNagumo",
    "GiererMeinhardt",
    "glider",
    "Gradient",
    "gradient_polarity",
    "Polarize",
    "gray_scott_state",
    "GrayScott",
    "Growth",
    "MeshGrowth",
    "hard_cells",
    "hex_image",
    "HexLattice",
    "has_converged",
    "Initial",
    "initial_state",
    "laplacian",
    "Lattice",
    "LIFE_RULES",
    "LaplacianGrowth",
    "LifeLike",
    "leopard_row_weights",
    "load_experiment",
    "kmeans",
    "load_frames",
    "load_npz",
    "load_sweep",
    "map_image",
    "max_stable_dt",
    "Mesh",
    "mesh_image",
    "Member",
    "model_from_name",
    "model_from_dict",
    "model_to_dict",
    "montage",
    "one_hot_cells",
    "order_parameter",
    "paper_state",
    "photo_palette",
    "parameter_map",
    "parse_rule",
    "Phase",
    "preset",
    "PRESETS",
    "radial_power_spectrum",
    "Modulated",
    "Modulation",
    "Morphogen",
    "Reaction",
    "random_cells",
    "random_state",
    "Reinforcement",
    "RuleReinforcement",
    "relative_change",
    "render",
    "render_experiment",
    "render_hex",
    "Result",
    "rollout",
    "Run",
    "run_experiment",
    "run_status",
    "RunStatus",
    "save_animation",
    "save_frames",
    "save_npz",
    "save_png",
    "Schnakenberg",
    "ThesisReinforcement",
    "turing_space",
    "TuringSpace",
    "Thomas",
    "simulate",
    "SimulationError",
    "AbstractSolver",
    "Euler",
    "ETDRK",
    "IMEX",
    "SteadyState",
    "slice_montage",
    "Source",
    "species_mesh",
    "State",
    "STENCILS",
    "sweep",
    "SweepResult",
    "texture_image",
    "thesis_state",
    "to_image",
    "to_jsonable",
    "Turing",
    "vertex_colours",
    "volume_fractions",
    "weighted_volume_difference",
    "WholeCapacity",
    "write_obj",
    "write_ply",
    "write_species_meshes",
    "YOUNG_P",
    "Wireworld",
    "wireworld_clock",
    "YoungCA",
    "Potts",
    "Cells",
    "cells_texture",
    "render_cells",
    "write_cells_svg",
    "Listing",
    "load_cells",
    "load_listing",
    "save_cells",
    "cell_disc",
    "cell_grid",
    "cells",
    "cells_at",
    "simulate_cells",
    "PottsState",
    "potts_blob",
    "potts_image",
    "type_clusters",
]

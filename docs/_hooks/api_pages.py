"""mkdocs hook: the API reference of `morphojax`, one page per job, generated from `__all__`.

A page of `docs/api/` that holds the marker `<!-- api: morphojax TOPIC -->` gets one
mkdocstrings directive (`::: morphojax.NAME`) for each public name that `TOPICS` files under
TOPIC and `morphojax.__all__` exports. The marker `<!-- api: morphojax other -->` gets every
exported name no topic claims, so a name added to `__all__` appears in the reference without
editing anything here (it can be filed under its topic later). A topic may list names that
do not exist yet; only exported names are rendered.

This module imports neither mkdocs nor mkdocstrings, so tests/test_docs.py can check it.
"""

from __future__ import annotations

import importlib
import re

PACKAGE = "morphojax"

TOPICS: dict[str, tuple[str, ...]] = {
    "models": (
        "AbstractModel", "Turing", "Bard", "GrayScott", "Reinforcement", "Composite",
        "FitzHughNagumo", "GiererMeinhardt", "Schnakenberg", "Brusselator", "Thomas", "Reaction",
        "ThesisReinforcement", "RuleReinforcement", "Morphogen", "Modulated", "Modulation",
        "Barrier", "parameter_map", "model_from_name", "model_to_dict", "model_from_dict",
    ),
    "domains": (
        "AbstractDomain", "Lattice", "HexLattice", "Mesh", "Polarize", "gradient_polarity",
        "laplacian", "max_stable_dt", "STENCILS", "BOUNDARIES",
    ),
    "stability": ("dispersion", "Dispersion", "turing_space", "TuringSpace"),
    "stepping": (
        "simulate", "rollout", "run_status", "State", "Run", "RunStatus", "SimulationError",
        "AbstractSolver", "Euler", "ETDRK", "IMEX", "SteadyState",
        "paper_state", "random_state", "constant_state", "gray_scott_state", "thesis_state",
        "initial_state", "use_compilation_cache",
    ),
    "growth": (
        "Growth", "MeshGrowth", "Source", "DISTRIBUTIONS", "leopard_row_weights", "BlockLadder", "WholeCapacity",
        "Experiment", "Phase", "Initial", "Result", "run_experiment", "load_experiment", "preset",
        "PRESETS", "render_experiment", "experiment_picture",
    ),
    "automata": (
        "AbstractAutomaton", "AutomatonRun", "YoungCA", "YOUNG_P", "LifeLike", "LIFE_RULES",
        "parse_rule", "glider", "Wireworld", "wireworld_clock", "LaplacianGrowth", "random_cells",
        "hard_cells", "one_hot_cells", "changed_fraction", "has_converged", "order_parameter",
        "weighted_volume_difference", "volume_fractions", "cells_image", "slice_montage",
        "species_mesh", "write_species_meshes",
    ),
    "potts": ("Potts", "PottsState", "potts_blob", "potts_image", "type_clusters"),
    "cells": (
        "cells", "Cells", "cell_grid", "cell_disc", "cells_at", "simulate_cells", "Listing",
        "load_listing", "render_cells", "cells_texture", "write_cells_svg", "save_cells",
        "load_cells",
    ),
    "sweeps": (
        "sweep", "SweepResult", "Member", "load_sweep", "describe", "Descriptors",
        "radial_power_spectrum", "relative_change", "montage", "map_image", "explore",
        "explore_sweep", "Explorer", "SweepExplorer",
    ),
    "output": (
        "render", "to_image", "save_png", "save_animation", "Gradient", "photo_palette", "kmeans",
        "hex_image", "render_hex", "mesh_image", "vertex_colours", "texture_image", "write_ply",
        "write_obj", "save_npz", "load_npz", "save_frames", "load_frames", "to_jsonable",
    ),
}

# submodules are rendered whole elsewhere: where, relative to docs/api/
SUBMODULES = {"cells": "cells.md#morphojax.cells"}

MARKER = re.compile(r"<!-- api: (\S+) (\S+) -->")


def exported(package: str = PACKAGE) -> list[str]:
    return list(importlib.import_module(package).__all__)


def names(topic: str, package: str = PACKAGE) -> list[str]:
    """The exported names rendered under `topic` ("other": those no topic claims)."""
    public = exported(package)
    if topic == "other":
        claimed = {name for members in TOPICS.values() for name in members}
        return sorted(name for name in public if name not in claimed)
    if topic not in TOPICS:
        raise KeyError(f"unknown API topic {topic!r}; known: {', '.join(TOPICS)}, other")
    return [name for name in TOPICS[topic] if name in public]


def directives(topic: str, package: str = PACKAGE, page_depth: int = 1) -> str:
    lines = []
    for name in names(topic, package):
        if name in SUBMODULES:
            link = "../" * (page_depth - 1) + SUBMODULES[name]
            lines.append(f"`{package}.{name}`: the subpackage, rendered whole [below]({link}).\n")
            continue
        lines.append(f"::: {package}.{name}\n")
    if not lines:
        lines.append("*No names at present.*\n")
    return "\n".join(lines)


def expand(markdown: str, page_depth: int = 1) -> str:
    return MARKER.sub(lambda m: directives(m.group(2), m.group(1), page_depth), markdown)


def on_page_markdown(markdown, page, config, files):
    if not MARKER.search(markdown):
        return markdown
    return expand(markdown, page.file.src_uri.count("/"))

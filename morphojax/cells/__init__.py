"""The thesis's off-lattice cell simulator (Pattern Explorer, thesis chapters 3-4): point
cells that react, diffuse, polarise, divide and collide, driven by rules."""

from ._prepattern import LATTICES, SPACING, cell_disc, cell_grid, cells_at, disc_positions, grid_positions
from ._rules import (
    AGE,
    BIRTH,
    NEIGHBORS,
    Always,
    Chance,
    Change,
    Compare,
    Divide,
    Map,
    Polarize,
    React,
    Rule,
    Var,
    Within,
    conc,
    diff,
    mapped,
)
from ._space import PACKING_AREA, Box, Packed, Torus
from ._state import Cells, concatenate, make_cells
from ._simulate import INFLUENCE_RADIUS, simulate_cells
from ._files import load_cells, save_cells
from ._listing import LISTINGS, Listing, ListingError, listing_path, load_listing
from ._render import cells_field, cells_texture, render_cells, texture_pixel_centres, write_cells_svg

__all__ = [
    "AGE",
    "Always",
    "BIRTH",
    "Box",
    "cell_disc",
    "cell_grid",
    "Cells",
    "cells_at",
    "cells_field",
    "cells_texture",
    "Chance",
    "Change",
    "Compare",
    "conc",
    "concatenate",
    "diff",
    "disc_positions",
    "Divide",
    "grid_positions",
    "INFLUENCE_RADIUS",
    "LATTICES",
    "Listing",
    "listing_path",
    "ListingError",
    "LISTINGS",
    "load_cells",
    "load_listing",
    "make_cells",
    "Map",
    "mapped",
    "NEIGHBORS",
    "Packed",
    "PACKING_AREA",
    "Polarize",
    "React",
    "render_cells",
    "Rule",
    "save_cells",
    "simulate_cells",
    "SPACING",
    "texture_pixel_centres",
    "Torus",
    "Var",
    "Within",
    "write_cells_svg",
]

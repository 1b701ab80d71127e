"""The parsed commands of the experiment language (thesis 4.8): plain frozen dataclasses
that `_listing_read` makes from the lines of a listing, `_listing_prepattern` executes and
`_listing_write` writes back, plus the language's fixed vocabularies (the `create` kinds and
their options, the colour map types and slots, the `heat` map) and `_rgb`, which reads a
colour as a listing writes it. They hold the numbers as written (angles in degrees).
"""

from __future__ import annotations

import dataclasses
import re
from typing import Union

from PIL import ImageColor

from .._render import Gradient

# Plain data, holding the numbers as written (angles in degrees). `line` (the line of the
# listing a command came from, for error messages) takes no part in comparisons.


@dataclasses.dataclass(frozen=True)
class Chemical:
    """`define chemical NAME [limit L] [anisotropic]` (thesis 4.8.1): a reagent, its
    saturation limit (None: unbounded) and whether its diffusion follows the polarity."""

    name: str
    limit: float | None = None
    anisotropic: bool = False


@dataclasses.dataclass(frozen=True)
class UseChemical:
    """`use chemical NAME [conc C [dev D]] [diff F [dev E]]` (4.8.2): the defaults of
    later `create`s. A part left out (None) keeps the current default; a value given
    without `dev` has none."""

    chemical: str
    conc: tuple[float, float] | None = None  # (value, dev)
    diff: tuple[float, float] | None = None  # (value, dev)
    line: int = dataclasses.field(default=0, compare=False)


@dataclasses.dataclass(frozen=True)
class UsePolarity:
    """`use polarity none | ANGLE [dev D]` (4.8.2), in degrees; angle None: unpolarised."""

    angle: float | None
    dev: float = 0.0
    line: int = dataclasses.field(default=0, compare=False)


CREATE_KINDS = ("cell", "sqr_grid", "sqr_circle", "hex_grid", "hex_circle", "shape")
_CREATE_OPTIONS = {  # Listing 4.4 (`wrap`, a torus, is the square grid's alone)
    "cell": ("fixed",),
    "sqr_grid": ("at", "dev", "fixed", "wrap"),
    "sqr_circle": ("at", "dev", "fixed"),
    "hex_grid": ("at", "dev", "fixed"),
    "hex_circle": ("at", "dev", "fixed"),
    "shape": ("at", "fixed"),
}


@dataclasses.dataclass(frozen=True)
class Create:
    """A `create` command (4.8.3). `size` is (x, y) for `cell`, (cols, rows) for the
    grids, (radius,) for the circles (in cell radii) and () for `shape`, whose letters
    are read from `file` (relative to the listing's directory). `dev` jitters every
    position by a uniform draw of that amplitude per axis. `wrap` (square grids only) makes
    the domain a torus of the grid's size, COLS x ROWS spacings, centred on the origin."""

    kind: str
    size: tuple = ()
    file: str | None = None
    at: tuple[float, float] = (0.0, 0.0)
    dev: float = 0.0
    fixed: bool = False
    wrap: bool = False
    line: int = dataclasses.field(default=0, compare=False)


@dataclasses.dataclass(frozen=True)
class SetCells:
    """`set cell I ...` / `set cells I to J ...` (4.8.4) on cells I..J (both included):
    each value given replaces the cells' own (plus uniform noise of its dev). `polarity`
    is None (unchanged), "none" (unpolarised) or an angle in degrees."""

    first: int
    last: int
    chemical: str | None = None
    conc: tuple[float, float] | None = None
    diff: tuple[float, float] | None = None
    polarity: float | str | None = None
    polarity_dev: float = 0.0
    fixed: bool = False
    line: int = dataclasses.field(default=0, compare=False)


@dataclasses.dataclass(frozen=True)
class Snap:
    """`snap at I ... [then exit]` (`every` None) or `snap from I repeat N step S [then
    exit]` (`at` = (I,), `every` = (N, S): the N iterations I, I + S, ..., I + (N-1) S)."""

    at: tuple[int, ...]
    every: tuple[int, int] | None = None
    exit: bool = False

    @property
    def iterations(self) -> tuple[int, ...]:
        if self.every is None:
            return self.at
        repeat, step = self.every
        return tuple(self.at[0] + k * step for k in range(repeat))


Command = Union[UseChemical, UsePolarity, Create, SetCells]

COLORMAP_KINDS = ("heat", "striped", "gradient")
SLOTS = 100  # thesis 4.8.6: colours are placed on 100 slots; slot k sits at k / 99
# "heat": the traditional hue ramp from blue (zero) to red (one) (thesis 4.8.6, Fig. 5.1)
HEAT = Gradient([(0.0, "#0000ff"), (0.25, "#00ffff"), (0.5, "#00ff00"), (0.75, "#ffff00"), (1.0, "#ff0000")])


HEX_TRIPLET = re.compile(r"[0-9a-fA-F]{6}")


def _rgb(colour) -> tuple[int, int, int]:
    """A colour as written in a listing (a CSS name, a hex triplet with or without '#',
    or (r, g, b) bytes) as (r, g, b)."""
    if not isinstance(colour, str):
        return tuple(int(v) for v in colour)
    spec = f"#{colour}" if HEX_TRIPLET.fullmatch(colour) else colour
    try:
        return ImageColor.getrgb(spec)[:3]
    except ValueError:
        raise ValueError(f"unknown colour '{colour}' (a CSS colour name or a hex triplet such as 420009)") from None


__all__ = [
    "COLORMAP_KINDS", "CREATE_KINDS", "HEAT", "SLOTS", "Chemical", "Command", "Create", "SetCells", "Snap",
    "UseChemical", "UsePolarity",
]

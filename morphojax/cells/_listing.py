"""The reader of the thesis's experiment language (thesis 4.8, Listings 4.1-4.8, Table 4.1).

An experiment file holds one statement per line; `//` starts a comment anywhere on a line.

    define chemical NAME [limit L] [anisotropic]       simulation parameters (4.8.1)
    define division_limit N | domain W H | domain packed [area A] | time_step DT
    use chemical NAME [conc C [dev D]] [diff F [dev E]] default values (4.8.2)
    use polarity none | ANGLE [dev D]  |  use seed N
    create cell X Y | sqr_grid COLS ROWS | sqr_circle R  cell placement (4.8.3)
           | hex_grid COLS ROWS | hex_circle R | shape "FILE"   [at X Y] [dev D] [fixed]
    set cell I | set cells I to J  chemical NAME [conc C [dev D]] [diff F [dev E]]
           [polarity none | ANGLE [dev D]] [fixed]          explicit parameters (4.8.4)
    rule [from I] [until J] CONDITION ACTION | and        rules (4.8.5)
    colormap select heat|striped|gradient, colormap slot K use color "C" | rgb R G B,
    snap at I ... [then exit], snap from I repeat N step S [then exit], stop at I,
    texture size W H, zoom level Z                           utility commands (4.8.6)

`load_listing` reads a file (or the text itself) into a `Listing`: the chemicals, the
simulation parameters, the prepattern commands in order, the rules as `Rule` data
(`_rules`) and the utility settings. `Listing.prepattern(key)` places the cells,
`Listing.run()` simulates them (`simulate_cells`), and `Listing.to_text()` writes the
canonical listing back (one command per line, comments dropped) that reads to an equal
`Listing`.

Conventions (the thesis's, made explicit):
- Angles in the language are degrees (polarity, divide direction and their `dev`); the
  `Listing` holds the prepattern's angles as written and the rules' in radians.
- Every `dev` is the amplitude of a uniform deviation: v dev d draws from [v - d, v + d].
- Cells are numbered in the order they are created; a grid numbers its cells row by row
  from the lowest row (see `_prepattern`), and `create shape` does the same for the
  letters of its file. `create sqr_grid COLS ROWS` is `cell_grid((ROWS, COLS))`.
- `set` REPLACES the named values of the cells (plus the noise of its `dev`); rules'
  `change` adds (thesis 4.8.5).
- An `and` chain (`rule COND and` lines followed by a rule) is one `Rule` whose `when`
  holds every condition; it runs on the intersection of the lines' iteration windows.
- The published listings are read as written: inconsistencies are recorded in
  `Listing.warnings`, never silently fixed (e.g. Listing A.17's `from 2500 until 2000`
  is an empty window, so that rule never fires).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import NoReturn, Union

import jax
import numpy as np
from PIL import ImageColor

from .._checks import check_count
from .._render import Gradient
from .._status import SimulationError
from ..models import Bard
from ._prepattern import SPACING, cells_at, disc_positions, grid_positions
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
from ._space import PACKING_AREA, Box, Packed
from ._state import Cells, make_cells

# ---- the parsed commands ---------------------------------------------------------------
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
_CREATE_OPTIONS = {  # Listing 4.4 (`wrap` is refused: toroidal wrapping is not supported)
    "cell": ("fixed",),
    "sqr_grid": ("at", "dev", "fixed"),
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
    position by a uniform draw of that amplitude per axis."""

    kind: str
    size: tuple = ()
    file: str | None = None
    at: tuple[float, float] = (0.0, 0.0)
    dev: float = 0.0
    fixed: bool = False
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


# ---- the listing ---------------------------------------------------------------------


@dataclasses.dataclass(frozen=True, eq=False)
class Listing:
    """A parsed experiment (thesis 4.8): read it with `load_listing`.

    Attributes:
        name: the file's stem, or "<text>".
        text: the source text.
        chemicals: the `Chemical`s in declaration order (the order of the cells' reagents).
        dt: `define time_step` (default 1).
        stop: `stop at N` (None if absent); see `steps`.
        domain: None, `Box(W, H)` (`define domain W H`) or `Packed(area)`.
        division_limit: `define division_limit N` (None if absent).
        seed: `use seed N` (None if absent; the thesis's 0, "seed from the clock", is
            kept as 0 and, like None, means "unspecified").
        commands: the prepattern commands (`UseChemical`, `UsePolarity`, `Create`,
            `SetCells`) in order.
        rules: the `Rule`s, in order (an `and` chain is one rule).
        colormap_select: "heat", "striped", "gradient" or None; colormap_slots: the
            `colormap slot` commands as (slot, colour) in order, the colour as written
            (a CSS name or a hex triplet) or an (r, g, b) triple; see `colormap`.
        texture: `texture size W H` or None; zoom: `zoom level Z` or None (unused).
        snaps: the `Snap` commands.
        warnings: what in the listing looks wrong but was read as written.
        directory: where `create shape` files are looked up (None: the working directory).
    """

    name: str = "<text>"
    text: str = ""
    chemicals: tuple[Chemical, ...] = ()
    dt: float = 1.0
    stop: int | None = None
    domain: Box | Packed | None = None
    division_limit: int | None = None
    seed: int | None = None
    commands: tuple[Command, ...] = ()
    rules: tuple[Rule, ...] = ()
    colormap_select: str | None = None
    colormap_slots: tuple = ()
    texture: tuple[int, int] | None = None
    zoom: float | None = None
    snaps: tuple[Snap, ...] = ()
    warnings: tuple[str, ...] = ()
    directory: Path | None = None

    # ---- derived settings ---------------------------------------------------------
    @property
    def species(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.chemicals)

    @property
    def steps(self) -> int | None:
        """The iterations to run: `stop at N`, or the last iteration of a `snap ... then
        exit` (the earlier of the two when both are given); None if neither."""
        ends = [max(s.iterations) for s in self.snaps if s.exit and s.iterations]
        if self.stop is not None:
            ends.append(self.stop)
        return min(ends) if ends else None

    @property
    def colormap(self) -> Gradient | None:
        """The listing's colour map (thesis 4.8.6) as a `morphojax.Gradient`, or None.

        `gradient` interpolates linearly between the slots' colours (slot k at position
        k / 99, constant beyond the first and last slot); `striped` repeats each slot's
        colour up to the next slot (piecewise constant); `heat` is the hue ramp from blue
        (0) to red (1). Slots without a `colormap select` make a gradient; a slot set
        twice keeps its last colour."""
        kind = self.colormap_select or ("gradient" if self.colormap_slots else None)
        if kind == "heat":
            return HEAT
        slots = dict((slot, _rgb(colour)) for slot, colour in self.colormap_slots)
        if kind is None or not slots:
            return None
        ordered = sorted(slots.items())
        if len(ordered) == 1:
            return Gradient([(0.0, ordered[0][1]), (1.0, ordered[0][1])])
        if kind == "gradient":
            return Gradient([(slot / (SLOTS - 1), rgb) for slot, rgb in ordered])
        stops = [(0.0, ordered[0][1])]  # striped: colour i holds on [slot_i, slot_i+1)
        for (_, before), (slot, rgb) in zip(ordered, ordered[1:]):
            edge = slot / (SLOTS - 1)
            stops += [(float(np.nextafter(edge, 0.0)), before), (edge, rgb)]
        return Gradient(stops + [(1.0, ordered[-1][1])])

    # ---- the prepattern -----------------------------------------------------------
    def prepattern(self, key) -> Cells:
        """The initial cells: the `use`, `create` and `set` commands executed in order
        (thesis 4.8.2-4.8.4), each with its own key split from `key` (so the result is
        the same for the same key).

        Cells take the `use chemical` defaults current when they are created (0 for a
        chemical never named) and the saturation limits and anisotropy of the `define
        chemical` lines. Polarity: a listing without a `use polarity` line makes cells
        polarised along +x (angle 0), since the thesis's Fig. 6.5 (Listing A.7) grows
        oriented patterns without one; `use polarity none` makes them unpolarised.
        `set` indices out of the cells created so far raise ValueError naming the line.
        """
        if not self.chemicals:
            raise ValueError(f"{self.name}: the listing defines no chemical; the cells need at least one")
        builder = _Prepattern(self)
        keys = jax.random.split(key, max(len(self.commands), 1))
        for command, command_key in zip(self.commands, keys):
            builder.execute(command, command_key)
        return builder.cells()

    # ---- running ------------------------------------------------------------------
    def run(self, seed: int | None = None, steps: int | None = None, capacity: int | None = None, key=None,
            max_neighbours: int | None = None, bucket_size: int | None = None) -> Cells:
        """Place the prepattern and simulate the listing (`simulate_cells`, thesis ch. 4).

        Args:
            seed: the random seed (default: the listing's `use seed`, else 0); ignored
                when `key` is given.
            steps: iterations (default: `self.steps`, from `stop at` or `snap ... then
                exit`; a listing with neither needs it).
            capacity: room for cells. Default: the prepattern's count when no rule
                divides; otherwise an estimate, max(4 * count, count + steps // 2).
            key: a `jax.random` key (split between the prepattern and the run).
            max_neighbours, bucket_size: room in the neighbour search (defaults of
                `simulate_cells`).

        A listing runs as published, whatever room it needs: when the divisions overflow
        a capacity you did not give, or the neighbour search overflows room you did not
        give, the run is repeated with twice that room, up to 3 times.

        Raises SimulationError when the run blows up or still overflows.
        """
        from ._simulate import BUCKET_SIZE, MAX_NEIGHBOURS, simulate_cells

        steps = self.steps if steps is None else steps
        if steps is None:
            raise ValueError(f"{self.name}: the listing has no 'stop at' or 'snap ... then exit' line; pass steps")
        check_count(steps, "steps", "iterations")
        if key is None:
            key = jax.random.key(seed if seed is not None else (self.seed or 0))
        prepattern_key, run_key = jax.random.split(key)
        cells = self.prepattern(prepattern_key)
        count = int(cells.count)
        divides = any(isinstance(rule.action, Divide) for rule in self.rules)
        grow_cells, grow_search = capacity is None and divides, max_neighbours is None and bucket_size is None
        if capacity is None:
            capacity = max(4 * count, count + int(steps) // 2) if divides else count
        room = [MAX_NEIGHBOURS if max_neighbours is None else max_neighbours,
                BUCKET_SIZE if bucket_size is None else bucket_size]
        for attempt in range(4):
            out = simulate_cells(
                None, cells.with_capacity(int(capacity)), steps, self.dt, rules=self.rules, key=run_key,
                domain=self.domain, division_limit=self.division_limit, max_neighbours=room[0],
                bucket_size=room[1], throw=False,
            )
            retry = False
            if grow_cells and int(out.overflow_step) >= 0:
                capacity, retry = 2 * capacity, True  # the divisions did not fit: twice the room
            if grow_search and int(out.neighbour_overflow_step) >= 0:
                room, retry = [2 * room[0], 2 * room[1]], True
            if not retry or attempt == 3 or int(out.nonfinite_step) >= 0:
                break
        if not bool(out.ok):
            raise SimulationError(f"{self.name}: {out.message()}")
        return out

    # ---- writing ------------------------------------------------------------------
    def to_text(self) -> str:
        """The canonical listing: one command per line, comments dropped, defaults left
        out, every rule written from its `Rule` (an `and` chain one line per condition,
        each carrying the chain's window). `load_listing(listing.to_text())` equals
        `listing`."""
        return "\n".join(_write_listing(self)) + "\n"

    def __eq__(self, other):
        if not isinstance(other, Listing):
            return NotImplemented
        return _listing_key(self) == _listing_key(other)

    __hash__ = None


# ---- the shipped listings ------------------------------------------------------------

LISTING_DIR = Path(__file__).parent / "listings"
_FIGURES = ("5.14", "5.15", "6.1", "6.2", "6.3", "6.4", "6.5", "6.6", "6.7", "6.8", "6.10",
            "7.2", "7.3", "7.7", "7.8", "7.16", "7.18", "7.21")


def _shipped() -> dict[str, Path]:
    names = {}
    for k, figure in enumerate(_FIGURES, start=1):
        path = LISTING_DIR / f"A{k:02d}_fig{figure}.txt"
        names[f"A.{k}"] = names[f"fig{figure}"] = path
    for stem in ("fig5.1", "fig5.2", "listing4.1", "listing5.1"):
        names[stem] = LISTING_DIR / f"{stem}.txt"
    return names


LISTINGS: Mapping[str, Path] = _shipped()
"""The thesis's listings shipped with morphojax, by name: "A.1" ... "A.18" (Appendix A)
and the same files by figure, "fig5.14" ... "fig7.21", plus "fig5.1", "fig5.2" (the
listings printed in Figs. 5.1 and 5.2), "listing4.1" and "listing5.1"."""


def listing_path(name: str) -> Path:
    """The file of a shipped listing: "A.18", "fig7.21", "Fig 7.21", "A18_fig7.21", ..."""
    wanted = _normalise_name(name)
    for known, path in LISTINGS.items():
        if wanted in (_normalise_name(known), _normalise_name(path.stem)):
            return path
    raise ValueError(f"unknown listing {name!r}; the shipped listings are {', '.join(LISTINGS)}")


def _normalise_name(name: str) -> str:
    return str(name).strip().lower().replace(" ", "").replace("figure", "fig").replace("listinga.", "a.")


def load_listing(source, *, name: str | None = None, directory=None) -> Listing:
    """Read an experiment (thesis 4.8) into a `Listing`.

    Args:
        source: a path to a listing file (str or Path), the name of a shipped listing
            (see `LISTINGS`, e.g. "A.18"), or the text itself.
        name: the name errors report (default: the file's stem, or "<text>").
        directory: where `create shape` files are looked up (default: the file's
            directory; for text, the working directory at `prepattern` time).

    Every malformed line raises ValueError("<name>:<line>: <what is wrong> (got
    '<line>')"); unknown chemicals and mapped values are caught here, out-of-range `set`
    indices when the prepattern is built.
    """
    path = _as_path(source)
    if path is not None:
        text = path.read_text()
        name = path.stem if name is None else name
        directory = path.parent if directory is None else directory
    else:
        text = str(source)
        name = "<text>" if name is None else name
    return _Reader(text, name, None if directory is None else Path(directory)).read()


def _as_path(source) -> Path | None:
    if isinstance(source, Path):
        if not source.is_file():
            raise ValueError(f"no listing file {str(source)!r}")
        return source
    if not isinstance(source, str):
        raise ValueError(f"source must be a path, a shipped listing's name or the listing text (got {type(source).__name__})")
    if "\n" in source:
        return None
    if source.strip() and Path(source).is_file():
        return Path(source)
    try:
        return listing_path(source)
    except ValueError:
        pass
    if source.strip().endswith(".txt"):
        raise ValueError(f"no listing file {source!r}")
    return None


# ---- reading -------------------------------------------------------------------------

NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
INTEGER = re.compile(r"[+-]?\d+")
IDENTIFIER = re.compile(r"[A-Za-z_]\w*")
HEX_TRIPLET = re.compile(r"[0-9a-fA-F]{6}")
TOKEN = re.compile(r'"[^"]*"|\S+')
CELL_VARIABLES = {"AGE": AGE, "BIRTH": BIRTH, "NEIGHBORS": NEIGHBORS}
ACTIONS = ("change", "react", "divide", "map", "polarize")
COMMANDS = ("define", "use", "create", "set", "rule", "colormap", "snap", "stop", "texture", "zoom")


class ListingError(ValueError):
    """A malformed line of a listing: "<name>:<line>: <what is wrong> (got '<line>')"."""

    @classmethod
    def at(cls, name: str, lines: list[str], number: int, message: str) -> "ListingError":
        got = lines[number - 1].strip() if 0 < number <= len(lines) else ""
        return cls(f"{name}:{number}: {message} (got '{got}')")


def strip_comment(text: str) -> str:
    """The line without its `//` comment (a `//` inside double quotes is kept)."""
    quoted = False
    for i, ch in enumerate(text):
        if ch == '"':
            quoted = not quoted
        elif not quoted and text.startswith("//", i):
            return text[:i]
    return text


class _Line:
    """The tokens of one line, read left to right; every complaint names the line."""

    def __init__(self, reader: "_Reader", number: int, text: str):
        self.reader, self.lineno, self.text = reader, number, text
        self.tokens = TOKEN.findall(strip_comment(text))
        self.i = 0
        for token in self.tokens:
            if token.startswith('"') and (len(token) < 2 or not token.endswith('"')):
                self.fail(f"unterminated quote in {token}")

    def fail(self, message: str) -> NoReturn:
        raise self.reader.error(self.lineno, message)

    # ---- cursor -------------------------------------------------------------------
    def peek(self) -> str | None:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self, what: str) -> str:
        token = self.peek()
        if token is None:
            after = f" after '{self.tokens[self.i - 1]}'" if self.i else ""
            self.fail(f"missing {what}{after}")
        self.i += 1
        return token

    def accept(self, word: str) -> bool:
        if self.peek() == word:
            self.i += 1
            return True
        return False

    def expect(self, word: str, context: str) -> None:
        token = self.take(f"'{word}' {context}")
        if token != word:
            self.fail(f"expected '{word}' {context}, found '{token}'")

    def end(self, context: str) -> None:
        if self.peek() is not None:
            self.fail(f"unexpected '{self.peek()}' {context}")

    # ---- values -------------------------------------------------------------------
    def number(self, what: str, *, low: float | None = None, low_open: bool = False) -> float:
        token = self.take(what)
        if not NUMBER.fullmatch(token):
            self.fail(f"{what} must be a number, found '{token}'")
        value = float(token)
        if low is not None and (value <= low if low_open else value < low):
            self.fail(f"{what} must be {'>' if low_open else '>='} {_format_number(low)}, found {token}")
        return value

    def integer(self, what: str, *, low: int = 0) -> int:
        token = self.take(what)
        if not INTEGER.fullmatch(token):
            self.fail(f"{what} must be an integer, found '{token}'")
        value = int(token)
        if value < low:
            self.fail(f"{what} must be >= {low}, found {token}")
        return value

    def chemical(self, what: str = "a chemical name") -> str:
        token = self.take(what)
        if token not in self.reader.chemicals:
            known = ", ".join(self.reader.chemicals) or "none yet"
            self.fail(f"unknown chemical '{token}' (defined: {known})")
        return token

    def quoted(self, what: str) -> str:
        token = self.take(what)
        return token[1:-1] if token.startswith('"') else token

    def operand(self, what: str):
        """A number, `R conc`, `R diff`, AGE, BIRTH, NEIGHBORS or a map's name (4.8.5)."""
        token = self.take(what)
        if NUMBER.fullmatch(token):
            return float(token)
        if token in CELL_VARIABLES:
            return CELL_VARIABLES[token]
        if token in self.reader.chemicals:
            kind = self.take(f"'conc' or 'diff' after chemical {token}")
            if kind not in ("conc", "diff"):
                self.fail(f"expected 'conc' or 'diff' after chemical {token}, found '{kind}'")
            return conc(token) if kind == "conc" else diff(token)
        if token in self.reader.maps:
            return mapped(token)
        maps = f"; maps defined so far: {', '.join(sorted(self.reader.maps))}" if self.reader.maps else ""
        self.fail(f"{what} must be a number, 'CHEMICAL conc', 'CHEMICAL diff', AGE, BIRTH, NEIGHBORS or the "
                  f"name of an earlier map; '{token}' is none of these (chemicals: {', '.join(self.reader.chemicals)}{maps})")

    def value_and_dev(self, what: str) -> tuple[float, float]:
        value = self.number(what)
        dev = self.number(f"the dev of {what}", low=0.0) if self.accept("dev") else 0.0
        return value, dev


class _Reader:
    def __init__(self, text: str, name: str, directory: Path | None):
        self.text, self.name, self.directory = text, name, directory
        self.chemicals: dict[str, Chemical] = {}
        self.maps: set[str] = set()
        self.settings: dict = {}
        self.once: dict[str, int] = {}  # statements that may appear once -> their line
        self.commands: list = []
        self.rules: list[Rule] = []
        self.snaps: list[Snap] = []
        self.slots: list = []
        self.warnings: list[str] = []
        self.chain: list = []  # the pending `and` lines: (line number, conditions, start, stop)
        self.lines = text.splitlines()

    def error(self, number: int, message: str) -> "ListingError":
        return ListingError.at(self.name, self.lines, number, message)

    def read(self) -> Listing:
        for number, text in enumerate(self.lines, start=1):
            line = _Line(self, number, text)
            if not line.tokens:
                continue
            if self.chain and line.tokens[0] != "rule":
                line.fail(f"expected a rule to complete the 'and' on line {self.chain[-1][0]}")
            self.statement(line)
        if self.chain:
            raise self.error(self.chain[-1][0], "the rule ends in 'and' but no rule follows it")
        if not self.chemicals:
            raise ValueError(f"{self.name}: the listing defines no chemical (a 'define chemical NAME' line is needed)")
        return Listing(
            name=self.name, text=self.text, chemicals=tuple(self.chemicals.values()),
            dt=self.settings.get("time_step", 1.0), stop=self.settings.get("stop"),
            domain=self.settings.get("domain"), division_limit=self.settings.get("division_limit"),
            seed=self.settings.get("seed"), commands=tuple(self.commands), rules=tuple(self.rules),
            colormap_select=self.settings.get("colormap"), colormap_slots=tuple(self.slots),
            texture=self.settings.get("texture"), zoom=self.settings.get("zoom"), snaps=tuple(self.snaps),
            warnings=tuple(self.warnings), directory=self.directory,
        )

    def statement(self, line: _Line) -> None:
        word = line.take("a command")
        handler = {
            "define": self.define, "use": self.use, "create": self.create, "set": self.set,
            "rule": self.rule, "colormap": self.colormap, "snap": self.snap, "stop": self.stop,
            "texture": self.texture, "zoom": self.zoom,
        }.get(word)
        if handler is None:
            line.fail(f"unknown command '{word}'; expected one of {', '.join(COMMANDS)}")
        handler(line)

    def single(self, line: _Line, key: str, value, statement: str) -> None:
        """Record a setting that a listing gives at most once."""
        if key in self.once:
            line.fail(f"{statement} was already given on line {self.once[key]}")
        self.once[key] = line.lineno
        self.settings[key] = value

    # ---- define (4.8.1) -----------------------------------------------------------
    def define(self, line: _Line) -> None:
        what = line.take("what to define (chemical, division_limit, domain or time_step)")
        if what == "chemical":
            name = line.take("the chemical's name")
            if not IDENTIFIER.fullmatch(name) or name in CELL_VARIABLES:
                line.fail(f"a chemical's name must be a word other than AGE, BIRTH, NEIGHBORS, found '{name}'")
            if name in self.chemicals or name in self.maps:
                line.fail(f"{name} is already defined ({'a chemical' if name in self.chemicals else 'a map'})")
            limit, anisotropic = None, False
            while line.peek() is not None:
                option = line.take("an option")
                if option == "limit" and limit is None:
                    limit = line.number("the limit", low=0.0)
                elif option == "anisotropic" and not anisotropic:
                    anisotropic = True
                else:
                    line.fail(f"unexpected '{option}' (define chemical takes 'limit L' and 'anisotropic', once each)")
            self.chemicals[name] = Chemical(name, limit, anisotropic)
        elif what == "division_limit":
            self.single(line, "division_limit", line.integer("the division limit (neighbours)"), "define division_limit")
        elif what == "time_step":
            self.single(line, "time_step", line.number("the time step", low=0.0, low_open=True), "define time_step")
        elif what == "domain":
            if line.accept("packed"):
                area = line.number("the area per cell", low=0.0, low_open=True) if line.accept("area") else PACKING_AREA
                domain = Packed(area)
            else:
                width = line.number("the domain's width (or 'packed')", low=0.0, low_open=True)
                domain = Box(width, line.number("the domain's height", low=0.0, low_open=True))
            self.single(line, "domain", domain, "define domain")
        else:
            line.fail(f"unknown 'define {what}'; expected chemical, division_limit, domain or time_step")
        line.end("at the end of the define command")

    # ---- use (4.8.2) --------------------------------------------------------------
    def use(self, line: _Line) -> None:
        what = line.take("what to use (chemical, polarity or seed)")
        if what == "chemical":
            name = line.chemical()
            parts: dict = {}
            while line.peek() is not None:
                option = line.take("an option")
                if option not in ("conc", "diff") or option in parts:
                    line.fail(f"unexpected '{option}' (use chemical takes 'conc C [dev D]' and 'diff F [dev E]', once each)")
                parts[option] = line.value_and_dev(f"the {option}")
            if not parts:
                line.fail(f"use chemical {name} sets nothing: give 'conc C' and/or 'diff F'")
            if parts.get("diff", (0.0, 0.0))[0] < 0:
                line.fail("a diffusion rate must be >= 0")
            self.commands.append(UseChemical(name, parts.get("conc"), parts.get("diff"), line=line.lineno))
        elif what == "polarity":
            if line.accept("none"):
                self.commands.append(UsePolarity(None, line=line.lineno))
            elif line.peek() is None:
                self.commands.append(UsePolarity(0.0, line=line.lineno))
            else:
                angle, dev = line.value_and_dev("the polarity angle (degrees)")
                self.commands.append(UsePolarity(angle, dev, line=line.lineno))
        elif what == "seed":
            self.single(line, "seed", line.integer("the seed"), "use seed")
        else:
            line.fail(f"unknown 'use {what}'; expected chemical, polarity or seed")
        line.end("at the end of the use command")

    # ---- create (4.8.3) -----------------------------------------------------------
    def create(self, line: _Line) -> None:
        kind = line.take("what to create")
        if kind not in CREATE_KINDS:
            line.fail(f"unknown 'create {kind}'; expected one of {', '.join(CREATE_KINDS)}")
        file = None
        if kind == "cell":
            size = (line.number("the cell's x"), line.number("the cell's y"))
        elif kind in ("sqr_grid", "hex_grid"):
            size = (line.integer("the number of columns", low=1), line.integer("the number of rows", low=1))
        elif kind in ("sqr_circle", "hex_circle"):
            size = (line.number("the circle's radius", low=0.0, low_open=True),)
        else:
            size, file = (), line.quoted('the shape\'s file name ("file.txt")')
        options: dict = {}
        allowed = _CREATE_OPTIONS[kind]
        while line.peek() is not None:
            option = line.take("an option")
            if option == "wrap":
                line.fail("'wrap' (toroidal wrapping of a square grid) is not supported yet")
            if option not in allowed or option in options:
                line.fail(f"unexpected '{option}' (create {kind} takes {', '.join(allowed)}, once each)")
            if option == "at":
                options["at"] = (line.number("the x of 'at'"), line.number("the y of 'at'"))
            elif option == "dev":
                options["dev"] = line.number("the position dev", low=0.0)
            else:
                options["fixed"] = True
        self.commands.append(Create(kind, size, file, line=line.lineno, **options))

    # ---- set (4.8.4) --------------------------------------------------------------
    def set(self, line: _Line) -> None:
        what = line.take("'cell' or 'cells'")
        if what == "cell":
            first = last = line.integer("the cell index")
        elif what == "cells":
            first = line.integer("the first cell index")
            line.expect("to", "between the cell indices")
            last = line.integer("the last cell index")
            if last < first:
                line.fail(f"the index range {first} to {last} is empty")
        else:
            line.fail(f"expected 'set cell I' or 'set cells I to J', found 'set {what}'")
        parts: dict = {}
        while line.peek() is not None:
            option = line.take("an option")
            if option in parts or option not in ("chemical", "conc", "diff", "polarity", "fixed"):
                line.fail(f"unexpected '{option}' (set takes chemical NAME, conc, diff, polarity and fixed, once each)")
            if option == "chemical":
                parts["chemical"] = line.chemical()
            elif option in ("conc", "diff"):
                if "chemical" not in parts:
                    line.fail(f"'{option}' needs 'chemical NAME' before it")
                parts[option] = line.value_and_dev(f"the {option}")
            elif option == "polarity":
                if line.accept("none"):
                    parts["polarity"] = ("none", 0.0)
                else:
                    parts["polarity"] = line.value_and_dev("the polarity angle (degrees)")
            else:
                parts["fixed"] = True
        if not set(parts) - {"chemical"}:
            line.fail("set changes nothing: give conc, diff, polarity or fixed")
        if parts.get("diff", (0.0, 0.0))[0] < 0:
            line.fail("a diffusion rate must be >= 0")
        polarity, polarity_dev = parts.get("polarity", (None, 0.0))
        self.commands.append(SetCells(first, last, parts.get("chemical"), parts.get("conc"), parts.get("diff"),
                                      polarity, polarity_dev, parts.get("fixed", False), line=line.lineno))

    # ---- rules (4.8.5) ------------------------------------------------------------
    def rule(self, line: _Line) -> None:
        start = line.integer("the first iteration after 'from'") if line.accept("from") else None
        stop = line.integer("the last iteration after 'until'") if line.accept("until") else None
        condition = self.condition(line)
        if line.accept("and"):
            line.end("after 'and' (the condition joins the next rule's)")
            self.chain.append((line.lineno, condition, start, stop))
            return
        action = self.action(line)
        if line.peek() == "and":
            line.fail("unexpected 'and' after the action: a line ending in 'and' holds only a condition")
        line.end("after the action")
        chain = self.chain + [(line.lineno, condition, start, stop)]
        self.chain = []
        starts = [s for _, _, s, _ in chain if s is not None]
        stops = [s for _, _, _, s in chain if s is not None]
        start, stop = (max(starts) if starts else None), (min(stops) if stops else None)
        if len({(s, e) for _, _, s, e in chain}) > 1:
            windows = "; ".join(f"line {n}: {_window_words(s, e)}" for n, _, s, e in chain)
            self.warnings.append(f"lines {chain[0][0]}-{line.lineno}: the 'and' chain joins rules with different "
                                 f"windows ({windows}); the rule runs on their intersection, {_window_words(start, stop)}")
        if start is not None and stop is not None and start > stop:
            self.warnings.append(f"line {line.lineno}: the window from {start} until {stop} is empty; this rule never fires")
        try:
            self.rules.append(Rule(action, tuple(c for _, c, _, _ in chain), start, stop))
        except ValueError as err:
            line.fail(str(err))
        if isinstance(action, Map):
            self.maps.add(action.name)

    def condition(self, line: _Line):
        word = line.take("a condition (always, if or probability)")
        try:
            if word == "always":
                return Always()
            if word == "probability":
                return Chance(line.operand("the probability"))
            if word == "if":
                left = line.operand("the left operand")
                op = line.take("a comparison (==, !=, <, <=, >, >= or in)")
                if op == "in":
                    return Within(left, line.operand("the low end of 'in'"), line.operand("the high end of 'in'"))
                if op not in ("==", "!=", "<", "<=", ">", ">="):
                    line.fail(f"expected a comparison (==, !=, <, <=, >, >= or in), found '{op}'")
                return Compare(left, op, line.operand("the right operand"))
        except ListingError:
            raise
        except ValueError as err:  # a rule's own check (e.g. a probability outside [0, 1])
            line.fail(str(err))
        line.fail(f"expected a condition (always, if or probability), found '{word}'")

    def action(self, line: _Line):
        word = line.take("an action (change, react, divide, map or polarize) or 'and'")
        if word not in ACTIONS:
            line.fail(f"expected an action (change, react, divide, map or polarize) or 'and', found '{word}'")
        try:
            return getattr(self, f"action_{word}")(line)
        except ListingError:
            raise
        except ValueError as err:  # a rule's own check (e.g. a probability outside [0, 1])
            line.fail(str(err))

    def action_change(self, line: _Line):
        name = line.chemical("the chemical to change")
        kind = line.take(f"'conc' or 'diff' after chemical {name}")
        if kind not in ("conc", "diff"):
            line.fail(f"expected 'conc' or 'diff' after chemical {name}, found '{kind}'")
        amount = line.operand("the amount to add")
        spread = line.number("the dev of the change", low=0.0) if line.accept("dev") else 0.0
        return Change(conc(name) if kind == "conc" else diff(name), amount, spread)

    def action_react(self, line: _Line):
        first = line.chemical("the first reagent of react")
        second = line.chemical("the second reagent of react")
        if first == second:
            line.fail(f"react needs two different reagents, found {first} twice")
        scale = line.operand("the scale") if line.accept("scale") else 1.0
        line.expect("turing", "(the reaction: react U V [scale S] turing alpha A beta B)")
        values = {}
        for parameter in ("alpha", "beta"):
            line.expect(parameter, "(react ... turing alpha A beta B)")
            token = line.peek()
            if token is not None and not NUMBER.fullmatch(token):
                line.fail(f"{parameter} must be a number (a reference such as '{token}' is supported only for scale)")
            values[parameter] = line.number(parameter)
        return React(Bard(alpha=values["alpha"], beta=values["beta"], sp=1.0), (first, second), scale=scale)

    def action_divide(self, line: _Line):
        direction = spread = 0.0
        if line.accept("direction"):
            direction, spread = line.value_and_dev("the division direction (degrees)")
        return Divide(direction=math.radians(direction), spread=math.radians(spread))

    def action_map(self, line: _Line):
        source = line.operand("the mapped value")
        low, high = line.number("the low end of the input"), line.number("the high end of the input")
        line.expect("to", "(map VALUE LOW HIGH to NAME LOW HIGH)")
        name = line.take("the map's name")
        if not IDENTIFIER.fullmatch(name) or name in CELL_VARIABLES or name in self.chemicals:
            line.fail(f"a map's name must be a word other than a chemical, AGE, BIRTH or NEIGHBORS, found '{name}'")
        out_low, out_high = line.number("the low end of the output"), line.number("the high end of the output")
        return Map(source, low, high, name, out_low, out_high)

    def action_polarize(self, line: _Line):
        name = line.chemical("the chemical whose gradient sets the polarity")
        line.accept("conc")  # Listing A.1 writes `polarize R conc`: the same action
        return Polarize(name)

    # ---- utility commands (4.8.6) -------------------------------------------------
    def colormap(self, line: _Line) -> None:
        what = line.take("'select' or 'slot'")
        if what == "select":
            kind = line.take("the colour map type (heat, striped or gradient)")
            if kind not in COLORMAP_KINDS:
                line.fail(f"unknown colour map type '{kind}'; expected heat, striped or gradient")
            self.single(line, "colormap", kind, "colormap select")
        elif what == "slot":
            slot = line.integer("the slot number")
            if slot >= SLOTS:
                line.fail(f"the slot number must lie in 0..{SLOTS - 1}, found {slot}")
            line.expect("use", "after the slot number")
            how = line.take("'color' or 'rgb'")
            if how == "color":
                colour = line.quoted('the colour (a CSS name or a hex triplet, e.g. "white" or "420009")')
                try:
                    _rgb(colour)
                except ValueError as err:
                    line.fail(str(err))
            elif how == "rgb":
                colour = tuple(line.integer(f"the {c} byte") for c in ("red", "green", "blue"))
                if max(colour) > 255:
                    line.fail(f"rgb bytes must lie in 0..255, found {' '.join(map(str, colour))}")
            else:
                line.fail(f"expected 'color' or 'rgb' after 'use', found '{how}'")
            self.slots.append((slot, colour))
        else:
            line.fail(f"expected 'colormap select' or 'colormap slot', found 'colormap {what}'")
        line.end("at the end of the colormap command")

    def snap(self, line: _Line) -> None:
        if line.accept("from"):
            first = line.integer("the first snapshot's iteration")
            line.expect("repeat", "(snap from I repeat N step S)")
            repeat = line.integer("the number of snapshots", low=1)
            line.expect("step", "(snap from I repeat N step S)")
            snap = Snap((first,), (repeat, line.integer("the iterations between snapshots", low=1)))
        else:
            line.expect("at", "or 'from' after 'snap'")
            at = [line.integer("an iteration")]
            while line.peek() not in (None, "then"):
                at.append(line.integer("an iteration"))
            snap = Snap(tuple(at))
        if line.accept("then"):
            line.expect("exit", "after 'then'")
            snap = dataclasses.replace(snap, exit=True)
        line.end("at the end of the snap command")
        self.snaps.append(snap)

    def stop(self, line: _Line) -> None:
        line.expect("at", "after 'stop'")
        self.single(line, "stop", line.integer("the last iteration"), "stop at")
        line.end("at the end of the stop command")

    def texture(self, line: _Line) -> None:
        line.expect("size", "after 'texture'")
        size = (line.integer("the texture's width", low=1), line.integer("the texture's height", low=1))
        self.single(line, "texture", size, "texture size")
        line.end("at the end of the texture command")

    def zoom(self, line: _Line) -> None:
        line.expect("level", "after 'zoom'")
        self.single(line, "zoom", line.number("the zoom level", low=0.0, low_open=True), "zoom level")
        line.end("at the end of the zoom command")


def _window_words(start: int | None, stop: int | None) -> str:
    if start is None and stop is None:
        return "every iteration"
    return " ".join(w for w in (f"from {start}" if start is not None else "",
                                f"until {stop}" if stop is not None else "") if w)


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


# ---- the prepattern ------------------------------------------------------------------


class _Prepattern:
    """The cells placed so far (NumPy arrays of the live cells) and the `use` defaults."""

    def __init__(self, listing: Listing):
        self.listing = listing
        self.species = listing.species
        s = len(self.species)
        self.defaults = {"conc": np.zeros(s), "conc_dev": np.zeros(s), "diff": np.zeros(s), "diff_dev": np.zeros(s)}
        self.polarity: tuple[float | None, float] = (0.0, 0.0)  # radians: polarised along +x by default
        self.position = np.zeros((0, 2))
        self.concentration = np.zeros((s, 0))
        self.diffusion = np.zeros((s, 0))
        self.angle = np.zeros(0)
        self.polarised = np.zeros(0, bool)
        self.fixed = np.zeros(0, bool)

    def fail(self, line: int, message: str) -> NoReturn:
        raise ListingError.at(self.listing.name, self.listing.text.splitlines(), line, message)

    def execute(self, command, key) -> None:
        if isinstance(command, UseChemical):
            row = self.species.index(command.chemical)
            for part in ("conc", "diff"):
                given = getattr(command, part)
                if given is not None:
                    self.defaults[part][row], self.defaults[f"{part}_dev"][row] = given
        elif isinstance(command, UsePolarity):
            angle = None if command.angle is None else math.radians(command.angle)
            self.polarity = (angle, math.radians(command.dev))
        elif isinstance(command, Create):
            self.create(command, key)
        elif isinstance(command, SetCells):
            self.set(command, key)
        else:
            raise ValueError(f"unknown prepattern command {command!r}")

    def create(self, command: Create, key) -> None:
        angle, angle_dev = self.polarity
        group = cells_at(
            self.positions(command), self.species,
            concentration=self.defaults["conc"], spread=self.defaults["conc_dev"],
            diffusion=self.defaults["diff"], diffusion_spread=self.defaults["diff_dev"],
            polarity=angle, polarity_spread=angle_dev if angle is not None else 0.0,
            jitter=command.dev, fixed=command.fixed, key=key,
        ).live()
        self.position = np.concatenate([self.position, group["position"]])
        self.concentration = np.concatenate([self.concentration, group["concentration"]], axis=1)
        self.diffusion = np.concatenate([self.diffusion, group["diffusion"]], axis=1)
        self.angle = np.concatenate([self.angle, group["polarity"]])
        self.polarised = np.concatenate([self.polarised, group["polarised"]])
        self.fixed = np.concatenate([self.fixed, group["fixed"]])

    def positions(self, command: Create) -> np.ndarray:
        if command.kind == "cell":
            return np.array([command.size], float)
        lattice = "hex" if command.kind.startswith("hex") else "square"
        if command.kind.endswith("grid"):
            cols, rows = command.size
            return grid_positions((rows, cols), lattice, at=command.at)
        if command.kind.endswith("circle"):
            return disc_positions(command.size[0], lattice, at=command.at)
        return self.shape_positions(command)

    def shape_positions(self, command: Create) -> np.ndarray:
        """Every letter of the file a cell of a square grid (4.8.3): the file's first row
        is the top one; cells are numbered from the lowest row up, left to right, and the
        letters' bounding box is centred on `at`."""
        directory = self.listing.directory or Path.cwd()
        path = Path(command.file) if Path(command.file).is_absolute() else directory / command.file
        try:
            rows = path.read_text().splitlines()
        except OSError as err:
            self.fail(command.line, f"cannot read the shape file {str(path)!r} ({err.strerror or err})")
        cells = [(-r, c) for r, text in enumerate(rows) for c, ch in enumerate(text) if ch.isalpha()]
        if not cells:
            self.fail(command.line, f"the shape file {str(path)!r} holds no letter (each letter is a cell)")
        cells.sort()  # lowest row first (y = -row), then left to right
        xy = np.array([(c * SPACING, y * SPACING) for y, c in cells], float)
        xy -= (xy.min(axis=0) + xy.max(axis=0)) / 2
        return xy + np.asarray(command.at, float)

    def set(self, command: SetCells, key) -> None:
        n = self.position.shape[0]
        if command.last >= n:
            where = f"cells 0 to {n - 1}" if n else "no cells"
            wanted = f"cell {command.first}" if command.first == command.last else f"cells {command.first} to {command.last}"
            self.fail(command.line, f"{wanted} out of range: the cells created before this line are {where}")
        cells = slice(command.first, command.last + 1)
        m = command.last + 1 - command.first
        conc_key, diff_key, polarity_key = jax.random.split(key, 3)
        if command.chemical is not None:
            row = self.species.index(command.chemical)
            if command.conc is not None:
                self.concentration[row, cells] = command.conc[0] + _uniform(conc_key, m, command.conc[1])
            if command.diff is not None:
                rates = command.diff[0] + _uniform(diff_key, m, command.diff[1])
                self.diffusion[row, cells] = np.maximum(rates, 0.0)  # rates are kept >= 0, as cells_at does
        if command.polarity == "none":
            self.polarised[cells] = False
        elif command.polarity is not None:
            spread = math.radians(command.polarity_dev)
            self.angle[cells] = math.radians(command.polarity) + _uniform(polarity_key, m, spread)
            self.polarised[cells] = True
        if command.fixed:
            self.fixed[cells] = True

    def cells(self) -> Cells:
        if self.position.shape[0] == 0:
            raise ValueError(f"{self.listing.name}: the listing creates no cells (no 'create' line)")
        return make_cells(
            self.species, self.position, concentration=self.concentration, diffusion=self.diffusion,
            polarity=self.angle, polarised=self.polarised, fixed=self.fixed,
            upper=[c.limit for c in self.listing.chemicals],
            anisotropic=tuple(c.anisotropic for c in self.listing.chemicals),
        )


def _uniform(key, n: int, amplitude: float) -> np.ndarray:
    """n draws from [-amplitude, amplitude] (zeros without drawing when amplitude is 0)."""
    if amplitude <= 0:
        return np.zeros(n)
    return np.asarray(jax.random.uniform(key, (n,), minval=-1.0, maxval=1.0), float) * amplitude


# ---- writing -------------------------------------------------------------------------


def _format_number(value) -> str:
    """The shortest decimal that reads back to the same value in its own precision (a
    float32 leaf of a rule reads back from "0.0004", not "0.0003999999898951501")."""
    array = np.asarray(value)
    scalar = (array if array.dtype.kind == "f" else array.astype(np.float64)).reshape(())[()]
    magnitude = abs(float(scalar))
    if magnitude != 0 and (magnitude < 1e-6 or magnitude >= 1e15):
        return np.format_float_scientific(scalar, unique=True, trim="-")
    return np.format_float_positional(scalar, unique=True, trim="-")


def _format_degrees(radians) -> str:
    """The shortest degree string that reads back (through `math.radians` and the leaf's
    dtype) to the same angle leaf."""
    leaf = np.asarray(radians)
    degrees = math.degrees(float(leaf))
    for digits in range(1, 18):
        text = np.format_float_positional(degrees, precision=digits, unique=False, fractional=False, trim="-")
        if np.asarray(math.radians(float(text)), leaf.dtype) == leaf:
            return text
    return repr(degrees)


def _format_operand(value) -> str:
    return str(value) if isinstance(value, Var) else _format_number(value)


def _format_condition(condition) -> str:
    if isinstance(condition, Always):
        return "always"
    if isinstance(condition, Chance):
        return f"probability {_format_operand(condition.probability)}"
    if isinstance(condition, Compare):
        return f"if {_format_operand(condition.left)} {condition.op} {_format_operand(condition.right)}"
    if isinstance(condition, Within):
        return (f"if {_format_operand(condition.value)} in {_format_operand(condition.low)} "
                f"{_format_operand(condition.high)}")
    raise ValueError(f"the listing language cannot write the condition {condition!r}")


def _format_action(action) -> str:
    if isinstance(action, Change):
        dev = f" dev {_format_number(action.spread)}" if float(action.spread) != 0 else ""
        return f"change {action.target} {_format_operand(action.amount)}{dev}"
    if isinstance(action, React):
        model = action.model
        if not isinstance(model, Bard) or float(model.sp) != 1.0:
            raise ValueError("the listing language writes only react ... turing (Bard with sp = 1); "
                             f"cannot write {type(model).__name__}")
        return (f"react {' '.join(action.species)} scale {_format_operand(action.scale)} turing "
                f"alpha {_format_number(model.alpha)} beta {_format_number(model.beta)}")
    if isinstance(action, Divide):
        dev = f" dev {_format_degrees(action.spread)}" if float(action.spread) != 0 else ""
        return f"divide direction {_format_degrees(action.direction)}{dev}"
    if isinstance(action, Map):
        return (f"map {_format_operand(action.source)} {_format_operand(action.low)} {_format_operand(action.high)} "
                f"to {action.name} {_format_operand(action.out_low)} {_format_operand(action.out_high)}")
    if isinstance(action, Polarize):
        return f"polarize {action.reagent}"
    raise ValueError(f"the listing language cannot write the action {action!r}")


def _format_rule(rule: Rule) -> list[str]:
    window = "".join(f" {word} {value}" for word, value in (("from", rule.start), ("until", rule.stop)) if value is not None)
    conditions = [_format_condition(c) for c in rule.when] or ["always"]
    lines = [f"rule{window} {c} and" for c in conditions[:-1]]
    return lines + [f"rule{window} {conditions[-1]} {_format_action(rule.action)}"]


def _format_value_dev(word: str, given) -> str:
    if given is None:
        return ""
    value, dev = given
    return f" {word} {_format_number(value)}" + (f" dev {_format_number(dev)}" if dev else "")


def _format_command(command) -> str:
    if isinstance(command, UseChemical):
        return (f"use chemical {command.chemical}{_format_value_dev('conc', command.conc)}"
                f"{_format_value_dev('diff', command.diff)}")
    if isinstance(command, UsePolarity):
        if command.angle is None:
            return "use polarity none"
        dev = f" dev {_format_number(command.dev)}" if command.dev else ""
        return f"use polarity {_format_number(command.angle)}{dev}"
    if isinstance(command, Create):
        if command.kind == "shape":
            size = f' "{command.file}"'
        else:
            size = "".join(f" {v}" if isinstance(v, int) else f" {_format_number(v)}" for v in command.size)
        at = f" at {_format_number(command.at[0])} {_format_number(command.at[1])}" if tuple(command.at) != (0.0, 0.0) else ""
        dev = f" dev {_format_number(command.dev)}" if command.dev else ""
        return f"create {command.kind}{size}{at}{dev}{' fixed' if command.fixed else ''}"
    if isinstance(command, SetCells):
        cells = f"cell {command.first}" if command.first == command.last else f"cells {command.first} to {command.last}"
        chemical = f" chemical {command.chemical}" if command.chemical is not None else ""
        if command.polarity == "none":
            polarity = " polarity none"
        else:
            polarity = _format_value_dev("polarity", None if command.polarity is None else (command.polarity, command.polarity_dev))
        return (f"set {cells}{chemical}{_format_value_dev('conc', command.conc)}{_format_value_dev('diff', command.diff)}"
                f"{polarity}{' fixed' if command.fixed else ''}")
    raise ValueError(f"unknown prepattern command {command!r}")


def _write_listing(listing: Listing) -> list[str]:
    lines = []
    for c in listing.chemicals:
        limit = f" limit {_format_number(c.limit)}" if c.limit is not None else ""
        lines.append(f"define chemical {c.name}{limit}{' anisotropic' if c.anisotropic else ''}")
    if listing.division_limit is not None:
        lines.append(f"define division_limit {listing.division_limit}")
    if isinstance(listing.domain, Box):
        lines.append(f"define domain {_format_number(listing.domain.width)} {_format_number(listing.domain.height)}")
    elif isinstance(listing.domain, Packed):
        default = np.asarray(listing.domain.area) == np.asarray(Packed().area)
        lines.append("define domain packed" + ("" if default else f" area {_format_number(listing.domain.area)}"))
    if listing.dt != 1.0:
        lines.append(f"define time_step {_format_number(listing.dt)}")
    if listing.seed is not None:
        lines.append(f"use seed {listing.seed}")
    lines += [_format_command(c) for c in listing.commands]
    for rule in listing.rules:
        lines += _format_rule(rule)
    if listing.colormap_select is not None:
        lines.append(f"colormap select {listing.colormap_select}")
    for slot, colour in listing.colormap_slots:
        use = f'color "{colour}"' if isinstance(colour, str) else "rgb " + " ".join(str(int(v)) for v in colour)
        lines.append(f"colormap slot {slot} use {use}")
    if listing.texture is not None:
        lines.append(f"texture size {listing.texture[0]} {listing.texture[1]}")
    if listing.zoom is not None:
        lines.append(f"zoom level {_format_number(listing.zoom)}")
    for snap in listing.snaps:
        if snap.every is None:
            text = "snap at " + " ".join(str(i) for i in snap.at)
        else:
            text = f"snap from {snap.at[0]} repeat {snap.every[0]} step {snap.every[1]}"
        lines.append(text + (" then exit" if snap.exit else ""))
    if listing.stop is not None:
        lines.append(f"stop at {listing.stop}")
    return lines


# ---- comparing -----------------------------------------------------------------------


def rule_key(rule: Rule):
    """A comparable, hashable form of a rule: its tree structure (actions, conditions,
    names, operators, window) and its numbers as Python floats."""
    leaves, treedef = jax.tree_util.tree_flatten(rule)
    return treedef, tuple(tuple(np.asarray(leaf, float).ravel().tolist()) for leaf in leaves)


def same_rules(a, b) -> bool:
    """Whether two sequences of rules are the same rules with the same numbers."""
    a, b = tuple(a), tuple(b)
    return len(a) == len(b) and all(rule_key(x) == rule_key(y) for x, y in zip(a, b))


def _domain_key(domain):
    if domain is None:
        return None
    return type(domain).__name__, tuple(np.asarray(leaf, float).item() for leaf in jax.tree_util.tree_leaves(domain))


def _listing_key(listing: Listing):
    return (
        listing.chemicals, listing.dt, listing.stop, _domain_key(listing.domain), listing.division_limit,
        listing.seed, listing.commands, tuple(rule_key(r) for r in listing.rules), listing.colormap_select,
        listing.colormap_slots, listing.texture, listing.zoom, listing.snaps,
    )


__all__ = [
    "LISTINGS", "Chemical", "Create", "Listing", "ListingError", "SetCells", "Snap", "UseChemical", "UsePolarity",
    "listing_path", "load_listing", "same_rules",
]

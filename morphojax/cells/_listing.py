"""The reader of the thesis's experiment language (thesis 4.8, Listings 4.1-4.8, Table 4.1).

An experiment file holds one statement per line; `//` starts a comment anywhere on a line.

    define chemical NAME [limit L] [anisotropic]       simulation parameters (4.8.1)
    define division_limit N | domain W H | domain packed [area A] | time_step DT
    use chemical NAME [conc C [dev D]] [diff F [dev E]] default values (4.8.2)
    use polarity none | ANGLE [dev D]  |  use seed N
    create cell X Y | sqr_grid COLS ROWS | sqr_circle R  cell placement (4.8.3)
           | hex_grid COLS ROWS | hex_circle R | shape "FILE"   [at X Y] [dev D] [fixed]
           (sqr_grid also takes [wrap]: the domain becomes a torus the grid tiles)
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
- `create sqr_grid COLS ROWS wrap` makes the domain `Torus(2 COLS, 2 ROWS)`, centred on the
  origin (a grid placed `at` elsewhere has its cells wrapped into it): cells at opposite
  edges are neighbours (thesis 7.3, Figs. 7.13 and 7.15). A listing wraps one grid, and
  then has no `define domain`; the text written back keeps the `wrap` on its grid.
- `set` REPLACES the named values of the cells (plus the noise of its `dev`); rules'
  `change` adds (thesis 4.8.5).
- An `and` chain (`rule COND and` lines followed by a rule) is one `Rule` whose `when`
  holds every condition; it runs on the intersection of the lines' iteration windows.
- The published listings are read as written: inconsistencies are recorded in
  `Listing.warnings`, never silently fixed (e.g. Listing A.17's `from 2500 until 2000`
  is an empty window, so that rule never fires).

The reader is split by job: `_listing_commands` (the parsed commands), `_listing_tokens`
(the line cursor and `ListingError`), `_listing_read` (the parser), `_listing_prepattern`
(executing `use`/`create`/`set`) and `_listing_write` (statements written back and rules
compared). This module holds the `Listing` (which writes and compares itself with
`_listing_write`'s pieces), the shipped listings and `load_listing`; it imports the others,
and none of them imports it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path

import jax
import numpy as np

from .._checks import check_count
from .._render import Gradient
from .._status import SimulationError
from ._listing_commands import HEAT, SLOTS, Chemical, Command, Snap, _rgb
from ._listing_prepattern import _Prepattern
from ._listing_read import _Reader
from ._listing_tokens import ListingError, format_number
from ._listing_write import domain_key, format_command, format_rule, rule_key, same_rules
from ._rules import Divide, Rule
from ._space import Box, Packed, Torus
from ._state import Cells

CAPACITY_GROWTH = 1.5  # a piece that outgrows the capacity runs again with half as much room again
ROOM_GROWTH = 1.5  # and so does the neighbour search (every slot costs every iteration)
MAX_RETRIES = 24  # 1.5 ** 24: from one cell to over 16,000 times as many
RUNG_CELLS = 1024  # from this many live cells, a growing run's capacity follows them on rungs


def capacity_rung(count: int, growth: int) -> int:
    """The capacity a piece of a growing run gets once it has `RUNG_CELLS` cells: the live
    `count`, a sixteenth of them more plus 64, and at least twice the last piece's
    `growth`, rounded up to the next rung m x 2**k (m = 4..8: steps of at most a quarter,
    each compiled once; eighths cut Listing A.18's work by a few percent more for twice the
    compilations). Every iteration pays for every slot of capacity, empty or not; a piece
    that outgrows its rung still runs again with half as much room again."""
    need = int(count) + max(int(count) // 16 + 64, 2 * int(growth))
    shift = max(need.bit_length() - 3, 0)
    return -(-need >> shift) << shift


def _more_room(room, need, given) -> list[int]:
    """Half as much again of the search room that `need` (what the cells need now) shows
    ran out, and at least that need; both when neither does (the crowd has passed); never
    a room the caller gave."""
    short = [need[0] + 2 > room[0], need[1] > room[1]]
    if not any(short):
        short = [True, True]
    return [max(math.ceil(ROOM_GROWTH * r), n + 2 * (k == 0)) if s and g is None else r
            for k, (r, n, s, g) in enumerate(zip(room, need, short, given))]


@dataclasses.dataclass(frozen=True, eq=False)
class Listing:
    """A parsed experiment (thesis 4.8): read it with `load_listing`.

    Attributes:
        name: the file's stem, or "<text>".
        text: the source text.
        chemicals: the `Chemical`s in declaration order (the order of the cells' reagents).
        dt: `define time_step` (default 1).
        stop: `stop at N` (None if absent); see `steps`.
        domain: None, `Box(W, H)` (`define domain W H`), `Packed(area)` or `Torus(W, H)`
            (`create sqr_grid ... wrap`).
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
        directory: the only folder `create shape` files are read from (None: no file is read).
    """

    name: str = "<text>"
    text: str = ""
    chemicals: tuple[Chemical, ...] = ()
    dt: float = 1.0
    stop: int | None = None
    domain: Box | Packed | Torus | None = None
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
        A listing with a `wrap` grid gives cells that live on its torus (`Cells.period`).
        """
        if not self.chemicals:
            raise ValueError(f"{self.name}: the listing defines no chemical; the cells need at least one")
        builder = _Prepattern(self.name, self.text, self.chemicals, self.directory)
        keys = jax.random.split(key, max(len(self.commands), 1))
        for command, command_key in zip(self.commands, keys):
            builder.execute(command, command_key)
        cells = builder.cells()
        return cells.with_period(self.domain.period) if isinstance(self.domain, Torus) else cells

    # ---- running ------------------------------------------------------------------
    def run(self, seed: int | None = None, steps: int | None = None, capacity: int | None = None, key=None,
            max_neighbours: int | None = None, bucket_size: int | None = None,
            progress: bool | str = False) -> Cells:
        """Place the prepattern and simulate the listing (`simulate_cells`, thesis ch. 4).

        Args:
            seed: the random seed (default: the listing's `use seed`, else 0); ignored
                when `key` is given.
            steps: iterations (default: `self.steps`, from `stop at` or `snap ... then
                exit`; a listing with neither needs it).
            capacity: room for cells. Default: the prepattern's count, and when a rule
                divides a quarter more, grown during the run as the cells need it.
            key: a `jax.random` key (split between the prepattern and the run).
            max_neighbours, bucket_size: room in the neighbour search (defaults of
                `simulate_cells`).
            progress: show a progress bar (see `simulate_cells`).

        A listing runs as published, whatever room it needs: room you do not give grows
        during the run (see `snapshots`). Raises SimulationError when the run blows up, or
        overflows room you gave.
        """
        steps = self.steps if steps is None else steps
        if steps is None:
            raise ValueError(f"{self.name}: the listing has no 'stop at' or 'snap ... then exit' line; pass steps")
        return self.snapshots((steps,), seed, capacity, key, max_neighbours, bucket_size, progress)[-1]

    def snapshots(self, iterations, seed: int | None = None, capacity: int | None = None, key=None,
                  max_neighbours: int | None = None, bucket_size: int | None = None,
                  progress: bool | str = False) -> list[Cells]:
        """The cells after each of the increasing `iterations` (0 = the prepattern) of one
        run (the thesis's `snap at`); arguments as `run`.

        The run goes in pieces (a fiftieth of it, and the snapshots). A piece whose
        divisions overflow a capacity you did not give is run again from its start with
        half as much room again, and one whose neighbour search overflows with half as much
        again of the room you did not give (`max_neighbours`, at least what the cells then
        need, and `bucket_size`): the random draws depend on
        the iteration only, so the cells are those of a run that had the room from the
        start (up to the order of float sums), and the capacity follows the tissue instead
        of being guessed. From `RUNG_CELLS` live cells on, each piece also starts on the
        rung just above its cells (`capacity_rung`, up or down), for up to a third less work
        than buffers grown by half: the same cells up to the order of float sums (XLA may
        group a row's sums by the buffers' length; the same divisions).
        """
        from .._progress import progress_bar
        from ._simulate import MAX_ROOM, PIECES, needed_room, simulate_cells

        iterations = [int(i) for i in iterations]
        if not iterations or any(b <= a for a, b in zip(iterations, iterations[1:])) or iterations[0] < 0:
            raise ValueError(f"iterations must increase from 0 or more (got {iterations})")
        for value in iterations:
            check_count(value, "iterations", "iterations")
        if key is None:
            key = jax.random.key(seed if seed is not None else (self.seed or 0))
        prepattern_key, run_key = jax.random.split(key)
        cells = self.prepattern(prepattern_key)
        divides = any(isinstance(rule.action, Divide) for rule in self.rules)
        grow_cells, grow_search = capacity is None and divides, max_neighbours is None or bucket_size is None
        if capacity is None:
            capacity = int(cells.count) + (int(cells.count) // 4 + 64 if divides else 0)
        # every iteration pays for each slot of the neighbour list, and each full build for
        # each candidate it reads: start from the room the prepattern needs (8 partners on a
        # square grid, 6 on a hexagonal one; the fullest three buckets in a row, plus one
        # cell a bucket), grown when it overflows
        need = needed_room(cells)
        room = [max(need[0] + 2, 8) if max_neighbours is None else max_neighbours,
                need[1] + 1 if bucket_size is None else bucket_size]
        last = iterations[-1]
        piece = max(1, last // PIECES)
        ends = sorted(set(iterations) | set(range(piece, last, piece)))
        bar = progress_bar(last, self.name if progress is True else progress, unit="iteration") if progress else None
        out, shots, retries = cells.with_capacity(int(capacity)), [], 0
        last_count = int(out.count)
        try:
            for end in ends:
                if grow_cells and int(out.count) >= RUNG_CELLS:  # the capacity follows the cells
                    rung = capacity_rung(int(out.count), int(out.count) - last_count)
                    if rung != out.capacity:
                        out = out.with_capacity(rung)
                last_count = int(out.count)
                while int(out.step) < end:
                    trial = simulate_cells(
                        None, out, end - int(out.step), self.dt, rules=self.rules, key=run_key, domain=self.domain,
                        division_limit=self.division_limit, max_neighbours=room[0], bucket_size=room[1], throw=False,
                        check_dt=int(out.step) == 0,  # once, on the prepattern
                    )
                    crowded = grow_cells and int(trial.overflow_step) >= 0
                    cramped = grow_search and int(trial.neighbour_overflow_step) >= 0
                    cramped &= max(room) < MAX_ROOM  # past that, more room would not help
                    if (crowded or cramped) and int(trial.nonfinite_step) < 0 and retries < MAX_RETRIES:
                        retries += 1  # this piece again, from its start, with more room
                        if crowded:
                            out = out.with_capacity(math.ceil(CAPACITY_GROWTH * out.capacity))
                        if cramped:  # more of the room that ran out (both if the crowd has passed)
                            room = _more_room(room, needed_room(trial), (max_neighbours, bucket_size))
                        continue
                    if bar is not None:
                        bar.update(int(trial.step) - int(out.step))
                    out = trial
                    if not bool(out.ok):
                        raise SimulationError(f"{self.name}: {out.message()}")
                if end in iterations:
                    shots.append(out)
        finally:
            if bar is not None:
                bar.close()
        return shots

    # ---- writing ------------------------------------------------------------------
    def to_text(self) -> str:
        """The canonical listing: one command per line, comments dropped, defaults left
        out, every rule written from its `Rule` (an `and` chain one line per condition,
        each carrying the chain's window). `load_listing(listing.to_text())` equals
        `listing`."""
        lines = []
        for c in self.chemicals:
            limit = f" limit {format_number(c.limit)}" if c.limit is not None else ""
            lines.append(f"define chemical {c.name}{limit}{' anisotropic' if c.anisotropic else ''}")
        if self.division_limit is not None:
            lines.append(f"define division_limit {self.division_limit}")
        if isinstance(self.domain, Box):
            lines.append(f"define domain {format_number(self.domain.width)} {format_number(self.domain.height)}")
        elif isinstance(self.domain, Packed):  # a Torus is written as its grid's `wrap`
            default = np.asarray(self.domain.area) == np.asarray(Packed().area)
            lines.append("define domain packed" + ("" if default else f" area {format_number(self.domain.area)}"))
        if self.dt != 1.0:
            lines.append(f"define time_step {format_number(self.dt)}")
        if self.seed is not None:
            lines.append(f"use seed {self.seed}")
        lines += [format_command(c) for c in self.commands]
        for rule in self.rules:
            lines += format_rule(rule)
        if self.colormap_select is not None:
            lines.append(f"colormap select {self.colormap_select}")
        for slot, colour in self.colormap_slots:
            use = f'color "{colour}"' if isinstance(colour, str) else "rgb " + " ".join(str(int(v)) for v in colour)
            lines.append(f"colormap slot {slot} use {use}")
        if self.texture is not None:
            lines.append(f"texture size {self.texture[0]} {self.texture[1]}")
        if self.zoom is not None:
            lines.append(f"zoom level {format_number(self.zoom)}")
        for snap in self.snaps:
            if snap.every is None:
                text = "snap at " + " ".join(str(i) for i in snap.at)
            else:
                text = f"snap from {snap.at[0]} repeat {snap.every[0]} step {snap.every[1]}"
            lines.append(text + (" then exit" if snap.exit else ""))
        if self.stop is not None:
            lines.append(f"stop at {self.stop}")
        return "\n".join(lines) + "\n"

    def __eq__(self, other):
        if not isinstance(other, Listing):
            return NotImplemented
        return self._key() == other._key()

    def _key(self):
        """What equal listings share: every field but the name, the text, the warnings and
        the folder, with rules and the domain compared by their structure and numbers."""
        return (
            self.chemicals, self.dt, self.stop, domain_key(self.domain), self.division_limit,
            self.seed, self.commands, tuple(rule_key(r) for r in self.rules), self.colormap_select,
            self.colormap_slots, self.texture, self.zoom, self.snaps,
        )

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
    for stem in ("fig5.1", "fig5.2", "fig7.13", "fig7.15", "fig7.20", "listing4.1", "listing5.1"):
        names[stem] = LISTING_DIR / f"{stem}.txt"
    return names


LISTINGS: Mapping[str, Path] = _shipped()
"""The thesis's listings shipped with morphojax, by name: "A.1" ... "A.18" (Appendix A)
and the same files by figure, "fig5.14" ... "fig7.21", plus "fig5.1", "fig5.2", "fig7.13",
"fig7.15" and "fig7.20" (the listings printed with Figs. 5.1, 5.2, 7.13, 7.15 and 7.20; 7.13
and 7.15 on a torus, `create sqr_grid 100 100 wrap`), "listing4.1" and "listing5.1"."""


def listing_path(name: str) -> Path:
    """The file of a shipped listing: "A.18", "fig7.21", "Fig 7.21", "A18_fig7.21", ..."""
    wanted = _normalise_name(name)
    for known, path in LISTINGS.items():
        if wanted in (_normalise_name(known), _normalise_name(path.stem)):
            return path
    raise ValueError(f"unknown listing {name!r}; the shipped listings are {', '.join(LISTINGS)}")


def _normalise_name(name: str) -> str:
    return str(name).strip().lower().replace(" ", "").replace("figure", "fig").replace("listinga.", "a.")


def load_listing(source, *, name: str | None = None, folder=None, directory=None) -> Listing:
    """Read an experiment (thesis 4.8) into a `Listing`.

    Args:
        source: a path to a listing file (str or Path), the name of a shipped listing
            (see `LISTINGS`, e.g. "A.18"), or the text itself.
        name: the name errors report (default: the file's stem, or "<text>").
        folder: the only folder `create shape` files are read from (default: the file's
            folder; text has none, and reads no file unless `folder` names one).
            `directory` is its older name.

    Every malformed line raises ValueError("<name>:<line>: <what is wrong> (got
    '<line>')"); unknown chemicals and mapped values are caught here, out-of-range `set`
    indices when the prepattern is built.
    """
    if folder is not None and directory is not None:
        raise ValueError("load_listing: give folder or directory (its older name), not both")
    directory = folder if folder is not None else directory
    path = _as_path(source)
    if path is not None:
        text = _read_listing_file(path)
        name = path.stem if name is None else name
        directory = path.parent if directory is None else directory
    else:
        text = str(source)
        name = "<text>" if name is None else name
    return Listing(**_Reader(text, name, None if directory is None else Path(directory)).read())


LISTING_BYTES = 1 << 20  # a listing is a page of commands; the thesis's longest is 3 kB


def _read_listing_file(path: Path) -> str:
    """A listing file's text: a regular file of at most LISTING_BYTES, decoded as UTF-8 (else Latin-1)."""
    from .._files import check_regular_file

    path = check_regular_file(path, "listing")
    size = path.stat().st_size
    if size > LISTING_BYTES:
        raise ValueError(f"listing file {path} holds {size} bytes; a listing has at most {LISTING_BYTES}")
    raw = path.read_bytes()
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _as_path(source) -> Path | None:
    if isinstance(source, Path):
        if not source.exists():
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


__all__ = ["LISTINGS", "Listing", "ListingError", "listing_path", "load_listing", "same_rules"]

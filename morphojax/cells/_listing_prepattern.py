"""The prepattern of a listing (thesis 4.8.2-4.8.4): `_Prepattern` executes the `use`,
`create` and `set` commands in order on NumPy arrays of the cells placed so far (the `use`
defaults apply to later `create`s; `set` replaces values of cells already created) and
makes the initial `Cells`. `Listing.prepattern` drives it, one key per command, and gives it
the parts of the listing it reads (this module does not import `_listing`).
"""

from __future__ import annotations

import math
import stat
from pathlib import Path
from typing import NoReturn

import jax
import numpy as np

from ._listing_commands import Chemical, Create, SetCells, UseChemical, UsePolarity
from ._listing_tokens import ListingError
from ._prepattern import SPACING, cells_at, disc_positions, grid_positions
from ._state import Cells, make_cells


class _Prepattern:
    """The cells placed so far (NumPy arrays of the live cells) and the `use` defaults, for the
    listing `name` with source `text` (for errors), its `chemicals` and the `directory` its
    shape files are read from."""

    def __init__(self, name: str, text: str, chemicals: tuple[Chemical, ...], directory: Path | None):
        self.name, self.text, self.chemicals, self.directory = name, text, chemicals, directory
        self.species = tuple(c.name for c in chemicals)
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
        raise ListingError.at(self.name, self.text.splitlines(), line, message)

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
        rows = read_shape_file(self.directory, command.file, lambda why: self.fail(command.line, why))
        cells = [(-r, c) for r, text in enumerate(rows) for c, ch in enumerate(text) if ch.isalpha()]
        if not cells:
            self.fail(command.line, f"the shape file {command.file!r} holds no letter (each letter is a cell)")
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
            raise ValueError(f"{self.name}: the listing creates no cells (no 'create' line)")
        return make_cells(
            self.species, self.position, concentration=self.concentration, diffusion=self.diffusion,
            polarity=self.angle, polarised=self.polarised, fixed=self.fixed,
            upper=[c.limit for c in self.chemicals],
            anisotropic=tuple(c.anisotropic for c in self.chemicals),
        )


def _uniform(key, n: int, amplitude: float) -> np.ndarray:
    """n draws from [-amplitude, amplitude] (zeros without drawing when amplitude is 0)."""
    if amplitude <= 0:
        return np.zeros(n)
    return np.asarray(jax.random.uniform(key, (n,), minval=-1.0, maxval=1.0), float) * amplitude


SHAPE_FILE_BYTES = 1 << 20  # a shape file is a picture in letters: 1 MB is a million cells


def read_shape_file(folder, name: str, fail) -> list[str]:
    """The lines of the shape file `name`, a regular file inside the listing's `folder` (no
    absolute path, no `..` out of it, no link leading out, no pipe or device), at most
    SHAPE_FILE_BYTES; `fail(why)` reports anything else. A listing given as text has no
    folder and reads no file unless `load_listing(text, folder=...)` names one."""
    if folder is None:
        fail(f"the shape file {name!r} cannot be read: a listing given as text has no folder; "
             "name one with load_listing(text, folder=PATH)")
    folder = Path(folder).resolve()
    path = (folder / name).resolve()
    if Path(name).is_absolute() or folder not in path.parents:
        fail(f"the shape file {name!r} lies outside the listing's folder {str(folder)!r}; shape files are read "
             "from that folder only")
    try:
        info = path.stat()
    except OSError as err:
        fail(f"cannot read the shape file {str(path)!r} ({err.strerror or err})")
    if not stat.S_ISREG(info.st_mode):
        fail(f"the shape file {str(path)!r} is not a regular file")
    if info.st_size > SHAPE_FILE_BYTES:
        fail(f"the shape file {str(path)!r} holds {info.st_size} bytes; at most {SHAPE_FILE_BYTES} are read")
    try:
        with open(path, "rb") as handle:
            return handle.read(SHAPE_FILE_BYTES + 1).decode("latin-1").splitlines()
    except OSError as err:
        fail(f"cannot read the shape file {str(path)!r} ({err.strerror or err})")

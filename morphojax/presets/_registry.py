"""The one preset registry: every named run of every kind, with the figure it reproduces.

A preset is registered once, under its name, as one of:

- `ExperimentPreset` (kind "reaction-diffusion"): its builder `build(quick)` gives the
  `Experiment` (`experiment(quick)`); a figure made of several experiments has no builder
  but `members`, and says how its montage is laid out (`row_labels`, `col_labels`,
  `snapshots`).
- `AutomatonPreset` (kind "automaton"): its builder `build(seed, quick, out, frames)` runs
  a cellular automaton and writes its pictures and `.npz` next to `out` (`run(...)`).

New kinds of run (cells, meshes) add a subclass with their own `kind`; `morphojax run NAME`
dispatches on `kind`.
"""

from __future__ import annotations

import difflib

import dataclasses
import time
from pathlib import Path
from typing import Callable, ClassVar

from .._experiment import Experiment
from .._render import png_path


@dataclasses.dataclass(frozen=True)
class Preset:
    """A named run: its `name`, a one-line `description`, the `figure` it reproduces and its
    builder `build` (what it takes and gives depends on the kind)."""

    kind: ClassVar[str] = ""
    name: str
    description: str
    figure: str
    build: Callable | None = dataclasses.field(default=None, repr=False)


@dataclasses.dataclass(frozen=True)
class ExperimentPreset(Preset):
    """A reaction-diffusion experiment (`build(quick)`), or a figure made of several
    (`members`, shown as the rows of one montage, e.g. the three rows of Fig. 6).

    A figure's montage has one row per member labelled `row_labels` (default: the last
    word of each member's name) and, with `snapshots`, one column per snapshot of the
    member's run; otherwise one tile per member, `len(col_labels)` to a row, the rows
    labelled by `row_labels` only. Tiles share the widest tile's width
    (`cli._run.figure_layout`).
    """

    kind: ClassVar[str] = "reaction-diffusion"
    members: tuple = ()
    row_labels: tuple | None = None
    col_labels: tuple | None = None
    snapshots: bool = False

    def experiment(self, quick: bool = False) -> Experiment:
        """The experiment (`quick`: a reduced version that runs in seconds)."""
        if self.build is None:
            raise ValueError(f"preset {self.name!r} is a figure of several experiments: {', '.join(self.members)}")
        return self.build(quick)


@dataclasses.dataclass(frozen=True)
class AutomatonPreset(Preset):
    """A cellular-automaton run: `build(seed, quick, out, frames) -> summary dict` writes
    its outputs next to the PNG path `out`."""

    kind: ClassVar[str] = "automaton"

    def run(self, seed: int = 0, quick: bool = False, out=None, frames: bool = False) -> dict:
        """Run and write `out` (default NAME.png) and its companions; returns the summary."""
        out = png_path(out if out is not None else f"{self.name}.png")
        out.parent.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        summary = self.build(int(seed), bool(quick), Path(out), bool(frames))
        summary["seconds_total"] = round(time.perf_counter() - t0, 3)
        return {"preset": self.name, **summary}


PRESETS: dict[str, Preset] = {}  # every preset of every kind, in registration order


def register(item: Preset) -> Preset:
    """Add a preset to `PRESETS` (names are unique across kinds)."""
    if item.name in PRESETS:
        raise ValueError(f"preset {item.name!r} is registered twice")
    PRESETS[item.name] = item
    return item


def registered(cls: type[Preset], name: str, description: str, figure: str, **fields) -> Callable:
    """Decorator: register the decorated function as the builder of a `cls` preset."""

    def decorate(build):
        register(cls(name, description, figure, build, **fields))
        return build

    return decorate


def of_kind(kind: str) -> dict[str, Preset]:
    """The registered presets of one kind, by name."""
    return {name: p for name, p in PRESETS.items() if p.kind == kind}


def lookup(name: str) -> Preset:
    """The registered preset `name`; an unknown name is a ValueError suggesting the closest."""
    if name not in PRESETS:
        close = difflib.get_close_matches(name, list(PRESETS), n=3, cutoff=0.5)
        hint = f"did you mean {' or '.join(close)}?" if close else f"e.g. {', '.join(list(PRESETS)[:4])}"
        raise ValueError(f"unknown preset {name!r}; {hint} (`morphojax presets` lists them all)")
    return PRESETS[name]


def preset(name: str, quick: bool = False) -> Experiment:
    """The experiment of a reaction-diffusion preset by name (see `PRESETS`, or `morphojax presets`)."""
    item = lookup(name)
    if not isinstance(item, ExperimentPreset):
        raise ValueError(f"preset {name!r} is a{'n' if item.kind[0] in 'aeiou' else ''} {item.kind} run, not an "
                         f"experiment: run it with `morphojax run {name}` or PRESETS[{name!r}].run()")
    return item.experiment(quick)

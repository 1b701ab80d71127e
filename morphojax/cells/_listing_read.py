"""The parser of the experiment language (thesis 4.8.1-4.8.6): `_Reader` reads a listing's
text statement by statement (`define`, `use`, `create`, `set`, `rule`, `colormap`, `snap`,
`stop`, `texture`, `zoom`), checks every value as it goes (unknown chemicals, maps and
options, ranges, settings given twice, unfinished `and` chains) and collects the fields of
a `Listing`: the chemicals, the settings, the prepattern commands, the rules as `Rule` data
and the warnings. `load_listing` (in `_listing`) builds the `Listing` from them.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from ..models import Bard
from ._listing_commands import (
    _CREATE_OPTIONS,
    COLORMAP_KINDS,
    CREATE_KINDS,
    SLOTS,
    Chemical,
    Create,
    SetCells,
    Snap,
    UseChemical,
    UsePolarity,
    _rgb,
)
from ._listing_tokens import CELL_VARIABLES, IDENTIFIER, NUMBER, ListingError, _Line
from ._rules import Always, Chance, Change, Compare, Divide, Map, Polarize, React, Rule, Within, conc, diff
from ._prepattern import SPACING
from ._space import PACKING_AREA, Box, Packed, Torus

ACTIONS = ("change", "react", "divide", "map", "polarize")
MAX_CELLS = 10**7  # cells a listing may create: the thesis's largest makes a few thousand
MAX_PIXELS = 10**8  # pixels of a listing's texture
COMMANDS = ("define", "use", "create", "set", "rule", "colormap", "snap", "stop", "texture", "zoom")


class _Reader:
    """One listing read line by line into the fields of a `Listing` (see `read`)."""

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
        self.wrapped: int | None = None  # the line of the grid with `wrap`, if any
        self.lines = text.splitlines()

    def error(self, number: int, message: str) -> "ListingError":
        return ListingError.at(self.name, self.lines, number, message)

    def read(self) -> dict:
        """The `Listing`'s fields (keyword arguments of `Listing`), every line read."""
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
        return dict(
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
            for option in line.options(("limit", "anisotropic"), "define chemical takes 'limit L' and 'anisotropic'"):
                if option == "limit":
                    limit = line.number("the limit", low=0.0)
                else:
                    anisotropic = True
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
            if self.wrapped is not None:
                line.fail(f"define domain: line {self.wrapped} already made the domain a torus ('wrap')")
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
            for option in line.options(("conc", "diff"), "use chemical takes 'conc C [dev D]' and 'diff F [dev E]'"):
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
            if size[0] * size[1] > MAX_CELLS:
                line.fail(f"a grid of {size[0]} x {size[1]} = {size[0] * size[1]} cells; a listing creates at most "
                          f"{MAX_CELLS} cells")
        elif kind in ("sqr_circle", "hex_circle"):
            size = (line.number("the circle's radius", low=0.0, low_open=True),)
            if size[0] ** 2 * 4 > MAX_CELLS:
                line.fail(f"a circle of radius {size[0]:g} holds about {size[0] ** 2 * 3.1416:.3g} cells; a listing "
                          f"creates at most {MAX_CELLS} cells")
        else:
            size, file = (), line.quoted('the shape\'s file name ("file.txt")')
        options: dict = {}
        allowed = _CREATE_OPTIONS[kind]
        for option in line.options((*allowed, "wrap"), f"create {kind} takes {', '.join(allowed)}"):
            if option == "wrap":
                self.wrap(line, kind, size)
                options["wrap"] = True
            elif option == "at":
                options["at"] = (line.number("the x of 'at'"), line.number("the y of 'at'"))
            elif option == "dev":
                options["dev"] = line.number("the position dev", low=0.0)
            else:
                options["fixed"] = True
        self.commands.append(Create(kind, size, file, line=line.lineno, **options))

    def wrap(self, line: _Line, kind: str, size) -> None:
        """`create sqr_grid COLS ROWS ... wrap` (4.8.3): the domain becomes the torus the
        grid tiles, COLS x ROWS spacings (one per listing; no `define domain` beside it)."""
        if kind != "sqr_grid":
            line.fail(f"'wrap' (a toroidal domain) applies to sqr_grid only, not to create {kind}")
        if "domain" in self.once:
            line.fail(f"'wrap' makes the domain a torus, but line {self.once['domain']} already set the domain")
        self.once["domain"] = self.wrapped = line.lineno
        self.settings["domain"] = Torus(size[0] * SPACING, size[1] * SPACING)

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
        for option in line.options(("chemical", "conc", "diff", "polarity", "fixed"),
                                   "set takes chemical NAME, conc, diff, polarity and fixed"):
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
        with line.checked():
            self.rules.append(Rule(action, tuple(c for _, c, _, _ in chain), start, stop))
        if isinstance(action, Map):
            self.maps.add(action.name)

    def condition(self, line: _Line):
        word = line.take("a condition (always, if or probability)")
        with line.checked():  # a condition's own check (e.g. a probability outside [0, 1])
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
        line.fail(f"expected a condition (always, if or probability), found '{word}'")

    def action(self, line: _Line):
        word = line.take("an action (change, react, divide, map or polarize) or 'and'")
        if word not in ACTIONS:
            line.fail(f"expected an action (change, react, divide, map or polarize) or 'and', found '{word}'")
        with line.checked():  # an action's own check
            return getattr(self, f"action_{word}")(line)

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
                with line.checked():
                    _rgb(colour)
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
        if size[0] * size[1] > MAX_PIXELS:
            line.fail(f"a texture of {size[0]} x {size[1]} pixels; at most {MAX_PIXELS} pixels")
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

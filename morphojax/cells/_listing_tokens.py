"""The line cursor of the experiment language's reader (thesis 4.8): a line split into
tokens (`//` comments stripped, double-quoted strings kept whole), read left to right as
words, numbers, integers, chemical names, rule operands and options, and `ListingError`,
the error that names the listing, the line number and the line. `format_number` writes a
number back as the shortest decimal that reads to the same value. `_listing_read` parses
statements with the cursor and `_listing_write` writes numbers with `format_number`; this
module imports neither (a line reads against any `Context`: the reader is one).
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator, Mapping
from typing import NoReturn, Protocol

import numpy as np

from ._rules import AGE, BIRTH, NEIGHBORS, conc, diff, mapped

FLOAT_MAX = 3.4028234663852886e38  # the largest float32
INT_MAX = 2**31 - 1  # the largest int32

NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
INTEGER = re.compile(r"[+-]?\d+")
IDENTIFIER = re.compile(r"[A-Za-z_]\w*")
TOKEN = re.compile(r'"[^"]*"|\S+')
CELL_VARIABLES = {"AGE": AGE, "BIRTH": BIRTH, "NEIGHBORS": NEIGHBORS}


def format_number(value) -> str:
    """The shortest decimal that reads back to the same value in its own precision (a
    float32 leaf of a rule reads back from "0.0004", not "0.0003999999898951501")."""
    array = np.asarray(value)
    scalar = (array if array.dtype.kind == "f" else array.astype(np.float64)).reshape(())[()]
    magnitude = abs(float(scalar))
    if magnitude != 0 and (magnitude < 1e-6 or magnitude >= 1e15):
        return np.format_float_scientific(scalar, unique=True, trim="-")
    return np.format_float_positional(scalar, unique=True, trim="-")


class ListingError(ValueError):
    """A malformed line of a listing: "<name>:<line>: <what is wrong> (got '<line>')"."""

    @classmethod
    def at(cls, name: str, lines: list[str], number: int, message: str) -> "ListingError":
        got = lines[number - 1].strip() if 0 < number <= len(lines) else ""
        return cls(f"{name}:{number}: {message} (got '{got}')")


class Context(Protocol):
    """What a line is read against: the chemicals and maps defined so far, and the error for
    one of its lines (`_listing_read._Reader` is one)."""

    chemicals: Mapping[str, object]
    maps: set[str]

    def error(self, number: int, message: str) -> ListingError: ...


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

    def __init__(self, reader: Context, number: int, text: str):
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

    def options(self, allowed, takes: str) -> Iterator[str]:
        """The options up to the end of the line, each one of `allowed` at most once; any other
        fails with "unexpected 'X' (<takes>, once each)". The caller reads each one's values."""
        seen = set()
        while self.peek() is not None:
            option = self.take("an option")
            if option not in allowed or option in seen:
                self.fail(f"unexpected '{option}' ({takes}, once each)")
            seen.add(option)
            yield option

    @contextlib.contextmanager
    def checked(self) -> Iterator[None]:
        """A ValueError raised inside (a rule's own check, e.g. a probability outside [0, 1])
        reported as this line's error; a `ListingError` passes as it is."""
        try:
            yield
        except ListingError:
            raise
        except ValueError as err:
            self.fail(str(err))

    # ---- values -------------------------------------------------------------------
    def matching(self, what: str, pattern: re.Pattern, kind: str) -> str:
        """The next token, which must match `pattern` (a `kind`, as the error says)."""
        token = self.take(what)
        if not pattern.fullmatch(token):
            self.fail(f"{what} must be {kind}, found '{token}'")
        return token

    def number(self, what: str, *, low: float | None = None, low_open: bool = False) -> float:
        token = self.matching(what, NUMBER, "a number")
        value = float(token)
        if not abs(value) <= FLOAT_MAX:  # the cells are float32: a larger number (or 1e400 = inf) cannot be held
            self.fail(f"{what} must be a finite number within +-{FLOAT_MAX:.4g}, found {token}")
        if low is not None and (value <= low if low_open else value < low):
            self.fail(f"{what} must be {'>' if low_open else '>='} {format_number(low)}, found {token}")
        return value

    def integer(self, what: str, *, low: int = 0) -> int:
        token = self.matching(what, INTEGER, "an integer")
        value = int(token)
        if value < low:
            self.fail(f"{what} must be >= {low}, found {token}")
        if value > INT_MAX:  # counters and indices are int32
            self.fail(f"{what} must be <= {INT_MAX}, found {token}")
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


__all__ = ["ListingError", "strip_comment"]

"""The line cursor of the experiment language's reader (thesis 4.8): a line split into
tokens (`//` comments stripped, double-quoted strings kept whole), read left to right as
words, numbers, integers, chemical names and rule operands, and `ListingError`, the error
that names the listing, the line number and the line. `_listing_read` parses statements
with it.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, NoReturn

from ._listing_write import _format_number
from ._rules import AGE, BIRTH, NEIGHBORS, conc, diff, mapped

FLOAT_MAX = 3.4028234663852886e38  # the largest float32
INT_MAX = 2**31 - 1  # the largest int32

if TYPE_CHECKING:
    from ._listing_read import _Reader

NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
INTEGER = re.compile(r"[+-]?\d+")
IDENTIFIER = re.compile(r"[A-Za-z_]\w*")
TOKEN = re.compile(r'"[^"]*"|\S+')
CELL_VARIABLES = {"AGE": AGE, "BIRTH": BIRTH, "NEIGHBORS": NEIGHBORS}


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
        if not abs(value) <= FLOAT_MAX:  # the cells are float32: a larger number (or 1e400 = inf) cannot be held
            self.fail(f"{what} must be a finite number within +-{FLOAT_MAX:.4g}, found {token}")
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

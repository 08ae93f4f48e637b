"""The typed errors of mitlc.

Library code raises these and never prints; the CLI renders them (``render``) and exits with
status 1. Every error about a spec carries a :class:`SourceLocation` so it can be shown as
``file:line:col: message``, the source line, and a caret under the column.
"""

from __future__ import annotations

from dataclasses import dataclass


class MitlcError(Exception):
    """Base class of every error mitlc raises on bad input."""

    def render(self) -> str:
        """The text the CLI prints for this error."""
        return str(self)


@dataclass(frozen=True, slots=True)
class SourceLocation:
    """A point in a source text: file name, 1-based line and column, and that line's text."""

    filename: str
    line: int
    column: int
    line_text: str

    def caret(self) -> str:
        """The source line and a caret under the column, each indented by four spaces.

        A line longer than :data:`CARET_WIDTH` is cut to that many characters around the
        column (``...`` marks a cut); characters that do not print (controls, lone surrogates)
        are shown as U+FFFD, so the caret stays under its character."""
        line, column = self.line_text, self.column
        start = 0
        if len(line) > CARET_WIDTH:
            start = max(0, min(column - 1 - CARET_WIDTH // 2, len(line) - CARET_WIDTH))
            line = line[start : start + CARET_WIDTH]
        shown = "".join(c if c.isprintable() or c == "\t" else "\ufffd" for c in line)
        before = "..." if start > 0 else ""
        after = "..." if start + CARET_WIDTH < len(self.line_text) else ""
        prefix = "".join(c if c == "\t" else " " for c in before + shown[: column - 1 - start])
        return f"    {before}{shown}{after}\n    {prefix}^"


CARET_WIDTH = 100
"""The most characters of a source line shown above a caret."""


def locate(text: str, offset: int, filename: str) -> SourceLocation:
    """The location of character ``offset`` (0-based) in ``text``."""
    offset = max(0, min(offset, len(text)))
    line = text.count("\n", 0, offset) + 1
    line_start = text.rfind("\n", 0, offset) + 1
    line_end = text.find("\n", offset)
    if line_end < 0:
        line_end = len(text)
    return SourceLocation(
        filename, line, offset - line_start + 1, text[line_start:line_end].rstrip("\r")
    )


class SpecError(MitlcError):
    """An error in a spec's text, at a known location."""

    def __init__(self, message: str, location: SourceLocation) -> None:
        super().__init__(f"{location.filename}:{location.line}:{location.column}: {message}")
        self.message = message
        self.location = location

    def render(self) -> str:
        loc = self.location
        return f"{loc.filename}:{loc.line}:{loc.column}: {self.message}\n{loc.caret()}"


class SpecSyntaxError(SpecError):
    """The text is not a formula of the grammar (or is not UTF-8, or is empty)."""


class SpecSemanticError(SpecError):
    """The text parses, but means nothing: a reversed, negative or empty interval."""

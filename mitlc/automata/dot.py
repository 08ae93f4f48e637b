"""DOT drawings of a T-LDGBA in the paper's style, and PNG/SVG through Graphviz.

Edges read like the paper's figure: ``a ∧ ¬b ∧ 5 ≤ x0 ≤ 10 / x0 := 0 {0}`` (letters, guard,
resets, acceptance sets). The initial location has an incoming arrow, the satisfied location a
double border, locations of the accepting component a yellow fill, and the rejecting sink is
drawn apart, dashed.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

from mitlc.automata.tldgba import Edge, Tldgba
from mitlc.errors import MitlcError
from mitlc.files import write_atomically
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline, LimitError, SubprocessError, run_within

_SYMBOLS = (("&", "∧"), ("|", "∨"), ("!", "¬"))


class RenderError(MitlcError):
    """Graphviz is missing or failed, or the output format is unknown."""


class DrawingSizeError(RenderError, LimitError):
    """An automaton has more states than a drawing may (``--max-states`` of ``mitlc render``)."""


LAYOUT = "Graphviz's layout"
"""The stage a deadline's message names while Graphviz runs."""

_LAYOUT_CHILD = """
import os, sys
import graphviz
try:
    sys.stdout.buffer.write(graphviz.pipe("dot", sys.argv[1], sys.stdin.buffer.read(), quiet=True))
except graphviz.CalledProcessError as err:
    sys.stderr.buffer.write(err.stderr or str(err).encode())
    sys.stderr.flush()
    if err.returncode < 0:
        os.kill(os.getpid(), -err.returncode)
    sys.exit(err.returncode or 1)
"""
"""The layout's process: the ``graphviz`` package's ``pipe`` of Graphviz's ``dot``, in a Python
of its own so that :func:`mitlc.limits.run_within` holds it and the ``dot`` it starts within
the command's limits (one process group, one memory cap); a ``dot`` killed by a signal kills
it with the same signal."""

_LAID_OUT = ("png", "svg", "pdf")
"""The formats Graphviz lays out (``.dot`` is written as it is)."""


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _pretty_label(text: str) -> str:
    for ascii_op, symbol in _SYMBOLS:
        text = text.replace(ascii_op, symbol)
    return text


def guard_text(automaton: Tldgba, edge: Edge) -> str:
    """``5 ≤ x0 ≤ 10``, ``x0 ≤ 4``, ``x0 ≥ 11`` joined by ``∧`` (clocks stop at their bound)."""
    names = automaton.clock_names
    parts = []
    for c, lo, hi in edge.guard:
        top = hi >= automaton.clock_bounds[c]
        if lo == hi:
            parts.append(f"{names[c]} = {lo}")
        elif lo == 0:
            parts.append(f"{names[c]} ≤ {hi}")
        elif top:
            parts.append(f"{names[c]} ≥ {lo}")
        else:
            parts.append(f"{lo} ≤ {names[c]} ≤ {hi}")
    return " ∧ ".join(parts)


def edge_text(automaton: Tldgba, edge: Edge) -> str:
    """The label of an edge: letters and guard, then resets and acceptance sets."""
    letters = _pretty_label(edge.label.text(automaton.propositions))
    guard = guard_text(automaton, edge)
    if guard:
        letters = f"({letters}) ∧ {guard}" if "∨" in letters else f"{letters} ∧ {guard}"
        letters = letters.removeprefix("true ∧ ")
    text = letters
    if edge.reset:
        text += " / " + ", ".join(f"{automaton.clock_names[c]} := 0" for c in edge.reset)
    if edge.acc:
        text += " {" + ",".join(map(str, edge.acc)) + "}"
    return text


def to_dot(automaton: Tldgba) -> str:
    """The DOT text of ``automaton`` (canonical: same automaton, same text)."""
    lines = [
        "digraph tldgba {",
        "  rankdir=LR;",
        '  node [shape=box, style=rounded, fontname="Helvetica"];',
        '  edge [fontname="Helvetica", fontsize=10];',
        f"  label={_quote(automaton.formula)}; labelloc=t;",
        '  start [shape=point, label=""];',
        f"  start -> q{automaton.initial};",
    ]
    sinks = []
    for loc in automaton.locations:
        attrs = {
            "label": _quote(f"{loc.name}\n{loc.obligation}"),
            "tooltip": _quote(loc.obligation),
        }
        if loc.verdict == "satisfied":
            attrs["peripheries"] = "2"
        if loc.verdict == "violated":
            attrs.update(style='"rounded,dashed"', color="gray40")
            sinks.append(f"q{loc.id}")
        if loc.component == "accepting":
            attrs.update(style='"rounded,filled"', fillcolor="lightyellow")
        body = ", ".join(f"{k}={v}" for k, v in attrs.items())
        lines.append(f"  q{loc.id} [{body}];")
    if sinks:
        lines.append("  { rank=sink; " + "; ".join(sinks) + "; }")
    violated = {loc.id for loc in automaton.locations if loc.verdict == "violated"}
    for edge in automaton.edges:
        style = ", style=dashed, color=gray40" if edge.target in violated else ""
        label = _quote(edge_text(automaton, edge))
        lines.append(f"  q{edge.source} -> q{edge.target} [label={label}{style}];")
    for jump in automaton.epsilon:
        reset = ", ".join(f"{automaton.clock_names[c]} := 0" for c in jump.reset)
        label = _quote("ε" + (f" / {reset}" if reset else ""))
        lines.append(f"  q{jump.source} -> q{jump.target} [label={label}, style=dotted];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def draw(
    automaton: Tldgba,
    path: Path,
    *,
    max_states: int | None = None,
    deadline: Deadline | None = None,
) -> None:
    """Write the drawing of ``automaton`` to ``path`` (:func:`render`), refusing one of more
    than ``max_states`` states (``None``: any) with :class:`DrawingSizeError` before Graphviz
    starts; a ``.dot`` file, which Graphviz does not lay out, is written at any size."""
    fmt = output_format(path)
    states = len(automaton.locations)
    if fmt in _LAID_OUT and max_states is not None and states > max_states:
        raise DrawingSizeError(
            f"the automaton has {states} states, more than --max-states {max_states} that a "
            f"drawing may have (a larger one cannot be read, and Graphviz may take minutes "
            f"over it); raise the limit with a larger --max-states, or write it as text "
            f"(-o FILE.dot, or mitlc compile -f dot)"
        )
    render(to_dot(automaton), path, deadline=deadline)


def output_format(path: Path) -> str:
    """``png``, ``svg``, ``pdf`` or ``dot``, by the suffix of ``path``; :class:`RenderError`
    for any other."""
    suffix = path.suffix.lower().lstrip(".")
    if suffix != "dot" and suffix not in _LAID_OUT:
        raise RenderError(f"{path}: unknown output format '.{suffix}' (use .png, .svg or .dot)")
    return suffix


def render(
    dot: str,
    path: Path,
    *,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    deadline: Deadline | None = None,
) -> None:
    """Write ``dot`` to ``path`` as PNG, SVG, PDF or DOT (by its suffix), atomically.

    Graphviz runs within ``deadline`` when one is given (the time left to it and its memory
    limit, see :func:`mitlc.limits.run_within`), else within ``time_limit`` seconds (``None``:
    none) and the command's memory limit (:func:`mitlc.limits.memory_limit`)."""
    fmt = output_format(path)
    if fmt == "dot":
        data = dot.encode("utf-8")
    else:
        clock = Deadline.of(deadline, time_limit, "render")
        data = graphviz(dot, fmt, clock)
    write_atomically(path, data)


def graphviz(dot: str, fmt: str, deadline: Deadline) -> bytes:
    """``dot`` laid out by Graphviz's ``dot`` program in format ``fmt`` (``png``, ``svg``,
    ``pdf``): the one place mitlc starts Graphviz, within ``deadline``'s time and memory
    (:class:`~mitlc.limits.LimitError` at either; :class:`RenderError` when Graphviz is
    missing or fails)."""
    if shutil.which("dot") is None:
        raise RenderError(
            "Graphviz's `dot` was not found: install Graphviz (e.g. apt-get install graphviz)"
        )
    argv = [sys.executable, "-I", "-c", _LAYOUT_CHILD, fmt]
    try:
        return run_within(argv, dot.encode("utf-8"), deadline.at(LAYOUT), "Graphviz")
    except SubprocessError as err:
        raise RenderError(str(err)) from None
    except OSError as err:
        raise RenderError(f"Graphviz's `dot` could not be started: {err}") from None

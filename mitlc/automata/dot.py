"""DOT drawings of a T-LDGBA in the paper's style, and PNG/SVG through Graphviz.

Edges read like the paper's figure: ``a ∧ ¬b ∧ 5 ≤ x0 ≤ 10 / x0 := 0 {0}`` (letters, guard,
resets, acceptance sets). The initial location has an incoming arrow, the satisfied location a
double border, locations of the accepting component a yellow fill, and the rejecting sink is
drawn apart, dashed.
"""

from __future__ import annotations

from pathlib import Path

from mitlc.automata.tldgba import Edge, Tldgba
from mitlc.errors import MitlcError
from mitlc.files import write_atomically

_SYMBOLS = (("&", "∧"), ("|", "∨"), ("!", "¬"))


class RenderError(MitlcError):
    """Graphviz is missing or failed, or the output format is unknown."""


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


def render(dot: str, path: Path) -> None:
    """Write ``dot`` to ``path`` as PNG, SVG or DOT (by its suffix), atomically."""
    suffix = path.suffix.lower().lstrip(".")
    if suffix == "dot":
        data = dot.encode("utf-8")
    elif suffix in ("png", "svg", "pdf"):
        data = _pipe(dot, suffix)
    else:
        raise RenderError(f"{path}: unknown output format '.{suffix}' (use .png, .svg or .dot)")
    write_atomically(path, data)


def _pipe(dot: str, fmt: str) -> bytes:
    import graphviz

    try:
        data: bytes = graphviz.Source(dot).pipe(format=fmt)
    except graphviz.ExecutableNotFound:
        raise RenderError(
            "Graphviz's `dot` was not found: install Graphviz (e.g. apt-get install graphviz)"
        ) from None
    except graphviz.CalledProcessError as err:
        raise RenderError(f"Graphviz failed: {err}") from None
    return data

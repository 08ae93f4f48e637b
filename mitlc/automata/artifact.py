"""The JSON artifact of a T-LDGBA (``mitlc.tldgba/1``, DESIGN.md "JSON artifact"), both ways.

Output is canonical: sorted keys, stable ids and edge order, so the same input gives
byte-identical text and golden files mean something.
"""

from __future__ import annotations

import json
from typing import Any

from mitlc.automata.labels import Letters, submasks
from mitlc.automata.tldgba import Edge, Jump, Location, Tldgba
from mitlc.errors import MitlcError
from mitlc.syntax import Formula, atoms, parse, to_text

FORMAT = "mitlc.tldgba/1"


class ArtifactError(MitlcError):
    """A JSON artifact that is not a ``mitlc.tldgba/1`` automaton."""


def to_data(automaton: Tldgba) -> dict[str, Any]:
    """The artifact as plain data (see DESIGN.md for every field)."""
    names = automaton.clock_names
    return {
        "format": FORMAT,
        "source": automaton.source,
        "formula": automaton.formula,
        "propositions": list(automaton.propositions),
        "clocks": list(names),
        "clock_bounds": {names[c]: b for c, b in enumerate(automaton.clock_bounds)},
        "acceptance": {"name": "generalized-buchi", "sets": automaton.num_sets},
        "initial": automaton.initial,
        "locations": [
            {
                "id": loc.id,
                "name": loc.name,
                "obligation": loc.obligation,
                "component": loc.component,
                "verdict": loc.verdict,
            }
            for loc in automaton.locations
        ],
        "edges": [
            {
                "source": e.source,
                "target": e.target,
                "label": e.label.text(automaton.propositions),
                "guard": {names[c]: [lo, hi] for c, lo, hi in e.guard},
                "reset": [names[c] for c in e.reset],
                "acc": list(e.acc),
            }
            for e in automaton.edges
        ],
        "epsilon": [
            {"source": j.source, "target": j.target, "reset": [names[c] for c in j.reset]}
            for j in automaton.epsilon
        ],
    }


def to_json(automaton: Tldgba, *, indent: int | None = 2) -> str:
    """The canonical JSON text of the artifact (one line when ``indent`` is None)."""
    separators = (",", ":") if indent is None else (",", ": ")
    text = json.dumps(
        to_data(automaton), indent=indent, sort_keys=True, ensure_ascii=False, separators=separators
    )
    return text + "\n"


def from_data(data: Any) -> Tldgba:
    """Read an artifact back; raises :class:`ArtifactError` on a malformed one."""
    try:
        if data.get("format") != FORMAT:
            raise ArtifactError(f"not a {FORMAT} artifact (format: {data.get('format')!r})")
        propositions = tuple(data["propositions"])
        names = list(data["clocks"])
        clock = {name: c for c, name in enumerate(names)}
        edges = tuple(_edge(e, propositions, clock) for e in data["edges"])
        used: dict[int, set[int]] = {}
        for e in edges:
            used.setdefault(e.source, set()).update(c for c, _, _ in e.guard)
        locations = tuple(
            _location(loc, tuple(sorted(used.get(int(loc["id"]), ())))) for loc in data["locations"]
        )
        return Tldgba(
            source=data["source"],
            formula=data["formula"],
            propositions=propositions,
            clock_bounds=tuple(int(data["clock_bounds"][n]) for n in names),
            num_sets=int(data["acceptance"]["sets"]),
            initial=int(data["initial"]),
            locations=locations,
            edges=edges,
            epsilon=tuple(
                Jump(int(j["source"]), int(j["target"]), tuple(clock[n] for n in j["reset"]))
                for j in data["epsilon"]
            ),
        )
    except ArtifactError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, MitlcError) as err:
        raise ArtifactError(f"malformed {FORMAT} artifact: {type(err).__name__}: {err}") from None


def _location(data: dict[str, Any], clocks: tuple[int, ...]) -> Location:
    if data["component"] not in ("initial", "accepting"):
        raise ValueError(f"component {data['component']!r}")
    if data["verdict"] not in ("satisfied", "violated", "pending"):
        raise ValueError(f"verdict {data['verdict']!r}")
    return Location(
        int(data["id"]),
        str(data["name"]),
        str(data["obligation"]),
        data["component"],
        data["verdict"],
        clocks,
    )


def label_letters(label: Formula, propositions: tuple[str, ...]) -> Letters:
    """The letters satisfying a propositional ``label``: the valuations of the propositions it
    mentions (``2^k`` for ``k`` of them, whatever the alphabet) that make it true."""
    from mitlc.semantics import holds_finite  # only reading artifacts back needs it

    index = {p: i for i, p in enumerate(propositions)}
    unknown = [p for p in atoms(label) if p not in index]
    if unknown:
        raise ValueError(f"label {to_text(label)!r} names {unknown[0]!r}, not a proposition")
    mask = sum(1 << index[p] for p in atoms(label))
    members = [
        sub
        for sub in submasks(mask)
        if holds_finite(label, [frozenset(p for p, i in index.items() if sub >> i & 1)])
    ]
    return Letters.of(mask, members)


def _edge(data: dict[str, Any], propositions: tuple[str, ...], clock: dict[str, int]) -> Edge:
    letters = label_letters(parse(data["label"], "<label>"), propositions)
    guard = tuple(sorted((clock[n], int(lo), int(hi)) for n, (lo, hi) in data["guard"].items()))
    return Edge(
        int(data["source"]),
        int(data["target"]),
        letters,
        guard,
        tuple(clock[n] for n in data["reset"]),
        tuple(int(k) for k in data["acc"]),
    )

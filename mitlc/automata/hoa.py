"""The digital automaton in the Hanoi Omega-Automata format (HOA v1, https://adl.github.io/hoaf/).

:func:`to_hoa` writes a :class:`~mitlc.automata.digital.DigitalAutomaton` as HOA text that Spot
(``spot.automaton``) and the other HOA tools read, with the same language:

* transition-based generalized Büchi acceptance, ``Acceptance: n Inf(0)&...&Inf(n-1)``
  (``acc-name: generalized-Buchi n``, or ``Buchi`` for one set);
* HOA has no epsilon: a jump ``s -> t`` becomes, for every letter, an edge from ``s`` to
  ``t``'s successor on that letter, with its marks (jumps are closed transitively);
* with zero acceptance sets the acceptance is ``t``, under which every infinite run accepts, so
  the violated states are written without outgoing edges: a run that enters one dies;
* the letters of the edges with one source, target and set of marks are merged into one edge
  whose label is their minimal cover (:mod:`mitlc.automata.labels`), made over the classes of
  letters the state (with the states its jumps reach) tells apart, never over all ``2^n``.

The text is canonical: states in id order, edges sorted by target then marks, labels minimised
deterministically. The ``properties`` line claims ``deterministic`` when there are no jumps,
``semi-deterministic`` when the states reachable from an accepting SCC are deterministic (Spot's
definition, checked here rather than assumed) and ``complete`` when no state lacks a letter.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TypeAlias

from mitlc.automata.digital import DigitalAutomaton
from mitlc.automata.graph import strongly_connected
from mitlc.automata.labels import Letters

Edges: TypeAlias = dict[tuple[int, int], Letters]
"""Per state: ``(target, marks) -> letters``."""


def quote(text: str) -> str:
    """A HOA string: double quotes, with backslash before ``"`` and ``\\``."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def letter_edges(automaton: DigitalAutomaton) -> list[Edges]:
    """The epsilon-free edges of every state, letters grouped by ``(target, marks)``, each a
    symbolic letter set (the union of the matching transitions of the state and of the states
    its jumps reach).

    With zero acceptance sets a violated state gets no edges (see the module doc).
    """
    closure = _jump_closure(automaton)
    edges: list[Edges] = []
    for s, state in enumerate(automaton.states):
        out: Edges = {}
        if not (automaton.num_sets == 0 and state.verdict == "violated"):
            for source in closure[s]:
                if automaton.num_sets == 0 and automaton.states[source].verdict == "violated":
                    continue
                for target, marks, letters in automaton.edges(source):
                    found = out.get((target, marks))
                    out[(target, marks)] = letters if found is None else found | letters
        edges.append(out)
    return edges


def _jump_closure(automaton: DigitalAutomaton) -> list[list[int]]:
    """For each state, itself and every state its epsilon jumps reach, ascending."""
    jumps: dict[int, list[int]] = {}
    for s, t in automaton.epsilon:
        jumps.setdefault(s, []).append(t)
    closure = []
    for s in range(len(automaton.states)):
        seen, todo = {s}, [s]
        while todo:
            for t in jumps.get(todo.pop(), []):
                if t not in seen:
                    seen.add(t)
                    todo.append(t)
        closure.append(sorted(seen))
    return closure


def _is_deterministic_at(out: Edges) -> bool:
    labels = list(out.values())
    return all((a & b).is_empty for i, a in enumerate(labels) for b in labels[i + 1 :])


def is_semi_deterministic(edges: list[Edges], initial: int, num_sets: int) -> bool:
    """Spot's semi-determinism of the epsilon-free automaton: every state reachable (from the
    initial state) through an accepting SCC, i.e. one with a cycle whose edges together carry
    every acceptance set, has pairwise disjoint edge labels."""
    reachable = _reach(edges, [initial])
    sccs = _sccs(edges, reachable)
    full = (1 << num_sets) - 1
    starts: list[int] = []
    for scc in sccs:
        members = set(scc)
        inside = [m for s in scc for (t, m) in edges[s] if t in members]
        union = 0
        for m in inside:
            union |= m
        if inside and union == full:
            starts.extend(scc)
    return all(_is_deterministic_at(edges[s]) for s in _reach(edges, starts))


def _reach(edges: list[Edges], starts: Iterable[int]) -> list[int]:
    seen = set(starts)
    todo = list(seen)
    while todo:
        for t, _ in edges[todo.pop()]:
            if t not in seen:
                seen.add(t)
                todo.append(t)
    return sorted(seen)


def _sccs(edges: list[Edges], states: list[int]) -> list[list[int]]:
    """The strongly connected components of the graph restricted to ``states``."""
    position = {state: i for i, state in enumerate(states)}
    successors = [
        sorted({position[t] for t, _ in edges[state] if t in position}) for state in states
    ]
    component = strongly_connected(successors)
    groups: dict[int, list[int]] = {}
    for i, c in enumerate(component):
        groups.setdefault(c, []).append(states[i])
    return [sorted(group) for group in groups.values()]


def _union(out: Edges) -> Letters:
    union = Letters.of(0, ())
    for letters in out.values():
        union = union | letters
    return union


def to_hoa(automaton: DigitalAutomaton, name: str | None = None) -> str:
    """The HOA v1 text of ``automaton`` (module doc); ``name`` defaults to the formula text."""
    edges = letter_edges(automaton)
    n = automaton.num_sets
    props = ["trans-labels", "explicit-labels", "trans-acc"]
    if all(_union(out).is_everything for out in edges):
        props.append("complete")
    if automaton.is_deterministic:
        props.append("deterministic")
    elif is_semi_deterministic(edges, automaton.initial, n):
        props.append("semi-deterministic")
    lines = [
        "HOA: v1",
        f"name: {quote(automaton.formula if name is None else name)}",
        f"States: {len(automaton.states)}",
        f"Start: {automaton.initial}",
        " ".join([f"AP: {len(automaton.propositions)}", *map(quote, automaton.propositions)]),
    ]
    if n == 0:
        lines += ["acc-name: all", "Acceptance: 0 t"]
    else:
        lines.append("acc-name: Buchi" if n == 1 else f"acc-name: generalized-Buchi {n}")
        lines.append(f"Acceptance: {n} " + "&".join(f"Inf({k})" for k in range(n)))
    lines += ["properties: " + " ".join(props), "--BODY--"]
    labels: dict[Letters, str] = {}  # many edges share a letter set
    for s, out in enumerate(edges):
        lines.append(f"State: {s}")
        for target, marks in sorted(out):
            letters = out[(target, marks)]
            if letters not in labels:
                labels[letters] = letters.text(automaton.propositions, "hoa")
            label = labels[letters]
            sets = [str(k) for k in range(n) if marks >> k & 1]
            acc = " {" + " ".join(sets) + "}" if sets else ""
            lines.append(f"[{label}] {target}{acc}")
    lines.append("--END--")
    return "\n".join(lines) + "\n"


def to_hoa_stream(automata: Iterable[DigitalAutomaton]) -> str:
    """Several automata, one after the other, each ending with ``--END--`` (HOA allows this;
    ``spot.automata`` reads them back in turn)."""
    return "".join(to_hoa(automaton) for automaton in automata)

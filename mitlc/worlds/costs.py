"""A world's costs (``costs:`` in a world file), validated: :class:`Costs`.

Costs are paid on the steps of an episode, beside its success (docs/costs.md); a negative
cost is a reward. Four kinds, all added up:

* ``step``: every step;
* ``actions``: every step that takes the named world action;
* ``propositions``: a step that arrives in a position where the proposition holds pays its
  ``hold`` cost, and its ``start`` cost too when the proposition did not hold in the position
  the step left (the start position is arrived in by no step: it pays nothing);
* ``transitions``: a step whose automaton transition matches a rule pays the rule's cost: its
  source state is an instance of the obligation ``from`` (a location of the T-LDGBA, as
  ``mitlc compile`` prints it: :mod:`mitlc.automata.patterns`; every state when left out), the
  letter it reads (that of the position the step leaves) satisfies ``when``, and, when ``to``
  is given, its target state is an instance of ``to``. Epsilon jumps pay nothing.

The shape of the section is checked by :class:`mitlc.worlds.schema.CostsSection`; what needs the
rest of the file (the propositions among the labels, the obligations' propositions among the
task's, the actions among the world's) is checked here (:func:`read_costs`), every problem
named by its field's path. What is paid on each product transition is computed by
:func:`mitlc.product.costs.product_costs`, the one definition the checker and the learners read.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mitlc.errors import SpecError

if TYPE_CHECKING:
    from mitlc.worlds.grid import FieldPath
    from mitlc.worlds.schema import CostsSection


@dataclass(frozen=True, slots=True)
class PropositionCost:
    """What a step arriving where ``proposition`` holds pays: ``hold`` always, ``start`` when
    it did not hold where the step came from."""

    proposition: str
    hold: float = 0.0
    start: float = 0.0


@dataclass(frozen=True, slots=True)
class TransitionCost:
    """A rule pricing automaton transitions (see the module docstring)."""

    source: str | None
    """The ``from`` obligation's text; ``None``: every state."""
    when: str
    """A letter formula over the world's propositions (``true``: every letter)."""
    target: str | None
    """The ``to`` obligation's text; ``None``: any target."""
    cost: float
    where: str = ""
    """Where the rule is written (``world.yaml:12:5: costs.transitions[0]``), for errors."""


@dataclass(frozen=True, slots=True)
class Costs:
    """A world's costs (see the module docstring)."""

    step: float = 0.0
    actions: tuple[tuple[str, float], ...] = ()
    """``(action name, cost)`` pairs."""
    propositions: tuple[PropositionCost, ...] = ()
    transitions: tuple[TransitionCost, ...] = ()

    def atoms(self) -> set[str]:
        """The world propositions the costs read: those priced, and those of each ``when``."""
        from mitlc.automata.patterns import letter_formula
        from mitlc.syntax import atoms

        found = {p.proposition for p in self.propositions}
        for rule in self.transitions:
            found |= set(atoms(letter_formula(rule.when)))
        return found


Found = list[tuple["FieldPath", str, str]]
"""Problems: (the field's path, the message, a detail such as a spec error's caret)."""


def read_costs(
    section: CostsSection,
    labels: Collection[str],
    task: Collection[str],
    actions: Sequence[str] | None,
    where: Callable[[FieldPath], str],
) -> tuple[Costs, Found]:
    """The costs of a checked ``costs:`` section and what is wrong with them: a priced
    proposition or one read by a ``when`` that is not among the ``labels``, an obligation that
    does not parse or names a proposition that is not in the ``task``, a ``when`` that is not
    a letter formula, an action not among ``actions`` (``None``: not known yet, see
    :func:`action_problems`). ``where(path)`` says where a field is written."""
    found: Found = []
    known = ", ".join(sorted(labels)) or "none"
    props = []
    for name, entry in section.propositions.items():
        path: FieldPath = ("costs", "propositions", name)
        if name not in labels:
            found.append((path, f"unknown proposition {name!r} (labels: {known})", ""))
        props.append(PropositionCost(name, entry.hold, entry.start))
    rules = []
    for i, rule in enumerate(section.transitions):
        path = ("costs", "transitions", i)
        for key, text in (("from", rule.source), ("to", rule.to)):
            if text is not None:
                found.extend(_obligation_problems((*path, key), text, task))
        found.extend(_letter_problems((*path, "when"), rule.when, labels, known))
        rules.append(TransitionCost(rule.source, rule.when, rule.to, rule.cost, where(path)))
    costs = Costs(
        step=section.step,
        actions=tuple(section.actions.items()),
        propositions=tuple(props),
        transitions=tuple(rules),
    )
    if actions is not None:
        found.extend(action_problems(costs, actions))
    return costs, found


def action_problems(costs: Costs, actions: Sequence[str]) -> Found:
    """Each priced action that the world does not have."""
    names = ", ".join(actions)
    return [
        (("costs", "actions", name), f"unknown action {name!r} (actions: {names})", "")
        for name, _ in costs.actions
        if name not in actions
    ]


def _obligation_problems(path: FieldPath, text: str, task: Collection[str]) -> Found:
    from mitlc.automata.patterns import ObligationPattern
    from mitlc.worlds.grid import render

    try:
        pattern = ObligationPattern.parse(text, render(path))
    except SpecError as err:
        return [(path, "the obligation does not parse", err.render())]
    extra = sorted(pattern.atoms() - set(task))
    if extra:
        names = ", ".join(sorted(task)) or "none"
        message = f"proposition {extra[0]!r} is not in the task (its propositions: {names})"
        return [(path, message, "")]
    return []


def _letter_problems(path: FieldPath, text: str, labels: Collection[str], known: str) -> Found:
    from mitlc.automata.patterns import letter_formula
    from mitlc.syntax import atoms
    from mitlc.worlds.grid import render

    try:
        formula = letter_formula(text, render(path))
    except SpecError as err:
        return [(path, "the letter formula does not parse", err.render())]
    except ValueError as err:
        return [(path, str(err), "")]
    unknown = [p for p in atoms(formula) if p not in labels]
    if unknown:
        return [(path, f"unknown proposition {unknown[0]!r} (labels: {known})", "")]
    return []

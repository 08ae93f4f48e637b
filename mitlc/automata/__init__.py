"""MITL to automata: the digital LDGBA (ground truth), its folding and its emitters."""

from dataclasses import dataclass
from types import EllipsisType
from typing import TYPE_CHECKING, Any

from mitlc.automata.digital import DigitalAutomaton, DigitalState
from mitlc.automata.fold import fold
from mitlc.automata.ldba import StateLimitError, TranslationError, translate, translate_terms
from mitlc.automata.tldgba import Tldgba
from mitlc.limits import DEFAULT_MAX_STATES, DEFAULT_TIME_LIMIT, Deadline, collector_paused
from mitlc.syntax import Formula

if TYPE_CHECKING:
    from mitlc.automata.lazy import LazyAutomaton


def __getattr__(name: str) -> Any:
    """``LazyAutomaton`` is imported on first use (``mitlc compile`` does not need it)."""
    if name == "LazyAutomaton":
        from mitlc.automata.lazy import LazyAutomaton

        return LazyAutomaton
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass(frozen=True, slots=True)
class Compiled:
    """A compiled formula: the digital automaton and its folded T-LDGBA."""

    digital: DigitalAutomaton
    timed: Tldgba


def compile_formula(
    formula: Formula,
    *,
    max_states: int = DEFAULT_MAX_STATES,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
) -> Compiled:
    """Translate ``formula`` to its digital LDGBA and fold it into a T-LDGBA.

    Both stages cost time linear in the states built (the guards: ``n log n``). They stop with
    :class:`StateLimitError` past ``max_states`` digital states, and with
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held (``None``: no limit) or at
    ``deadline`` when one is given (a clock the caller shares with its other stages)."""
    clock = Deadline.of(deadline, time_limit, "compile", memory_limit)
    translation = translate_terms(formula, max_states=max_states, deadline=clock)
    with collector_paused():
        timed = fold(translation, deadline=clock.at("folding"))
    return Compiled(translation.automaton, timed)


__all__ = [
    "DEFAULT_MAX_STATES",
    "Compiled",
    "DigitalAutomaton",
    "DigitalState",
    "LazyAutomaton",
    "StateLimitError",
    "Tldgba",
    "TranslationError",
    "compile_formula",
    "translate",
]

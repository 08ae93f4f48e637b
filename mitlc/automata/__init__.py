"""MITL to automata: the digital LDGBA (ground truth), its folding and its emitters."""

from dataclasses import dataclass

from mitlc.automata.digital import DigitalAutomaton, DigitalState
from mitlc.automata.fold import fold
from mitlc.automata.ldba import TranslationError, translate, translate_terms
from mitlc.automata.tldgba import Tldgba
from mitlc.syntax import Formula

DEFAULT_MAX_STATES = 1_000_000


@dataclass(frozen=True, slots=True)
class Compiled:
    """A compiled formula: the digital automaton and its folded T-LDGBA."""

    digital: DigitalAutomaton
    timed: Tldgba


def compile_formula(formula: Formula, *, max_states: int = DEFAULT_MAX_STATES) -> Compiled:
    """Translate ``formula`` to its digital LDGBA and fold it into a T-LDGBA."""
    translation = translate_terms(formula, max_states=max_states)
    return Compiled(translation.automaton, fold(translation))


__all__ = [
    "DEFAULT_MAX_STATES",
    "Compiled",
    "DigitalAutomaton",
    "DigitalState",
    "Tldgba",
    "TranslationError",
    "compile_formula",
    "translate",
]

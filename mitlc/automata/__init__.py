"""MITL to automata: the digital LDGBA (ground truth), its folding and its emitters."""

from mitlc.automata.digital import DigitalAutomaton, DigitalState
from mitlc.automata.ldba import TranslationError, translate

__all__ = ["DigitalAutomaton", "DigitalState", "TranslationError", "translate"]

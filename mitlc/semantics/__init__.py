"""The reference semantics of MITL: exact truth on finite traces and on lassos.

The oracle every later stage (automata, product checker, learner) is tested against.
:mod:`mitlc.semantics.finite` follows rtamt's discrete-time offline conventions at the end of a
finite trace; :mod:`mitlc.semantics.lasso` evaluates infinite ultimately periodic words exactly.
"""

from mitlc.semantics.episode import episode_formula, episode_success
from mitlc.semantics.finite import (
    Letter,
    SemanticsError,
    Timeline,
    Truth,
    evaluate_finite,
    evaluate_on,
    holds_finite,
)
from mitlc.semantics.lasso import Lasso, evaluate_lasso, holds_lasso

__all__ = [
    "Lasso",
    "Letter",
    "SemanticsError",
    "Timeline",
    "Truth",
    "episode_formula",
    "episode_success",
    "evaluate_finite",
    "evaluate_lasso",
    "evaluate_on",
    "holds_finite",
    "holds_lasso",
]

"""What a state owes when the trace ends: the value of an obligation on the empty suffix.

A state of the digital automaton after ``n`` letters is the obligation ``φ_n`` that the rest of
the word must satisfy (formula progression, :mod:`mitlc.automata.progress`). When an episode
stops there, the task is judged on the finite trace it read, by the finite-trace semantics of
:mod:`mitlc.semantics.finite` (LTLf with windows: ``X``, ``F``, ``U`` strong, ``G``, ``R`` weak;
De Giacomo and Vardi, IJCAI 2013). Progression turns that into a property of ``φ_n`` alone, its
value on the empty suffix (:meth:`mitlc.automata.terms.TermStore.end_value`), read atom by atom:

* a pending ``F`` or ``U`` atom fails: a window that has not closed, a strong delay
  ``F[k,k] ψ`` (``X^k ψ``: a letter the trace never reached), a strong point ``F[0,0] ψ``;
* a pending ``G`` or ``R`` atom holds: a window that has not closed, a weak delay
  ``G[k,k] ψ`` (``G[k,k] ψ`` and ``!X ψ`` hold when the trace ends first), a weak point;
* a literal, a letter the trace never reached, does not hold.

Progression keeps the difference until the delayed letter is read
(:meth:`mitlc.automata.terms.TermStore.point`), and folds a constant inside a window only where
that holds on finite traces too (``F[2,4] true`` is ``F[2,2] true``, three letters), so the end
value is exact: no departure from :mod:`mitlc.semantics.finite`.

What a stop is worth (the end code of :attr:`mitlc.automata.DigitalState.end`, read by
:func:`mitlc.task.rules.success`): :data:`END_FAILS`, or :func:`holds_after` a mask of
acceptance sets, which the episode must have seen (:data:`END_HOLDS`: none).

* An initial-component state: its obligation's end value.
* A recurrence state (``S & C & G χ``, :mod:`mitlc.automata.recurrence`): the end value of
  ``S``, ``C`` and every pending token of a recurrence that is not eventual (a request of
  ``G (a -> F b)`` not answered fails), but not of the ``G χ`` themselves nor of an eventual
  recurrence's tokens, once the eventual recurrences' sets have been seen: ``G F β`` owes one
  ``β`` and ``G F (a & F b)`` one ``a`` then ``b``, not a completion at the last letter.
* A state of the accepting component (after an epsilon jump), a guess proved by completed
  rounds: its safety part's end value (a deadline still open fails there too), once every set
  has been seen (a round completed); its recurrences' pending tokens are the renewed
  obligations and are not owed.
"""

from __future__ import annotations

END_FAILS, END_HOLDS = 0, 1
"""The end codes of a state where a stop fails, and where it succeeds whatever was seen."""


def holds_after(sets: int) -> int:
    """The end code of a state where a stop succeeds once every acceptance set of the mask
    ``sets`` has been seen (:data:`END_HOLDS` for none)."""
    return 1 + sets

"""What a state owes when the trace ends: the value of an obligation on the empty suffix.

A state of the digital automaton after ``n`` letters is the obligation ``φ_n`` that the rest of
the word must satisfy (formula progression, :mod:`mitlc.automata.progress`). When an episode
stops there, the task is judged on the finite trace it read, by the finite-trace semantics of
:mod:`mitlc.semantics.finite` (rtamt's conventions: positions past the end are neutral, so a
window of ``F``/``U`` that has not closed fails and one of ``G``/``R`` holds). Progression
turns that into a property of ``φ_n`` alone, its value on the empty suffix
(:func:`end_value`), read atom by atom:

* a pending ``F`` or ``U`` window (``F[0,0]`` and ``U[0,0]``, a window's last step, included)
  is not met: ``false``; a pending ``G`` or ``R`` window is not broken: ``true``;
* a *delay* ``F[k,k] ψ`` with ``k > 0`` is ``ψ`` on the empty suffix (a delay ends in ``ψ``
  itself, :meth:`mitlc.automata.terms.TermStore.delay`), so ``F[a,inf) p = X^a F p`` fails and
  ``G[a,inf) p = X^a G p`` holds, as their windows say;
* a literal, a letter the trace never reached, does not hold: ``false``.

The one departure from :mod:`mitlc.semantics.finite` is at a next-step obligation on a letter
that was never read. On infinite words ``X p``, ``F[k,k] p`` and ``G[k,k] p`` are one formula,
and the normal forms keep one of them (a delay), so the state cannot tell the weak reading
(``X p`` and ``G[k,k] p`` hold past the end) from the strong one (``F[k,k] p`` fails there): it
takes the strong one, and never counts a success from a letter that was not read. So ``X p``,
``G[k,k] p`` and ``X F[...]`` still open at the end fail, and so does a window whose constant
operand was folded away (``F[2,4] true`` is ``true``; ``G[2,4] false`` is ``false``).

A state of the accepting component (after an epsilon jump) is a guess about the infinite
future, proved only by completed rounds: its value at the end is ``false``, so a jump taken at
the end of an episode can never make it a success. A recurrence state (``S & C & G χ``) owes
its obligation (:meth:`mitlc.automata.recurrence.Recurrence.obligation`).
"""

from __future__ import annotations

from mitlc.automata.terms import EVENTUALLY, LIT, UNTIL, TermStore


def end_value(store: TermStore, form: int, memo: dict[int, bool] | None = None) -> bool:
    """Whether the obligation ``form`` holds on the empty suffix (see the module docstring):
    some cube whose every atom does."""
    memo = {} if memo is None else memo
    found = memo.get(form)
    if found is None:
        found = memo[form] = any(
            all(_atom_end(store, atom, memo) for atom in cube) for cube in store.forms[form]
        )
    return found


def _atom_end(store: TermStore, atom: int, memo: dict[int, bool]) -> bool:
    kind, lo, hi, operand, _ = store.atoms[atom]
    if kind in (LIT, UNTIL):
        return False
    if kind == EVENTUALLY:
        return lo == hi and lo > 0 and end_value(store, operand, memo)
    return True  # G, R: the window holds

"""The reference semantics of MITL on lassos: the ultimately periodic words ``u v^omega``.

The definitions are those of :mod:`mitlc.semantics.finite`, on an infinite word, so there is no
end-of-trace convention: ``X q`` at the last letter of the loop looks at the loop's first letter.
The truth of any formula on ``u v^omega`` is periodic from ``len(u)`` on with period ``len(v)``,
so it is computed exactly at the ``len(u) + len(v)`` canonical positions, in time linear in that
number per subformula whatever the intervals' bounds (``[0,1000]`` and ``[500,inf)`` included).
"""

from __future__ import annotations

from dataclasses import dataclass

from mitlc.semantics.finite import Letter, SemanticsError, Timeline, Truth, evaluate_on
from mitlc.syntax import ast


@dataclass(frozen=True, slots=True)
class Lasso:
    """The infinite word ``prefix loop loop loop ...``; ``loop`` must not be empty.

    Positions ``0 .. len(prefix) + len(loop) - 1`` are canonical; any later position is the
    canonical one it repeats (period ``len(loop)`` from ``len(prefix)`` on).
    """

    prefix: tuple[Letter, ...]
    loop: tuple[Letter, ...]

    def __post_init__(self) -> None:
        if not self.loop:
            raise SemanticsError("the loop of a lasso needs at least one letter")

    @property
    def size(self) -> int:
        """The number of canonical positions, ``len(prefix) + len(loop)``."""
        return len(self.prefix) + len(self.loop)

    @property
    def letters(self) -> tuple[Letter, ...]:
        """The letters at the canonical positions: ``prefix + loop``."""
        return self.prefix + self.loop

    @property
    def timeline(self) -> Timeline:
        """The canonical positions, the last followed by the loop's start."""
        return Timeline(self.size, len(self.prefix))

    def canonical(self, position: int) -> int:
        """The canonical position that ``position >= 0`` repeats.

        Raises :class:`SemanticsError` for a negative position.
        """
        if position < 0:
            raise SemanticsError(f"position {position} is negative")
        canonical = self.timeline.canonical(position)
        assert canonical is not None  # a lasso's timeline never ends
        return canonical

    def letter(self, position: int) -> Letter:
        """The letter at ``position >= 0``."""
        canonical = self.canonical(position)
        if canonical < len(self.prefix):
            return self.prefix[canonical]
        return self.loop[canonical - len(self.prefix)]

    def unroll(self, length: int) -> tuple[Letter, ...]:
        """The first ``length`` letters of the word, a finite trace."""
        return tuple(self.letter(i) for i in range(length))


def evaluate_lasso(formula: ast.Formula, lasso: Lasso) -> Truth:
    """The exact truth of ``formula`` at each canonical position ``0 .. lasso.size - 1``.

    Pointwise discrete-time semantics on the infinite word (``p U_I q`` at ``i``: some ``j`` with
    ``j - i`` in ``I`` has ``q``, and ``p`` holds on ``[i, j)``; ``F``, ``G``, ``R`` and ``X`` as
    in :mod:`mitlc.semantics.finite`, with no end). For ``U_I`` only the earliest ``j >= i + lo``
    with ``q`` is a candidate; it is found from the distances to the next ``q`` at the canonical
    positions, which equals a scan of ``j`` up to ``min(i + hi, max(i + lo, len(prefix)) +
    len(loop) - 1)``, in O(1) per position.
    """
    return evaluate_on(formula, lasso.letters, lasso.timeline)


def holds_lasso(formula: ast.Formula, lasso: Lasso, position: int = 0) -> bool:
    """Whether ``(lasso, position) |= formula`` for any ``position >= 0`` (see
    :func:`evaluate_lasso`). Raises :class:`SemanticsError` for a negative position.
    """
    return evaluate_lasso(formula, lasso)[lasso.canonical(position)]

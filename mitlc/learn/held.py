"""Labels that never held: the task's propositions that no letter read in a whole run (or
evaluation) of a world learned through the task wrapper made true.

A proposition that never holds in hundreds of thousands of episodes is almost always a
mistaken label (a wrong attribute value, an ``info`` key that is never set, a region nobody can
reach), and the run then ends ``violated`` with no other hint. Each
:class:`mitlc.gym.TaskWrapper` or-s the letters it reads into ``held``; this module folds those
of a vector of wrapped envs and names the propositions left out. Finite worlds need none of
it: there, a proposition that holds in no state is refused when the world is loaded.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mitlc.learn.evaluation.montecarlo import Batches
    from mitlc.learn.learners.base import Episodes


def held_of(envs: Iterable[Any]) -> int:
    """The letters held in ``envs`` (task wrappers, or anything wrapping one), or-ed."""
    mask = 0
    for env in envs:
        while env is not None and not hasattr(env, "held"):
            env = getattr(env, "env", None)
        mask |= int(getattr(env, "held", 0) or 0)
    return mask


def never_held(propositions: Sequence[str], mask: int) -> tuple[str, ...]:
    """The propositions whose bit is not in ``mask`` (bit ``i``: ``propositions[i]``)."""
    return tuple(p for i, p in enumerate(propositions) if not mask >> i & 1)


def run_never_held(
    finite: bool, propositions: Sequence[str], envs: Iterable[Any]
) -> tuple[str, ...]:
    """A run's propositions that never held in its wrapped ``envs`` (none on a finite world,
    which refuses a proposition that holds in no state when it is loaded)."""
    return () if finite else never_held(propositions, held_of(envs))


def never_held_note(names: Sequence[str], episodes: int, steps: int | None = None) -> str:
    """One line for the user: which labels never held, over how many episodes."""
    listed = ", ".join(f"`{p}`" for p in names)
    what = "label" if len(names) == 1 else "labels"
    over = f"{episodes:,} episodes" + (f" ({steps:,} steps)" if steps is not None else "")
    return (f"{what} {listed} never held in {over}: check {'its' if len(names) == 1 else 'their'} "
            "declaration in the world file (a wrong value, an info key never set, a region "
            "out of reach)")  # fmt: skip


class HeldLog:
    """The letters held over many batches of wrapped envs: :meth:`track` wraps a maker of
    batches (``(count, first) -> a vector of wrapped envs``) and folds each batch's letters in
    when the next is made, so no batch is kept alive."""

    def __init__(self) -> None:
        self.mask = 0
        self._last: Any = None

    def track(self, make: Batches) -> Batches:
        """``make``, with each batch it makes recorded."""

        def tracked(count: int, first: int) -> Episodes:
            self._fold()
            self._last = batch = make(count, first)
            return batch

        return tracked

    def held(self) -> int:
        """The letters held in every batch made so far, or-ed."""
        self._fold()
        return self.mask

    def _fold(self) -> None:
        if self._last is not None:
            self.mask |= held_of(getattr(self._last, "envs", ()))
            self._last = None

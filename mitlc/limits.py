"""The limits that bound mitlc's work on any input, and the clock that enforces time limits.

Every computation whose cost depends on its input has a stop: a size limit checked before or
while the work is done (states, product size, nesting depth, text size), and for the long ones
a time limit. Each ends in a :class:`LimitError` whose message says which limit was hit and how
to raise it. The values are documented in the README ("Limits").
"""

from __future__ import annotations

import time

from mitlc.errors import MitlcError

DEFAULT_TIME_LIMIT = 600.0
"""Seconds a compile, check or POMDP bound may run before it stops (``--time-limit``)."""


class LimitError(MitlcError):
    """A computation stopped at one of mitlc's limits (the message names it)."""


class Deadline:
    """A time limit for one computation: :meth:`check` raises :class:`LimitError` once
    ``seconds`` have passed since the deadline was made (``None`` or 0: no limit).

    ``what`` names the computation and ``how`` says how to raise the limit, e.g.
    ``Deadline(60, "compile", "--time-limit SECONDS (0 for none)")``. :meth:`check` reads the
    clock only every ``every`` calls, so it is cheap in an inner loop.
    """

    __slots__ = ("_calls", "_end", "every", "how", "seconds", "what")

    def __init__(
        self,
        seconds: float | None,
        what: str,
        how: str = "--time-limit SECONDS (0 for none)",
        *,
        every: int = 256,
    ) -> None:
        self.seconds = seconds if seconds else None
        self.what, self.how, self.every = what, how, max(1, every)
        self._end = None if self.seconds is None else time.monotonic() + self.seconds
        self._calls = 0

    @classmethod
    def none(cls) -> Deadline:
        """A deadline that never passes."""
        return cls(None, "")

    def check(self) -> None:
        """Raise :class:`LimitError` when the time is up (the clock is read every ``every``
        calls)."""
        if self._end is None:
            return
        self._calls += 1
        if self._calls % self.every == 0:
            self.check_now()

    def check_now(self) -> None:
        """Raise :class:`LimitError` when the time is up (reads the clock now)."""
        if self._end is not None and time.monotonic() > self._end:
            raise LimitError(
                f"{self.what} stopped at the time limit of {self.seconds:g} s; raise it with "
                f"{self.how}"
            )

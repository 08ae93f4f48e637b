"""The memory limit of a command (``--memory-limit GB``): every command takes it, and a
watchdog stops the process where the library's own checks cannot.

The library looks at the process's resident size inside its long loops
(:meth:`mitlc.limits.Deadline.check_now`) and stops with a one-line
:class:`~mitlc.limits.LimitError` that names the stage. Some memory is taken where no loop of
mitlc's runs: one call into numpy, torch or a simulator. The watchdog, a daemon thread that
reads the resident size every :data:`WATCH_SECONDS`, ends the process with the same kind of
line and exit status 1 once it holds :data:`WATCHDOG_MARGIN` times the limit: the library's
checks, at the limit itself, get the first chance to stop cleanly. Files a command writes are
written atomically (:func:`mitlc.files.write_atomically`), so what it wrote before stays whole.
"""

from __future__ import annotations

import functools
import inspect
import os
import sys
import threading
from collections.abc import Callable
from typing import Annotated, Any

import typer

from mitlc.limits import (
    CLI_MEMORY_HOW,
    DEFAULT_MEMORY_LIMIT,
    GB,
    Deadline,
    memory_setting,
    resident_bytes,
    set_memory_limit,
)

WATCH_SECONDS = 0.05
"""How often the watchdog reads the resident size (a few microseconds each time)."""

WATCHDOG_MARGIN = 1.05
"""The watchdog stops the process at this many times the limit, within the promised 10%."""

MemoryLimitOpt = Annotated[
    float,
    typer.Option(
        "--memory-limit",
        min=0,
        metavar="GB",
        help="Stop the command once the process holds this many GB of memory (0: no limit).",
    ),
]


def with_memory_limit(command: Callable[..., Any]) -> Callable[..., Any]:
    """``command`` with a ``--memory-limit GB`` option (default
    :data:`~mitlc.limits.DEFAULT_MEMORY_LIMIT`) that sets the limit of every deadline the
    command makes and watches the process while it runs."""
    signature = inspect.signature(command)
    name = "mitlc " + command.__name__.removesuffix("_command")  # the commands' naming
    option = inspect.Parameter(
        "memory_limit",
        inspect.Parameter.KEYWORD_ONLY,
        default=round(DEFAULT_MEMORY_LIMIT, 1),
        annotation=MemoryLimitOpt,
    )

    @functools.wraps(command)
    def wrapper(*args: Any, memory_limit: float = DEFAULT_MEMORY_LIMIT, **kwargs: Any) -> Any:
        before = memory_setting()
        set_memory_limit(memory_limit, CLI_MEMORY_HOW)
        watchdog = _Watchdog(memory_limit, name) if memory_limit else None
        try:
            return command(*args, **kwargs)
        finally:
            if watchdog is not None:
                watchdog.stop()
            set_memory_limit(*before)

    wrapper.__signature__ = signature.replace(  # type: ignore[attr-defined]
        parameters=[*signature.parameters.values(), option]
    )
    return wrapper


class _Watchdog:
    """A daemon thread that ends the process once it holds ``WATCHDOG_MARGIN`` times
    ``limit`` GB (see the module docstring)."""

    def __init__(self, limit: float, command: str = "mitlc") -> None:
        self.limit = limit
        self.command = command
        self._stopped = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="mitlc-memory", daemon=True)
        self._thread.start()

    def _watch(self) -> None:
        threshold = self.limit * GB * WATCHDOG_MARGIN
        while not self._stopped.wait(WATCH_SECONDS):
            resident = resident_bytes()
            if resident > threshold:  # the library's own message, without a stage
                error = Deadline(None, self.command, memory=self.limit).memory_error(resident)
                sys.stderr.write(f"{error}\n")
                sys.stderr.flush()
                os._exit(1)

    def stop(self) -> None:
        self._stopped.set()


_stopped: list[bool] = [False]
"""Whether the command stopped at a limit (:func:`stopped_at_a_limit`)."""


def stopped_at_a_limit() -> None:
    """Note that the command stopped at its time or memory limit, so that :func:`exit_now`
    ends the process without tearing down what the stopped work built."""
    _stopped[0] = True


def exit_now(code: int) -> None:
    """End the process with ``code`` at once where the command stopped at a limit.

    What the stopped work built (a translation of millions of small objects, some in reference
    cycles) would otherwise be torn down by the interpreter at exit: a second and more past the
    limit, which the limit promises not to take. Output is flushed first; nothing is left to
    write (files are written atomically, and a stopped stage writes none)."""
    if _stopped[0] and code:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)

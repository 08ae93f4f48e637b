"""The limits that bound mitlc's work on any input, and the clock that enforces time limits.

Every computation whose cost depends on its input has a stop: a size limit checked before or
while the work is done (states, product size, nesting depth, text size), and for the long ones
a time limit. Each ends in a :class:`LimitError` whose message says which limit was hit and how
to raise it. The values are documented in the README ("Limits").
"""

from __future__ import annotations

import gc
import os
import resource
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from types import EllipsisType
from typing import TYPE_CHECKING

from mitlc.errors import MitlcError

if TYPE_CHECKING:
    import subprocess

DEFAULT_TIME_LIMIT = 60.0
"""Seconds a compile, check or POMDP bound may run before it stops (``--time-limit``).

A minute: the paper's checks take under a second, the whole check of a 100x100 grid about
20 s and ``F[0,100000] a`` compiles in a few seconds, while a runaway translation (``F[0,1000]
G[0,1000] a``, about a million states of hundreds of atoms each) holds 3 GB after a minute."""

DEFAULT_MAX_STATES = 1_000_000
"""The most digital states a translation builds before it stops (``--max-states``; the
``max_states`` of :func:`mitlc.automata.compile_formula`)."""

DEFAULT_MAX_DRAWN_STATES = 100
"""The most states ``mitlc render`` draws through Graphviz (its ``--max-states``), checked before
Graphviz starts.

The largest automaton of ``bench/formulas.txt`` and the paper's specs has 87 states (case 2,
``G F[5,10] a & G F[15,20] b``: laid out in 0.4 s), while a drawing of more than a hundred boxes
cannot be read. Graphviz's layout time depends on the edges more than on the states: nested
windows (``F[0,5] F[0,5] ... a``, 5 edges a state) took 5 s at 41 states, 56 s at 49 and more
than 100 s at 61 (measured on this 2-core machine), so the time limit stops what this cap lets
through (:func:`run_within`)."""

DEFAULT_MAX_PRODUCT_STATES = 8_000_000
"""The largest product (its bound ``S * Q`` on the states) built by default
(``--max-product-states``): a product of a million reachable states takes about 2 GB to check,
so the default keeps a check within about 16 GB; the 100x100 grid of ``make bench-check``
(bound 5.0 million, 3.0 million reachable) is within it."""

LIBRARY_HOW = "the time_limit argument (seconds; None for none)"
"""How a library caller raises a time limit (the command line says ``--time-limit``)."""

CLI_HOW = "--time-limit SECONDS (0 for none)"
"""How the command line raises a time limit."""

GB = 1_000_000_000
"""Bytes in a gigabyte, the unit of memory limits (``--memory-limit 8`` is 8 * 10^9 bytes)."""


def _physical_memory() -> int | None:
    """Bytes of memory this machine has, where the system says (``None`` elsewhere)."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


DEFAULT_MEMORY_LIMIT = min(8.0, 0.75 * (_physical_memory() or 8 * GB) / GB)
"""Gigabytes of resident memory a command (or a library call) may hold before it stops
(``--memory-limit GB``; the ``memory_limit`` argument of the library's entry points).

8 GB, or three quarters of the machine's memory where it has less: the checks and compiles
this project measures peak under 6 GB (the 100x100 grid of ``make bench-check``), while a
runaway translation (``F[0,1000] G[0,1000] a``) reached 12 GB in a minute and would take a
smaller machine into swap or the kernel's out-of-memory killer. The whole process counts
(what ``top`` shows as its resident size), Python's and the libraries' memory alike."""

MEMORY_CHECK_SECONDS = 0.01
"""The resident size is read at most this often by :meth:`Deadline.check_now` (reading it
takes a few microseconds; a construction adds well under 100 MB in 10 ms)."""

LIBRARY_MEMORY_HOW = "the memory_limit argument (GB; None for none)"
"""How a library caller raises a memory limit (the command line says ``--memory-limit``)."""

CLI_MEMORY_HOW = "--memory-limit GB (0 for none)"
"""How the command line raises a memory limit."""

_command_memory: list[tuple[float | None, str]] = [(DEFAULT_MEMORY_LIMIT, LIBRARY_MEMORY_HOW)]
"""The memory limit of the command being run and how to raise it (set by the command line's
``--memory-limit``), which every :class:`Deadline` made without a limit of its own takes."""


def set_memory_limit(gigabytes: float | None, how: str = LIBRARY_MEMORY_HOW) -> None:
    """Make ``gigabytes`` (``None`` or 0: none) the memory limit of the deadlines made from now
    on without a limit of their own, their messages saying ``how`` to raise it: what
    ``--memory-limit`` does for a whole command (with :data:`CLI_MEMORY_HOW`)."""
    _command_memory[0] = (gigabytes if gigabytes else None, how)


def memory_limit() -> float | None:
    """The memory limit, in GB, that a deadline made now without one of its own takes."""
    return _command_memory[0][0]


def memory_setting() -> tuple[float | None, str]:
    """The memory limit a deadline made now takes and how to raise it (to set back after a
    command with :func:`set_memory_limit`)."""
    return _command_memory[0]


def resident_bytes() -> int:
    """The resident size of this process now, in bytes (Linux: ``/proc/self/statm``;
    elsewhere the peak resident size, which only grows)."""
    try:
        with open("/proc/self/statm", "rb") as handle:
            return int(handle.read().split()[1]) * _PAGE
    except (OSError, IndexError, ValueError):
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return peak if sys.platform == "darwin" else peak * 1024


_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def gigabytes(count: float) -> str:
    """``count`` bytes as a short text in GB (``8.2 GB``; ``0.012 GB`` below one)."""
    value = count / GB
    return f"{value:.1f} GB" if value >= 1 else f"{value:.2g} GB"


class LimitError(MitlcError):
    """A computation stopped at one of mitlc's limits (the message names it)."""


class Deadline:
    """A time limit for one computation: :meth:`check` raises :class:`LimitError` once
    ``seconds`` have passed since the deadline was made (``None`` or 0: no limit).

    ``what`` names the computation and ``how`` says how to raise the limit, e.g.
    ``Deadline(60, "compile", "--time-limit SECONDS (0 for none)")``. :meth:`check` reads the
    clock only every ``every`` calls, so it is cheap in an inner loop. ``stage`` (set by the
    stages a deadline is passed to) says in the message where the time ran out.
    """

    __slots__ = (
        "_calls",
        "_end",
        "_next_memory",
        "every",
        "how",
        "memory",
        "memory_how",
        "seconds",
        "stage",
        "what",
    )

    def __init__(
        self,
        seconds: float | None,
        what: str,
        how: str = CLI_HOW,
        *,
        every: int = 256,
        memory: float | EllipsisType | None = ...,
        memory_how: str = CLI_MEMORY_HOW,
    ) -> None:
        self.seconds = seconds if seconds else None
        self.what, self.how, self.every = what, how, max(1, every)
        self._end = None if self.seconds is None else time.monotonic() + self.seconds
        self._calls = 0
        self.stage = ""
        if isinstance(memory, EllipsisType):  # the command's limit, raised as it says
            memory, memory_how = _command_memory[0]
        self.memory: float | None = memory if memory else None
        """The memory limit in GB (``None``: none); by default the command's
        (:func:`memory_limit`)."""
        self.memory_how = memory_how
        self._next_memory = 0.0

    @classmethod
    def none(cls) -> Deadline:
        """A deadline that never passes, without a memory limit."""
        return cls(None, "", memory=None)

    @classmethod
    def of(
        cls,
        deadline: Deadline | None,
        time_limit: float | None,
        what: str,
        memory_limit: float | EllipsisType | None = ...,
    ) -> Deadline:
        """``deadline`` when given, else a new one of ``time_limit`` seconds and
        ``memory_limit`` GB (by default the command's, :func:`memory_limit`) for ``what``
        (raised with :data:`LIBRARY_HOW`, :data:`LIBRARY_MEMORY_HOW`): how a public entry
        point takes either."""
        if deadline is not None:
            return deadline
        return cls(
            time_limit, what, LIBRARY_HOW, memory=memory_limit, memory_how=LIBRARY_MEMORY_HOW
        )

    @property
    def unlimited(self) -> bool:
        """True for a deadline that never passes (it may still have a memory limit)."""
        return self._end is None

    def remaining(self) -> float | None:
        """Seconds left (at least 0), or ``None`` without a limit."""
        return None if self._end is None else max(0.0, self._end - time.monotonic())

    def counted_from(self, seconds_ago: float) -> Deadline:
        """This deadline, its time counted from ``seconds_ago`` seconds ago (a command's from
        the start of its process); returns ``self``."""
        if self._end is not None:
            self._end -= max(0.0, seconds_ago)
        return self

    def at(self, stage: str) -> Deadline:
        """This deadline, its message now naming ``stage`` (returns ``self``)."""
        self.stage = stage
        return self

    def check(self) -> None:
        """Raise :class:`LimitError` when the time is up or the memory past its limit (the
        clock is read every ``every`` calls)."""
        if self._end is None and self.memory is None:
            return
        self._calls += 1
        if self._calls % self.every == 0:
            self.check_now()

    def check_now(self) -> None:
        """Raise :class:`LimitError` when the time is up (reads the clock now) or the process's
        resident memory is past the limit (read at most every :data:`MEMORY_CHECK_SECONDS`)."""
        if self._end is None and self.memory is None:
            return
        now = time.monotonic()
        if self._end is not None and now > self._end:
            raise self.error()
        if self.memory is not None and now >= self._next_memory:
            self._next_memory = now + MEMORY_CHECK_SECONDS
            resident = resident_bytes()
            if resident > self.memory * GB:
                raise self.memory_error(resident)

    def reserve(self, count: int, what: str) -> None:
        """Raise :class:`LimitError` before ``count`` more bytes are taken for ``what`` (an
        estimate, made before a product or a table is built) when they would take the process
        past the memory limit."""
        if self.memory is None:
            return
        resident = resident_bytes()
        if resident + count > self.memory * GB:
            where = self._where()
            raise LimitError(
                f"{self.what} stopped at the memory limit of {self.memory:g} GB{where}: "
                f"{what} would take about {gigabytes(count)} more, beside the "
                f"{gigabytes(resident)} held; raise it with {self.memory_how}"
            )

    def _where(self) -> str:
        return f" (during {self.stage})" if self.stage and self.stage != self.what else ""

    def error(self) -> LimitError:
        """The one-line error of this deadline having passed."""
        return LimitError(
            f"{self.what} stopped at the time limit of {self.seconds:g} s{self._where()}; "
            f"raise it with {self.how}"
        )

    def memory_error(self, resident: int) -> LimitError:
        """The one-line error of the memory having passed its limit."""
        return LimitError(
            f"{self.what} stopped at the memory limit of {self.memory:g} GB{self._where()}, "
            f"holding {gigabytes(resident)}; raise it with {self.memory_how}"
        )


@contextmanager
def collector_paused() -> Iterator[None]:
    """Pause Python's cyclic garbage collector for a construction that makes millions of small
    long-lived objects and no garbage cycles (a translation, a folding): its full collections
    rescan every object made so far, a third of the time of a 100,000-state compile. Reference
    counting still frees everything; the collector runs again (as before) on leaving.

    Leaving with an error (a limit), what was built is about to be freed: the objects present
    are frozen (:func:`gc.freeze`) before the collector runs again, so that its first
    collection does not walk all of them first (a second and more past the limit on a
    gigabyte). They are unfrozen when the next construction starts, by when reference
    counting has freed what the error dropped; the rest joins the oldest generation."""
    if _frozen[0]:
        gc.unfreeze()
        _frozen[0] = False
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    except BaseException:
        if enabled:
            gc.freeze()
            _frozen[0] = True
        raise
    finally:
        if enabled:
            gc.enable()


_frozen: list[bool] = [False]
"""Whether :func:`collector_paused` froze the collector's objects on leaving with an error."""


# --- subprocesses: the same time and memory limits -------------------------------------------

_KILLED_FOR_MEMORY = (b"out of memory", b"cannot allocate", b"memory exhausted", b"alloc",
                      b"resource temporarily unavailable")  # fmt: skip
"""What a program's error output says (lower case) when an allocation failed under its cap."""


def run_within(argv: Sequence[str], data: bytes, deadline: Deadline, name: str) -> bytes:
    """Run ``argv`` with ``data`` on its standard input, within what is left of ``deadline``;
    its standard output.

    The program runs in a process group of its own, with the time left to ``deadline`` and
    (Linux) an address-space limit (``RLIMIT_AS``) of the memory left to it: ``deadline``'s
    memory limit less what this process holds. At the time limit the whole group is killed and
    :meth:`Deadline.error` raised; a program that fails within its memory cap (killed by a
    signal, or saying it is out of memory) raises :class:`LimitError` naming the memory limit.
    ``name`` names the program in messages. A program that cannot be started raises
    :class:`OSError`; one that fails otherwise :class:`SubprocessError` with its error output.
    """
    import subprocess

    deadline.check_now()
    cap = _memory_left(deadline)
    process = subprocess.Popen(
        list(argv),
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,  # a process group of its own, to kill whatever it started
    )
    try:
        if cap is not None:  # before its input is written, so before any of its work
            with suppress(ProcessLookupError):  # it has ended already
                resource.prlimit(process.pid, resource.RLIMIT_AS, (cap, cap))
        out, err = process.communicate(data, timeout=deadline.remaining())
    except subprocess.TimeoutExpired:
        _kill_group(process)
        raise deadline.error() from None
    finally:
        if process.poll() is None:  # an interrupt, an error: leave nothing running
            _kill_group(process)
    if process.returncode != 0:
        if cap is not None and _out_of_memory(process.returncode, err):
            raise LimitError(
                f"{deadline.what} stopped at the memory limit of {deadline.memory:g} GB"
                f"{deadline._where()}: {name} {_ended(process.returncode)} within the "
                f"{gigabytes(cap)} of memory left to it; raise it with {deadline.memory_how}"
            )
        raise SubprocessError(name, process.returncode, err)
    return out


class SubprocessError(MitlcError):
    """A program run by :func:`run_within` failed (not at a limit); the message quotes the
    first line of its error output."""

    def __init__(self, name: str, code: int, stderr: bytes) -> None:
        lines = stderr.decode("utf-8", "replace").strip().splitlines()
        said = f": {lines[0].strip()}" if lines else ""
        super().__init__(f"{name} {_ended(code)}{said}")
        self.code = code
        self.stderr = stderr


def _memory_left(deadline: Deadline) -> int | None:
    """Bytes a program may map under ``deadline``'s memory limit (``None``: no cap, or no
    ``prlimit`` on this system); :class:`LimitError` where none are left."""
    if deadline.memory is None or not hasattr(resource, "prlimit"):
        return None
    resident = resident_bytes()
    left = int(deadline.memory * GB) - resident
    if left <= 0:
        raise deadline.memory_error(resident)
    return left


def _kill_group(process: subprocess.Popen[bytes]) -> None:
    """Kill ``process`` and its process group, and wait for it."""
    import signal

    with suppress(ProcessLookupError, PermissionError):  # ended, its group with it
        os.killpg(process.pid, signal.SIGKILL)
    process.communicate()


def _out_of_memory(code: int, stderr: bytes) -> bool:
    """Whether a program that ended with ``code`` under a memory cap failed for memory: killed
    by a signal (a failed allocation often ends in ``SIGSEGV`` or ``SIGABRT``) or saying so."""
    said = stderr.lower()
    return code < 0 or any(words in said for words in _KILLED_FOR_MEMORY)


def _ended(code: int) -> str:
    """``exited with status 1`` or ``was killed by SIGSEGV``."""
    if code >= 0:
        return f"exited with status {code}"
    import signal

    try:
        return f"was killed by {signal.Signals(-code).name}"
    except ValueError:
        return f"was killed by signal {-code}"


# --- input sizes: specs, world files, traces (checked before or while they are read) --------

MAX_SPEC_CHARS = 50_000
"""Characters in one spec (a file, ``-e``, standard input, a line of ``compile --batch``).

The paper's specs are under 100 characters. mitlc parses 40,000 to 55,000 characters a second
of CPU time on this 2-core machine (Lark's LALR parser and the AST transformer), so a spec at
the limit parses in about a second; the 1 MB spec of issue 11 ran 21 s and 970 MB before it
failed. A file is read only as far as the bytes that many characters can take, so a larger one
is refused without being read whole."""

MAX_SPEC_DEPTH = 100
"""Nesting depth of a spec: operators and parentheses inside one another (``!!a`` is 3 deep,
``(a)`` 2, ``a & b & c`` 3).

Lark's LALR parser is iterative, but the passes after it (the parse-tree transformer, the
printer, normalisation, formula progression in the translation) recurse once or more per level:
with Python's default recursion limit of 1,000 the transformer stops near 490 levels and the
translation of a chain of ``U`` (5 frames a level) near 196. At 100 levels the deepest pass
needs about 470 frames, leaving room for the command line and test runners."""

MAX_BOUND = 1_000_000_000_000
"""The largest interval bound (``F[0,1000000000000] a``); ``inf`` is unbounded.

A bound ``k`` costs about ``k`` states of the digital automaton, so bounds past 10^6 stop at
``--max-states`` anyway (the reference semantics on lasso words takes any bound); 10^12 keeps
the sum of the bounds of 100 nested operators far within 64-bit integers. A
bound with more digits is refused before it is converted (Python's int() refuses more than
4,300 digits)."""

MAX_BATCH_BYTES = 10_000_000
"""Bytes in a ``compile --batch`` file (each line also within :data:`MAX_SPEC_CHARS`)."""

MAX_BATCH_FORMULAS = 10_000
"""Formulas in a ``compile --batch`` file. Parsing and compiling the smallest formula takes
about half a millisecond, so 10,000 take seconds; the 5 million lines that fit in
:data:`MAX_BATCH_BYTES` would take 40 minutes. ``bench/formulas.txt`` has 46."""

MAX_WORLD_BYTES = 1_000_000
"""Bytes in a world file (YAML). The paper's worlds are under 2 KB; listing every cell of the
largest grid allowed (:data:`MAX_GRID_CELLS`) one per line is not what a world file is for."""

MAX_YAML_DEPTH = 64
"""Nesting depth of a world file's YAML (collections inside collections). A world needs 4
(``walls: [[[r, c], N]]``); PyYAML's composer recurses per level and stops with
``RecursionError`` near 490."""

MAX_YAML_ALIASES = 100
"""Aliases (``*name``) in a world file. An alias shares its anchor's value, so a few dozen
aliases of aliases make a "billion laughs" value of 10^9 items that the checks would walk."""

MAX_YAML_NODES = 1_000_000
"""Values in a world file counted with every alias expanded (a 1 MB file without aliases has
at most about 500,000): an alias bomb is refused before anything walks it."""

MAX_YAML_INT_DIGITS = 30
"""Characters in an integer of a world file, before it is converted; after it, an integer must
lie within 64 bits (``|n| < 2**63``), as the arrays it ends up in."""

MAX_GRID_CELLS = 1_000_000
"""Cells of a world's grid (rows x cols): a 1000x1000 grid. The product of a 100x100 world
already has 3 million states and takes 14 s to build (README, ``make bench-check``)."""

MAX_TEAM_TRANSITIONS = 40_000_000
"""The most entries (joint state, joint action, outcome) of a team world's joint transition
table, and of its joint observation table, counted before they are built
(:mod:`mitlc.worlds.team`). An entry costs 16 bytes in the table (plus 8 a row): three robots
with five actions each and certain moves on an 8x8 grid, collisions blocked (250,000 joint
states, 31 million entries), take about 4 s and 1 GB to build, within the limit; the same
robots with sideways slips (530 million entries) are far past it."""

MAX_HORIZON = 10_000
"""The largest ``horizon`` of a world. The paper's horizons are 30 and 40, ``make bench-check``
uses 401 on a 100x100 grid; ``mitlc check`` keeps a value table per step (``horizon + 1`` of
them, 8 bytes a product state) and runs a step of value iteration per step, so 10^9 hung."""

MAX_TRACE_BYTES = 16_000_000
"""Bytes in a trace file for ``mitlc monitor``."""

MAX_TRACE_STEPS = 1_000_000
"""Steps (rows of a CSV trace, lines of a JSON Lines trace) in a trace file."""

MAX_TRACE_JSON_DEPTH = 8
"""Nesting depth of one JSON Lines step (a valid step is 1 deep: ``["a"]``, ``{"a": true}``);
checked before the line is parsed, as Python's JSON parser recurses per level."""

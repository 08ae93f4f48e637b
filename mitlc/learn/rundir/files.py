"""The files of a run directory as data, and its lock.

Everything here reads bytes, decodes them as UTF-8 and parses them as JSON: nothing read from
a run directory runs code. Damage of any kind is a :class:`RunError` whose message names the
file and what is wrong, on one line.

:func:`locked` holds an exclusive ``flock`` on the directory's ``.lock`` file (which then names
the holding process) for as long as a training run writes there; the operating system drops
the lock when the process ends, however it ends, so a lock is never stale.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import stat
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from mitlc.errors import MitlcError
from mitlc.inputs import (
    MAX_METRICS_BYTES,
    MAX_RECORD_BYTES,
    RefusedFile,
    read_capped,
    read_lines_capped,
    regular_size,
)

LOCK = ".lock"
METRICS, SUMMARY = "metrics.jsonl", "summary.json"
"""A run's metrics (one line a window) and its summary (written at the end)."""
METRIC_FIELDS = ("episodes", "success_rate", "return", "epsilon")
"""The numbers every ``metrics.jsonl`` line holds (besides ``steps`` and ``seconds``)."""


class RunError(MitlcError):
    """A run directory that cannot be used as asked: missing, foreign, damaged or in use."""


RECORD = "a run's JSON record"
"""What :data:`~mitlc.inputs.MAX_RECORD_BYTES` bounds, as a refusal names it."""


def _unreadable(path: Path, err: OSError) -> RunError:
    """``err`` (reading ``path``) as a :class:`RunError` naming the file."""
    if isinstance(err, RefusedFile):  # not a regular file, or larger than its cap
        return RunError(f"{path}: {err.strerror}")
    return RunError(f"{path}: cannot read ({err.strerror or err})")


def read_bytes(path: Path, limit: int = MAX_RECORD_BYTES, what: str = RECORD) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them (``what`` names the
    file's kind in the refusal): a device, a pipe or a larger file is refused, not read
    (:func:`mitlc.inputs.read_capped`)."""
    try:
        return read_capped(path, limit, what)
    except OSError as err:
        raise _unreadable(path, err) from None


def file_size(path: Path) -> int:
    """The size of the regular file ``path``, without opening it (a :class:`RunError` when it is
    missing or not a regular file)."""
    try:
        return regular_size(path)
    except OSError as err:
        raise _unreadable(path, err) from None


def read_text(path: Path) -> str:
    """The UTF-8 text of ``path``."""
    return decode(read_bytes(path), path)


def decode(data: bytes, path: Path, where: str = "") -> str:
    """``data`` (read from ``path``) as UTF-8 text."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise RunError(f"{path}: {where}not UTF-8 text (byte {err.start}: {err.reason})") from None


def parse_json(text: str, path: Path, where: str = "") -> Any:
    """``text`` parsed as JSON; errors name ``path`` (and ``where`` in it, e.g. a line)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise RunError(
            f"{path}: {where}not valid JSON (line {err.lineno}, column {err.colno}: {err.msg})"
        ) from None
    except (ValueError, RecursionError) as err:  # too many digits, too deeply nested
        raise RunError(f"{path}: {where}not valid JSON ({err})") from None


def read_json(path: Path) -> Any:
    """The JSON value in ``path``."""
    return parse_json(read_text(path), path)


def _is_number(value: Any) -> bool:
    """A JSON number that a float holds (not a bool, not an integer beyond float's range)."""
    if not isinstance(value, int | float) or isinstance(value, bool):
        return False
    return isinstance(value, float) or abs(value) < 2**1023


def read_metrics_rows(path: Path) -> list[dict[str, Any]]:
    """The lines of ``metrics.jsonl`` in ``path``, read one at a time, the file within
    :data:`~mitlc.inputs.MAX_METRICS_BYTES`. A last line without its newline that does not
    parse is a line cut short by a killed run, and is left out; any other bad line is a
    :class:`RunError` naming its number."""
    rows: list[dict[str, Any]] = []
    try:
        lines = read_lines_capped(path, MAX_METRICS_BYTES, "a run's metrics")
        for number, line in enumerate(lines, start=1):
            cut = not line.endswith(b"\n")
            try:
                rows.append(_metrics_row(line.removesuffix(b"\n"), path, number))
            except RunError:
                if cut:
                    break  # cut short when the run was killed: nothing after it counts
                raise
    except OSError as err:
        raise _unreadable(path, err) from None
    return rows


def _metrics_row(piece: bytes, path: Path, number: int) -> dict[str, Any]:
    where = f"line {number}: "
    row = parse_json(decode(piece, path, where), path, where)
    if not isinstance(row, dict):
        raise RunError(f"{path}: {where}expected a JSON object, got {type(row).__name__}")
    for name in METRIC_FIELDS:
        if not _is_number(row.get(name)):
            raise RunError(f"{path}: {where}{name!r} is missing or not a number")
    if not isinstance(row["episodes"], int) or row["episodes"] < 0:
        raise RunError(f"{path}: {where}'episodes' is not a count ({row['episodes']!r})")
    return row


def _holder(text: str) -> str:
    """``process PID (COMMAND)`` from a lock file's text."""
    pid, _, command = text.partition("\n")
    command = " ".join(command.split())[:200]
    if not pid.strip().isdigit():
        return "another process"
    return f"process {pid.strip()} ({command or 'unknown command'})"


def _command() -> str:
    """This process's command line, the program by its name only."""
    try:
        raw = Path("/proc/self/cmdline").read_bytes().split(b"\0")
        parts = [part.decode(errors="replace") for part in raw if part]
    except OSError:
        parts = [sys.executable, *sys.argv]
    return " ".join([Path(parts[0]).name, *parts[1:]]) if parts else ""


def _check_lock(path: Path) -> None:
    """Refuse a lock file ``path`` that is there but not a regular file (a FIFO, a device, a
    link), before it is opened."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as err:
        raise RunError(f"{path}: cannot open the run's lock file ({err.strerror})") from None
    if not stat.S_ISREG(mode):
        raise RunError(f"{path}: not a regular file, so not a run's lock file; remove it")


@contextmanager
def locked(directory: Path) -> Iterator[None]:
    """Hold the run directory ``directory`` (which must exist) for the ``with`` block; a
    :class:`RunError` names the holder when another process has it."""
    path = directory / LOCK
    _check_lock(path)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as err:
        raise RunError(f"{path}: cannot open the run's lock file ({err.strerror})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            if err.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise RunError(f"{path}: cannot lock ({err.strerror})") from None
            holder = _holder(os.read(fd, 4096).decode("utf-8", errors="replace"))
            raise RunError(
                f"{directory}: in use by {holder}; wait for it to finish or stop it"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n{_command()}\n".encode(errors="replace"), 0)
        yield
    finally:
        os.close(fd)  # closing the last descriptor drops the lock

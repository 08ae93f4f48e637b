"""Reading input files within a size limit, refusing what is not a regular file, and locating
bad UTF-8 in them.

Every file mitlc reads goes through this module. A path is checked with ``os.stat`` before it
is opened (:func:`open_regular`): a FIFO, a device, a socket or a directory is refused
(:class:`NotRegularFile`), as opening a FIFO for reading waits for a writer and a device such as
``/dev/zero`` never ends. Text that is held to a length (a spec, a ``compile --batch`` file, a
world, a trace) is read with :func:`read_head`: at most ``limit`` bytes, so that a file too large
is refused without reading it all. The files mitlc wrote itself (a run directory, a sweep
directory, an automaton artifact) are read with :func:`read_capped` or :func:`read_lines_capped`,
which refuse a file larger than its cap (:class:`FileTooLarge`, from ``st_size``) before reading
it, and still read no more than the cap should it grow meanwhile. Both refusals are
:class:`OSError` subclasses whose ``strerror`` says what is wrong in words, so a caller that
turns an unreadable file into its own typed error handles them as it handles a missing file.
Decoding errors become the caller's typed error through :func:`bad_utf8`, which says where the
first bad byte is.

The caps (``MAX_*_BYTES`` below) are measured on real run directories (``mitlc train`` of the
paper's case 1 with Q-learning and with DQN).
"""

from __future__ import annotations

import codecs
import errno
import os
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from mitlc.errors import SourceLocation, locate

KIB, MIB, GIB = 2**10, 2**20, 2**30
"""Binary units of file sizes."""

MAX_RECORD_BYTES = 4 * MIB
"""Bytes in a JSON record of a run or sweep directory: ``config.json``, ``summary.json``,
``checkpoint.json``, a checkpoint's ``checkpoint_<steps>_steps.json``, and a sweep's
``sweep.json``, ``trials/*/result.json`` and ``report.md``.

Measured, they hold under 3 KB (case 1: ``config.json`` 2.7 KB, a DQN checkpoint's JSON 2.6 KB,
the index 0.5 KB). The largest possible is ``config.json`` holding a spec at
:data:`~mitlc.limits.MAX_SPEC_CHARS` (50,000 characters, at most 12 bytes each once JSON escapes
them: 600 KB); a checkpoint's JSON grows by about 400 bytes a network layer (100 layers at
most: 40 KB). Parsed, 4 MiB of the densest JSON (``[[],[],...]``) takes under 400 MB."""

MAX_METRICS_BYTES = 128 * MIB
"""Bytes in a run's ``metrics.jsonl`` (read line by line, parsed lines kept).

A line is about 110 bytes, and a run writes 100 by default (``log_every``: a hundredth of the
run; 11 KB); 128 MiB is 1.2 million lines, a line every episode of a million-episode run. A
parsed line takes about 770 bytes, so the largest file allowed takes about 1 GB to plot."""

MAX_CHECKPOINT_BYTES = 2 * GIB
"""Bytes in a checkpoint's ``.npz`` (numpy arrays) and ``.safetensors`` (torch tensors)
together.

Measured: 78 KB for Q-learning on case 1 (the Q-table), 630 KB for DQN (its replay memory and
the networks with Adam's moments). The largest the settings allow: a network at the bound on
``layers x hidden^2`` (2^26 float32 weights, 256 MiB) is 1 GiB with its target network and
Adam's two moments; beside it, DQN's replay memory of 1,000,000 entries of a small observation
(about 80 bytes each: 80 MB); a Q-table over the default product bound
(:data:`~mitlc.limits.DEFAULT_MAX_PRODUCT_STATES`, 8 million states, 2 frontiers and 5 actions
of 8 bytes) is 640 MB. Loading holds the bytes and the decoded arrays at once, so a checkpoint
at the cap takes about 4 GiB to load, the order of what its run held while it trained; a larger
one (a replay memory of big observations) is refused on resume, eval and plot."""

MAX_ZIP_DIRECTORY_BYTES = 1 * MIB
"""Bytes in the zip directory of a checkpoint's ``.npz``, checked before ``zipfile`` reads it
(it builds an object of about 500 bytes per member from entries of 46 bytes or more). An
array takes about 80 bytes there and a DQN checkpoint has 18: 1 MiB is 13,000 arrays."""

MAX_TENSOR_HEADER_BYTES = 1 * MIB
"""Bytes in the JSON header of a checkpoint's ``.safetensors`` (the library's own limit is
100 MB, and it builds a tensor per entry). An entry takes about 80 bytes and a DQN of 100
layers has 1,000 tensors (networks, target and Adam's moments): 80 KB."""

MAX_ARTIFACT_BYTES = 16 * MIB
"""Bytes in an automaton artifact (``mitlc.tldgba/1`` JSON) given to ``mitlc render``.

The largest artifact of ``bench/formulas.txt`` is 43 KB; an edge takes about 160 bytes, so
16 MiB is 100,000 edges, far past what Graphviz lays out (minutes past a few thousand)."""


class RefusedFile(OSError):
    """A file mitlc will not read; ``strerror`` says why, without the path (``filename``)."""


class NotRegularFile(RefusedFile):
    """A path naming a FIFO, a device, a socket or a directory: refused before it is opened."""


class FileTooLarge(RefusedFile):
    """A file larger than the cap on what it may hold: refused before it is read."""


_KINDS = (
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISDIR, "a directory"),
)


def _not_regular(mode: int, path: str | Path) -> NotRegularFile:
    """The refusal of ``path``, whose ``os.stat`` gave ``mode``."""
    kind = next((f" ({name})" for test, name in _KINDS if test(mode)), "")
    error = errno.EISDIR if stat.S_ISDIR(mode) else errno.EINVAL
    return NotRegularFile(error, f"not a regular file{kind}", str(path))


def size_text(size: int) -> str:
    """``size`` bytes in words: ``512 bytes``, ``4 MiB``, ``6.0 GiB``."""
    for unit, name in ((GIB, "GiB"), (MIB, "MiB"), (KIB, "KiB")):
        if size >= unit:
            return f"{size // unit} {name}" if size % unit == 0 else f"{size / unit:.1f} {name}"
    return f"{size} bytes"


def too_large(path: str | Path, size: int | None, limit: int, what: str) -> FileTooLarge:
    """The refusal of ``path``, of ``size`` bytes (``None``: it grew while it was read), beyond
    ``limit``, the most ``what`` (e.g. ``a run's metrics``) may hold."""
    cap = size_text(limit)
    if size is None:
        reason = f"grew past the {cap} {what} may hold while it was read"
    else:
        reason = f"{size_text(size)}, larger than the {cap} {what} may hold"
    return FileTooLarge(errno.EFBIG, reason, str(path))


def regular_size(path: str | Path) -> int:
    """The size of the regular file ``path`` (symbolic links followed), from ``os.stat``, so
    without opening it: :class:`NotRegularFile` for anything else, :class:`OSError` when it
    cannot be looked at."""
    info = os.stat(path)
    if not stat.S_ISREG(info.st_mode):
        raise _not_regular(info.st_mode, path)
    return info.st_size


def open_regular(path: str | Path) -> BinaryIO:
    """``path`` opened for reading, once ``os.stat`` says it is a regular file. It is opened
    without blocking and checked again (``fstat``), so a path swapped for a FIFO in between is
    refused rather than waited on."""
    regular_size(path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise _not_regular(mode, path)
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_head(source: str | Path | BinaryIO, limit: int) -> tuple[bytes, bool]:
    """At most ``limit`` bytes of ``source`` (a path to a regular file, see
    :func:`open_regular`, or a binary stream such as standard input), and whether there was
    more. Raises :class:`OSError` when it cannot be read."""
    if isinstance(source, str | Path):
        with open_regular(source) as handle:
            return read_head(handle, limit)
    chunks: list[bytes] = []
    size = 0
    while size <= limit:
        chunk = source.read(limit + 1 - size)
        if not chunk:
            break
        chunks.append(chunk)
        size += len(chunk)
    data = b"".join(chunks)
    return data[:limit], len(data) > limit


def read_capped(path: str | Path, limit: int, what: str) -> bytes:
    """The bytes of the regular file ``path``, which may hold at most ``limit`` bytes (``what``
    names its kind in the refusal, e.g. ``a run's metrics``). A file whose size is larger is
    refused before it is read (:class:`FileTooLarge`), one that grows past it while it is read
    once ``limit + 1`` bytes are in; :class:`NotRegularFile` before it is opened, and
    :class:`OSError` when it cannot be read."""
    size = regular_size(path)
    if size > limit:
        raise too_large(path, size, limit, what)
    with open_regular(path) as handle:
        data, more = read_head(handle, limit)
    if more:
        raise too_large(path, None, limit, what)
    return data


def read_lines_capped(path: str | Path, limit: int, what: str) -> Iterator[bytes]:
    """The lines of ``path`` (each with its ``\\n``, the last one without when the file does
    not end in one), read one at a time under the checks of :func:`read_capped`."""
    size = regular_size(path)
    if size > limit:
        raise too_large(path, size, limit, what)
    with open_regular(path) as handle:
        left = limit
        while line := handle.readline(left + 1):
            left -= len(line)
            if left < 0:
                raise too_large(path, None, limit, what)
            yield line


def bad_utf8(data: bytes, filename: str) -> tuple[str, SourceLocation] | None:
    """``None`` when ``data`` is UTF-8 (a leading byte-order mark allowed), else a message
    naming the first bad byte and its location (line and column of the text decoded so far)."""
    body = data.removeprefix(codecs.BOM_UTF8)
    try:
        body.decode("utf-8")
    except UnicodeDecodeError as err:
        good = body[: err.start].decode("utf-8")
        shown = good + body[err.start :].decode("utf-8", errors="replace")
        byte = body[err.start]
        message = f"invalid UTF-8: byte 0x{byte:02x} cannot start or continue a character"
        return message, locate(shown, len(good), filename)
    return None

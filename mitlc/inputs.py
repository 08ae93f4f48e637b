"""Reading input files within a size limit, and locating bad UTF-8 in them.

Every file mitlc reads as text (a spec, a ``compile --batch`` file, a world, a trace) is read
with :func:`read_head`: at most ``limit`` bytes, so that a file too large (or endless, like
``/dev/zero``) is refused without reading it all. Decoding errors become the caller's typed
error through :func:`bad_utf8`, which says where the first bad byte is.
"""

from __future__ import annotations

import codecs
from pathlib import Path
from typing import BinaryIO

from mitlc.errors import SourceLocation, locate


def read_head(source: str | Path | BinaryIO, limit: int) -> tuple[bytes, bool]:
    """At most ``limit`` bytes of ``source`` (a path, or a binary stream such as standard
    input), and whether there was more. Raises :class:`OSError` when it cannot be read."""
    if isinstance(source, str | Path):
        with open(source, "rb") as handle:
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

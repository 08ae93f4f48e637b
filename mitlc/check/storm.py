"""Every call mitlc makes into Storm (stormpy) goes through :func:`storm_guard`.

Storm reports a model or property it rejects, and its own failures, as Python exceptions of
several kinds (mostly ``RuntimeError`` with Storm's exception name in the text), and logs the
error on standard output too. Inside :func:`storm_guard` Storm's log is off, and any exception
but mitlc's own becomes a :class:`StormError`: one line that says what mitlc asked Storm for and
what Storm answered, which the CLI prints without a traceback.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from mitlc.errors import MitlcError


class StormError(MitlcError, ValueError):
    """Storm rejected a model or property mitlc gave it, or failed on it.

    A ``ValueError`` too, as :func:`mitlc.check.pomdp.pomdp_bounds` documents for the inputs it
    cannot bound: a caller that reports the bounds as unavailable on one does so on the other.
    """


@contextmanager
def storm_guard(what: str) -> Iterator[None]:
    """Run the Storm calls of the ``with`` body with Storm's log off; an exception they raise
    (other than a :class:`mitlc.errors.MitlcError`, such as a time limit) becomes a
    :class:`StormError` saying that Storm failed on ``what``."""
    restore = _silence()
    try:
        yield
    except MitlcError:
        raise
    except Exception as err:
        raise StormError(f"Storm failed on {what}: {_first_line(err)}") from err
    finally:
        restore()


def _first_line(err: BaseException) -> str:
    """The first non-empty line of ``err``'s text, or its type's name when it has none."""
    for line in str(err).splitlines():
        if line.strip():
            return line.strip()
    return type(err).__name__


def _silence() -> Callable[[], None]:
    """Turn Storm's log off (it writes errors to standard output, where ``--json`` goes); the
    function that turns it back to its level. Nothing is changed where stormpy offers no log
    level."""
    try:
        import stormpy.developer as developer

        level = developer.get_log_level()
        developer.set_log_level(developer.LogLevel.OFF)
    except (ImportError, AttributeError):
        return lambda: None
    return lambda: developer.set_log_level(level)

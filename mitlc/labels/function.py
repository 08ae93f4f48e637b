"""The contract of a labelling function given as a callable, checked where it can be.

A labelling function takes ``(obs, info)`` and returns the propositions true there: a set of
names (any iterable of strings will do: a list, a tuple, a frozenset; not a single string).
:func:`check_signature` checks, where Python can tell, that the callable takes those two
arguments; :func:`check_result` checks what one call returned (the task wrapper calls it once,
on the first reset's observation); :func:`true_names` is what reads every result.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable
from typing import Any

from mitlc.errors import MitlcError

CONTRACT = (
    "a labelling function takes (obs, info) and returns the set of true propositions "
    "(an iterable of their names, such as a set)"
)
"""What a labelling function must take and return, as every error here says it."""


class LabelFunctionError(MitlcError, TypeError):
    """A labelling function does not keep to :data:`CONTRACT`: it cannot take ``(obs, info)``,
    or returned something that is not an iterable of proposition names."""


def describe(function: Callable[..., Any]) -> str:
    """The function's name, as errors show it."""
    name = getattr(function, "__qualname__", None) or type(function).__name__
    return f"labels: {name}"


def check_signature(function: Callable[..., Any]) -> None:
    """Raise :class:`LabelFunctionError` where ``function``'s signature (when Python knows it)
    cannot be called with the two positional arguments ``(obs, info)``."""
    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):  # a builtin or an extension's callable: unknown
        return
    try:
        signature.bind(None, {})
    except TypeError as err:
        raise LabelFunctionError(
            f"{describe(function)}{signature} cannot be called as f(obs, info) ({err}): {CONTRACT}"
        ) from None


def true_names(function: Callable[..., Any], result: Any) -> frozenset[Any] | set[Any]:
    """The set of what ``function`` returned: a set as it is, another iterable made one (a
    :class:`LabelFunctionError` for a string, bytes or something that is not iterable)."""
    if isinstance(result, set | frozenset):
        return result
    if isinstance(result, str | bytes) or not isinstance(result, Iterable):
        raise LabelFunctionError(f"{describe(function)} returned {_shown(result)}: {CONTRACT}")
    return frozenset(result)


def check_result(function: Callable[..., Any], result: Any) -> None:
    """Raise :class:`LabelFunctionError` unless ``result`` (what ``function`` returned) is an
    iterable of strings, other than a string itself."""
    names = true_names(function, result)
    odd = [name for name in names if not isinstance(name, str)]
    if odd:
        raise LabelFunctionError(
            f"{describe(function)} returned {_shown(result)}, with {_shown(odd[0])} among the "
            f"names: {CONTRACT}"
        )


def call_checked(function: Callable[..., Any], obs: Any, info: Any) -> None:
    """Call ``function`` on ``(obs, info)`` once and check what it returns
    (:func:`check_result`); what the call itself raises is left as it is."""
    check_result(function, function(obs, info))


def _shown(value: Any) -> str:
    """``value`` as an error shows it: its repr, cut to 60 characters, and its type."""
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{text} ({type(value).__name__})"

"""Typer's coercion of command-line values, without importing pydantic where it is not needed.

Typer (0.2x) turns every parameter's value (given or default) into its annotated type through
a pydantic ``TypeAdapter``, built on the first value a parameter meets, so every command
imported pydantic (about 70 ms of CPU) before it ran, ``mitlc fmt -e a`` included. :func:`install`
gives typer's parameters a coercion that takes the values whose result is plain and certain
itself (a string for a ``str``, an integer or decimal within the option's ``min``/``max``, an
``Enum`` member, ``None``) and hands every other value to typer's own coercion, built then, so
that any value that fails (and its message), a path, a list or a parser goes through typer
unchanged. ``tests/test_startup.py`` checks that both give the same value for every parameter
of ``mitlc``.

With a typer whose internals differ (no ``typer._coercion``), :func:`install` does nothing.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields, is_dataclass
from enum import Enum
from typing import Any

_PASS = object()
"""What :func:`plain_value` returns for a value it leaves to typer."""

_INT = re.compile(r"[0-9]{1,18}")
_DECIMAL = re.compile(r"[0-9]{1,15}(\.[0-9]{1,15})?")


def plain_value(annotation: Any, parameter_info: Any, value: Any, ctx: Any) -> Any:
    """``value`` coerced to ``annotation`` where the result is plain (the same as typer's),
    else :data:`_PASS`."""
    if parameter_info.parser is not None:
        return _PASS
    if annotation is str:
        return value if type(value) is str else _PASS
    if annotation is int or annotation is float:
        if parameter_info.clamp:
            return _PASS
        if type(value) is str and (_INT if annotation is int else _DECIMAL).fullmatch(value):
            number: int | float = annotation(value)
        elif type(value) is annotation or (annotation is float and type(value) is int):
            number = annotation(value)
        else:
            return _PASS
        low, high = parameter_info.min, parameter_info.max
        if not math.isfinite(number):
            return _PASS
        if (low is not None and number < low) or (high is not None and number > high):
            return _PASS  # typer's own message
        return number
    if isinstance(annotation, type) and issubclass(annotation, Enum):
        from typer._param_types import coerce_cli_choice  # typer's own matching of choices

        try:
            return coerce_cli_choice(
                value,
                choices=tuple(annotation),
                case_sensitive=parameter_info.case_sensitive,
                ctx=ctx,
            )
        except ValueError:
            return _PASS  # typer's own message
    return _PASS


def install() -> None:
    """Make typer's parameters coerce plain values without pydantic (see the module)."""
    try:
        from typer._coercion import RuntimeParam as base
        from typer._coercion import build_runtime_param as build
        from typer.core import _TyperParameter as parameter
    except ImportError:  # another typer: its own coercion throughout
        return
    if getattr(parameter, "_mitlc_plain", False):
        return
    if not is_dataclass(base) or {f.name for f in fields(base)} != {"parameter_info", "annotation"}:
        return  # typer's coercion has changed shape: leave it as it is

    @dataclass(frozen=True)
    class PlainFirst(base):
        """Plain values here; the others through typer's coercion, built on first use."""

        descriptor: Any = None
        full: list[Any] = field(default_factory=list)

        def _coerce_value(self, value: Any, param: Any, ctx: Any) -> Any:
            done = plain_value(self.annotation, self.parameter_info, value, ctx)
            if done is not _PASS:
                return done
            if not self.full:
                self.full.append(build(self.descriptor))
            return self.full[0]._coerce_value(value, param=param, ctx=ctx)

    def get_runtime_param(self: Any) -> Any:
        if self._runtime_param is None:
            descriptor = self.type_descriptor
            self._runtime_param = PlainFirst(
                parameter_info=descriptor.parameter_info,
                annotation=descriptor.annotation,
                descriptor=descriptor,
            )
        return self._runtime_param

    parameter.get_runtime_param = get_runtime_param  # type: ignore[method-assign]
    parameter._mitlc_plain = True  # type: ignore[attr-defined]

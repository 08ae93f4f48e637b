"""Labels that read a value, checked against a running env: every ``attr`` path must exist on
``env.unwrapped`` after ``reset``, every ``info`` path in the info of ``reset`` or of the first
step, and the value found must suit its test (a number for ``below``/``above``, a vector long
enough for ``box``/``disc``, one value for a truthy test). A path that meets ``None`` on the
way (MiniGrid's ``carrying`` before anything is carried) cannot be checked further and is
accepted.

Each problem is a message that starts with the field's path (``labels.cliff[0].info: ...``),
as :class:`~mitlc.labels.LabelDeclarationError` messages do, and says what was found.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from mitlc.labels.forms import Labeller
from mitlc.labels.values import (
    MISSING,
    PUBLIC,
    AttrPath,
    Bound,
    Code,
    InfoPath,
    Region,
    Select,
    Step,
    Test,
    Truthy,
    Value,
    attribute,
    follow,
    number,
    show_path,
    step_into,
    vector,
)


def _where(labeller: Labeller, proposition: str, i: int, field: str) -> str:
    forms = labeller.forms[labeller.propositions.index(proposition)]
    at = f"labels.{proposition}" + (f"[{i}]" if len(forms) > 1 else "")
    return f"{at}.{field}"


def attr_problems(labeller: Labeller, env: Any) -> list[str]:
    """What is wrong with the ``attr`` paths of ``labeller`` on ``env`` (``env.unwrapped``,
    after ``reset``): a step that is not there, or that is code (a property, a method, a
    descriptor: :func:`mitlc.labels.values.attribute`), or a value that does not suit its
    test."""
    found = []
    for proposition, i, form in labeller.values():
        if isinstance(form.source, AttrPath):
            where = _where(labeller, proposition, i, "attr")
            problem = _safely(_form_problem, env, form, form.source.steps)
            if problem:
                found.append(f"{where}: {problem}")
    for where, source in _guide_ends(labeller):
        if isinstance(source, AttrPath):
            problem = _safely(_guide_problem, env, source, source.steps)
            if problem:
                found.append(f"{where}: {problem}")
    return found


def _form_problem(env: Any, form: Value) -> str | None:
    """Why the ``attr`` path of ``form`` cannot be read on ``env``, or its value tested."""
    assert isinstance(form.source, AttrPath)
    return _walk(env, form.source.steps, True, "env.unwrapped") or _suits(env, form)


def _safely(check: Callable[[Any, Any], str | None], env: Any, what: Any,
            steps: Sequence[Step]) -> str | None:  # fmt: skip
    """``check(env, what)``, or one line saying what went wrong reading ``steps`` (the env's
    own code, a value's ``repr`` or ``len``, may raise anything)."""
    try:
        return check(env, what)
    except Exception as err:
        text = str(err).strip().splitlines()[0][:200] if str(err).strip() else ""
        what = f"{type(err).__name__}: {text}" if text else type(err).__name__
        return f"reading env.unwrapped.{show_path(steps)} failed ({what})"


def _guide_ends(labeller: Labeller) -> list[tuple[str, AttrPath | InfoPath]]:
    """Each end of each guide (``toward``), with its field's path."""
    found: list[tuple[str, AttrPath | InfoPath]] = []
    for proposition, i, form in labeller.guides():
        for end, source in (("from", form.origin), ("to", form.target)):
            kind = "attr" if isinstance(source, AttrPath) else "info"
            found.append((_where(labeller, proposition, i, f"toward.{end}.{kind}"), source))
    return found


def _guide_problem(
    root: Any, source: AttrPath | InfoPath, name: str = "env.unwrapped"
) -> str | None:
    """Why a guide's end cannot be read as a position from ``root``."""
    attributes = isinstance(source, AttrPath)
    problem = _walk(root, source.steps, attributes, name)
    if problem is not None:
        return problem
    value = follow(root, source.steps, attributes)
    if value is not MISSING and value is not None and vector(value) is None:
        kind = type(value).__name__
        return f"{name}.{show_path(source.steps)} is a {kind}, not a position (numbers)"
    return None


def info_problems(labeller: Labeller, infos: Sequence[Mapping[str, Any]]) -> list[str]:
    """What is wrong with the ``info`` paths of ``labeller``: a path must be found in one of
    ``infos`` (those of ``reset`` and of the first step), and its value suit its test."""
    found = []
    for proposition, i, form in labeller.values():
        if not isinstance(form.source, InfoPath) or not infos:
            continue
        where = _where(labeller, proposition, i, "info")
        problems = [_walk(info, form.source.steps, False, "info") for info in infos]
        problem = next((p for p in problems if p is not None), None)
        if None in problems:
            problem = _suits(infos[problems.index(None)], form)
        elif len(infos) > 1:
            problem = f"{problem}, after reset or the first step"
        if problem:
            found.append(f"{where}: {problem}")
    for where, source in _guide_ends(labeller):
        if isinstance(source, InfoPath) and infos:
            problems = [_guide_problem(info, source, "info") for info in infos]
            if None not in problems:
                found.append(f"{where}: {problems[-1]}")
    return found


def info_paths_found(labeller: Labeller, info: Mapping[str, Any]) -> bool:
    """Whether every ``info`` path of ``labeller`` is found in ``info``."""
    paths = [form.source.steps for _, _, form in labeller.values()
             if isinstance(form.source, InfoPath)]  # fmt: skip
    paths += [source.steps for _, source in _guide_ends(labeller) if isinstance(source, InfoPath)]
    return all(_walk(info, steps, False, "info") is None for steps in paths)


def _walk(root: Any, steps: Sequence[Step], attributes: bool, name: str) -> str | None:
    """Why ``steps`` cannot be followed from ``root`` (``None``: they can, or they meet
    ``None``, after which nothing can be checked)."""
    value = root
    for k, step in enumerate(steps):
        if value is None:
            return None
        found = step_into(value, step, attributes)
        if found is MISSING:
            return _missing(value, step, attributes, name, show_path(steps[:k]))
        value = found
    if attributes and callable(value) and not isinstance(value, type):
        return f"{name}.{show_path(steps)} is a method; name a value (an attribute holding data)"
    return None


def _missing(value: Any, step: Step, attributes: bool, name: str, done: str) -> str:
    """What was found where ``step`` finds nothing in ``value``."""
    where = f"{name}.{done}" if done else name
    if isinstance(step, Select):
        kind = type(value).__name__
        if not isinstance(value, list | tuple):
            return f"{where} is a {kind}, not a list to select [{step.name}={step.value}] in"
        return f"no entry of {where} (a {kind} of {len(value)}) has {step.name} = {step.value!r}"
    if isinstance(step, int):
        kind = type(value).__name__
        if not isinstance(value, Mapping | Sequence | np.ndarray) or isinstance(value, str):
            return f"{where} is a {kind}, not a list, an array or a mapping to index"
        size = len(value)
        return f"index {step} is out of range at {where} (a {kind}" + (
            f" of length {size})" if size is not None else ")"
        )
    if isinstance(value, Mapping):
        keys = sorted(str(k) for k in value)
        return f"{where} has no key {step!r}{_hint(step, keys)} (keys: {_listed(keys)})"
    if not attributes:
        return f"{where} is a {type(value).__name__}, not a mapping with key {step!r}"
    code = attribute(value, step)
    if isinstance(code, Code):
        return (
            f"{where}.{step} is a {code.kind} of {type(value).__name__}: reading it runs "
            "code; attr: reads data (an attribute the object holds, a dataclass field, an "
            "array, a list or a mapping), so name the attribute that holds the value"
        )
    names = sorted(n for n in dir(value) if PUBLIC.match(n))
    return (f"{where} (a {type(value).__name__}) has no attribute {step!r}{_hint(step, names)} "
            f"(attributes: {_listed(names)})")  # fmt: skip


def _hint(step: str, names: list[str]) -> str:
    close = difflib.get_close_matches(step, names, n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def _listed(names: list[str], most: int = 12) -> str:
    if not names:
        return "none"
    shown = ", ".join(names[:most])
    return shown + (f", ... ({len(names)} in all)" if len(names) > most else "")


def _suits(root: Any, form: Value) -> str | None:
    """Why the value at the form's path does not suit its test (``None``: it does)."""
    attributes = isinstance(form.source, AttrPath)
    steps = form.source.steps if isinstance(form.source, AttrPath | InfoPath) else ()
    value = root
    for step in steps:
        if value is None:
            return None
        value = step_into(value, step, attributes)
    return test_problem(form.test, value)


def test_problem(test: Test, value: Any) -> str | None:
    """Why ``value`` cannot be given ``test`` (``None``: it can)."""
    if value is None or value is MISSING:
        return None
    if isinstance(test, Bound) and number(value) is None:
        return f"below/above need a number, found {_show(value)}"
    if isinstance(test, Region):
        x = vector(value)
        if x is None:
            return f"box/disc need a vector of numbers, found {_show(value)}"
        need = max(test.index) + 1 if test.index else test.size
        if (test.index and len(x) < need) or (not test.index and len(x) != need):
            return (f"the region reads {need} numbers, found {len(x)}: {_show(value)} (give "
                    "index to pick entries)")  # fmt: skip
    if isinstance(test, Truthy):
        x = vector(value) if not isinstance(value, str | bytes | Mapping) else None
        if x is not None and len(x) > 1:
            return (f"found a vector of {len(x)} numbers ({_show(value)}): give a test "
                    "(equals, in, box, disc)")  # fmt: skip
    return None


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."

"""Making the env a world file names: ``gymnasium.make(id, **kwargs)``, after importing the
installed packages that register it, then the listed gymnasium wrappers in order.

The trust model: a world file may make mitlc *import an installed module by its dotted name*,
as ``gymnasium.make("module:EnvId")`` does, and nothing else runs code.

* ``env.import: [minigrid, highway_env]`` imports those modules (whose import registers their
  envs); ``env.id`` may also be gymnasium's ``"module:EnvId"``. A module is named by dotted
  Python identifiers only (never a file path), found on ``sys.path`` as Python finds any
  installed package (mitlc adds nothing to it), never imported from the current directory or
  the world file's folder (:func:`mitlc.worlds.trust.local_origin`, checked on each dotted
  prefix before it is imported), and an import that fails is an error naming the field.
* ``env.wrappers: ["minigrid.wrappers:ImgObsWrapper", {class: "module:Class", kwargs: {...}}]``
  wraps the made env with each class in turn (before the task wrapper, which is outermost);
  each must be a subclass of ``gymnasium.Wrapper`` from ``gymnasium.wrappers`` or a package
  the file names, and its arguments YAML values.
* No argument (``env.kwargs``, a wrapper's ``kwargs``) names a file or a ``module:name``
  (:func:`mitlc.worlds.trust.path_arguments`); ``--trust-world`` lifts this rule and the
  wrappers' (:mod:`mitlc.worlds.trust`).
* Ids that make another env named in their arguments (shimmy's compatibility layers) and
  mitlc's own ids (``mitlc/...``, made from world files, not named in one) are refused; an own
  id is refused before anything is imported.
* **Nested ids.** An env whose entry point makes another env by an id in its arguments
  (:data:`NESTED`: mitlc's ``make_task_env``, the entry point of ``mitlc/Task-v0``, reads
  ``env_id`` and that env's ``env_kwargs``; a package may register an id of its own on it) has
  that id, where the file gives it in ``env.kwargs``, checked as ``env.id`` is: ``module:EnvId``
  only with an installed module's dotted name, imported here by the same rule (the argument then
  holds the bare id, so that gymnasium imports nothing of its own), a registered id, not
  mitlc's, not one that wraps another by name; and so on down ``env_kwargs``. mitlc's other
  registered env, ``mitlc/Product-v0`` (:class:`mitlc.product.ProductEnv`), takes a world and an
  automaton, objects no file can hold, and names no env.
"""

from __future__ import annotations

import contextlib
import difflib
import importlib
import importlib.util
import re
import sys
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from mitlc.worlds import trust
from mitlc.worlds.env_schema import Env, WrapperEntry
from mitlc.worlds.grid import FieldPath

ENV_ID: FieldPath = ("env", "id")

WRAPPING = frozenset({"GymV21Environment-v0", "GymV26Environment-v0"})
"""Registered ids that make another environment named in their arguments (shimmy's
compatibility layers, which read an old gym id, ``module:Class`` included): refused, so that a
world file makes only what gymnasium registers."""

NESTED: dict[str, tuple[str, str]] = {
    "mitlc.gym.registration:make_task_env": ("env_id", "env_kwargs"),
}
"""Entry points (``module:name``) that make another env by id: the argument that names it and
the argument that holds its own arguments."""

MODULE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*\Z")
"""A module's dotted name."""
CLASS = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
"""A public class name."""


class EnvMakeError(Exception):
    """What went wrong making the env: (the field's path, a message) pairs; the callers turn
    them into their own typed errors."""

    def __init__(self, found: list[tuple[FieldPath, str]]) -> None:
        self.found = found
        super().__init__("; ".join(m for _, m in found))


@contextlib.contextmanager
def quiet() -> Iterator[None]:
    """gymnasium's warnings (deprecations, the env checker's advice) silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


def reason(err: BaseException) -> str:
    """An exception in one line, without gymnasium's note on where it was raised."""
    text = str(err).strip().splitlines()[0] if str(err).strip() else ""
    text = text.split(" was raised from the environment creator")[0]
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def check_module_name(name: object, where: FieldPath) -> None:
    """An :class:`EnvMakeError` at ``where`` unless ``name`` is a module's dotted name."""
    if not isinstance(name, str) or not MODULE.match(name):
        message = (f"{name!r} is not a module's dotted name (such as minigrid or "
                   "highway_env): a world file imports installed packages by name, never a "
                   "file")  # fmt: skip
        raise EnvMakeError([(where, message)])


def import_named(name: str, where: FieldPath, folder: Path | None = None) -> Any:
    """The installed module ``name`` (dotted identifiers), imported; an :class:`EnvMakeError`
    at ``where`` if the name is not a module name, is not installed, lies in the current
    directory or the world's ``folder`` (each dotted prefix is found and checked before it is
    imported) or fails to import."""
    check_module_name(name, where)
    parts = name.split(".")
    for k in range(1, len(parts) + 1):
        _find_installed(".".join(parts[:k]), name, where, folder)
    try:
        with quiet(), contextlib.redirect_stdout(sys.stderr):  # keep stdout for mitlc's output
            return importlib.import_module(name)
    except Exception as err:  # the module's own import may raise anything
        raise EnvMakeError([(where, f"importing {name!r} failed: {reason(err)}")]) from None


def _find_installed(name: str, whole: str, where: FieldPath, folder: Path | None) -> None:
    """Find the module ``name`` (a prefix of ``whole``; its parent is imported by now) and
    refuse it where it is not installed: not found, or local (in the current directory or the
    world's ``folder``)."""
    try:
        with quiet():
            found = importlib.util.find_spec(name)
    except Exception as err:  # a parent package's import may raise anything
        found, problem = None, reason(err)
    else:
        problem = ""
    if found is None:
        hint = f" ({problem})" if problem else " (pip install it, or check the name)"
        raise EnvMakeError([(where, f"no installed module {whole!r}{hint}")])
    root = trust.local_origin(found.origin if found.has_location else None,
                              trust.roots_of(folder))  # fmt: skip
    if root is not None:
        what = "the current directory" if root == Path.cwd().resolve() else "the world's folder"
        message = (f"module {name!r} is a file in {what}, not an installed package: a world "
                   "file imports installed packages only")  # fmt: skip
        raise EnvMakeError([(where, message)])


def make_env(settings: Env, folder: Path | None = None) -> Any:
    """The env of ``settings`` (see the module docstring), made and wrapped; an
    :class:`EnvMakeError` at the field at fault if it cannot be. ``folder``: the world file's,
    from which no module is imported."""
    with quiet():
        import gymnasium
    module, env_id = split_id(settings.id, ENV_ID)
    named = [*settings.imports, *([module] if module else [])]
    refused: list[tuple[FieldPath, str]] = []
    for i, entry in enumerate(settings.wrappers):  # before anything is imported
        wrapper: FieldPath = ("env", "wrappers", i)
        _wrapper_class(entry, (*wrapper, "class") if entry.kwargs else wrapper, named)
        refused += trust.path_arguments(entry.kwargs, (*wrapper, "kwargs"))
    if refused:
        raise EnvMakeError(refused)
    for i, name in enumerate(settings.imports):
        import_named(name, ("env", "import", i), folder)
    if module:
        import_named(module, ENV_ID, folder)
    _check_id(env_id, gymnasium.registry, ENV_ID)
    where: FieldPath = ("env", "kwargs")
    kwargs = nested_ids(
        gymnasium.registry[env_id], settings.kwargs, where, gymnasium.registry, folder
    )
    refused = trust.path_arguments(kwargs, where, gymnasium.registry)  # ids are not paths
    if refused:
        raise EnvMakeError(refused)
    try:
        with quiet():
            env = gymnasium.make(env_id, **kwargs)
    except Exception as err:  # the env's own constructor may raise anything
        at: FieldPath = where if settings.kwargs else ENV_ID
        raise EnvMakeError([(at, f"{env_id} cannot be made: {reason(err)}")]) from None
    for i, entry in enumerate(settings.wrappers):
        env = _wrap(env, entry, ("env", "wrappers", i), gymnasium.Wrapper, folder)
    return env


def split_id(text: object, where: FieldPath) -> tuple[str, str]:
    """``(module, id)`` of an env id, ``module:EnvId`` or a bare id (module ``""``), checked
    before anything is imported: the module's dotted name, and an id that is not mitlc's."""
    if not isinstance(text, str) or not text.strip():
        message = f"expected a gymnasium environment id (e.g. FrozenLake-v1), got {text!r}"
        raise EnvMakeError([(where, message)])
    module, sep, env_id = text.partition(":")
    if not sep:
        module, env_id = "", text
    else:
        check_module_name(module, where)
    _refuse_own(env_id, where)
    return module, env_id


def nested_ids(
    spec: Any,
    kwargs: Mapping[str, Any],
    where: FieldPath,
    registry: Any,
    folder: Path | None = None,
) -> dict[str, Any]:
    """``kwargs`` (at ``where``) of the registered env ``spec``, with the id of another env
    that its entry point makes (:data:`NESTED`) checked as ``env.id`` is, its module imported by
    name and the argument holding the bare id; the same down that env's own arguments."""
    out = dict(kwargs)
    names = NESTED.get(entry_point_name(spec.entry_point))
    if names is None:
        return out
    id_name, kwargs_name = names
    inner = spec.kwargs.get(id_name)  # the registering package's own choice, if any
    if id_name in out:
        at: FieldPath = (*where, id_name)
        module, inner = split_id(out[id_name], at)
        if module:
            import_named(module, at, folder)
        _check_id(inner, registry, at)
        out[id_name] = inner
    more = out.get(kwargs_name)
    inner_id = inner.rpartition(":")[2] if isinstance(inner, str) else None
    if isinstance(more, Mapping) and inner_id in registry:
        at = (*where, kwargs_name)
        out[kwargs_name] = nested_ids(registry[inner_id], more, at, registry, folder)
    return out


def entry_point_name(entry_point: Any) -> str:
    """A registered entry point as ``module:name`` (a callable's module and qualified name)."""
    if isinstance(entry_point, str):
        return entry_point
    module = getattr(entry_point, "__module__", "")
    return f"{module}:{getattr(entry_point, '__qualname__', '')}"


def _refuse_own(env_id: str, where: FieldPath) -> None:
    if env_id.startswith("mitlc/"):
        message = (f"{env_id} is mitlc's own: a world file is the task, so name the env it "
                   "runs on")  # fmt: skip
        raise EnvMakeError([(where, message)])


def _check_id(env_id: str, registry: Any, where: FieldPath) -> None:
    _refuse_own(env_id, where)
    if env_id not in registry:
        close = difflib.get_close_matches(env_id, sorted(registry), n=1, cutoff=0.7)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        if not close and "-v" in env_id:
            hint = "; if a package registers it, list it under env.import or write module:EnvId"
        raise EnvMakeError([(where, f"no gymnasium environment {env_id!r}{hint}")])
    if env_id in WRAPPING:
        message = f"{env_id} makes another environment by name; name that environment's id"
        raise EnvMakeError([(where, message)])


def _wrapper_class(entry: WrapperEntry, at: FieldPath, named: Sequence[str]) -> tuple[str, str]:
    """``(module, class)`` of a wrapper entry, refused (at ``at``) unless it reads as
    ``module:Class`` of ``gymnasium.wrappers`` or of a package the file names (``named``)."""
    module_name, sep, class_name = entry.cls.partition(":")
    if not sep or not CLASS.match(class_name):
        raise EnvMakeError([(at, f"expected module:Class, got {entry.cls!r}")])
    check_module_name(module_name, at)
    if not trust.wrapper_allowed(module_name, named):
        message = (f"{module_name} is neither gymnasium.wrappers nor a package the file names "
                   f"(env.import): a world file runs only the code it declares; list the package "
                   f"under env.import, or {trust.TRUST_HINT}")  # fmt: skip
        raise EnvMakeError([(at, message)])
    return module_name, class_name


def _wrap(
    env: Any, entry: WrapperEntry, where: FieldPath, base: type[Any], folder: Path | None
) -> Any:
    """``env`` wrapped by the entry's class with its arguments (its module checked by
    :func:`_wrapper_class` before; none from the world's ``folder``)."""
    at: FieldPath = (*where, "class") if entry.kwargs else where
    module_name, _, class_name = entry.cls.partition(":")
    module = import_named(module_name, at, folder)
    cls = getattr(module, class_name, None)
    if not (isinstance(cls, type) and issubclass(cls, base)) or cls is base:
        what = ("not there" if cls is None else "a class" if isinstance(cls, type)
                else f"a {type(cls).__name__}")  # fmt: skip
        message = f"{module_name}.{class_name} is {what}, not a gymnasium.Wrapper subclass"
        raise EnvMakeError([(at, message)])
    try:
        with quiet():
            return cls(env, **entry.kwargs)
    except Exception as err:  # the wrapper's own constructor may raise anything
        raise EnvMakeError([(where, f"{entry.cls} cannot wrap the env: {reason(err)}")]) from None

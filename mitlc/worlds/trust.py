"""What a world file written by someone else may make mitlc do: the trust model.

Running a world file must read and write no file outside the world file's folder and the run
directory, and run no code but the import of the installed packages it names and the
constructors of their registered envs. Each rule here closes one way out; the callers
(:mod:`mitlc.worlds.env_make`, :mod:`mitlc.worlds.load`, :mod:`mitlc.labels.values`) apply
them and report a refusal at the field that asked.

* **Files.** ``spec:`` names a file inside the world file's folder (:func:`inside_folder`: no
  absolute path, no ``..`` out of it, symlinks resolved); a refused file is named, never read.
* **Modules.** A module is imported only from the installed packages
  (:func:`local_origin`): a module whose file lies in the current directory or the world's
  folder is refused, however mitlc was started (``python -m mitlc`` puts the current
  directory on ``sys.path``), unless a ``sys.path`` entry *below* that folder holds it (a
  virtual environment's ``site-packages`` inside a project).
* **Arguments.** ``env.kwargs`` and a wrapper's ``kwargs`` are YAML data, and none of them
  names a file (:func:`path_arguments`: a key such as ``xml_file``, ``video_folder``,
  ``filename``, or a string that reads as a path): an env or a wrapper writes or reads where its
  arguments say (SB3's ``Monitor``, gymnasium's ``RecordVideo``, MuJoCo's ``xml_file``).
* **Wrappers.** A wrapper class comes from ``gymnasium.wrappers`` or a package the file names
  (``env.import``, the module of ``env.id``), or one of their submodules
  (:func:`wrapper_allowed`): the code that runs is the code the file declares.

``--trust-world`` on the command line (:func:`trusting`) lifts the last two rules, for a world
file the user vouches for as for their own code; the first two always hold.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

FieldPath = tuple[str | int, ...]

_TRUSTED: list[bool] = [False]
"""Whether the world files loaded now are trusted (``--trust-world``)."""


def trusted() -> bool:
    """Whether the user vouched for the world files loaded now (``--trust-world``)."""
    return _TRUSTED[0]


@contextlib.contextmanager
def trusting(flag: bool = True) -> Iterator[None]:
    """World files loaded inside trusted (``flag``) or not; the setting before, after."""
    before = _TRUSTED[0]
    _TRUSTED[0] = bool(flag)
    try:
        yield
    finally:
        _TRUSTED[0] = before


TRUST_HINT = "pass --trust-world if you trust this world file as your own code"


# -- files ---------------------------------------------------------------------------------------


class OutsideError(ValueError):
    """A file a world file names lies outside its folder."""


def inside_folder(folder: Path, name: str) -> Path:
    """The file ``name`` (relative, as written in a world file) in ``folder``, resolved; an
    :class:`OutsideError` saying why if it is absolute or resolves (``..``, a symlink) outside
    ``folder``."""
    if "\0" in name:
        raise OutsideError("a NUL in the name")
    if os.path.isabs(name) or name.startswith("~"):
        raise OutsideError("an absolute path: name a file in the world file's folder")
    base = folder.resolve()
    target = (base / name).resolve()
    if not target.is_relative_to(base):
        raise OutsideError("outside the world file's folder (a '..' or a symlink out of it)")
    return target


# -- modules -------------------------------------------------------------------------------------


def local_origin(origin: str | None, roots: Sequence[Path]) -> Path | None:
    """The root of ``roots`` (the current directory, the world's folder) that holds a module
    whose file is ``origin``, unless an installed location holds it: a ``sys.path`` entry
    strictly below that root (a virtual environment inside a project). ``None``: the module is
    not local (built in, frozen, a namespace package, or installed)."""
    if not origin or not os.path.isabs(origin):
        return None
    where = Path(origin).resolve()
    entries = [Path(e).resolve() for e in sys.path if e and e != "."]
    for root in (r.resolve() for r in roots):
        if not where.is_relative_to(root):
            continue
        installed = any(e != root and e.is_relative_to(root) and where.is_relative_to(e)
                        for e in entries)  # fmt: skip
        if not installed:
            return root
    return None


def roots_of(folder: Path | None) -> list[Path]:
    """The folders a module may not be imported from: the current directory and the world
    file's folder."""
    roots = [Path.cwd()]
    return roots + ([folder] if folder is not None else [])


# -- arguments -----------------------------------------------------------------------------------

PATH_WORDS = frozenset({
    "path", "paths", "file", "files", "filename", "filenames", "fname", "dir", "dirs",
    "directory", "folder", "root", "xml", "log", "logs", "logdir", "save", "load", "video",
    "videos", "record", "output", "outdir", "cache", "checkpoint", "url", "uri",
})  # fmt: skip
"""Words of an argument's name that say it names a file (``xml_file``, ``video_folder``,
``log_dir``, ``filename``, ``savePath``)."""

_WORDS = re.compile(r"[A-Z]?[a-z]+|[A-Z]+(?![a-z])|\d+")
_SUFFIX = re.compile(r"\.[A-Za-z][A-Za-z0-9]{0,5}\Z")


def path_key(key: str) -> bool:
    """Whether an argument's name says it names a file."""
    return any(word.lower() in PATH_WORDS for word in _WORDS.findall(key))


def path_text(text: str, ids: Any = ()) -> bool:
    """Whether a string reads as a file's path (a separator, a leading ``~`` or ``.``, a file
    suffix: ``maze.xml``) or a ``module:name`` that an env would import; an env id registered
    in ``ids`` is not one (``ALE/Pong-v5``)."""
    if text in ids:
        return False
    return ("/" in text or "\\" in text or text.startswith(("~", ".")) or ":" in text
            or bool(_SUFFIX.search(text)))  # fmt: skip


def path_arguments(value: Any, where: FieldPath, ids: Any = ()) -> list[tuple[FieldPath, str]]:
    """Each argument in ``value`` (a mapping of YAML data, at ``where``) that names a file,
    with a message; nothing when the world is trusted."""
    if trusted():
        return []
    found: list[tuple[FieldPath, str]] = []
    _paths(value, where, ids, found)
    return found


def _paths(value: Any, where: FieldPath, ids: Any, found: list[tuple[FieldPath, str]]) -> None:
    if isinstance(value, Mapping):
        for key, item in value.items():
            at: FieldPath = (*where, str(key))
            named = item is not None and item is not False
            if isinstance(key, str) and ((path_key(key) and named) or path_text(key, ids)):
                message = (f"an argument that names a file ({key}): a world file reads and "
                           f"writes no file outside its folder; {TRUST_HINT}")  # fmt: skip
                found.append((at, message))
            else:
                _paths(item, at, ids, found)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            _paths(item, (*where, i), ids, found)
    elif isinstance(value, str) and path_text(value, ids):
        shown = value if len(value) <= 40 else value[:37] + "..."
        message = (f"{shown!r} reads as a file's path or a module:name: a world file names no "
                   f"file outside its folder and no code; {TRUST_HINT}")  # fmt: skip
        found.append((where, message))


# -- wrappers ------------------------------------------------------------------------------------

WRAPPER_MODULES = ("gymnasium.wrappers",)
"""Where a wrapper may come from besides the packages a world file names."""


def wrapper_allowed(module: str, named: Sequence[str]) -> bool:
    """Whether a wrapper class of ``module`` may wrap the env of a world file that names the
    packages ``named``: ``gymnasium.wrappers`` or a named package, or a submodule of one (any,
    when trusted)."""
    if trusted():
        return True
    return any(module == top or module.startswith(top + ".") for top in (*WRAPPER_MODULES, *named))

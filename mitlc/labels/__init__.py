"""Labelling functions: which propositions hold at an environment's observation.

A labelling function maps an observation and its ``info`` to the set of true propositions,
``(obs, info) -> frozenset[str]`` (DESIGN.md, "Where the design goes next"). It is either a
callable, or declared as plain data (a YAML-ready mapping from proposition names to *forms*)
and compiled by :func:`compile_labels`:

``{obs: [15, 3]}``
    a discrete observation (an int or a numpy integer) is one of these;
``{decoded: {radices: ..., fields: ..., where: ...}}``
    e.g. ``{decoded: {radices: [5, 5, 5, 4], fields: [row, col, passenger, destination],
    where: {passenger: [4]}}}``: a discrete observation decoded in mixed radix (the first field
    the most significant, as Taxi's ``decode``): every field listed in ``where`` has one of its
    values (or, where its entry names another field, ``{passenger: destination}``, the two
    fields are equal);
``{box: {index: [0, 1], low: [0.0, 0.0], high: [1.0, 2.0]}}``
    the position read from a Box observation at ``index`` lies in the closed box;
``{disc: {index: [0, 1], center: [2.0, 3.0], radius: 0.5}}``
    that position lies in the closed disc;
``{info: rewards.arrived_reward}``, ``{attr: carrying.type, equals: key}``
    a value read from a dotted path into nested ``info`` or on ``env.unwrapped``, tested:
    truthy, ``equals``, ``in``, ``below``/``above``, ``box`` or ``disc`` (a missing value is
    false; :mod:`mitlc.labels.declare_values`);
``{reward: {below: -50}}``, ``{terminated: true}``
    an event of the step that reached the position (false at the first position).

For a Dict observation, ``key`` names the part a form reads: beside ``obs``
(``{obs: [1, 2], key: agent}``), inside the mapping of ``decoded``, ``box`` and ``disc``. A
proposition may also be declared by a list of forms: it holds when any of them holds. Any form
may carry ``probability: p`` beside it (``{obs: [15], probability: 0.9}``): where it holds, the
proposition is perceived with probability ``p``, drawn anew at each position
(:mod:`mitlc.labels.chance`).

A callable that does not keep to that contract raises :class:`LabelFunctionError` (a
``TypeError``; :mod:`mitlc.labels.function`). A bad declaration raises
:class:`LabelDeclarationError` naming the field's path, e.g.
``labels.goal.obs: expected a list of integers``. Given the observation space, the forms are
also checked against it (an index past a Box's length, a value outside a Discrete, radices that
do not multiply to its size). Nothing here imports gymnasium: spaces are read by their
attributes. Compiled labels are plain classes holding data, so they pickle (AsyncVectorEnv).
"""

from mitlc.labels.chance import ChanceReader, Chances, perceive
from mitlc.labels.declare import FORMS, as_labels, compile_labels, letters_of_states
from mitlc.labels.forms import (
    CachedLetters,
    CallableLetters,
    DeclaredLetters,
    Decoded,
    Form,
    InBox,
    InDisc,
    LabelDeclarationError,
    LabelFunction,
    Labeller,
    Labels,
    LetterReader,
    ObsIn,
    letter_reader,
    undeclared,
)
from mitlc.labels.function import LabelFunctionError
from mitlc.labels.values import Moment, Value

__all__ = [
    "FORMS",
    "CachedLetters",
    "CallableLetters",
    "ChanceReader",
    "Chances",
    "DeclaredLetters",
    "Decoded",
    "Form",
    "InBox",
    "InDisc",
    "LabelDeclarationError",
    "LabelFunction",
    "LabelFunctionError",
    "Labeller",
    "Labels",
    "LetterReader",
    "Moment",
    "ObsIn",
    "Value",
    "as_labels",
    "compile_labels",
    "letter_reader",
    "letters_of_states",
    "perceive",
    "undeclared",
]

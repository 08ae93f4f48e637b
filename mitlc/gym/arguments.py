"""The task wrapper's arguments, checked when it is made: what each must be, and what the
wrapper makes of the spec, the reward terms and the shaping.

A wrong argument raises :class:`TaskWrapperError` (a ``ValueError``) naming it, or, where its
type is wrong, :class:`TaskWrapperTypeError` (a ``TaskWrapperError`` and a ``TypeError``), so
that nothing fails later, at ``reset`` or ``step``, for what was given here.
"""

from __future__ import annotations

from collections.abc import Mapping
from numbers import Real
from typing import Any

import gymnasium as gym
import numpy as np

from mitlc.automata import DigitalAutomaton, translate
from mitlc.automata.clocks import ClockView, ClockViewError, clock_view, clock_view_of
from mitlc.automata.ldba import translate_terms
from mitlc.errors import MitlcError
from mitlc.labels import Labels
from mitlc.labels.function import check_signature
from mitlc.syntax import parse
from mitlc.task import TaskAutomaton
from mitlc.task.potential import TaskPotential, task_potential
from mitlc.task.rules import TaskRewards
from mitlc.worlds.model import Rewards

TASK_PARTS = ("automaton", "frontier", "location", "clocks")
"""The names of the task's parts of the observation (``env_key`` must be another)."""


class TaskWrapperError(MitlcError, ValueError):
    """The wrapper cannot be built as asked (or a lazy automaton outgrew its declared size)."""


class TaskWrapperTypeError(TaskWrapperError, TypeError):
    """An argument of the wrapper has the wrong type."""


def _type_name(value: Any) -> str:
    return type(value).__name__


def _is_int(value: Any) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)


def _is_number(value: Any) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool | np.bool_)


def _choice(name: str, value: Any, options: tuple[str, ...]) -> None:
    """``value`` must be one of the strings ``options``."""
    if value in options and isinstance(value, str):
        return
    shown = " or ".join(repr(o) for o in options)
    error = TaskWrapperError if isinstance(value, str) else TaskWrapperTypeError
    raise error(f"{name}: expected {shown}, got {value!r}")


def _count(name: str, value: Any, least: int, *, optional: bool = True) -> None:
    """``value`` must be an integer of at least ``least`` (or ``None`` when ``optional``)."""
    if value is None and optional:
        return
    what = f"an integer >= {least}" if least != 1 else "a positive integer"
    if not _is_int(value):
        raise TaskWrapperTypeError(f"{name}: expected {what}, got {value!r} ({_type_name(value)})")
    if value < least:
        raise TaskWrapperError(f"{name}: expected {what}, got {value!r}")


def check_arguments(env: Any, spec: Any, labels: Any, options: Mapping[str, Any]) -> None:
    """Check the wrapper's arguments: ``env``, ``spec``, ``labels`` and the keywords in
    ``options`` (``horizon``, ``rewards``, ``reward_mode``, ``flatten``,
    ``max_automaton_states``, ``max_jumps``, ``env_key``, ``env_end``, ``task_obs``,
    ``potential``, ``guide``)."""
    if not isinstance(env, gym.Env):
        raise TaskWrapperTypeError(f"env: expected a gymnasium.Env, got {_type_name(env)}")
    _check_spec(spec)
    _check_labels(labels)
    _count("horizon", options["horizon"], 1, optional=False)
    check_rewards(options["rewards"])
    _choice("reward_mode", options["reward_mode"], ("replace", "add"))
    if not isinstance(options["flatten"], bool | np.bool_):
        raise TaskWrapperTypeError(f"flatten: expected True or False, got {options['flatten']!r}")
    _count("max_automaton_states", options["max_automaton_states"], 1)
    _count("max_jumps", options["max_jumps"], 0)
    env_key = options["env_key"]
    if not isinstance(env_key, str) or not env_key:
        raise TaskWrapperTypeError(f"env_key: expected a non-empty string, got {env_key!r}")
    if env_key in TASK_PARTS:
        raise TaskWrapperError(f"env_key: {env_key!r} is the name of the task's part")
    _choice("env_end", options["env_end"], ("auto", "step", "finish"))
    _choice("task_obs", options["task_obs"], ("state", "clocks"))
    potential = options["potential"]
    if potential is not None and (not _is_number(potential) or potential < 0):
        error = TaskWrapperError if _is_number(potential) else TaskWrapperTypeError
        raise error(f"potential: expected a reach >= 0, got {potential!r}")
    if not isinstance(options["guide"], bool):
        raise TaskWrapperTypeError(f"guide: expected True or False, got {options['guide']!r}")
    if options["guide"] and potential is None:
        raise TaskWrapperError(
            "guide: the way points along the shaping potential's pull: give potential=REACH "
            "too (0: the largest distance at the first reset)"
        )


def _check_spec(spec: Any) -> None:
    """``spec`` must be a formula's text or an automaton."""
    if isinstance(spec, str):
        return
    if isinstance(spec, bytes):
        raise TaskWrapperTypeError(
            "spec: expected a formula's text (str) or an automaton, got bytes: decode it first"
        )
    needed = ("propositions", "num_sets", "initial", "successor", "verdict", "jumps")
    missing = [name for name in needed if not hasattr(spec, name)]
    if missing:
        raise TaskWrapperTypeError(
            f"spec: expected a formula's text (str) or an automaton (mitlc.automata.translate), "
            f"got {spec!r} ({_type_name(spec)})"
        )


def _check_labels(labels: Any) -> None:
    """``labels`` must be declarations (a mapping), labels, or a labelling function that takes
    ``(obs, info)``."""
    if isinstance(labels, Mapping | Labels):
        return
    if not callable(labels):
        raise TaskWrapperTypeError(
            "labels: expected a mapping of declarations or a callable (obs, info) -> set of "
            f"true propositions, got {_type_name(labels)}"
        )
    check_signature(labels)


def check_rewards(rewards: Any) -> None:
    """``rewards`` must be ``None``, reward terms, or a mapping of known terms to numbers."""
    if rewards is None:
        return
    if isinstance(rewards, Mapping):
        for key, value in rewards.items():
            if key not in Rewards.__dataclass_fields__:
                raise TaskWrapperError(
                    f"rewards: unknown term {key!r} (expected accept, satisfied, violated, move)"
                )
            if not _is_number(value):
                raise TaskWrapperTypeError(
                    f"rewards.{key}: expected a number, got {value!r} ({_type_name(value)})"
                )
        return
    odd = [n for n in ("accept", "satisfied", "violated") if not _is_number(getattr(rewards, n, 0))]
    if not all(hasattr(rewards, n) for n in ("accept", "satisfied", "violated")) or odd:
        raise TaskWrapperTypeError(
            "rewards: expected a mapping of reward terms (accept, satisfied, violated, move) to "
            f"numbers, or mitlc.worlds.model.Rewards, got {rewards!r} ({_type_name(rewards)})"
        )


def task_rewards(rewards: TaskRewards | Mapping[str, float] | None) -> TaskRewards:
    """The reward terms of ``rewards`` (checked by :func:`check_arguments`)."""
    if rewards is None:
        return Rewards()
    if isinstance(rewards, Mapping):
        return Rewards(**{k: float(v) for k, v in rewards.items()})
    return rewards


def task_of(
    spec: str | TaskAutomaton, task_obs: str, source: str = "<spec>"
) -> tuple[TaskAutomaton, ClockView | None]:
    """The automaton of ``spec`` and, with ``task_obs="clocks"``, its clock view (``source``:
    the name a parse error gives the text)."""
    if isinstance(spec, str):
        if task_obs == "state":
            return translate(parse(spec, source)), None
        translation = translate_terms(parse(spec, source))
        return translation.automaton, clock_view(translation)
    if task_obs == "state":
        return spec, None
    if not isinstance(spec, DigitalAutomaton):
        raise TaskWrapperError(
            "task_obs: the clocks of a lazy automaton are not known: use 'state'"
        )
    try:
        return spec, clock_view_of(spec)
    except ClockViewError as err:
        raise TaskWrapperError(f"task_obs: {err}") from None


def shaping_of(automaton: TaskAutomaton, potential: float | None) -> TaskPotential | None:
    """The task's shaping potential where ``potential`` is set (an eager automaton's only)."""
    if potential is None:
        return None
    if not isinstance(automaton, DigitalAutomaton):
        raise TaskWrapperError("potential: the shaping of a lazy automaton is not known")
    return task_potential(automaton)

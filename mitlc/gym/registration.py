"""``gymnasium.make("mitlc/Task-v0", env_id=..., spec=..., labels=..., horizon=...)``: the
inner env made by id and wrapped in a :class:`mitlc.gym.TaskWrapper` (registered on import)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

from mitlc.gym.wrapper import ENV_ID, TaskWrapper
from mitlc.labels import LabelFunction, Labels
from mitlc.task import TaskAutomaton


def make_task_env(
    *,
    env_id: str,
    spec: str | TaskAutomaton,
    labels: Labels | LabelFunction | Mapping[str, Any],
    horizon: int,
    env_kwargs: Mapping[str, Any] | None = None,
    render_mode: str | None = None,
    **options: Any,
) -> TaskWrapper:
    """The entry point of :data:`ENV_ID`: ``gymnasium.make(env_id, **env_kwargs)`` wrapped in a
    :class:`TaskWrapper` (``options`` are its keywords: rewards, reward_mode, flatten, ...)."""
    kwargs = dict(env_kwargs or {})
    if render_mode is not None:
        kwargs["render_mode"] = render_mode
    wrapper = TaskWrapper(gym.make(env_id, **kwargs), spec, labels, horizon=horizon, **options)
    wrapper._spec_is_inner = True
    return wrapper


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="mitlc.gym.registration:make_task_env")

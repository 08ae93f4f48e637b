"""The task on any gymnasium environment: :class:`TaskWrapper`, and the registered id
``mitlc/Task-v0`` (importing this package registers it)."""

from mitlc.gym.wrapper import (
    ENV_ID,
    EpisodeCutWarning,
    TaskWrapper,
    TaskWrapperError,
    make_task_env,
)

__all__ = ["ENV_ID", "EpisodeCutWarning", "TaskWrapper", "TaskWrapperError", "make_task_env"]

"""The task on any gymnasium environment: :class:`TaskWrapper`, and the registered id
``mitlc/Task-v0`` (importing this package registers it)."""

from mitlc.gym.arguments import TaskWrapperError, TaskWrapperTypeError
from mitlc.gym.guide import StraightDistanceWarning
from mitlc.gym.registration import make_task_env
from mitlc.gym.wrapper import ENV_ID, EpisodeCutWarning, TaskWrapper

__all__ = [
    "ENV_ID",
    "EpisodeCutWarning",
    "StraightDistanceWarning",
    "TaskWrapper",
    "TaskWrapperError",
    "TaskWrapperTypeError",
    "make_task_env",
]

"""Timed tasks for teams on any PettingZoo ``ParallelEnv``: :class:`TeamTaskWrapper` (needs the
``teams`` extra: ``pip install 'mitlc[teams]'``)."""

from mitlc.pettingzoo.tasks import Run, Task, TeamTaskError, TeamTaskTypeError
from mitlc.pettingzoo.wrapper import TeamTaskWrapper

__all__ = ["Run", "Task", "TeamTaskError", "TeamTaskTypeError", "TeamTaskWrapper"]

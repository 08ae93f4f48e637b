"""The task as one component: its rules (:mod:`mitlc.task.rules`) and the monitor that follows
a run of its automaton along an episode's letters (:mod:`mitlc.task.monitor`)."""

from mitlc.task.monitor import BatchOutcome, MonitorState, Outcome, TaskAutomaton, TaskMonitor
from mitlc.task.rules import PENDING, SATISFIED, VERDICT_NAMES, VIOLATED

__all__ = [
    "PENDING",
    "SATISFIED",
    "VERDICT_NAMES",
    "VIOLATED",
    "BatchOutcome",
    "MonitorState",
    "Outcome",
    "TaskAutomaton",
    "TaskMonitor",
]

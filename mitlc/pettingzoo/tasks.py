"""The tasks of a team: each compiled once (:func:`compile_task`), and followed along an
episode by a :class:`Run` whose every step, verdict, reward, success and round is
:class:`mitlc.task.TaskMonitor`'s (the one definition of a task step); the rest of a run whose
world has ended is :func:`mitlc.gym.reading.run_out`, as in the gymnasium wrapper.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from mitlc.automata import DigitalAutomaton
from mitlc.errors import MitlcError
from mitlc.gym.arguments import task_of
from mitlc.gym.parts import TaskPart
from mitlc.gym.reading import run_out
from mitlc.task import MonitorState, Outcome, TaskMonitor
from mitlc.task.rules import TaskRewards, terminated

TaskObs = Literal["state", "clocks"]


class TeamTaskError(MitlcError, ValueError):
    """A team task wrapper cannot be built as asked (an unknown agent, a proposition no label
    declares, a task with epsilon jumps, ...), or is used out of turn."""


class TeamTaskTypeError(TeamTaskError, TypeError):
    """An argument of the team task wrapper has the wrong type."""


@dataclass(frozen=True, slots=True)
class Task:
    """A compiled task: where it was given (``tasks.<agent>`` or ``team``), its eager
    automaton, the monitor over it, and its part of an observation (:class:`TaskPart`)."""

    where: str
    automaton: DigitalAutomaton
    monitor: TaskMonitor
    part: TaskPart

    @property
    def propositions(self) -> tuple[str, ...]:
        """The automaton's propositions: bit ``i`` of a letter is ``propositions[i]``."""
        return self.automaton.propositions


def compile_task(spec: Any, where: str, rewards: TaskRewards, task_obs: TaskObs) -> Task:
    """The task of ``spec`` (a formula's text or an eager automaton) given at ``where``. A task
    whose automaton has epsilon jumps is refused: this wrapper chooses no jumps."""
    if not isinstance(spec, str | DigitalAutomaton):
        if all(hasattr(spec, n) for n in ("propositions", "successor", "jumps")):
            raise TeamTaskError(
                f"{where}: a lazy automaton is not taken (its states are not known ahead); give "
                "the formula's text or an eager automaton (mitlc.automata.translate)"
            )
        raise TeamTaskTypeError(
            f"{where}: expected a formula's text (str) or an automaton, got {type(spec).__name__}"
        )
    try:
        automaton, clocks = task_of(spec, task_obs, where)
    except MitlcError as err:
        if isinstance(err, TeamTaskError) or not isinstance(err, ValueError):
            raise
        raise TeamTaskError(f"{where}: {err}") from None
    assert isinstance(automaton, DigitalAutomaton)
    monitor = TaskMonitor(automaton, rewards)
    count = len(automaton.states)
    if count:
        monitor.jumps(count - 1)  # learns every state at once
    jumpy = [q for q in range(count) if monitor.jumps(q)]
    if jumpy:
        raise TeamTaskError(
            f"{where}: the task {automaton.formula!r} has epsilon jumps (automaton states "
            f"{jumpy[:5]}): this version of the team wrapper takes no jumps (no action chooses "
            "one); give a task without them, such as a bounded deadline, G F a or G (a -> F b)"
        )
    return Task(where, automaton, monitor, TaskPart.of(count, automaton.num_sets, clocks))


class Run:
    """One task's run along an episode: the monitor's state, and the verdict, decision and
    success of its last step (or of its start)."""

    __slots__ = ("decided", "state", "success", "task", "verdict")

    def __init__(self, task: Task) -> None:
        self.task = task
        self.state: MonitorState = task.monitor.reset()
        self.verdict, self.decided, self.success = 0, False, False
        self.restart()

    def restart(self) -> None:
        """Back to the start of a run (position 0, nothing read)."""
        monitor = self.task.monitor
        self.state = monitor.reset()
        self.verdict = monitor.verdict(self.state.q)
        self.decided = bool(terminated(self.verdict))
        self.success = monitor.success(self.state)

    def step(self, letter: int) -> Outcome:
        """The monitor reads ``letter``, that of the position being left."""
        return self._keep(self.task.monitor.step(self.state, letter))

    def finish(self, last: Outcome, letter: int, horizon: int) -> Outcome:
        """The rest of the run after ``last``, the step whose world ended: ``letter`` (the
        world's last position) read until the task is decided or ``horizon`` is reached."""
        return self._keep(run_out(self.task.monitor, last, letter, horizon))

    def observe(self) -> dict[str, Any]:
        """The task's part of an observation now."""
        return self.task.part.observe(self.state.q, self.state.frontier)

    def _keep(self, out: Outcome) -> Outcome:
        self.state, self.verdict = out.state, out.verdict
        self.decided, self.success = bool(out.terminated), bool(out.success)
        return out

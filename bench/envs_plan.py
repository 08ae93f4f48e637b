"""What bench/envs_bench.py runs: its tasks, arms and targets (issue 24), the plan of runs and
each run's ``mitlc train`` command (see envs_bench.py's docstring)."""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
MITLC = [sys.executable, "-m", "mitlc"]
Records = dict[str, dict[str, list[dict[str, Any]]]]
"""Finished runs' records by task and arm."""
RECORDS = ROOT / "bench" / "results" / "envs"
"""Where full-budget runs keep their records, in git: the machine the bench ran on may not be
the next sitting's, and a record outlives its run directory."""


@dataclass(frozen=True)
class Arm:
    """How a task is learned: ``--set`` settings, whether counterfactual experience is asked for,
    and, for an arm of its own learner, the algorithm and its budget in episodes."""

    name: str
    settings: tuple[str, ...]
    crm: bool
    algo: str | None = None
    """None: the task's algorithm and env-step budget."""
    episodes: int | None = None
    """The budget of ``algo`` in episodes (``--episodes``) in place of the task's env steps."""


@dataclass(frozen=True)
class Task:
    """A world file, the SB3 algorithm both arms run and its budget (env steps, ``sb3.steps``)."""

    name: str
    world: str
    algo: str
    steps: int
    settings: tuple[str, ...] = ()
    """More ``--set`` settings of every arm on this task (besides the arm's own)."""
    eval_episodes: int = 10_000
    extra_arms: tuple[Arm, ...] = ()


ARMS = (
    Arm("plain", ("task_obs=state", "shaping=0"), crm=False),
    Arm("mitlc", ("task_obs=clocks", "shaping=1"), crm=False),
)

ENV_EVAL = 200
"""Greedy evaluation episodes on env worlds (slow: a gymnasium env steps one at a time)."""

TASKS = (
    # 292 rollouts of 8 envs x 128 steps: PPO ends on a whole rollout, so 299,008 is the last
    # one within the 300,000 steps.
    Task("doorkey", "specs/envs/minigrid-doorkey.yaml", "sb3-ppo", 299_008,
         ("sb3.num_envs=8", "sb3.n_steps=128"), eval_episodes=ENV_EVAL),
    # MiniGrid Empty 8x8 with two deadlines (issue 24's second table row): 147 rollouts.
    Task("empty", "specs/envs/minigrid-empty.yaml", "sb3-ppo", 150_528,
         ("sb3.num_envs=8", "sb3.n_steps=128"), eval_episodes=ENV_EVAL),
    # Half the 300,000 steps (within its target), as the world file trains: SAC is
    # about 125 env steps/s here, so a run is about 20 minutes.
    Task("pointmaze", "specs/envs/pointmaze.yaml", "sb3-sac", 150_000, eval_episodes=ENV_EVAL,
         extra_arms=(Arm("mitlc-crm", ("task_obs=clocks", "shaping=1", "sb3.crm_share=0.5"),
                         crm=True),)),
    # PointMaze_Medium-v3 (issue 44): every arm without the way (task settings), as the
    # world file trains before it gained it, then with it and acting along it first
    # (``mitlc-way``: the world file as shipped; the way's arms win, coming later).
    Task("maze", "specs/envs/pointmaze-medium.yaml", "sb3-sac", 150_000,
         ("guide=false", "sb3.guide_warmup=0"), eval_episodes=ENV_EVAL,
         extra_arms=(Arm("mitlc-crm", ("task_obs=clocks", "shaping=1", "sb3.crm_share=0.5"),
                         crm=True),
                     Arm("mitlc-way", ("task_obs=clocks", "shaping=1", "guide=true",
                                       "sb3.guide_warmup=20000"), crm=False),
                     Arm("mitlc-way-crm", ("task_obs=clocks", "shaping=1", "guide=true",
                                           "sb3.guide_warmup=20000", "sb3.crm_share=0.5"),
                         crm=True))),
    Task("case1c", "specs/continuous/case1.yaml", "sb3-ppo", 150_000),
    Task("case2c", "specs/continuous/case2.yaml", "sb3-recurrent-ppo", 150_000),
    Task("case2", "specs/paper/case2.yaml", "sb3-recurrent-ppo", 150_000,
         extra_arms=(Arm("mitlc-q", ("shaping=1",), crm=False, algo="q",
                         episodes=200_000),)),
)  # fmt: skip

CASE2_LOWER = 0.963648
"""The best lower bound of case 2's optimum (``mitlc check specs/paper/case2.yaml``)."""


@dataclass(frozen=True)
class Target:
    """Issue 24's target: mean greedy success over the seeds of ``arm`` on ``task`` at least
    ``success``, every run within ``steps`` env steps and ``seconds`` of mean wall time."""

    task: str
    arm: str
    success: float
    text: str
    steps: int | None = None
    seconds: float | None = None


TARGETS = (
    Target("doorkey", "mitlc", 0.9, "DoorKey-5x5 >= 0.9 within 300,000 steps", steps=300_000),
    Target("pointmaze", "mitlc", 0.9, "PointMaze_UMaze >= 0.9 within 300,000 steps",
           steps=300_000),
    Target("maze", "mitlc-way", 0.9, "PointMaze_Medium >= 0.9 within 300,000 steps",
           steps=300_000),
    Target("case2", "mitlc-q", 0.95 * CASE2_LOWER,
           f"case 2 POMDP >= 0.95 x {CASE2_LOWER} = {0.95 * CASE2_LOWER:.4f} in under 120 s",
           seconds=120.0),
)  # fmt: skip


def crm_section(algo: str) -> str | None:
    """The settings section whose ``crm`` field ``algo`` reads, where it has one and the
    learner takes it (SB3's counterfactual experience goes into a replay memory: its
    off-policy algorithms only); None otherwise. Read from the config classes, so the bench
    works before and after a learner gains the field."""
    from mitlc.learn.backends.sb3_offpolicy import OFF_POLICY
    from mitlc.learn.config import TrainConfig

    if algo.startswith("sb3-") and algo not in OFF_POLICY:
        return None
    section = "sb3" if algo.startswith("sb3-") else algo
    config = getattr(TrainConfig(), section, None)
    if config is None or "crm" not in {f.name for f in dataclasses.fields(config)}:
        return None
    return section


@dataclass
class Run:
    """One (task, arm, seed) and where it lives: ``DIR/run`` is the run directory,
    ``DIR/train.json`` the timed train process, ``DIR/result.json`` the finished record."""

    task: Task
    arm: Arm
    seed: int
    directory: Path
    result: dict[str, Any] | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def label(self) -> str:
        return f"{self.task.name} {self.arm.name} s{self.seed}"


def plan(tasks: list[Task], seeds: list[int], out: Path,
         arms: list[str] | None = None) -> list[Run]:  # fmt: skip
    """Every (task, arm, seed) of ``tasks`` in their order, of ``arms`` (in its order) where
    given."""
    runs = []
    for task in tasks:
        own = {arm.name: arm for arm in (*ARMS, *task.extra_arms)}
        for arm in [own[a] for a in arms if a in own] if arms is not None else own.values():
            for seed in seeds:
                runs.append(Run(task, arm, seed, out / task.name / arm.name / f"s{seed}"))
    return runs


def timed(run: Run) -> bool:
    """Whether a target of :data:`TARGETS` holds ``run``'s wall time (it must run alone)."""
    return any(t.seconds is not None and (t.task, t.arm) == (run.task.name, run.arm.name)
               for t in TARGETS)  # fmt: skip


def crm_on(run: Run) -> bool:
    """Whether ``run`` asks for counterfactual experience: its arm's, unless the learner has
    refused it (its notes say so)."""
    return run.arm.crm and not any(note.startswith("crm refused") for note in run.notes)


def command(run: Run, scale: float, device: str | None, crm: bool) -> list[str]:
    """The ``mitlc train`` command of ``run`` (budgets times ``scale``)."""
    algo = run.arm.algo or run.task.algo
    line = [*MITLC, "train", run.task.world, "--algo", algo, "--seed", str(run.seed)]
    line += ["--out", str(run.directory / "run"), "--quiet", "--no-eval"]
    if run.arm.episodes is not None:
        line += ["--episodes", str(max(1, round(run.arm.episodes * scale)))]
    else:
        line += ["--set", f"sb3.steps={max(1, round(run.task.steps * scale))}"]
    for setting in (*run.task.settings, *run.arm.settings):
        line += ["--set", setting]
    section = crm_section(algo)
    if section is not None:  # the plain arm turns it off, whatever the world file says
        line += ["--set", f"{section}.crm={'true' if crm else 'false'}"]
    if device is not None:
        line += ["--device", device]
    return line

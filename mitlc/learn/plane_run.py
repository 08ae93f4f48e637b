"""Learning a continuous world (``plane:``) from the command line: its setting, learner,
simulator and greedy evaluation.

A continuous world is not finite, so there is no product: the learner (DQN, the deep learner
that reads a Box observation, :meth:`mitlc.learn.nets.Encoder.of_spaces`) steps a
:class:`mitlc.learn.envvec.VectorTask` of the world's wrapped envs
(:func:`mitlc.worlds.plane_env.make_plane_env`), and the run directory, metrics and checkpoints
are those of :mod:`mitlc.learn.run`. A checkpoint holds the learner, the tally and, for each
env, the robot's position, the task monitor's state and the env's random state, so a resumed
run goes on exactly. Evaluation is Monte-Carlo only: no exact optimum exists, and the reports
say so.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np
from gymnasium.spaces import Discrete

from mitlc.automata import DigitalAutomaton, translate
from mitlc.learn.base import Learner, Policy
from mitlc.learn.config import TrainConfig
from mitlc.learn.envvec import VectorTask, task_vector
from mitlc.learn.rundir import RunError
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline
from mitlc.syntax import parse
from mitlc.worlds.plane import PlaneWorld

LEARNERS = ("dqn", "drqn")
"""The learners of a continuous world from the command line."""


@dataclass(frozen=True, slots=True)
class PlaneSetting:
    """A continuous world's run: the world, its task's automaton and the settings."""

    world_path: Path
    world: PlaneWorld
    automaton: DigitalAutomaton
    config: TrainConfig


def prepare_plane(
    world_path: Path,
    config: TrainConfig,
    spec: str | None = None,
    *,
    deadline: Deadline | None = None,
) -> PlaneSetting:
    """Load the continuous world and compile its task (``spec`` in its place if given)."""
    from mitlc.worlds.load import load_plane_world

    clock = Deadline.of(deadline, DEFAULT_TIME_LIMIT, "setting up the run")
    world = load_plane_world(world_path, spec)
    automaton = translate(parse(world.spec, world.spec_source), deadline=clock)
    return PlaneSetting(world_path, world, automaton, config)


def make_vector(setting: PlaneSetting, num_envs: int, seed: int) -> VectorTask:
    """``num_envs`` wrapped envs of the world, the first reset with ``seed``."""
    from mitlc.worlds.plane_env import plane_task

    envs = [plane_task(setting.world, automaton=setting.automaton) for _ in range(num_envs)]
    return task_vector(envs, seed=seed)


def make_plane_learner(setting: PlaneSetting, rng: np.random.Generator) -> Learner:
    """The run's learner on the world's wrapped envs: DQN, or the recurrent DQN (for a world
    with a noisy sensor)."""
    config = setting.config
    if config.algo not in LEARNERS:
        raise RunError(
            f"{config.algo} does not learn a continuous world yet (it is not finite: "
            f"use --algo {' or '.join(LEARNERS)})"
        )
    if config.dqn.crm:
        raise RunError("counterfactual experience needs a finite product: not here")
    from mitlc.learn.base import automaton_potential
    from mitlc.learn.nets import Encoder

    phi = automaton_potential(setting.automaton, config.shaping) if config.shaping else None

    probe = make_vector(setting, 1, 0)
    space = probe.observation_space
    recurrent = config.algo == "drqn"
    encoder = Encoder.of_spaces(
        space[probe.env_key],
        int(cast("Discrete", space["automaton"]).n),
        setting.automaton.num_sets,
        probe.num_actions,
        previous_action=recurrent and config.drqn.previous_action,
        tiles=config.drqn.tiles if recurrent else config.dqn.tiles,
    )
    if recurrent:
        from mitlc.learn.drqn import DRQNLearner

        return DRQNLearner(
            None, config, rng, phi, encoder=encoder, num_actions=probe.num_actions,
            horizon=setting.world.horizon,
        )  # fmt: skip
    from mitlc.learn.dqn import DQNLearner

    return DQNLearner(None, config, rng, phi, encoder=encoder, num_actions=probe.num_actions)


def monte_carlo_plane(
    setting: PlaneSetting, policy: Policy, episodes: int, seed: int
) -> tuple[int, float]:
    """Successes and mean return of ``episodes`` greedy episodes (64 at a time)."""
    width = min(64, episodes)
    vector = make_vector(setting, width, seed)
    policy.reset(width)
    wins, returns, ended = 0, 0.0, 0
    while ended < episodes:
        step = vector.step(policy.act(vector))
        policy.observe(step)
        done = np.flatnonzero(step.done)[: episodes - ended]
        wins += int(step.success[done].sum())
        returns += float(step.episode_return[done].sum())
        ended += len(done)
    return wins, returns / max(ended, 1)


def rollouts_plane(
    setting: PlaneSetting, policy: Policy, count: int, seed: int
) -> list[tuple[list[tuple[float, float]], bool]]:
    """``count`` greedy trajectories (positions) and whether each succeeded."""
    drawn = []
    for k in range(count):
        vector = make_vector(setting, 1, seed + k)
        policy.reset(1)
        x, y = vector.envs[0].unwrapped.position
        path = [(float(x), float(y))]
        while True:
            step = vector.step(policy.act(vector))
            policy.observe(step)
            x, y = vector.reached("position")[0]
            path.append((float(x), float(y)))
            if step.done[0]:
                drawn.append((path, bool(step.success[0])))
                break
    return drawn

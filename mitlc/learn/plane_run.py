"""Learning a world that is not finite from the command line: a continuous world (``plane:``)
or a gymnasium env without a transition table (``env:``, :mod:`mitlc.worlds.env_task`). Its
setting, learner, vector of wrapped envs and greedy evaluation.

There is no product: the learner steps a :class:`mitlc.learn.envvec.VectorTask` of the world's
wrapped envs (:func:`mitlc.worlds.plane_env.plane_task`, :meth:`EnvTask.make`): DQN or the
recurrent DQN on any observation (:meth:`mitlc.learn.nets.Encoder.of_spaces`), or tabular
Q-learning where the env's observation is discrete
(:class:`mitlc.learn.qlearning_env.ObservedQLearner`). The run directory, metrics and
checkpoints are those of :mod:`mitlc.learn.run`. A checkpoint holds the learner, the tally and,
for each env, the task monitor's state and, where the env has one (a continuous world's
robot), the env's state, so a resumed run of a continuous world goes on exactly. Evaluation is
Monte-Carlo only (:func:`mitlc.learn.montecarlo.monte_carlo` over :func:`open_batches`, the one
estimate of every kind of world): no exact optimum exists, and the reports say so.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
from gymnasium.spaces import Discrete

from mitlc.automata import DigitalAutomaton, translate
from mitlc.learn.base import Learner, Policy
from mitlc.learn.config import TrainConfig
from mitlc.learn.envvec import VectorTask, task_vector
from mitlc.learn.montecarlo import Batches
from mitlc.learn.rundir import RunError
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline
from mitlc.syntax import parse
from mitlc.worlds.env_task import EnvTask
from mitlc.worlds.plane import PlaneWorld

LEARNERS = ("q", "dqn", "drqn")
"""The learners of a world that is not finite (``q`` for a discrete observation only)."""


@dataclass(frozen=True, slots=True)
class OpenSetting:
    """The run of a world that is not finite: the world, its task's automaton, the settings."""

    world_path: Path
    world: PlaneWorld | EnvTask
    automaton: DigitalAutomaton
    config: TrainConfig


def prepare_open(
    world_path: Path,
    config: TrainConfig,
    spec: str | None = None,
    *,
    deadline: Deadline | None = None,
) -> OpenSetting:
    """Load the world and compile its task (``spec`` in its place if given)."""
    from mitlc.worlds.env_task import load_env_task
    from mitlc.worlds.load import is_plane_world, load_plane_world

    clock = Deadline.of(deadline, DEFAULT_TIME_LIMIT, "setting up the run")
    world: PlaneWorld | EnvTask = (
        load_plane_world(world_path, spec)
        if is_plane_world(world_path)
        else load_env_task(world_path, spec)
    )
    automaton = translate(parse(world.spec, world.spec_source), deadline=clock)
    return OpenSetting(world_path, world, automaton, config)


def open_env(setting: OpenSetting, *, flatten: bool = False) -> Any:
    """A fresh wrapped env of the world (:class:`mitlc.gym.TaskWrapper`)."""
    from mitlc.worlds.plane_env import plane_task

    world, automaton = setting.world, setting.automaton
    if isinstance(world, PlaneWorld):
        return plane_task(world, automaton=automaton, flatten=flatten)
    return world.make(automaton, flatten=flatten)


def make_vector(setting: OpenSetting, num_envs: int, seed: int) -> VectorTask:
    """``num_envs`` wrapped envs of the world, the first reset with ``seed``."""
    return task_vector([open_env(setting) for _ in range(num_envs)], seed=seed)


def open_batches(setting: OpenSetting, seed: int) -> Batches:
    """The batches of :func:`mitlc.learn.montecarlo.monte_carlo` in the world's wrapped envs:
    episode ``j`` of an estimate starts from a reset with ``base + j``, ``base`` a 63-bit
    number drawn from ``seed`` (so that the estimates of nearby seeds share no episodes)."""
    base = int(np.random.SeedSequence(seed).generate_state(1, np.uint64)[0] >> np.uint64(1))

    def batch(count: int, first: int) -> VectorTask:
        return make_vector(setting, count, base + first)

    return batch


def make_open_learner(setting: OpenSetting, rng: np.random.Generator) -> Learner:
    """The run's learner on the world's wrapped envs: DQN, the recurrent DQN (for a world
    with a noisy sensor) or, on a discrete observation, tabular Q-learning."""
    config = setting.config
    if config.algo not in LEARNERS:
        raise RunError(
            f"{config.algo} does not learn this world yet (it is not finite: "
            f"use --algo {', '.join(LEARNERS)})"
        )
    if (config.algo == "dqn" and config.dqn.crm) or (config.algo == "q" and config.q.crm):
        raise RunError("counterfactual experience needs a finite product: not here")
    from mitlc.learn.base import automaton_potential
    from mitlc.learn.nets import Encoder

    phi = automaton_potential(setting.automaton, config.shaping) if config.shaping else None
    probe = make_vector(setting, 1, 0)
    space = probe.observation_space
    own = space[probe.env_key]
    num_q = int(cast("Discrete", space["automaton"]).n)
    if config.algo == "q":
        if not isinstance(own, Discrete):
            raise RunError(f"tabular Q-learning needs a discrete observation, not {own}: use "
                           "--algo dqn or drqn")  # fmt: skip
        if phi is not None:
            raise RunError("shaping with tabular Q-learning needs a finite product: not here")
        from mitlc.learn.qlearning_env import ObservedQLearner

        return ObservedQLearner(int(own.n), num_q, setting.automaton.num_sets,
                                probe.num_actions, config, rng)  # fmt: skip
    recurrent = config.algo == "drqn"
    encoder = Encoder.of_spaces(
        own,
        num_q,
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


def rollouts_plane(
    setting: OpenSetting, policy: Policy, count: int, seed: int
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

"""The learners of a world that is not finite: a continuous world (``plane:``) or a gymnasium
env without a transition table (``env:``, :mod:`mitlc.worlds.env_task`).

There is no product: the learner steps a :class:`mitlc.learn.envs.envvec.VectorTask` of the world's
wrapped envs (:func:`mitlc.learn.setting.task_vector_of`): DQN or the recurrent DQN on any
observation (its readable part, :func:`mitlc.gym.observations.readable`, through
:meth:`mitlc.learn.learners.nets.Encoder.of_spaces`; images through a CNN,
:mod:`mitlc.learn.learners.images`), or tabular Q-learning where the
env's
observation is discrete (:class:`mitlc.learn.learners.qlearning_env.ObservedQLearner`). DQN
takes counterfactual experience over the task's states (``dqn.crm``,
:mod:`mitlc.learn.learners.crm_env`, shaped as the run is), and so does tabular Q-learning
(``q.crm``, without shaping, which it takes on a finite product only). The run
directory, metrics and checkpoints are those of every run (:mod:`mitlc.learn.run`). A
checkpoint holds the learner, the tally and, for each env, the task monitor's state and, where
the env has one (a continuous world's robot), the env's state, so a resumed run of a
continuous world goes on exactly. Evaluation is Monte-Carlo only
(:func:`mitlc.learn.evaluation.montecarlo.monte_carlo` over :func:`mitlc.learn.setting.batches`,
the one
estimate of every kind of world): no exact optimum exists, and the reports say so.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import numpy as np
from gymnasium.spaces import Discrete

from mitlc.learn.learners.base import Learner
from mitlc.learn.rundir.files import RunError
from mitlc.learn.setting import Setting, task_vector_of

if TYPE_CHECKING:
    from mitlc.learn.learners.crm_env import EnvCounterfactuals

LEARNERS = ("q", "dqn", "drqn")
"""The learners of a world that is not finite (``q`` for a discrete observation only)."""


def make_open_learner(setting: Setting, rng: np.random.Generator) -> Learner:
    """The run's learner on the world's wrapped envs: DQN, the recurrent DQN (for a world
    with a noisy sensor) or, on a discrete observation, tabular Q-learning."""
    config = setting.config
    if config.algo not in LEARNERS:
        raise RunError(
            f"{config.algo} does not learn this world yet (it is not finite: "
            f"use --algo {', '.join(LEARNERS)})"
        )
    crm = (config.algo == "dqn" and config.dqn.crm) or (config.algo == "q" and config.q.crm)
    from mitlc.learn.learners.base import EnvShaping
    from mitlc.learn.learners.encoder import Encoder, task_features

    shaping = EnvShaping(config.shaping) if config.shaping else None
    probe = task_vector_of(setting, 1, 0)
    space = probe.observation_space
    own = space[probe.env_key]
    num_q = int(cast("Discrete", space["automaton"]).n)
    if probe.continuous:
        actions = probe.venv.single_action_space
        raise RunError(f"{config.algo} takes Discrete actions, and this env's are {actions}: "
                       "use --algo sb3-ppo")  # fmt: skip
    if config.algo == "q":
        if not isinstance(own, Discrete):
            raise RunError(f"tabular Q-learning needs a discrete observation, not {own}: use "
                           "--algo dqn or drqn")  # fmt: skip
        if shaping is not None:
            raise RunError("shaping with tabular Q-learning needs a finite product: not here")
        from mitlc.learn.learners.qlearning_env import ObservedQLearner

        return ObservedQLearner(int(own.n), num_q, setting.automaton.num_sets,
                                probe.num_actions, config, rng,
                                counterfactuals=_counterfactuals(probe, crm))  # fmt: skip
    recurrent = config.algo == "drqn"
    encoder = Encoder.of_spaces(
        own,
        num_q,
        setting.automaton.num_sets,
        probe.num_actions,
        previous_action=recurrent and config.drqn.previous_action,
        tiles=config.drqn.tiles if recurrent else config.dqn.tiles,
        images=probe.images,
        task_features=task_features(setting.automaton, config.task_obs),
    )
    if recurrent:
        from mitlc.learn.learners.drqn import DRQNLearner

        return DRQNLearner(
            None, config, rng, shaping, encoder=encoder, num_actions=probe.num_actions,
            horizon=setting.world.horizon,
        )  # fmt: skip
    from mitlc.learn.learners.dqn import DQNLearner

    return DQNLearner(None, config, rng, shaping, _counterfactuals(probe, crm), encoder=encoder,
                      num_actions=probe.num_actions)  # fmt: skip


def _counterfactuals(probe: Any, crm: bool) -> EnvCounterfactuals | None:
    """The task states of the world's wrapped env, for counterfactual experience (``None``
    without it); a :class:`RunError` where they cannot be known."""
    from mitlc.learn.learners.crm_env import CounterfactualError, EnvCounterfactuals

    try:
        return EnvCounterfactuals.of(probe.envs[0]) if crm else None
    except CounterfactualError as err:
        raise RunError(f"crm: {err}") from None

"""The off-policy algorithms of the SB3 backend (:mod:`mitlc.learn.backends.sb3`): ``sb3-dqn``,
and for worlds whose env takes continuous actions (a ``Box``, e.g. gymnasium-robotics'
PointMaze) ``sb3-sac`` (SAC, Haarnoja et al., ICML 2018) and ``sb3-td3`` (TD3, Fujimoto, van
Hoof and Meger, ICML 2018).

* **Settings**: the ``sb3`` section's replay and update fields (``buffer_size``,
  ``learning_starts``, ``tau``, ``train_freq``, ``gradient_steps``; a 0 means SB3's default),
  DQN's exploration schedule and target copies, SAC's ``ent_coef`` (0: SB3's ``"auto"``, the
  coefficient learned toward the target entropy) and TD3's ``noise_std`` (Gaussian action
  noise, on SB3's actions scaled to [-1, 1]; 0: none).
* **Actions**: SAC and TD3 need a ``Box`` action space; on another a :class:`RunError` says
  which backends take it, before the run directory is made.
* **Checkpoints** hold what SB3 itself declares as its model's state
  (``_get_torch_save_params``): the policy (SAC: actor, critic, critic_target; TD3 also the
  actor_target), every optimiser (actor and critic; SAC's entropy coefficient's when it is
  learned) and SAC's ``log_ent_coef``; and the replay memory
  (:mod:`mitlc.learn.backends.sb3_replay`), so a resumed run samples from what the stopped one
  had and learns from its first step.
* **Counterfactual experience** (``sb3.crm``): the replay memory also stores the transitions of
  the task's other states (:mod:`mitlc.learn.backends.sb3_crm`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from mitlc.learn.config import TrainConfig
from mitlc.learn.rundir.files import RunError

OFF_POLICY = ("sb3-dqn", "sb3-sac", "sb3-td3")
"""The backends that learn from a replay memory (checkpointed with the model)."""

CONTINUOUS = ("sb3-sac", "sb3-td3")
"""The backends that need a ``Box`` action space."""

OTHERS = "sb3-ppo, sb3-dqn, sb3-maskable-ppo or sb3-recurrent-ppo"
"""The backends that take a world's discrete actions."""


def offpolicy_settings(config: TrainConfig) -> tuple[dict[str, Any], dict[str, float]]:
    """The keywords of an off-policy algorithm: those always given, and those given where they
    are not 0 (else SB3's default)."""
    s = config.sb3
    given: dict[str, Any] = {"learning_starts": s.learning_starts}
    if config.algo == "sb3-dqn":
        given.update(
            exploration_fraction=s.exploration_fraction,
            exploration_final_eps=s.exploration_final_eps,
            target_update_interval=s.target_update_interval,
        )
    elif config.algo == "sb3-sac":
        given["ent_coef"] = s.ent_coef or "auto"
    optional: dict[str, float] = {
        "buffer_size": s.buffer_size,
        "tau": s.tau,
        "train_freq": s.train_freq,
        "gradient_steps": s.gradient_steps,
    }
    return given, optional


def offpolicy_extras(config: TrainConfig, env: Any) -> dict[str, Any]:
    """The keywords of the algorithm learning on ``env`` that a checkpoint does not hold: TD3's
    :func:`action_noise` and, with ``sb3.crm``, the replay memory of
    :func:`mitlc.learn.backends.sb3_crm.replay_settings`."""
    given = action_noise(config, env.action_space)
    if config.sb3.crm:
        from mitlc.learn.backends.sb3_crm import replay_settings

        given.update(replay_settings(config, env))
    return given


def action_noise(config: TrainConfig, space: Any) -> dict[str, Any]:
    """TD3's ``action_noise`` keyword for the action space ``space`` (none for the others, or
    with ``sb3.noise_std`` 0)."""
    if config.algo != "sb3-td3" or not config.sb3.noise_std or not isinstance(space, spaces.Box):
        return {}
    from stable_baselines3.common.noise import NormalActionNoise

    shape = space.shape
    sigma = np.full(shape, config.sb3.noise_std)
    return {"action_noise": NormalActionNoise(mean=np.zeros(shape), sigma=sigma)}


def needs_box(algo: str, make_env: Callable[[], Any], where: Path) -> None:
    """For ``algo`` in :data:`CONTINUOUS`, a :class:`RunError` unless the action space of the
    env ``make_env`` makes (the wrapped env of the world at ``where``) is a ``Box``."""
    if algo not in CONTINUOUS:
        return
    env = make_env()
    space = env.action_space
    env.close()
    if not isinstance(space, spaces.Box):
        raise RunError(
            f"{where}: --algo {algo} needs Box (continuous) actions, and this world's are "
            f"{space}; use {OTHERS}"
        )

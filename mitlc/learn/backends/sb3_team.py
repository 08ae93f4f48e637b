"""Stable-Baselines3 on a PettingZoo team world (``pettingzoo:`` files,
:mod:`mitlc.worlds.pettingzoo_world`): one policy shared by every agent, learned on
:class:`mitlc.pettingzoo.vector.TeamVecEnv` (an SB3 ``VecEnv`` with a slot per agent).

* **Training** (:func:`team_venv`, :func:`team_view`): ``sb3.num_envs`` teams, each agent a slot,
  under SB3's ``VecMonitor``; ``sb3.steps`` counts SB3's steps, one per agent and team step.
  ``metrics.jsonl`` counts team episodes: the callback reads each team's first slot, whose
  ``is_success`` is the team task's success, and the team's return (the mean of its agents').
* **Evaluation** (:class:`TeamEpisodes`, the batches of
  :func:`mitlc.learn.evaluation.montecarlo.monte_carlo` for this kind): slot ``i`` of a batch is
  a whole team episode, reset with its own seed; success is the team task's, rounds its rounds,
  the return the mean of the agents'. :class:`TeamPolicy` acts as SB3's
  ``predict(obs, deterministic=True)`` on every agent's slot.
* Only :data:`~mitlc.worlds.pettingzoo_world.LEARNED_BY` learn it (PPO and DQN); no shield
  (it needs the exact product), no shaping, no counterfactuals.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mitlc.learn.backends.loaded import LoadedLearner
from mitlc.learn.envs.vec import Step
from mitlc.learn.learners.base import Episodes, Policy
from mitlc.learn.learners.nets import build, configure_torch
from mitlc.learn.rundir import checkpoint
from mitlc.learn.rundir.files import RunError
from mitlc.learn.rundir.state import Mismatch, conform
from mitlc.learn.setting import Setting
from mitlc.worlds.model import BoolArray, IntArray
from mitlc.worlds.pettingzoo_world import TeamEnvTask


def _world(setting: Setting) -> TeamEnvTask:
    world = setting.world
    assert isinstance(world, TeamEnvTask), "a PettingZoo team world"
    return world


def check_team(setting: Setting) -> None:
    """A :class:`RunError` for the settings a team world does not take."""
    config = setting.config
    if config.sb3.crm or config.shaping:
        raise RunError(
            f"{setting.world_path}: a PettingZoo team world takes no sb3.crm and no shaping yet"
        )


def team_venv(setting: Setting, teams: int) -> Any:
    """``teams`` fresh teams of the world as SB3's ``VecMonitor`` over a ``TeamVecEnv``."""
    from stable_baselines3.common.vec_env import VecMonitor

    return VecMonitor(_world(setting).vec_env(teams))


def team_view(agents: int) -> Any:
    """What the run's callback reads of a vector step: each team's first slot, with the team's
    return (the mean of its agents') in ``info["episode"]["r"]`` where it ended."""

    def view(dones: Any, infos: list[dict[str, Any]]) -> tuple[Any, list[dict[str, Any]]]:
        firsts = []
        for base in range(0, len(infos), agents):
            info = dict(infos[base])
            if "team_verdict" in info:  # the run counts the team task's violations
                info["verdict"] = info["team_verdict"]
            if "episode" in info:
                returns = [float(infos[base + k]["episode"]["r"]) for k in range(agents)]
                info["episode"] = {**info["episode"], "r": sum(returns) / agents}
            firsts.append(info)
        return np.asarray(dones)[::agents], firsts

    return view


class TeamEpisodes:
    """A batch of whole team episodes for the Monte-Carlo estimate (module docstring): slot
    ``i`` is a team, reset first with ``seed + i``."""

    def __init__(self, setting: Setting, count: int, seed: int) -> None:
        self.vec = _world(setting).vec_env(count)
        self.num_envs, self.agents = count, self.vec.n
        self.vec.seed(seed)
        self.observation: Any = self.vec.reset()
        """Every agent's slot vector, ``(count * agents, size)``."""
        self.returns = np.zeros(self.vec.num_envs)
        self.steps = np.zeros(count, dtype=np.int64)
        actions = self.vec.action_space
        self.num_actions = int(getattr(actions, "n", 0))

    @property
    def envs(self) -> list[Any]:
        """For :class:`mitlc.learn.held.HeldLog`: the adapter, which holds the letters."""
        return list(self.vec.envs)

    @property
    def automaton(self) -> IntArray:
        """Unused by the team's policy (zeros)."""
        return np.zeros(self.num_envs, dtype=np.int64)

    mask = automaton
    state = automaton

    def valid_actions(self) -> BoolArray:
        """Every action (no shield here)."""
        return np.ones((self.num_envs, self.num_actions), dtype=np.bool_)

    def step(self, actions: IntArray) -> Step:
        """Step every agent's slot with ``actions``; each team's outcome."""
        self.vec.step_async(actions)
        obs, rewards, dones, infos = self.vec.step_wait()
        self.observation = obs
        self.returns += rewards
        n, count = self.agents, self.num_envs
        team_returns = self.returns.reshape(count, n).mean(axis=1)
        ended = np.asarray(dones).reshape(count, n)[:, 0]
        self.steps += 1
        success = np.array([bool(infos[t * n].get("is_success", False)) for t in range(count)])
        rounds = np.array([int(infos[t * n].get("team_rounds", 0)) for t in range(count)])
        zeros, none = np.zeros(count, dtype=np.int64), np.zeros(count, dtype=np.bool_)
        step = Step(
            reward=rewards.reshape(count, n).mean(axis=1), accepting=none, terminated=ended,
            truncated=none, next_state=zeros - 1, next_mask=zeros, next_observation=zeros,
            success=success & ended, episode_return=team_returns, episode_steps=self.steps.copy(),
            next_automaton=zeros, next_valid=self.valid_actions(), episode_rounds=rounds,
        )  # fmt: skip
        self.returns.reshape(count, n)[ended] = 0.0
        self.steps[ended] = 0
        return step


def team_batches(setting: Setting, base: int) -> Any:
    """The batches of :func:`mitlc.learn.evaluation.montecarlo.monte_carlo`: team episode ``j``
    starts from a reset with ``base + j``."""

    def batch(count: int, first: int) -> Episodes:
        return TeamEpisodes(setting, count, base + first)

    return batch


class TeamPolicy(Policy):
    """The shared SB3 policy acting on every agent's slot as ``predict(obs,
    deterministic=True)``."""

    def __init__(self, net: Any) -> None:
        self.net = net

    def act(self, env: Episodes) -> IntArray:
        """Each slot's action (``env``: :class:`TeamEpisodes`)."""
        actions, _ = self.net.predict(env.observation, deterministic=True)
        return np.asarray(actions)


class TeamLearner(LoadedLearner):
    """A trained shared policy loaded for ``mitlc eval`` and ``mitlc plot``."""

    def policy(self) -> Policy:
        """The greedy shared policy."""
        return TeamPolicy(self.net)


def load_team_learner(directory: Path, setting: Setting) -> TeamLearner:
    """The shared policy of the sb3 run in ``directory`` (its latest checkpoint), rebuilt from
    the settings and the adapter's spaces."""
    from mitlc.learn.backends.sb3 import algorithm, model_settings

    configure_torch()
    cls, name = algorithm(setting.config.algo)
    vec = _world(setting).vec_env(1)
    try:
        kwargs = model_settings(setting.config, vec)["policy_kwargs"]
        net = build(0, lambda: cls.policy_aliases[name](
            vec.observation_space, vec.action_space, lambda _: 0.0, **kwargs
        ))  # fmt: skip
    finally:
        vec.close()
    net.set_training_mode(False)
    loaded = checkpoint.load(directory)
    saved = loaded.state.get("model")
    try:
        if not isinstance(saved, dict) or "policy" not in saved:
            raise Mismatch("model", "no policy in the checkpoint")
        conform({"policy": saved["policy"]}, {"policy": dict(net.state_dict())}, "model")
    except Mismatch as err:
        raise RunError(f"{loaded.files.get(err.kind, loaded.files['json'])}: {err}") from None
    learner = TeamLearner(net, setting)
    learner.load_state_dict(saved)
    return learner

"""Stable-Baselines3 as a backend: ``mitlc train WORLD --algo sb3-ppo | sb3-dqn |
sb3-maskable-ppo | sb3-recurrent-ppo | sb3-sac | sb3-td3`` (the extra ``mitlc[sb3]``), into a
mitlc run directory. SAC and TD3 take continuous (``Box``) actions; what is particular to the
off-policy algorithms is in :mod:`mitlc.learn.backends.sb3_offpolicy`.

* **The env** is the world's wrapped env, :class:`~mitlc.product.env.ProductEnv` (a
  :class:`~mitlc.gym.TaskWrapper` on the world) with the wrapper's flat observation: one
  float32 vector, the one-hot world observation, the one-hot automaton state and the frontier's
  bits (the layout of ``TaskWrapper(..., flatten=True)`` and of mitlc's own deep learners), so
  every algorithm uses ``MlpPolicy`` (``MlpLstmPolicy`` for recurrent PPO); where the env's
  observation holds images, the policy reads each with a CNN first
  (:mod:`mitlc.learn.backends.sb3_images`). The ``Dict``
  observation with ``MultiInputPolicy`` gives the network the same information (SB3 one-hot
  encodes each ``Discrete`` part) at a higher cost per step (PPO on case 1: 14% slower), so
  the flat form is used. ``sb3.num_envs`` copies run in SB3's ``DummyVecEnv`` (``make_vec_env``,
  with its ``Monitor``); ``MaskablePPO`` reads the wrapper's ``action_masks()``.
* **Settings**: the ``sb3`` section of the training settings
  (:class:`~mitlc.learn.config.SB3Config`; a 0 means SB3's own default), the discount's
  ``gamma``, the run's ``seed`` (SB3's ``seed``) and ``device``
  (:func:`mitlc.learn.device.resolve_device`). The budget is ``sb3.steps`` environment
  steps, the run's total also when resumed; a PPO run ends at the first whole rollout past it.
  SB3 learns with a constant discount (``discount.mode: accepting`` is refused); ``task_obs``
  and ``shaping`` (:class:`mitlc.gym.shaping.ShapedReward`) are read as mitlc's learners read
  them.
* **The run directory** is mitlc's (:mod:`mitlc.learn.run`): ``config.json``,
  ``metrics.jsonl`` (a line every ``sb3.log_every`` steps from an SB3 callback: episodes,
  steps, the success rate from ``info["is_success"]`` and the mean return of the episodes ended
  since the last line, ``epsilon`` (DQN's exploration rate, 0 for the others), seconds),
  ``summary.json``, the lock, and checkpoints written by :mod:`mitlc.learn.rundir.checkpoint`
  (every ``sb3.checkpoint_every`` steps, at the end and on Ctrl-C): the ``state_dict()`` of the
  policy, of every optimiser and SB3's other tensors (SAC's entropy coefficient), as SB3 lists
  them (``_get_torch_save_params``), as safetensors, SB3's settings and counters as JSON; never
  SB3's zip, which holds pickles.
* **Resume** rebuilds the model from the settings and loads the policy, the optimisers and the
  counters (``num_timesteps`` included, so the schedules go on where they were), on the run's
  device or another (``--device`` may change). It does not replay the run exactly: the envs
  restart with new episodes (seeded by the seed plus the steps), a PPO rollout in progress is
  collected again. The replay memory of sb3-dqn, sb3-sac and sb3-td3 is saved with the model
  (:mod:`mitlc.learn.backends.sb3_replay`), so the resumed run samples from it and learns from
  its first step; where it was not saved (too large, or an older checkpoint) the resumed run
  refills it for ``sb3.learning_starts`` steps before it learns again.
* **eval and plot** (:func:`load_learner`, called by :func:`mitlc.learn.run.load_learner`;
  :mod:`mitlc.learn.backends.sb3_policy`): the policy acts greedily (as ``deterministic=True``)
  among
  the valid actions in mitlc's simulator of the product, the model of the wrapped env, fed the
  same observation vector; so a run is reported as mitlc's learners are: success with a Wilson
  interval beside ``pmax_horizon``, and for a memoryless policy on an MDP its exact success.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from operator import attrgetter
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import torch

from mitlc.automata.clocks import clocks_shown
from mitlc.gym.shaping import ShapedReward
from mitlc.learn.backends.sb3_offpolicy import (
    OFF_POLICY,
    needs_box,
    offpolicy_extras,
    offpolicy_settings,
)
from mitlc.learn.backends.sb3_replay import ReplayState
from mitlc.learn.backends.sb3_team import check_team, team_venv, team_view
from mitlc.learn.config import TrainConfig
from mitlc.learn.device import resolve_device
from mitlc.learn.held import run_never_held
from mitlc.learn.learners.nets import configure_torch
from mitlc.learn.rundir import checkpoint
from mitlc.learn.rundir.files import METRICS, SUMMARY, RunError
from mitlc.learn.rundir.runlog import (
    Progress,
    RunResult,
    Tally,
    log_window,
    progress_of,
    summary_of,
    truncate_metrics,
    write_json,
)
from mitlc.learn.rundir.state import one_line, restore
from mitlc.learn.setting import (
    Setting,
    is_team,
    opened_run,
    prepare,
    save_config,
    setting_notes,
)
from mitlc.limits import Deadline
from mitlc.product.worlds import task_env
from mitlc.worlds.door import AnyWorld

Vectors = npt.NDArray[np.float32]

ALGORITHMS = {
    "sb3-ppo": ("stable_baselines3", "PPO", "MlpPolicy"),
    "sb3-dqn": ("stable_baselines3", "DQN", "MlpPolicy"),
    "sb3-maskable-ppo": ("sb3_contrib", "MaskablePPO", "MlpPolicy"),
    "sb3-recurrent-ppo": ("sb3_contrib", "RecurrentPPO", "MlpLstmPolicy"),
    "sb3-sac": ("stable_baselines3", "SAC", "MlpPolicy"),
    "sb3-td3": ("stable_baselines3", "TD3", "MlpPolicy"),
}
"""mitlc's name of each backend: SB3's module, algorithm class and policy."""


def algorithm(algo: str) -> tuple[Any, str]:
    """The SB3 algorithm class and policy name of ``algo`` (a :class:`RunError` saying what to
    install when SB3 is missing)."""
    module, name, policy = ALGORITHMS[algo]
    try:
        return getattr(importlib.import_module(module), name), policy
    except ImportError:
        raise RunError(
            f"--algo {algo} needs Stable-Baselines3 and sb3-contrib: pip install 'mitlc[sb3]'"
        ) from None


# -- the observation -------------------------------------------------------------------------------


def wrapped_env(setting: Setting) -> Any:
    """The env an sb3 run learns on: the world's wrapped env with the wrapper's flat
    observation (the env's observation flattened, the task's state as a one-hot or by its
    clocks as ``task_obs`` says, frontier bits: the features of
    :class:`mitlc.learn.learners.encoder.Encoder`, which evaluation feeds the same network),
    for every kind of world (:func:`mitlc.product.worlds.task_env`); with ``shaping``, under
    :class:`mitlc.gym.shaping.ShapedReward` at the run's discount."""
    config = setting.config
    clocks = clocks_shown(setting.automaton, config.task_obs)
    options: dict[str, Any] = {"task_obs": "clocks" if clocks else "state"}
    if config.shaping or config.guide:
        options["potential"] = config.shaping_reach
    if config.guide:
        options["guide"] = True
    if setting.tables is not None and setting.tables.shield is not None:
        options["shield"], options["product"] = setting.tables.shield, setting.product
        options["shield_audit"] = not setting.tables.shield_enforced
    env: Any = task_env(setting.world, setting.automaton, flatten=True, **options)
    if config.shaping:
        env = ShapedReward(env, scale=config.shaping, gamma=config.discount.gamma)
    return env


def model_settings(config: TrainConfig, env: Any) -> dict[str, Any]:
    """The keywords given to the SB3 algorithm learning on ``env`` (:func:`wrapped_env`):
    :func:`sb3_settings`, with the features extractor of the images in ``env``'s observation
    (:func:`mitlc.learn.backends.sb3_images.image_policy_kwargs`) and what else a checkpoint
    does not hold (:func:`~mitlc.learn.backends.sb3_offpolicy.offpolicy_extras`)."""
    from mitlc.learn.backends.sb3_images import image_policy_kwargs

    given = sb3_settings(config)
    given["policy_kwargs"] = {**given["policy_kwargs"], **image_policy_kwargs(env)}
    given.update(offpolicy_extras(config, env))
    return given


def sb3_settings(config: TrainConfig) -> dict[str, Any]:
    """The keywords given to the SB3 algorithm (beside the env, seed and device)."""
    s = config.sb3
    given: dict[str, Any] = {
        "gamma": config.discount.gamma,
        "policy_kwargs": {"net_arch": [s.hidden] * s.layers},
    }
    if config.algo in OFF_POLICY:
        off, optional = offpolicy_settings(config)
        given.update(off)
    else:
        given.update(n_epochs=s.n_epochs, ent_coef=s.ent_coef)
        optional = {"n_steps": s.n_steps}
    optional.update(learning_rate=s.learning_rate, batch_size=s.batch_size)
    given.update({name: value for name, value in optional.items() if value})
    return given


# -- the model as checkpointed state ---------------------------------------------------------------


class ModelState:
    """An SB3 model as :class:`~mitlc.learn.rundir.state.Stateful` data: settings, the
    ``state_dict()`` of the policy and of each optimiser, SB3's other tensors, counters. The
    optimisers and tensors are those SB3 saves (``_get_torch_save_params``): the policy's
    ``optimizer`` (PPO family, DQN); ``actor_optimizer`` and ``critic_optimizer`` (SAC, TD3);
    SAC's ``ent_coef_optimizer`` and ``log_ent_coef`` (or the fixed ``ent_coef_tensor``)."""

    COUNTERS = ("num_timesteps", "_n_updates", "_episode_num", "_n_calls")

    def __init__(self, model: Any, config: TrainConfig) -> None:
        self.model, self.settings = model, {"algo": config.algo, **sb3_settings(config)}
        names, tensors = model._get_torch_save_params()
        self.optimizers = {
            "optimizer" if name == "policy.optimizer" else name.replace(".", "_"): name
            for name in names
            if name != "policy"
        }
        """Each optimiser's key in the state, and its attribute path in the model
        (``actor.optimizer``)."""
        self.tensors: tuple[str, ...] = tuple(tensors)
        memory = getattr(model, "replay_buffer", None)
        self.replay = None if memory is None else ReplayState(memory)
        """The off-policy algorithms' replay memory (:mod:`mitlc.learn.backends.sb3_replay`)."""

    def unchecked(self) -> tuple[str, ...]:
        """The optimisers' moments (a fresh optimiser has none yet: torch checks them against
        the network on loading) and the replay memory's rows (:class:`ReplayState` checks
        them)."""
        return (*(f"model.{key}.state" for key in self.optimizers), "model.replay.arrays")

    OPTIONAL = ("model.replay",)
    """What a checkpoint of an older mitlc lacks (:func:`~mitlc.learn.rundir.state.restore`)."""

    def state_dict(self) -> dict[str, Any]:
        """The checkpointed part of the model."""
        model = self.model
        state: dict[str, Any] = {
            "settings": self.settings,
            "policy": dict(model.policy.state_dict()),
        }
        for key, path in self.optimizers.items():
            state[key] = attrgetter(path)(model).state_dict()
        for name in self.tensors:
            state[name] = getattr(model, name).detach()
        state["counters"] = {n.strip("_"): int(getattr(model, n, 0)) for n in self.COUNTERS}
        if self.replay is not None:
            state["replay"] = self.replay.state_dict()
        return state

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Load :meth:`state_dict` into the model (on its device)."""
        if saved["settings"] != self.settings:
            raise ValueError("the checkpoint was made with other settings than the run's")
        self.model.policy.load_state_dict(saved["policy"])
        for key, path in self.optimizers.items():
            attrgetter(path)(self.model).load_state_dict(saved[key])
        with torch.no_grad():
            for name in self.tensors:
                getattr(self.model, name).copy_(saved[name])
        for name in self.COUNTERS:
            if hasattr(self.model, name):
                setattr(self.model, name, int(saved["counters"][name.strip("_")]))
        if self.replay is not None and "replay" in saved:
            self.replay.load_state_dict(saved["replay"])


# -- training --------------------------------------------------------------------------------------


def train(
    world_path: str | Path,
    config: TrainConfig,
    out: str | Path,
    *,
    spec: str | None = None,
    resume: bool = False,
    progress: Callable[[Progress], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    deadline: Deadline | None = None,
    notes: Callable[[str], None] | None = None,
    world: AnyWorld | None = None,
) -> RunResult:
    """Train ``config.algo`` (an ``sb3-*`` name) as :func:`mitlc.learn.run.train` trains
    mitlc's learners (same arguments), for ``config.sb3.steps`` environment steps in all, on
    ``config.device``."""
    if config.discount.mode != "constant":
        raise RunError(f"{config.algo}: SB3 learns with a constant discount")
    algorithm(config.algo)  # SB3 installed?
    device = resolve_device(config.device)
    directory = Path(out)
    setting = prepare(world_path, config, spec, deadline=deadline, world=world)
    if notes is not None:
        for note in setting_notes(setting):
            notes(note)
    if is_team(setting.world):  # a PettingZoo team: mitlc.learn.backends.sb3_team
        check_team(setting)
    else:
        needs_box(config.algo, lambda: wrapped_env(setting), setting.world_path)
    with opened_run(directory, setting, resume, sb3=True):
        return _train(directory, setting, device, resume, progress, should_stop, notes)


def _train(
    directory: Path,
    setting: Setting,
    device: torch.device,
    resume: bool,
    progress: Callable[[Progress], None] | None,
    should_stop: Callable[[], bool] | None,
    notes: Callable[[str], None] | None = None,
) -> RunResult:
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    config, s = setting.config, setting.config.sb3
    configure_torch()
    team = is_team(setting.world)  # a PettingZoo team: a slot per agent, one shared policy
    if team:
        venv = team_venv(setting, s.num_envs)
    else:
        venv = make_vec_env(
            lambda: wrapped_env(setting), s.num_envs, seed=config.seed, vec_env_cls=DummyVecEnv
        )
    cls, policy = algorithm(config.algo)
    assert team or isinstance(venv, DummyVecEnv)
    given = model_settings(config, venv if team else venv.envs[0])
    try:
        model = cls(policy, venv, seed=config.seed, device=device, verbose=0, **given)
    except (ValueError, TypeError, AssertionError, MemoryError) as err:
        where = setting.world_path
        raise RunError(f"{where}: cannot build {config.algo} ({one_line(err)})") from None
    if s.guide_warmup:
        _act_along_the_way(model, setting, venv)
    state, tally = ModelState(model, config), Tally()
    if resume:
        loaded = restore(directory, {"model": state, "tally": tally},
                         unchecked=state.unchecked(), optional=state.OPTIONAL)  # fmt: skip
        if tally.steps != loaded.steps or model.num_timesteps != loaded.steps:
            raise RunError(f"{loaded.files['json']}: the counters are not the checkpoint's steps")
        if tally.steps >= s.steps:
            raise RunError(
                f"{directory}: the run already has {tally.steps:,} steps; sb3.steps is the "
                f"run's total, so give more than {tally.steps:,} to go on"
            )
        model.set_random_seed(config.seed + tally.steps)  # new episodes, not the first ones
        if state.replay is not None and not state.replay.restored:  # refill it first
            model.learning_starts = tally.steps + s.learning_starts
            if notes is not None:
                notes(f"note: {loaded.files['json']}: {state.replay.missing}; the run takes "
                      f"{s.learning_starts:,} steps of random actions to refill it before it "
                      "learns again")  # fmt: skip
        truncate_metrics(directory / METRICS, tally.episodes)
        (directory / SUMMARY).unlink(missing_ok=True)
    save_config(directory, setting)
    run = _Run(directory, config, state, tally, progress, should_stop)
    run.view = team_view(venv.n) if team else None
    try:
        with (directory / METRICS).open("a", encoding="utf-8") as run.metrics:
            model.learn(s.steps - tally.steps, callback=run.callback(), reset_num_timesteps=False)
            if run.logged_at != tally.steps:  # the last line, at the run's end or stop
                log_window(run.metrics, tally, run.epsilon())
    finally:
        run.save(final=True)
    stopped = run.stopped and tally.steps < s.steps
    unseen = run_never_held(setting.finite, setting.automaton.propositions, venv.envs)
    if not stopped:
        write_json(directory / SUMMARY, summary_of(tally, setting.shield_summary, unseen))
    return RunResult(directory, config, tally.episodes, tally.steps, tally.seconds, stopped, unseen)


class _Run:
    """What the SB3 callback updates: the tally, metrics, checkpoints, progress and stopping."""

    def __init__(
        self,
        directory: Path,
        config: TrainConfig,
        state: ModelState,
        tally: Tally,
        progress: Callable[[Progress], None] | None,
        should_stop: Callable[[], bool] | None,
    ) -> None:
        self.directory, self.config, self.state, self.tally = directory, config, state, tally
        self.progress, self.should_stop = progress, should_stop
        self.saved_at = tally.steps if tally.steps else -1
        self.stopped, self.beat, self.logged_at = False, 0, tally.steps
        self.metrics: Any = None
        self.clock = time.perf_counter() - tally.seconds
        self.strayed: list[bool] = []
        """Per env: whether its episode took an action the shield blocks."""
        self.paid: list[float] = []
        """Per env: what its episode has cost so far."""
        self.view: Callable[[Any, Any], tuple[Any, Any]] | None = None
        """What the callback reads of a vector step (a team's first slot: :func:`team_view`)."""

    def epsilon(self) -> float:
        """DQN's exploration rate (0 for the others, which explore by sampling or noise)."""
        return float(getattr(self.state.model, "exploration_rate", 0.0))

    def save(self, final: bool = False) -> None:
        """Checkpoint, unless no step was taken since the last one and this is not the ``final``
        one (the model learns after the callback of its last step: a PPO update, an off-policy
        gradient step)."""
        if final or self.tally.steps != self.saved_at:
            data = {"model": self.state.state_dict(), "tally": self.tally.state_dict()}
            checkpoint.save(self.directory, self.tally.steps, data, self.config.keep_checkpoints)
            self.saved_at = self.tally.steps

    def on_step(self, steps: int, dones: Any, infos: list[dict[str, Any]]) -> bool:
        """After a vector step that brought the model to ``steps``: count the episodes that
        ended, log, checkpoint, show progress; whether to go on."""
        tally, s = self.tally, self.config.sb3
        before, tally.steps = tally.steps, steps
        if len(self.strayed) != len(infos):
            self.strayed, self.paid = [False] * len(infos), [0.0] * len(infos)
        for i, (done, info) in enumerate(zip(dones, infos, strict=True)):
            if "shield_blocked" in info:  # a shielded (or audited) run
                tally.shielded = True
                tally.blocked += bool(info["shield_blocked"])
                self.strayed[i] = self.strayed[i] or bool(info["shield_blocked"])
            if "cost" in info:  # a world with costs (the product env pays them)
                tally.costed = True
                self.paid[i] += float(info["cost"])
            if done:
                tally.window_cost += self.paid[i]
                self.paid[i] = 0.0
                violated = info.get("verdict") == "violated"
                tally.episodes += 1
                tally.window_count += 1
                tally.window_success += bool(info.get("is_success", False))
                tally.window_return += float(info["episode"]["r"])
                tally.violations += violated
                tally.preventable += violated and self.strayed[i]
                self.strayed[i] = False
        tally.seconds = time.perf_counter() - self.clock
        epsilon = self.epsilon()
        logged = steps // s.log_every > before // s.log_every
        if logged:
            log_window(self.metrics, tally, epsilon)
            self.logged_at = steps
        if steps // s.checkpoint_every > before // s.checkpoint_every:
            self.save()
        self.beat += 1
        if self.progress is not None and (logged or self.beat % 50 == 0):
            self.progress(progress_of(tally, s.steps, epsilon))
        self.stopped = self.should_stop is not None and self.should_stop()
        return not self.stopped

    def callback(self) -> Any:
        """An SB3 callback calling :meth:`on_step`."""
        from stable_baselines3.common.callbacks import BaseCallback

        run = self

        class Callback(BaseCallback):
            def _on_step(self) -> bool:
                dones, infos = self.locals["dones"], self.locals["infos"]
                if run.view is not None:
                    dones, infos = run.view(dones, infos)
                return run.on_step(self.num_timesteps, dones, infos)

        return Callback()


def _act_along_the_way(model: Any, setting: Setting, venv: Any) -> None:
    """``sb3.guide_warmup``: the first steps act along the way (:mod:`.sb3_guided`)."""
    from mitlc.learn.backends.sb3_guided import follow_the_way, way_size_problem

    config = setting.config
    where = setting.world_path
    if not config.guide or config.algo not in ("sb3-sac", "sb3-td3"):
        raise RunError(f"{where}: sb3.guide_warmup acts along the way: it needs guide: true "
                       f"and --algo sb3-sac or sb3-td3")  # fmt: skip
    pointing = int(venv.envs[0].get_wrapper_attr("way_size"))
    problem = way_size_problem(tuple(venv.action_space.shape or ()), pointing)
    if problem is not None:
        raise RunError(f"{where}: {problem}")
    follow_the_way(model, config.sb3.guide_warmup, pointing, config.seed)

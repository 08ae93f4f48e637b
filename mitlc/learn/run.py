"""A training run and its directory: ``train(world_path, config, out) -> RunResult``.

The directory holds

* ``config.json``: the world file's path, the task, and the resolved :class:`TrainConfig`;
* ``metrics.jsonl``: one line every ``log_every`` episodes (episodes, environment steps,
  success rate and mean return over those episodes, epsilon, seconds);
* ``checkpoint_<steps>_steps.json``, ``.npz`` and (deep learners) ``.safetensors``, named by
  ``checkpoint.json`` (see :mod:`mitlc.learn.rundir.checkpoint`: data only, never a pickle): the
  learner, the episodes in flight, every random state and the counters, written every
  ``checkpoint_every`` episodes, at the end, and when the caller asks the run to stop (Ctrl-C
  in the CLI); the ``keep_checkpoints`` latest are kept. ``train(..., resume=True)`` continues
  from the latest and reaches exactly what an uninterrupted run with the same seed reaches;
* ``summary.json`` at the end;
* ``.lock``: a run holds it (``flock``) while it trains, so a second ``train`` or resume in
  the same directory is refused, naming the process that has it.

``config.episodes`` is the run's total, resumed or not: the run stops at the first vector step
at which at least that many episodes have ended, so it ends with between ``episodes`` and
``episodes + num_envs - 1`` of them. Resuming asks for more than the checkpoint has.

Anything wrong with a run directory's files is a :class:`RunError` naming the file and what is
wrong, on one line.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.learn.config import TrainConfig, validate
from mitlc.learn.envs.envvec import VectorTask
from mitlc.learn.envs.vec import Tables
from mitlc.learn.envs.vector import ProductVectorEnv
from mitlc.learn.held import run_never_held
from mitlc.learn.learners.base import Learner, ProductShaping, product_potential
from mitlc.learn.learners.open_world import make_open_learner
from mitlc.learn.rundir import checkpoint
from mitlc.learn.rundir.files import METRICS, SUMMARY
from mitlc.learn.rundir.files import RunError as RunError
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
from mitlc.learn.rundir.state import Stateful, one_line, restore
from mitlc.learn.setting import (
    CONFIG,
    Setting,
    load_setting,
    opened_run,
    prepare,
    save_config,
    setting_notes,
    task_vector_of,
)
from mitlc.limits import Deadline
from mitlc.worlds.door import AnyWorld
from mitlc.worlds.model import FloatArray

CHECKPOINT = checkpoint.INDEX
ROWS, UNCHECKED = ("learner.replay.data",), ("learner.optimizer.state",)
"""For :func:`mitlc.learn.rundir.state.conform`: a replay memory holds any number of rows up to
its capacity; the optimiser's moments are checked against the network when restored."""


def make_learner(setting: Setting, rng: np.random.Generator) -> Learner:
    """The learner ``setting.config.algo`` names (the deep ones import torch): on the
    product's simulator where the world is finite, else on the world's wrapped envs
    (:func:`mitlc.learn.learners.open_world.make_open_learner`)."""
    if not setting.finite:
        return make_open_learner(setting, rng)
    world, product, table = setting.model()
    config = setting.config
    phi = (
        product_potential(table, world, setting.automaton, config.shaping, config.shaping_reach)
        if config.shaping
        else None
    )
    shaping = ProductShaping(phi) if phi is not None else None
    if config.team != "joint":
        return _team_learner(setting, phi, shaping, rng)
    if world.is_pomdp and config.algo == "q":
        return _observed_q(setting, table, phi, rng)
    if world.is_pomdp and config.algo != "drqn":
        raise RunError(
            f"{config.algo} learns on the true cell, which a POMDP's agent does not see: use "
            "drqn or q on this world"
        )
    if config.algo == "q":
        from mitlc.learn.learners.crm import Counterfactuals
        from mitlc.learn.learners.qlearning import QLearner

        crm = Counterfactuals.build(product, world, setting.automaton) if config.q.crm else None
        return QLearner(table, config, rng, phi, crm)
    from mitlc.learn.learners.encoder import Encoder, task_features

    task = task_features(setting.automaton, config.task_obs)
    if config.algo == "dqn":
        from mitlc.learn.learners.crm import Counterfactuals
        from mitlc.learn.learners.dqn import DQNLearner

        crm = Counterfactuals.build(product, world, setting.automaton) if config.dqn.crm else None
        encoder = Encoder(table, task_features=task)
        return DQNLearner(table, config, rng, shaping, crm, encoder=encoder)
    from mitlc.learn.learners.drqn import DRQNLearner

    encoder = Encoder(table, config.drqn.previous_action, task_features=task)
    return DRQNLearner(table, config, rng, shaping, encoder=encoder)


def _team_learner(
    setting: Setting,
    phi: FloatArray | None,
    shaping: ProductShaping | None,
    rng: np.random.Generator,
) -> Learner:
    """A team's decentralised learner (``team: independent`` or ``shared``,
    :mod:`mitlc.learn.learners.team`)."""
    from mitlc.learn.learners.encoder import task_features
    from mitlc.learn.learners.team import IndependentQLearner, RobotView, TeamLearnerError
    from mitlc.learn.learners.team_dqn import SharedDQNLearner

    world, _, table = setting.model()
    config, mode = setting.config, setting.config.team
    if world.team is None:
        raise RunError(f"team: {mode} is for a team of robots (a world with robots:); "
                       f"{world.name} has one agent")  # fmt: skip
    try:
        view = RobotView(world.team, table, world.is_pomdp)
    except TeamLearnerError as err:
        raise RunError(f"team: {mode}: {err}") from None
    wanted = {"independent": "q", "shared": "dqn"}[mode]
    if config.algo != wanted:
        raise RunError(f"team: {mode} learns with algo {wanted}, not {config.algo} (team: "
                       "independent with q, a table per robot; team: shared with dqn, one "
                       "network for every robot; team: joint with any learner)")  # fmt: skip
    if (config.q.crm and mode == "independent") or (config.dqn.crm and mode == "shared"):
        raise RunError(f"team: {mode}: counterfactual experience is for joint learners")
    if mode == "independent":
        return IndependentQLearner(view, config, rng, phi)
    features = task_features(setting.automaton, config.task_obs)
    return SharedDQNLearner(view, config, rng, shaping, features)


def _observed_q(
    setting: Setting, table: Tables, phi: FloatArray | None, rng: np.random.Generator
) -> Learner:
    """Tabular Q-learning on a finite POMDP over what its agent sees: the observation, the
    automaton state and the frontier (:mod:`mitlc.learn.learners.qlearning_env`)."""
    from mitlc.learn.learners.qlearning_env import ObservedQLearner

    if setting.config.q.crm:
        raise RunError("q.crm on a POMDP: counterfactuals need the true cell, which q does "
                       "not see there; set q.crm=false")  # fmt: skip
    return ObservedQLearner(
        table.num_observations, table.num_automaton_states, table.num_sets, table.num_actions,
        setting.config, rng, phi,
    )  # fmt: skip


def _rngs(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    env_seq, learner_seq = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(env_seq), np.random.default_rng(learner_seq)


def load_learner(directory: Path, *, deadline: Deadline | None = None) -> tuple[Setting, Learner]:
    """The run in ``directory``, of any world: its setting, and its learner as last
    checkpointed."""
    setting = load_setting(directory, deadline=deadline)
    if setting.config.algo.startswith("sb3-"):  # Stable-Baselines3's runs
        from mitlc.learn.backends import sb3_policy

        return setting, sb3_policy.load_learner(directory, setting)
    # wherever it trained, a run is read back on the device this machine has
    setting = replace(setting, config=replace(setting.config, device="auto"))
    _, learner_rng = _rngs(setting.config.seed)
    learner, env = _build(directory / CONFIG, setting, learner_rng, np.random.default_rng(0))
    _restore(directory, learner, env, Tally())
    return setting, learner


def _build(
    where: Path | str,
    setting: Setting,
    learner_rng: np.random.Generator,
    env_rng: np.random.Generator,
) -> tuple[Learner, Any]:
    """A fresh learner and the episodes it steps: the product's simulator where the world is
    finite, else a vector of the world's wrapped envs (sizes the machine cannot hold are a
    :class:`RunError` naming ``where`` the settings come from)."""
    try:
        learner = make_learner(setting, learner_rng)
        if setting.tables is None:
            seed = int(env_rng.integers(2**31))
            return learner, task_vector_of(setting, learner.num_envs, seed)
        venv = ProductVectorEnv(setting.tables, learner.num_envs, rng=env_rng)
        return learner, VectorTask(venv)
    except (ValueError, TypeError, MemoryError, RuntimeError, OverflowError) as err:
        raise RunError(
            f"{where}: cannot build the learner from these settings ({one_line(err)})"
        ) from None


def _restore(directory: Path, learner: Learner, env: Any, tally: Tally) -> None:
    """Load the run's latest checkpoint into fresh ``learner``, ``env`` and ``tally``."""
    parts: dict[str, Stateful] = {"learner": learner, "env": env, "tally": tally}
    loaded = restore(directory, parts, rows=ROWS, unchecked=UNCHECKED)
    if tally.steps != loaded.steps:
        raise RunError(f"{loaded.files['json']}: tally.steps is not the checkpoint's steps")


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
    """Train ``config.algo`` on the world file's product for ``config.episodes`` episodes in
    all, writing the run to ``out`` (see the module docstring), which it locks meanwhile.
    ``should_stop`` is polled after every step; when it says so, the run checkpoints and
    returns with ``stopped`` set. ``deadline`` bounds the set-up (compile and product, see
    :func:`prepare`), not the training, which runs its episodes. ``notes`` is given what the
    user should know before the run (:func:`setting_notes`); ``world`` is the file's world
    where the caller has loaded it (with ``spec``). Settings outside their bounds
    (:mod:`mitlc.learn.bounds`) are a :class:`~mitlc.learn.config.ConfigError` first."""
    validate(config)
    if config.algo.startswith("sb3-"):  # Stable-Baselines3's runs: mitlc.learn.backends.sb3
        from mitlc.learn.backends import sb3

        return sb3.train(
            world_path, config, out, spec=spec, resume=resume, progress=progress,
            should_stop=should_stop, deadline=deadline, notes=notes, world=world,
        )  # fmt: skip
    directory = Path(out)
    setting = prepare(world_path, config, spec, deadline=deadline, world=world)
    if notes is not None:
        for note in setting_notes(setting):
            notes(note)
    with opened_run(directory, setting, resume, sb3=False):
        return _train(directory, setting, resume, progress, should_stop)


def _train(
    directory: Path,
    setting: Setting,
    resume: bool,
    progress: Callable[[Progress], None] | None,
    should_stop: Callable[[], bool] | None,
) -> RunResult:
    config = setting.config
    env_rng, learner_rng = _rngs(config.seed)
    where = directory / CONFIG if resume else setting.world_path
    learner, env = _build(where, setting, learner_rng, env_rng)
    tally = Tally()
    if resume:
        _restore(directory, learner, env, tally)
        if tally.episodes >= config.episodes:
            raise RunError(
                f"{directory}: the run already has {tally.episodes:,} episodes; --episodes is "
                f"the run's total, so give more than {tally.episodes:,} to go on"
            )
        truncate_metrics(directory / METRICS, tally.episodes)
        (directory / SUMMARY).unlink(missing_ok=True)
    save_config(directory, setting)
    saved_at = tally.steps if resume else -1

    def save() -> None:
        nonlocal saved_at
        if tally.steps != saved_at:  # else nothing changed since that checkpoint
            state = {
                "learner": learner.state_dict(),
                "env": env.state_dict(),
                "tally": tally.state_dict(),
            }
            checkpoint.save(directory, tally.steps, state, config.keep_checkpoints)
            saved_at = tally.steps

    clock = time.perf_counter() - tally.seconds
    total, stopped, beat = config.episodes, False, 0
    metrics = (directory / METRICS).open("a", encoding="utf-8")
    try:
        while tally.episodes < total:
            step = learner.train_step(env, tally.episodes / total)
            tally.steps += env.num_envs
            ended = step.done
            before = tally.episodes
            tally.episodes += int(ended.sum())
            tally.window_count += int(ended.sum())
            tally.window_success += int(step.success[ended].sum())
            tally.window_return += float(step.episode_return[ended].sum())
            tally.count(step)
            tally.seconds = time.perf_counter() - clock
            logged = tally.episodes // config.log_every > before // config.log_every
            if logged or tally.episodes >= total:
                log_window(metrics, tally, learner.epsilon)
            if tally.episodes // config.checkpoint_every > before // config.checkpoint_every:
                save()
            beat += 1
            if progress is not None and (logged or beat % 50 == 0):
                progress(progress_of(tally, total, learner.epsilon))
            if should_stop is not None and should_stop():
                stopped = tally.episodes < total
                break
    finally:
        metrics.close()
        save()
    unseen = run_never_held(setting.finite, setting.automaton.propositions, env.envs)
    if not stopped:
        write_json(directory / SUMMARY, summary_of(tally, setting.shield_summary, unseen))
    return RunResult(directory, config, tally.episodes, tally.steps, tally.seconds, stopped, unseen)

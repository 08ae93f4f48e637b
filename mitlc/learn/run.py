"""A training run and its directory: ``train(world_path, config, out) -> RunResult``.

The directory holds

* ``config.json``: the world file's path, the task, and the resolved :class:`TrainConfig`;
* ``metrics.jsonl``: one line every ``log_every`` episodes (episodes, environment steps,
  success rate and mean return over those episodes, epsilon, seconds);
* ``checkpoint_<steps>_steps.json``, ``.npz`` and (deep learners) ``.safetensors``, named by
  ``checkpoint.json`` (see :mod:`mitlc.learn.checkpoint`: data only, never a pickle): the
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

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from mitlc import __version__
from mitlc.automata import DigitalAutomaton, translate
from mitlc.errors import MitlcError
from mitlc.files import write_atomically
from mitlc.learn import checkpoint
from mitlc.learn.base import Learner, automaton_potential, potential
from mitlc.learn.config import ConfigError, TrainConfig, from_data, to_data
from mitlc.learn.envvec import VectorTask
from mitlc.learn.plane_run import OpenSetting, make_open_learner, make_vector, prepare_open
from mitlc.learn.rundir import RunError as RunError
from mitlc.learn.rundir import locked, read_json, read_metrics_rows
from mitlc.learn.state import Stateful, one_line, restore
from mitlc.learn.vec import Tables, tables
from mitlc.learn.vector import ProductVectorEnv
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline, LimitError
from mitlc.product.explicit import Product, build_product
from mitlc.syntax import parse
from mitlc.task.horizon import short_horizon_note
from mitlc.worlds import World, load_world
from mitlc.worlds.env_task import is_open_world

CONFIG, METRICS, CHECKPOINT, SUMMARY = (
    "config.json",
    "metrics.jsonl",
    checkpoint.INDEX,
    "summary.json",
)
ROWS, UNCHECKED = ("learner.replay.data",), ("learner.optimizer.state",)
"""For :func:`mitlc.learn.state.conform`: a replay memory holds any number of rows up to
its capacity; the optimiser's moments are checked against the network when restored."""


@dataclass(frozen=True, slots=True)
class Progress:
    """Where a run stands, for a progress display."""

    episodes: int
    total: int
    steps: int
    success_rate: float
    """Over the episodes since the last metrics line (or the last line's, right after one)."""
    mean_return: float
    epsilon: float
    seconds: float


@dataclass(frozen=True, slots=True)
class RunResult:
    """A finished (or stopped) run."""

    directory: Path
    config: TrainConfig
    episodes: int
    steps: int
    seconds: float
    stopped: bool
    """The caller asked the run to stop before its episodes were done."""


@dataclass(frozen=True, slots=True)
class Setting:
    """A run's world, task and product, rebuilt from ``config.json``."""

    world_path: Path
    world: World
    automaton: DigitalAutomaton
    product: Product
    tables: Tables
    config: TrainConfig


def prepare(
    world_path: Path,
    config: TrainConfig,
    spec: str | None = None,
    *,
    deadline: Deadline | None = None,
) -> Setting:
    """Load the world, compile its task (``spec`` in its place if given), build the product;
    the compile and the product stop at ``deadline`` (by default
    :data:`~mitlc.limits.DEFAULT_TIME_LIMIT` seconds)."""
    clock = Deadline.of(deadline, DEFAULT_TIME_LIMIT, "setting up the run")
    world = load_world(world_path)
    if spec is not None and spec != world.spec:
        world = load_world(world_path, spec)
    automaton = translate(parse(world.spec, world.spec_source), deadline=clock)
    product = build_product(world, automaton, deadline=clock.at("the product"))
    return Setting(world_path, world, automaton, product, tables(product, world), config)


def prepare_world(
    world_path: str | Path,
    config: TrainConfig,
    spec: str | None = None,
    *,
    deadline: Deadline | None = None,
) -> Setting | OpenSetting:
    """The run's setting: a finite world's product (:func:`prepare`), or for a world that is
    not finite its wrapped envs' (:func:`mitlc.learn.plane_run.prepare_open`)."""
    if is_open_world(world_path):
        return prepare_open(Path(world_path), config, spec, deadline=deadline)
    return prepare(Path(world_path), config, spec, deadline=deadline)


def setting_notes(setting: Setting | OpenSetting) -> list[str]:
    """One-line notes on a run's setting: a horizon shorter than the task needs to be decided
    (:func:`mitlc.task.horizon.short_horizon_note`)."""
    world = setting.world
    note = short_horizon_note(parse(world.spec, world.spec_source), world.horizon)
    return [] if note is None else [note]


def make_learner(setting: Setting, rng: np.random.Generator) -> Learner:
    """The learner ``setting.config.algo`` names (the deep ones import torch)."""
    config = setting.config
    phi = None
    if config.shaping:  # per product state for the table, per automaton state for the nets
        phi = (
            potential(setting.tables, setting.automaton, config.shaping)
            if config.algo == "q"
            else automaton_potential(setting.automaton, config.shaping)
        )
    if setting.world.is_pomdp and config.algo != "drqn":
        raise RunError(
            f"{config.algo} learns on the true cell, which a POMDP's agent does not see: use "
            "drqn on this world"
        )
    if config.algo == "q":
        from mitlc.learn.crm import Counterfactuals
        from mitlc.learn.qlearning import QLearner

        crm = (
            Counterfactuals.build(setting.product, setting.world, setting.automaton)
            if config.q.crm
            else None
        )
        return QLearner(setting.tables, config, rng, phi, crm)
    if config.algo == "dqn":
        from mitlc.learn.crm import Counterfactuals
        from mitlc.learn.dqn import DQNLearner

        crm = (
            Counterfactuals.build(setting.product, setting.world, setting.automaton)
            if config.dqn.crm
            else None
        )
        return DQNLearner(setting.tables, config, rng, phi, crm)
    from mitlc.learn.drqn import DRQNLearner

    return DRQNLearner(setting.tables, config, rng, phi)


def _rngs(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    env_seq, learner_seq = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(env_seq), np.random.default_rng(learner_seq)


def read_config(directory: Path) -> tuple[dict[str, Any], TrainConfig]:
    """``config.json`` of a run: its raw data (``world`` and ``spec`` checked to be text) and
    the settings."""
    path = directory / CONFIG
    if not path.is_file():
        raise RunError(f"{directory}: not a run directory (no {CONFIG})")
    data = read_json(path)
    if not isinstance(data, dict):
        raise RunError(f"{path}: expected a JSON object, got {type(data).__name__}")
    for key in ("world", "spec"):
        value = data.get(key)
        if not isinstance(value, str) or not value or "\x00" in value:
            raise RunError(f"{path}: {key!r} is missing or not a usable string")
    if not isinstance(data.get("train"), dict):
        raise RunError(f"{path}: 'train' is missing or not a JSON object")
    try:
        return data, from_data(data["train"])
    except ConfigError as err:
        raise RunError(f"{path}: train.{err}") from None


def load_setting(directory: Path, *, deadline: Deadline | None = None) -> Setting:
    """The world, task and product of the run in ``directory`` (built by ``deadline``, see
    :func:`prepare`)."""
    data, config = read_config(directory)
    if not Path(data["world"]).is_file():  # a device would be read for ever
        raise RunError(f"{directory / CONFIG}: the run's world {data['world']} is not a file")
    try:
        return prepare(Path(data["world"]), config, data["spec"], deadline=deadline)
    except OSError as err:
        raise RunError(
            f"{directory / CONFIG}: the run's world {data['world']}: {err.strerror or err}"
        ) from None
    except LimitError:  # the time or size limit, not a fault of the run's files
        raise
    except MitlcError as err:  # the world file or the task no longer compiles
        raise RunError(f"{directory / CONFIG}: the run's world or task: {one_line(err)}") from None


def load_open_learner(directory: Path) -> tuple[OpenSetting, Learner]:
    """The run of a world that is not finite in ``directory``: its setting, and its learner
    as last checkpointed."""
    data, config = read_config(directory)
    setting = prepare_open(Path(data["world"]), config, data["spec"])
    if config.algo.startswith("sb3-"):  # Stable-Baselines3's runs: mitlc.learn.sb3
        from mitlc.learn import sb3

        return setting, sb3.load_learner(directory, setting)
    _, learner_rng = _rngs(config.seed)
    learner, env = _build(directory / CONFIG, setting, learner_rng, np.random.default_rng(0))
    _restore(directory, learner, env, _Tally())
    return setting, learner


def is_open_run(directory: Path) -> bool:
    """Whether the run in ``directory`` learns a world that is not finite (a continuous world,
    an env without a transition table); a world file that no longer loads is left to the
    finite path, which reports it."""
    data, _ = read_config(directory)
    if not Path(data["world"]).is_file():
        return False
    try:
        return is_open_world(data["world"])
    except MitlcError:
        return False


def load_learner(directory: Path, *, deadline: Deadline | None = None) -> tuple[Setting, Learner]:
    """The run in ``directory``: its setting, and its learner as last checkpointed."""
    setting = load_setting(directory, deadline=deadline)
    if setting.config.algo.startswith("sb3-"):  # Stable-Baselines3's runs: mitlc.learn.sb3
        from mitlc.learn import sb3

        return setting, sb3.load_learner(directory, setting)
    _, learner_rng = _rngs(setting.config.seed)
    learner, env = _build(directory / CONFIG, setting, learner_rng, np.random.default_rng(0))
    _restore(directory, learner, env, _Tally())
    return setting, learner


def _build(
    where: Path | str,
    setting: Setting | OpenSetting,
    learner_rng: np.random.Generator,
    env_rng: np.random.Generator,
) -> tuple[Learner, Any]:
    """A fresh learner and simulator for the run's settings: the product's simulator, or for
    a continuous world a vector of its wrapped envs (sizes the machine cannot hold are a
    :class:`RunError` naming ``where`` the settings come from)."""
    try:
        if isinstance(setting, OpenSetting):
            learner = make_open_learner(setting, learner_rng)
            seed = int(env_rng.integers(2**31))
            return learner, make_vector(setting, learner.num_envs, seed)
        learner = make_learner(setting, learner_rng)
        venv = ProductVectorEnv(setting.tables, learner.num_envs, rng=env_rng)
        return learner, VectorTask(venv)
    except (ValueError, TypeError, MemoryError, RuntimeError, OverflowError) as err:
        raise RunError(
            f"{where}: cannot build the learner from these settings ({one_line(err)})"
        ) from None


def _write_json(path: Path, data: Any) -> None:
    write_atomically(path, (json.dumps(data, indent=2, sort_keys=True) + "\n").encode())


class _Tally:
    """Episodes, steps and the current metrics window."""

    def __init__(self) -> None:
        self.episodes = self.steps = 0
        self.window_count = self.window_success = 0
        self.window_return = 0.0
        self.last_rate = self.last_return = 0.0
        self.seconds = 0.0

    def state_dict(self) -> dict[str, Any]:
        return dict(vars(self))

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        counts = ("episodes", "steps", "window_count", "window_success")
        if any(saved[name] < 0 for name in counts):
            raise ValueError(f"negative counts among {', '.join(counts)}")
        vars(self).update(saved)


def _restore(directory: Path, learner: Learner, env: Any, tally: _Tally) -> None:
    """Load the run's latest checkpoint into fresh ``learner``, ``env`` and ``tally``."""
    parts: dict[str, Stateful] = {"learner": learner, "env": env, "tally": tally}
    loaded = restore(directory, parts, rows=ROWS, unchecked=UNCHECKED)
    if tally.steps != loaded.steps:
        raise RunError(f"{loaded.files['json']}: tally.steps is not the checkpoint's steps")


def _start(directory: Path, setting: Setting | OpenSetting, spec: str, resume: bool) -> None:
    """Check the run directory (locked by the caller) for a fresh run or a resumed one."""
    if not resume:
        if (directory / CONFIG).exists() or checkpoint.exists(directory):
            raise RunError(f"{directory}: a run is already there (use --resume, or another --out)")
        return
    data, saved = read_config(directory)
    if replace(saved, episodes=setting.config.episodes) != setting.config:
        raise RunError(
            f"{directory}: --resume with settings other than the run's own (only "
            "--episodes may change)"
        )
    if Path(data["world"]) != setting.world_path.resolve() or data["spec"] != spec:
        raise RunError(f"{directory}: --resume with another world or task than the run's")


def _save_config(directory: Path, setting: Setting | OpenSetting) -> None:
    _write_json(
        directory / CONFIG,
        {
            "mitlc": __version__,
            "world": str(setting.world_path.resolve()),
            "world_name": setting.world.name,
            "spec": setting.world.spec,
            "train": to_data(setting.config),
        },
    )


def _truncate_metrics(path: Path, episodes: int) -> None:
    """Drop lines written after the checkpoint a resumed run starts from."""
    if not path.exists():
        return
    kept = [row for row in read_metrics_rows(path) if row["episodes"] <= episodes]
    write_atomically(path, "".join(json.dumps(row) + "\n" for row in kept).encode())


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
) -> RunResult:
    """Train ``config.algo`` on the world file's product for ``config.episodes`` episodes in
    all, writing the run to ``out`` (see the module docstring), which it locks meanwhile.
    ``should_stop`` is polled after every step; when it says so, the run checkpoints and
    returns with ``stopped`` set. ``deadline`` bounds the set-up (compile and product, see
    :func:`prepare`), not the training, which runs its episodes. ``notes`` is given what the
    user should know before the run (:func:`setting_notes`)."""
    if config.algo.startswith("sb3-"):  # Stable-Baselines3's runs: mitlc.learn.sb3
        from mitlc.learn import sb3

        return sb3.train(
            world_path, config, out, spec=spec, resume=resume, progress=progress,
            should_stop=should_stop, deadline=deadline, notes=notes,
        )  # fmt: skip
    directory = Path(out)
    setting = prepare_world(world_path, config, spec, deadline=deadline)
    if notes is not None:
        for note in setting_notes(setting):
            notes(note)
    if resume:
        read_config(directory)  # a run directory at all?
    else:
        directory.mkdir(parents=True, exist_ok=True)
    with locked(directory):
        _start(directory, setting, setting.world.spec, resume)
        return _train(directory, setting, resume, progress, should_stop)


def _train(
    directory: Path,
    setting: Setting | OpenSetting,
    resume: bool,
    progress: Callable[[Progress], None] | None,
    should_stop: Callable[[], bool] | None,
) -> RunResult:
    config = setting.config
    env_rng, learner_rng = _rngs(config.seed)
    where = directory / CONFIG if resume else setting.world_path
    learner, env = _build(where, setting, learner_rng, env_rng)
    tally = _Tally()
    if resume:
        _restore(directory, learner, env, tally)
        if tally.episodes >= config.episodes:
            raise RunError(
                f"{directory}: the run already has {tally.episodes:,} episodes; --episodes is "
                f"the run's total, so give more than {tally.episodes:,} to go on"
            )
        _truncate_metrics(directory / METRICS, tally.episodes)
        (directory / SUMMARY).unlink(missing_ok=True)
    _save_config(directory, setting)
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
            tally.seconds = time.perf_counter() - clock
            logged = tally.episodes // config.log_every > before // config.log_every
            if logged or tally.episodes >= total:
                _log(metrics, tally, learner.epsilon)
            if tally.episodes // config.checkpoint_every > before // config.checkpoint_every:
                save()
            beat += 1
            if progress is not None and (logged or beat % 50 == 0):
                progress(_progress(tally, total, learner.epsilon))
            if should_stop is not None and should_stop():
                stopped = tally.episodes < total
                break
    finally:
        metrics.close()
        save()
    if not stopped:
        _write_json(
            directory / SUMMARY,
            {
                "episodes": tally.episodes,
                "steps": tally.steps,
                "seconds": round(tally.seconds, 3),
                "success_rate": tally.last_rate,
                "mean_return": tally.last_return,
            },
        )
    return RunResult(directory, config, tally.episodes, tally.steps, tally.seconds, stopped)


def _log(metrics: Any, tally: _Tally, epsilon: float) -> None:
    if tally.window_count:
        tally.last_rate = tally.window_success / tally.window_count
        tally.last_return = tally.window_return / tally.window_count
    line = {
        "episodes": tally.episodes,
        "steps": tally.steps,
        "success_rate": round(tally.last_rate, 6),
        "return": round(tally.last_return, 6),
        "epsilon": round(epsilon, 6),
        "seconds": round(tally.seconds, 3),
    }
    metrics.write(json.dumps(line) + "\n")
    metrics.flush()
    tally.window_count = tally.window_success = 0
    tally.window_return = 0.0


def _progress(tally: _Tally, total: int, epsilon: float) -> Progress:
    rate, mean = tally.last_rate, tally.last_return
    if tally.window_count:
        rate = tally.window_success / tally.window_count
        mean = tally.window_return / tally.window_count
    return Progress(tally.episodes, total, tally.steps, rate, mean, epsilon, tally.seconds)

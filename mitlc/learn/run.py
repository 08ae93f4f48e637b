"""A training run and its directory: ``train(world_path, config, out) -> RunResult``.

The directory holds

* ``config.json``: the world file's path, the task, and the resolved :class:`TrainConfig`;
* ``metrics.jsonl``: one line every ``log_every`` episodes (episodes, environment steps,
  success rate and mean return over those episodes, epsilon, seconds);
* ``checkpoint.pkl``: the learner, the episodes in flight, every random state and the
  counters, written atomically every ``checkpoint_every`` episodes, at the end, and when the
  caller asks the run to stop (Ctrl-C in the CLI); ``train(..., resume=True)`` continues from it
  and reaches exactly what an uninterrupted run with the same seed reaches;
* ``summary.json`` at the end.
"""

from __future__ import annotations

import json
import pickle
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from mitlc import __version__
from mitlc.automata import DigitalAutomaton, translate
from mitlc.automata.dot import write_atomically
from mitlc.errors import MitlcError
from mitlc.learn.base import Learner, potential
from mitlc.learn.config import TrainConfig, from_data, to_data
from mitlc.learn.vec import Tables, VecProduct, tables
from mitlc.product.env import relabel
from mitlc.product.explicit import Product, build_product
from mitlc.syntax import parse
from mitlc.worlds import World, load_world, read_world_file

CONFIG, METRICS, CHECKPOINT, SUMMARY = (
    "config.json",
    "metrics.jsonl",
    "checkpoint.pkl",
    "summary.json",
)


class RunError(MitlcError):
    """A run directory that cannot be used as asked (missing, foreign, or in the way)."""


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


def prepare(world_path: Path, config: TrainConfig, spec: str | None = None) -> Setting:
    """Load the world, compile its task (``spec`` in its place if given), build the product."""
    world = load_world(world_path)
    if spec is not None and spec != world.spec:
        world = relabel(world, read_world_file(world_path).labels, spec)
    automaton = translate(parse(world.spec, world.spec_source))
    product = build_product(world, automaton)
    return Setting(world_path, world, automaton, product, tables(product, world), config)


def make_learner(setting: Setting, rng: np.random.Generator) -> Learner:
    """The learner ``setting.config.algo`` names (the deep ones import torch)."""
    config = setting.config
    phi = potential(setting.tables, setting.automaton, config.shaping) if config.shaping else None
    if setting.world.is_pomdp and config.algo != "drqn":
        raise RunError(
            f"{config.algo} learns on the true cell, which a POMDP's agent does not see: use "
            "drqn on this world"
        )
    if config.algo == "q":
        from mitlc.learn.qlearning import QLearner

        return QLearner(setting.tables, config, rng, phi)
    if config.algo == "dqn":
        from mitlc.learn.dqn import DQNLearner

        return DQNLearner(setting.tables, config, rng, phi)
    from mitlc.learn.drqn import DRQNLearner

    return DRQNLearner(setting.tables, config, rng, phi)


def _rngs(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    env_seq, learner_seq = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(env_seq), np.random.default_rng(learner_seq)


def read_config(directory: Path) -> tuple[dict[str, Any], TrainConfig]:
    """``config.json`` of a run: its raw data and the settings."""
    path = directory / CONFIG
    if not path.is_file():
        raise RunError(f"{directory}: not a run directory (no {CONFIG})")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return data, from_data(data["train"])
    except (json.JSONDecodeError, KeyError, TypeError) as err:
        raise RunError(f"{path}: unreadable run configuration ({err})") from None


def load_setting(directory: Path) -> Setting:
    """The world, task and product of the run in ``directory``."""
    data, config = read_config(directory)
    return prepare(Path(data["world"]), config, data["spec"])


def load_learner(directory: Path) -> tuple[Setting, Learner]:
    """The run in ``directory``: its setting, and its learner as last checkpointed."""
    setting = load_setting(directory)
    saved = load_checkpoint(directory)
    learner = make_learner(setting, _rngs(setting.config.seed)[1])
    learner.load_state_dict(saved["learner"])
    return setting, learner


def _write_json(path: Path, data: Any) -> None:
    write_atomically(path, (json.dumps(data, indent=2, sort_keys=True) + "\n").encode())


def save_checkpoint(path: Path, state: dict[str, Any]) -> None:
    """Pickle ``state`` to ``path`` atomically (a temporary file, then a rename)."""
    write_atomically(path, pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL))


def load_checkpoint(directory: Path) -> dict[str, Any]:
    """The run's last checkpoint (a pickle this package wrote: load only your own runs)."""
    path = directory / CHECKPOINT
    if not path.is_file():
        raise RunError(f"{directory}: no {CHECKPOINT} to resume from")
    with path.open("rb") as handle:
        state: dict[str, Any] = pickle.load(handle)
    return state


class _Tally:
    """Episodes, steps and the current metrics window."""

    def __init__(self) -> None:
        self.episodes = self.steps = 0
        self.window_count = self.window_success = 0
        self.window_return = 0.0
        self.last_rate = self.last_return = 0.0
        self.seconds = 0.0

    def state(self) -> dict[str, Any]:
        return dict(vars(self))

    def restore(self, saved: dict[str, Any]) -> None:
        vars(self).update(saved)


def _start(directory: Path, setting: Setting, spec: str, resume: bool) -> dict[str, Any] | None:
    """Create (or check, when resuming) the run directory; the checkpoint to resume from."""
    if resume:
        data, saved = read_config(directory)
        if replace(saved, episodes=setting.config.episodes) != setting.config:
            raise RunError(
                f"{directory}: --resume with settings other than the run's own (only "
                "--episodes may change)"
            )
        if Path(data["world"]) != setting.world_path.resolve() or data["spec"] != spec:
            raise RunError(f"{directory}: --resume with another world or task than the run's")
        return load_checkpoint(directory)
    if (directory / CONFIG).exists() or (directory / CHECKPOINT).exists():
        raise RunError(f"{directory}: a run is already there (use --resume, or another --out)")
    directory.mkdir(parents=True, exist_ok=True)
    return None


def _save_config(directory: Path, setting: Setting) -> None:
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
    kept = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            if json.loads(line)["episodes"] <= episodes:
                kept.append(line + "\n")
        except (json.JSONDecodeError, KeyError, TypeError):
            break  # a line cut short when the run was killed: nothing after it counts
    write_atomically(path, "".join(kept).encode())


def train(
    world_path: str | Path,
    config: TrainConfig,
    out: str | Path,
    *,
    spec: str | None = None,
    resume: bool = False,
    progress: Callable[[Progress], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> RunResult:
    """Train ``config.algo`` on the world file's product, writing the run to ``out`` (see the
    module docstring). ``should_stop`` is polled after every step; when it says so, the run
    checkpoints and returns with ``stopped`` set."""
    directory = Path(out)
    setting = prepare(Path(world_path), config, spec)
    saved = _start(directory, setting, setting.world.spec, resume)
    env_rng, learner_rng = _rngs(config.seed)
    learner = make_learner(setting, learner_rng)
    env = VecProduct(setting.tables, learner.num_envs, env_rng)
    tally = _Tally()
    if saved is not None:
        learner.load_state_dict(saved["learner"])
        env.load_state_dict(saved["env"])
        tally.restore(saved["tally"])
        _truncate_metrics(directory / METRICS, tally.episodes)
    _save_config(directory, setting)

    def checkpoint() -> None:
        save_checkpoint(
            directory / CHECKPOINT,
            {"learner": learner.state_dict(), "env": env.state_dict(), "tally": tally.state()},
        )

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
                checkpoint()
            beat += 1
            if progress is not None and (logged or beat % 50 == 0):
                progress(_progress(tally, total, learner.epsilon))
            if should_stop is not None and should_stop():
                stopped = tally.episodes < total
                break
    finally:
        metrics.close()
        checkpoint()
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

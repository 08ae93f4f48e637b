"""Training settings: typed dataclasses, read from a world file's ``training`` mapping and
``--set key=value`` overrides, with errors that name the field's path.

A world file may say::

    training:
      algo: q            # q | dqn | drqn (default: q for an MDP, drqn for a POMDP), or
                         # sb3-ppo | sb3-dqn | sb3-maskable-ppo | sb3-recurrent-ppo |
                         # sb3-sac | sb3-td3 (the last two for Box actions)
      device: auto       # auto | cpu | cuda (mitlc.learn.device)
      episodes: 20000
      q: {alpha: 0.2}    # the learner's own section: QConfig, DQNConfig or DRQNConfig
      dqn: {episodes: 40000, initial_value: 100}

A section's ``episodes`` is that learner's budget: it wins over the top-level ``episodes`` when
the learner runs (so ``--algo dqn`` on a file tuned for ``q`` does not inherit its budget), and
an ``episodes`` override (``--episodes``) wins over both. The ``sb3-*`` algorithms (Stable-
Baselines3, :mod:`mitlc.learn.backends.sb3`) share the ``sb3`` section (:class:`SB3Config`), whose
budget is ``sb3.steps`` environment steps.

Every learner's config is a frozen dataclass whose fields have defaults; :func:`resolve`
checks names and types and fills the rest in.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, TypeVar

from mitlc.errors import MitlcError
from mitlc.learn.bounds import PRODUCTS, TRAINING
from mitlc.learn.names import ALGORITHMS

Algorithm = Literal[
    "q",
    "dqn",
    "drqn",
    "sb3-ppo",
    "sb3-dqn",
    "sb3-maskable-ppo",
    "sb3-recurrent-ppo",
    "sb3-sac",
    "sb3-td3",
]
Device = Literal["auto", "cpu", "cuda"]
TaskObs = Literal["auto", "state", "clocks"]
TeamMode = Literal["joint", "independent", "shared"]
DEFAULT_EPISODES = {"q": 300_000, "dqn": 5_000, "drqn": 20_000}


class ConfigError(MitlcError):
    """A training setting with a bad name or value; the message names its path."""


@dataclass(frozen=True, slots=True)
class Discount:
    """The discount of a step: ``gamma``, or with ``mode: accepting`` (Bozkurt, Wang, Zavlanos
    and Pajic, "Control synthesis from linear temporal logic specifications using model-free
    reinforcement learning", ICRA 2020) ``gamma_accept`` on steps that add an acceptance set to
    the frontier and ``gamma`` on the others. ``gamma`` stays below 1 by default: with 1 off
    acceptance, waiting forever would cost a greedy policy nothing."""

    mode: Literal["constant", "accepting"] = "constant"
    gamma: float = 0.99
    gamma_accept: float = 0.99


@dataclass(frozen=True, slots=True)
class QConfig:
    """Tabular Q-learning over (frontier, product state) pairs."""

    num_envs: int = 1024
    alpha: float = 0.5
    """The learning rate at the start."""
    alpha_end: float = 0.01
    """The learning rate at the end; it falls linearly over the run."""
    epsilon_start: float = 1.0
    epsilon_end: float = 0.1
    epsilon_decay: float = 0.6
    """The fraction of the episodes over which epsilon falls linearly to ``epsilon_end``."""
    initial_value: float = 100.0
    """Optimistic when at least the largest return (the paper's rewards are 100): untried
    actions look good, which drives exploration to the rare successes of a timed task."""
    crm: bool = False
    """Counterfactual experience (:mod:`mitlc.learn.learners.crm`): every world step also updates
    every
    other automaton state and frontier it tells about."""


@dataclass(frozen=True, slots=True)
class DQNConfig:
    """Deep Q-learning with a target network and replay (Mnih et al., Nature 2015), optionally
    Double DQN (van Hasselt, Guez and Silver, AAAI 2016)."""

    num_envs: int = 16
    hidden: int = 128
    layers: int = 2
    lr: float = 1e-3
    batch_size: int = 128
    replay_size: int = 100_000
    warmup_steps: int = 2_000
    train_every: int = 1
    """Vector steps between gradient steps."""
    target_update: int = 500
    """Gradient steps between target network copies."""
    tiles: int = 0
    """For a Box observation (a continuous world): also a one-hot of the tile it lies in, the
    box cut into this many tiles per axis (tile coding; 0: the values alone)."""
    crm: bool = False
    """Counterfactual experience (:mod:`mitlc.learn.learners.crm`) in the replay memory."""
    double: bool = True
    epsilon_start: float = 1.0
    epsilon_end: float = 0.02
    epsilon_decay: float = 0.5
    grad_clip: float = 10.0
    reward_scale: float = 0.01
    """The network learns the learning signal times this (Q values near 1 suit the Huber loss)."""
    initial_value: float = 0.0
    """The value every action starts at, in reward units (the output layer's bias; its weights
    start small): optimism drives exploration toward rarely tried actions."""
    lr_end_ratio: float = 1.0
    """The learning rate at the end of the run as a share of ``lr`` (it falls linearly)."""


@dataclass(frozen=True, slots=True)
class DRQNConfig:
    """Recurrent DQN over the observation history (Hausknecht and Stone, 2015), with sequence
    replay and burn-in (Kapturowski et al., "R2D2", ICLR 2019)."""

    num_envs: int = 16
    cell: Literal["gru", "lstm"] = "gru"
    hidden: int = 128
    lr: float = 1e-3
    batch_size: int = 32
    """Sequences per gradient step."""
    sequence_length: int = 20
    burn_in: int = 10
    replay_size: int = 5_000
    """Stored sequences."""
    warmup_sequences: int = 200
    train_every: int = 4
    target_update: int = 250
    double: bool = True
    epsilon_start: float = 1.0
    epsilon_end: float = 0.02
    epsilon_decay: float = 0.5
    grad_clip: float = 10.0
    reward_scale: float = 0.01
    """The network learns the learning signal times this (Q values near 1 suit the Huber loss)."""
    initial_value: float = 0.0
    """The value every action starts at, in reward units (the output layer's bias; its weights
    start small): optimism drives exploration toward rarely tried actions."""
    lr_end_ratio: float = 1.0
    """The learning rate at the end of the run as a share of ``lr`` (it falls linearly)."""
    previous_action: bool = True
    """Feed the previous action (one-hot) to the recurrent cell with the observation."""
    tiles: int = 0
    """For a Box observation (a continuous world): also a one-hot of the tile it lies in, the
    box cut into this many tiles per axis (tile coding; 0: the values alone)."""


# -- Stable-Baselines3 (mitlc.learn.backends.sb3): the section of the sb3-* algorithms -------------

SB3_STEPS = 100_000
"""The default budget of an sb3 run, in environment steps."""


@dataclass(frozen=True, slots=True)
class SB3Config:
    """Stable-Baselines3's algorithms (``sb3-ppo``, ``sb3-dqn``, ``sb3-maskable-ppo``,
    ``sb3-recurrent-ppo``, ``sb3-sac``, ``sb3-td3``; :mod:`mitlc.learn.backends.sb3`). Budgets
    count environment steps. A 0 where its bound allows it (:data:`mitlc.learn.bounds.TRAINING`)
    means SB3's own default for the algorithm."""

    steps: int = SB3_STEPS
    """The run's total environment steps (``total_timesteps``), also when resumed."""
    num_envs: int = 1
    log_every: int = 0
    """Environment steps between lines of ``metrics.jsonl`` (default: a hundredth of steps)."""
    checkpoint_every: int = 0
    """Environment steps between checkpoints (default: a tenth of steps)."""
    hidden: int = 64
    layers: int = 2
    """The MLP's hidden layers (``net_arch``, the actor's and the critic's for SAC and TD3;
    SB3's default is two of 64 for PPO and DQN, 256 for SAC, 400 and 300 for TD3)."""
    learning_rate: float = 0.0
    """0: SB3's (3e-4 for the PPO family and SAC, 1e-4 for DQN, 1e-3 for TD3)."""
    n_steps: int = 0
    """PPO family: steps per env per rollout; 0: SB3's (2048; 128 for recurrent PPO)."""
    batch_size: int = 0
    """Minibatch (PPO family) or replay batch (DQN, SAC, TD3); 0: SB3's (64; 128 recurrent; DQN
    32; SAC and TD3 256)."""
    n_epochs: int = 10
    ent_coef: float = 0.0
    """The entropy bonus of the PPO family (SB3's default is 0); SAC's entropy coefficient,
    where 0 means SB3's default ``"auto"`` (learned, starting at 1, toward the target entropy
    ``-dim(actions)``)."""
    buffer_size: int = 0
    """The replay capacity of DQN, SAC and TD3; 0: SB3's (1,000,000)."""
    learning_starts: int = 100
    """DQN, SAC, TD3: the steps of random actions before learning starts (SB3's default)."""
    tau: float = 0.0
    """DQN, SAC, TD3: the soft update of the target networks; 0: SB3's (1 for DQN, a hard copy
    every ``target_update_interval`` steps; 0.005 for SAC and TD3)."""
    train_freq: int = 0
    """DQN, SAC, TD3: environment steps (per env) between updates; 0: SB3's (4 for DQN, 1)."""
    gradient_steps: int = 0
    """DQN, SAC, TD3: gradient steps per update; 0: SB3's (1)."""
    noise_std: float = 0.1
    """TD3's exploration: Gaussian noise of this standard deviation on its actions, which SB3
    scales to [-1, 1] (rl-zoo's setting); 0: none, SB3's default."""
    exploration_fraction: float = 0.1
    exploration_final_eps: float = 0.05
    target_update_interval: int = 10_000
    guide_warmup: int = 0
    """SAC, TD3 with ``guide``: the env steps at the run's start in which it acts along the way
    the shaping pulls, with noise, instead of by its policy (:mod:`mitlc.learn.backends.sb3_guided`;
    envs whose action moves the labels' position along the same axes); 0: none."""
    crm: bool = False
    """DQN, SAC, TD3: counterfactual experience in the replay memory, every transition's over
    the task's other states (:mod:`mitlc.learn.backends.sb3_crm`), shaped as the run is."""
    crm_limit: int = 64
    """With ``crm``: the most counterfactual transitions one experienced step adds (a uniform
    sample of the task states where there are more, :mod:`mitlc.learn.learners.crm_env`). The
    gradient steps do not grow with them, so more dilute what the agent lived (on PointMaze,
    the more a step, the later the first success: ``docs/deadlines.md``)."""
    crm_share: float = 0.0
    """With ``crm``: the share of each sampled batch that is counterfactual, the rest lived
    (:meth:`mitlc.learn.backends.sb3_crm.CounterfactualReplay.sample`); 0: SB3's uniform sample
    over the memory."""


@dataclass(frozen=True, slots=True)
class TrainConfig:
    """Everything a run needs besides the world; saved as the run's ``config.json``."""

    algo: Algorithm = "q"
    seed: int = 0
    episodes: int = 300_000
    """The run's total, also when it is resumed (default: ``DEFAULT_EPISODES[algo]``); it stops
    at the first vector step with at least this many ended, so up to ``num_envs - 1`` more."""
    log_every: int = 3_000
    """Episodes between lines of ``metrics.jsonl`` (default: a hundredth of the episodes)."""
    checkpoint_every: int = 30_000
    """Episodes between checkpoints, also written at the end and on interruption (default: a
    tenth of the episodes)."""
    keep_checkpoints: int = 2
    """Checkpoints kept in the run directory (the latest and the ones before it); older ones
    are deleted."""
    eval_episodes: int = 10_000
    device: Device = "auto"
    """Where torch trains (:func:`mitlc.learn.device.resolve_device`): ``auto`` (CUDA where
    there is one, else the CPU), ``cpu`` or ``cuda``. A run saved without it trained on the
    CPU, as ``auto`` does on a machine without CUDA."""
    discount: Discount = field(default_factory=Discount)
    shaping: float = 0.0
    """The scale of potential-based shaping (Ng, Harada and Russell, ICML 1999) with the task's
    potential (:mod:`mitlc.task.potential`: the automaton's distance to acceptance, the env's
    distance to a proposition that advances it, the share of the deadline spent); 0 turns it
    off."""
    shaping_reach: float = 0.0
    """The env distance past which a proposition's pull is flat (0: in a finite world the
    longest distance in steps, in an env the largest distance at a first reset with the run's
    seed, resolved when the run is set up)."""
    guide: bool = False
    """Show the policy the way the shaping potential pulls (the SB3 backends on env worlds
    whose labels have regions or positions): a unit vector toward the nearest region that
    advances the task, through free space where the env's occupancy is known
    (:meth:`mitlc.gym.guide.TaskGuide.way`; the wrapper's ``guide=True``)."""
    task_obs: TaskObs = "auto"
    """What the deep learners and the SB3 backends see of the task: ``state``, a one-hot of the
    digital automaton's state; ``clocks``, the T-LDGBA's location (one-hot) and its clocks
    scaled by their bounds (:mod:`mitlc.automata.clocks`); ``auto``, the clocks where the
    automaton has more than 1,000 states and its folding has clocks, else the state
    (:func:`mitlc.automata.clocks.clocks_shown`). (Tabular Q-learning reads product
    states.)"""
    shield: float = 0.0
    """The shield's ``theta`` (:mod:`mitlc.check.shield`, finite MDPs): only actions that keep
    every shielded policy at ``theta`` times the optimum within the horizon; 0 turns it off,
    1 allows only optimal actions."""
    shield_violation: float = 1.0
    """The shield's ``delta``: only actions whose violation probability within the horizon,
    for every shielded policy, exceeds the least possible by at most ``delta``; 1 turns it
    off, 0 allows only actions of least violation."""
    shield_audit: bool = False
    """Compute the shield but do not keep to it: ``metrics.jsonl`` records the actions taken
    that it blocks and the violations that followed one (for a side-by-side benchmark)."""
    team: TeamMode = "joint"
    """How a team of robots learns (a team world, :mod:`mitlc.learn.learners.team`):
    ``joint``, one learner over the joint state and the joint action; ``independent``, one
    learner per robot (``q``: a table each) over its own observation and the task's state;
    ``shared``, one network for every robot with the robot's id in its input (``dqn``)."""
    q: QConfig = field(default_factory=QConfig)
    dqn: DQNConfig = field(default_factory=DQNConfig)
    drqn: DRQNConfig = field(default_factory=DRQNConfig)
    sb3: SB3Config = field(default_factory=SB3Config)
    """The section of every ``sb3-*`` algorithm."""

    @property
    def shielded(self) -> bool:
        """Whether a shield is asked for (``shield > 0`` or ``shield_violation < 1``)."""
        return self.shield > 0 or self.shield_violation < 1

    @property
    def learner(self) -> QConfig | DQNConfig | DRQNConfig | SB3Config:
        """The chosen algorithm's own section."""
        if self.algo.startswith("sb3-"):
            return self.sb3
        section: QConfig | DQNConfig | DRQNConfig = getattr(self, self.algo)
        return section


T = TypeVar("T")


def _coerce(value: Any, kind: Any, path: str) -> Any:
    """``value`` as the annotated type ``kind`` (int, float, bool, str, Literal, dataclass)."""
    if dataclasses.is_dataclass(kind) and isinstance(kind, type):
        if not isinstance(value, Mapping):
            raise ConfigError(f"{path}: expected a mapping, got {value!r}")
        return _build(kind, value, path)
    if typing.get_origin(kind) is Literal:
        choices = typing.get_args(kind)
        if value not in choices:
            raise ConfigError(f"{path}: expected one of {', '.join(choices)}, got {value!r}")
        return value
    if kind is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.lower() in ("true", "false"):
            return value.lower() == "true"
        raise ConfigError(f"{path}: expected true or false, got {value!r}")
    if kind in (int, float):
        if isinstance(value, bool):
            raise ConfigError(f"{path}: expected a number, got {value!r}")
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{path}: expected a number, got {value!r}") from None
        if kind is int:
            if not number.is_integer():
                raise ConfigError(f"{path}: expected an integer, got {value!r}")
            return int(number)
        return number
    if kind is str:
        return str(value)
    raise TypeError(f"unsupported setting type {kind!r} at {path}")  # pragma: no cover


def _build(cls: type[T], values: Mapping[str, Any], path: str) -> T:
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    kwargs = {}
    for key, value in values.items():
        where = f"{path}.{key}" if path else str(key)
        if key not in names:
            raise ConfigError(f"{where}: unknown setting (expected one of {', '.join(names)})")
        kwargs[key] = _coerce(value, hints[key], where)
    built = cls(**kwargs)
    _check_ranges(built, path)
    return built


def _check_ranges(config: object, path: str) -> None:
    """Each number of ``config`` (the section at ``path``) against its bound in
    :data:`mitlc.learn.bounds.TRAINING`."""
    for f in dataclasses.fields(config):  # type: ignore[arg-type]
        value = getattr(config, f.name)
        where = f"{path}.{f.name}" if path else f.name
        if isinstance(value, bool) or not isinstance(value, int | float):
            continue
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(f"{where}: expected a finite number, got {value!r}")
        problem = TRAINING[where].problem(value)  # a number without a bound is a KeyError
        if problem is not None:
            raise ConfigError(f"{where}: {problem}")


def _check_products(config: TrainConfig) -> None:
    """The products of settings against :data:`mitlc.learn.bounds.PRODUCTS`."""

    def get(path: str) -> float:
        section, name = path.split(".")
        value: float = getattr(getattr(config, section), name)
        return value

    for product in PRODUCTS:
        problem = product.problem(get)
        if problem is not None:
            raise ConfigError(f"{product.first}: {problem}")


def _build_train(values: Mapping[str, Any]) -> TrainConfig:
    """The settings of ``values`` (paths without the ``training.`` prefix), every bound
    checked."""
    config = _build(TrainConfig, values, "")
    _check_products(config)
    return config


def _nest(overrides: Mapping[str, Any]) -> dict[str, Any]:
    """``{"q.alpha": 0.2}`` as ``{"q": {"alpha": 0.2}}``."""
    nested: dict[str, Any] = {}
    for dotted, value in overrides.items():
        *heads, last = dotted.split(".")
        place = nested
        for head in heads:
            place = place.setdefault(head, {})
            if not isinstance(place, dict):
                raise ConfigError(f"{dotted}: {head} is not a section")
        place[last] = value
    return nested


def _merge(base: Mapping[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    merged = dict(base)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(merged.get(key), Mapping):
            merged[key] = _merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def resolve(
    training: Mapping[str, Any],
    overrides: Mapping[str, Any],
    *,
    discount: float,
    pomdp: bool,
) -> TrainConfig:
    """The run's settings: defaults (``drqn`` for a POMDP; the world's ``discount`` as
    ``gamma``), then the world file's ``training`` mapping, then ``overrides`` (dotted keys,
    e.g. ``{"q.alpha": "0.2"}``). Raises :class:`ConfigError` naming the path
    (``training.q.alpha``)."""
    base: dict[str, Any] = {"algo": "drqn" if pomdp else "q", "discount": {"gamma": discount}}
    extra = _nest(overrides)
    values = _merge(_merge(base, training), extra)
    if not isinstance(values.get("discount"), Mapping):
        raise ConfigError(f"training.discount: expected a mapping, got {values['discount']!r}")
    budgets = _section_episodes(values)
    algo = values.get("algo")
    if algo in budgets and "episodes" not in extra:
        values["episodes"] = budgets[algo]
    if algo in DEFAULT_EPISODES and "episodes" not in values:
        values["episodes"] = DEFAULT_EPISODES[algo]
    episodes = _coerce(values["episodes"], int, "training.episodes") if "episodes" in values else 0
    if episodes > 0:
        values.setdefault("log_every", max(1, episodes // 100))
        values.setdefault("checkpoint_every", max(1, episodes // 10))
    if isinstance(algo, str) and algo.startswith("sb3-"):
        _sb3_defaults(values)
    try:
        return _build_train(values)
    except ConfigError as err:
        raise ConfigError(f"training.{err}") from None


def _sb3_defaults(values: dict[str, Any]) -> None:
    """An sb3 run's ``sb3.log_every`` and ``sb3.checkpoint_every`` from its ``sb3.steps``."""
    section = values.get("sb3", {})
    if not isinstance(section, Mapping):
        return  # reported with its path by _build
    section = dict(section)
    steps = _coerce(section.get("steps", SB3_STEPS), int, "training.sb3.steps")
    for name, share in (("log_every", 100), ("checkpoint_every", 10)):
        if steps > 0 and _coerce(section.get(name, 0), int, f"training.sb3.{name}") == 0:
            section[name] = max(1, steps // share)
    values["sb3"] = section


def _section_episodes(values: dict[str, Any]) -> dict[str, int]:
    """Each learner section's own ``episodes``, removed from ``values`` and checked."""
    budgets = {}
    for name in ALGORITHMS:
        section = values.get(name)
        if isinstance(section, Mapping) and "episodes" in section:
            section = dict(section)
            where = f"training.{name}.episodes"
            budget = _coerce(section.pop("episodes"), int, where)
            problem = TRAINING["episodes"].problem(budget)
            if problem is not None:
                raise ConfigError(f"{where}: {problem}")
            budgets[name] = budget
            values[name] = section
    return budgets


def config_for(world: Any, overrides: Mapping[str, Any]) -> tuple[TrainConfig, str]:
    """The settings of a run on the loaded ``world`` (:func:`mitlc.worlds.door.open_world`)
    with ``overrides`` (:func:`resolve`) over its file's ``training``, and the world's name.
    The default learner is the world's own (``world.default_algo``: the recurrent DQN for a
    POMDP, DQN for a world that is not finite, else tabular Q-learning)."""
    chosen = "algo" in overrides or "algo" in world.training
    if not chosen:
        overrides = {**overrides, "algo": world.default_algo}
    config = resolve(world.training, overrides, discount=world.discount, pomdp=world.is_pomdp)
    return config, world.name


def to_data(config: TrainConfig) -> dict[str, Any]:
    """The settings as JSON-ready data (``config.json``); :func:`from_data` reads it back."""
    return dataclasses.asdict(config)


def from_data(data: Mapping[str, Any]) -> TrainConfig:
    """The settings saved by :func:`to_data`, every bound checked (a run's ``config.json``)."""
    return _build_train(data)


def validate(config: TrainConfig) -> None:
    """Check settings built in Python (not read by :func:`resolve` or :func:`from_data`)
    against every bound: a :class:`ConfigError` naming the path (``training.q.num_envs``)."""
    try:
        from_data(to_data(config))
    except ConfigError as err:
        raise ConfigError(f"training.{err}") from None


__all__ = [
    "ALGORITHMS",
    "ConfigError",
    "DQNConfig",
    "DRQNConfig",
    "Discount",
    "QConfig",
    "SB3Config",
    "TrainConfig",
    "config_for",
    "from_data",
    "resolve",
    "to_data",
    "validate",
]

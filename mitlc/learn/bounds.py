"""The bounds of every numeric setting: a world file's ``training`` mapping (also ``--set`` and a
run's ``config.json``), a sweep file, and the learning and sweep commands' options. This module
is the single source the checks read (:mod:`mitlc.learn.config`, :mod:`mitlc.sweep.spec`,
:mod:`mitlc.cli_learn`, :mod:`mitlc.cli_sweep`) and ``docs/limits_settings.md`` lists
(``tests/test_settings_bounds.py`` checks that the two agree). Each bound says why it has its
value: no value within the bounds reaches an allocation that fails with a traceback, or a loop
that runs for ever, and every shipped example and documented command stays within them.

It imports nothing heavy: the command line reads it when a command runs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from mitlc.errors import MitlcError
from mitlc.learn.names import MAX_EVAL_EPISODES


class OutOfRange(MitlcError):
    """A command-line option's value outside its bound; the message names the option."""


@dataclass(frozen=True, slots=True)
class Bound:
    """The allowed values of one setting, ``low`` to ``high`` (``low`` itself excluded where
    ``open_low``), and the reason for them."""

    low: float
    high: float
    reason: str
    open_low: bool = False

    @property
    def positive(self) -> bool:
        """Whether the bound's low end says "positive": ``[1, ...]`` or ``(0, ...]``."""
        return (self.low == 1 and not self.open_low) or (self.low == 0 and self.open_low)

    def range_text(self) -> str:
        """The allowed values in interval notation: ``[1, 65536]``, ``(0, 1]``."""
        opening = "(" if self.open_low else "["
        return f"{opening}{_show(self.low)}, {_show(self.high)}]"

    def problem(self, value: float) -> str | None:
        """What is wrong with ``value`` (``expected at most 65536, got 100000000``), or None."""
        if value != value:  # NaN: in no range
            return f"expected a finite number, got {value!r}"
        below = value <= self.low if self.open_low else value < self.low
        if not below and value <= self.high:
            return None
        if self.positive:
            return f"expected a positive value, got {value!r}" if below else (
                f"expected at most {_show(self.high)}, got {value!r}")  # fmt: skip
        return f"expected a value in {self.range_text()}, got {value!r}"


@dataclass(frozen=True, slots=True)
class Product:
    """A bound on a product of settings (what one allocation holds): ``formula`` as the docs
    and messages write it, computed by ``measure`` from a getter of settings by path."""

    formula: str
    first: str
    """The setting the message names (a path within ``training``)."""
    limit: int
    reason: str
    measure: Callable[[Callable[[str], float]], float]

    def problem(self, get: Callable[[str], float]) -> str | None:
        """What is wrong with the settings that ``get`` reads, or None."""
        value = self.measure(get)
        if value <= self.limit:
            return None
        return f"{self.formula} is {_show(value)}, expected at most {_show(self.limit)}"


def _show(number: float) -> str:
    """An integral number as an integer (``65536``), else as Python writes it."""
    if float(number).is_integer() and abs(number) < 2**64:
        return str(int(number))
    return repr(number)


def check_option(command: str, option: str, value: float | None) -> None:
    """Raise :class:`OutOfRange` naming ``option`` where ``value`` is outside the bound of
    ``command option`` in :data:`OPTIONS` (None: not given, nothing to check)."""
    if value is None:
        return
    problem = OPTIONS[f"{command} {option}"].problem(value)
    if problem is not None:
        raise OutOfRange(f"{option}: {problem}")


# -- the reasons shared by several settings -------------------------------------------------------

BUDGET = 100_000_000
"""The largest budget: episodes, or environment steps of an sb3 run."""

_BUDGET_WHY = (
    "a run's total: at tabular Q's 40,000 episodes/s (1,000,000 in 25 s on case 2) the most "
    "takes 40 minutes, the deep learners and SB3 days; the largest shipped budget is 1,200,000 "
    "episodes (frozenlake8x8), 299,008 sb3 steps (DoorKey, bench/envs_bench.py)"
)
_COUNTER_WHY = (
    "compared with a counter of the run: past the largest budget (100,000,000) it could never "
    "be reached"
)
_UNIT_WHY = "a probability or a fraction"
_HIDDEN_WHY = (
    "a 4096x4096 float32 layer is 64 MB (four times that with Adam's moments and the target "
    "network); larger networks are not what a tabular-scale task needs and would take minutes "
    "per step on CPU (shipped: 64 to 128)"
)
_LAYERS_WHY = (
    "building the network loops over its layers; 100 is 50 times the default 2 (see also the "
    "product layers x hidden^2)"
)
_LR_WHY = "an optimiser's step size: above 1 a network diverges at its first steps"
_INITIAL_WHY = (
    "an action's first value in reward units: mitlc's rewards are at most 100 (the paper's), "
    "and float32 keeps 7 digits"
)
_DEEP_ENVS_WHY = (
    "each vector step builds a num_envs x features float32 matrix (a one-hot of the world's "
    "observations and the automaton's states, thousands wide) and DRQN keeps num_envs x "
    "(4 horizon + 5) recurrent states; shipped: at most 64"
)
_TILES_WHY = (
    "a Box axis cut into this many tiles (a one-hot of tiles^axes cells): the encoder refuses "
    "more than 100,000 cells, so more tiles fit no axis"
)
_GRAD_CLIP_WHY = "a gradient norm: above 10^6 it clips nothing a network here produces"
_REWARD_SCALE_WHY = (
    "the learning signal times this: with rewards up to 100, 0.01 (the default) gives Q "
    "values near 1, the Huber loss's quadratic zone; at 1 a pass/fail reward already does"
)
_LR_END_WHY = "a share of lr: the learning rate falls linearly to lr x lr_end_ratio"
_SEED_WHY = (
    "seeds numpy's generators and torch.manual_seed; saved as a signed 64-bit integer "
    "(config.json, checkpoints)"
)


def _epsilons(section: str) -> dict[str, Bound]:
    return {f"{section}.{name}": Bound(0, 1, _UNIT_WHY)
            for name in ("epsilon_start", "epsilon_end", "epsilon_decay")}  # fmt: skip


def _deep(section: str, replay: Bound, batch: Bound) -> dict[str, Bound]:
    """The bounds DQN and DRQN share (their own replay memory and batch apart)."""
    return {
        f"{section}.num_envs": Bound(1, 1024, _DEEP_ENVS_WHY),
        f"{section}.hidden": Bound(1, 4096, _HIDDEN_WHY),
        f"{section}.lr": Bound(0, 1, _LR_WHY, open_low=True),
        f"{section}.batch_size": batch,
        f"{section}.replay_size": replay,
        f"{section}.train_every": Bound(1, BUDGET, _COUNTER_WHY),
        f"{section}.target_update": Bound(1, BUDGET, _COUNTER_WHY),
        f"{section}.tiles": Bound(0, 100_000, _TILES_WHY),
        **_epsilons(section),
        f"{section}.grad_clip": Bound(0, 1e6, _GRAD_CLIP_WHY, open_low=True),
        f"{section}.reward_scale": Bound(0, 1, _REWARD_SCALE_WHY, open_low=True),
        f"{section}.initial_value": Bound(-1e6, 1e6, _INITIAL_WHY),
        f"{section}.lr_end_ratio": Bound(0, 1, _LR_END_WHY),
    }


# fmt: off
_DQN_REPLAY = Bound(1, 1_000_000, (
    "entries allocated at the start, about 80 bytes each (plus 8 per Box axis): 80 MB and "
    "more; 1,000,000 is Mnih et al.'s (Nature 2015) and SB3's capacity (default 100,000)"))
_DRQN_REPLAY = Bound(1, 100_000, (
    "stored sequences of burn_in + sequence_length + 1 steps each, allocated at the start: "
    "100,000 of the default 31 steps are 3,100,000 steps (default 5,000 sequences)"))

# -- a world file's training mapping (--set, config.json): paths within `training` --------------

TRAINING: dict[str, Bound] = {
    "seed": Bound(0, 2**63 - 1, _SEED_WHY),
    "episodes": Bound(1, BUDGET, _BUDGET_WHY),
    "log_every": Bound(1, BUDGET, _COUNTER_WHY),
    "checkpoint_every": Bound(1, BUDGET, _COUNTER_WHY),
    "keep_checkpoints": Bound(1, 100, (
        "each kept checkpoint holds the learner's whole state (a DQN's replay memory: up to "
        "about 100 MB); 100 of them is already gigabytes of disk (default 2)")),
    "eval_episodes": Bound(1, MAX_EVAL_EPISODES, (
        "an evaluation runs its episodes all at once, so memory grows with them")),
    "shaping": Bound(0, 100, (
        "the scale of a potential difference of a few units beside rewards of at most 100; "
        "shipped worlds use 0 and 1")),
    "shaping_reach": Bound(0, 1e6, (
        "an env distance: a grid's longest distance is below its 1,000,000 cells (mitlc's "
        "limit), and a continuous world's rooms are far smaller")),
    "shield": Bound(0, 1, "a share of the optimum (0: no shield)"),
    "shield_violation": Bound(0, 1, "a probability (1: no shield)"),
    "discount.gamma": Bound(0, 1, "a discount factor"),
    "discount.gamma_accept": Bound(0, 1, "a discount factor"),
    "q.num_envs": Bound(1, 65_536, (
        "episodes step in lock step as numpy arrays of a few integers each: at 65,536 (64 "
        "times the default 1,024) case 1 trains 300,000 episodes in 7 s; a run overshoots its "
        "budget by up to num_envs - 1 episodes")),
    "q.alpha": Bound(0, 1, "a learning rate: above 1 an update overshoots its target",
                     open_low=True),
    "q.alpha_end": Bound(0, 1, "a learning rate (the last one)"),
    **_epsilons("q"),
    "q.initial_value": Bound(-1e6, 1e6, _INITIAL_WHY),
    **_deep("dqn", _DQN_REPLAY, Bound(1, 65_536, (
        "each gradient step gathers and runs batch_size replay entries: 65,536 x a few "
        "thousand features of float32 is already about a GB (default 128)"))),
    "dqn.layers": Bound(1, 100, _LAYERS_WHY),
    "dqn.warmup_steps": Bound(0, _DQN_REPLAY.high, (
        "replay entries before learning starts: the memory never holds more than "
        "replay_size's bound")),
    **_deep("drqn", _DRQN_REPLAY, Bound(1, 4096, (
        "sequences per gradient step, each of burn_in + sequence_length + 1 steps through "
        "the recurrent cell (default 32, shipped at most 64)"))),
    "drqn.sequence_length": Bound(1, 1000, (
        "transitions a stored sequence holds, learned through by backpropagation in time "
        "(default 20); an episode is at most 10,000 steps (mitlc's horizon limit)")),
    "drqn.burn_in": Bound(0, 1000, (
        "steps replayed before a sequence to warm the recurrent state (default 10)")),
    "drqn.warmup_sequences": Bound(0, _DRQN_REPLAY.high, (
        "stored sequences before learning starts: the memory never holds more than "
        "replay_size's bound")),
    "sb3.steps": Bound(1, BUDGET, _BUDGET_WHY),
    "sb3.num_envs": Bound(1, 256, (
        "copies of the env stepped one after the other in one process (SB3's DummyVecEnv): "
        "256 FrozenLakes run 4,096 steps in 2 s, 100,000 did not finish building in 90 s; "
        "shipped at most 8")),
    "sb3.log_every": Bound(0, BUDGET, _COUNTER_WHY),
    "sb3.checkpoint_every": Bound(0, BUDGET, _COUNTER_WHY),
    "sb3.hidden": Bound(1, 4096, _HIDDEN_WHY),
    "sb3.layers": Bound(1, 100, _LAYERS_WHY),
    "sb3.learning_rate": Bound(0, 1, _LR_WHY + " (0: SB3's default)"),
    "sb3.n_steps": Bound(0, 65_536, (
        "PPO's steps per env per rollout (0: SB3's 2,048), held in its rollout buffer (see "
        "the product n_steps x num_envs)")),
    "sb3.batch_size": Bound(0, 65_536, (
        "a minibatch or replay batch run through the networks at once (0: SB3's, 32 to "
        "256)")),
    "sb3.n_epochs": Bound(1, 100, "passes over each PPO rollout: 10 times SB3's default 10"),
    "sb3.ent_coef": Bound(0, 10, (
        "an entropy bonus beside rewards of at most 100 scaled to a few units: above 10 it is "
        "all the policy learns (SB3's default 0; SAC's 0: auto)")),
    "sb3.buffer_size": Bound(0, 1_000_000, (
        "SB3 allocates its replay memory at the start: 1,000,000 (0: its default) is its "
        "largest setting in rl-zoo")),
    "sb3.learning_starts": Bound(0, BUDGET, _COUNTER_WHY),
    "sb3.tau": Bound(0, 1, "a soft update's share of the new weights"),
    "sb3.train_freq": Bound(0, BUDGET, _COUNTER_WHY),
    "sb3.gradient_steps": Bound(0, 1000, (
        "gradient steps per update: 1,000 per env step makes a 100,000-step run take 10^8 "
        "gradient steps (0: SB3's 1)")),
    "sb3.noise_std": Bound(0, 10, (
        "noise on actions scaled to [-1, 1]: above a few standard deviations every action is "
        "clipped to an end")),
    "sb3.exploration_fraction": Bound(0, 1, _UNIT_WHY),
    "sb3.exploration_final_eps": Bound(0, 1, _UNIT_WHY),
    "sb3.target_update_interval": Bound(1, BUDGET, _COUNTER_WHY),
    "sb3.crm_limit": Bound(1, 4096, (
        "transitions made and stored each env step: 4,096 a step fill SB3's largest memory "
        "(1,000,000) in 245 steps")),
    "sb3.crm_share": Bound(0, 1, _UNIT_WHY),
    "sb3.guide_warmup": Bound(0, BUDGET, _COUNTER_WHY),
}
"""Every numeric training setting by its path within ``training``."""


def _span(get: Callable[[str], float]) -> float:
    return get("drqn.burn_in") + get("drqn.sequence_length") + 1


_NETWORK_WHY = (
    "float32 weights of 256 MB, four times that with the target network and Adam's moments "
    "(e.g. 4 layers of 4096, or 1,024 of 256); 4 layers of 4096 take seconds a gradient step "
    "on a 2-core CPU")

PRODUCTS: tuple[Product, ...] = (
    Product("dqn.layers x dqn.hidden^2", "dqn.layers", 2**26, _NETWORK_WHY,
            lambda get: get("dqn.layers") * get("dqn.hidden") ** 2),
    Product("sb3.layers x sb3.hidden^2", "sb3.layers", 2**26, _NETWORK_WHY,
            lambda get: get("sb3.layers") * get("sb3.hidden") ** 2),
    Product("drqn.replay_size x (drqn.burn_in + drqn.sequence_length + 1)", "drqn.replay_size",
            4_000_000, "steps the sequence replay allocates at the start, about 70 bytes each "
            "(a finite world's observation) plus a recurrent state a sequence: 280 MB and more "
            "(default 155,000)",
            lambda get: get("drqn.replay_size") * _span(get)),
    Product("drqn.batch_size x (drqn.burn_in + drqn.sequence_length + 1)", "drqn.batch_size",
            2**20, "steps one gradient step runs through the recurrent cell, each a row of "
            "features (default 992)",
            lambda get: get("drqn.batch_size") * _span(get)),
    Product("sb3.n_steps (0: 2048) x sb3.num_envs", "sb3.n_steps", 2**20,
            "the observations, values and log-probabilities PPO's rollout buffer holds "
            "(rl-zoo's largest: 2,048 x 16 = 32,768)",
            lambda get: (get("sb3.n_steps") or 2048) * get("sb3.num_envs")),
)
"""Bounds on products of training settings: what one allocation holds."""

# -- a sweep file ------------------------------------------------------------------------------

SWEEP: dict[str, Bound] = {
    "trials": Bound(1, 10_000, (
        "worlds x learners x grid points x seeds, counted from the sizes before the grid is "
        "expanded: each trial is a run directory and a line of the report")),
    "seeds": Bound(1, 10_000, "a count of seeds: no more than trials"),
    "seeds[]": Bound(0, 2**31 - 1, (
        "a listed seed: SB3 seeds numpy's legacy generator (below 2^32) with the seed plus "
        "each env's index")),
    "episodes": TRAINING["episodes"],
    "eval_episodes": TRAINING["eval_episodes"],
    "cpus_per_trial": Bound(0, 1024, "Ray's CPUs per trial: more than any node has",
                            open_low=True),
    "max_failures": Bound(0, 100, (
        "retries of a trial whose worker dies, each from its checkpoint: past a few a trial "
        "fails for a reason a retry does not remove")),
}
"""Every numeric field of a sweep file (``seeds[]``: each listed seed; ``trials``: their
number)."""

# -- the command line --------------------------------------------------------------------------

_REPS = Bound(100, 50_000, (
    "bootstrap resamples: fewer give no interval worth printing; 50,000 is rliable's own "
    "default, about 0.2 ms a setting each (10 s a setting), and memory grows with them "
    "(10^12 asked for 29 TiB)"))

OPTIONS: dict[str, Bound] = {
    "train --episodes": TRAINING["episodes"],
    "train --seed": TRAINING["seed"],
    "eval --episodes": TRAINING["eval_episodes"],
    "eval --seed": TRAINING["seed"],
    "plot --trajectories": Bound(0, 100, "greedy trajectories drawn on one figure"),
    "plot --seed": TRAINING["seed"],
    "sweep --reps": _REPS,
    "report --reps": _REPS,
    "report --seed": Bound(0, 2**32 - 1, (
        "seeds numpy's RandomState (rliable's bootstrap), which takes 32 bits")),
}
"""Every numeric option of the learning and sweep commands, by ``COMMAND --option``."""
# fmt: on

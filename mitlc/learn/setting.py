"""A run's setting, for every kind of world: ``prepare(world_path, config) -> Setting``.

One route for every world: :func:`prepare` loads the world the file declares once
(:func:`mitlc.worlds.door.open_world`, unless the command loaded it), compiles its task and,
where the world is finite, builds its product and the simulator's tables. Everything after asks
the setting what it offers, never the file again: :attr:`Setting.finite`; the world's gymnasium
envs under the task wrapper (:func:`task_vector_of`, any world); the batches of the Monte-Carlo
estimate (:func:`batches`: the product's simulator where the world is finite, else its wrapped
envs).
``config.json`` (the world file's path, the task, the settings) is written and read here.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mitlc import __version__
from mitlc.automata import DigitalAutomaton, translate
from mitlc.errors import MitlcError
from mitlc.files import write_atomically
from mitlc.learn.config import ConfigError, TrainConfig, from_data, to_data
from mitlc.learn.envs.envvec import VectorTask, task_vector
from mitlc.learn.envs.vec import Tables, VecProduct, tables
from mitlc.learn.evaluation.montecarlo import Batches
from mitlc.learn.rundir import checkpoint
from mitlc.learn.rundir.files import RunError, locked, read_json
from mitlc.learn.rundir.state import one_line
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline, LimitError
from mitlc.product.explicit import Product, build_product
from mitlc.product.worlds import AnyWorld, is_finite, open_world, task_env
from mitlc.syntax import parse
from mitlc.task.horizon import short_horizon_note
from mitlc.worlds.model import World

if TYPE_CHECKING:
    from mitlc.check.shield import Shield

CONFIG = "config.json"


@dataclass(frozen=True, slots=True)
class Setting:
    """A run's world, task and settings; for a finite world its product and the tables of
    the product's simulator too."""

    world_path: Path
    world: AnyWorld
    automaton: DigitalAutomaton
    config: TrainConfig
    product: Product | None = None
    tables: Tables | None = None

    @property
    def shield_summary(self) -> dict[str, Any] | None:
        """The settings and guarantees of the run's shield (``None``: none)."""
        shield = None if self.tables is None else self.tables.shield
        return None if shield is None else dict(shield.summary())

    @property
    def finite(self) -> bool:
        """Whether the world is finite (its product is here)."""
        return self.product is not None

    def model(self) -> tuple[World, Product, Tables]:
        """The finite world, its product and the simulator's tables (a :class:`RunError` for
        a world that is not finite)."""
        world = self.world
        if not is_finite(world) or self.product is None or self.tables is None:
            raise RunError(f"{self.world_path}: not a finite world (no product to read)")
        return world, self.product, self.tables


def prepare(
    world_path: str | Path,
    config: TrainConfig,
    spec: str | None = None,
    *,
    deadline: Deadline | None = None,
    world: AnyWorld | None = None,
) -> Setting:
    """Load the world (``world``: the file's world already loaded by the command, with
    ``spec``), compile its task (``spec`` in its place if given) and, for a finite world, build
    the product; the compile and the product stop at ``deadline`` (by default
    :data:`~mitlc.limits.DEFAULT_TIME_LIMIT` seconds)."""
    clock = Deadline.of(deadline, DEFAULT_TIME_LIMIT, "setting up the run")
    world_path = Path(world_path)
    if world is None:
        world = open_world(world_path, spec)
    automaton = translate(parse(world.spec, world.spec_source), deadline=clock)
    learned_by = getattr(world, "learned_by", None)  # a world only some learners learn
    if learned_by is not None and config.algo not in learned_by:
        raise ConfigError(f"{world_path}: --algo {config.algo} does not learn this world; use "
                          f"{' or '.join(learned_by)}")  # fmt: skip
    if config.guide and not config.algo.startswith("sb3-"):
        raise ConfigError(
            f"{world_path}: guide (the way the shaping pulls, shown to the policy) is read by "
            f"the SB3 backends (--algo sb3-sac, sb3-ppo, ...), not by --algo {config.algo}"
        )
    if (config.guide or config.sb3.guide_warmup) and is_team(world):
        raise ConfigError(
            f"{world_path}: guide and sb3.guide_warmup are read on a single robot's env, not "
            "on a team's (PettingZoo) env"
        )
    if not is_finite(world):
        if getattr(world, "costs", None) is not None:
            raise ConfigError(
                f"{world_path}: costs are learned on finite worlds (the product's transitions "
                "carry them); this world is not finite"
            )
        if config.shielded:
            raise ConfigError(
                f"{world_path}: a shield is computed from the exact product, which a world "
                "that is not finite does not have (drop --shield / --shield-violation)"
            )
        if (config.shaping or config.guide) and not config.shaping_reach:
            config = replace(config, shaping_reach=_first_reach(world, automaton, config.seed))
        return Setting(world_path, world, automaton, config)
    product = build_product(world, automaton, deadline=clock.at("the product"))
    simulated = tables(product, world)
    if world.costs is not None:
        simulated = _with_costs(world, automaton, product, simulated)
    if config.shielded:
        simulated = _shielded(world, product, simulated, config, clock.at("the shield"))
    return Setting(world_path, world, automaton, config, product, simulated)


def _first_reach(world: AnyWorld, automaton: DigitalAutomaton, seed: int) -> float:
    """The reach of the shaping potential (``shaping_reach`` 0: automatic) of a world that is
    not finite: the wrapper's own choice at a first reset with the run's seed, made once here so
    that every env of the run, its counterfactuals and a resumed run share one potential (and
    ``config.json`` records it)."""
    wrapper = task_env(world, automaton, potential=0.0)
    try:
        wrapper.reset(seed=seed)
        return wrapper.reach
    finally:
        wrapper.close()


def _with_costs(
    world: World, automaton: DigitalAutomaton, product: Product, simulated: Tables
) -> Tables:
    """``simulated`` with the cost of every product transition (:mod:`mitlc.product.costs`,
    the one definition), which the simulator takes off the reward."""
    from mitlc.product.costs import product_costs

    return replace(simulated, cost=product_costs(world, automaton, product).transition)


def _shielded(
    world: World, product: Product, simulated: Tables, config: TrainConfig, clock: Deadline
) -> Tables:
    """``simulated`` with the shield the settings ask for (:mod:`mitlc.check.shield`)."""
    from mitlc.check.shield import ShieldError, shield
    from mitlc.check.shield_observed import ObservedShield, observed_shield

    if config.algo.startswith("sb3-") and config.algo != "sb3-maskable-ppo":
        raise ConfigError(
            f"--algo {config.algo} reads no action masks, so it cannot keep to a shield: use "
            "q, dqn, drqn or sb3-maskable-ppo (sb3-contrib's MaskablePPO reads the task "
            "wrapper's action_masks())"
        )
    theta = config.shield if config.shield > 0 else None
    delta = config.shield_violation if config.shield_violation < 1 else None
    made: Shield | ObservedShield
    if world.team is not None and config.team != "joint":  # the robots choose on their own
        made = _team_shield(world, product, config, theta, delta, clock)
    elif world.is_pomdp:
        if config.algo.startswith("sb3-"):
            raise ConfigError(
                f"{world.name}: a POMDP's shield (over its observations) reaches mitlc's own "
                "learners (q, dqn, drqn), not the SB3 backends"
            )
        try:
            made = observed_shield(world, product, world.horizon, theta=theta, delta=delta,
                                   deadline=clock)  # fmt: skip
        except ShieldError as err:
            raise ConfigError(f"{world.name}: {err}") from None
    else:
        made = shield(product, world.horizon, theta=theta, delta=delta, deadline=clock)
    return replace(simulated, shield=made, shield_enforced=not config.shield_audit)


def _team_shield(
    world: World,
    product: Product,
    config: TrainConfig,
    theta: float | None,
    delta: float | None,
    clock: Deadline,
) -> Shield:
    """The per-robot shield of a team learning on its own (:mod:`mitlc.check.team_shield`):
    every combination of the robots' masks keeps the guarantee."""
    from mitlc.check.team_shield import team_shield

    assert world.team is not None
    if world.is_pomdp:
        raise ConfigError(
            f"{world.name}: a per-robot shield over noisy observations is not built; shield "
            f"the team with team: joint, or learn team: {config.team} without one"
        )
    radices = tuple(len(actions) for actions in world.team.actions)
    return team_shield(product, world.horizon, radices, theta=theta, delta=delta,
                       deadline=clock)  # fmt: skip


SMALL_NETWORKS_ON_CUDA = (
    "note: --device auto trains on CUDA here; mitlc's networks are small, and on an H200 the "
    "CPU trained every shipped learner as fast or up to 2.6 times faster: --device cpu may be "
    "quicker (docs/deadlines.md, 'On a GPU')"
)
"""The note of a deep run that ``auto`` puts on CUDA (measured by ``bench/device_speed.py``)."""


def is_team(world: Any) -> bool:
    """Whether ``world`` learns as a team of agents sharing one policy: it makes its
    multi-agent env (``team_env``) and the SB3 vector of its agents (``vec_env``), as a
    PettingZoo world does (asked of the world, never of its kind;
    :mod:`mitlc.learn.backends.sb3_team`)."""
    return callable(getattr(world, "team_env", None)) and callable(getattr(world, "vec_env", None))


POMDP_PICK = (
    "note: a POMDP; on the paper's case 2 sb3-recurrent-ppo learned none of the deadlines in "
    "150,000 steps, where --algo q (a table over the observation, the automaton state and the "
    "frontier) reached 0.940 in 5 s; --algo drqn is the paper's recurrent learner "
    "(docs/deadlines.md)"
)
"""What a run of an SB3 backend on a finite POMDP is told (measured by ``make bench-envs``)."""


def setting_notes(setting: Setting) -> list[str]:
    """One-line notes on a run's setting: a horizon shorter than the task needs to be decided
    (:func:`mitlc.task.horizon.short_horizon_note`); which learner to pick on a POMDP
    (:data:`POMDP_PICK`); the guarantee of its shield; a network that ``--device auto`` puts on
    CUDA (:data:`SMALL_NETWORKS_ON_CUDA`)."""
    world = setting.world
    note = short_horizon_note(parse(world.spec, world.spec_source), world.horizon)
    notes = [] if note is None else [note]
    config = setting.config
    if setting.finite and world.is_pomdp and config.algo.startswith("sb3-"):
        notes.append(POMDP_PICK)
    shield = setting.shield_summary
    if shield is not None:
        robots = (
            " per robot (every combination of the robots' own choices)"
            if (getattr(world, "team", None) is not None and config.team != "joint")
            else ""
        )
        notes.append(
            f"note: shield (theta {shield['theta']}, delta {shield['delta']}){robots}: every "
            f"policy it allows succeeds within the horizon with at least "
            f"{shield['guaranteed_success']:.6f} (the optimum: {shield['optimum']:.6f}) and "
            f"violates with at most {shield['guaranteed_violation']:.6f}"
        )
    if config.algo != "q" and config.device == "auto":
        from mitlc.learn.device import DeviceError, resolve_device

        try:
            if resolve_device("auto").type == "cuda":
                notes.append(SMALL_NETWORKS_ON_CUDA)
        except DeviceError:  # no torch: the run refuses itself, its learner needs it
            pass
    return notes


def task_vector_of(setting: Setting, num_envs: int, seed: int, *, flatten: bool = False) -> Any:
    """``num_envs`` fresh envs of the world under the task wrapper, as a
    :class:`~mitlc.learn.envs.envvec.VectorTask` whose first env is reset with ``seed``; with
    shaping on, the wrappers report the task's potential."""
    config = setting.config
    options: dict[str, Any] = {}
    if config.shaping or config.guide:
        options["potential"] = config.shaping_reach
    if config.guide:
        options["guide"] = True
    envs = [
        task_env(setting.world, setting.automaton, flatten=flatten, **options)
        for _ in range(num_envs)
    ]
    vector: VectorTask = task_vector(envs, seed=seed)
    return vector


def batches(setting: Setting, seed: int) -> Batches:
    """The batches of :func:`mitlc.learn.evaluation.montecarlo.monte_carlo` for the run's world: the
    product's simulator where it is finite (the batch of episodes ``first ..`` draws from
    ``default_rng((seed, first))``), else the world's wrapped envs (episode ``j`` starts from
    a reset with ``base + j``, ``base`` a 63-bit number drawn from ``seed``, so that the
    estimates of nearby seeds share no episodes)."""
    if setting.tables is not None:
        table = setting.tables

        def product_batch(count: int, first: int) -> VecProduct:
            return VecProduct(table, count, np.random.default_rng((seed, first)))

        return product_batch
    base = int(np.random.SeedSequence(seed).generate_state(1, np.uint64)[0] >> np.uint64(1))
    if is_team(setting.world):  # whole team episodes
        from mitlc.learn.backends.sb3_team import team_batches

        made: Batches = team_batches(setting, base)
        return made

    def open_batch(count: int, first: int) -> VectorTask:
        vector: VectorTask = task_vector_of(setting, count, base + first)
        return vector

    return open_batch


# -- config.json -----------------------------------------------------------------------------------


def read_config(directory: Path) -> tuple[dict[str, Any], TrainConfig]:
    """``config.json`` of a run: its raw data (``world`` and ``spec`` checked to be text) and
    the settings."""
    path = directory / CONFIG
    if not path.exists():  # a FIFO or a device there is refused by read_json, not waited on
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
    train = {"task_obs": "state", **data["train"]}  # runs from before the setting saw states
    try:
        return data, from_data(train)
    except ConfigError as err:
        raise RunError(f"{path}: train.{err}") from None


def save_config(directory: Path, setting: Setting) -> None:
    """Write the run's ``config.json``."""
    data = {
        "mitlc": __version__,
        "world": str(setting.world_path.resolve()),
        "world_name": setting.world.name,
        "spec": setting.world.spec,
        "train": to_data(setting.config),
    }
    write_atomically(
        directory / CONFIG, (json.dumps(data, indent=2, sort_keys=True) + "\n").encode()
    )


@contextmanager
def opened_run(directory: Path, setting: Setting, resume: bool, *, sb3: bool) -> Iterator[None]:
    """Hold the run directory locked for a fresh run or a resumed one, after checking it: a
    fresh run needs a directory with no run in it; a resumed one the run's own world, task and
    settings, of which only the budget (``--episodes``, and ``sb3.steps`` for Stable-Baselines3's
    runs) and the device may change."""
    if resume:
        read_config(directory)  # a run directory at all?
    else:
        directory.mkdir(parents=True, exist_ok=True)
    with locked(directory):
        _check_start(directory, setting, resume, sb3)
        yield


def _check_start(directory: Path, setting: Setting, resume: bool, sb3: bool) -> None:
    if not resume:
        if (directory / CONFIG).exists() or checkpoint.exists(directory):
            raise RunError(f"{directory}: a run is already there (use --resume, or another --out)")
        return
    data, saved = read_config(directory)
    config = setting.config
    kept = replace(saved, episodes=config.episodes, device=config.device)
    if sb3:
        kept = replace(kept, sb3=replace(saved.sb3, steps=config.sb3.steps))
    if kept != config:  # the run's settings, with what may change taken from the new ones
        budget = "sb3.steps" if sb3 else "--episodes"
        raise RunError(
            f"{directory}: --resume with settings other than the run's own (only {budget} may "
            "change, and the device)"
        )
    if Path(data["world"]) != setting.world_path.resolve() or data["spec"] != setting.world.spec:
        raise RunError(f"{directory}: --resume with another world or task than the run's")


def load_setting(directory: Path, *, deadline: Deadline | None = None) -> Setting:
    """The setting of the run in ``directory`` (built by ``deadline``, see :func:`prepare`);
    a :class:`RunError` naming ``config.json`` when its world or task no longer loads."""
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

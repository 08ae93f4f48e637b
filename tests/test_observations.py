"""Any observation the env gives reaches every learner: the readable part of a space
(:mod:`mitlc.gym.observations`: Box of any rank, Dict, Tuple, MultiBinary, MultiDiscrete, nested;
text left out), mitlc's DQN and recurrent DQN over it (images through a CNN,
:mod:`mitlc.learn.learners.images`), their checkpoints, and the SB3 backends' flat observation
with its image reader. The envs are made here, small and fast."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium import spaces

from mitlc.errors import MitlcError
from mitlc.gym import TaskWrapper, TaskWrapperError
from mitlc.gym.observations import ImagePart, UnreadableObservation, image_part, readable
from mitlc.gym.parts import TaskObservation
from mitlc.learn.config import resolve
from mitlc.learn.envs.envvec import VectorTask, task_vector
from mitlc.learn.learners.base import Learner
from mitlc.learn.learners.dqn import DQNLearner
from mitlc.learn.learners.drqn import DRQNLearner
from mitlc.learn.learners.encoder import Encoder
from mitlc.learn.learners.images import NATURE_FEATURES, SMALL_FEATURES, ImageCNN, ImageFeatures

SPEC, LABELS = "F[0,5] goal", {"goal": {"info": "goal"}}
IMAGE = spaces.Box(0, 255, (7, 7, 3), np.uint8)
MINIGRID = spaces.Dict(  # MiniGrid's observation, its mission a Text
    {"direction": spaces.Discrete(4), "image": IMAGE, "mission": spaces.Text(20)}
)
SPACES = {
    "box2d": spaces.Box(-1.0, 1.0, (5, 5), np.float32),  # highway-env's Kinematics
    "minigrid": MINIGRID,
    "tuple": spaces.Tuple(
        (
            spaces.Discrete(3, start=1),
            spaces.Box(0.0, 1.0, (2,), np.float32),
            spaces.Dict({"bits": spaces.MultiBinary(3), "name": spaces.Text(5)}),
        )
    ),
    "multibinary": spaces.MultiBinary([2, 3]),
    "multidiscrete": spaces.MultiDiscrete([[3, 2], [2, 4]], start=[[1, 0], [0, 2]]),
}


class Random(gym.Env[Any, int]):
    """Random observations of ``space``; action 1 at the third step reaches the goal; the env
    ends after four steps."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012

    def __init__(self, space: spaces.Space[Any]) -> None:
        self.observation_space, self.action_space = space, spaces.Discrete(2)
        self.t = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:
            self.observation_space.seed(seed)
        self.t = 0
        return self.observation_space.sample(), {"goal": False}

    def step(self, action: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        self.t += 1
        goal = self.t == 3 and int(action) == 1
        return self.observation_space.sample(), 0.0, self.t >= 4, False, {"goal": goal}


class Pixel(gym.Env[Any, int]):
    """One bright pixel in a dark 8x8 grey image, in its left half or its right half; the
    action naming that half (0 left, 1 right) reaches the goal; the env ends after one step.
    Chance is 1/2: only a learner that reads the image does better."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012
    SIDE = 8

    def __init__(self) -> None:
        self.observation_space = spaces.Box(0, 255, (self.SIDE, self.SIDE, 1), np.uint8)
        self.action_space = spaces.Discrete(2)
        self.half = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        rng, half = self.np_random, self.SIDE // 2
        self.half = int(rng.integers(2))
        image = np.zeros(self.observation_space.shape, np.uint8)
        image[rng.integers(self.SIDE), self.half * half + rng.integers(half), 0] = 255
        return image, {"goal": False}

    def step(self, action: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        image = np.zeros(self.observation_space.shape, np.uint8)
        return image, 0.0, True, False, {"goal": int(action) == self.half}


def wrapped(env: gym.Env[Any, Any], flatten: bool = False) -> TaskWrapper:
    return TaskWrapper(env, SPEC, LABELS, horizon=10, flatten=flatten)


def learner_of(
    vector: VectorTask, algo: str, seed: int = 0, changes: dict[str, Any] | None = None
) -> Learner:
    """DQN or the recurrent DQN on ``vector``, as :mod:`mitlc.learn.learners.open_world` makes
    them, small."""
    overrides = {"algo": algo, f"{algo}.num_envs": vector.num_envs, f"{algo}.hidden": 32,
                 f"{algo}.lr": 3e-3, f"{algo}.target_update": 50}  # fmt: skip
    if algo == "dqn":
        overrides.update({"dqn.warmup_steps": 64, "dqn.batch_size": 32, "dqn.replay_size": 4000})
    else:
        overrides.update({"drqn.warmup_sequences": 16, "drqn.batch_size": 8,
                          "drqn.sequence_length": 4, "drqn.burn_in": 2,
                          "drqn.train_every": 2})  # fmt: skip
    overrides.update(changes or {})
    config = resolve({}, overrides, discount=0.9, pomdp=False)
    space = vector.observation_space
    encoder = Encoder.of_spaces(
        space[vector.env_key], int(space["automaton"].n), vector.envs[0].monitor.num_sets,
        vector.num_actions, previous_action=algo == "drqn", images=vector.images,
    )  # fmt: skip
    rng = np.random.default_rng(seed)
    if algo == "dqn":
        return DQNLearner(None, config, rng, encoder=encoder, num_actions=vector.num_actions)
    return DRQNLearner(None, config, rng, encoder=encoder, num_actions=vector.num_actions,
                       horizon=10)  # fmt: skip


def train(learner: Learner, vector: VectorTask, steps: int) -> int:
    """``steps`` vector steps; the episodes that ended."""
    ended = 0
    for k in range(steps):
        ended += int(learner.train_step(vector, k / steps).done.sum())
    return ended


def has_conv(net: torch.nn.Module) -> bool:
    return any(isinstance(m, torch.nn.Conv2d) for m in net.modules())


# -- the readable part -------------------------------------------------------------------------


def test_the_minigrid_dict_reads_direction_and_image_and_leaves_the_mission_out() -> None:
    part = readable(MINIGRID)
    assert part.size == 4 + 147 and part.left_out == (("mission",),)
    assert part.images == (ImagePart(4, (7, 7, 3), False),)
    assert part.space.dtype == np.float32 and part.space.high[4:].max() == 255.0
    obs = MINIGRID.sample()
    obs["direction"] = 2
    flat = part.extract(obs)
    assert flat[:4].tolist() == [0, 0, 1, 0]
    assert np.array_equal(flat[4:], obs["image"].reshape(-1).astype(np.float32))


@pytest.mark.parametrize("name", sorted(SPACES))
def test_a_batch_reads_as_its_episodes_and_as_gymnasium_flattens(name: str) -> None:
    space = SPACES[name]
    space.seed(3)
    part = readable(space)
    batched = gym.vector.utils.batch_space(space, 5)
    samples = [space.sample() for _ in range(5)]
    together = gym.vector.utils.concatenate(
        space, samples, gym.vector.utils.create_empty_array(space, 5)
    )
    rows = part.extract_batch(together, 5)
    assert rows.shape == (5, part.size) and batched is not None
    for row, one in zip(rows, samples, strict=True):
        assert np.array_equal(row, part.extract(one))
        if not part.left_out:  # nothing left out: exactly gymnasium's flatten
            assert np.array_equal(row, spaces.flatten(space, one).astype(row.dtype))


def test_images_are_told_as_sb3_tells_them() -> None:
    assert image_part(IMAGE, 3) == ImagePart(3, (7, 7, 3), False)
    first = image_part(spaces.Box(0, 255, (1, 9, 9), np.uint8), 0)
    assert first is not None and first.chw == (1, 9, 9)
    for other in (spaces.Box(0, 255, (7, 7, 2), np.uint8), spaces.Box(0, 1, (7, 7, 3), np.uint8),
                  spaces.Box(0.0, 255.0, (7, 7, 3), np.float32),
                  spaces.Box(0, 255, (7, 7), np.uint8)):  # fmt: skip
        assert image_part(other, 0) is None


def test_a_space_with_nothing_readable_is_a_typed_error() -> None:
    text = spaces.Dict({"mission": spaces.Text(10), "path": spaces.Sequence(spaces.Discrete(3))})
    with pytest.raises(UnreadableObservation, match="nothing a learner can read"):
        readable(text)
    assert issubclass(UnreadableObservation, ValueError | MitlcError)
    with pytest.raises(TaskWrapperError, match="nothing a learner can read"):
        wrapped(Random(text), flatten=True)
    with pytest.raises(UnreadableObservation):
        task_vector([wrapped(Random(text))])


def test_the_sb3_flat_observation_of_the_minigrid_dict() -> None:
    view = TaskObservation.of(MINIGRID, "env", 3, 1, flatten=True)
    assert view.space.shape == (151 + 3 + 1,) and view.space.dtype == np.float32
    obs = MINIGRID.sample()
    obs["direction"] = 3
    flat = view.observe(obs, 2, 1)
    assert flat[:4].tolist() == [0, 0, 0, 1] and flat[151:].tolist() == [0, 0, 1, 1]
    assert np.array_equal(flat[4:151], obs["image"].reshape(-1))
    assert view.space.contains(flat)
    env = wrapped(Random(MINIGRID), flatten=True)  # the wrapper gives it
    first, _ = env.reset(seed=0)
    assert first.shape == (151 + env.num_q + env.monitor.num_sets,)
    assert env.observation_space.contains(first) and first[151] == 1  # automaton state 0


def test_the_sb3_policy_reads_the_image_with_a_cnn() -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from mitlc.learn.backends.sb3_images import FlatImageExtractor, image_policy_kwargs

    env = wrapped(Random(MINIGRID), flatten=True)
    kwargs = image_policy_kwargs(gym.wrappers.RecordEpisodeStatistics(env))
    assert kwargs["features_extractor_class"] is FlatImageExtractor
    assert kwargs["features_extractor_kwargs"]["images"] == (ImagePart(4, (7, 7, 3), False),)
    assert image_policy_kwargs(wrapped(Random(SPACES["tuple"]), flatten=True)) == {}
    model = PPO("MlpPolicy", env, n_steps=16, batch_size=16, n_epochs=1, device="cpu", seed=0,
                policy_kwargs={"net_arch": [16], **kwargs})  # fmt: skip
    assert has_conv(model.policy)
    extractor = model.policy.features_extractor
    task = env.num_q + env.monitor.num_sets
    assert extractor.features_dim == 4 + task + SMALL_FEATURES  # direction, task; the CNN's
    model.learn(16)
    x = torch.zeros(2, int(env.observation_space.shape[0]))
    x[1, 4:151] = 255.0  # the extractor scales the raw pixels itself
    features = extractor(x)
    assert features.shape == (2, extractor.features_dim) and not torch.equal(*features)


# -- the CNN -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("chw", "features"),
    [((3, 36, 40), NATURE_FEATURES), ((3, 7, 7), SMALL_FEATURES), ((1, 3, 3), SMALL_FEATURES),
     ((1, 1, 1), SMALL_FEATURES)],
)  # fmt: skip
def test_the_cnn_fits_the_image(chw: tuple[int, int, int], features: int) -> None:
    cnn = ImageCNN(chw)
    assert cnn.features == features
    assert cnn(torch.rand(2, *chw)).shape == (2, features)
    convs = [m for m in cnn.modules() if isinstance(m, torch.nn.Conv2d)]
    side = min(chw[1:])
    if side >= 36:
        assert [c.kernel_size for c in convs] == [(8, 8), (4, 4), (3, 3)]
    else:
        assert [c.out_channels for c in convs] == [16, 32, 64][: min(3, side - 1)]


def test_image_features_cut_the_image_out_of_the_vector() -> None:
    part = ImagePart(2, (4, 4, 1), False)
    reader = ImageFeatures(2 + 16 + 3, [part])
    x = torch.rand(5, 6, 21)  # any leading shape
    out = reader(x)
    assert reader.out == 5 + SMALL_FEATURES and out.shape == (5, 6, reader.out)
    assert torch.equal(out[..., :2], x[..., :2]) and torch.equal(out[..., 2:5], x[..., 18:])
    changed = x.clone()
    changed[..., 2:18] = 0.0
    assert not torch.equal(reader(changed)[..., 5:], out[..., 5:])
    with pytest.raises(ValueError, match="does not fit"):
        ImageFeatures(10, [part])


# -- mitlc's learners --------------------------------------------------------------------------


@pytest.mark.parametrize("algo", ["dqn", "drqn"])
@pytest.mark.parametrize("name", sorted(SPACES))
def test_every_space_trains_and_checkpoints(name: str, algo: str) -> None:
    vector = task_vector([wrapped(Random(SPACES[name])) for _ in range(4)], seed=0)
    size = readable(SPACES[name]).size
    assert vector.observation.shape == (4, size)
    learner = learner_of(vector, algo)
    assert has_conv(learner.net) == (name == "minigrid")  # type: ignore[attr-defined]
    ended = train(learner, vector, 60)  # 240 env steps
    assert ended >= 4 * 60 // 5 - 4 and learner.gradient_steps > 0  # type: ignore[attr-defined]
    saved = learner.state_dict()
    other = learner_of(vector, algo, seed=1)
    other.load_state_dict(saved)
    again = other.state_dict()
    for key, value in saved["net"].items():
        assert torch.equal(value, again["net"][key])
    for key, value in saved["replay"]["data"].items():
        assert np.array_equal(value, again["replay"]["data"][key])
    first, second = learner.policy(), other.policy()
    assert np.array_equal(first.act(vector), second.act(vector))


def test_a_checkpoint_with_an_image_reader_does_not_fit_a_learner_without() -> None:
    vector = task_vector([wrapped(Random(MINIGRID)) for _ in range(2)], seed=0)
    learner = learner_of(vector, "dqn")
    space = vector.observation_space
    flat = Encoder.of_spaces(space["env"], int(space["automaton"].n), 1, vector.num_actions)
    config = resolve({}, {"algo": "dqn", "dqn.num_envs": 2, "dqn.hidden": 32}, discount=0.9,
                     pomdp=False)  # fmt: skip
    plain = DQNLearner(None, config, np.random.default_rng(0), encoder=flat, num_actions=2)
    assert not has_conv(plain.net)
    with pytest.raises((RuntimeError, ValueError)):
        plain.load_state_dict(learner.state_dict())


def test_the_encoder_scales_the_image_to_the_unit_interval() -> None:
    vector = task_vector([wrapped(Random(MINIGRID)) for _ in range(3)], seed=0)
    encoder = learner_of(vector, "dqn").encoder  # type: ignore[attr-defined]
    x = encoder(vector.observation, vector.automaton, vector.mask)
    image = x[:, 4:151]
    assert float(image.max()) <= 1.0 and float(image.max()) > 0.5
    expected = vector.observation[:, 4:151] / 255.0
    assert np.allclose(image.numpy(), expected)


LEARNS = {  # vector steps of 8 episodes (each one step long), and settings
    "dqn": (160, {"dqn.lr": 2e-3, "dqn.target_update": 20}),
    "drqn": (160, {"drqn.lr": 1e-3, "drqn.target_update": 20, "drqn.train_every": 1,
                   "drqn.batch_size": 32, "drqn.sequence_length": 1, "drqn.burn_in": 0}),
}  # fmt: skip


@pytest.mark.parametrize("algo", ["dqn", "drqn"])
def test_a_learner_reads_the_pixel_that_decides(algo: str) -> None:
    """Chance is 1/2; a learner that reads the image through its CNN does far better."""
    vector = task_vector([wrapped(Pixel()) for _ in range(8)], seed=0)
    assert vector.images == (ImagePart(0, (8, 8, 1), False),)
    steps, settings = LEARNS[algo]
    learner = learner_of(vector, algo, changes={f"{algo}.epsilon_decay": 0.6, **settings})
    assert has_conv(learner.net)  # type: ignore[attr-defined]
    train(learner, vector, steps)
    policy, wins, ended = learner.policy(), 0, 0
    while ended < 160:
        step = vector.step(policy.act(vector))
        policy.observe(step)
        wins += int((step.success & step.done).sum())
        ended += int(step.done.sum())
    assert wins / ended >= 0.85

"""The replay memory of SB3's off-policy backends in checkpoints
(:mod:`mitlc.learn.backends.sb3_replay`): a memory saved and loaded through a checkpoint's files
is the memory it was (wrapped around or not, dict observations, counterfactual rows and their
generator); rows that do not fit are refused; a run resumed from a checkpoint without its
memory (an older mitlc's, or one too large to save) refills it before it learns again."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3.common.buffers import DictReplayBuffer, ReplayBuffer

from mitlc.learn.backends import sb3_replay
from mitlc.learn.backends.sb3_crm import CounterfactualReplay
from mitlc.learn.backends.sb3_replay import ReplayState
from mitlc.learn.rundir import checkpoint
from tests.test_sb3_continuous import train
from tests.test_sb3_crm_store import pendulum_task, random_rows

ACTION = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)


def fill(memory: Any, rng: np.random.Generator, steps: int) -> None:
    """``steps`` of SB3's ``add`` with random transitions of ``memory``'s spaces."""
    space, n = memory.observation_space, memory.n_envs
    for _ in range(steps):
        obs = (
            {k: np.stack([s.sample() for _ in range(n)]) for k, s in space.spaces.items()}
            if isinstance(space, gym.spaces.Dict)
            else np.stack([space.sample() for _ in range(n)])
        )
        after = {k: v + 1 for k, v in obs.items()} if isinstance(obs, dict) else obs + 1
        action = rng.uniform(-2, 2, size=(n, 1)).astype(np.float32)
        done = rng.random(n) < 0.2
        infos = [{"TimeLimit.truncated": bool(rng.random() < 0.5)} for _ in range(n)]
        memory.add(obs, after, action, rng.normal(size=n), done, infos)


def through_files(memory: Any, fresh: Any, directory: Path) -> ReplayState:
    """Save ``memory``'s state in a checkpoint, load it back into ``fresh``."""
    checkpoint.save(directory, 1, {"replay": ReplayState(memory).state_dict()})
    state = ReplayState(fresh)
    state.load_state_dict(checkpoint.load(directory).state["replay"])
    return state


def arrays_of(memory: Any) -> dict[str, np.ndarray[Any, Any]]:
    return {k: v.copy() for k, v in sb3_replay._buffers(memory).items()}


@pytest.mark.parametrize("steps", [0, 3, 5, 12])
def test_a_memory_comes_back_as_it_was(tmp_path: Path, steps: int) -> None:
    """Empty, part full, just full and wrapped around (10 transitions of 2 envs: 5 rows):
    every array, ``pos`` and ``full`` as saved."""
    space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
    memory = ReplayBuffer(10, space, ACTION, "cpu", 2)
    fill(memory, np.random.default_rng(steps), steps)
    fresh = ReplayBuffer(10, space, ACTION, "cpu", 2)
    state = through_files(memory, fresh, tmp_path)
    assert state.restored and (fresh.pos, fresh.full) == (memory.pos, memory.full)
    assert memory.buffer_size == 5 and (fresh.pos, fresh.full) == (steps % 5, steps >= 5)
    for name, array in arrays_of(memory).items():
        assert np.array_equal(getattr(fresh, name), array), name
    if 0 < steps < 5:  # the rows not yet written stay as a fresh memory has them
        assert not fresh.observations[steps:].any()


def test_a_dict_observation_and_the_memory_sampled_after(tmp_path: Path) -> None:
    """A dict observation's keys each come back; the two memories sample the same batch."""
    space = gym.spaces.Dict({"a": gym.spaces.Box(0, 1, (2,)), "b": gym.spaces.Discrete(4)})
    memory = DictReplayBuffer(9, space, ACTION, "cpu", 1)
    fill(memory, np.random.default_rng(0), 12)
    fresh = DictReplayBuffer(9, space, ACTION, "cpu", 1)
    through_files(memory, fresh, tmp_path)
    assert set(sb3_replay._buffers(memory)) >= {"observations:a", "observations:b"}
    np.random.seed(4)
    one = memory.sample(5)
    np.random.seed(4)
    two = fresh.sample(5)
    for key in ("a", "b"):
        assert np.array_equal(one.observations[key].numpy(), two.observations[key].numpy())
    assert np.array_equal(one.rewards.numpy(), two.rewards.numpy())


def test_counterfactual_rows_their_count_and_generator_come_back(tmp_path: Path) -> None:
    """Which rows are counterfactual, how many were made, and the generator that samples them:
    the restored one draws what the saved one draws next."""
    task = pendulum_task()
    space = task.view.space
    memory = CounterfactualReplay(11, space, ACTION, "cpu", 1, task=task, seed=5)
    rng = np.random.default_rng(1)
    memory.store_rows(random_rows(rng, 4, gym.spaces.flatdim(space)))
    fill(memory, rng, 3)
    memory.made = 4
    memory.rng.random(3)  # moved on from its seed
    fresh = CounterfactualReplay(11, space, ACTION, "cpu", 1, task=task, seed=5)
    through_files(memory, fresh, tmp_path)
    assert fresh.counterfactual[:, 0].tolist() == [True] * 4 + [False] * 3 + [False] * 4
    assert fresh.made == 4 and fresh.pos == 7
    assert np.array_equal(fresh.rng.random(4), memory.rng.random(4))


def test_rows_that_do_not_fit_are_refused(tmp_path: Path) -> None:
    """Rows unlike the memory's position, or another observation's shape: a ValueError (the
    run's restore makes it a one-line RunError naming the checkpoint)."""
    space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
    memory = ReplayBuffer(7, space, ACTION, "cpu", 1)
    fill(memory, np.random.default_rng(0), 4)
    saved = ReplayState(memory).state_dict()
    with pytest.raises(ValueError, match=re.escape("observations is float32 (4, 1, 3), expected")):
        ReplayState(ReplayBuffer(7, space, ACTION, "cpu", 1)).load_state_dict({**saved, "pos": 5})
    wide = gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    with pytest.raises(ValueError, match=re.escape("expected float32 (4, 1, 4)")):
        ReplayState(ReplayBuffer(7, wide, ACTION, "cpu", 1)).load_state_dict(saved)
    with pytest.raises(ValueError, match="position 9 outside a memory of 7 rows"):
        ReplayState(ReplayBuffer(7, space, ACTION, "cpu", 1)).load_state_dict({**saved, "pos": 9})


def without_replay(out: Path) -> None:
    """Rewrite ``out``'s latest checkpoint as an older mitlc wrote it: no replay memory."""
    loaded = checkpoint.load(out)
    state = loaded.state
    del state["model"]["replay"]
    checkpoint.save(out, loaded.steps, state)


@pytest.mark.parametrize("how", ["older checkpoint", "too large"])
def test_a_run_resumed_without_its_memory_refills_it(
    tmp_path: Path, how: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A checkpoint without the memory (an older mitlc's), or with a memory too large to save:
    the resumed run goes on, taking ``learning_starts`` (50) steps before it learns again: 100
    updates by step 150, 60 more by 260 (110 with the memory restored)."""
    world = tmp_path / "pendulum.yaml"
    from tests.test_sb3_continuous import PENDULUM

    world.write_text(PENDULUM)
    out = tmp_path / "run"
    if how == "too large":
        monkeypatch.setattr(sb3_replay, "REPLAY_BYTES", 100)
    assert train(world, out, "sb3-sac", 150).exit_code == 0
    if how == "older checkpoint":
        without_replay(out)
    else:
        saved = checkpoint.load(out).state["model"]["replay"]
        assert not saved["kept"] and saved["arrays"] == {} and saved["pos"] == 150
    more = train(world, out, None, 260, "--resume")
    assert more.exit_code == 0, more.output
    why = "an older mitlc's" if how == "older checkpoint" else "its rows take more than 100 bytes"
    assert why in more.output and "50 steps of random actions to refill it" in more.output
    model = checkpoint.load(out).state["model"]
    assert model["counters"]["n_updates"] == 160


@pytest.mark.parametrize("share", ["0", "0.5"])
def test_a_resumed_run_with_counterfactuals_goes_on_with_its_memory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, share: str
) -> None:
    """``sb3.crm``: the memory the resumed SAC starts from is the checkpoint's (its rows, which
    of them are counterfactual, their count), and it learns from its first step; with
    ``sb3.crm_share`` too."""
    from mitlc.learn.backends.sb3 import ModelState
    from tests.test_sb3_continuous import PENDULUM

    world = tmp_path / "pendulum.yaml"
    world.write_text(PENDULUM)
    out = tmp_path / "run"
    shared = f"sb3.crm_share={share}"
    assert (
        train(world, out, "sb3-sac", 150, "sb3.crm=true", "sb3.crm_limit=2", shared).exit_code == 0
    )
    saved = checkpoint.load(out).state["model"]["replay"]
    flags = saved["arrays"]["counterfactual"]
    assert saved["kept"] and saved["made"] > 0 and int(flags.sum()) == saved["made"]
    assert len(flags) == saved["pos"] > 150
    loaded: dict[str, Any] = {}
    load = ModelState.load_state_dict

    def spy(self: ModelState, state: dict[str, Any]) -> None:
        load(self, state)
        assert self.replay is not None
        loaded.update(rows=self.replay.rows(), made=self.replay.memory.made,
                      arrays=arrays_of(self.replay.memory))  # fmt: skip

    monkeypatch.setattr(ModelState, "load_state_dict", spy)
    more = train(world, out, None, 260, "--resume")
    assert more.exit_code == 0, more.output
    assert loaded["rows"] == saved["pos"] and loaded["made"] == saved["made"]
    for name, array in saved["arrays"].items():
        assert np.array_equal(loaded["arrays"][name][: saved["pos"]], array), name
    assert checkpoint.load(out).state["model"]["counters"]["n_updates"] == 210

"""The counterfactual replay's bulk paths against their one-by-one references: a block of rows
stored at once (:meth:`CounterfactualReplay.store_rows`) is what SB3's own ``add`` stores row
by row, wrapping around the memory; the dense task-part table of :class:`FlatTask` gives what
the part of each task state built one at a time gives."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from mitlc.gym import TaskWrapper

pytest.importorskip("stable_baselines3")

from stable_baselines3.common.buffers import ReplayBuffer

from mitlc.learn.backends import sb3_crm
from mitlc.learn.backends.sb3_crm import CounterfactualReplay, FlatTask

LABELS = {"up": {"box": {"index": [0], "low": [0.9], "high": [1.0]}},
          "left": {"box": {"index": [1], "low": [0.5], "high": [1.0]}}}  # fmt: skip


def pendulum_task(task_obs: str = "state") -> FlatTask:
    env = TaskWrapper(gym.make("Pendulum-v1"), "F[0,6] up & G[0,9] (left -> F[0,3] up)",
                      LABELS, horizon=12, flatten=True, task_obs=task_obs)  # type: ignore[arg-type]  # fmt: skip
    return FlatTask.of(env)


def random_rows(rng: np.random.Generator, count: int, dim: int) -> dict[str, Any]:
    return {
        "obs": rng.normal(size=(count, dim)).astype(np.float32),
        "next_obs": rng.normal(size=(count, dim)).astype(np.float32),
        "action": rng.uniform(-2, 2, size=(count, 1)).astype(np.float32),
        "reward": rng.normal(size=count).astype(np.float32),
        "done": (rng.random(count) < 0.3).astype(np.float32),
        "timeout": rng.random(count) < 0.2,
    }


@pytest.mark.parametrize("n_envs", [1, 2, 3])
def test_a_block_of_rows_is_stored_as_sb3_stores_them_one_at_a_time(n_envs: int) -> None:
    """Blocks of 0 to 3 memories' worth of rows, in turn: the arrays, ``pos`` and ``full`` equal
    those of SB3's ``ReplayBuffer`` fed the same rows through its ``add``."""
    task = pendulum_task()
    space = task.view.space
    action = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)
    size = 7
    memory = CounterfactualReplay(size, space, action, "cpu", n_envs, task=task)
    reference = ReplayBuffer(size, space, action, "cpu", n_envs)
    rng = np.random.default_rng(3)
    for rows_count in (0, 2, 5, 1, 9, 23, 4):
        rows = random_rows(rng, rows_count * n_envs, gym.spaces.flatdim(space))
        memory.store_rows(rows)
        for r in range(rows_count):
            part = {k: v[r * n_envs : (r + 1) * n_envs] for k, v in rows.items()}
            infos = [{"TimeLimit.truncated": bool(t)} for t in part["timeout"]]
            reference.add(part["obs"], part["next_obs"], part["action"], part["reward"],
                          part["done"], infos)  # fmt: skip
        assert (memory.pos, memory.full) == (reference.pos, reference.full)
        for name in ("observations", "next_observations", "actions", "rewards", "dones",
                     "timeouts"):  # fmt: skip
            np.testing.assert_array_equal(getattr(memory, name), getattr(reference, name))
    assert memory.counterfactual.all() and memory.full


@pytest.mark.parametrize("task_obs", ["state", "clocks"])
def test_the_dense_task_parts_are_the_parts_made_one_by_one(
    task_obs: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``observe`` through the dense table (filled as task states turn up) equals the loop over
    ``part`` that a task too large for the table takes, on random rows and task states."""
    dense = pendulum_task(task_obs)
    monkeypatch.setattr(sb3_crm, "DENSE", 0)
    looped = pendulum_task(task_obs)
    assert dense._index.size and not looped._index.size
    rng = np.random.default_rng(0)
    num_q, frontiers = dense.view.num_q, 1 << dense.view.num_sets
    for count in (1, 5, 40, 40):
        flat = rng.normal(size=(count, gym.spaces.flatdim(dense.view.space))).astype(np.float32)
        q = rng.integers(num_q, size=count)
        frontier = rng.integers(frontiers, size=count)
        got = dense.observe(flat, q, frontier)
        np.testing.assert_array_equal(got, looped.observe(flat, q, frontier))
        np.testing.assert_array_equal(got[:, : dense.view.env_dim], flat[:, : dense.view.env_dim])


@pytest.mark.parametrize("limit", [1, 3])
def test_sb3_crm_limit_bounds_the_counterfactuals_of_a_step(tmp_path: Any, limit: int) -> None:
    """``sb3.crm_limit``: SAC on Pendulum (whose task has more pending states than the limit)
    adds at most ``limit`` counterfactuals an env step, and exactly that many on the steps that
    give any (it samples when there are more)."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    from mitlc.learn.backends.sb3 import algorithm, model_settings, wrapped_env
    from mitlc.learn.config import resolve
    from mitlc.learn.setting import prepare
    from tests.test_crm_env import PENDULUM, TINY

    path = tmp_path / "pendulum.yaml"
    path.write_text(PENDULUM)
    settings = {"algo": "sb3-sac", **TINY, "sb3.crm_limit": limit}
    config = resolve({}, settings, discount=0.95, pomdp=False)
    setting = prepare(path, config)
    venv: Any = make_vec_env(lambda: wrapped_env(setting), 1, seed=0, vec_env_cls=DummyVecEnv)
    cls, policy = algorithm("sb3-sac")
    model = cls(policy, venv, seed=0, device="cpu", **model_settings(config, venv.envs[0]))
    memory = model.replay_buffer
    assert isinstance(memory, CounterfactualReplay)
    assert len(memory.task.counterfactuals.pair_q) > limit
    made = []
    add = memory.add

    def counted(*args: Any, **kwargs: Any) -> None:
        before = memory.made
        add(*args, **kwargs)
        made.append(memory.made - before)

    memory.add = counted  # type: ignore[method-assign]
    model.learn(120)
    assert len(made) == 120 and set(made) <= {0, limit} and made.count(limit) > 100


def mixed_memory(share: float, lived: int, made: int, seed: int = 1) -> CounterfactualReplay:
    """A memory of 2 envs holding ``lived`` rows put in by SB3's own ``add`` (reward 1), then
    ``made`` counterfactual rows (reward -1); each cell's first observation value is its
    number (row * 2 + env)."""
    task = pendulum_task()
    space, n = task.view.space, 2
    action = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)
    memory = CounterfactualReplay((lived + made) * n, space, action, "cpu", n, task=task, seed=seed,
                                  share=share)  # fmt: skip
    rows = random_rows(np.random.default_rng(0), (lived + made) * n, gym.spaces.flatdim(space))
    rows["obs"][:, 0] = np.arange((lived + made) * n)
    rows["reward"][:] = np.repeat([1.0, -1.0], [lived * n, made * n])
    for r in range(lived):
        part = {k: v[r * n : (r + 1) * n] for k, v in rows.items()}
        ReplayBuffer.add(memory, part["obs"], part["next_obs"], part["action"], part["reward"],
                         part["done"], [{}] * n)  # fmt: skip
    memory.store_rows({k: v[lived * n :] for k, v in rows.items()})
    assert memory.counterfactual.sum() == made * n
    return memory


def same_batch(a: Any, b: Any) -> bool:
    """Whether two SB3 batches hold the same tensors (its fields left None alike)."""
    return all(
        (x is None and y is None) or np.array_equal(x.numpy(), y.numpy())
        for x, y in zip(a, b, strict=True)
    )


def test_a_share_fixes_the_mix_of_each_batch_and_each_kind_is_drawn_uniformly() -> None:
    """``sb3.crm_share``: 10 lived rows and 40 counterfactual ones; a batch of 64 at share 0.25
    holds 16 counterfactual transitions and 48 lived ones, whatever the memory's proportions.
    Over 400 batches every cell of each kind turns up about equally often; the same seed
    draws the same batches."""
    memory = mixed_memory(0.25, lived=10, made=40)
    seen = np.zeros(100, dtype=np.int64)
    for _ in range(400):
        batch = memory.sample(64)
        rewards = batch.rewards.numpy().ravel()
        assert (rewards == -1).sum() == 16 and (rewards == 1).sum() == 48
        cells = batch.observations.numpy()[:, 0].astype(np.int64)
        assert np.array_equal(rewards, np.where(cells < 20, 1.0, -1.0))  # the cell's own row
        np.add.at(seen, cells, 1)
    lived, made = seen[:20], seen[20:]
    assert lived.sum() == 400 * 48 and made.sum() == 400 * 16
    assert lived.min() > 0.8 * lived.mean() and lived.max() < 1.2 * lived.mean()
    assert made.min() > 0.6 * made.mean() and made.max() < 1.4 * made.mean()
    first, again = mixed_memory(0.25, 10, 40, seed=5), mixed_memory(0.25, 10, 40, seed=5)
    for _ in range(5):
        assert same_batch(first.sample(32), again.sample(32))


@pytest.mark.parametrize(("lived", "made"), [(6, 0), (0, 6)])
def test_a_share_takes_the_one_kind_a_memory_holds(lived: int, made: int) -> None:
    memory = mixed_memory(0.5, lived=lived, made=made)
    rewards = memory.sample(40).rewards.numpy().ravel()
    assert len(rewards) == 40 and set(rewards.tolist()) == {1.0 if lived else -1.0}


def test_no_share_is_sb3s_own_uniform_sample() -> None:
    """Share 0: the batch SB3's ``ReplayBuffer.sample`` draws (numpy's global generator) from
    the same contents."""
    memory = mixed_memory(0.0, lived=10, made=40)
    reference = ReplayBuffer(memory.buffer_size * memory.n_envs, memory.observation_space,
                             memory.action_space, "cpu", memory.n_envs)  # fmt: skip
    for name in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts"):
        setattr(reference, name, getattr(memory, name).copy())
    reference.pos, reference.full = memory.pos, memory.full
    for _ in range(3):
        np.random.seed(11)
        ours = memory.sample(32)
        np.random.seed(11)
        theirs = reference.sample(32)
        assert same_batch(ours, theirs)

"""Counterfactual experience for tabular Q-learning on a wrapped env
(:class:`mitlc.learn.learners.qlearning_env.ObservedQLearner` with ``q.crm``), against the
hand-worked line of ``tests/test_crm_env.py``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mitlc.learn.config import resolve
from mitlc.learn.envs.envvec import task_vector
from mitlc.learn.learners.crm_env import EnvCounterfactuals
from mitlc.learn.learners.qlearning_env import ObservedQLearner
from tests.test_crm_env import CHAIN, RIGHT, A, by_hand, line

NUM_Q = 8  # the line task's digital automaton (0..7)


def learner(crm: EnvCounterfactuals | None, start: float) -> ObservedQLearner:
    config = resolve({}, {"algo": "q", "q.num_envs": 1, "q.initial_value": start,
                          "q.alpha": 0.5, "q.alpha_end": 0.5, "q.epsilon_start": 0.0,
                          "q.epsilon_end": 0.0, "q.crm": crm is not None},
                     discount=0.9, pomdp=False)  # fmt: skip
    return ObservedQLearner(5, NUM_Q, 0, 2, config, np.random.default_rng(0),
                            counterfactuals=crm)  # fmt: skip


def test_one_step_updates_every_other_task_state_as_the_table_says() -> None:
    """From cell 1 (``a``) right to cell 2 in state 0: besides the experienced entry, the
    entries (cell 1, q, right) of the five other pending states move half way (alpha 0.5) to
    the table's reward plus 0.9 x the best of the next entry (0 where the task ends)."""
    start = 0.25
    envs = [line()]
    vector = task_vector(envs, seed=0)
    q = learner(EnvCounterfactuals.of(envs[0]), start)
    q.q_table[0, 1 * NUM_Q + 0, 0] = -1.0  # greedy: right from (cell 1, state 0)
    q.train_step(vector, 0.0)
    table = q.q_table[0]
    experienced = (2 * NUM_Q + 2, start)  # reached cell 2 in state 2: both actions still 0.25
    for other, (_, reward, ended) in by_hand(A, 0).items():
        target = reward + (0.0 if ended else 0.9 * experienced[1])
        assert table[1 * NUM_Q + other, RIGHT] == pytest.approx(start + 0.5 * (target - start))
        assert table[1 * NUM_Q + other, 0] == start  # the other action: untouched
    assert table[1 * NUM_Q + 0, RIGHT] == pytest.approx(start + 0.5 * (-0.1 + 0.9 * start - start))
    untouched = np.ones(table.shape[0], dtype=bool)
    untouched[[1 * NUM_Q + k for k in (0, 1, 2, 4, 5, 6)]] = False
    assert (table[untouched] == start).all()


def test_without_crm_only_the_experienced_entry_moves() -> None:
    vector = task_vector([line()], seed=0)
    q = learner(None, 0.25)
    q.q_table[0, 1 * NUM_Q + 0, 0] = -1.0
    q.train_step(vector, 0.0)
    moved = np.argwhere(q.q_table[0] != 0.25)
    assert sorted(map(tuple, moved.tolist())) == [(NUM_Q, 0), (NUM_Q, RIGHT)]


def test_q_crm_on_an_env_world_trains(tmp_path: Path) -> None:
    """``--algo q --set q.crm=true`` on the slippery chain (a discrete observation) trains, and
    in 3,000 episodes its greedy policy mostly does the task (0.78 over these 100 episodes;
    0.0025 without counterfactuals, measured in ``docs/deadlines.md``)."""
    from mitlc.learn.evaluation.evaluate import evaluate
    from mitlc.learn.run import train

    path = tmp_path / "chain.yaml"
    path.write_text(CHAIN)
    config = resolve({}, {"algo": "q", "episodes": 3000, "q.crm": True}, discount=0.95,
                     pomdp=False)  # fmt: skip
    assert not train(path, config, tmp_path / "run").stopped
    assert evaluate(tmp_path / "run", episodes=100).successes >= 60

"""Recurrent deep Q-learning for POMDP products (Hausknecht and Stone, "Deep recurrent
Q-learning for partially observable MDPs", 2015) with sequence replay and burn-in (Kapturowski
et al., "Recurrent experience replay in distributed reinforcement learning" (R2D2), ICLR 2019),
a target network (Mnih et al., Nature 2015) and optionally Double DQN (van Hasselt, Guez and
Silver, AAAI 2016).

Each step the network reads what the agent sees (the observation, the automaton state, the
frontier mask and the previous action, see :class:`mitlc.learn.learners.nets.Encoder`) through a
GRU or
LSTM whose state carries the episode's history; it restarts from zero when an episode ends.
Each episode's stream is cut into segments of ``sequence_length`` transitions; a segment is
stored with the ``burn_in`` inputs before it and the recurrent state the actor had at the first
of those (zero at an episode's start), so a sequence never spans two episodes (a short last
segment is padded and the padding is left out of the loss). Learning unrolls the online and the
target network over the burn-in without gradient from the stored state, then over the segment,
and moves each step's value toward ``r + gamma * Q_target(next, best valid action)`` (0 after a
terminal step) under the Huber loss.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import torch
from torch import nn

from mitlc.learn.config import DRQNConfig, TrainConfig
from mitlc.learn.device import resolve_device
from mitlc.learn.envs.vec import Step, Tables
from mitlc.learn.learners.base import (
    Episodes,
    Learner,
    Policy,
    Shaping,
    epsilon_at,
    learning_signal,
    random_valid,
)
from mitlc.learn.learners.encoder import Encoder
from mitlc.learn.learners.images import ImageFeatures, image_features
from mitlc.learn.learners.nets import (
    Ring,
    anneal,
    bootstrap,
    build,
    check_indices,
    configure_torch,
    deep_state,
    gradient_step,
    greedy,
    huber,
    load_deep_state,
    optimistic,
    tensors,
    torch_seed,
)
from mitlc.worlds.model import BoolArray, FloatArray, IntArray


class Recurrent(nn.Module):
    """A ReLU layer (after the CNNs of the images in the inputs, with ``features``:
    :mod:`mitlc.learn.learners.images`), a GRU or LSTM, a linear head. The recurrent state is
    one tensor of shape ``(batch, state_size)`` (an LSTM's ``h`` and ``c`` side by side)."""

    def __init__(
        self, inputs: int, hidden: int, actions: int, cell: str,
        features: ImageFeatures | None = None,
    ) -> None:  # fmt: skip
        super().__init__()
        self.hidden, self.lstm = hidden, cell == "lstm"
        first = [] if features is None else [features]
        width = inputs if features is None else features.out
        self.embed = nn.Sequential(*first, nn.Linear(width, hidden), nn.ReLU())
        self.rnn: nn.GRU | nn.LSTM = (nn.LSTM if self.lstm else nn.GRU)(
            hidden, hidden, batch_first=True
        )
        self.head = nn.Linear(hidden, actions)
        self.state_size = 2 * hidden if self.lstm else hidden

    def forward(self, x: torch.Tensor, state: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Action values ``(batch, time, actions)`` along ``x`` ``(batch, time, inputs)`` and
        the state after it."""
        embedded = self.embed(x)
        if isinstance(self.rnn, nn.LSTM):
            h, c = state[:, : self.hidden], state[:, self.hidden :]
            out, (h_n, c_n) = self.rnn(embedded, (h[None].contiguous(), c[None].contiguous()))
            return self.head(out), torch.cat([h_n[0], c_n[0]], dim=-1)
        out, h_n = self.rnn(embedded, state[None].contiguous())
        return self.head(out), h_n[0]

    def burn(self, x: torch.Tensor, state: torch.Tensor, live: torch.Tensor) -> torch.Tensor:
        """The state after reading the steps of ``x`` where ``live`` ``(batch, time)`` holds
        (the others, before an episode's start, leave it as it is; no burn-in: as it is)."""
        if x.shape[1] == 0:
            return state
        whole = live.all(dim=1)
        if bool((whole | ~live.any(dim=1)).all()):  # each row all or nothing: one call
            _, after = self(x, state)
            return torch.where(whole[:, None], after, state)
        for j in range(x.shape[1]):
            _, after = self(x[:, j : j + 1], state)
            state = torch.where(live[:, j : j + 1], after, state)
        return state


class Streams:
    """The current episode of each environment: inputs, transitions and actor states by step."""

    NAMES = ("observation", "automaton", "mask", "previous", "action", "terminated")

    def __init__(
        self,
        num_envs: int,
        longest: int,
        actions: int,
        state_size: int,
        observation: tuple[tuple[int, ...], Any] = ((), np.int64),
    ) -> None:
        """``observation``: the shape and dtype of one observation (an id, or a Box's values:
        :attr:`mitlc.learn.learners.nets.Encoder.observation_field`)."""
        self.length = np.zeros(num_envs, dtype=np.int64)
        self.rows = np.arange(num_envs)
        inputs, steps = (num_envs, longest + 1), (num_envs, longest)
        shape, dtype = observation
        self.data: dict[str, np.ndarray[Any, Any]] = {
            "observation": np.zeros((*inputs, *shape), dtype=dtype),
            "automaton": np.zeros(inputs, dtype=np.int64),
            "mask": np.zeros(inputs, dtype=np.int64),
            "previous": np.full(inputs, -1, dtype=np.int64),
            "state": np.zeros((*inputs, state_size), dtype=np.float32),
            "action": np.zeros(steps, dtype=np.int64),
            "reward": np.zeros(steps, dtype=np.float32),
            "gamma": np.zeros(steps, dtype=np.float32),
            "terminated": np.zeros(steps, dtype=np.bool_),
            "next_valid": np.zeros((*steps, actions), dtype=np.bool_),
        }

    def write(self, offset: int, **values: np.ndarray[Any, Any]) -> None:
        """Store ``values`` of every environment at its step ``length + offset``."""
        for name, value in values.items():
            self.data[name][self.rows, self.length + offset] = value

    def cut(self, emit: BoolArray, burn_in: int, length: int) -> dict[str, np.ndarray[Any, Any]]:
        """The sequences of the environments in ``emit``: each one's last segment (started at
        a multiple of ``length``), its ``burn_in`` inputs before, and the actor's state then."""
        rows = self.rows[emit][:, None]
        count = self.length[emit][:, None]
        start = (count - 1) // length * length
        inputs = start - burn_in + np.arange(burn_in + length + 1)
        steps = start + np.arange(length)
        top_in, top_step = self.data["previous"].shape[1] - 1, self.data["action"].shape[1] - 1
        at_in, at_step = np.clip(inputs, 0, top_in), np.clip(steps, 0, top_step)
        sequences = {name: self.data[name][rows, at_in] for name in self.NAMES[:4]}
        for name in ("action", "reward", "gamma", "terminated", "next_valid"):
            sequences[name] = self.data[name][rows, at_step]
        sequences["burn"] = inputs[:, :burn_in] >= 0
        sequences["live"] = steps < count
        sequences["state"] = self.data["state"][rows[:, 0], np.maximum(start[:, 0] - burn_in, 0)]
        return sequences


class DRQNPolicy(Policy):
    """Greedy in a frozen copy of the recurrent network, with a state per episode."""

    def __init__(self, tables: Tables | None, encoder: Encoder, net: Recurrent) -> None:
        self.tables, self.encoder, self.net = tables, encoder, net
        self.reset(1)

    def reset(self, num_envs: int) -> None:
        """Fresh episodes: zero states, no previous action."""
        self.state = torch.zeros(num_envs, self.net.state_size, device=self.encoder.device)
        self.previous = np.full(num_envs, -1, dtype=np.int64)

    def act(self, env: Episodes) -> IntArray:
        """The greedy valid action of each episode; the states move on."""
        if len(self.previous) != env.num_envs:
            self.reset(env.num_envs)
        x = self.encoder(env.observation, env.automaton, env.mask, self.previous)
        with torch.no_grad():
            values, self.state = self.net(x[:, None], self.state)
        self.previous = greedy(values[:, 0], env.valid_actions())
        return self.previous

    def observe(self, step: Step) -> None:
        """Episodes that ended start over."""
        done = torch.from_numpy(step.done).to(self.state.device)
        self.state = torch.where(done[:, None], torch.zeros_like(self.state), self.state)
        self.previous = np.where(step.done, -1, self.previous)


class DRQNLearner(Learner):
    """Epsilon-greedy recurrent DQN with sequence replay (see the module docstring)."""

    def __init__(
        self,
        tables: Tables | None,
        config: TrainConfig,
        rng: np.random.Generator,
        shaping: Shaping | None = None,
        *,
        encoder: Encoder | None = None,
        num_actions: int | None = None,
        horizon: int | None = None,
    ) -> None:
        """``tables``: the finite product it learns on; ``None`` for any wrapped env, with the
        ``encoder`` of its observations (made with ``previous_action`` as the settings say),
        its ``num_actions`` and the task's ``horizon``."""
        configure_torch()
        self.tables, self.config, self.rng, self.shaping = tables, config, rng, shaping
        self.settings: DRQNConfig = config.drqn
        s = self.settings
        if tables is not None:
            encoder = encoder or Encoder(tables, previous_action=s.previous_action)
            num_actions, horizon = num_actions or tables.num_actions, horizon or tables.horizon
        if encoder is None or num_actions is None or horizon is None:
            raise ValueError("a learner of any env needs its encoder, actions and horizon")
        self.num_envs, num_a = s.num_envs, num_actions
        self.encoder = encoder
        self.device = encoder.device = resolve_device(config.device)
        self.net: Recurrent = build(
            torch_seed(rng),
            lambda: Recurrent(
                self.encoder.size, s.hidden, num_a, s.cell, image_features(self.encoder)
            ),
        ).to(self.device)
        if s.initial_value:
            optimistic(self.net.head, s.initial_value * s.reward_scale)
        self.target = copy.deepcopy(self.net)
        self.target.requires_grad_(False)
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=s.lr)
        size, length, burn = self.net.state_size, s.sequence_length, s.burn_in
        span = (burn + length + 1,)
        obs_shape, obs_dtype = self.encoder.observation_field
        self.replay = Ring(
            s.replay_size,
            {
                **{name: (span, np.int64) for name in Streams.NAMES[1:4]},
                "observation": ((*span, *obs_shape), obs_dtype),
                "burn": ((burn,), np.bool_),
                "action": ((length,), np.int64),
                "reward": ((length,), np.float32),
                "gamma": ((length,), np.float32),
                "terminated": ((length,), np.bool_),
                "next_valid": ((length, num_a), np.bool_),
                "live": ((length,), np.bool_),
                "state": ((size,), np.float32),
            },
        )
        self.streams = Streams(
            s.num_envs, 4 * horizon + 4, num_a, size, self.encoder.observation_field
        )
        self.state = torch.zeros(s.num_envs, size, device=self.device)
        self.previous = np.full(s.num_envs, -1, dtype=np.int64)
        self.vector_steps = self.gradient_steps = 0
        self._epsilon = s.epsilon_start

    @property
    def epsilon(self) -> float:
        """The exploration rate of the last step."""
        return self._epsilon

    def train_step(self, env: Episodes, fraction: float) -> Step:
        """One epsilon-greedy step of every episode; store finished segments; learn every
        ``train_every`` steps once enough sequences are stored."""
        s = self.settings
        self._epsilon = epsilon_at(fraction, s.epsilon_start, s.epsilon_end, s.epsilon_decay)
        anneal(self.optimizer, s.lr, s.lr_end_ratio, fraction)
        automaton = env.automaton
        seen = {"observation": env.observation, "automaton": automaton, "mask": env.mask}
        self.streams.write(0, **seen, previous=self.previous, state=self.state.cpu().numpy())
        x = self.encoder(env.observation, automaton, env.mask, self.previous)
        with torch.no_grad():
            values, after = self.net(x[:, None], self.state)
        valid = env.valid_actions()
        explore = self.rng.random(env.num_envs) < self._epsilon
        actions = np.where(explore, random_valid(self.rng, valid), greedy(values[:, 0], valid))
        before = self.shaping.before(env) if self.shaping is not None else None
        step = env.step(actions)
        reward, gammas = learning_signal(step, before, self.config, self.shaping)
        self._record(step, actions, reward * s.reward_scale, gammas, after)
        self.vector_steps += 1
        if self.replay.size >= s.warmup_sequences and self.vector_steps % s.train_every == 0:
            self._learn()
        return step

    def _record(
        self,
        step: Step,
        actions: IntArray,
        reward: FloatArray,
        gammas: FloatArray,
        after: torch.Tensor,
    ) -> None:
        """Store the transitions and the next inputs; cut finished segments into the replay;
        restart the actor's state of ended episodes."""
        s, streams = self.settings, self.streams
        streams.write(
            0,
            action=actions,
            reward=reward,
            gamma=gammas,
            terminated=step.terminated,
            next_valid=step.next_valid,
        )
        streams.write(
            1,
            observation=step.next_observation,
            automaton=step.next_automaton,
            mask=step.next_mask,
            previous=actions,
            state=after.cpu().numpy(),
        )
        streams.length += 1
        done = step.done
        emit = done | (streams.length % s.sequence_length == 0)
        if emit.any():
            self.replay.add(streams.cut(emit, s.burn_in, s.sequence_length))
        streams.length[done] = 0
        ended = torch.from_numpy(done).to(self.device)
        self.state = torch.where(ended[:, None], torch.zeros_like(after), after)
        self.previous = np.where(done, -1, actions)

    def _learn(self) -> None:
        """One gradient step on a batch of replayed sequences (burn-in, then the loss)."""
        s = self.settings
        batch = self.replay.sample(self.rng, s.batch_size)
        x = self.encoder(batch["observation"], batch["automaton"], batch["mask"], batch["previous"])
        state, burn, action, reward, gamma, terminated, next_valid, live = tensors(
            batch, "state", "burn", "action", "reward", "gamma", "terminated", "next_valid", "live",
            device=self.device,
        )  # fmt: skip
        head, rest = x[:, : s.burn_in], x[:, s.burn_in :]
        with torch.no_grad():
            online_state = self.net.burn(head, state, burn)
            target_values, _ = self.target(rest, self.target.burn(head, state, burn))
        values, _ = self.net(rest, online_state)
        taken = values[:, :-1].gather(2, action[..., None]).squeeze(-1)
        with torch.no_grad():
            value = bootstrap(values[:, 1:], target_values[:, 1:], next_valid, terminated, s.double)
            goal = reward + gamma * value
        loss = huber(taken - goal, live.float())
        gradient_step(loss, self.optimizer, list(self.net.parameters()), s.grad_clip)
        self.gradient_steps += 1
        if self.gradient_steps % s.target_update == 0:
            self.target.load_state_dict(self.net.state_dict())

    def state_dict(self) -> dict[str, Any]:
        """Networks, optimiser, replay memory, open streams, counters and the random state."""
        return {
            **deep_state(self),
            "streams": {k: v.copy() for k, v in self.streams.data.items()},
            "length": self.streams.length.copy(),
            "state": self.state.clone(),
            "previous": self.previous.copy(),
        }

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (``ValueError`` or ``RuntimeError`` if it does not fit)."""
        if self.tables is not None:
            check_indices(saved["replay"]["data"], self.tables, "replay.")
            check_indices(saved["streams"], self.tables, "streams.")
            check_indices({"previous": saved["previous"]}, self.tables, "")
        length, longest = saved["length"], self.streams.data["action"].shape[1]
        if np.size(length) and not 0 <= int(np.min(length)) <= int(np.max(length)) < longest:
            raise ValueError(f"length: values outside 0..{longest - 1}")
        load_deep_state(self, saved)
        self.streams.data = {k: np.array(v) for k, v in saved["streams"].items()}
        self.streams.length = np.array(saved["length"])
        self.state = saved["state"].clone().to(self.device)
        self.previous = np.array(saved["previous"])

    def policy(self) -> DRQNPolicy:
        """Greedy in a frozen copy of the current network."""
        net = copy.deepcopy(self.net)
        net.requires_grad_(False)
        return DRQNPolicy(self.tables, self.encoder, net)

"""Acting along the way the shaping pulls for a run's first steps: demonstrations that the task
gives a SAC or TD3 run (``sb3.guide_warmup``).

With ``guide: true`` the policy sees the way (:meth:`mitlc.gym.guide.TaskGuide.way`: a unit
vector toward the nearest region that advances the task, through free space). Potential-based
shaping gives a critic that has only seen failures no action to prefer (docs/deadlines.md, "The
way the shaping pulls"), so a run whose early episodes all fail may never find the first
success. For its first ``sb3.guide_warmup`` env steps such a run acts along the way instead of
by its policy: ``clip(2 * way + N(0, 0.3^2))`` in the action space scaled to [-1, 1], a
point robot pushed toward the region, with noise. The transitions go into the replay memory as
the actions taken (off-policy learning takes them as it takes any), and the policy learns from
the start, beside them. It fits envs whose continuous action moves the position the labels read
along the same axes (a point mass: PointMaze, mitlc's planes); the run checks that the action
has as many values as the way, and nothing else.

SB3 2.9.2 (pinned) picks an off-policy algorithm's exploratory action in
``OffPolicyAlgorithm._sample_action``; :func:`follow_the_way` replaces that method on one model
for the steps before ``guide_warmup``, and leaves it as it is after them (also on a resumed run,
which counts its steps from the checkpoint's).
"""

from __future__ import annotations

from typing import Any

import numpy as np

GAIN = 2.0
"""The push along the way, before clipping to the action bounds."""
NOISE = 0.3
"""The standard deviation of the Gaussian noise on each value of the scaled action."""


def way_size_problem(action_shape: tuple[int, ...], way_size: int) -> str | None:
    """Why a run cannot act along a way of ``way_size`` values with actions of
    ``action_shape``, or ``None``."""
    if action_shape != (way_size,):
        return (
            f"sb3.guide_warmup: acting along the way needs a continuous action of "
            f"{way_size} values, one per value of the position the labels read; this env's "
            f"action has shape {action_shape}"
        )
    return None


def way_action(way: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The scaled actions (in [-1, 1]) of a batch of ``way`` rows (module docstring)."""
    noisy = GAIN * np.asarray(way, dtype=np.float64) + rng.normal(0.0, NOISE, np.shape(way))
    return np.clip(noisy, -1.0, 1.0)


def follow_the_way(model: Any, steps: int, way_size: int, seed: int) -> None:
    """Make ``model`` (SAC or TD3) act along the way, the last ``way_size`` values of its flat
    observation, until it has ``steps`` env steps (module docstring)."""
    own = model._sample_action
    rng = np.random.default_rng((seed, 0x6775696465))

    def sample(
        learning_starts: int, action_noise: Any = None, n_envs: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        if model.num_timesteps >= steps:
            result: tuple[np.ndarray, np.ndarray] = own(learning_starts, action_noise, n_envs)
            return result
        scaled = way_action(np.asarray(model._last_obs)[:, -way_size:], rng)
        return model.policy.unscale_action(scaled), scaled

    model._sample_action = sample

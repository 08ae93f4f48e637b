"""The learners' names, the devices and the evaluation's size limit: what the command line
needs to declare its options, without importing the training settings
(:mod:`mitlc.learn.config`)."""

from __future__ import annotations

ALGORITHMS = (
    "q",
    "dqn",
    "drqn",
    "sb3-ppo",
    "sb3-dqn",
    "sb3-maskable-ppo",
    "sb3-recurrent-ppo",
    "sb3-sac",
    "sb3-td3",
)
"""Every ``algo`` of a world's ``training`` (``--algo``)."""

DEVICES = ("auto", "cpu", "cuda")
"""Every ``device`` of a world's ``training`` (``--device``; :mod:`mitlc.learn.device`)."""

MAX_EVAL_EPISODES = 1_000_000
"""The most episodes an evaluation runs (all at once, so memory grows with them): the bound of
``eval_episodes`` and ``eval --episodes`` in :mod:`mitlc.learn.bounds`."""

"""The SB3 backends' reader of images in the wrapper's flat observation.

An sb3 run learns on :class:`mitlc.gym.TaskWrapper`'s flat observation (one float32 vector), so
SB3's ``MlpPolicy`` would read an image's pixels as so many numbers. When the env's observation
holds images (:class:`mitlc.gym.observations.ImagePart`, told as SB3's ``is_image_space`` tells
them), :func:`image_policy_kwargs` gives the policy :class:`FlatImageExtractor` as its features
extractor (SB3's ``policy_kwargs=dict(features_extractor_class=...,
features_extractor_kwargs=...)``): each image is cut out of the vector at its offset, scaled by
1/255 (the vector holds raw pixels; SB3's ``preprocess_obs`` scales an image so) and read by
the CNN of mitlc's own deep learners (:class:`mitlc.learn.learners.images.ImageFeatures`: the
Nature CNN, or MiniGrid's small one), beside the rest of the vector; the policy's MLP follows.
This module imports Stable-Baselines3: import it only where SB3 is installed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import torch
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from mitlc.gym import TaskWrapper
from mitlc.gym.observations import ImagePart, readable
from mitlc.learn.learners.images import ImageFeatures

PIXEL = 1.0 / 255
"""What turns a raw pixel into [0, 1]."""


class FlatImageExtractor(BaseFeaturesExtractor):
    """SB3's features extractor of a flat observation with ``images`` in it (see the module
    docstring)."""

    def __init__(self, observation_space: spaces.Box, images: Sequence[ImagePart]) -> None:
        reader = ImageFeatures(int(observation_space.shape[0]), images, PIXEL)
        super().__init__(observation_space, reader.out)
        self.reader = reader

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        """The features of a batch of flat observations."""
        out: torch.Tensor = self.reader(observations)
        return out


def image_policy_kwargs(env: gym.Env[Any, Any]) -> dict[str, Any]:
    """The ``policy_kwargs`` entries that read the images of ``env``'s flat observation (a
    :class:`mitlc.gym.TaskWrapper` with ``flatten=True``, the env's part first, under any
    wrappers such as SB3's ``Monitor``), or none when it holds no image."""
    while not isinstance(env, TaskWrapper) and isinstance(env, gym.Wrapper):
        env = env.env
    if not isinstance(env, TaskWrapper) or not env.flatten:
        return {}
    images = readable(env.env.observation_space).images
    if not images:
        return {}
    return {
        "features_extractor_class": FlatImageExtractor,
        "features_extractor_kwargs": {"images": images},
    }

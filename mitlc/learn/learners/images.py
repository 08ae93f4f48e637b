"""Convolutional readers of the images in a flat feature vector.

mitlc's deep learners see one flat float vector per step
(:class:`mitlc.learn.learners.nets.Encoder`, which their replay memories store). An image part
of the env's observation (:class:`mitlc.gym.observations.ImagePart`: SB3's ``is_image_space``)
lies at a known offset of that vector; :class:`ImageFeatures` cuts each image out, reshapes it
to ``C, H, W``, scales it (by 1/255 where the vector holds raw pixels, as SB3's
``preprocess_obs`` does; mitlc's encoder has already scaled an image's values by its bounds
0..255) and runs a small CNN on it (:class:`ImageCNN`), then concatenates the CNN features with
the rest of the vector. The Q-network (:func:`q_network`) and the recurrent DQN's input layer
put it before their MLP; the SB3 backends' features extractor
(:mod:`mitlc.learn.backends.sb3_images`) is the same module.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import numpy as np
import torch
from torch import nn

from mitlc.gym.observations import ImagePart
from mitlc.learn.learners.encoder import Encoder
from mitlc.learn.learners.nets import mlp

NATURE_SIDE = 36
"""The smallest side the Nature CNN reads (its three convolutions leave one pixel)."""
NATURE_FEATURES = 512
"""The Nature CNN's features (its last linear layer; SB3's ``NatureCNN`` default)."""
SMALL_FEATURES = 128
"""The small CNN's features (MiniGrid's documented custom features extractor for SB3)."""


class ImageCNN(nn.Module):
    """The CNN of one image ``C, H, W``, then a linear layer and a ReLU:

    * a side of :data:`NATURE_SIDE` pixels or more: the Nature CNN (Mnih et al., "Human-level
      control through deep reinforcement learning", Nature 2015; SB3's ``NatureCNN``): 32
      filters 8x8 stride 4, 64 4x4 stride 2, 64 3x3 stride 1, then :data:`NATURE_FEATURES`;
    * a smaller image (MiniGrid's 7x7 view): the features extractor of MiniGrid's
      documentation ("Training MiniGrid environments" with SB3): 2x2 convolutions of 16, 32
      and 64 filters (as many as the image's side allows, the side less one), then
      :data:`SMALL_FEATURES`."""

    def __init__(self, chw: tuple[int, int, int]) -> None:
        super().__init__()
        channels, height, width = chw
        side = min(height, width)
        layers: list[nn.Module] = []
        if side >= NATURE_SIDE:
            shapes = [(channels, 32, 8, 4), (32, 64, 4, 2), (64, 64, 3, 1)]
            self.features = NATURE_FEATURES
        else:
            widths = [channels, 16, 32, 64][: min(3, side - 1) + 1]
            shapes = [(a, b, 2, 1) for a, b in pairwise(widths)]
            self.features = SMALL_FEATURES
        for inputs, outputs, kernel, stride in shapes:
            layers += [nn.Conv2d(inputs, outputs, kernel, stride), nn.ReLU()]
            height, width = (height - kernel) // stride + 1, (width - kernel) // stride + 1
        self.cnn = nn.Sequential(*layers, nn.Flatten())
        flat = (shapes[-1][1] if shapes else channels) * height * width
        self.linear = nn.Sequential(nn.Linear(flat, self.features), nn.ReLU())

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        """The features ``(batch, features)`` of ``images`` ``(batch, C, H, W)``."""
        out: torch.Tensor = self.linear(self.cnn(images))
        return out


class ImageFeatures(nn.Module):
    """A flat vector of ``size`` values with the ``images`` in it, read as the vector without
    the images followed by each image's CNN features (:class:`ImageCNN`); ``scale`` multiplies
    the image values first. Any leading shape: ``(..., size)`` to ``(..., out)``."""

    rest: torch.Tensor

    def __init__(self, size: int, images: Sequence[ImagePart], scale: float = 1.0) -> None:
        super().__init__()
        self.size, self.parts, self.scale = size, tuple(images), scale
        keep = np.ones(size, dtype=np.bool_)
        for part in self.parts:
            if part.offset < 0 or part.offset + part.size > size:
                raise ValueError(f"an image at {part.offset} of {part.size} values does not fit "
                                 f"in {size}")  # fmt: skip
            keep[part.offset : part.offset + part.size] = False
        self.register_buffer("rest", torch.from_numpy(np.flatnonzero(keep)), persistent=False)
        cnns = [ImageCNN(part.chw) for part in self.parts]
        self.cnns = nn.ModuleList(cnns)
        self.out = int(keep.sum()) + sum(cnn.features for cnn in cnns)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The features of the vectors ``x``."""
        lead = x.shape[:-1]
        flat = x.reshape(-1, self.size)
        pieces = [flat.index_select(1, self.rest)]
        for part, cnn in zip(self.parts, self.cnns, strict=True):
            image = flat[:, part.offset : part.offset + part.size].reshape(-1, *part.shape)
            if not part.channels_first:
                image = image.permute(0, 3, 1, 2)
            pieces.append(cnn(image * self.scale))
        return torch.cat(pieces, dim=-1).reshape(*lead, self.out)


def image_features(encoder: Encoder) -> ImageFeatures | None:
    """The image reader of an :class:`~mitlc.learn.learners.nets.Encoder`'s vectors (``None``
    when they hold no image)."""
    if not encoder.images:
        return None
    return ImageFeatures(encoder.size, encoder.images, encoder.image_scale)


def q_network(encoder: Encoder, hidden: int, layers: int, outputs: int) -> nn.Sequential:
    """DQN's network of an encoder's vectors: :func:`~mitlc.learn.learners.nets.mlp`, after
    the :class:`ImageFeatures` where the vectors hold images (its last layer is the linear
    output layer either way)."""
    features = image_features(encoder)
    if features is None:
        return mlp(encoder.size, hidden, layers, outputs)
    return nn.Sequential(features, *mlp(features.out, hidden, layers, outputs))

"""Labels perceived with a probability: ``{obs: [15], probability: 0.9}``.

Any declared form may carry ``probability: p`` beside it (0 < p <= 1; 1, the default, is
certain): where the form holds, the proposition is perceived with probability ``p``, drawn anew
at every position read (the reset's and each step's), independently of every other position,
label and form; where the form does not hold, it gives nothing. A proposition declared by a
list of forms is perceived where any of its holding forms is, each form its own draw: with
probability ``1 - prod(1 - p)`` over the forms that hold.

What a position gives is its :data:`Chances` (:class:`ChanceReader`): the bits of the letter
that hold surely, and those that hold with a probability below 1. :func:`perceive` is the one
draw, what the task wrapper reads (:mod:`mitlc.gym.reading`); the exact model of a finite env
world (:mod:`mitlc.worlds.gym_uncertain`, over :mod:`mitlc.worlds.uncertain`) gives each
outcome the probability this draw gives it: each uncertain bit holds with its probability,
independently of the others.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from mitlc.labels.values import NO_MOMENT, Moment

if TYPE_CHECKING:
    from mitlc.labels.forms import Form

CERTAIN = 1.0
"""The probability of a form that carries none."""

Chances = tuple[int, tuple[tuple[int, float], ...]]
"""``(certain, ((bit, p), ...))``: the letter's bits that hold surely, and each bit that holds
with probability ``p`` (0 < p < 1), independently of the others."""


def either(held: float, p: float) -> float:
    """The probability that at least one of two independent events of probabilities ``held``
    and ``p`` occurs (``p`` itself where ``held`` is 0, exactly)."""
    return CERTAIN if p >= CERTAIN else held + p - held * p


@dataclass(frozen=True, slots=True)
class ChanceReader:
    """The chances of a position from compiled forms: ``checks[i] = (bit, forms,
    probabilities)``, each form perceived with its probability where it holds."""

    checks: tuple[tuple[int, tuple[Form, ...], tuple[float, ...]], ...]

    def __call__(self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT) -> Chances:
        """The chances of ``(obs, info)`` at ``moment``."""
        certain = 0
        uncertain = []
        for bit, forms, probabilities in self.checks:
            held = 0.0
            for form, p in zip(forms, probabilities, strict=True):
                if form.holds(obs, info, moment):
                    held = either(held, p)
                    if held >= CERTAIN:
                        break
            if held >= CERTAIN:
                certain |= bit
            elif held > 0.0:
                uncertain.append((bit, held))
        return certain, tuple(uncertain)


def perceive(chances: Chances, rng: np.random.Generator) -> int:
    """The letter perceived at a position of ``chances``: its certain bits, and each uncertain
    bit where one uniform draw in ``[0, 1)`` from ``rng`` falls below its probability (one draw
    per uncertain bit, in the order given; none where every bit is certain)."""
    letter, uncertain = chances
    for bit, p in uncertain:
        if rng.random() < p:
            letter |= bit
    return letter

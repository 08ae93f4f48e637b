"""The compiled label forms and the letter readers, what runs on every step (the
declarations they are compiled from: :mod:`mitlc.labels`)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

from mitlc.errors import MitlcError
from mitlc.labels.chance import CERTAIN, ChanceReader
from mitlc.labels.function import true_names
from mitlc.labels.values import NO_MOMENT, AttrPath, InfoPath, Moment, Value

LabelFunction = Callable[[Any, dict[str, Any]], Iterable[str]]
"""A labelling function: ``(obs, info) -> the true propositions``."""

LetterReader = Callable[..., int]
"""``(obs, info[, moment]) -> letter`` over given propositions (bit ``i`` for
``propositions[i]``); ``moment`` (:class:`~mitlc.labels.values.Moment`) is what the task wrapper
knows beside them: the env and the last step's reward and end."""

_CACHE_LIMIT = 1 << 16


class LabelDeclarationError(MitlcError, ValueError):
    """A label declaration is malformed, or does not fit the observation space; the message
    starts with the field's path."""


@runtime_checkable
class Labels(Protocol):
    """Labels that declare their propositions and read letters directly (what the wrapper
    prefers to a bare callable)."""

    @property
    def propositions(self) -> tuple[str, ...]: ...
    def __call__(
        self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT
    ) -> frozenset[str]: ...
    def letter_reader(self, propositions: Sequence[str]) -> LetterReader: ...


# -- the forms ---------------------------------------------------------------------------------


def obs_part(obs: Any, key: str | None) -> Any:
    return obs if key is None else obs[key]


@dataclass(frozen=True, slots=True)
class ObsIn:
    """A discrete observation is one of ``values``."""

    values: frozenset[int]
    key: str | None = None

    def holds(self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT) -> bool:
        """Whether the form holds."""
        return int(obs_part(obs, self.key)) in self.values


@dataclass(frozen=True, slots=True)
class Decoded:
    """Each checked field ``(divisor, radix, allowed)`` of a mixed-radix observation has one of
    its allowed values (the field is ``obs // divisor % radix``), and each pair of fields in
    ``equal`` (``(divisor, radix, divisor, radix)``) has the same value."""

    checks: tuple[tuple[int, int, frozenset[int]], ...]
    key: str | None = None
    equal: tuple[tuple[int, int, int, int], ...] = ()

    def holds(self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT) -> bool:
        """Whether the form holds."""
        value = int(obs_part(obs, self.key))
        return all(value // d % r in allowed for d, r, allowed in self.checks) and all(
            value // d % r == value // e % s for d, r, e, s in self.equal
        )


@dataclass(frozen=True, slots=True)
class InBox:
    """``low[j] <= obs[index[j]] <= high[j]`` for every ``j``."""

    index: tuple[int, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]
    key: str | None = None

    def holds(self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT) -> bool:
        """Whether the form holds."""
        x = obs_part(obs, self.key)
        return all(
            lo <= float(x[i]) <= hi
            for i, lo, hi in zip(self.index, self.low, self.high, strict=True)
        )


@dataclass(frozen=True, slots=True)
class InDisc:
    """``sum((obs[index[j]] - center[j]) ** 2) <= radius ** 2``."""

    index: tuple[int, ...]
    center: tuple[float, ...]
    radius: float
    key: str | None = None

    def holds(self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT) -> bool:
        """Whether the form holds."""
        x = obs_part(obs, self.key)
        squared = sum((float(x[i]) - c) ** 2 for i, c in zip(self.index, self.center, strict=True))
        return squared <= self.radius * self.radius


@dataclass(frozen=True, slots=True)
class Guided:
    """A form with a guide for shaping (``toward``): it holds as ``form`` does; ``origin`` is
    where the agent is and ``target`` where the proposition can be made true, both read from
    the env or its info, which only :mod:`mitlc.labels.distance` reads (MiniGrid's key, whose
    place changes with every episode)."""

    form: ObsIn | Decoded | InBox | InDisc | Value
    origin: AttrPath | InfoPath
    target: AttrPath | InfoPath

    def holds(self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT) -> bool:
        """Whether the form holds."""
        return self.form.holds(obs, info, moment)


Form = ObsIn | Decoded | InBox | InDisc | Value | Guided


# -- compiled labels ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class DeclaredLetters:
    """Letters from compiled forms: ``checks[i] = (bit, forms)``, the bit set when any form
    holds."""

    checks: tuple[tuple[int, tuple[Form, ...]], ...]

    def __call__(self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT) -> int:
        """The letter of ``(obs, info)`` at ``moment``."""
        letter = 0
        for bit, forms in self.checks:
            for form in forms:
                if form.holds(obs, info, moment):
                    letter |= bit
                    break
        return letter


@dataclass(slots=True)
class CachedLetters:
    """:class:`DeclaredLetters` of forms that read only a discrete observation, memoised per
    observation (up to a bound on the entries)."""

    letters: DeclaredLetters
    cache: dict[int, int] = field(default_factory=dict)

    def __call__(self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT) -> int:
        """The letter of ``(obs, info)`` (the forms do not read ``moment``)."""
        cache = self.cache
        if type(obs) is int:
            found = cache.get(obs)
            if found is not None:
                return found
        letter = self.letters(obs, info)
        if len(cache) < _CACHE_LIMIT:
            cache[int(obs)] = letter
        return letter


@dataclass(frozen=True, slots=True)
class Labeller:
    """Compiled declarative labels: ``forms[i]`` are the forms of ``propositions[i]`` (any of
    them makes it true), ``probabilities[i][j]`` the probability that form ``forms[i][j]`` is
    perceived where it holds (:mod:`mitlc.labels.chance`; empty: every form certain)."""

    propositions: tuple[str, ...]
    forms: tuple[tuple[Form, ...], ...]
    probabilities: tuple[tuple[float, ...], ...] = ()

    def __call__(
        self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT
    ) -> frozenset[str]:
        """The propositions whose forms hold at ``(obs, info)`` at ``moment`` (those with a
        probability are then perceived only with it: :meth:`chance_reader`)."""
        return frozenset(
            p
            for p, forms in zip(self.propositions, self.forms, strict=True)
            if any(f.holds(obs, info, moment) for f in forms)
        )

    def values(self) -> tuple[tuple[str, int, Value], ...]:
        """Each form that reads a value (an attribute, an ``info`` path, an event) with its
        proposition and its index among the proposition's forms (a guided form's own)."""
        found = []
        for p, forms in zip(self.propositions, self.forms, strict=True):
            for i, f in enumerate(forms):
                own = f.form if isinstance(f, Guided) else f
                if isinstance(own, Value):
                    found.append((p, i, own))
        return tuple(found)

    def guides(self) -> tuple[tuple[str, int, Guided], ...]:
        """Each guided form with its proposition and its index among the proposition's
        forms."""
        return tuple(
            (p, i, f)
            for p, forms in zip(self.propositions, self.forms, strict=True)
            for i, f in enumerate(forms)
            if isinstance(f, Guided)
        )

    def probabilities_of(self, proposition: str) -> tuple[float, ...]:
        """The probability of each form of ``proposition`` (declared here)."""
        i = self.propositions.index(proposition)
        return self.probabilities[i] if self.probabilities else (CERTAIN,) * len(self.forms[i])

    def uncertain(self, propositions: Sequence[str]) -> list[str]:
        """Those of ``propositions`` (each must be declared here) that a form perceives with a
        probability below 1."""
        self._index(propositions)
        return [p for p in propositions if any(q < CERTAIN for q in self.probabilities_of(p))]

    def chance_reader(self, propositions: Sequence[str]) -> ChanceReader:
        """A reader of the chances over ``propositions`` (each must be declared here) that
        :func:`mitlc.labels.chance.perceive` draws a letter from."""
        index = self._index(propositions)
        return ChanceReader(
            tuple(
                (1 << j, self.forms[index[p]], self.probabilities_of(p))
                for j, p in enumerate(propositions)
            )
        )

    def letter_reader(self, propositions: Sequence[str]) -> DeclaredLetters | CachedLetters:
        """A reader of letters over ``propositions`` (each must be declared here and certain:
        a letter with a probability is drawn, :meth:`chance_reader`)."""
        index = self._index(propositions)
        if drawn := self.uncertain(propositions):
            raise LabelDeclarationError(
                f"labels.{drawn[0]}.probability: the proposition is perceived with a "
                "probability, so its letter is drawn: read it with Labeller.chance_reader and "
                "mitlc.labels.chance.perceive"
            )
        checks = tuple((1 << j, self.forms[index[p]]) for j, p in enumerate(propositions))
        letters = DeclaredLetters(checks)
        if all(isinstance(f, ObsIn | Decoded) and f.key is None for _, fs in checks for f in fs):
            return CachedLetters(letters)
        return letters

    def _index(self, propositions: Sequence[str]) -> dict[str, int]:
        """Each declared proposition's index; an error naming those of ``propositions`` that
        are not declared."""
        index = {p: i for i, p in enumerate(self.propositions)}
        missing = [p for p in propositions if p not in index]
        if missing:
            raise undeclared(missing, self.propositions)
        return index


@dataclass(frozen=True, slots=True)
class CallableLetters:
    """Letters from a labelling function, over ``propositions``."""

    function: LabelFunction
    propositions: tuple[str, ...]

    def __call__(self, obs: Any, info: dict[str, Any], moment: Moment = NO_MOMENT) -> int:
        """The letter of ``(obs, info)`` (a labelling function reads only those); a
        :class:`~mitlc.labels.function.LabelFunctionError` where the function returns no
        iterable of names."""
        true = self.function(obs, info)
        if not isinstance(true, set | frozenset):
            true = true_names(self.function, true)
        letter = 0
        for i, p in enumerate(self.propositions):
            if p in true:
                letter |= 1 << i
        return letter


def undeclared(missing: Sequence[str], declared: Sequence[str]) -> LabelDeclarationError:
    """The error of a task naming propositions that the labels do not declare."""
    return LabelDeclarationError(
        f"labels: the task's propositions {list(missing)} are not declared "
        f"(declared: {sorted(declared)})"
    )


def letter_reader(labels: Labels | LabelFunction, propositions: Sequence[str]) -> LetterReader:
    """A reader of letters over ``propositions``: the labels' own, or one calling the function."""
    if isinstance(labels, Labels):
        return labels.letter_reader(propositions)
    return CallableLetters(labels, tuple(propositions))

"""A trained SB3 network loaded for ``mitlc eval`` and ``mitlc plot``: what every such learner
shares (it does not train: :func:`mitlc.learn.backends.sb3.train` does; it is greedy)."""

from __future__ import annotations

from typing import Any

from mitlc.learn.envs.vec import Step
from mitlc.learn.learners.base import Episodes, Learner
from mitlc.learn.rundir.files import RunError
from mitlc.learn.setting import Setting


class LoadedLearner(Learner):
    """A network's weights, of a run's setting; :meth:`policy` is the subclass's."""

    def __init__(self, net: Any, setting: Setting) -> None:
        self.net, self.setting = net, setting
        self.num_envs = setting.config.sb3.num_envs

    def train_step(self, env: Episodes, fraction: float) -> Step:
        """Not here: an sb3 run trains through :func:`mitlc.learn.backends.sb3.train`."""
        raise RunError("an sb3 run trains through mitlc.learn.backends.sb3.train")

    @property
    def epsilon(self) -> float:
        """No exploration: the policy is greedy."""
        return 0.0

    def state_dict(self) -> dict[str, Any]:
        """The policy's weights."""
        return {"policy": dict(self.net.state_dict())}

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Load :meth:`state_dict`."""
        self.net.load_state_dict(saved["policy"])

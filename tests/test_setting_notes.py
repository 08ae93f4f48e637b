"""What ``mitlc train`` tells before a run (:func:`mitlc.learn.setting.setting_notes`): which
learner to pick on a POMDP when an SB3 backend is asked for, and nothing of it otherwise."""

from __future__ import annotations

import pytest

from mitlc.learn.config import config_for
from mitlc.learn.setting import POMDP_PICK, prepare, setting_notes
from mitlc.worlds.door import open_world
from tests.conftest import ROOT

PAPER = ROOT / "specs" / "paper"


@pytest.mark.parametrize(
    ("world", "algo", "told"),
    [
        ("case2.yaml", "sb3-recurrent-ppo", True),
        ("case2.yaml", "q", False),
        ("case1.yaml", "sb3-ppo", False),
    ],
)
def test_an_sb3_run_on_a_pomdp_is_told_which_learner_to_pick(
    world: str, algo: str, told: bool
) -> None:
    loaded = open_world(PAPER / world)
    config, _ = config_for(loaded, {"algo": algo})
    setting = prepare(PAPER / world, config, world=loaded)
    assert (POMDP_PICK in setting_notes(setting)) is told

"""Shared test fixtures: the golden-file switch and the repository paths."""

from __future__ import annotations

from pathlib import Path

import pytest

from mitlc.learn.config import DRQNConfig

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "golden"

TINY_DRQN = DRQNConfig(
    num_envs=4,
    hidden=16,
    batch_size=4,
    sequence_length=6,
    burn_in=3,
    replay_size=200,
    warmup_sequences=4,
    train_every=2,
    target_update=10,
)
"""A recurrent DQN small enough for a test to train in a second (the deep tests share it)."""


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--update-golden",
        action="store_true",
        default=False,
        help="Rewrite golden files from the current output instead of comparing (read the diff!).",
    )


@pytest.fixture
def update_golden(request: pytest.FixtureRequest) -> bool:
    return bool(request.config.getoption("--update-golden"))


def check_golden(path: Path, actual: str, update: bool) -> None:
    """Compare ``actual`` with the golden file at ``path``, or rewrite it when ``update``."""
    if update:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(actual, encoding="utf-8")
        return
    assert path.exists(), f"missing golden {path}; run pytest --update-golden, read the diff"
    expected = path.read_text(encoding="utf-8")
    assert actual == expected, f"{path.name} differs from its golden file"
